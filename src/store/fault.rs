//! Injectable faults, so that tests can prove what a full disk or a crash does to a run.
//!
//! With `CLV_FAULT_DISK_FULL_AFTER=BYTES` in the environment, every file the store writes
//! through [`Output`] counts against one budget for the process, and writes beyond it fail
//! with ENOSPC exactly as a full file system would. Without the variable this is a plain file.
//!
//! With `CLV_FAULT_CRASH_AT=POINT` (or `POINT#N`, the N-th time it is reached), the process
//! exits on the spot at that [`crash_point`], with status [`CRASH_STATUS`], running no
//! destructor and flushing no buffer: what is on disk then is what a SIGKILL or a power cut
//! between two steps of the store's protocol leaves. Random kills rarely land in the short
//! windows between those steps; the crash points name every one of them.
//!
//! `CLV_FAULT_DISK_FREE=BYTES` fakes the free space of every file system,
//! `CLV_FAULT_MEMORY_AVAILABLE=BYTES` the memory the machine offers, and
//! `CLV_FAULT_NO_LOCKS` a file system that cannot lock files.

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

/// How many of `len` bytes fit in what is left of the injected budget (all without one):
/// as a real file system does, a write that does not fit is short, and the next one fails.
fn room_for(len: usize) -> io::Result<usize> {
    let Some(limit) = budget() else { return Ok(len) };
    let taken = WRITTEN.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |w| Some(w.saturating_add(len as u64).min(limit.max(w)))).unwrap_or(0);
    match limit.saturating_sub(taken).min(len as u64) as usize {
        0 if len > 0 => Err(io::Error::from_raw_os_error(28)), // ENOSPC
        room => Ok(room),
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let room = room_for(buf.len())?;
        self.0.write(&buf[..room])
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

/// With `CLV_FAULT_DISK_FREE=BYTES`, the free space the store reports for any file system
/// (so that tests can see the warning a too-small disk gets without filling one).
pub fn fake_free_bytes() -> Option<u64> {
    std::env::var("CLV_FAULT_DISK_FREE").ok().and_then(|v| v.parse().ok())
}

/// With `CLV_FAULT_MEMORY_AVAILABLE=BYTES`, the memory [`crate::machine::available_memory`]
/// reports (so that tests can see a run refused for memory without exhausting it).
pub fn fake_available_memory() -> Option<u64> {
    std::env::var("CLV_FAULT_MEMORY_AVAILABLE").ok().and_then(|v| v.parse().ok())
}

/// With `CLV_FAULT_NO_LOCKS=1`, locking a file fails as on a file system without locks
/// (ENOLCK; Lustre mounted without flock, NFS without a lock manager).
pub fn locks_unsupported() -> bool {
    std::env::var_os("CLV_FAULT_NO_LOCKS").is_some()
}

/// Every point between two durable steps of the store, in the order a run meets them.
pub const CRASH_POINTS: &[&str] = &[
    // write_atomic (run.json, spectrum.json, backward.json, clv_spectrum.json)
    "atomic-synced",
    "atomic-renamed",
    // a run segment: finished and synced, renamed, older segments pruned
    "segment-synced",
    "segment-renamed",
    "segment-pruned",
    // the forward stage: every segment written, spectrum.json not yet
    "forward-done",
    // a frame file: a segment's frames synced, the file finished, renamed
    "frames-synced",
    "frames-finished",
    "frames-renamed",
    // resuming a frame file: the interrupted file moved aside, its frames copied
    "salvage-moved",
    "salvage-copied",
    // an extension: one of the shorter run's results moved into previous-S-steps/
    "result-moved",
    // a repair whose steps did not arrive at the next segment: the segments from there on
    // set aside, its own recomputed ones not yet moved into the run
    "repair-set-aside",
];

/// The exit status of a process stopped at a crash point.
pub const CRASH_STATUS: i32 = 86;

/// The crash point and count `CLV_FAULT_CRASH_AT` asks for.
fn crash_target() -> Option<&'static (String, u64)> {
    static TARGET: OnceLock<Option<(String, u64)>> = OnceLock::new();
    TARGET
        .get_or_init(|| {
            let v = std::env::var("CLV_FAULT_CRASH_AT").ok()?;
            let target = parse_target(&v);
            if target.is_none() {
                crate::note!("clv: CLV_FAULT_CRASH_AT={v:?} is not POINT or POINT#N (N >= 1) with a POINT of {CRASH_POINTS:?}; ignored");
            }
            target
        })
        .as_ref()
}

/// `POINT` or `POINT#N` (N >= 1): the point and the occurrence to stop at.
fn parse_target(v: &str) -> Option<(String, u64)> {
    let (name, n) = v.split_once('#').map_or(Some((v, 1)), |(a, b)| b.parse().ok().map(|n| (a, n)))?;
    CRASH_POINTS.contains(&name).then_some(()).filter(|_| n >= 1).map(|_| (name.to_string(), n))
}

static REACHED: AtomicU64 = AtomicU64::new(0);

/// Exit here if `CLV_FAULT_CRASH_AT` names this point (see the module doc).
pub fn crash_point(name: &'static str) {
    debug_assert!(CRASH_POINTS.contains(&name), "unlisted crash point {name}");
    if let Some((target, n)) = crash_target()
        && target == name
        && REACHED.fetch_add(1, Ordering::SeqCst) + 1 == *n {
            crate::note!("clv: crash point {name} reached (CLV_FAULT_CRASH_AT)");
            std::process::exit(CRASH_STATUS);
        }
}

#[cfg(test)]
mod tests {
    use super::parse_target;

    #[test]
    fn crash_targets_name_a_listed_point_and_an_occurrence() {
        assert_eq!(parse_target("frames-synced"), Some(("frames-synced".into(), 1)));
        assert_eq!(parse_target("segment-renamed#3"), Some(("segment-renamed".into(), 3)));
        assert_eq!(parse_target("segment-renamed#0"), None);
        assert_eq!(parse_target("segment-renamed#"), None);
        assert_eq!(parse_target("no-such-point"), None);
    }
}
