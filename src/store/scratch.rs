//! Scratch buffers that may live on disk: the backward stage keeps a segment's Gram-Schmidt
//! bases (D k values per kept step, 5 MB each at D = k = 792) in one, and past its memory
//! budget they go to an unlinked file in the run directory, mapped with memmap2, so that a
//! machine with little RAM still runs the paper's system.

use crate::error::{Error, Result};
use std::path::Path;

/// A contiguous buffer of f64, on the heap or in an unlinked scratch file.
pub enum Storage {
    Heap(Vec<f64>),
    Mapped(memmap2::MmapMut),
}

impl Storage {
    /// `len` zeros: on the heap, or with `out_of_core` in an unlinked file in that directory.
    pub fn new(len: usize, out_of_core: Option<&Path>) -> Result<Self> {
        let Some(dir) = out_of_core else { return Ok(Storage::Heap(vec![0.0; len])) };
        static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = dir.join(format!(".scratch-{}-{n}", std::process::id()));
        let file = std::fs::OpenOptions::new().read(true).write(true).create_new(true).open(&path).map_err(|e| Error::io(&path, e))?;
        let result = file.set_len(8 * len as u64).and_then(|_| reserve(&file, 8 * len as u64)).map_err(|e| Error::io(&path, e)).and_then(|_| {
            // SAFETY: the file was just created by us and is unlinked below; nobody else maps it.
            unsafe { memmap2::MmapMut::map_mut(&file) }.map_err(|e| Error::io(&path, e))
        });
        let _ = std::fs::remove_file(&path);
        Ok(Storage::Mapped(result?))
    }

    pub fn slice(&self) -> &[f64] {
        match self {
            Storage::Heap(v) => v,
            // SAFETY: mappings are page-aligned (so aligned for f64) and hold 8 * len bytes.
            Storage::Mapped(m) => unsafe { std::slice::from_raw_parts(m.as_ptr() as *const f64, m.len() / 8) },
        }
    }

    pub fn slice_mut(&mut self) -> &mut [f64] {
        match self {
            Storage::Heap(v) => v,
            // SAFETY: as above, and we hold the only reference.
            Storage::Mapped(m) => unsafe { std::slice::from_raw_parts_mut(m.as_mut_ptr() as *mut f64, m.len() / 8) },
        }
    }
}

/// Give the file its blocks now: a sparse file would get them when the mapping is first
/// written, and a full disk then raises SIGBUS, which ends the process without a word.
/// Reserved up front, a full disk is an error here, met like any other (free space, then
/// resume). File systems that cannot reserve (NFSv3, older Lustre: EOPNOTSUPP) keep the
/// sparse file: fallocate(2) itself, not posix_fallocate(3), which would emulate it there by
/// writing every block.
#[cfg(not(target_os = "linux"))]
fn reserve(_: &std::fs::File, _: u64) -> std::io::Result<()> {
    Ok(())
}

#[cfg(target_os = "linux")]
fn reserve(file: &std::fs::File, bytes: u64) -> std::io::Result<()> {
    use std::os::fd::AsRawFd;
    let Ok(len) = libc::off_t::try_from(bytes) else { return Ok(()) };
    // SAFETY: fallocate(2) on an open descriptor of ours, mode 0 (allocate, extend size).
    if unsafe { libc::fallocate(file.as_raw_fd(), 0, 0, len) } == 0 {
        return Ok(());
    }
    let e = std::io::Error::last_os_error();
    match e.raw_os_error() {
        Some(libc::EOPNOTSUPP | libc::ENOSYS | libc::EINVAL) => Ok(()),
        _ => Err(e),
    }
}
