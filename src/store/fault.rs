//! An injectable disk-full fault, so that tests can prove what a full disk does to a run.
//!
//! With `CLV_FAULT_DISK_FULL_AFTER=BYTES` in the environment, every file the store writes
//! through [`Output`] counts against one budget for the process, and writes beyond it fail
//! with ENOSPC exactly as a full file system would. Without the variable this is a plain file.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

fn budget() -> Option<u64> {
    static LIMIT: OnceLock<Option<u64>> = OnceLock::new();
    *LIMIT.get_or_init(|| std::env::var("CLV_FAULT_DISK_FULL_AFTER").ok().and_then(|v| v.parse().ok()))
}

static WRITTEN: AtomicU64 = AtomicU64::new(0);

/// A file the store writes to.
pub struct Output(pub File);

impl Output {
    pub fn into_inner(self) -> File {
        self.0
    }
}

/// Account for `len` bytes about to be written; ENOSPC once the injected budget is spent.
pub fn charge(len: usize) -> io::Result<()> {
    if let Some(limit) = budget()
        && WRITTEN.fetch_add(len as u64, Ordering::Relaxed) + len as u64 > limit {
            return Err(io::Error::from_raw_os_error(28)); // ENOSPC
        }
    Ok(())
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        charge(buf.len())?;
        self.0.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()
    }
}

impl Seek for Output {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.0.seek(pos)
    }
}
