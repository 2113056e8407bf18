//! The unit of the CLV stream: one step of the backward pass, as every analysis sees it.

/// Covariant vectors (and optionally Gram-Schmidt vectors) at one step n.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub step: u64,
    /// t_n = n tau.
    pub time: f64,
    /// Phase-space dimension D.
    pub d: usize,
    /// Number of vectors k.
    pub k: usize,
    /// Gamma_n in the paper's ordering.
    pub phase: Vec<f64>,
    /// V_n = G_n C_n (paper eq. for V_n): unit columns, column-major D x k, paper ordering;
    /// empty in the frames the backward stage formed no vectors for (`--vectors-every`).
    pub v: Vec<f64>,
    /// Local CLV exponents over [t_n, t_{n+1}], ln |D phi^tau v^l(Gamma(t_n))| / tau, k
    /// values: the paper's Lambda_l^cov (Sec. 6, after eq. intcov) at t_{n+1}, one step
    /// later than this frame.
    pub local: Vec<f64>,
    /// Local GS exponents over [t_n, t_{n+1}], ln |[R_{n+1}]_ii| / tau, k values; empty in
    /// frames written before they were carried.
    pub gs_local: Vec<f64>,
    /// G_n, column-major D x k, when the backward stage ran with --with-gs.
    pub g: Option<Vec<f64>>,
}

impl Frame {
    /// Covariant vector j (0-based; the paper's v^{j+1}).
    pub fn v(&self, j: usize) -> &[f64] {
        &self.v[j * self.d..(j + 1) * self.d]
    }

    /// Gram-Schmidt vector j, if the frame carries them.
    pub fn g(&self, j: usize) -> Option<&[f64]> {
        self.g.as_ref().map(|g| &g[j * self.d..(j + 1) * self.d])
    }
}

/// Whether the frame of `step` is on a stride of m steps: the one rule of every stride of the
/// pipeline (`clv backward --vectors-every` and `--save-every`, `clv analyze --every`). By
/// the step, not by the frames' position in a stream, so that a stream that starts anywhere
/// (a resumed sweep, a file that keeps every `--save-every`-th step) lands on the same frames,
/// and a stride that is a multiple of another lands on its frames.
pub fn on_stride(step: u64, m: u64) -> bool {
    step.is_multiple_of(m.max(1))
}

/// The least common multiple of two strides: the steps on both.
pub fn lcm(a: u64, b: u64) -> u64 {
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let (a, b) = (a.max(1), b.max(1));
    a / gcd(a, b) * b
}

/// How many steps in lo..=hi are on the stride m ([`on_stride`]); none if lo > hi.
pub fn multiples_in(lo: u64, hi: u64, m: u64) -> u64 {
    let m = m.max(1);
    (hi / m + 1).saturating_sub(lo.div_ceil(m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multiples_in_counts_inclusively() {
        let brute = |lo: u64, hi: u64, m: u64| (lo..=hi).filter(|&n| on_stride(n, m)).count() as u64;
        for (lo, hi, m) in [(0, 0, 3), (0, 10, 3), (1, 10, 3), (3, 3, 3), (4, 5, 3), (7, 7, 1), (5, 4, 2), (1500, 1900, 62)] {
            assert_eq!(multiples_in(lo, hi, m), brute(lo, hi, m), "{lo}..={hi}, m = {m}");
        }
    }
}
