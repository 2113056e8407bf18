//! Time averages with their errors: the running sums of ln R_ii that make a Lyapunov
//! spectrum, their batch means (blocks) for standard errors, and the quantities made of a
//! spectrum (h_KS, D_KY). Shared by the forward and backward stages, the analyses, the
//! records on disk and the reports, so it belongs to none of them.

use faer::Mat;
use serde::{Deserialize, Deserializer, Serialize};

/// A standard error read from JSON, where serde_json writes the NaN of an unknown one (a
/// single block) as null: null is read back as NaN, not refused as damage.
pub fn error_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Option::<f64>::deserialize(d).map(|x| x.unwrap_or(f64::NAN))
}

/// Standard errors read from JSON, each null read back as NaN ([`error_or_nan`]).
pub fn errors_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    Vec::<Option<f64>>::deserialize(d).map(|v| v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
}

/// Running sums of ln R_ii, with block sums for the standard error (batch means).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Accumulator {
    /// Sum over all accumulated steps of ln [R_n]_ii.
    pub sum: Vec<f64>,
    pub steps: u64,
    /// Steps per block.
    pub block_len: u64,
    /// Sums of completed blocks.
    pub blocks: Vec<Vec<f64>>,
    /// Sum of the block in progress.
    pub current: Vec<f64>,
}

/// Steps (or frames) per block when `samples` of them are to make `blocks` blocks for batch
/// means: at least `blocks` complete blocks (fewer than 2 `blocks`), so a run never gets
/// fewer than it asks for; the samples left over, fewer than a block, count in the averages,
/// not in the errors. One rule for the forward spectrum, the backward stage's CLV spectrum
/// and the analyses.
pub fn block_len(samples: u64, blocks: u64) -> u64 {
    (samples / blocks.max(1)).max(1)
}

impl Accumulator {
    pub fn new(k: usize, block_len: u64) -> Self {
        Accumulator { sum: vec![0.0; k], steps: 0, block_len: block_len.max(1), blocks: Vec::new(), current: vec![0.0; k] }
    }

    /// The mean of ln [R_n]_11 - ln [R_n]_kk over the steps so far, (lambda_1 - lambda_k) tau;
    /// None before the first step or with one vector.
    pub fn mean_spread(&self) -> Option<f64> {
        let (first, last) = (self.sum.first()?, self.sum.last()?);
        (self.sum.len() >= 2 && self.steps > 0).then(|| (first - last) / self.steps as f64)
    }

    /// Accumulate ln [R_n]_ii of one step.
    pub fn add(&mut self, r: &Mat<f64>) {
        self.add_logs((0..self.sum.len()).map(|i| r[(i, i)].ln()));
    }

    /// Accumulate one step's logarithmic growth factors (one per vector).
    pub fn add_logs(&mut self, logs: impl Iterator<Item = f64>) {
        for ((s, c), l) in self.sum.iter_mut().zip(self.current.iter_mut()).zip(logs) {
            *s += l;
            *c += l;
        }
        self.steps += 1;
        if self.steps.is_multiple_of(self.block_len) {
            let k = self.current.len();
            self.blocks.push(std::mem::replace(&mut self.current, vec![0.0; k]));
        }
    }

    /// Merge neighbouring completed blocks pairwise, doubling the block length, once there
    /// are `2 * blocks` of them: a run extended past the length its blocks were planned for
    /// keeps between `blocks` and `2 * blocks` blocks, each as long as the run allows.
    /// Runs that end where they were planned to never get there (the sums are untouched).
    pub fn limit_blocks(&mut self, blocks: usize) {
        let (n, empty_current) = (self.blocks.len(), self.steps.is_multiple_of(self.block_len));
        if n < 2 * blocks.max(1) || !n.is_multiple_of(2) || !empty_current {
            return;
        }
        self.blocks = self.blocks.chunks(2).map(|p| p[0].iter().zip(&p[1]).map(|(a, b)| a + b).collect()).collect();
        self.block_len *= 2;
    }

    /// lambda_i = sum ln R_ii / (steps tau).
    pub fn exponents(&self, tau: f64) -> Vec<f64> {
        let t = self.steps.max(1) as f64 * tau;
        self.sum.iter().map(|s| s / t).collect()
    }

    /// The batch means: each exponent averaged over each completed block, oldest first.
    pub fn block_averages(&self, tau: f64) -> BlockAverages {
        let t = self.block_len as f64 * tau;
        BlockAverages { block_steps: self.block_len, exponents: self.blocks.iter().map(|b| b.iter().map(|s| s / t).collect()).collect() }
    }

    /// Standard error of each exponent from the spread of the block averages (NaN with
    /// fewer than two completed blocks).
    pub fn stderr(&self, tau: f64) -> Vec<f64> {
        let t = self.block_len as f64 * tau;
        (0..self.sum.len()).map(|i| standard_error(&self.blocks.iter().map(|b| b[i] / t).collect::<Vec<_>>())).collect()
    }

