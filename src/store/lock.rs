//! Exclusive write locks between clv processes: one for a run directory, one for a frame
//! file, one for a report directory.
//!
//! Why: two clv processes writing the same thing at once (two sweeps given the same --out,
//! two forward passes started into one new directory, two analyses into one report) would
//! interleave their files and leave a result that is neither's. A check that a file exists
//! cannot prevent that: both processes find it missing before either creates it. So the
//! writer takes an OS file lock (flock) on a small lock file before it writes or removes
//! anything, and holds it until it is done; the kernel releases it when the process ends,
//! however it ends, so a crash never leaves a stale lock behind.
//!
//! A lock file that is removed when its writer is done (one beside a frame file) is checked
//! after locking to still be the file at its path: a process that opened it just before the
//! holder removed it would otherwise hold a lock on a file nobody else can find.
//!
//! Cluster file systems may have no locks (Lustre without flock, NFS without a lock
//! manager): there the writer warns and works without that protection.

use crate::error::{Error, Result};
use std::fs;
use std::path::{Path, PathBuf};

/// Exclusive right to write something, held while a stage writes it; released (and its
/// lock file removed, if asked) when dropped.
pub struct WriteLock {
    file: Option<fs::File>,
    path: PathBuf,
    remove_when_done: bool,
}

impl WriteLock {
    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for WriteLock {
    fn drop(&mut self) {
        // Removed while still locked, so that no other process can lock it in between.
        if self.remove_when_done {
            let _ = fs::remove_file(&self.path);
        }
        drop(self.file.take());
    }
}

/// Take the lock in the file `lock` (created, and its directory, if missing) for writing
/// `writing` in the `what` ("forward pass", ...), or say who holds it. `open_error` explains
/// a lock file that cannot be opened. With `remove_when_done`, the lock file is removed
/// when the lock is dropped.
pub fn take(lock: &Path, writing: &Path, what: &str, remove_when_done: bool, open_error: impl Fn(std::io::Error) -> Error) -> Result<WriteLock> {
    // A few tries: each one lost only to a holder that removed the file just then.
    for _ in 0..100 {
        if let Some(dir) = lock.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(dir).map_err(&open_error)?;
        }
        let file = match fs::OpenOptions::new().create(true).truncate(false).write(true).open(lock) {
            Ok(file) => file,
            // Its directory was removed by a holder that had made it (an empty report).
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(e) => return Err(open_error(e)),
        };
        let locked = if super::fault::locks_unsupported() { Err(fs::TryLockError::Error(std::io::Error::from_raw_os_error(libc::ENOLCK))) } else { file.try_lock() };
        match locked {
            Ok(()) if is_at(&file, lock) => return Ok(WriteLock { file: Some(file), path: lock.to_path_buf(), remove_when_done }),
            Ok(()) => continue,
            Err(fs::TryLockError::WouldBlock) => return Err(refusal(lock, writing, what)),
            Err(fs::TryLockError::Error(e)) if matches!(e.raw_os_error(), Some(libc::ENOLCK | libc::EOPNOTSUPP | libc::ENOSYS)) => {
                crate::note!(
                    "clv: warning: the file system of {} cannot lock files ({e}), so clv cannot refuse a second process writing it; make sure only one runs the {what}",
                    writing.display()
                );
                return Ok(WriteLock { file: Some(file), path: lock.to_path_buf(), remove_when_done });
            }
            Err(fs::TryLockError::Error(e)) => return Err(Error::io(lock, e)),
        }
    }
    Err(Error::Other(format!(
        "could not lock {} for the {what}: it was replaced again and again while clv tried; is another clv process writing {}? Wait for it to finish, then try again",
        lock.display(),
        writing.display()
    )))
}

/// Whether a process holds the lock in the file `lock` now. Asks without taking it or
/// creating the file; false where the file system cannot lock.
pub fn is_held(lock: &Path) -> bool {
    let Ok(file) = fs::File::open(lock) else { return false };
    matches!(file.try_lock_shared(), Err(fs::TryLockError::WouldBlock))
}

/// Refuse with [`take`]'s message if a process holds the lock in `lock` now: for a check
/// that would otherwise give another reason (a directory not empty because that process is
/// filling it).
pub fn refuse_if_held(lock: &Path, writing: &Path, what: &str) -> Result<()> {
    if is_held(lock) { Err(refusal(lock, writing, what)) } else { Ok(()) }
}

fn refusal(lock: &Path, writing: &Path, what: &str) -> Error {
    Error::Other(format!(
        "another clv process is writing {} (it holds {}); wait for it to finish or stop it before the {what}",
        writing.display(),
        lock.display()
    ))
}

/// Whether the open `file` is still the file at `path` (not removed or replaced since it
/// was opened).
#[cfg(unix)]
fn is_at(file: &fs::File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn is_at(_: &fs::File, path: &Path) -> bool {
    path.exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("clv-lock-test-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn a_second_lock_is_refused_naming_the_thing_and_its_lock_file() {
        let dir = scratch("second");
        let lock = dir.join("x.lock");
        let first = take(&lock, &dir.join("x"), "test", false, |e| Error::io(&lock, e)).unwrap();
        let Err(e) = take(&lock, &dir.join("x"), "test", false, |e| Error::io(&lock, e)) else { panic!("a second lock was granted") };
        let msg = e.to_string();
        assert!(msg.contains("another clv process is writing") && msg.contains(&dir.join("x").display().to_string()) && msg.contains("x.lock"), "{msg}");
        drop(first);
        assert!(lock.exists(), "a kept lock file was removed");
        drop(take(&lock, &dir.join("x"), "test", false, |e| Error::io(&lock, e)).unwrap());
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_removed_lock_file_goes_when_done_and_a_stale_handle_does_not_count() {
        let dir = scratch("removed");
        let lock = dir.join("y.lock");
        let first = take(&lock, &dir.join("y"), "test", true, |e| Error::io(&lock, e)).unwrap();
        // Opened before the holder removes it: locking it afterwards must not pass for the lock.
        let stale = fs::File::open(&lock).unwrap();
        drop(first);
        assert!(!lock.exists(), "the lock file was left behind");
        stale.try_lock().unwrap();
        assert!(!is_at(&stale, &lock));
        let second = take(&lock, &dir.join("y"), "test", true, |e| Error::io(&lock, e)).unwrap();
        assert!(take(&lock, &dir.join("y"), "test", true, |e| Error::io(&lock, e)).is_err());
        assert!(is_held(&lock) && refuse_if_held(&lock, &dir.join("y"), "test").is_err());
        drop(second);
        assert!(!is_held(&lock) && refuse_if_held(&lock, &dir.join("y"), "test").is_ok());
        fs::remove_dir_all(&dir).unwrap();
    }
}
