//! The QR step Gbar_n = G_n R_n with a positive diagonal of R, and packed triangles.
//!
//! This is where a forward step spends nearly all its time (8/3 D^3 flops for k = D), so it
//! uses faer's blocked Householder QR and forms the explicit Q the way LAPACK's orgqr does:
//! applying the reflector blocks from last to first, each only to the part of Q it can
//! change, which saves about a third of the flops of applying them to a full identity.
//! The sign fix (diag R > 0) makes G_n unique, so that ln R_ii are the exponent increments
//! and the Ginelli iteration C_{n-1} = R_n^{-1} C_n carries no sign noise.

use crate::system::Tangent;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::qr::no_pivoting::factor;
use faer::{Conj, Mat, MatMut, Par};

/// Workspace for repeated QR factorisations of D x k tangent blocks.
pub struct Qr {
    a: Mat<f64>,
    h: Mat<f64>,
    q: Mat<f64>,
    mem: MemBuffer,
    /// Parallelism of the factorisation and of the formation of Q (chosen separately:
    /// they scale differently with threads).
    par_factor: Par,
    par_q: Par,
}

/// The parallelism setting for `threads` worker threads (1 = sequential).
pub fn par(threads: usize) -> Par {
    if threads <= 1 { Par::Seq } else { Par::rayon(threads) }
}

/// The QR workspace for a D x k block on `threads` threads, tuned by measurement at
/// D = k = 792 (examples/qr_blocks.rs, 2-core Zen 3):
/// - threads speed up the formation of Q (gemm-like) but slow faer's blocked factorisation
///   down below D of about 800 (5x at D = 200, 2.6x at D = 400, break-even at 792), so the
///   factorisation is threaded only for larger blocks;
/// - Householder blocks of 16 instead of faer's default 48: 34.4 against 39.2 ms on one
///   thread, 30.3 against 34 ms with Q formed on two.
pub fn qr_for(d: usize, k: usize, threads: usize) -> Qr {
    let factor = if d * k >= 1200 * 1200 { par(threads) } else { Par::Seq };
    if d.min(k) >= 512 {
        Qr::with_block(d, k, 16, factor, par(threads))
    } else {
        Qr::with_par(d, k, factor, par(threads))
    }
}

impl Qr {
    pub fn new(d: usize, k: usize, par: Par) -> Self {
        Self::with_par(d, k, par, par)
    }

    /// A workspace with separate parallelism for the factorisation and for forming Q.
    pub fn with_par(d: usize, k: usize, par_factor: Par, par_q: Par) -> Self {
        Self::with_block(d, k, factor::recommended_block_size::<f64>(d, k), par_factor, par_q)
    }

    /// A workspace with a chosen Householder block size (for tuning experiments).
    pub fn with_block(d: usize, k: usize, bs: usize, par_factor: Par, par_q: Par) -> Self {
        let par = par_factor;
        let bs = bs.clamp(1, k.min(d).max(1));
        let req = StackReq::any_of(&[
            factor::qr_in_place_scratch::<f64>(d, k, bs, par, Default::default()),
            householder::apply_block_householder_on_the_left_in_place_scratch::<f64>(d, bs, k),
        ]);
        Qr { a: Mat::zeros(d, k), h: Mat::zeros(bs, k.min(d)), q: Mat::zeros(d, k), mem: MemBuffer::new(req), par_factor, par_q }
    }

    /// Factor the block in place (Gbar_n = G_n R_n): on return `g` holds G_n and `r` the
    /// k x k upper-triangular R_n with a positive diagonal (its lower part is zero).
    pub fn factor(&mut self, g: &mut Tangent, r: &mut Mat<f64>) {
        let (d, k) = (g.dim(), g.count());
        assert!(k <= d && r.nrows() == k && r.ncols() == k && self.a.nrows() == d && self.a.ncols() == k);
        transpose_in(g.rows(), k, self.a.as_mut());
        let stack = MemStack::new(&mut self.mem);
        factor::qr_in_place(self.a.as_mut(), self.h.as_mut(), self.par_factor, stack, Default::default());

        // Explicit Q: start from [I; 0] and apply the blocks of reflectors from last to first,
        // each to the trailing rows and columns only (orgqr).
        self.q.fill(0.0);
        for j in 0..k {
            self.q[(j, j)] = 1.0;
        }
        let bs = self.h.nrows();
        let mut end = k;
        while end > 0 {
            let start = (end - 1) / bs * bs;
            let essentials = self.a.as_ref().get(start.., start..end);
            let factor = self.h.as_ref().get(..end - start, start..end);
            let target = self.q.as_mut().get_mut(start.., start..k);
            householder::apply_block_householder_on_the_left_in_place_with_conj(
                essentials, factor, Conj::No, target, self.par_q, MemStack::new(&mut self.mem),
            );
            end = start;
        }

        for j in 0..k {
            for i in 0..k {
                r[(i, j)] = if i <= j { self.a[(i, j)] } else { 0.0 };
            }
        }
        for j in 0..k {
            if r[(j, j)] < 0.0 {
                for c in j..k {
                    r[(j, c)] = -r[(j, c)];
                }
                for x in self.q.col_mut(j).iter_mut() {
                    *x = -*x;
                }
            }
        }
        transpose_out(self.q.as_ref(), g.rows_mut(), k);
    }
}

