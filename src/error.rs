//! One error type for the whole tool.
//!
//! Every error says what was wrong, where (parameter, file, offset, step) and, where there is
//! one, what to do about it. Nothing here panics on user input.

use std::fmt;
use std::path::PathBuf;

#[derive(Debug)]
pub enum Error {
    /// A parameter the user gave (or a combination of them) is not acceptable.
    Param { name: &'static str, msg: String },
    /// An I/O operation on a named file failed.
    Io { path: PathBuf, source: std::io::Error },
    /// The dynamics cannot go on (diverged orbit, overlapping disks, stalled event loop).
    Dynamics(String),
    /// A file is damaged or not what it claims to be.
    Corrupt { path: PathBuf, msg: String },
    /// The forward stage stopped on `signal` (SIGTERM, SIGINT) after `step`, with everything
    /// up to it saved in the run directory `run`; `then` says how to continue. The process
    /// exits as a shell reports death by that signal (128 + signal).
    Stopped { step: u64, total: u64, run: PathBuf, signal: i32, then: String },
    /// The reader of a frame stream (`clv backward --out -`) closed it after `frames` frames,
    /// of which the progress record holds `recorded` (those of the finished segments): the
    /// sweep stopped unfinished. The process exits as a writer killed by SIGPIPE (141), so
    /// that a script does not take the sweep for done.
    ReaderClosed { frames: u64, recorded: u64 },
    /// The reader of standard output closed it before `what` (a clause: "the output was
    /// written whole"); `then` says what was saved all the same, and how to get the rest.
    /// Exits as a writer killed by SIGPIPE (141).
    OutputClosed { what: String, then: String },
    /// Anything else, already phrased for the user.
    Other(String),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn param(name: &'static str, msg: impl Into<String>) -> Self {
        Error::Param { name, msg: msg.into() }
    }
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
    pub fn corrupt(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Corrupt { path: path.into(), msg: msg.into() }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Param { name, msg } => write!(f, "invalid --{name}: {msg}"),
            Error::Io { path, source } if source.is_disk_full() => write!(f, "{}: {} ({source}); every file finished before it is intact: {}, then give the command again", path.display(), source.no_room(), source.remedy()),
            Error::Io { path, source } if source.kind() == std::io::ErrorKind::PermissionDenied => write!(
                f,
                "{}: {source}; check the permissions of the file and of its directory (ls -ld): clv reads what it is given and writes where its output goes",
                path.display()
            ),
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Dynamics(msg) => write!(f, "dynamics: {msg}"),
            Error::Corrupt { path, msg } => write!(f, "{}: corrupt or unreadable: {msg}", path.display()),
            Error::Stopped { step, total, run, then, .. } => write!(f, "stopped by a signal after step {step} of {total} of the forward pass; everything up to it is saved in {}: {then}", run.display()),
            Error::ReaderClosed { frames, recorded } => write!(
                f,
                "the reader closed the stream after {frames} frames, and the sweep stopped unfinished (no CLV spectrum written). \
                 To start over, give the same command again without --resume (and the reader's own again, e.g. `clv analyze - --overwrite`). {}",
                match (recorded, frames > recorded) {
                    (0, _) => "With --resume the sweep would stream the whole window again: it finished no segment.".to_string(),
                    (r, true) => format!("A reader that kept what it read can take the rest with --resume: the sweep finished the segments of its first {r} frames and streams from frame {} on, so frames {}..{frames}, which the reader had, come again.", r + 1, r + 1),
                    (r, false) => format!("A reader that kept what it read can take the rest with --resume: the sweep streams from frame {} on.", r + 1),
                }
            ),
            Error::OutputClosed { what, then } => write!(f, "the reader of standard output closed it before {what}; {then}"),
            Error::Other(msg) => f.write_str(msg),
        }
    }
}

/// No room for a write: a full disk (ENOSPC), a quota (EDQUOT) or a file-size limit (EFBIG,
/// `ulimit -f`). The same way out for all: make room, then continue.
trait DiskFull {
    fn is_disk_full(&self) -> bool;
    /// What ran out, for the message.
    fn no_room(&self) -> &'static str;
    fn remedy(&self) -> &'static str;
}

impl DiskFull for std::io::Error {
    fn is_disk_full(&self) -> bool {
        self.kind() == std::io::ErrorKind::StorageFull || matches!(self.raw_os_error(), Some(libc::ENOSPC | libc::EDQUOT | libc::EFBIG))
    }
    fn no_room(&self) -> &'static str {
        match self.raw_os_error() {
            Some(libc::EDQUOT) => "disk quota exceeded",
            Some(libc::EFBIG) => "file-size limit reached",
            _ => "disk full",
        }
    }
    fn remedy(&self) -> &'static str {
        match self.raw_os_error() {
            Some(libc::EDQUOT) => "free space within the quota (or have it raised)",
            Some(libc::EFBIG) => "raise the limit (`ulimit -f`, or the batch system's)",
            _ => "free space",
        }
    }
}

impl Error {
    /// No room for a write: a full disk, a quota or a file-size limit ([`DiskFull`]).
    pub fn is_disk_full(&self) -> bool {
        matches!(self, Error::Io { source, .. } if source.is_disk_full())
    }

    /// A full disk, said with how this command continues once there is space (`then`, e.g.
    /// "continue with `clv forward --resume RUN`"); any other error as it is.
    pub fn on_full_disk(self, then: impl FnOnce() -> String) -> Self {
        match self {
            Error::Io { path, source } if source.is_disk_full() => {
                Error::Other(format!("{}: {} ({source}); every file finished before it is intact: {}, then {}", path.display(), source.no_room(), source.remedy(), then()))
            }
            other => other,
        }
    }

    /// The process's exit status for this error: 128 + the signal for a stop on a signal
    /// (as for death by it, so that a batch system sees the same either way), else 1.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Stopped { signal, .. } => 128 + signal,
            Error::ReaderClosed { .. } | Error::OutputClosed { .. } => 128 + libc::SIGPIPE,
            _ => 1,
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A permission error says what to check.
    #[test]
    fn a_permission_error_says_what_to_check() {
        let e = Error::io("run/backward.tmp", std::io::Error::from(std::io::ErrorKind::PermissionDenied));
        assert!(e.to_string().starts_with("run/backward.tmp: permission denied; check the permissions of the file and of its directory"), "{e}");
    }

    /// A closed reader: how to start over, and what --resume would stream, in each case.
    #[test]
    fn a_closed_reader_says_what_resume_streams() {
        let say = |frames, recorded| Error::ReaderClosed { frames, recorded }.to_string();
        assert!(say(7, 0).ends_with("With --resume the sweep would stream the whole window again: it finished no segment."), "{}", say(7, 0));
        assert!(say(70, 50).ends_with("its first 50 frames and streams from frame 51 on, so frames 51..70, which the reader had, come again."), "{}", say(70, 50));
        assert!(say(50, 50).ends_with("the sweep streams from frame 51 on."), "{}", say(50, 50));
        assert!(say(50, 50).contains("To start over, give the same command again without --resume"));
    }
}
