//! Reading a run's checkpoints back by step, for the backward stage's recomputation.
//!
//! The backward stage asks for checkpoints newest first, one segment at a time, and must
//! not read a whole multi-gigabyte segment for each: the checkpoint's chunk is found through
//! the file's chunk index and only it is decompressed and checked. Damage is never passed
//! on: a chunk that fails its checks is read again strictly, which names the damage and the
//! repair (`clv forward --resume`).

use super::records::{decode_r, Checkpoint};
use super::run::SegmentFile;
use super::schema::{CHECKPOINT, R};
use super::segment::{read_segment, ReadMode};
use crate::error::{Error, Result};
use crate::linalg::pack_upper;
use crate::stage::forward::ForwardState;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Reads checkpoints (and stored R) of a run by step. Only the last checkpoint read is kept
/// (the older end of one segment is the newer end of the next): memory stays at one
/// checkpoint whatever the layout of the files; re-reading a file costs far less than
/// recomputing its steps.
pub struct Checkpoints {
    segments: Vec<SegmentFile>,
    last: Option<Arc<ForwardState>>,
}

impl Checkpoints {
    /// A reader over the run's finished segments (oldest first, as [`super::run::RunDir::segments`] lists them).
    pub fn new(segments: Vec<SegmentFile>) -> Self {
        Checkpoints { segments, last: None }
    }

    /// The segment that holds the checkpoint of `step`.
    pub fn segment_of(&self, step: u64) -> Result<&SegmentFile> {
        self.segments.iter().find(|s| s.first <= step && step <= s.last).ok_or_else(|| {
            let dir = self.segments.first().and_then(|s| s.path.parent()).map_or("RUN_DIR".into(), |d| d.display().to_string());
            Error::Other(format!(
                "no segment holds the checkpoint at step {step}: the run directory is incomplete (a segment moved out or deleted; `clv inspect {dir}` names what is missing); \
                 `clv forward --resume {dir}` recomputes it with bit-identical numbers, then give this again"
            ))
        })
    }

    /// The forward state at the checkpoint of `step`.
    pub fn get(&mut self, step: u64) -> Result<Arc<ForwardState>> {
        if let Some(cp) = self.last.as_ref().filter(|cp| cp.step == step) {
            return Ok(cp.clone());
        }
        // The old one goes before the new one is read: one fewer G_n in memory at the peak.
        self.last = None;
        let SegmentFile { path: seg, first, last, .. } = self.segment_of(step)?.clone();
        let bytes = match indexed_checkpoint(&seg, step) {
            Some(bytes) => bytes,
            None => {
                // No usable index: read the whole file, every CRC checked.
                let mut found = None;
                read_segment(&seg, ReadMode::Strict, |m| {
                    if m.topic == CHECKPOINT.topic && m.step == step {
                        found = Some(m.data.to_vec());
                    }
                    Ok(())
                })
                .map_err(damaged)?;
                found.ok_or_else(|| damaged(Error::corrupt(&seg, format!("no checkpoint at step {step}, though its name says it holds steps {first}..{last}"))))?
            }
        };
        let cp = Checkpoint::decode(&bytes).map_err(|e| damaged(Error::corrupt(&seg, format!("step {step}: {e}"))))?.state;
        let cp = Arc::new(cp);
        self.last = Some(cp.clone());
        Ok(cp)
    }

    /// Stored R_n (packed) for n in (from, to].
    pub fn stored_r(&self, from: u64, to: u64) -> Result<BTreeMap<u64, Vec<f64>>> {
        let mut out = BTreeMap::new();
        for seg in self.segments.iter().filter(|s| s.last > from && s.first <= to) {
            read_segment(&seg.path, ReadMode::Strict, |m| {
                if m.topic == R.topic && m.step > from && m.step <= to {
                    let (_, r) = decode_r(m.data).map_err(|e| Error::corrupt(&seg.path, e))?;
                    out.insert(m.step, pack_upper(r.as_ref()));
                }
                Ok(())
            })
            .map_err(damaged)?;
        }
        Ok(out)
    }
}

/// A run segment that does not read back, with the way to repair it.
fn damaged(e: Error) -> Error {
    match e {
        Error::Corrupt { path, msg } => Error::Other(format!(
            "{}: corrupt or unreadable: {msg}; the forward stage sets it aside and recomputes what no intact segment holds, with bit-identical numbers: run `clv forward --resume {}`, then this again",
            path.display(),
            path.parent().map(|p| p.display().to_string()).unwrap_or_default()
        )),
        e => e,
    }
}

/// The checkpoint message at `step`, found through the file's chunk index so that only its
/// chunk is decompressed. None when the index is missing or unusable (the caller then reads
/// the file whole, which then names the damage). A damaged chunk cannot pass unnoticed: it
/// fails its CRC here, and a checkpoint altered with a valid CRC fails the recomputation's
/// bitwise check against the next one.
fn indexed_checkpoint(path: &Path, step: u64) -> Option<Vec<u8>> {
    // The index and chunk headers are checked below before anything is decompressed; a
    // panic of the mcap crate on damage they do not catch is the strict read's to report.
    std::panic::catch_unwind(|| indexed_checkpoint_unguarded(path, step)).ok().flatten()
}

fn indexed_checkpoint_unguarded(path: &Path, step: u64) -> Option<Vec<u8>> {
    let file = std::fs::File::open(path).ok()?;
    // SAFETY: finished segments are never modified (written under a temporary name, renamed).
    let map = unsafe { memmap2::Mmap::map(&file) }.ok()?;
    let summary = mcap::Summary::read(&map).ok()??;
    let channel = summary.channels.values().find(|c| c.topic == CHECKPOINT.topic)?.id;
    let limit = super::segment::record_limit(map.len() as u64);
    for index in summary.chunk_indexes.iter().filter(|c| c.message_start_time <= step && step <= c.message_end_time) {
        // The chunk is decompressed here, into at most its stated size, and its CRC checked
        // before a record in it is parsed: the mcap crate's chunk reader trusts the lengths
        // inside a chunk, and a damaged one would make it ask for impossible memory.
        let start = usize::try_from(index.chunk_start_offset).ok()?;
        let end = start.checked_add(usize::try_from(index.chunk_length).ok()?)?;
        let record = map.get(start.checked_add(9)?..end)?;
        let mcap::records::Record::Chunk { header, data } = mcap::parse_record(mcap::records::op::CHUNK, record).ok()? else { return None };
        if header.compression != "zstd" || header.uncompressed_size > limit {
            return None;
        }
        let raw = zstd::bulk::decompress(&data, usize::try_from(header.uncompressed_size).ok()?).ok()?;
        if raw.len() as u64 != header.uncompressed_size || crc32fast::hash(&raw) != header.uncompressed_crc {
            return None;
        }
        let mut rest = &raw[..];
        while let Some((&opcode, after)) = rest.split_first() {
            let len = usize::try_from(u64::from_le_bytes(after.get(..8)?.try_into().ok()?)).ok()?;
            let body = after.get(8..8usize.checked_add(len)?)?;
            rest = &after[8 + len..];
            // a message: channel id (u16), sequence (u32), log time (u64), publish time (u64), data
            if opcode == mcap::records::op::MESSAGE && body.len() >= 22 {
                let channel_id = u16::from_le_bytes(body[..2].try_into().ok()?);
                let log_time = u64::from_le_bytes(body[6..14].try_into().ok()?);
                if channel_id == channel && log_time == step {
                    return Some(body[22..].to_vec());
                }
            }
        }
    }
    None
}