    /// Kolmogorov-Sinai entropy by Pesin's identity, h_KS = sum of the positive lambda_i
    /// outside the `neutral` indices ([`ks_entropy`]), with its standard error from the block
    /// sums of the same exponents (NaN with fewer than two completed blocks). None when every
    /// one of the k exponents is positive: the positive part of the spectrum was then not all
    /// computed.
    pub fn ks_entropy(&self, tau: f64, neutral: std::ops::Range<usize>) -> Option<Estimate> {
        let lambda = self.exponents(tau);
        let value = ks_entropy(&lambda, neutral.clone())?;
        let counted = |i: usize, l: f64| l > 0.0 && !neutral.contains(&i);
        let positive = |sums: &[f64], t: f64| sums.iter().zip(&lambda).enumerate().filter(|(i, (_, l))| counted(*i, **l)).map(|(_, (s, _))| s / t).sum::<f64>();
        let t = self.block_len as f64 * tau;
        let per_block: Vec<f64> = self.blocks.iter().map(|b| positive(b, t)).collect();
        Some(Estimate { value, stderr: standard_error(&per_block) })
    }
}

/// h_KS = sum of the positive lambda_i (Pesin's identity), leaving out the `neutral` indices
/// (exponents zero by symmetry, [`crate::config::SystemConfig::neutral`], which a finite run
/// may measure slightly positive); None when all others are positive (the spectrum does not
/// reach the null space or the non-positive part).
pub fn ks_entropy(lambda: &[f64], neutral: std::ops::Range<usize>) -> Option<f64> {
    let reaches_the_rest = lambda.iter().enumerate().any(|(i, &l)| l <= 0.0 || neutral.contains(&i));
    // + 0.0: an empty sum is -0.0, which would print as "-0.000000" for a system without chaos.
    reaches_the_rest.then(|| lambda.iter().enumerate().filter(|&(i, &l)| l > 0.0 && !neutral.contains(&i)).map(|(_, l)| l).sum::<f64>() + 0.0)
}

/// The exponents averaged over consecutive blocks of a run: the batch means its standard
/// errors come from, kept so that a reader can judge them (src/stage/analyze/convergence.rs).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BlockAverages {
    /// Steps per block.
    pub block_steps: u64,
    /// exponents[b][i]: lambda_(i+1) averaged over block b, oldest block first.
    pub exponents: Vec<Vec<f64>>,
}

/// A time average with its standard error (batch means).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub value: f64,
    #[serde(deserialize_with = "error_or_nan")]
    pub stderr: f64,
}

impl Estimate {
    /// `x` as text, "not known" where there is none.
    pub fn or_unknown(x: Option<Estimate>) -> String {
        x.map_or("not known".to_string(), |x| x.to_string())
    }
}

impl std::fmt::Display for Estimate {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "{:.6}", self.value)?;
        if self.stderr.is_finite() {
            write!(f, " ± {:.1e}", self.stderr)?;
        }
        Ok(())
    }
}

/// Standard error of the mean of `x` (NaN with fewer than two values).
pub fn standard_error(x: &[f64]) -> f64 {
    (sample_variance(x) / x.len() as f64).sqrt()
}

/// Standard error of the mean of the series `x` by batch means: the standard error of the
/// means of its consecutive whole blocks of `block_len` values, from the first (NaN with
/// fewer than two blocks). Blocks longer than the series' correlation time make it honest
/// where [`standard_error`] of correlated values would be too small.
pub fn batch_stderr(x: &[f64], block_len: usize) -> f64 {
    let means: Vec<f64> = x.chunks_exact(block_len.max(1)).map(|b| b.iter().sum::<f64>() / b.len() as f64).collect();
    standard_error(&means)
}

/// The median of the finite values of `x` (the mean of the middle two of an even count;
/// NaN if there are none).
pub fn median(x: &[f64]) -> f64 {
    let mut v: Vec<f64> = x.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        m if m % 2 == 1 => v[m / 2],
        m => 0.5 * (v[m / 2 - 1] + v[m / 2]),
    }
}

/// Sample standard deviation of `x`, with n - 1 (NaN with fewer than two values: one value
/// shows no spread, it does not show that there is none).
pub fn sample_std(x: &[f64]) -> f64 {
    sample_variance(x).sqrt()
}

