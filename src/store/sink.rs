//! The writer thread of a run: receives encoded messages over a bounded channel, writes and
//! rotates segment files, and prunes segments the backward stage will not need.
//!
//! Why a thread: zstd compression and file I/O stay off the simulation thread, and the
//! bounded channel gives backpressure instead of an unbounded queue in memory.

use super::segment::SegmentWriter;
use super::run::RunDir;
use super::schema::{CHECKPOINT, RUN_SCHEMAS};
use crate::error::{Error, Result};
use crossbeam_channel::{bounded, Sender};
use std::fs;
use std::path::PathBuf;
use std::thread::JoinHandle;

/// When to close a segment and what to keep.
#[derive(Clone, Debug)]
pub struct Policy {
    pub segment_checkpoints: u64,
    pub segment_bytes: u64,
    /// The last step of the run; its checkpoint closes the last segment.
    pub total_steps: u64,
    /// Segments whose last checkpoint is before this step are prunable...
    pub prune_before: u64,
    /// ...except the newest `keep_segments` of them.
    pub keep_segments: u64,
}

/// The topic of the item that tells the writer to finish its segment (never written).
const FINISH: &str = "";

struct Item {
    topic: &'static str,
    step: u64,
    data: Vec<u8>,
}

pub struct Sink {
    tx: Option<Sender<Item>>,
    handle: Option<JoinHandle<Result<()>>>,
}

impl Sink {
    pub fn spawn(dir: PathBuf, run_json: String, policy: Policy) -> Result<Sink> {
        let (tx, rx) = bounded::<Item>(8);
        let handle = std::thread::Builder::new()
            .name("clv-writer".into())
            .spawn(move || -> Result<()> {
                let mut current: Option<SegmentWriter> = None;
                for item in rx {
                    if item.topic == FINISH {
                        if let Some(w) = current.take() {
                            w.finish()?;
                        }
                        continue;
                    }
                    if current.is_none() {
                        current = Some(SegmentWriter::create(&dir, item.step, &run_json, &RUN_SCHEMAS)?);
                    }
                    let w = current.as_mut().expect("just created");
                    w.write(item.topic, item.step, &item.data)?;
                    let full = w.checkpoints >= policy.segment_checkpoints || w.bytes >= policy.segment_bytes;
                    if item.topic == CHECKPOINT.topic && (full || item.step == policy.total_steps) {
                        current.take().expect("open").finish()?;
                        prune(&dir, policy.prune_before, policy.keep_segments)?;
                    }
                }
                Ok(())
            })
            .map_err(|e| Error::Other(format!("cannot start the writer thread: {e}")))?;
        Ok(Sink { tx: Some(tx), handle: Some(handle) })
    }

    /// Queue a message; if the writer has failed, its error is returned here.
    pub fn send(&mut self, topic: &'static str, step: u64, data: Vec<u8>) -> Result<()> {
        let tx = self.tx.as_ref().expect("sink open");
        if tx.send(Item { topic, step, data }).is_err() {
            self.tx = None;
            return Err(self.join().err().unwrap_or_else(|| Error::Other("the writer thread stopped".into())));
        }
        Ok(())
    }

    /// Finish the open segment early (the last message sent must be a checkpoint), then
    /// [`Sink::close`]: a run stopped between its planned segment ends keeps every step.
    pub fn close_at_checkpoint(mut self) -> Result<()> {
        self.send(FINISH, 0, Vec::new())?;
        self.close()
    }

    /// Wait until everything queued is written.
    pub fn close(mut self) -> Result<()> {
        self.tx = None;
        self.join()
    }

    fn join(&mut self) -> Result<()> {
        match self.handle.take() {
            Some(h) => h.join().map_err(|_| Error::Other("the writer thread panicked".into()))?,
            None => Ok(()),
        }
    }
}

impl Drop for Sink {
    fn drop(&mut self) {
        self.tx = None;
        let _ = self.join();
    }
}

/// Delete the segments whose last checkpoint is before `prune_before` except the newest
/// `keep` of them (the backward stage starts at or after `prune_before`); returns their paths.
pub fn prune(dir: &std::path::Path, prune_before: u64, keep: u64) -> Result<Vec<PathBuf>> {
    let run = RunDir { path: dir.to_path_buf() };
    let prunable: Vec<_> = run.segments()?.into_iter().filter(|s| s.last < prune_before).collect();
    let excess = prunable.len().saturating_sub(keep as usize);
    let mut pruned = Vec::with_capacity(excess);
    for s in &prunable[..excess] {
        fs::remove_file(&s.path).map_err(|e| Error::io(&s.path, e))?;
        super::fault::crash_point("segment-pruned");
        pruned.push(s.path.clone());
    }
    Ok(pruned)
}
