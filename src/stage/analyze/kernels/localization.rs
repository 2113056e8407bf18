//! Localization of tangent vectors in physical space (paper Sec. 5.2, Fig. 5).
//!
//! Each disk n carries the weight mu_n = |dq_n|^2 + |dp_n|^2 of a unit vector; the Shannon
//! entropy S = -sum mu_n ln mu_n of these weights is averaged over time, and the
//! Taniguchi-Morriss measure W = exp(<S>) / N runs from 1/N (one disk) to 1 (all disks).
//! Note that the paper averages S, not W: the accumulator keeps sums of S per vector index.

use super::vecset;

/// Per-disk weights mu_n = |dq_n|^2 + |dp_n|^2 of a tangent vector of length 4N (paper
/// Sec. 5.2, definition of mu_n). They sum to |v|^2, i.e. to 1 for a unit vector.
pub fn particle_weights(v: &[f64]) -> Vec<f64> {
    assert!(v.len().is_multiple_of(4), "tangent vector length {} is not 4N", v.len());
    let n = v.len() / 4;
    let (dq, dp) = v.split_at(2 * n);
    (0..n)
        .map(|i| dq[2 * i].powi(2) + dq[2 * i + 1].powi(2) + dp[2 * i].powi(2) + dp[2 * i + 1].powi(2))
        .collect()
}

/// Shannon entropy S = -sum_n mu_n ln mu_n of the weights of `v` (paper Sec. 5.2, the
/// quantity inside < > of S), with 0 ln 0 = 0. The weights are divided by |v|^2 so that a
/// slightly unnormalised vector still gives a probability distribution. Returns NaN for a
/// zero or non-finite vector.
pub fn entropy(v: &[f64]) -> f64 {
    let mu = particle_weights(v);
    let total: f64 = mu.iter().sum();
    if !(total.is_finite() && total > 0.0) {
        return f64::NAN;
    }
    -mu.iter()
        .map(|&m| m / total)
        .filter(|&m| m > 0.0)
        .map(|m| m * m.ln())
        .sum::<f64>()
}

/// Localization measure W = exp(S) / N for a (time-averaged) entropy S of N disks
/// (paper Sec. 5.2, equation for W); 1/N <= W <= 1.
pub fn localization_width(mean_entropy: f64, n_particles: usize) -> f64 {
    mean_entropy.exp() / n_particles as f64
}

/// Time average of the entropy S for each vector index of a stream of frames (paper Fig. 5:
/// W_i = exp(<S_i>) / N), with its standard error from the means of consecutive blocks of
/// frames (batch means). Non-finite entropies (NaN vectors) are skipped, each index
/// counting its own: that is why this is not [`crate::statistics::Accumulator`], whose
/// blocks count every step for every index.
#[derive(Clone, Debug)]
pub struct LocalizationAverage {
    n_particles: usize,
    sum: Vec<f64>,
    count: Vec<u64>,
    /// Frames per block, frames in the current block, its sums and counts.
    block_len: u64,
    in_block: u64,
    block_sum: Vec<f64>,
    block_count: Vec<u64>,
    /// Mean entropy of every completed block, per index.
    block_means: Vec<Vec<f64>>,
}

impl LocalizationAverage {
    /// Accumulator for frames of `n_vectors` tangent vectors of N = `n_particles` disks, with
    /// blocks of `block_len` frames for the errors.
    pub fn new(n_particles: usize, n_vectors: usize, block_len: u64) -> Self {
        LocalizationAverage {
            n_particles,
            sum: vec![0.0; n_vectors],
            count: vec![0; n_vectors],
            block_len: block_len.max(1),
            in_block: 0,
            block_sum: vec![0.0; n_vectors],
            block_count: vec![0; n_vectors],
            block_means: Vec::new(),
        }
    }

    /// Add the entropy of vector `index` (0-based; paper index `index + 1`).
    pub fn add_vector(&mut self, index: usize, v: &[f64]) {
        debug_assert_eq!(v.len(), 4 * self.n_particles);
        let s = entropy(v);
        if s.is_finite() {
            self.sum[index] += s;
            self.count[index] += 1;
            self.block_sum[index] += s;
            self.block_count[index] += 1;
        }
    }

    /// Add a frame: column-major 4N x k vectors, vector j counted as index j (k <= n_vectors).
    pub fn add_frame(&mut self, vectors: &[f64]) {
        let d = 4 * self.n_particles;
        for j in 0..vecset::count(vectors, d) {
            self.add_vector(j, vecset::col(vectors, d, j));
        }
        self.in_block += 1;
        if self.in_block == self.block_len {
            let means = self.block_sum.iter().zip(&self.block_count).map(|(&s, &c)| if c > 0 { s / c as f64 } else { f64::NAN }).collect();
            self.block_means.push(means);
            self.block_sum.iter_mut().for_each(|s| *s = 0.0);
            self.block_count.iter_mut().for_each(|c| *c = 0);
            self.in_block = 0;
        }
    }

    /// Standard error of <S_i> from the spread of the block means (NaN with fewer than two
    /// blocks that saw the index).
    pub fn entropy_stderr(&self) -> Vec<f64> {
        (0..self.sum.len())
            .map(|i| {
                let means: Vec<f64> = self.block_means.iter().map(|b| b[i]).filter(|m| m.is_finite()).collect();
                crate::statistics::standard_error(&means)
            })
            .collect()
    }

