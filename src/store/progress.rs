//! The backward stage's record of a sweep on disk (RUN_DIR/backward.json: its options, C where
//! it stopped, the accumulated exponents, the frames written), read back by `clv backward
//! --resume`, by `clv analyze` (which frame file is the run's) and by `clv inspect`; and the
//! CLV spectra of sweeps (RUN_DIR/clv_spectrum.json, those of earlier sweeps kept as
//! clv_spectrum-N.json). When to save and what to resume is decided in
//! [`crate::stage::backward`]; here is only how the records are kept.

use crate::error::{Error, Result};
use crate::linalg::unpack_upper;
use crate::stage::backward::{BackwardOptions, BackwardReport, BackwardStats};
use crate::statistics::Accumulator;
use crate::store::checked_json;
use crate::store::run::{write_atomic, RunDir};
use faer::{Mat, MatRef};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Saved after every finished segment (RUN_DIR/backward.json).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Progress {
    pub(crate) options: BackwardOptions,
    pub(crate) at: u64,
    /// C_at: its upper triangle packed column by column ([`pack_upper`](crate::linalg::pack_upper)), written as hex.
    #[serde(with = "f64_hex")]
    pub(crate) c: Vec<f64>,
    pub(crate) acc: Accumulator,
    /// ln [R_n]_ii over the same steps, for [`BackwardReport::gs_window`].
    #[serde(default)]
    pub(crate) acc_gs: Option<Accumulator>,
    pub(crate) stats: BackwardStats,
    pub(crate) done: bool,
}

impl Progress {
    /// The progress record `file` (holding `bytes`) of the run in `run`. A record of a build
    /// before records carried checksums named its frame file relative to the directory the
    /// command ran in: it is read with that meaning (resolved against this one, the best
    /// guess there is) and held as records name it now.
    pub(crate) fn read(run: &Path, file: &Path, bytes: &[u8]) -> Result<Self> {
        let (mut p, seal): (Progress, _) = checked_json::from_slice(file, bytes)?;
        if seal == checked_json::Seal::Absent
            && let Some(relative) = p.options.frames_path.clone().filter(|f| f.is_relative())
        {
            p.options.frames_path = Some(BackwardOptions::record_frames_path(run, &relative)?);
        }
        Ok(p)
    }

    /// C_at as a matrix: packed, or column-major k x k as earlier builds wrote it.
    pub(crate) fn c_matrix(&self, k: usize) -> Option<Mat<f64>> {
        match self.c.len() {
            n if n == k * (k + 1) / 2 => unpack_upper(&self.c),
            n if n == k * k => Some(MatRef::from_column_major_slice(&self.c, k, k).to_owned()),
            _ => None,
        }
    }

    /// Write the record to `file` (RUN_DIR/backward.json) whole, with its checksum.
    pub(crate) fn save(&self, file: &Path) -> Result<()> {
        write_atomic(file, &checked_json::to_vec(self)?)
    }
}

/// The numbers of C in the progress record as one hex string of their little-endian bytes:
/// exact, and cheap. At k = 792 the JSON array of numbers took 30-80 ms a segment to encode
/// on the sweep's thread; with hex the whole record, write and fsync included, took 16-50 ms
/// (measured). Arrays of numbers (earlier builds) still read.
mod f64_hex {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        const DIGITS: &[u8; 16] = b"0123456789abcdef";
        let mut text = String::with_capacity(16 * v.len());
        for byte in v.iter().flat_map(|x| x.to_le_bytes()) {
            text.push(DIGITS[(byte >> 4) as usize] as char);
            text.push(DIGITS[(byte & 15) as usize] as char);
        }
        s.serialize_str(&text)
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Repr {
        Hex(String),
        Numbers(Vec<f64>),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        match Repr::deserialize(d)? {
            Repr::Numbers(v) => Ok(v),
            Repr::Hex(text) => {
                let digit = |c: u8| (c as char).to_digit(16).map(|x| x as u8);
                let bytes: Option<Vec<u8>> = text.as_bytes().chunks(2).map(|p| Some(digit(p[0])? << 4 | digit(*p.get(1)?)?)).collect();
                let bytes = bytes.filter(|b| b.len() % 8 == 0).ok_or_else(|| serde::de::Error::custom("C is not a hex string of whole f64 values"))?;
                Ok(crate::store::cbor::f64s_from_le_bytes(&bytes))
            }
        }
    }
}

/// The options of the sweep recorded in the run's progress record, if there is one.
pub fn stored_options(run: &Path) -> Option<BackwardOptions> {
    last_sweep(run).ok().flatten().map(|s| s.options)
}

