//! A fixed crew of worker threads for one kernel that runs many times (the QR step).
//!
//! The QR workers wait on each other (a worker needs the panel another one factors), which
//! is only safe if all of them really run at once. Rayon's tasks may run one after another
//! on a busy pool, so the crew owns its threads: helpers sleep on a channel between calls.

use crossbeam_channel::{Receiver, Sender};
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::thread::JoinHandle;

type Work = dyn Fn(usize) + Sync;

/// A pointer to the caller's work, valid until [`Crew::run_on`] returns (it waits for every
/// helper to finish with it before returning).
struct Task(*const Work);
unsafe impl Send for Task {}

pub struct Crew {
    senders: Vec<Sender<Task>>,
    done: Receiver<std::thread::Result<()>>,
    handles: Vec<JoinHandle<()>>,
}

impl Crew {
    /// A crew of `workers` (the calling thread is worker 0, so `workers - 1` helper threads).
    pub fn new(workers: usize) -> std::io::Result<Self> {
        let (done_tx, done) = crossbeam_channel::unbounded();
        let mut senders = Vec::new();
        let mut handles = Vec::new();
        for id in 1..workers.max(1) {
            let (tx, rx) = crossbeam_channel::bounded::<Task>(1);
            let done_tx = done_tx.clone();
            handles.push(std::thread::Builder::new().name(format!("clv-qr-{id}")).spawn(move || {
                for Task(work) in rx {
                    // Safety: `run` keeps the work alive until this send.
                    let result = catch_unwind(AssertUnwindSafe(|| unsafe { (*work)(id) }));
                    if done_tx.send(result).is_err() {
                        return;
                    }
                }
            })?);
            senders.push(tx);
        }
        Ok(Crew { senders, done, handles })
    }

    pub fn workers(&self) -> usize {
        self.senders.len() + 1
    }

    /// Run `work(worker)` at once on the first `workers` workers (at least the calling
    /// thread; the others keep sleeping, so a caller can give cores back while something
    /// else needs them) and return when all are done. A panic in any worker is re-raised
    /// here, after all have stopped.
    pub fn run_on(&self, workers: usize, work: &(dyn Fn(usize) + Sync)) {
        // Safety: the lifetime is erased only until every helper has reported back below.
        let ptr: *const Work = unsafe { std::mem::transmute::<*const (dyn Fn(usize) + Sync + '_), *const Work>(work) };
        let mut sent = 0;
        for s in self.senders.iter().take(workers.saturating_sub(1)) {
            if s.send(Task(ptr)).is_ok() {
                sent += 1;
            }
        }
        let mine = catch_unwind(AssertUnwindSafe(|| work(0)));
        let mut panic = mine.err();
        for _ in 0..sent {
            match self.done.recv() {
                Ok(Err(p)) => panic = panic.or(Some(p)),
                Ok(Ok(())) => {}
                Err(_) => break,
            }
        }
        if let Some(p) = panic {
            resume_unwind(p);
        }
    }
}

impl Drop for Crew {
    fn drop(&mut self) {
        self.senders.clear();
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Every worker runs, at once: each waits until all have started.
    #[test]
    fn workers_run_concurrently() {
        let crew = Crew::new(3).unwrap();
        for _ in 0..50 {
            let started = AtomicUsize::new(0);
            let seen = AtomicUsize::new(0);
            crew.run_on(crew.workers(), &|id| {
                seen.fetch_or(1 << id, Ordering::Relaxed);
                started.fetch_add(1, Ordering::SeqCst);
                while started.load(Ordering::SeqCst) < 3 {
                    std::thread::yield_now();
                }
            });
            assert_eq!(seen.load(Ordering::Relaxed), 0b111);
        }
    }

    /// run_on(n) runs workers 0..n and no other.
    #[test]
    fn run_on_uses_the_first_workers_only() {
        let crew = Crew::new(3).unwrap();
        for n in [1, 2, 3, 5] {
            let seen = AtomicUsize::new(0);
            crew.run_on(n, &|id| {
                seen.fetch_or(1 << id, Ordering::Relaxed);
            });
            assert_eq!(seen.load(Ordering::Relaxed), (1 << n.min(3)) - 1, "run_on({n})");
        }
    }

    #[test]
    fn a_panicking_worker_is_reported_after_all_stop() {
        let crew = Crew::new(2).unwrap();
        let finished = AtomicUsize::new(0);
        let r = catch_unwind(AssertUnwindSafe(|| {
            crew.run_on(crew.workers(), &|id| {
                if id == 1 {
                    panic!("worker 1 fails");
                }
                finished.fetch_add(1, Ordering::SeqCst);
            })
        }));
        assert!(r.is_err());
        assert_eq!(finished.load(Ordering::SeqCst), 1);
        // The crew is still usable.
        crew.run_on(crew.workers(), &|_| {
            finished.fetch_add(1, Ordering::SeqCst);
        });
        assert_eq!(finished.load(Ordering::SeqCst), 3);
    }
}
