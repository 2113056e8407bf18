//! Free flight and the linearised collision map of hard disks, applied to the k tangent
//! vectors of one or two particles.
//!
//! The rows of a particle are [dq_x; dq_y; dp_x; dp_y], each holding all k vectors, so both
//! maps are a handful of contiguous sweeps of length k: O(k) per collision, never O(D k).
//! Reduced units sigma = m = 1, hence dp = dv.

use std::ops::Range;

/// Tangent free flight over dt: dq += dp dt (m = 1), for the vectors (columns) in `cols` of
/// one particle's rows (row stride k).
pub fn fly(rows: &mut [f64], k: usize, cols: Range<usize>, dt: f64) {
    let (q, p) = rows.split_at_mut(2 * k);
    let (qx, qy) = q.split_at_mut(k);
    fly_rows([&mut qx[cols.clone()], &mut qy[cols.clone()]], [&p[cols.clone()], &p[k..][cols]], dt);
}

/// [`fly`] on one particle's rows given one by one: dq_x += dp_x dt, dq_y += dp_y dt.
pub fn fly_rows(dq: [&mut [f64]; 2], dp: [&[f64]; 2], dt: f64) {
    if dt == 0.0 {
        return;
    }
    let [dqx, dqy] = dq;
    dispatch!(axpy(dqx, dp[0], dt));
    dispatch!(axpy(dqy, dp[1], dt));
}

/// Linearised elastic collision of disks i and j at contact (Dellago, Posch & Hoover,
/// PRE 53, 1485 (1996); DESIGN.md), with the unit normal n = q_ij/|q_ij|, the pre-collision
/// relative velocity v = v_i - v_j and vn = v.n < 0:
///
/// ```text
/// dt_c = -(dq_ij.n)/vn,   dn = (dq_ij + v dt_c)/sigma
/// dq_i' = dq_i - (dq_ij.n) n                      dq_j' = dq_j + (dq_ij.n) n
/// dp_i' = dp_i - [(dp_ij.n) n + (v.dn) n + vn dn]  dp_j' = dp_j + [same]
/// ```
///
/// Applied to the vectors (columns) in `cols`; every column sees the same operations in the
/// same order whatever the range, so blocked and unblocked application agree bit for bit.
#[allow(clippy::too_many_arguments)]
pub fn collide(ri: &mut [f64], rj: &mut [f64], k: usize, cols: Range<usize>, n: [f64; 2], v: [f64; 2], vn: f64) {
    let (qxi, rest) = ri.split_at_mut(k);
    let (qyi, rest) = rest.split_at_mut(k);
    let (pxi, pyi) = rest.split_at_mut(k);
    let (qxj, rest) = rj.split_at_mut(k);
    let (qyj, rest) = rest.split_at_mut(k);
    let (pxj, pyj) = rest.split_at_mut(k);
    let c = cols;
    let rows = [
        &mut qxi[c.clone()],
        &mut qyi[c.clone()],
        &mut pxi[c.clone()],
        &mut pyi[c.clone()],
        &mut qxj[c.clone()],
        &mut qyj[c.clone()],
        &mut pxj[c.clone()],
        &mut pyj[c],
    ];
    collide_rows(rows, n, v, vn);
}

/// [`collide`] on the rows given one by one: [dq_x, dq_y, dp_x, dp_y] of i, then of j,
/// all of the same length.
pub fn collide_rows(rows: [&mut [f64]; 8], n: [f64; 2], v: [f64; 2], vn: f64) {
    dispatch!(collide_kernel(rows, n, v, vn));
}

/// Run a kernel through its AVX2 build where the CPU has it. Only vector width changes, not
/// the operations: Rust never contracts a * b + c into an FMA, so both builds round alike.
macro_rules! dispatch {
    ($kernel:ident($($arg:expr),*)) => {{
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                unsafe { avx2::$kernel($($arg),*) }
            } else {
                portable::$kernel($($arg),*)
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            portable::$kernel($($arg),*)
        }
    }};
}
use dispatch;

