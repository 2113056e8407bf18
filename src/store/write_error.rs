//! The OS error behind a failed write, kept where the write failed.
//!
//! Why: the MCAP writer hands some I/O errors on wrapped beyond recognition (a message
//! header's write comes back as a binrw error of kind Other, with no OS error number), and
//! what a failed write means for a run depends on knowing which it was: a full disk stops a
//! stage with the way to continue, a closed pipe ends a stream.

use crate::error::Error;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicI32, Ordering};

/// What the writers made by [`Witness::watch`] saw fail: the OS error number of the last
/// failed write, seek or flush.
#[derive(Clone, Default)]
pub struct Witness(Arc<AtomicI32>);

impl Witness {
    /// `inner`, writing as before, with its failures reported to this witness.
    pub fn watch<W>(&self, inner: W) -> Watched<W> {
        Watched { inner, witness: self.clone() }
    }

    /// The OS error a watched writer failed with, if one did.
    pub fn os_error(&self) -> Option<io::Error> {
        Some(self.0.load(Ordering::Relaxed)).filter(|&errno| errno != 0).map(io::Error::from_raw_os_error)
    }

    fn saw<T>(&self, result: io::Result<T>) -> io::Result<T> {
        if let Err(errno) = result.as_ref().map_err(io::Error::raw_os_error)
            && let Some(errno) = errno
        {
            self.0.store(errno, Ordering::Relaxed);
        }
        result
    }

    /// An MCAP writer's error as the store reports it, named with the file `path`: the OS
    /// error of the write beneath it when there was one, however the writer wrapped it.
    pub fn mcap_error(&self, path: &Path, e: mcap::McapError) -> Error {
        match (self.os_error(), e) {
            (Some(io), _) | (None, mcap::McapError::Io(io)) => Error::io(path, io),
            (None, other) => Error::Other(format!("{}: {other}", path.display())),
        }
    }
}

/// A writer whose failures a [`Witness`] keeps.
pub struct Watched<W> {
    inner: W,
    witness: Witness,
}

impl<W> Watched<W> {
    pub fn into_inner(self) -> W {
        self.inner
    }
}

impl<W: Write> Write for Watched<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.witness.saw(self.inner.write(buf))
    }
    fn flush(&mut self) -> io::Result<()> {
        self.witness.saw(self.inner.flush())
    }
}

impl<W: Seek> Seek for Watched<W> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.witness.saw(self.inner.seek(pos))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A write that fails under a message header comes back from the MCAP writer without
    /// its OS error; the witness still names it.
    #[test]
    fn a_wrapped_full_disk_is_still_a_full_disk() {
        struct Full;
        impl Write for Full {
            fn write(&mut self, _: &[u8]) -> io::Result<usize> {
                Err(io::Error::from_raw_os_error(libc::ENOSPC))
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let witness = Witness::default();
        assert!(witness.os_error().is_none());
        let wrapped = io::Error::other("a binrw error around it");
        assert!(witness.watch(Full).write_all(b"x").is_err());
        let e = witness.mcap_error(Path::new("seg.tmp"), mcap::McapError::Io(wrapped));
        assert!(matches!(&e, Error::Io { source, .. } if source.raw_os_error() == Some(libc::ENOSPC)), "{e}");
        assert!(e.to_string().contains("disk full"), "{e}");
    }
}