fn sample_variance(x: &[f64]) -> f64 {
    let n = x.len();
    if n < 2 {
        return f64::NAN;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64
}

/// Kaplan-Yorke (Lyapunov) dimension D_KY = j + (lambda_1 + ... + lambda_j) / |lambda_(j+1)|,
/// j the largest index whose partial sum is not negative (Kaplan & Yorke 1979). For a
/// system that preserves phase volume (hard disks) it is the dimension D of phase space.
/// None when the k = `lambda.len()` exponents of a D-dimensional system stay non-negative
/// in sum, so that the vectors not followed would decide it.
pub fn kaplan_yorke_dimension(lambda: &[f64], d: usize) -> Option<f64> {
    let mut sorted = lambda.to_vec();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let mut partial = 0.0;
    for (j, &l) in sorted.iter().enumerate() {
        if partial + l < 0.0 {
            return Some(j as f64 + partial / l.abs());
        }
        partial += l;
    }
    (sorted.len() == d).then_some(d as f64)
}

/// P(|T| > t) for Student's t with `dof` degrees of freedom: the regularised incomplete
/// beta function I_x(dof/2, 1/2) at x = dof / (dof + t^2).
pub fn student_t_two_sided(t: f64, dof: f64) -> f64 {
    incomplete_beta(dof / (dof + t * t), dof / 2.0, 0.5)
}

/// The regularised incomplete beta function I_x(a, b), by its continued fraction (modified
/// Lentz), with the symmetry I_x(a, b) = 1 - I_(1-x)(b, a) where that converges faster.
fn incomplete_beta(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    if x > (a + 1.0) / (a + b + 2.0) {
        return 1.0 - incomplete_beta(1.0 - x, b, a);
    }
    let ln_gamma = |z: f64| -> f64 {
        // Lanczos (g = 7, n = 9), good to 1e-15 for z > 0.
        const C: [f64; 9] = [0.999_999_999_999_809_9, 676.520_368_121_885_1, -1_259.139_216_722_402_8, 771.323_428_777_653_1, -176.615_029_162_140_6, 12.507_343_278_686_905, -0.138_571_095_265_720_12, 9.984_369_578_019_572e-6, 1.505_632_735_149_311_6e-7];
        let z = z - 1.0;
        let t = z + 7.5;
        let sum: f64 = C[0] + (1..9).map(|i| C[i] / (z + i as f64)).sum::<f64>();
        0.5 * (2.0 * std::f64::consts::PI).ln() + (z + 0.5) * t.ln() - t + sum.ln()
    };
    let front = (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp() / a;
    let tiny = 1e-300;
    let (mut c, mut d) = (1.0, 1.0 - (a + b) * x / (a + 1.0));
    d = 1.0 / if d.abs() < tiny { tiny } else { d };
    let mut f = d;
    for m in 1..300 {
        let m = m as f64;
        for numerator in [m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m)), -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0))] {
            d = 1.0 + numerator * d;
            d = 1.0 / if d.abs() < tiny { tiny } else { d };
            c = 1.0 + numerator / c;
            if c.abs() < tiny {
                c = tiny;
            }
            f *= c * d;
        }
        if (c * d - 1.0).abs() < 1e-15 {
            break;
        }
    }
    front * f
}