/// Below this size the triangular kernels fall back to dense faer calls.
const TRI_BLOCK: usize = 64;

/// C <- R^{-1} C for upper-triangular R and C (so the result is upper triangular too), the
/// Ginelli step C_{n-1} = R_n^{-1} C_n. Recursive on 2 x 2 blocks: n^3/2 flops instead of
/// the n^3 of a dense triangular solve.
pub fn solve_upper_tri_tri(r: faer::MatRef<'_, f64>, c: MatMut<'_, f64>, par: Par) {
    let n = c.nrows();
    if n <= TRI_BLOCK {
        faer::linalg::triangular_solve::solve_upper_triangular_in_place(r, c, par);
        return;
    }
    let h = n / 2;
    let (c_top, c_bottom) = c.split_at_row_mut(h);
    let (c11, mut c12) = c_top.split_at_col_mut(h);
    let (_, mut c22) = c_bottom.split_at_col_mut(h);
    let (r11, r12, r22) = (r.get(..h, ..h), r.get(..h, h..), r.get(h.., h..));
    solve_upper_tri_tri(r22, c22.as_mut(), par);
    faer::linalg::matmul::matmul(c12.as_mut(), faer::Accum::Add, r12, c22.as_ref(), -1.0, par);
    faer::linalg::triangular_solve::solve_upper_triangular_in_place(r11, c12, par);
    solve_upper_tri_tri(r11, c11, par);
}

/// V <- G C for a D x k matrix G and an upper-triangular k x k matrix C (V_n = G_n C_n):
/// recursive on column blocks, D k^2 flops instead of the 2 D k^2 of a dense product.
pub fn mul_upper(v: MatMut<'_, f64>, g: faer::MatRef<'_, f64>, c: faer::MatRef<'_, f64>, par: Par) {
    let k = c.ncols();
    if k <= TRI_BLOCK {
        faer::linalg::matmul::triangular::matmul(
            v,
            faer::linalg::matmul::triangular::BlockStructure::Rectangular,
            faer::Accum::Replace,
            g,
            faer::linalg::matmul::triangular::BlockStructure::Rectangular,
            c,
            faer::linalg::matmul::triangular::BlockStructure::TriangularUpper,
            1.0,
            par,
        );
        return;
    }
    let h = k / 2;
    let (mut v1, mut v2) = v.split_at_col_mut(h);
    let (g1, g2) = (g.get(.., ..h), g.get(.., h..));
    mul_upper(v2.as_mut(), g2, c.get(h.., h..), par);
    faer::linalg::matmul::matmul(v2.as_mut(), faer::Accum::Add, g1, c.get(..h, h..), 1.0, par);
    mul_upper(v1.as_mut(), g1, c.get(..h, ..h), par);
}

const TILE: usize = 32;

/// Row-major D x k `rows` into the column-major matrix `a` (tiled for the cache).
fn transpose_in(rows: &[f64], k: usize, mut a: MatMut<'_, f64>) {
    let d = a.nrows();
    for j0 in (0..k).step_by(TILE) {
        for i0 in (0..d).step_by(TILE) {
            for j in j0..(j0 + TILE).min(k) {
                for i in i0..(i0 + TILE).min(d) {
                    a[(i, j)] = rows[i * k + j];
                }
            }
        }
    }
}

fn transpose_out(a: faer::MatRef<'_, f64>, rows: &mut [f64], k: usize) {
    let d = a.nrows();
    for i0 in (0..d).step_by(TILE) {
        for j0 in (0..k).step_by(TILE) {
            for i in i0..(i0 + TILE).min(d) {
                for j in j0..(j0 + TILE).min(k) {
                    rows[i * k + j] = a[(i, j)];
                }
            }
        }
    }
}

/// The upper triangle of a k x k matrix, packed column by column: (i, j), i <= j, at
/// j (j + 1) / 2 + i (LAPACK's "U" packing; k (k + 1) / 2 numbers).
pub fn pack_upper(r: faer::MatRef<'_, f64>) -> Vec<f64> {
    let k = r.ncols();
    let mut out = Vec::with_capacity(k * (k + 1) / 2);
    for j in 0..k {
        out.extend((0..=j).map(|i| r[(i, j)]));
    }
    out
}

/// [`pack_upper`] into a buffer of k (k + 1) / 2 values.
pub fn pack_upper_into(r: faer::MatRef<'_, f64>, out: &mut [f64]) {
    let k = r.ncols();
    assert_eq!(out.len(), k * (k + 1) / 2, "buffer must hold k (k + 1) / 2 values");
    let mut at = 0;
    for j in 0..k {
        for i in 0..=j {
            out[at] = r[(i, j)];
            at += 1;
        }
    }
}

