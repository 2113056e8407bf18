//! Experiment (not part of the tool): how to share two cores between the backward stage's
//! recomputation (a QR per step) and its sweep (R^-1 C and V = G C).
//!
//! Measured on the 2-core CI-like machine (2026-11-24), ms per QR at D = 792 as throughput:
//! one QR on 2 threads 12.7, on 1 thread 23.4, two 1-thread QRs side by side 11.9; a
//! 1-thread QR beside the sweep 24.2 (the sweep 9.4, as alone). So, with the blocks in
//! cache, the sweep does not slow the QR, and a QR on two threads does 94-98 % of the work
//! of two on one. A backward stage with two recomputation workers (one QR each, the second
//! taking the core the sweep leaves idle) was built on this and measured against the stage
//! with one worker (its QR on two threads while the sweep waits): over a 1030-step run,
//! 22.4 / 21.9 / 20.9 s against 21.3 / 21.7 / 21.4 s (V every frame, alternating), and it
//! kept a third segment in memory (backward peak RSS 148 -> 207-228 MB in `clv bench`). It
//! was not kept.
//!
//! Where the rest goes (instrumented, not kept): inside the backward stage the two slow
//! each other through the shared cache and memory, where this example's blocks stay in
//! cache. A one-thread recomputed step took 25.5-26 ms while the sweep waited and 27.5-28
//! ms beside it, against 24.2 ms for a forward step alone, and the sweep 10.5 ms against
//! 9.0 alone. That is 37.5 thread-ms a step, 18.8 ms on two cores, or 1.30 forward steps
//! (14.4 ms). `clv bench` prints the bound from the work measured alone: 16.6 ms, 1.15.
//! Measured, a step takes 20.4 ms (1.41). The rest is the schedule: the recomputation's
//! two-thread phase is 15.5 ms a step, with its copies into the segment.
//!
//! cargo run --release --example backward_balance [-- SECONDS]
use clv::linalg::{ginelli_step, mul_upper, Qr};
use clv::rng::Rng;
use clv::system::Tangent;
use faer::{Mat, Par};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

const D: usize = 792;

fn block(seed: u64) -> Tangent {
    let mut rng = Rng::new(seed);
    let mut g = Tangent::zeros(D, D);
    g.rows_mut().iter_mut().for_each(|x| *x = rng.normal());
    g
}

/// Runs `qr_workers` (threads each) and `sweeps` sweep threads for `secs`: (ms per QR, ms per sweep step).
fn run(qr_workers: &[usize], sweeps: usize, secs: f64) -> (f64, f64) {
    let stop = Arc::new(AtomicBool::new(false));
    let qrs = Arc::new(AtomicU64::new(0));
    let sw = Arc::new(AtomicU64::new(0));
    let mut handles = vec![];
    for (w, &threads) in qr_workers.iter().enumerate() {
        let (stop, qrs) = (stop.clone(), qrs.clone());
        handles.push(std::thread::spawn(move || {
            let src = block(w as u64 + 1);
            let mut qr = Qr::new(D, D, threads);
            let mut r = Mat::zeros(D, D);
            let mut g = src.clone();
            while !stop.load(Ordering::Relaxed) {
                g.rows_mut().copy_from_slice(src.rows());
                qr.factor(&mut g, &mut r);
                qrs.fetch_add(1, Ordering::Relaxed);
            }
        }));
    }
    for s in 0..sweeps {
        let (stop, sw) = (stop.clone(), sw.clone());
        handles.push(std::thread::spawn(move || {
            let mut rng = Rng::new(100 + s as u64);
            let r = Mat::from_fn(D, D, |i, j| if i < j { rng.normal() * 0.01 } else if i == j { 1.0 + rng.uniform() } else { 0.0 });
            let g = Mat::from_fn(D, D, |_, _| rng.normal());
            let mut c = Mat::<f64>::identity(D, D);
            let mut v = Mat::<f64>::zeros(D, D);
            let mut norms = vec![0.0; D];
            while !stop.load(Ordering::Relaxed) {
                ginelli_step(r.as_ref(), c.as_mut(), &mut norms, Par::Seq);
                mul_upper(v.as_mut(), g.as_ref(), c.as_ref(), Par::Seq);
                sw.fetch_add(1, Ordering::Relaxed);
            }
        }));
    }
    let t = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(secs));
    let (q0, s0) = (qrs.load(Ordering::Relaxed), sw.load(Ordering::Relaxed));
    std::thread::sleep(Duration::from_secs_f64(secs));
    let el = t.elapsed().as_secs_f64() - secs;
    let (q1, s1) = (qrs.load(Ordering::Relaxed), sw.load(Ordering::Relaxed));
    stop.store(true, Ordering::Relaxed);
    handles.into_iter().for_each(|h| h.join().unwrap());
    let per = |n: u64| if n == 0 { f64::NAN } else { el * 1e3 / n as f64 };
    (per(q1 - q0), per(s1 - s0))
}

fn main() {
    let secs: f64 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(3.0);
    for _ in 0..2 {
        for (name, q, s) in [
            ("one QR, 2 threads", vec![2], 0),
            ("one QR, 1 thread", vec![1], 0),
            ("sweep alone", vec![], 1),
            ("two QRs, 1 thread each", vec![1, 1], 0),
            ("QR 1 thread + sweep", vec![1], 1),
            ("two QRs 1 thread + sweep", vec![1, 1], 1),
        ] {
            let (qms, sms) = run(&q, s, secs);
            println!("{name:28} ms per QR (throughput) {qms:7.2}   ms per sweep step {sms:7.2}");
        }
    }
}
