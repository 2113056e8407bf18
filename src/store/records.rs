//! Typed messages of a run directory and their encoding through the schemas.

use super::schema::{CHECKPOINT, R, STATS};
use crate::stage::forward::ForwardState;
use crate::statistics::Accumulator;
use crate::system::Snapshot;
use faer::Mat;

/// A checkpoint: the forward state plus what a reader needs to interpret it.
#[derive(Clone, Debug, PartialEq)]
pub struct Checkpoint {
    pub state: ForwardState,
    pub time: f64,
    pub system: String,
    pub d: usize,
    pub k: usize,
}

impl Checkpoint {
    pub fn encode(&self) -> Vec<u8> {
        let s = &self.state;
        let blocks: Vec<f64> = s.acc.blocks.iter().flatten().copied().collect();
        CHECKPOINT
            .encoder(8 * (s.g.len() + s.system.phase.len() + blocks.len() + 3 * self.k))
            .u64("step", s.step)
            .f64("time", self.time)
            .text("system", &self.system)
            .u64("d", self.d as u64)
            .u64("k", self.k as u64)
            .u64("events", s.system.events)
            .f64s("phase", &s.system.phase)
            .f64s("g", &s.g)
            .u64("acc_steps", s.acc.steps)
            .u64("acc_block_len", s.acc.block_len)
            .f64s("acc_sum", &s.acc.sum)
            .f64s("acc_current", &s.acc.current)
            .f64s("acc_blocks", &blocks)
            .finish()
    }

    pub fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut m = CHECKPOINT.decode(bytes)?;
        let (d, k) = (m.u64("d") as usize, m.u64("k") as usize);
        let phase = m.take_f64s("phase");
        let g = m.take_f64s("g");
        let sum = m.take_f64s("acc_sum");
        let current = m.take_f64s("acc_current");
        let blocks = m.take_f64s("acc_blocks");
        let step = m.u64("step");
        if phase.len() != d || g.len() != d * k || sum.len() != k || current.len() != k || (k > 0 && blocks.len() % k != 0) {
            return Err(format!("checkpoint at step {step}: array lengths do not match D = {d}, k = {k}"));
        }
        let acc = Accumulator {
            sum,
            steps: m.u64("acc_steps"),
            block_len: m.u64("acc_block_len").max(1),
            blocks: blocks.chunks(k.max(1)).map(<[f64]>::to_vec).collect(),
            current,
        };
        Ok(Checkpoint {
            state: ForwardState { step, system: Snapshot { phase, events: m.u64("events") }, g, acc },
            time: m.f64("time"),
            system: m.text("system").to_string(),
            d,
            k,
        })
    }
}

/// R_n's upper triangle, column by column, encoded straight from the matrix (a step of a run
/// that stores every R_n allocates only the message).
pub fn encode_r(step: u64, r: &Mat<f64>) -> Vec<u8> {
    let k = r.ncols();
    let len = k * (k + 1) / 2;
    let upper = (0..k).flat_map(|j| r.col_as_slice(j)[..=j].iter().copied());
    R.encoder(8 * len).u64("step", step).u64("k", k as u64).f64s_of("r", len, upper).finish()
}

/// (step, R_n).
pub fn decode_r(bytes: &[u8]) -> Result<(u64, Mat<f64>), String> {
    let mut m = R.decode(bytes)?;
    let (step, k) = (m.u64("step"), m.u64("k") as usize);
    let r = crate::linalg::unpack_upper(&m.take_f64s("r")).filter(|r| r.ncols() == k);
    r.map(|r| (step, r)).ok_or_else(|| format!("R at step {step}: packed length does not match k = {k}"))
}

/// The running spectrum and statistics at a checkpoint.
#[derive(Clone, Debug, PartialEq)]
pub struct Stats {
    pub step: u64,
    pub time: f64,
    pub exponents: Vec<f64>,
    pub stderr: Vec<f64>,
    pub energy: f64,
    pub energy_initial: f64,
    pub momentum: [f64; 2],
    pub collisions: u64,
    pub wall_seconds: f64,
}

impl Stats {
    pub fn encode(&self) -> Vec<u8> {
        STATS
            .encoder(16 * self.exponents.len())
            .u64("step", self.step)
            .f64("time", self.time)
            .f64s("exponents", &self.exponents)
            .f64s("stderr", &self.stderr)
            .f64("energy", self.energy)
            .f64("energy_initial", self.energy_initial)
            .f64s("momentum", &self.momentum)
            .u64("collisions", self.collisions)
            .f64("wall_seconds", self.wall_seconds)
            .finish()
    }