/// Unpack into an existing k x k matrix (the strictly lower part is left untouched).
pub fn unpack_upper_into(packed: &[f64], r: &mut Mat<f64>) {
    let k = r.ncols();
    assert_eq!(packed.len(), k * (k + 1) / 2, "packed length must be k (k + 1) / 2");
    let mut at = 0;
    for j in 0..k {
        for i in 0..=j {
            r[(i, j)] = packed[at];
            at += 1;
        }
    }
}

/// Inverse of [`pack_upper`]; `None` if the length is not a triangular number.
pub fn unpack_upper(packed: &[f64]) -> Option<Mat<f64>> {
    let k = ((((8 * packed.len() + 1) as f64).sqrt() - 1.0) / 2.0).round() as usize;
    if k * (k + 1) / 2 != packed.len() {
        return None;
    }
    let mut r = Mat::zeros(k, k);
    let mut at = 0;
    for j in 0..k {
        for i in 0..=j {
            r[(i, j)] = packed[at];
            at += 1;
        }
    }
    Some(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random_block(d: usize, k: usize, seed: u64) -> Tangent {
        let mut rng = Rng::new(seed);
        let mut t = Tangent::zeros(d, k);
        t.rows_mut().iter_mut().for_each(|x| *x = rng.normal());
        t
    }

    /// G R reproduces the input, G has orthonormal columns, R is upper triangular with a
    /// positive diagonal; for several shapes around the block-size boundaries.
    #[test]
    fn qr_reconstructs_with_positive_diagonal() {
        for &(d, k, bs) in &[(2, 2, 0), (2, 1, 0), (7, 3, 0), (40, 40, 0), (100, 37, 0), (130, 129, 0), (130, 129, 16), (600, 520, 16)] {
            let a = random_block(d, k, (d * 1000 + k) as u64);
            let mut g = a.clone();
            let mut r = Mat::zeros(k, k);
            let mut qr = if bs == 0 { Qr::new(d, k, Par::Seq) } else { Qr::with_block(d, k, bs, Par::Seq, Par::rayon(2)) };
            qr.factor(&mut g, &mut r);
            let mut worst: f64 = 0.0;
            for i in 0..d {
                for j in 0..k {
                    let gr: f64 = (0..k).map(|l| g.get(i, l) * r[(l, j)]).sum();
                    worst = worst.max((gr - a.get(i, j)).abs());
                }
            }
            assert!(worst < 1e-12 * d as f64, "{d}x{k}: |GR - A| = {worst}");
            for p in 0..k {
                assert!(r[(p, p)] > 0.0);
                for q in 0..k {
                    let dot: f64 = (0..d).map(|i| g.get(i, p) * g.get(i, q)).sum();
                    let want = if p == q { 1.0 } else { 0.0 };
                    assert!((dot - want).abs() < 1e-12, "{d}x{k}: G^T G [{p},{q}] = {dot}");
                    if q < p {
                        assert_eq!(r[(p, q)], 0.0);
                    }
                }
            }
        }
    }

    fn random_upper(k: usize, rng: &mut Rng) -> Mat<f64> {
        Mat::from_fn(k, k, |i, j| if i < j { rng.normal() } else if i == j { 1.0 + rng.uniform() } else { 0.0 })
    }

    /// The triangular kernels agree with dense faer products and solves.
    #[test]
    fn triangular_kernels_match_dense_reference() {
        let mut rng = Rng::new(11);
        for &(d, k) in &[(5, 5), (64, 64), (100, 65), (300, 200), (257, 257)] {
            let r = random_upper(k, &mut rng);
            let c = random_upper(k, &mut rng);
            let mut x = c.clone();
            solve_upper_tri_tri(r.as_ref(), x.as_mut(), Par::Seq);
            let mut want = c.clone();
            faer::linalg::triangular_solve::solve_upper_triangular_in_place(r.as_ref(), want.as_mut(), Par::Seq);
            let err = (&x - &want).norm_max() / want.norm_max();
            assert!(err < 1e-12, "{k}: R^-1 C off by {err}");
            assert!((0..k).all(|j| (j + 1..k).all(|i| x[(i, j)] == 0.0)), "R^-1 C must stay upper triangular");
            let g = Mat::from_fn(d, k, |_, _| rng.normal());
            let mut v = Mat::zeros(d, k);
            mul_upper(v.as_mut(), g.as_ref(), c.as_ref(), Par::Seq);
            let want = &g * &c;
            let err = (&v - &want).norm_max() / want.norm_max();
            assert!(err < 1e-12, "{d}x{k}: G C off by {err}");
        }
    }

    #[test]
    fn packing_round_trips() {
        let mut r = Mat::zeros(5, 5);
        for j in 0..5 {
            for i in 0..=j {
                r[(i, j)] = (10 * i + j) as f64;
            }
        }
        let p = pack_upper(r.as_ref());
        assert_eq!(p.len(), 15);
        assert_eq!(unpack_upper(&p).unwrap(), r);
        assert!(unpack_upper(&[1.0, 2.0]).is_none());
    }
}