/// The kernels, written so that the compiler can vectorise them (equal-length slices, no
/// bounds checks in the loop); compiled once for the baseline and once with AVX2.
macro_rules! kernels {
    ($($attr:meta)?) => {
        $(#[$attr])?
        pub fn axpy(dq: &mut [f64], dp: &[f64], dt: f64) {
            for (q, p) in dq.iter_mut().zip(dp) {
                *q += p * dt;
            }
        }

        $(#[$attr])?
        pub fn collide_kernel(rows: [&mut [f64]; 8], n: [f64; 2], v: [f64; 2], vn: f64) {
            let [qxi, qyi, pxi, pyi, qxj, qyj, pxj, pyj] = rows;
            let m = qxi.len();
            let (qyi, pxi, pyi) = (&mut qyi[..m], &mut pxi[..m], &mut pyi[..m]);
            let (qxj, qyj, pxj, pyj) = (&mut qxj[..m], &mut qyj[..m], &mut pxj[..m], &mut pyj[..m]);
            let [nx, ny] = n;
            let [vx, vy] = v;
            let inv_vn = 1.0 / vn;
            for c in 0..m {
                let dqx = qxi[c] - qxj[c];
                let dqy = qyi[c] - qyj[c];
                let dqn = dqx * nx + dqy * ny;
                let dtc = -dqn * inv_vn;
                let dnx = dqx + vx * dtc;
                let dny = dqy + vy * dtc;
                let dpn = (pxi[c] - pxj[c]) * nx + (pyi[c] - pyj[c]) * ny;
                let vdn = vx * dnx + vy * dny;
                let s = dpn + vdn;
                let ex = s * nx + vn * dnx;
                let ey = s * ny + vn * dny;
                qxi[c] -= dqn * nx;
                qyi[c] -= dqn * ny;
                qxj[c] += dqn * nx;
                qyj[c] += dqn * ny;
                pxi[c] -= ex;
                pyi[c] -= ey;
                pxj[c] += ex;
                pyj[c] += ey;
            }
        }
    };
}

mod portable {
    kernels!();
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    kernels!(target_feature(enable = "avx2"));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 build of the kernels gives the same bits as the portable one, so runs do not
    /// depend on which the CPU takes.
    #[test]
    #[cfg(target_arch = "x86_64")]
    fn vector_build_rounds_like_the_portable_one() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = crate::rng::Rng::new(3);
        let k = 37;
        let data: Vec<f64> = (0..8 * k).map(|_| rng.normal()).collect();
        let (mut a, mut b) = (data.clone(), data.clone());
        fn split(x: &mut [f64], k: usize) -> [&mut [f64]; 8] {
            let mut it = x.chunks_mut(k);
            std::array::from_fn(|_| it.next().unwrap())
        }
        let (n, v, vn) = ([0.6, -0.8], [1.3, 0.2], 0.6 * 1.3 - 0.8 * 0.2 - 1.5);
        portable::collide_kernel(split(&mut a, k), n, v, vn);
        // SAFETY: AVX2 is present (checked above).
        unsafe { avx2::collide_kernel(split(&mut b, k), n, v, vn) };
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        let (mut c, mut d) = (data[..k].to_vec(), data[..k].to_vec());
        portable::axpy(&mut c, &data[k..2 * k], 0.37);
        // SAFETY: as above.
        unsafe { avx2::axpy(&mut d, &data[k..2 * k], 0.37) };
        assert!(c.iter().zip(&d).all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    /// The independently computed 8 x 8 collision matrix of tests/fixtures: apply the map
    /// to each unit vector of (dq1, dq2, dp1, dp2) and compare column by column.
    #[test]
    fn matches_fixture_collision_matrix() {
        let f: serde_json::Value = serde_json::from_str(include_str!("../../../tests/fixtures/two-disk-collision.json")).unwrap();
        let m: Vec<Vec<f64>> = serde_json::from_value(f["collision_matrix"].clone()).unwrap();
        let n: [f64; 2] = serde_json::from_value(f["normal"].clone()).unwrap();
        let v0: Vec<[f64; 2]> = serde_json::from_value(f["vel0"].clone()).unwrap();
        let v = [v0[0][0] - v0[1][0], v0[0][1] - v0[1][1]];
        let vn = v[0] * n[0] + v[1] * n[1];
        assert!((vn - f["v12_dot_n"].as_f64().unwrap()).abs() < 1e-12);
        // Fixture order (dq1, dq2, dp1, dp2) -> our per-particle rows [dq; dp], k = 8 columns.
        let ours = |a: usize| match a {
            0..=1 => (0, a),
            2..=3 => (1, a - 2),
            4..=5 => (0, a - 2),
            _ => (1, a - 4),
        };
        let k = 8;
        let (mut ri, mut rj) = (vec![0.0; 4 * k], vec![0.0; 4 * k]);
        for col in 0..8 {
            let (p, r) = ours(col);
            if p == 0 { ri[r * k + col] = 1.0 } else { rj[r * k + col] = 1.0 }
        }
        collide(&mut ri, &mut rj, k, 0..k, n, v, vn);
        for row in 0..8 {
            for col in 0..8 {
                let (p, r) = ours(row);
                let got = if p == 0 { ri[r * k + col] } else { rj[r * k + col] };
                assert!((got - m[row][col]).abs() < 1e-12, "M[{row}][{col}]: {got} vs {}", m[row][col]);
            }
        }
    }
}
