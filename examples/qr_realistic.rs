//! Experiment (not part of the tool): subnormal numbers in the QR step.
//!
//! The QR of the forward stage's own tangent block (disks, N = 198, after a few steps) was
//! about 10 % slower than that of a random block, although neither holds a subnormal number
//! (nor does any result). Setting flush-to-zero / denormals-are-zero removed the difference
//! and left every bit unchanged: faer's Euclidean norm squares every entry scaled by
//! sqrt(2.2e-308) into an accumulator it then discards (src/linalg/subnormals.rs).
//! linalg::Qr now flushes them (linalg::FlushSubnormals); this compares faer's sequential
//! blocked QR (block 32) with and without, and linalg::Qr on both blocks.
//!
//! cargo run --release --example qr_realistic [-- THREADS STEPS]
use clv::config::{RunConfig, SystemConfig};
use clv::linalg::{FlushSubnormals, Qr};
use clv::rng::Rng;
use clv::stage::forward::Forward;
use clv::system::Tangent;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::factor;
use faer::{Mat, Par};
use std::time::Instant;

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// faer's sequential QR (no Q) of `a`, block 32: (factored matrix, milliseconds).
fn faer_factor(a: &Mat<f64>, flush: bool) -> (Mat<f64>, f64) {
    let (d, k) = a.shape();
    let mut a = a.clone();
    let mut h = Mat::<f64>::zeros(32, k);
    let mut mem = MemBuffer::new(factor::qr_in_place_scratch::<f64>(d, k, 32, Par::Seq, Default::default()));
    let t = Instant::now();
    let guard = flush.then(FlushSubnormals::new);
    factor::qr_in_place(a.as_mut(), h.as_mut(), Par::Seq, MemStack::new(&mut mem), Default::default());
    drop(guard);
    (a, t.elapsed().as_secs_f64() * 1e3)
}

fn main() {
    let threads: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let steps: u64 = std::env::args().nth(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let n = 198;
    let d = 4 * n;
    let cfg = RunConfig { system: SystemConfig::disks(n, 0.7, 2.0 / 11.0).unwrap(), tau: 0.6, relax_steps: steps, steps: 10, vectors: d, seed: 1, threads, blocks: 4 };
    let mut f = Forward::new(&cfg).unwrap();
    for _ in 0..steps {
        f.step().unwrap();
    }
    // the block the next QR step sees
    let mut real = f.g.clone();
    f.system.advance(&mut real).unwrap();
    let subnormal = real.rows().iter().filter(|x| **x != 0.0 && x.abs() < f64::MIN_POSITIVE).count();
    println!("tangent block D = {d} after {steps} steps: {subnormal} subnormal entries");
    let mut rng = Rng::new(1);
    let mut rand = Tangent::zeros(d, d);
    rand.rows_mut().iter_mut().for_each(|x| *x = rng.normal());

    for (name, src) in [("tangent", &real), ("random", &rand)] {
        let a = Mat::from_fn(d, d, |i, j| src.get(i, j));
        let (plain, flushed) = (faer_factor(&a, false).0, faer_factor(&a, true).0);
        let same = (0..d).all(|j| (0..d).all(|i| plain[(i, j)].to_bits() == flushed[(i, j)].to_bits()));
        let (mut t0, mut t1) = (Vec::new(), Vec::new());
        for _ in 0..9 {
            t0.push(faer_factor(&a, false).1);
            t1.push(faer_factor(&a, true).1);
        }
        println!("faer factorisation, {name} block: {:.2} ms, flushed {:.2} ms, same bits: {same}", median(t0), median(t1));
    }

    let mut qr = Qr::new(d, d, threads);
    let mut r = Mat::zeros(d, d);
    let (mut tr, mut tq) = (Vec::new(), Vec::new());
    for _ in 0..15 {
        for (src, out) in [(&real, &mut tr), (&rand, &mut tq)] {
            let mut a = src.clone();
            let t = Instant::now();
            qr.factor(&mut a, &mut r);
            out.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    println!("linalg::Qr with Q on {threads} thread(s): tangent block {:.2} ms, random {:.2} ms (medians of 15)", median(tr), median(tq));

    // The Ginelli step's kernels with this R: C <- R^-1 C (columns normalised) and V = G C.
    let mut g = real.clone();
    qr.factor(&mut g, &mut r);
    let g = g.to_paper_columns(f.system.as_ref());
    let g = faer::MatRef::from_column_major_slice(&g, d, d);
    let mut v = Mat::<f64>::zeros(d, d);
    for flush in [false, true] {
        let mut c = Mat::<f64>::identity(d, d);
        let (mut ts, mut tv, mut tn) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..9 {
            let guard = flush.then(FlushSubnormals::new);
            let t = Instant::now();
            clv::linalg::solve_upper_tri_tri(r.as_ref(), c.as_mut(), Par::Seq);
            ts.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            for j in 0..d {
                let norm = c.col(j).norm_l2();
                c.col_mut(j).iter_mut().for_each(|x| *x /= norm);
            }
            tn.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            clv::linalg::mul_upper(v.as_mut(), g, c.as_ref(), Par::Seq);
            tv.push(t.elapsed().as_secs_f64() * 1e3);
            drop(guard);
        }
        println!("Ginelli kernels, flushed {flush}: R^-1 C {:.2} ms, normalising C {:.2} ms, V = G C {:.2} ms", median(ts), median(tn), median(tv));
    }
}
