//! Dense linear algebra of the forward and backward stages: the QR step (qr.rs), the
//! triangular kernels of the Ginelli iteration, and the packed form R_n is stored in.
//! Every kernel runs with subnormal numbers flushed to zero on the threads of this crate
//! (subnormals.rs: up to a third faster, same bits on our tangent blocks).

mod crew;
mod qr;
mod subnormals;

pub use qr::{par, Copies, PaperColumns, Qr};
pub use subnormals::FlushSubnormals;
use faer::{Mat, MatMut, Par};

/// ln(1 / eps) of a double: tangent vectors that spread by more than e^this between two
/// QR steps, (lambda_1 - lambda_k) tau, are dependent to the QR's rounding.
pub const RESOLVED_SPREAD: f64 = 36.04;
/// Above this spread the most contracting vectors keep fewer than half of a double's digits
/// through a step. Measured, N = 16 disks at t = 1200: the sum of the exponents, zero by
/// symmetry, was -4e-12 at a spread of 6 (tau = 0.6), 1.7e-4 at 24, 0.04 at 30 and 6.1 at
/// 40 (against lambda_1 = 5).
pub const PRECISE_SPREAD: f64 = 18.0;

/// The mean spread (lambda_1 - lambda_k) tau of k vectors above which it is rounding's own:
/// where the most contracting vectors shrink to rounding between two QR steps, R_kk is
/// rounding, and the spread it gives stays near ln(1 / eps) = 36 whatever the dynamics
/// (Lorenz, k = 3, at tau = 6, 10, 20: 37.9, 37.4, 37.0, with lambda_3 = -5.3, -2.8, -1.0
/// instead of -14.57; faer's rank test caught such columns at some tau, not at others). The
/// rounding of a column grows with the columns before it, so the floor falls with k: N = 16
/// disks (k = 64) at tau = 3.5 measured 33.8 for a spread of about 35, lambda_k 7 % off.
/// Hence 36 - 2 - ln k: 32.9 for Lorenz, 29.9 for k = 64, 27.3 for the paper's 792.
pub fn unresolved_spread(k: usize) -> f64 {
    RESOLVED_SPREAD - 2.0 - (k.max(1) as f64).ln()
}

/// Why QR steps `tau` apart whose k vectors have the mean spread (lambda_1 - lambda_k) tau =
/// `spread` measure rounding instead of the stable exponents, if they do
/// ([`unresolved_spread`]).
pub fn unresolved(spread: f64, tau: f64, k: usize) -> Option<String> {
    (spread > unresolved_spread(k)).then(|| {
        format!(
            "the QR steps measure (lambda_1 - lambda_k) tau = {spread:.1}, at the limit of what the 16 digits of a double resolve for k = {k} vectors (about {:.0}): \
             between two QR steps the most contracting tangent vectors shrink to rounding, so their exponents measure rounding, not the dynamics; \
             give a smaller --tau (below {:.3} keeps half of the digits: a spread of {PRECISE_SPREAD:.0}, if the exponents were as measured, which they are not: \
             take less)",
            unresolved_spread(k),
            PRECISE_SPREAD * tau / spread
        )
    })
}

/// Why the exponents `lambda` (lambda_1 first) measured with QR steps `tau` apart are less
/// precise than the run's statistics say, if they are: a spread (lambda_1 - lambda_k) tau
/// above [`PRECISE_SPREAD`], or past [`unresolved_spread`] not measured at all.
pub fn precision_warning(lambda: &[f64], tau: f64) -> Option<String> {
    let range = lambda.first()? - lambda.last()?;
    let spread = range * tau;
    // A run written before such runs stopped (inspect reads them).
    if let Some(why) = unresolved(spread, tau, lambda.len()) {
        return Some(why);
    }
    (spread > PRECISE_SPREAD).then(|| {
        format!(
            "(lambda_1 - lambda_k) tau = {spread:.1}: between two QR steps the tangent vectors spread by e^{spread:.0}, so that the most contracting of them keep \
             about {:.0} of a double's 16 digits, and the stable exponents (their sum, the conjugate pairs) are off by more than their errors say; \
             give a --tau below {:.3} (a spread of {PRECISE_SPREAD:.0})",
            (16.0 - spread / std::f64::consts::LN_10).max(0.0),
            PRECISE_SPREAD / range
        )
    })
}

/// Below this size the triangular kernels fall back to dense faer calls.
const TRI_BLOCK: usize = 64;

/// C <- R^{-1} C for upper-triangular R and C (so the result is upper triangular too), the
/// Ginelli step C_{n-1} = R_n^{-1} C_n. Recursive on 2 x 2 blocks, with the off-diagonal
/// block's product R_12 C_22 triangular too: n^3/3 flops instead of the n^3 of a dense
/// triangular solve (4.5 -> 3.8 ms at n = 792 on one thread, measured, normalisation included).
pub fn solve_upper_tri_tri(r: faer::MatRef<'_, f64>, c: MatMut<'_, f64>, par: Par) {
    let _flush = FlushSubnormals::new();
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
    mul_upper_into(c12.as_mut(), faer::Accum::Add, r12, c22.as_ref(), -1.0, par);
    faer::linalg::triangular_solve::solve_upper_triangular_in_place(r11, c12, par);
    solve_upper_tri_tri(r11, c11, par);
}

