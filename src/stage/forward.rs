//! The forward Gram-Schmidt pass (paper section 3): Gbar_n = J G_{n-1}, Gbar_n = G_n R_n,
//! lambda_i = lim (1 / n tau) sum ln [R_n]_ii.
//!
//! The pass is a value ([`Forward`]) advanced one step at a time, so that whoever drives it
//! (the CLI, a test, the run store) decides what to keep of each G_n and R_n.

use crate::config::RunConfig;
use crate::error::{Error, Result};
use crate::linalg::{Copies, PaperColumns, Qr};
use crate::system::{DynamicalSystem, Snapshot, Tangent};
use faer::Mat;
use serde::{Deserialize, Serialize};

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
/// may measure slightly positive); None when all are positive (the spectrum does not reach
/// the non-positive part).
pub fn ks_entropy(lambda: &[f64], neutral: std::ops::Range<usize>) -> Option<f64> {
    // + 0.0: an empty sum is -0.0, which would print as "-0.000000" for a system without chaos.
    lambda.iter().any(|&l| l <= 0.0).then(|| lambda.iter().enumerate().filter(|&(i, &l)| l > 0.0 && !neutral.contains(&i)).map(|(_, l)| l).sum::<f64>() + 0.0)
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
    let n = x.len();
    if n < 2 {
        return f64::NAN;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    (var / n as f64).sqrt()
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

/// The complete state of a forward pass at a step boundary (what a checkpoint holds).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ForwardState {
    /// Steps done, relaxation included.
    pub step: u64,
    pub system: Snapshot,
    /// G_n in the paper's ordering, column-major D x k.
    pub g: Vec<f64>,
    pub acc: Accumulator,
}

/// The state of a forward pass between two steps.
pub struct Forward {
    pub system: Box<dyn DynamicalSystem>,
    /// G_n, the current orthonormal (Gram-Schmidt) basis, in the system's row layout.
    pub g: Tangent,
    /// R_n of the last step (k x k, upper triangular, positive diagonal).
    pub r: Mat<f64>,
    /// Steps done since the start of the run, relaxation included; t_n = step tau.
    pub step: u64,
    pub acc: Accumulator,
    relax_steps: u64,
    /// The run's number of blocks for the standard error ([`Accumulator::limit_blocks`]).
    blocks: usize,
    /// The run's thread setting: the most [`Forward::set_threads`] may use.
    threads: usize,
    qr: Qr,
    /// internal_row(i) for every paper index i (see [`Forward::step_with_copies`]).
    paper_rows: Vec<usize>,
}

impl Forward {
    pub fn new(config: &RunConfig) -> Result<Self> {
        let mut system = config.build_system()?;
        system.set_threads(config.threads);
        let (d, k) = (system.dim(), config.vectors);
        let g = Tangent::identity(system.as_ref(), k);
        let paper_rows = (0..d).map(|i| system.internal_row(i)).collect();
        let block_len = block_len(config.steps, config.blocks as u64);
        Ok(Forward {
            system,
            g,
            r: Mat::identity(k, k),
            step: 0,
            acc: Accumulator::new(k, block_len),
            relax_steps: config.relax_steps,
            blocks: config.blocks,
            threads: config.threads.max(1),
            qr: Qr::new(d, k, config.threads),
            paper_rows,
        })
    }

    /// Use at most `threads` threads from the next step on (tangent updates and QR); the
    /// numbers do not depend on it. `threads` above the run's setting are not used.
    pub fn set_threads(&mut self, threads: usize) {
        let threads = threads.clamp(1, self.threads);
        self.system.set_threads(threads);
        self.qr.set_threads(threads);
    }

    /// One step: propagate over tau, re-orthonormalise, accumulate ln R_ii once relaxed.
    pub fn step(&mut self) -> Result<()> {
        self.step_timed().map(|_| ())
    }

    /// [`Forward::step`], returning the time spent in the dynamics (MD and tangent updates)
    /// and in the QR step (for `clv bench`).
    pub fn step_timed(&mut self) -> Result<(std::time::Duration, std::time::Duration)> {
        self.step_into(None)
    }

    /// [`Forward::step`], also writing R_n packed ([`crate::linalg::pack_upper`]) to
    /// `r_packed` and, if asked, the new G_n in the paper's column layout (column-major D x k)
    /// to `g_paper`: what the backward stage keeps of a recomputed step, at almost no cost.
    pub fn step_with_copies(&mut self, g_paper: Option<&mut [f64]>, r_packed: &mut [f64]) -> Result<()> {
        self.step_into(Some((g_paper, r_packed))).map(|_| ())
    }

    fn step_into(&mut self, copies: Option<(Option<&mut [f64]>, &mut [f64])>) -> Result<(std::time::Duration, std::time::Duration)> {
        let t0 = std::time::Instant::now();
        self.system.advance(&mut self.g)?;
        let t1 = std::time::Instant::now();
        let copies = match copies {
            Some((g_paper, r_packed)) => Copies { g_paper: g_paper.map(|out| PaperColumns { internal_row: &self.paper_rows, out }), r_packed: Some(r_packed) },
            None => Copies::default(),
        };
        self.qr.factor_with_copies(&mut self.g, &mut self.r, copies);
        let t2 = std::time::Instant::now();
        if let Some(i) = (0..self.r.ncols()).find(|&i| !(self.r[(i, i)].is_finite() && self.r[(i, i)] > 0.0)) {
            return Err(Error::Dynamics(format!(
                "step {}: R_{}{} = {} after the QR step: the tangent vectors are not finite or linearly dependent \
                 (k larger than the rank, or a numerical blow-up: a --tau so long that they grow or shrink by more than e^700 between two QR steps; \
                 if so, give a smaller --tau); no exponent is accumulated from it",
                self.step + 1,
                i + 1,
                i + 1,
                self.r[(i, i)]
            )));
        }
        if self.step >= self.relax_steps {
            self.acc.add(&self.r);
            self.acc.limit_blocks(self.blocks);
        }
        self.step += 1;
        Ok((t1 - t0, t2 - t1))
    }

    /// Everything needed to continue this pass bit for bit.
    pub fn state(&self) -> ForwardState {
        ForwardState {
            step: self.step,
            system: self.system.snapshot(),
            g: self.g.to_paper_columns(self.system.as_ref()),
            acc: self.acc.clone(),
        }
    }

    /// A pass continued from `state`, which must come from a run with the same `config`.
    pub fn resume(config: &RunConfig, state: &ForwardState) -> Result<Self> {
        let mut fwd = Forward::new(config)?;
        fwd.restore(state)?;
        Ok(fwd)
    }

    /// Continue from `state` (of a run with this pass's configuration) in this pass's
    /// workspace: what [`Forward::resume`] does, without building the system, the QR
    /// workspace and its threads again (the backward stage restores once a segment).
    pub fn restore(&mut self, state: &ForwardState) -> Result<()> {
        let (d, k) = (self.g.dim(), self.g.count());
        if state.g.len() != d * k || state.acc.sum.len() != k {
            return Err(Error::Other(format!(
                "the saved state at step {} holds {} basis numbers and {} sums, but the configuration needs D x k = {d} x {k}",
                state.step, state.g.len(), state.acc.sum.len()
            )));
        }
        self.system.restore(&state.system)?;
        self.g.read_paper_columns(self.system.as_ref(), &state.g);
        self.acc = state.acc.clone();
        self.step = state.step;
        Ok(())
    }

    pub fn time(&self) -> f64 {
        self.step as f64 * self.system.tau()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SystemConfig;

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

    /// A used pass restored to a saved state continues exactly as a fresh pass resumed from it.
    #[test]
    fn restore_into_a_used_pass_is_resume() {
        let config = RunConfig { system: SystemConfig::disks(16, 0.7, 1.0).unwrap(), tau: 0.6, relax_steps: 1, steps: 8, vectors: 40, seed: 5, threads: 2, blocks: 2 };
        let mut a = Forward::new(&config).unwrap();
        a.step().unwrap();
        let saved = a.state();
        for _ in 0..4 {
            a.step().unwrap();
        }
        let mut fresh = Forward::resume(&config, &saved).unwrap();
        a.restore(&saved).unwrap();
        assert!(a.state() == saved);
        for _ in 0..3 {
            a.step().unwrap();
            fresh.step().unwrap();
            assert!(a.state() == fresh.state() && a.r == fresh.r);
        }
    }

    /// The backward stage's step (copies of G_n and R_n written from inside the QR, or of R_n
    /// alone) is the plain step: same state, and the copies have the bits of
    /// `to_paper_columns` and `pack_upper`.
    #[test]
    fn step_with_copies_is_the_plain_step() {
        for (threads, k) in [(1, 64), (2, 64), (2, 40)] {
            let config = RunConfig { system: SystemConfig::disks(16, 0.7, 1.0).unwrap(), tau: 0.6, relax_steps: 0, steps: 4, vectors: k, seed: 3, threads, blocks: 2 };
            let (mut a, mut b) = (Forward::new(&config).unwrap(), Forward::new(&config).unwrap());
            let (mut out, mut packed) = (vec![f64::NAN; 64 * k], vec![f64::NAN; k * (k + 1) / 2]);
            let same = |x: &[f64], y: &[f64]| x.len() == y.len() && x.iter().zip(y).all(|(x, y)| x.to_bits() == y.to_bits());
            for step in 0..4 {
                a.step().unwrap();
                // The backward stage asks for G_n only at the steps whose frames carry vectors.
                let with_g = step != 1;
                b.step_with_copies(with_g.then_some(&mut out[..]), &mut packed).unwrap();
                assert!(a.state() == b.state() && a.r == b.r, "{threads} thread(s), k = {k}");
                if with_g {
                    assert!(same(&out, &a.g.to_paper_columns(a.system.as_ref())), "G_n, {threads} thread(s), k = {k}");
                }
                assert!(same(&packed, &crate::linalg::pack_upper(a.r.as_ref())), "R_n, {threads} thread(s), k = {k}");
            }
        }
    }
}
