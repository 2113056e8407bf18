//! Angles between vectors and subspaces (paper Secs. 5.1 and 5.6, Figs. 3, 4, 13-17).
//!
//! Transversality of Oseledec subspaces is judged by the smallest principal angle (Fig. 15:
//! Phi between a mode subspace and its conjugate, Psi between E^u and E^s) and by the angle
//! Theta = arccos |v^i . v^j| between single CLVs (Figs. 16, 17). The paper computes principal
//! angles from the singular values of Q1^T Q2 (Bjoerck & Golub); cosines lose accuracy for
//! small angles (an angle of 1e-9 has cos = 1 to machine precision), so, as Knyazev &
//! Argentati (the paper's ref.) recommend, angles below pi/4 are taken from the sines, the
//! singular values of Q1 - Q2 (Q2^T Q1). Fig. 17 is about exactly such small angles.

use super::vecset;
use std::f64::consts::FRAC_PI_4;

/// Principal angles between span(a) and span(b), both column-major sets of vectors of
/// length `d` with full column rank (paper Sec. 5.6: "singular values of M = Q^T Q* are equal
/// to the cosines of the principal angles"). Returns min(ka, kb) angles in radians,
/// ascending, in [0, pi/2]; all NaN if an input is non-finite; empty if a set is empty.
pub fn principal_angles(a: &[f64], b: &[f64], d: usize) -> Vec<f64> {
    let (ka, kb) = (vecset::count(a, d), vecset::count(b, d));
    // the smaller set goes first so that Q1 - Q2 Q2^T Q1 has one sine per angle
    let (small, large, k) = if ka <= kb { (a, b, ka) } else { (b, a, kb) };
    if k == 0 {
        return Vec::new();
    }
    let (Some(q1), Some(q2)) = (vecset::orthonormal_basis(small, d), vecset::orthonormal_basis(large, d)) else {
        return vec![f64::NAN; k];
    };
    let mt = vecset::mul_tn(q2.as_ref(), q1.as_ref()); // Q2^T Q1, kl x k
    let residual = vecset::sub_mul(q1.as_ref(), q2.as_ref(), mt.as_ref()); // Q1 - Q2 Q2^T Q1
    let (Some(cos), Some(sin)) = (vecset::singular_values(mt.as_ref()), vecset::singular_values(residual.as_ref())) else {
        return vec![f64::NAN; k];
    };
    // cos descending <-> angles ascending; sin descending <-> angles descending
    (0..k)
        .map(|i| {
            let c = cos[i].clamp(0.0, 1.0);
            let s = sin[k - 1 - i].clamp(0.0, 1.0);
            let from_cos = c.acos();
            if from_cos < FRAC_PI_4 { s.asin() } else { from_cos }
        })
        .collect()
}

/// Smallest principal angle between span(a) and span(b) (paper Fig. 15, Phi and Psi).
pub fn min_principal_angle(a: &[f64], b: &[f64], d: usize) -> f64 {
    principal_angles(a, b, d).first().copied().unwrap_or(f64::NAN)
}

/// Largest principal angle between span(a) and span(b): zero iff the smaller span lies in
/// the larger one (used for the null-space check, paper Sec. 5.4).
pub fn max_principal_angle(a: &[f64], b: &[f64], d: usize) -> f64 {
    principal_angles(a, b, d).last().copied().unwrap_or(f64::NAN)
}

/// Theta(u, v) = arccos(|u . v| / (|u| |v|)) in [0, pi/2] (paper Sec. 5.6, Figs. 16, 17: "the
/// angle Theta = cos^-1 |v^i . v^j|"). Computed as 2 asin(|u/|u| -+ v/|v||/2), which is
/// accurate also for tiny angles. NaN for a zero or non-finite vector.
pub fn vector_angle(u: &[f64], v: &[f64]) -> f64 {
    let (nu, nv) = (vecset::norm(u), vecset::norm(v));
    if !(nu.is_finite() && nv.is_finite() && nu > 0.0 && nv > 0.0) {
        return f64::NAN;
    }
    let sign = if vecset::dot(u, v) < 0.0 { -1.0 } else { 1.0 };
    let dist = u.iter().zip(v).map(|(x, y)| (x / nu - sign * y / nv).powi(2)).sum::<f64>().sqrt();
    2.0 * (dist / 2.0).min(1.0).asin()
}

/// Absolute dot products |a_j . b_j| of corresponding vectors of two equally long sets (paper
/// Fig. 3: |g^i . v^i| for each index i).
pub fn abs_dots_pairwise(a: &[f64], b: &[f64], d: usize) -> Vec<f64> {
    let k = vecset::count(a, d);
    assert_eq!(k, vecset::count(b, d), "sets of different size");
    (0..k).map(|j| vecset::dot(vecset::col(a, d, j), vecset::col(b, d, j)).abs()).collect()
}

/// Absolute dot products |x . s_i| of one vector with every vector of a set (paper Figs. 4,
/// 13, 14: |v^j . g^i| or |v^j . v^i| as a function of i).
pub fn abs_dots_with(x: &[f64], set: &[f64]) -> Vec<f64> {
    let d = x.len();
    (0..vecset::count(set, d)).map(|i| vecset::dot(x, vecset::col(set, d, i)).abs()).collect()
}

/// 0-based index of the conjugate partner of 0-based index `i` in a spectrum of `d`
/// exponents: paper index 4N+1-i becomes d-1-i.
pub fn conjugate_index(i: usize, d: usize) -> usize {
    d - 1 - i
}