/// The Ginelli step with renormalisation: C <- R^{-1} C (see [`solve_upper_tri_tri`]),
/// then every column scaled to unit length; `norms[j]` receives the length of column j
/// before the scaling (-ln norms[j] / tau is the local exponent Lambda_j^cov of CLV j, paper
/// Sec. 6).
pub fn ginelli_step(r: faer::MatRef<'_, f64>, mut c: MatMut<'_, f64>, norms: &mut [f64], par: Par) {
    let _flush = FlushSubnormals::new();
    assert_eq!(norms.len(), c.ncols());
    solve_upper_tri_tri(r, c.as_mut(), par);
    for (j, norm) in norms.iter_mut().enumerate() {
        // Only the upper triangle: the rest of the column is zero.
        let col = c.as_mut().col_mut(j).subrows_mut(0, j + 1);
        *norm = col.norm_l2();
        col.iter_mut().for_each(|x| *x /= *norm);
    }
}

/// V <- G C for a D x k matrix G and an upper-triangular k x k matrix C (V_n = G_n C_n):
/// recursive on column blocks, D k^2 flops instead of the 2 D k^2 of a dense product.
pub fn mul_upper(v: MatMut<'_, f64>, g: faer::MatRef<'_, f64>, c: faer::MatRef<'_, f64>, par: Par) {
    let _flush = FlushSubnormals::new();
    mul_upper_into(v, faer::Accum::Replace, g, c, 1.0, par);
}