/// The run's last backward sweep, as its progress record (RUN/backward.json) describes it.
pub struct LastSweep {
    pub options: BackwardOptions,
    /// It finished (its frame file, if any, is complete under its own name).
    pub done: bool,
    /// Frames emitted up to its last finished segment, where `--resume` continues.
    pub frames: u64,
    /// The step whose C the record holds (where an interrupted sweep continues).
    pub at: u64,
}

/// The last backward sweep of the run in `run`: None without a progress record, an error
/// when the record cannot be read (damaged, edited).
pub fn last_sweep(run: &Path) -> Result<Option<LastSweep>> {
    let file = RunDir { path: run.to_path_buf() }.progress_path();
    let text = match std::fs::read_to_string(&file) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(&file, e)),
    };
    let p = Progress::read(run, &file, text.as_bytes())?;
    Ok(Some(LastSweep { options: p.options, done: p.done, frames: p.stats.frames, at: p.at }))
}

/// RUN_DIR/clv_spectrum.json. The CLV spectrum of an earlier sweep with other options
/// (another C, transient, file) can be hours of work: kept beside the new one
/// (clv_spectrum-N.json), not replaced, and the report notes where.
pub(crate) fn write_report(dir: &RunDir, report: &mut BackwardReport) -> Result<()> {
    let json = checked_json::to_vec(&*report)?;
    let path = dir.clv_spectrum_path();
    if let Some((earlier, _)) = std::fs::read(&path).ok().and_then(|bytes| checked_json::from_slice::<BackwardReport>(&path, &bytes).ok())
        && earlier.options != report.options
    {
        let mut i = 1;
        while dir.earlier_clv_spectrum_path(i).exists() {
            i += 1;
        }
        let kept = dir.earlier_clv_spectrum_path(i);
        std::fs::rename(&path, &kept).map_err(|e| Error::io(&path, e))?;
        report.notes.push(format!("the CLV spectrum of the earlier sweep, made with {}, is kept as {}", earlier.options.as_flags(), kept.display()));
    }
    write_atomic(&path, &json)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::linalg::pack_upper;
    use crate::stage::backward::CInit;

    /// A record of a sweep with C = `c` (also for the stage's tests).
    pub(crate) fn record(c: Vec<f64>) -> Progress {
        Progress { options: BackwardOptions { transient: 1, c_init: CInit::Identity, with_gs: false, save_every: 1, frames_path: None, vectors_every: 1, no_frames: false }, at: 7, c, acc: Accumulator::new(3, 2), acc_gs: None, stats: BackwardStats::default(), done: false }
    }

    /// C survives the progress record bit for bit (hex), and records of earlier builds (a JSON
    /// array, column-major k x k) still read; a damaged C is an error, not a panic.
    #[test]
    fn progress_record_keeps_c_exactly() {
        let k = 3;
        let c = Mat::from_fn(k, k, |i, j| if i <= j { [1.0 / 3.0, -0.0, 5e-324, f64::MAX, -1.25e-300, 0.1][(i + j) % 6] } else { 0.0 });
        let text = serde_json::to_string(&record(pack_upper(c.as_ref()))).unwrap();
        let back: Progress = serde_json::from_str(&text).unwrap();
        let got = back.c_matrix(k).unwrap();
        assert!((0..k).all(|i| (0..k).all(|j| got[(i, j)].to_bits() == c[(i, j)].to_bits())));

        let legacy = text.replace(&format!("\"c\":{}", serde_json::to_string(&serde_json::to_value(&back).unwrap()["c"]).unwrap()), "\"c\":[1.0,0.0,0.0,2.0,3.0,0.0,4.0,5.0,6.0]");
        let old: Progress = serde_json::from_str(&legacy).unwrap();
        assert_eq!(old.c_matrix(k).unwrap(), Mat::from_fn(k, k, |i, j| [[1.0, 2.0, 4.0], [0.0, 3.0, 5.0], [0.0, 0.0, 6.0]][i][j]));

        assert!(record(vec![1.0; 5]).c_matrix(k).is_none(), "5 numbers are no 3 x 3 triangle");
        for bad in ["\"c\":\"0g00000000000000\"", "\"c\":\"00000000000000\"", "\"c\":\"000\""] {
            let damaged = legacy.replace("\"c\":[1.0,0.0,0.0,2.0,3.0,0.0,4.0,5.0,6.0]", bad);
            assert!(serde_json::from_str::<Progress>(&damaged).is_err(), "{bad}");
        }
    }
}
