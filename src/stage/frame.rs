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
    /// Local CLV exponents over [t_n, t_{n+1}], k values.
    pub local: Vec<f64>,
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