/// V <- alpha G C (Replace) or V + alpha G C (Add), C upper triangular; see [`mul_upper`].
fn mul_upper_into(v: MatMut<'_, f64>, accum: faer::Accum, g: faer::MatRef<'_, f64>, c: faer::MatRef<'_, f64>, alpha: f64, par: Par) {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    let k = c.ncols();
    if k <= TRI_BLOCK {
        matmul(v, BlockStructure::Rectangular, accum, g, BlockStructure::Rectangular, c, BlockStructure::TriangularUpper, alpha, par);
        return;
    }
    let h = k / 2;
    let (mut v1, mut v2) = v.split_at_col_mut(h);
    let (g1, g2) = (g.get(.., ..h), g.get(.., h..));
    mul_upper_into(v2.as_mut(), accum, g2, c.get(h.., h..), alpha, par);
    faer::linalg::matmul::matmul(v2.as_mut(), faer::Accum::Add, g1, c.get(..h, h..), alpha, par);
    mul_upper_into(v1.as_mut(), accum, g1, c.get(..h, ..h), alpha, par);
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

/// Unpack into an existing k x k matrix (the strictly lower part is left untouched).
pub fn unpack_upper_into(packed: &[f64], r: &mut Mat<f64>) {
    let k = r.ncols();
    assert_eq!(packed.len(), k * (k + 1) / 2, "packed length must be k (k + 1) / 2");
    let mut at = 0;
    for j in 0..k {
        r.col_as_slice_mut(j)[..=j].copy_from_slice(&packed[at..at + j + 1]);
        at += j + 1;
    }
}

/// Inverse of [`pack_upper`]; `None` if the length is not a triangular number.
pub fn unpack_upper(packed: &[f64]) -> Option<Mat<f64>> {
    let k = ((((8 * packed.len() + 1) as f64).sqrt() - 1.0) / 2.0).round() as usize;
    if k * (k + 1) / 2 != packed.len() {
        return None;
    }
    let mut r = Mat::zeros(k, k);
    unpack_upper_into(packed, &mut r);
    Some(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A spread (lambda_1 - lambda_k) tau beyond half a double's digits is named with the
    /// tau that would keep it within; the default disks' (about 6) is not.
    #[test]
    fn precision_warning_names_the_spread_and_a_tau() {
        assert!(precision_warning(&[5.0, 0.0, -5.0], 0.6).is_none() && precision_warning(&[], 0.6).is_none());
        let w = precision_warning(&[5.0, 0.0, -5.0], 2.5).unwrap();
        assert!(w.contains("tau = 25.0") && w.contains("give a --tau below 1.800"), "{w}");
        let w = precision_warning(&[5.0, 0.0, -5.0], 4.0).unwrap();
        assert!(w.contains("tau = 40.0, at the limit") && w.contains("measure rounding"), "past unresolved_spread: {w}");
        // The floor falls with k: 31 is rounding for 64 vectors (N = 16 disks at tau = 3.5
        // measured 33.8), not for Lorenz's 3 (tau = 2 measured 30.9, lambda_3 still -14.56).
        assert!(unresolved(31.0, 3.5, 64).is_some() && unresolved(31.0, 2.0, 3).is_none());
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

    /// Forward QR steps and the Ginelli iteration on a constant 2 x 2 map A, with exactly
    /// the kernels the stages use: the GS exponents (time averages of ln R_ii) and the CLV
    /// exponents (of the renormalisation), each after a transient of 20 steps, and G and
    /// V = G C at step `at` of `n`.
    fn ginelli_constant(a: [[f64; 2]; 2], n: usize, at: usize) -> ([f64; 2], [f64; 2], Mat<f64>, Mat<f64>) {
        let mut qr = Qr::new(2, 2, 1);
        let mut g = crate::system::Tangent::zeros(2, 2);
        g.set(0, 0, 1.0);
        g.set(1, 1, 1.0);
        let mut r = Mat::zeros(2, 2);
        let (mut gs, mut rs) = (vec![], vec![]);
        let mut sum = [0.0; 2];
        for step in 1..=n {
            let old = g.clone();
            for (i, row) in a.iter().enumerate() {
                for j in 0..2 {
                    g.set(i, j, row[0] * old.get(0, j) + row[1] * old.get(1, j));
                }
            }
            qr.factor(&mut g, &mut r);
            assert!(r[(0, 0)] > 0.0 && r[(1, 1)] > 0.0, "diag R > 0 (sign fix)");
            for i in 0..2 {
                if step > 20 {
                    sum[i] += r[(i, i)].ln() / (n - 20) as f64;
                }
            }
            gs.push(Mat::from_fn(2, 2, |i, j| g.get(i, j)));
            rs.push(r.clone());
        }
        let mut c = Mat::<f64>::identity(2, 2);
        let (mut norms, mut clv) = ([0.0; 2], [0.0; 2]);
        // C converges from the identity within a few steps: the CLV exponents are averaged
        // over the steps after a backward transient of 20.
        for m in (at + 1..=n).rev() {
            ginelli_step(rs[m - 1].as_ref(), c.as_mut(), &mut norms, Par::Seq);
            for j in 0..2 {
                if m <= n - 20 {
                    clv[j] -= norms[j].ln() / (n - 20 - at) as f64;
                }
            }
        }
        let g_at = gs[at - 1].clone();
        let mut v = Mat::zeros(2, 2);
        mul_upper(v.as_mut(), g_at.as_ref(), c.as_ref(), Par::Seq);
        (sum, clv, g_at, v)
    }

    /// |cos| of the angle between column j of `m` and the vector `u`.
    fn parallel(m: &Mat<f64>, j: usize, u: [f64; 2]) -> f64 {
        let dot = m[(0, j)] * u[0] + m[(1, j)] * u[1];
        dot.abs() / (m[(0, j)].hypot(m[(1, j)]) * u[0].hypot(u[1]))
    }

    /// Exact tests: the non-normal map [[2, 1], [0, 0.5]] has lambda =
    /// +-ln 2, GS vectors e_1, e_2 and CLVs (1, 0), (1, -1.5) (the smallest case in which
    /// they differ); the Henon Jacobian at its fixed point x* = y* = 0.883896268 has
    /// ln |mu| = 0.65427061, -1.85824342 for mu = -1.92373886, 0.15594632, and its
    /// eigenvectors (mu, 1) as CLVs, but not as GS vectors.
    #[test]
    fn ginelli_on_constant_maps_gives_their_eigenvectors() {
        let (gs, clv, g, v) = ginelli_constant([[2.0, 1.0], [0.0, 0.5]], 80, 40);
        for (got, want) in [(gs, [2f64.ln(), -(2f64.ln())]), (clv, [2f64.ln(), -(2f64.ln())])] {
            assert!((got[0] - want[0]).abs() < 1e-12 && (got[1] - want[1]).abs() < 1e-12, "{got:?}");
        }
        assert!(parallel(&g, 0, [1.0, 0.0]) > 1.0 - 1e-14 && parallel(&g, 1, [0.0, 1.0]) > 1.0 - 1e-14);
        assert!(parallel(&v, 0, [1.0, 0.0]) > 1.0 - 1e-14 && parallel(&v, 1, [1.0, -1.5]) > 1.0 - 1e-14, "V = {v:?}");

        let (x, b) = (0.883896268, 0.3);
        let mu = [-1.92373886, 0.15594632];
        let (gs, clv, g, v) = ginelli_constant([[-2.0 * x, b], [1.0, 0.0]], 80, 40);
        for (got, want) in [(gs, [0.65427061, -1.85824342]), (clv, [0.65427061, -1.85824342])] {
            assert!((got[0] - want[0]).abs() < 1e-7 && (got[1] - want[1]).abs() < 1e-7, "{got:?}");
        }
        for (j, mu) in mu.into_iter().enumerate() {
            assert!(parallel(&v, j, [mu, 1.0]) > 1.0 - 1e-14, "v^{}: {v:?}", j + 1);
        }
        assert!(parallel(&g, 1, [mu[1], 1.0]) < 0.99, "g^2 is not an eigenvector");
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
        // Into a reused matrix, whatever it held (the backward stage's buffers).
        let mut into = Mat::from_fn(5, 5, |i, j| (100 + i * 5 + j) as f64);
        unpack_upper_into(&p, &mut into);
        for j in 0..5 {
            for i in 0..5 {
                assert_eq!(into[(i, j)], if i <= j { r[(i, j)] } else { (100 + i * 5 + j) as f64 }, "({i}, {j})");
            }
        }
    }
}
