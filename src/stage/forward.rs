//! The forward Gram-Schmidt pass (paper section 3): Gbar_n = J G_{n-1}, Gbar_n = G_n R_n,
//! lambda_i = lim (1 / n tau) sum ln [R_n]_ii.
//!
//! The pass is a value ([`Forward`]) advanced one step at a time, so that whoever drives it
//! (the CLI, a test, the run store) decides what to keep of each G_n and R_n.

use crate::config::RunConfig;
use crate::error::{Error, Result};
use crate::linalg::{Copies, PaperColumns, Qr};
use crate::statistics::{block_len, Accumulator};
use crate::system::{DynamicalSystem, Snapshot, Tangent};
use faer::Mat;
use serde::{Deserialize, Serialize};

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

impl ForwardState {
    /// Where a recomputed state `got` first differs from this stored one, in words.
    pub fn first_difference(&self, got: &ForwardState) -> String {
        let first = |a: &[f64], b: &[f64]| a.iter().zip(b).position(|(x, y)| x.to_bits() != y.to_bits());
        if self.system.events != got.system.events {
            format!("collision count {} stored, {} recomputed", self.system.events, got.system.events)
        } else if let Some(i) = first(&self.system.phase, &got.system.phase) {
            format!("phase component {i}: {:e} stored, {:e} recomputed", self.system.phase[i], got.system.phase[i])
        } else if let Some(i) = first(&self.g, &got.g) {
            format!("G_n element {i}: {:e} stored, {:e} recomputed", self.g[i], got.g[i])
        } else {
            "the accumulated exponent sums differ".into()
        }
    }
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
        // Copies are taken by the backward stage's recomputation of a stored step, which a
        // run written before a refusal was added must still pass.
        let recomputed = copies.is_some();
        let t0 = std::time::Instant::now();
        self.system.advance(&mut self.g)?;
        let t1 = std::time::Instant::now();
        let copies = match copies {
            Some((g_paper, r_packed)) => Copies { g_paper: g_paper.map(|out| PaperColumns { internal_row: &self.paper_rows, out }), r_packed: Some(r_packed) },
            None => Copies::default(),
        };
        let dependent = self.qr.factor_with_copies(&mut self.g, &mut self.r, copies);
        let t2 = std::time::Instant::now();
        if let Some(i) = dependent.or_else(|| (0..self.r.ncols()).find(|&i| !(self.r[(i, i)].is_finite() && self.r[(i, i)] > 0.0))) {
            let (step, tau) = (self.step + 1, self.system.tau());
            // The settings' error, not the dynamics': the same step fails again with them.
            if !self.r[(i, i)].is_finite() {
                return Err(Error::param("tau", format!(
                    "step {step}: the QR step found tangent vector {} not finite, a numerical blow-up: between two QR steps the vectors grow like e^(lambda_1 tau), \
                     past a double's range for lambda_1 tau above about 700; with tau = {tau}, give a smaller --tau; no exponent is accumulated from it",
                    i + 1
                )));
            }
            return Err(Error::param("tau", format!(
                "step {step}: the QR step found the first {} tangent vectors linearly dependent in double precision: k larger than the rank, \
                 or a --tau so long that between two QR steps they spread by more than the 16 digits of a double resolve, (lambda_1 - lambda_k) tau above about {:.0} \
                 (with tau = {tau}: exponents more than {:.3} apart); give a smaller --tau; no exponent is accumulated from it",
                i + 1,
                crate::linalg::RESOLVED_SPREAD,
                crate::linalg::RESOLVED_SPREAD / tau
            )));
        }
        if self.step >= self.relax_steps {
            // Twenty steps average out a single step's spread.
            let k = self.r.ncols();
            if let Some(why) = self.acc.mean_spread().filter(|_| self.acc.steps >= 20 && !recomputed).and_then(|s| crate::linalg::unresolved(s, self.system.tau(), k)) {
                return Err(Error::param("tau", format!("step {}: {why}; no exponent is accumulated from it", self.step + 1)));
            }
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

    /// At the step `steps.min(20)` after the relaxation (of a run of `steps` steps), why tau
    /// is too long for a double's digits, if it is: the first exponents say already, long
    /// before the table at the end ([`crate::linalg::precision_warning`]).
    pub fn early_precision_warning(&self, steps: u64) -> Option<String> {
        let tau = self.system.tau();
        // Past unresolved_spread the next step stops the run with the same words.
        let unresolved = self.acc.mean_spread().and_then(|s| crate::linalg::unresolved(s, tau, self.r.ncols())).is_some();
        (self.step == self.relax_steps + steps.min(20) && !unresolved).then(|| crate::linalg::precision_warning(&self.acc.exponents(tau), tau)).flatten()
    }

    pub fn time(&self) -> f64 {
        self.step as f64 * self.system.tau()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SystemConfig;

    /// A tau so long that the tangent vectors spread beyond a double's digits in one step
    /// (N = 16, (lambda_1 - lambda_64) tau near 55) stops the run at its first step, naming
    /// the spread (before, this read "R_11 = 0" whatever column was dependent).
    #[test]
    fn a_tau_beyond_double_precision_is_named() {
        let config = RunConfig { system: SystemConfig::disks(16, 0.7, 1.0).unwrap(), tau: 6.0, relax_steps: 0, steps: 4, vectors: 64, seed: 3, threads: 1, blocks: 2 };
        let err = Forward::new(&config).unwrap().step().unwrap_err().to_string();
        assert!(err.contains("step 1: the QR step found the first") && err.contains("(lambda_1 - lambda_k) tau above about 36"), "{err}");
    }

    /// Where the QR's rank test does not notice (Lorenz at tau = 10: lambda_3 came out -2.85
    /// instead of -14.57, the spread at the rounding's 37), the mean spread past
    /// linalg::unresolved_spread stops the run after 20 accumulated steps; tau = 1 (a spread of 15)
    /// runs on.
    #[test]
    fn a_spread_at_the_rounding_limit_stops_the_run() {
        let lorenz = |tau: f64| RunConfig { system: SystemConfig::lorenz(), tau, relax_steps: 10, steps: 200, vectors: 3, seed: 1, threads: 1, blocks: 2 };
        let mut f = Forward::new(&lorenz(10.0)).unwrap();
        let err = loop {
            if let Err(e) = f.step() {
                break e.to_string();
            }
        };
        assert!(err.contains("step 31: the QR steps measure (lambda_1 - lambda_k) tau = 3") && err.contains("give a smaller --tau"), "{err}");
        assert!(f.early_precision_warning(200).is_none(), "the error, not a warning with a --tau from rounding");
        let mut f = Forward::new(&lorenz(1.0)).unwrap();
        for _ in 0..210 {
            f.step().unwrap();
        }
        assert!(crate::linalg::unresolved(f.acc.mean_spread().unwrap(), 1.0, 3).is_none());
        // The backward stage's recomputation of a stored step is not refused: a run written
        // before the refusal replays (its table keeps the warning).
        let mut old = Forward::new(&lorenz(10.0)).unwrap();
        let (mut r_packed, k) = (vec![0.0; 6], 3);
        for _ in 0..60 {
            old.step_with_copies(None, &mut r_packed).unwrap();
        }
        assert!(crate::linalg::unresolved(old.acc.mean_spread().unwrap(), 10.0, k).is_some());
        assert!(crate::linalg::precision_warning(&[0.9, 0.0, -14.57], 10.0).is_some_and(|w| w.contains("at the limit")), "inspect of an older run");
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
