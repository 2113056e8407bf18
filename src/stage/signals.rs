//! What SIGTERM (a batch system's time limit, before its SIGKILL), SIGINT (Ctrl-C), SIGHUP
//! (the terminal of a job started without nohup gone, as when an ssh session drops),
//! SIGUSR1 and SIGUSR2 (the warning batch systems send ahead of a time limit when asked, as
//! SLURM's `--signal=USR1@120`) and SIGXCPU (a soft CPU-time limit reached, the warning of
//! SGE, PBS and LSF before the hard one) do; by default the last three would kill the
//! process without a checkpoint.
//!
//! The forward stage stops cleanly after the step it is in ([`StopOnSignals`]): it writes a
//! checkpoint there, so that `--resume` loses nothing. The backward stage and the analyses
//! keep their work in files that are only ever renamed into place, so being killed loses at
//! most the segment in hand; there a signal ends the process at once, as by default, but
//! first says what was kept and how to continue ([`ExplainOnSignals`]). The warnings
//! (SIGUSR1, SIGUSR2, SIGXCPU) they ignore: ending at once would only lose the work until
//! the SIGTERM or SIGKILL that follows.
//!
//! A signal the process was started to ignore (SIGINT of a shell's background job) stays
//! ignored under both.

use std::sync::atomic::{AtomicI32, AtomicPtr, AtomicUsize, Ordering};

const SIGNALS: [libc::c_int; 6] = [libc::SIGTERM, libc::SIGINT, libc::SIGHUP, libc::SIGUSR1, libc::SIGUSR2, libc::SIGXCPU];

/// The signals of [`SIGNALS`] that warn of an end to come rather than ask for one now.
fn is_warning(sig: libc::c_int) -> bool {
    matches!(sig, libc::SIGUSR1 | libc::SIGUSR2 | libc::SIGXCPU)
}

/// The signal that asked for a stop; 0 for none.
static STOP: AtomicI32 = AtomicI32::new(0);

/// [`StopOnSignals`] guards alive: a stop asked for under an outer one is kept for the
/// inner ones (a resume's repair, then its continuation).
static GUARDS: AtomicUsize = AtomicUsize::new(0);

extern "C" fn request_stop(sig: libc::c_int) {
    STOP.store(sig, Ordering::SeqCst);
}

/// The message [`explain_and_exit`] writes: leaked, so that the handler only ever reads
/// memory that stays valid, and swapped in one store.
static MESSAGE: AtomicPtr<Vec<u8>> = AtomicPtr::new(std::ptr::null_mut());

extern "C" fn explain_and_exit(sig: libc::c_int) {
    let message = MESSAGE.load(Ordering::SeqCst);
    // SAFETY: write(2) and _exit(2) are async-signal-safe; `message` is null or a leaked,
    // never modified Vec.
    unsafe {
        if let Some(text) = message.as_ref() {
            libc::write(libc::STDERR_FILENO, text.as_ptr() as *const libc::c_void, text.len());
        }
        libc::_exit(128 + sig);
    }
}

/// Handlers in place while the guard lives; dropping it puts back what was there before.
struct Installed {
    before: [libc::sighandler_t; SIGNALS.len()],
}

impl Installed {
    /// `handler` for every signal, or for all but the warnings, which are then ignored.
    fn new(handler: extern "C" fn(libc::c_int), warnings_too: bool) -> Self {
        // SAFETY: both handlers above are async-signal-safe.
        let before = SIGNALS.map(|sig| unsafe {
            let disposition = if warnings_too || !is_warning(sig) { handler as *const () as libc::sighandler_t } else { libc::SIG_IGN };
            let before = libc::signal(sig, disposition);
            if before == libc::SIG_IGN {
                libc::signal(sig, libc::SIG_IGN);
            }
            before
        });
        Installed { before }
    }
}

impl Drop for Installed {
    fn drop(&mut self) {
        for (sig, handler) in SIGNALS.into_iter().zip(self.before) {
            // SAFETY: puts back the disposition signal(2) returned at install.
            unsafe { libc::signal(sig, handler) };
        }
    }
}

/// While this lives, the signals above only ask for a stop, which the loop polls with
/// [`StopOnSignals::requested`] (the signal's number, once one came). Guards nest: a stop
/// asked for while an outer one lives is seen by the inner ones.
pub struct StopOnSignals {
    _handlers: Installed,
}

impl StopOnSignals {
    pub fn install() -> Self {
        if GUARDS.fetch_add(1, Ordering::SeqCst) == 0 {
            STOP.store(0, Ordering::SeqCst);
        }
        StopOnSignals { _handlers: Installed::new(request_stop, true) }
    }

    pub fn requested(&self) -> Option<i32> {
        Some(STOP.load(Ordering::SeqCst)).filter(|&sig| sig != 0)
    }
}

impl Drop for StopOnSignals {
    fn drop(&mut self) {
        GUARDS.fetch_sub(1, Ordering::SeqCst);
    }
}

/// While this lives, the signals above but the warnings end the process with `message` on
/// standard error and the exit status of death by that signal (128 + its number, as a shell
/// reports it); the warnings are ignored.
pub struct ExplainOnSignals {
    _handlers: Installed,
}

impl ExplainOnSignals {
    pub fn install(message: &str) -> Self {
        let text = Box::leak(Box::new(format!("{message}\n").into_bytes()));
        MESSAGE.store(text, Ordering::SeqCst);
        ExplainOnSignals { _handlers: Installed::new(explain_and_exit, false) }
    }
}