/// The t with P(|T| > t) = `p` for Student's t with `dof` degrees of freedom (by bisection
/// of [`student_t_two_sided`]): the factor of a standard error for a two-sided interval
/// of probability 1 - p estimated from `dof` degrees of freedom (1.84 for p = 0.3173, the
/// one-sigma probability, with one).
pub fn student_t_quantile(p: f64, dof: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    while student_t_two_sided(hi, dof) > p {
        hi *= 2.0;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if student_t_two_sided(mid, dof) > p { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Student's t tails against closed forms (dof 1: 1 - 2 atan(t) / pi; dof 2:
    /// 1 - t / sqrt(t^2 + 2)) and the normal limit; its one-sigma quantile likewise.
    #[test]
    fn student_t_tails_are_right() {
        // The one-sigma interval from one degree of freedom is tan(pi/2 (1 - 0.3173)) wide.
        let one_sigma = 1.0 - 0.682_689_492_137_086;
        assert!((student_t_quantile(one_sigma, 1.0) - (std::f64::consts::FRAC_PI_2 * (1.0 - one_sigma)).tan()).abs() < 1e-9);
        assert!((student_t_quantile(one_sigma, 1e6) - 1.0).abs() < 1e-5);
        assert!((student_t_two_sided(2.0, 1.0) - (1.0 - 2.0 * 2f64.atan() / std::f64::consts::PI)).abs() < 1e-12);
        assert!((student_t_two_sided(2.0, 2.0) - (1.0 - 2.0 / 6f64.sqrt())).abs() < 1e-12);
        assert!((student_t_two_sided(2.0, 1e6) - 0.04550026).abs() < 1e-6);
        assert!((student_t_two_sided(0.0, 5.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn kaplan_yorke_dimension_interpolates_where_the_partial_sums_turn_negative() {
        let d_ky = |l: &[f64], d| kaplan_yorke_dimension(l, d);
        assert_eq!(d_ky(&[0.4, -1.6], 2), Some(1.25));
        assert_eq!(d_ky(&[-1.6, 0.4], 2), Some(1.25), "order of the input");
        assert_eq!(d_ky(&[2.0, 1.0, -1.0, -4.0], 4), Some(3.5));
        assert_eq!(d_ky(&[2.0, 1.0, -1.0, -2.0], 4), Some(4.0), "volume preserving");
        assert_eq!(d_ky(&[-0.1, -0.2], 2), Some(0.0), "a stable fixed point");
        assert_eq!(d_ky(&[2.0, 1.0, -1.0], 4), None, "lambda_4 not known");
        assert_eq!(d_ky(&[2.0, 1.0, -4.0], 4), Some(2.75), "decided by the k leading exponents");
    }

    /// h_KS is the sum of the positive exponents; its error comes from the same blocks as
    /// the exponents' errors, so with one positive exponent the two coincide.
    #[test]
    fn ks_entropy_sums_the_positive_exponents_with_their_block_error() {
        let mut acc = Accumulator::new(3, 2);
        for n in 0..20 {
            let wobble = if n % 4 < 2 { 0.1 } else { -0.1 };
            acc.add_logs([1.0 + wobble, -0.5 - 0.3 * wobble, -2.0].into_iter());
        }
        let h = acc.ks_entropy(0.5, 0..0).unwrap();
        assert_eq!(h.value, acc.exponents(0.5)[0]);
        assert_eq!(h.stderr, acc.stderr(0.5)[0]);
        assert!(h.stderr > 0.0);
        let mut all_positive = Accumulator::new(2, 2);
        all_positive.add_logs([1.0, 0.5].into_iter());
        assert_eq!(all_positive.ks_entropy(1.0, 0..0), None);
        // Without a positive exponent (disks that never collide) h_KS is zero, not -0.
        let h = ks_entropy(&[-0.0, -1.0], 0..0).unwrap();
        assert_eq!(format!("{h:.6}"), "0.000000");
        // Leading exponents that reach into the null space, all measured slightly positive:
        // every positive one is there, so h_KS is known.
        assert_eq!(ks_entropy(&[2.0, 1.0, 1e-16, 2e-16], 2..4), Some(3.0));
        assert_eq!(ks_entropy(&[2.0, 1.0], 2..4), None);
        // A flow's direction has exponent zero, measured slightly positive in a finite run
        // (Lorenz: lambda_2 = +3e-4): not counted.
        let mut flow = Accumulator::new(3, 2);
        for n in 0..20 {
            let wobble = if n % 4 < 2 { 0.1 } else { -0.1 };
            flow.add_logs([0.9 + wobble, 3e-4 + 0.01 * wobble, -14.5].into_iter());
        }
        let lambda = flow.exponents(1.0);
        assert!(lambda[1] > 0.0);
        assert_eq!(flow.ks_entropy(1.0, 0..0).unwrap().value, lambda[0] + lambda[1]);
        let h = flow.ks_entropy(1.0, 1..2).unwrap();
        assert_eq!((h.value, h.stderr), (lambda[0], flow.stderr(1.0)[0]));
    }

    /// Feeding 4B blocks' worth of steps with the doubling rule gives the blocks of an
    /// accumulator planned with four times the block length from the start (up to the order of
    /// the additions), and the same sums bit for bit; a planned run never merges.
    #[test]
    fn blocks_double_when_a_run_outgrows_its_plan() {
        let logs = |n: u64| [(n as f64 * 0.37).sin(), -(n as f64 * 0.11).cos() - 1.0];
        let (mut doubled, mut planned, mut wide) = (Accumulator::new(2, 3), Accumulator::new(2, 3), Accumulator::new(2, 12));
        for n in 0..4 * 4 * 3 + 2 {
            doubled.add_logs(logs(n).into_iter());
            doubled.limit_blocks(4);
            wide.add_logs(logs(n).into_iter());
            if n < 4 * 3 {
                planned.add_logs(logs(n).into_iter());
                planned.limit_blocks(4);
            }
        }
        assert_eq!((planned.block_len, planned.blocks.len()), (3, 4), "a run that ends as planned keeps its blocks");
        assert_eq!((doubled.block_len, doubled.blocks.len()), (12, 4), "8 blocks of 3 became 4 of 6, then 8 of 6 became 4 of 12");
        assert_eq!(doubled.sum, wide.sum);
        assert_eq!(doubled.current, wide.current, "the block in progress (2 steps) is unchanged");
        for (a, b) in doubled.blocks.iter().flatten().zip(wide.blocks.iter().flatten()) {
            assert!((a - b).abs() < 1e-14, "{a} {b}");
        }
        let (e, w) = (doubled.stderr(0.5), wide.stderr(0.5));
        assert!(e.iter().zip(&w).all(|(a, b)| (a - b).abs() < 1e-12 && a.is_finite()));
    }
}
