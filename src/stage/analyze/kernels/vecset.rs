//! Column-major sets of vectors: views, dot products and orthonormal bases.
//!
//! Every analysis reads frames as column-major D x k slices; these helpers keep the index
//! arithmetic and the faer calls in one place. All faer calls run sequentially (`Par::Seq`),
//! not with faer's global parallelism: analyses run as concurrent frame consumers and must
//! not fight the forward/backward stages for threads.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::qr::no_pivoting::factor;
use faer::linalg::{householder, matmul, svd};
use faer::diag::Diag;
use faer::{Accum, Conj, Mat, MatRef, Par};

/// Column j of a column-major set of vectors of length `d`.
pub fn col(data: &[f64], d: usize, j: usize) -> &[f64] {
    &data[j * d..(j + 1) * d]
}

/// Number of vectors of length `d` in `data` (panics if `d` does not divide the length).
pub fn count(data: &[f64], d: usize) -> usize {
    assert!(d > 0 && data.len().is_multiple_of(d), "vector set of length {} is not a multiple of {d}", data.len());
    data.len() / d
}

/// Euclidean dot product.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Sum of squares.
pub fn norm_sq(a: &[f64]) -> f64 {
    a.iter().map(|x| x * x).sum()
}

/// Euclidean norm.
pub fn norm(a: &[f64]) -> f64 {
    norm_sq(a).sqrt()
}

/// True if every entry is finite.
pub fn all_finite(a: &[f64]) -> bool {
    a.iter().all(|x| x.is_finite())
}

/// faer view of a column-major d x k set.
pub fn as_mat(data: &[f64], d: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(data, d, count(data, d))
}

/// Thin Householder QR of an m x n matrix: Q (m x min(m, n), orthonormal columns) and R
/// (min(m, n) x n, upper triangular; diagonal signs as Householder leaves them).
pub fn thin_qr(a: MatRef<'_, f64>) -> (Mat<f64>, Mat<f64>) {
    let (m, n) = a.shape();
    let size = m.min(n);
    let mut qr = a.to_owned();
    let bs = factor::recommended_block_size::<f64>(m, n);
    let mut coeff = Mat::zeros(bs, size);
    let req = factor::qr_in_place_scratch::<f64>(m, n, bs, Par::Seq, Default::default());
    factor::qr_in_place(qr.as_mut(), coeff.as_mut(), Par::Seq, MemStack::new(&mut MemBuffer::new(req)), Default::default());
    let r = Mat::from_fn(size, n, |i, j| if i <= j { qr[(i, j)] } else { 0.0 });
    // unit lower-trapezoidal Householder basis, as faer's own Qr keeps it
    let basis = Mat::from_fn(m, size, |i, j| match i.cmp(&j) {
        std::cmp::Ordering::Less => 0.0,
        std::cmp::Ordering::Equal => 1.0,
        std::cmp::Ordering::Greater => qr[(i, j)],
    });
    let mut q = Mat::identity(m, size);
    let req = householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(m, bs, size);
    householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
        basis.as_ref(),
        coeff.as_ref(),
        Conj::No,
        q.as_mut(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(req)),
    );
    (q, r)
}

/// Singular values of a matrix in non-increasing order; `None` if the SVD fails.
pub fn singular_values(a: MatRef<'_, f64>) -> Option<Vec<f64>> {
    let (m, n) = a.shape();
    let mut s = Diag::<f64>::zeros(m.min(n));
    let no = svd::ComputeSvdVectors::No;
    let req = svd::svd_scratch::<f64>(m, n, no, no, Par::Seq, Default::default());
    svd::svd(a, s.as_mut(), None, None, Par::Seq, MemStack::new(&mut MemBuffer::new(req)), Default::default()).ok()?;
    let mut out: Vec<f64> = s.column_vector().iter().copied().collect();
    out.sort_by(|x, y| y.total_cmp(x));
    Some(out)
}

/// a^T b (sequential).
pub fn mul_tn(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(a.ncols(), b.ncols());
    matmul::matmul(out.as_mut(), Accum::Replace, a.transpose(), b, 1.0, Par::Seq);
    out
}

/// c - a b (sequential).
pub fn sub_mul(c: MatRef<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = c.to_owned();
    matmul::matmul(out.as_mut(), Accum::Add, a, b, -1.0, Par::Seq);
    out
}

/// Orthonormal basis (thin Q of a Householder QR, d x k) of the span of the k columns.
/// The columns must be linearly independent (k <= d) for the span to be preserved; `None` if
/// the input has a non-finite entry.
pub fn orthonormal_basis(data: &[f64], d: usize) -> Option<Mat<f64>> {
    if !all_finite(data) {
        return None;
    }
    let a = as_mat(data, d);
    if a.ncols() == 0 {
        return Some(Mat::zeros(d, 0));
    }
    Some(thin_qr(a).0)
}

/// Squared norm of the orthogonal projection of `x` onto the span of the orthonormal columns
/// of `q`: sum_j (q_j . x)^2.
pub fn projected_norm_sq(q: MatRef<'_, f64>, x: &[f64]) -> f64 {
    (0..q.ncols())
        .map(|j| {
            let c: f64 = q.col(j).iter().zip(x).map(|(a, b)| a * b).sum();
            c * c
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orthonormal_basis_spans_input() {
        let d = 5;
        let data = [1.0, 2.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 3.0, 0.0];
        let q = orthonormal_basis(&data, d).unwrap();
        for i in 0..2 {
            for j in 0..2 {
                let g: f64 = q.col(i).iter().zip(q.col(j).iter()).map(|(a, b)| a * b).sum();
                assert!((g - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
            let c = col(&data, d, i);
            assert!((projected_norm_sq(q.as_ref(), c) - norm_sq(c)).abs() < 1e-12);
        }
        assert!(orthonormal_basis(&[f64::NAN, 1.0], 2).is_none());
    }

    #[test]
    fn qr_reproduces_matrix_and_svd_is_sorted() {
        let d = 7;
        let data: Vec<f64> = (0..21).map(|i| ((i * 37 % 11) as f64 - 5.0) / 3.0).collect();
        let a = as_mat(&data, d);
        let (q, r) = thin_qr(a);
        let back = sub_mul(a, q.as_ref(), r.as_ref());
        assert!(back.norm_max() < 1e-13);
        let qtq = mul_tn(q.as_ref(), q.as_ref());
        for i in 0..3 {
            for j in 0..3 {
                assert!((qtq[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
        let m = Mat::from_fn(2, 2, |i, j| [[3.0, 0.0], [0.0, -5.0]][i][j]);
        let s = singular_values(m.as_ref()).unwrap();
        assert!((s[0] - 5.0).abs() < 1e-14 && (s[1] - 3.0).abs() < 1e-14, "{s:?}");
    }
}
