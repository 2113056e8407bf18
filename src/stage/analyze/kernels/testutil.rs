//! Deterministic random numbers and synthetic phase points for the unit tests.

/// SplitMix64: tiny, deterministic, good enough for test data.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u = 1.0 - self.uniform();
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    pub fn normals(&mut self, len: usize) -> Vec<f64> {
        (0..len).map(|_| self.normal()).collect()
    }
}

/// Random phase point of n disks in an lx x ly box with zero total momentum and
/// kinetic energy N (K/N = 1 as in the paper).
pub fn phase_point(n: usize, lx: f64, ly: f64, rng: &mut Rng) -> Vec<f64> {
    let mut g = vec![0.0; 4 * n];
    for i in 0..n {
        g[2 * i] = lx * rng.uniform();
        g[2 * i + 1] = ly * rng.uniform();
    }
    let p = &mut g[2 * n..];
    for x in p.iter_mut() {
        *x = rng.normal();
    }
    for c in 0..2 {
        let mean: f64 = (0..n).map(|i| p[2 * i + c]).sum::<f64>() / n as f64;
        for i in 0..n {
            p[2 * i + c] -= mean;
        }
    }
    let k: f64 = p.iter().map(|x| x * x).sum::<f64>() / 2.0;
    let scale = (n as f64 / k).sqrt();
    for x in p.iter_mut() {
        *x *= scale;
    }
    g
}

/// Scale `v` to unit norm.
pub fn normalized(mut v: Vec<f64>) -> Vec<f64> {
    let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    for x in v.iter_mut() {
        *x /= n;
    }
    v
}