    /// Standard error of W_i = exp(<S_i>) / N: W_i times that of <S_i>.
    pub fn width_stderr(&self) -> Vec<f64> {
        self.widths().iter().zip(self.entropy_stderr()).map(|(w, e)| w * e).collect()
    }

    /// Time-averaged entropy <S_i> per index (NaN where nothing was added).
    pub fn mean_entropy(&self) -> Vec<f64> {
        self.sum.iter().zip(&self.count).map(|(&s, &c)| if c > 0 { s / c as f64 } else { f64::NAN }).collect()
    }

    /// Localization spectrum W_i = exp(<S_i>) / N (paper Fig. 5; NaN where nothing was added).
    pub fn widths(&self) -> Vec<f64> {
        self.mean_entropy().into_iter().map(|s| localization_width(s, self.n_particles)).collect()
    }

    /// Number of frames that contributed to each index.
    pub fn counts(&self) -> &[u64] {
        &self.count
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::{Rng, normalized};
    use super::*;

    #[test]
    fn single_disk_vector_has_w_one_over_n() {
        let n = 10;
        let mut v = vec![0.0; 4 * n];
        // disk 3: dq and dp components only
        v[2 * 3] = 0.6;
        v[2 * n + 2 * 3 + 1] = 0.8;
        assert_eq!(entropy(&v), 0.0);
        assert!((localization_width(entropy(&v), n) - 0.1).abs() < 1e-15);
    }

    #[test]
    fn uniform_vector_has_w_one() {
        let n = 7;
        let mut rng = Rng::new(1);
        // every disk gets weight 1/N, distributed randomly over its four components
        let mut v = vec![0.0; 4 * n];
        for i in 0..n {
            let c = normalized(rng.normals(4));
            v[2 * i] = c[0];
            v[2 * i + 1] = c[1];
            v[2 * n + 2 * i] = c[2];
            v[2 * n + 2 * i + 1] = c[3];
        }
        let v = normalized(v);
        let mu = particle_weights(&v);
        assert!(mu.iter().all(|m| (m - 1.0 / n as f64).abs() < 1e-14));
        assert!((entropy(&v) - (n as f64).ln()).abs() < 1e-13);
        assert!((localization_width(entropy(&v), n) - 1.0).abs() < 1e-13);
    }

    #[test]
    fn two_disks_half_each() {
        let n = 4;
        let mut v = vec![0.0; 4 * n];
        v[0] = 0.5f64.sqrt();
        v[2 * n + 5] = -(0.5f64.sqrt());
        assert!((entropy(&v) - 2f64.ln()).abs() < 1e-15);
        assert!((localization_width(entropy(&v), n) - 0.5).abs() < 1e-15);
    }

    /// Two vectors of 4 disks: one on a single disk (S = 0), one spread evenly (|v|^2 = 4,
    /// S = ln 4).
    fn local_and_spread() -> (Vec<f64>, Vec<f64>) {
        let mut local = vec![0.0; 16];
        local[1] = 1.0;
        (local, vec![0.5; 16])
    }

    #[test]
    fn accumulator_averages_entropy_not_width() {
        let n = 4;
        let d = 4 * n;
        let (local, spread) = local_and_spread();
        let mut frame_a = local.clone();
        frame_a.extend_from_slice(&spread);
        let mut frame_b = spread.clone();
        frame_b.extend_from_slice(&spread);
        let mut acc = LocalizationAverage::new(n, 2, 10);
        acc.add_frame(&frame_a);
        acc.add_frame(&frame_b);
        acc.add_vector(0, &vec![f64::NAN; d]); // skipped
        let w = acc.widths();
        // index 0: <S> = ln(4)/2 -> W = 2/4, not the mean of W (0.25 + 1)/2
        assert!((w[0] - 0.5).abs() < 1e-14);
        assert!((w[1] - 1.0).abs() < 1e-14);
        assert_eq!(acc.counts(), &[2, 2]);
        assert!(entropy(&vec![0.0; d]).is_nan());
    }

    /// The error of <S> comes from the means of blocks of frames: four blocks whose means are
    /// 0, ln 4, 0, ln 4 (two frames each) give the standard error of those four numbers.
    #[test]
    fn errors_come_from_block_means() {
        let n = 4;
        let (local, spread) = local_and_spread();
        let mut acc = LocalizationAverage::new(n, 1, 2);
        for block in 0..4 {
            for _ in 0..2 {
                acc.add_frame(if block % 2 == 0 { &local } else { &spread });
            }
        }
        acc.add_frame(&local); // an incomplete block counts in the mean, not in the error
        let ln4 = 4f64.ln();
        let want = (4.0 * (ln4 / 2.0).powi(2) / 3.0 / 4.0).sqrt();
        assert!((acc.entropy_stderr()[0] - want).abs() < 1e-15, "{:?} against {want}", acc.entropy_stderr());
        assert!((acc.mean_entropy()[0] - 4.0 * ln4 / 9.0).abs() < 1e-15);
        assert!((acc.width_stderr()[0] - acc.widths()[0] * want).abs() < 1e-15);
        assert!(LocalizationAverage::new(n, 1, 100).entropy_stderr()[0].is_nan(), "no complete block");
    }
}
