//! The null space (central manifold) N of the six vanishing exponents (paper Sec. 5.4,
//! Tables I and II).
//!
//! Time translation, the two space translations and their conjugates (energy and total
//! momentum changes) generate six vectors e_1..e_6 that span N; the six GS or covariant
//! vectors with paper indices 2N-2..2N+3 must span exactly the same space, and every other
//! vector must be orthogonal to it. The projection matrices alpha (GS) and beta (CLV) show how
//! the null vectors are composed of the e_k.

use super::{angles, vecset};

/// The six null vectors e_1..e_6 of the paper (Sec. 5.4) at a phase point of N disks,
/// column-major 4N x 6 (column k-1 is e_k):
/// e_1 = (p; 0)/sqrt(2K), e_2 = (1_x; 0)/sqrt(N), e_3 = (1_y; 0)/sqrt(N),
/// e_4 = (0; p)/sqrt(2K), e_5 = (0; 1_x)/sqrt(N), e_6 = (0; 1_y)/sqrt(N),
/// with 2K = sum |p_n|^2 (m = 1), so every e_k has unit norm. They are mutually orthogonal
/// (the paper's "six orthogonal spanning vectors") when the total momentum is zero, as in the
/// paper; otherwise e_1 . e_2 = P_x / (sqrt(2K N)) and likewise for e_3, e_4/e_5, e_4/e_6.
/// No Gram-Schmidt is applied, so the columns are exactly the paper's e_k.
pub fn null_vectors(phase: &[f64]) -> Vec<f64> {
    assert!(phase.len().is_multiple_of(4), "phase point length {} is not 4N", phase.len());
    let d = phase.len();
    let n = d / 4;
    let p = &phase[2 * n..];
    let inv_p = 1.0 / vecset::norm(p);
    let inv_n = 1.0 / (n as f64).sqrt();
    let mut e = vec![0.0; 6 * d];
    for half in 0..2 {
        // half 0: position block (e_1..e_3), half 1: momentum block (e_4..e_6)
        let off = half * 2 * n;
        let base = 3 * half * d;
        for i in 0..2 * n {
            e[base + off + i] = p[i] * inv_p;
        }
        for i in 0..n {
            e[base + d + off + 2 * i] = inv_n;
            e[base + 2 * d + off + 2 * i + 1] = inv_n;
        }
    }
    e
}

/// Projection matrix of a set of tangent vectors onto the null vectors: row j is
/// [x_j . e_1, ..., x_j . e_6] for vector j of `vectors` (column-major 4N x k). This is the
/// paper's signed alpha_{i,k} = g^i . e_k for GS vectors (Table I) and beta_{i,k} = v^i . e_k
/// for CLVs (Table II), Sec. 5.4: "alpha_{i,k} = g^i . e_k; beta_{i,k} = v^i . e_k". For the
/// six null vectors the squared entries of each row sum to 1; for all others they vanish.
pub fn null_projections(vectors: &[f64], phase: &[f64]) -> Vec<[f64; 6]> {
    let d = phase.len();
    let e = null_vectors(phase);
    (0..vecset::count(vectors, d))
        .map(|j| {
            let x = vecset::col(vectors, d, j);
            std::array::from_fn(|k| vecset::dot(x, vecset::col(&e, d, k)))
        })
        .collect()
}

/// Largest principal angle (radians) between the span of the given vectors (k <= 6,
/// column-major 4N x k, full rank) and span{e_1..e_6} (paper Sec. 5.4: the six null vectors
/// "completely span the null subspace"). Zero up to round-off iff every given vector lies in
/// the null space; pi/2 if some direction of their span is orthogonal to it.
pub fn null_space_angle(vectors: &[f64], phase: &[f64]) -> f64 {
    let d = phase.len();
    assert!(vecset::count(vectors, d) <= 6, "more than six vectors for a 6-dimensional space");
    angles::max_principal_angle(vectors, &null_vectors(phase), d)
}

#[cfg(test)]
mod tests {
    use super::super::testutil::{Rng, normalized, phase_point};
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn setup(n: usize, seed: u64) -> (Vec<f64>, Rng) {
        let mut rng = Rng::new(seed);
        let g = phase_point(n, 5.0, 3.0, &mut rng);
        (g, rng)
    }

    /// A unit vector orthogonal to all six e_k (they are orthonormal at zero total momentum).
    fn orthogonal_to_null(g: &[f64], rng: &mut Rng) -> Vec<f64> {
        let d = g.len();
        let e = null_vectors(g);
        let mut x = rng.normals(d);
        for k in 0..6 {
            let ek = vecset::col(&e, d, k);
            let c = vecset::dot(&x, ek);
            for (a, b) in x.iter_mut().zip(ek) {
                *a -= c * b;
            }
        }
        normalized(x)
    }

    #[test]
    fn null_vectors_are_orthonormal_at_zero_momentum() {
        let (g, _) = setup(9, 6);
        let d = g.len();
        let e = null_vectors(&g);
        for i in 0..6 {
            for j in 0..6 {
                let x = vecset::dot(vecset::col(&e, d, i), vecset::col(&e, d, j));
                assert!((x - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14, "e{} . e{} = {x}", i + 1, j + 1);
            }
        }
        // e_1 is the flow direction in q, e_2 a uniform x shift (paper definitions)
        assert!((e[0] - g[2 * 9] / vecset::norm(&g[18..])).abs() < 1e-15);
        assert!((e[d] - 1.0 / 3.0).abs() < 1e-15 && e[d + 1] == 0.0);
    }

    #[test]
    fn projections_of_null_vectors_are_identity() {
        let (g, _) = setup(5, 7);
        let alpha = null_projections(&null_vectors(&g), &g);
        for (i, row) in alpha.iter().enumerate() {
            for (k, &x) in row.iter().enumerate() {
                assert!((x - if i == k { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn orthogonal_vector_projects_to_zero_and_breaks_span() {
        let (g, mut rng) = setup(6, 8);
        let x = orthogonal_to_null(&g, &mut rng);
        assert!(null_projections(&x, &g)[0].iter().all(|c| c.abs() < 1e-14));
        let mut six = null_vectors(&g);
        let d = g.len();
        six[5 * d..].copy_from_slice(&x);
        assert!((null_space_angle(&six, &g) - FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn rotated_null_basis_spans_null_space() {
        // six orthonormal mixtures of e_1..e_6, like the GS null vectors of Table I
        let (g, mut rng) = setup(8, 9);
        let d = g.len();
        let e = null_vectors(&g);
        let mix = vecset::orthonormal_basis(&rng.normals(36), 6).unwrap();
        let mut g6 = vec![0.0; 6 * d];
        for j in 0..6 {
            for k in 0..6 {
                for r in 0..d {
                    g6[j * d + r] += mix[(k, j)] * e[k * d + r];
                }
            }
        }
        assert!(null_space_angle(&g6, &g) < 1e-13);
        for row in null_projections(&g6, &g) {
            assert!((row.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-13);
        }
        // a single vector tilted out of the null space by 1e-8 is detected
        let x = orthogonal_to_null(&g, &mut rng);
        let tilted: Vec<f64> = (0..d).map(|r| g6[r] + 1e-8 * x[r]).collect();
        assert!((null_space_angle(&tilted, &g) - 1e-8).abs() < 1e-15);
    }
}