/// Smallest principal angle between span{v_i : i in first..first+len} and its conjugate
/// span{v_{d-1-i}} within a full set of d vectors of length d (paper Fig. 15, Phi for the mode
/// subspaces E^(X) and E^(X)*; paper indices first+1 .. first+len and their conjugates).
pub fn min_angle_conjugate(vectors: &[f64], d: usize, first: usize, len: usize) -> f64 {
    let k = vecset::count(vectors, d);
    assert!(k == d, "need the full set of {d} vectors, got {k}");
    let lo = conjugate_index(first + len - 1, d);
    assert!(first + len <= lo, "subspace {first}..{} overlaps its conjugate", first + len);
    let a = &vectors[first * d..(first + len) * d];
    let b = &vectors[lo * d..(lo + len) * d];
    min_principal_angle(a, b, d)
}

/// Smallest principal angle between the unstable subspace span{v_1..v_m} and the stable
/// subspace span{v_{D-m+1}..v_D} (paper indices; 0-based 0..m and d-m..d) of a full set of d
/// CLVs (paper Fig. 15, Psi, with m = 2N-3).
pub fn min_angle_unstable_stable(vectors: &[f64], d: usize, m: usize) -> f64 {
    min_angle_conjugate(vectors, d, 0, m)
}

#[cfg(test)]
mod tests {
    use super::super::testutil::{Rng, normalized};
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn unit(d: usize, i: usize) -> Vec<f64> {
        let mut e = vec![0.0; d];
        e[i] = 1.0;
        e
    }

    #[test]
    fn identical_spans_give_zero_angles() {
        let mut rng = Rng::new(4);
        let d = 9;
        let a = rng.normals(3 * d);
        // b: different basis of the same span
        let mut b = Vec::new();
        for (c0, c1, c2) in [(1.0, 2.0, -1.0), (0.5, 0.0, 3.0), (-1.0, 1.0, 1.0)] {
            b.extend((0..d).map(|r| c0 * a[r] + c1 * a[d + r] + c2 * a[2 * d + r]));
        }
        let t = principal_angles(&a, &b, d);
        assert_eq!(t.len(), 3);
        assert!(t.iter().all(|x| x.abs() < 1e-12), "{t:?}");
    }

    #[test]
    fn rotated_plane_gives_zero_and_a() {
        let d = 5;
        for a in [0.3, 1.2, 1e-9, FRAC_PI_2 - 1e-9] {
            let s1 = [unit(d, 0), unit(d, 1)].concat();
            let rot: Vec<f64> = (0..d).map(|r| a.cos() * unit(d, 1)[r] + a.sin() * unit(d, 2)[r]).collect();
            let s2 = [unit(d, 0), rot].concat();
            let t = principal_angles(&s1, &s2, d);
            assert!(t[0].abs() < 1e-15, "{t:?}");
            assert!((t[1] - a).abs() < 1e-14 * a.max(1e-3), "a = {a}: {t:?}");
        }
    }

    #[test]
    fn orthogonal_spaces_give_right_angles() {
        let d = 6;
        let s1 = [unit(d, 0), unit(d, 1)].concat();
        let s2 = [unit(d, 2), unit(d, 3), unit(d, 4)].concat();
        let t = principal_angles(&s1, &s2, d);
        assert_eq!(t.len(), 2);
        assert!(t.iter().all(|x| (x - FRAC_PI_2).abs() < 1e-15));
        assert!(principal_angles(&[f64::NAN; 6], &s2, d).iter().all(|x| x.is_nan()));
    }

    #[test]
    fn vector_angle_small_and_sign_blind() {
        let d = 4;
        let a: f64 = 1e-10;
        let u = unit(d, 0);
        let v: Vec<f64> = (0..d).map(|r| -(a.cos() * unit(d, 0)[r] + a.sin() * unit(d, 3)[r])).collect();
        assert!((vector_angle(&u, &v) - a).abs() < 1e-22);
        assert!((vector_angle(&u, &unit(d, 2)) - FRAC_PI_2).abs() < 1e-15);
        let w = [0.6, 0.8, 0.0, 0.0];
        assert!((vector_angle(&u, &w) - 0.6f64.acos()).abs() < 1e-15);
    }

    #[test]
    fn unstable_stable_angle_of_constructed_frame() {
        // d = 4: v1 = e0, v2 = e1, v3 = (cos a e1 + sin a e2), v4 = e3 -> m = 1 pairs v1, v4;
        // conjugate of {v2} is {v3}; their angle is a.
        let d = 4;
        let a: f64 = 0.2;
        let v3: Vec<f64> = (0..d).map(|r| a.cos() * unit(d, 1)[r] + a.sin() * unit(d, 2)[r]).collect();
        let frame = [unit(d, 0), unit(d, 1), v3, unit(d, 3)].concat();
        assert!((min_angle_unstable_stable(&frame, d, 1) - FRAC_PI_2).abs() < 1e-15);
        assert!((min_angle_conjugate(&frame, d, 1, 1) - a).abs() < 1e-15);
        assert_eq!(conjugate_index(0, d), 3);
    }

    #[test]
    fn dot_helpers() {
        let mut rng = Rng::new(5);
        let d = 6;
        let a: Vec<f64> = (0..3).flat_map(|_| normalized(rng.normals(d))).collect();
        let dots = abs_dots_pairwise(&a, &a, d);
        assert!(dots.iter().all(|x| (x - 1.0).abs() < 1e-14));
        let with = abs_dots_with(vecset::col(&a, d, 1), &a);
        assert!((with[1] - 1.0).abs() < 1e-14 && with.len() == 3);
    }
}
