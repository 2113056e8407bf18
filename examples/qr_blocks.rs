//! Experiment (not part of the tool): the QR step at D = 792 on 1 and 2 threads, measured side
//! by side: gemm (the floor), faer's own blocked QR with Q formed by orgqr-style block
//! application (the forward stage's kernel until clv-numerics/3), and clv's driver
//! (linalg::Qr: lookahead and column chunks) for several panel widths.
//!
//! cargo run --release --example qr_blocks [-- D]
use clv::linalg::Qr;
use clv::rng::Rng;
use clv::system::Tangent;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::qr::no_pivoting::factor;
use faer::{Conj, Mat, Par};
use std::time::Instant;

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// faer's blocked QR (block `bs`, parallelism `pf`) and orgqr-style Q (parallelism `pq`).
fn faer_qr(a: &Mat<f64>, bs: usize, pf: Par, pq: Par) -> f64 {
    let (d, k) = a.shape();
    let mut a = a.clone();
    let mut h = Mat::zeros(bs, k);
    let mut q = Mat::<f64>::zeros(d, k);
    let req = StackReq::any_of(&[
        factor::qr_in_place_scratch::<f64>(d, k, bs, pf, Default::default()),
        householder::apply_block_householder_on_the_left_in_place_scratch::<f64>(d, bs, k),
    ]);
    let mut mem = MemBuffer::new(req);
    let s = Instant::now();
    factor::qr_in_place(a.as_mut(), h.as_mut(), pf, MemStack::new(&mut mem), Default::default());
    for j in 0..k {
        q[(j, j)] = 1.0;
    }
    let mut end = k;
    while end > 0 {
        let start = (end - 1) / bs * bs;
        householder::apply_block_householder_on_the_left_in_place_with_conj(
            a.as_ref().get(start.., start..end),
            h.as_ref().get(..end - start, start..end),
            Conj::No,
            q.as_mut().get_mut(start.., start..k),
            pq,
            MemStack::new(&mut mem),
        );
        end = start;
    }
    s.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let d: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(792);
    let reps = 9;
    let mut rng = Rng::new(1);
    let mut t = Tangent::zeros(d, d);
    t.rows_mut().iter_mut().for_each(|x| *x = rng.normal());
    let a = Mat::from_fn(d, d, |i, j| t.get(i, j));
    let mut r = Mat::zeros(d, d);
    for threads in [1usize, 2] {
        let par = if threads == 1 { Par::Seq } else { Par::rayon(threads) };
        let mut c = Mat::<f64>::zeros(d, d);
        let gemm = median((0..reps).map(|_| {
            let s = Instant::now();
            faer::linalg::matmul::matmul(c.as_mut(), faer::Accum::Replace, a.as_ref(), a.as_ref(), 1.0, par);
            2.0 * (d as f64).powi(3) / s.elapsed().as_secs_f64() / 1e9
        }).collect());
        let floor = 8.0 / 3.0 * (d as f64).powi(3) / (gemm * 1e9) * 1e3;
        println!("{threads} thread(s): gemm {gemm:.1} GFLOP/s, floor {floor:.1} ms");
        for (bs, pf) in [(16, Par::Seq), (48, Par::Seq), (48, par)] {
            let ms = median((0..reps).map(|_| faer_qr(&a, bs, pf, par)).collect());
            println!("  faer block {bs:>3}, factor {:>3}: {ms:6.1} ms = {:.2} floor", if pf == Par::Seq { "seq" } else { "par" }, ms / floor);
        }
        for nb in [16, 24, 32, 48, 64] {
            let mut qr = Qr::with_panel(d, d, nb, threads);
            let ms = median((0..reps).map(|_| {
                let mut g = t.clone();
                let s = Instant::now();
                qr.factor(&mut g, &mut r);
                s.elapsed().as_secs_f64() * 1e3
            }).collect());
            println!("  clv panel {nb:>3}:               {ms:6.1} ms = {:.2} floor", ms / floor);
        }
    }
}
