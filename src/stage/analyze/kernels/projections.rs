//! Position/momentum content of tangent vectors (paper Sec. 5.3, Figs. 6, 7 and 9).
//!
//! eta_q and eta_p are the squared projections onto the configuration subspace Q and the
//! momentum subspace P; for GS vectors they are interchanged between conjugate indices i and
//! 4N+1-i, for CLVs they agree. cos Theta measures how parallel dq and dp are.
//!
//! cos Theta is the *signed* cosine. The paper's Fig. 9 caption defines the plotted quantity
//! as "Time averaged value of cos(Theta) = (dq . dp) / (|dq| |dp|)", and the text says it
//! "converges to +1 for the smallest positive, and to -1 for the smallest negative
//! exponents", which |cos| could not do. Averaging the signed value is meaningful because it
//! is invariant under the irrelevant sign flip v -> -v (both dq and dp flip).

/// Squared projections (eta_q, eta_p) = (sum_n |dq_n|^2, sum_n |dp_n|^2) of a tangent vector
/// of length 4N (paper Sec. 5.3, equation for eta_q, eta_p before time averaging). Their sum
/// is |v|^2 = 1 for unit vectors; no renormalisation is done.
pub fn eta_q_p(v: &[f64]) -> (f64, f64) {
    assert!(v.len().is_multiple_of(4), "tangent vector length {} is not 4N", v.len());
    let (dq, dp) = v.split_at(v.len() / 2);
    (dq.iter().map(|x| x * x).sum(), dp.iter().map(|x| x * x).sum())
}

/// Signed cosine of the angle Theta between the 2N-vectors dq and dp of `v` (paper Fig. 9:
/// cos Theta = dq . dp / (|dq| |dp|)), in [-1, 1]. NaN if dq or dp vanishes or is non-finite.
pub fn cos_theta(v: &[f64]) -> f64 {
    assert!(v.len().is_multiple_of(4), "tangent vector length {} is not 4N", v.len());
    let (dq, dp) = v.split_at(v.len() / 2);
    let qq: f64 = dq.iter().map(|x| x * x).sum();
    let pp: f64 = dp.iter().map(|x| x * x).sum();
    let qp: f64 = dq.iter().zip(dp).map(|(a, b)| a * b).sum();
    let denom = (qq * pp).sqrt();
    if !(denom.is_finite() && denom > 0.0) {
        return f64::NAN;
    }
    (qp / denom).clamp(-1.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::super::testutil::{Rng, normalized};
    use super::*;

    fn join(dq: &[f64], dp: &[f64]) -> Vec<f64> {
        dq.iter().chain(dp).copied().collect()
    }

    #[test]
    fn eta_sums_to_one() {
        let mut rng = Rng::new(2);
        let v = normalized(rng.normals(40));
        let (q, p) = eta_q_p(&v);
        assert!((q + p - 1.0).abs() < 1e-14);
        assert!(q > 0.1 && p > 0.1);
        let mut pure_q = normalized(rng.normals(20));
        pure_q.extend(vec![0.0; 20]);
        assert_eq!(eta_q_p(&pure_q).1, 0.0);
        assert!((eta_q_p(&pure_q).0 - 1.0).abs() < 1e-14);
    }

    #[test]
    fn cos_theta_of_constructed_vectors() {
        let mut rng = Rng::new(3);
        let a = rng.normals(8);
        let equal = join(&a, &a);
        assert!((cos_theta(&equal) - 1.0).abs() < 1e-14);
        let neg: Vec<f64> = a.iter().map(|x| -2.0 * x).collect();
        assert!((cos_theta(&join(&a, &neg)) + 1.0).abs() < 1e-14);
        // b orthogonal to a
        let mut b = rng.normals(8);
        let c = b.iter().zip(&a).map(|(x, y)| x * y).sum::<f64>() / a.iter().map(|x| x * x).sum::<f64>();
        for (x, y) in b.iter_mut().zip(&a) {
            *x -= c * y;
        }
        assert!(cos_theta(&join(&a, &b)).abs() < 1e-14);
        // sign flip of the whole vector leaves the signed cosine unchanged
        let v = join(&a, &rng.normals(8));
        let minus: Vec<f64> = v.iter().map(|x| -x).collect();
        assert!((cos_theta(&v) - cos_theta(&minus)).abs() < 1e-15);
        assert!(cos_theta(&join(&a, &[0.0; 8])).is_nan());
    }
}