    pub fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut m = STATS.decode(bytes)?;
        let momentum = m.take_f64s("momentum");
        let momentum: [f64; 2] = momentum.try_into().map_err(|_| "stats: momentum must hold 2 values".to_string())?;
        Ok(Stats {
            step: m.u64("step"),
            time: m.f64("time"),
            exponents: m.take_f64s("exponents"),
            stderr: m.take_f64s("stderr"),
            energy: m.f64("energy"),
            energy_initial: m.f64("energy_initial"),
            momentum,
            collisions: m.u64("collisions"),
            wall_seconds: m.f64("wall_seconds"),
        })
    }
}

impl crate::stage::frame::Frame {
    pub fn encode(&self) -> Vec<u8> {
        let g: &[f64] = self.g.as_deref().unwrap_or(&[]);
        super::schema::FRAME
            .encoder(8 * (self.v.len() + g.len() + self.phase.len() + 2 * self.k))
            .u64("step", self.step)
            .f64("time", self.time)
            .u64("d", self.d as u64)
            .u64("k", self.k as u64)
            .f64s("phase", &self.phase)
            .f64s("v", &self.v)
            .f64s("local", &self.local)
            .f64s("gs_local", &self.gs_local)
            .f64s("g", g)
            .finish()
    }

    pub fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut m = super::schema::FRAME.decode(bytes)?;
        let (d, k, step) = (m.u64("d") as usize, m.u64("k") as usize, m.u64("step"));
        let (phase, v, local, g) = (m.take_f64s("phase"), m.take_f64s("v"), m.take_f64s("local"), m.take_f64s("g"));
        let gs_local = m.take_optional_f64s("gs_local");
        if phase.len() != d || !(v.is_empty() || v.len() == d * k) || local.len() != k || !(gs_local.is_empty() || gs_local.len() == k) || !(g.is_empty() || g.len() == d * k) {
            return Err(format!("frame at step {step}: array lengths do not match D = {d}, k = {k}"));
        }
        Ok(Self { step, time: m.f64("time"), d, k, phase, v, local, gs_local, g: if g.is_empty() { None } else { Some(g) } })
    }
}

#[cfg(test)]
mod tests {
    use crate::stage::frame::Frame;

    /// A frame survives encoding, with or without its vectors (`--vectors-every`); arrays of
    /// the wrong length are refused with the step named.
    #[test]
    fn frames_round_trip_with_and_without_vectors() {
        let (d, k) = (4, 2);
        let full = Frame { step: 12, time: 7.2, d, k, phase: vec![0.5; d], v: (0..d * k).map(|i| i as f64 / 7.0).collect(), local: vec![1.5, -1.5], gs_local: vec![1.25, -1.75], g: Some(vec![0.25; d * k]) };
        let bare = Frame { v: Vec::new(), g: None, ..full.clone() };
        for f in [&full, &bare] {
            assert_eq!(&Frame::decode(&f.encode()).unwrap(), f);
        }
        // A frame written before frames carried their local GS exponents still reads.
        let mut old = crate::store::cbor::MapWriter::new(8, 0);
        old.u64("step", 12);
        old.f64("time", 7.2);
        old.u64("d", d as u64);
        old.u64("k", k as u64);
        old.f64s("phase", &full.phase);
        old.f64s("v", &full.v);
        old.f64s("local", &full.local);
        old.f64s("g", &[]);
        assert_eq!(Frame::decode(&old.finish()).unwrap(), Frame { gs_local: Vec::new(), g: None, ..full.clone() });
        let short = Frame { v: vec![1.0; d * k - 1], ..full.clone() };
        let err = Frame::decode(&short.encode()).unwrap_err();
        assert!(err.contains("step 12") && err.contains("D = 4"), "{err}");
    }

    /// R_n encoded straight from the matrix is the message of its packed triangle (the format
    /// of every stored run), reads back bit for bit, and leaves the lower part out.
    #[test]
    fn r_is_encoded_from_its_upper_triangle() {
        let k = 5;
        let r = faer::Mat::from_fn(k, k, |i, j| if i <= j { (1 + i + 7 * j) as f64 / 3.0 } else { f64::NAN });
        let bytes = super::encode_r(9, &r);
        let packed = crate::linalg::pack_upper(r.as_ref());
        assert_eq!(bytes, crate::store::schema::R.encoder(0).u64("step", 9).u64("k", k as u64).f64s("r", &packed).finish());
        let (step, back) = super::decode_r(&bytes).unwrap();
        assert_eq!(step, 9);
        for j in 0..k {
            for i in 0..=j {
                assert_eq!(back[(i, j)].to_bits(), r[(i, j)].to_bits());
            }
        }
    }
}
