//! Experiment (not part of the tool): forming Q from reflector blocks wider than the panels.
//!
//! The factorisation works on panels of 32 columns; forming Q with those 32-wide blocks
//! makes every gemm of the formation have an inner dimension of 32. Merging W/32 panels into
//! one W-wide block (its factor is triu(V^T V) with the panels' tau on the diagonal, faer's
//! convention) costs a small Gram product and makes the inner dimension W. Measured on one
//! thread at D = 792 (2026-11-24): 9.8 ms with the panels' own blocks, 10.7 ms with blocks of
//! 64 and 11.1-15.2 ms with 128-256; faer's block application pays the larger triangular
//! factor on every chunk. Not adopted.
//!
//! It also times the panel factorisations alone (2.4 ms of the 22 ms QR on one thread) for
//! faer's recursion thresholds: stopping the recursion at 16 columns saves 0.6 ms on one
//! thread and nothing measurable on two, where the panels overlap the trailing updates. Not
//! adopted either: it would change the bits of every run for about 2 %.
//!
//! cargo run --release --example qr_merge [-- D]
use clv::linalg::FlushSubnormals;
use clv::rng::Rng;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::linalg::qr::no_pivoting::factor;
use faer::{Accum, Conj, Mat, MatRef, Par};
use std::time::Instant;

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// The factor of the block of reflectors in columns s..e (V unit lower trapezoidal in `a`).
fn merged_factor(a: MatRef<'_, f64>, t: MatRef<'_, f64>, nb: usize, s: usize, e: usize, out: &mut Mat<f64>) {
    let w = e - s;
    let v = a.get(s.., s..e);
    let (v0, v1) = v.split_at_row(w);
    let mut o = out.as_mut().get_mut(..w, ..w);
    triangular::matmul(o.as_mut(), BlockStructure::StrictTriangularUpper, Accum::Replace, v0.transpose(), BlockStructure::UnitTriangularUpper, v0, BlockStructure::UnitTriangularLower, 1.0, Par::Seq);
    triangular::matmul(o.as_mut(), BlockStructure::StrictTriangularUpper, Accum::Add, v1.transpose(), BlockStructure::Rectangular, v1, BlockStructure::Rectangular, 1.0, Par::Seq);
    for j in s..e {
        o[(j - s, j - s)] = t[(j % nb, j)];
    }
}

/// Q (orgqr order, chunks of `chunk` columns) from blocks of width w (a multiple of nb).
#[allow(clippy::too_many_arguments)]
fn form_q(a: MatRef<'_, f64>, t: MatRef<'_, f64>, nb: usize, w: usize, chunk: usize, q: &mut Mat<f64>, tb: &mut [Mat<f64>], mem: &mut MemBuffer) -> (f64, f64) {
    let (_, k) = a.shape();
    let blocks: Vec<(usize, usize)> = (0..k.div_ceil(w)).map(|b| (b * w, ((b + 1) * w).min(k))).collect();
    let s0 = Instant::now();
    if w != nb {
        for (i, &(s, e)) in blocks.iter().enumerate() {
            merged_factor(a, t, nb, s, e, &mut tb[i]);
        }
    }
    let merge_ms = s0.elapsed().as_secs_f64() * 1e3;
    q.fill(0.0);
    for c in (0..k.div_ceil(chunk)).rev() {
        let cols = c * chunk..((c + 1) * chunk).min(k);
        for j in cols.clone() {
            q[(j, j)] = 1.0;
        }
        for (i, &(s, e)) in blocks.iter().enumerate().rev().filter(|(_, b)| b.0 < cols.end) {
            let from = s.max(cols.start);
            let f = if w == nb { t.get(..e - s, s..e) } else { tb[i].as_ref().get(..e - s, ..e - s) };
            householder::apply_block_householder_on_the_left_in_place_with_conj(a.get(s.., s..e), f, Conj::No, q.as_mut().get_mut(s.., from..cols.end), Par::Seq, MemStack::new(mem));
        }
    }
    (merge_ms, s0.elapsed().as_secs_f64() * 1e3)
}

fn main() {
    let d: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(792);
    let _flush = FlushSubnormals::new();
    let nb = 32;
    let mut rng = Rng::new(1);
    let a0 = Mat::from_fn(d, d, |_, _| rng.normal());
    let mut a = a0.clone();
    let mut t = Mat::zeros(nb, d);
    let mut mem = MemBuffer::new(StackReq::any_of(&[
        factor::qr_in_place_scratch::<f64>(d, d, nb, Par::Seq, Default::default()),
        householder::apply_block_householder_on_the_left_in_place_scratch::<f64>(d, 256, d),
    ]));
    let s = Instant::now();
    factor::qr_in_place(a.as_mut(), t.as_mut(), Par::Seq, MemStack::new(&mut mem), Default::default());
    println!("factor (faer, block 32, 1 thread): {:.1} ms", s.elapsed().as_secs_f64() * 1e3);

    for nbp in [16, 32, 64] {
        for bt in [48 * 48, 792 * 3, 792 * 5, 792 * 9, 792 * 17, usize::MAX] {
            let ms = median((0..9).map(|_| panels_only(&a0, nbp, bt)).collect());
            println!("panels of {nbp} alone, blocking threshold {bt}: {ms:.2} ms");
        }
    }
    let mut reference = Mat::zeros(d, d);
    let mut tb: Vec<Mat<f64>> = (0..d).map(|_| Mat::zeros(256, 256)).collect();
    form_q(a.as_ref(), t.as_ref(), nb, nb, 64, &mut reference, &mut tb, &mut mem);
    let mut q = Mat::zeros(d, d);
    for round in 0..2 {
        for (w, chunk) in [(32, 64), (64, 64), (128, 64), (128, 128), (256, 64), (256, 128)] {
            let mut ms = vec![];
            let mut mm = vec![];
            for _ in 0..7 {
                let (m, total) = form_q(a.as_ref(), t.as_ref(), nb, w, chunk, &mut q, &mut tb, &mut mem);
                ms.push(total);
                mm.push(m);
            }
            let diff = (0..d).flat_map(|j| (0..d).map(move |i| (i, j))).map(|(i, j)| (q[(i, j)] - reference[(i, j)]).abs()).fold(0.0, f64::max);
            if round == 1 {
                println!("Q from blocks of {w:>3}, chunks of {chunk:>3}: {:6.2} ms (merge {:.2} ms), max |Q - Q_32| = {diff:.1e}", median(ms), median(mm));
            }
        }
    }
}

/// Factor only the panels of `a0` (each as if it were up to date), recursion threshold `bt`.
fn panels_only(a0: &Mat<f64>, nb: usize, bt: usize) -> f64 {
    let (d, k) = a0.shape();
    let mut a = a0.clone();
    let mut t = Mat::zeros(nb, k);
    let mut mem = MemBuffer::new(factor::qr_in_place_scratch::<f64>(d, nb, nb, Par::Seq, Default::default()));
    let s = Instant::now();
    for p in 0..k.div_ceil(nb) {
        let cols = p * nb..((p + 1) * nb).min(k);
        let w = cols.len();
        let mut spec: faer::Spec<factor::QrParams, f64> = Default::default();
        spec.blocking_threshold = bt;
        factor::qr_in_place(a.as_mut().get_mut(cols.start.., cols.clone()), t.as_mut().get_mut(..w, cols.clone()), Par::Seq, MemStack::new(&mut mem), spec);
    }
    s.elapsed().as_secs_f64() * 1e3
}
