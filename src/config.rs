//! The configuration of a run: which system, how long, how many vectors.
//!
//! One serialisable value that says everything needed to redo a run (it is printed with
//! `--json` and kept with the run's files, in run.json).

use crate::error::{Error, Result};
use crate::rng::Rng;
use crate::system::disks::{box_sides, HardDisks};
use crate::system::henon::Henon;
use crate::system::lorenz::Lorenz;
use crate::system::DynamicalSystem;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum SystemConfig {
    /// The Henon map x' = a - x^2 + b y, y' = x (paper section 4).
    Henon { a: f64, b: f64 },
    /// The Lorenz-63 flow (a flow without conservation laws, with exponents known to four digits).
    Lorenz { sigma: f64, rho: f64, beta: f64 },
    /// N hard disks in a periodic Lx x Ly box (paper section 5); density = N/(Lx Ly) and
    /// aspect = Ly/Lx are kept for the record.
    Disks { n: usize, lx: f64, ly: f64, density: f64, aspect: f64 },
}

impl SystemConfig {
    /// The Henon map at the paper's a = 1.4, b = 0.3.
    pub fn henon() -> Self {
        SystemConfig::Henon { a: Henon::A, b: Henon::B }
    }

    /// The Lorenz flow at the classic sigma = 10, rho = 28, beta = 8/3.
    pub fn lorenz() -> Self {
        SystemConfig::Lorenz { sigma: Lorenz::SIGMA, rho: Lorenz::RHO, beta: Lorenz::BETA }
    }

    /// The Henon map with parameters a and b, checked ([`SystemConfig::check_parameters`]).
    pub fn henon_with(a: f64, b: f64) -> Result<Self> {
        let system = SystemConfig::Henon { a, b };
        system.check_parameters()?;
        Ok(system)
    }

    /// The Lorenz flow with parameters sigma, rho and beta, checked.
    pub fn lorenz_with(sigma: f64, rho: f64, beta: f64) -> Result<Self> {
        let system = SystemConfig::Lorenz { sigma, rho, beta };
        system.check_parameters()?;
        Ok(system)
    }

    /// Refuse parameters of the Henon map or the Lorenz flow for which the exponents are not
    /// defined or not resolved by a double's digits, or the Lorenz integrator's steps would be
    /// too many (the disks' box is checked where it is made). Whether the orbit stays bounded
    /// (a Henon orbit escapes for a above about 1.42 at b = 0.3) and is chaotic is left to the
    /// run, which stops or warns.
    pub fn check_parameters(&self) -> Result<()> {
        match *self {
            SystemConfig::Henon { a, b } => {
                if !a.is_finite() {
                    return Err(Error::param("henon-a", format!("must be a finite number, got {a}")));
                }
                // det J = -b at every point: lambda_1 + lambda_2 = ln |b|.
                if !(b.is_finite() && b != 0.0) {
                    return Err(Error::param("henon-b", format!("must be a finite number other than 0 (det J = -b, so with b = 0 the map folds the plane onto a line and lambda_2 = -infinity), got {b}")));
                }
                // lambda_1 - lambda_2 >= -ln |b| per iteration, and the map's tau is 1: beyond
                // e^-16 the contracting vector keeps too few of a double's digits.
                if b.abs() < MIN_HENON_B {
                    return Err(Error::param(
                        "henon-b",
                        format!("|b| = {:e} is below e^-16 = {MIN_HENON_B:.1e}: lambda_1 + lambda_2 = ln |b|, so in one iteration (the map's fixed tau) the contracting vector shrinks against the other by more than e^16, near the e^18 past which it keeps fewer than half of a double's 16 digits; take |b| above {MIN_HENON_B:.1e}", b.abs()),
                    ));
                }
            }
            SystemConfig::Lorenz { sigma, rho, beta } => {
                // With sigma, beta > 0 every orbit enters a bounded ellipsoid; otherwise the
                // flow's divergence -(sigma + 1 + beta) need not contract phase space.
                for (flag, value, what) in [("lorenz-sigma", sigma, "the Prandtl number"), ("lorenz-beta", beta, "the geometric factor")] {
                    if !(value > 0.0 && value.is_finite()) {
                        return Err(Error::param(flag, format!("must be a positive finite number ({what}; with it at or below 0 the orbits need not stay bounded), got {value}")));
                    }
                }
                if !rho.is_finite() {
                    return Err(Error::param("lorenz-rho", format!("must be a finite number, got {rho}")));
                }
                let per_unit = Lorenz::steps_per_unit(sigma, rho, beta);
                if per_unit > crate::system::lorenz::MAX_STEPS_PER_UNIT {
                    let rotation = (sigma * rho.abs()).sqrt() + (beta * rho.abs()).sqrt();
                    let flag = if rotation >= sigma.max(beta) { "lorenz-rho" } else if sigma >= beta { "lorenz-sigma" } else { "lorenz-beta" };
                    return Err(Error::param(
                        flag,
                        format!("sigma = {sigma}, rho = {rho}, beta = {beta} make a field so fast that the integrator would need {per_unit:.1e} Runge-Kutta steps per unit time (at most {:.0e}); choose smaller parameters", crate::system::lorenz::MAX_STEPS_PER_UNIT),
                    ));
                }
            }
            SystemConfig::Disks { n, .. } => {
                if n > MAX_DISKS {
                    return Err(Error::param("n", format!("{n} disks are more than any machine holds: give at most {MAX_DISKS} = 2^30 (whose tangent vectors of D = 4N doubles take 32 GB each)")));
                }
            }
        }
        Ok(())
    }

    /// Disks from N, density and aspect ratio Ly/Lx.
    pub fn disks(n: usize, density: f64, aspect: f64) -> Result<Self> {
        if !(density > 0.0 && density.is_finite()) {
            return Err(Error::param("density", format!("must be a positive finite number, got {density}")));
        }
        // Hexagonal close packing of unit disks: 2/sqrt(3) disks per unit area.
        let close_packed = 2.0 / 3f64.sqrt();
        if density >= close_packed {
            return Err(Error::param("density", format!("{density} is at or above the close packing of disks, 2/sqrt(3) = {close_packed:.4}: no box holds disks that dense")));
        }
        if !(aspect > 0.0 && aspect.is_finite()) {
            return Err(Error::param("aspect", format!("must be a positive finite number, got {aspect}")));
        }
        let (lx, ly) = box_sides(n, density, aspect);
        Ok(SystemConfig::Disks { n, lx, ly, density, aspect })
    }

    /// Disks in a box with given sides.
    pub fn disks_in_box(n: usize, lx: f64, ly: f64) -> Self {
        SystemConfig::Disks { n, lx, ly, density: n as f64 / (lx * ly), aspect: ly / lx }
    }

    /// The same dynamical system: for disks N and the box sides (density and aspect ratio
    /// are derived from them, and a box given by its sides derives them with other rounding).
    pub fn same_system(&self, other: &SystemConfig) -> bool {
        match (self, other) {
            (SystemConfig::Disks { n, lx, ly, .. }, SystemConfig::Disks { n: n2, lx: lx2, ly: ly2, .. }) => n == n2 && lx == lx2 && ly == ly2,
            (a, b) => a == b,
        }
    }

    /// The (0-based) indices of the exponents that vanish exactly, by conservation laws and
    /// the flow's own direction: the six of hard disks' null space (paper indices 2N-2..2N+3),
    /// Lorenz's lambda_2, none for a map. A finite run measures them as small numbers of
    /// either sign; Pesin's h_KS must not count those that come out positive.
    pub fn neutral(&self) -> std::ops::Range<usize> {
        match self {
            SystemConfig::Henon { .. } => 0..0,
            SystemConfig::Lorenz { .. } => 1..2,
            // A stored configuration is validated (N >= 2) before it is used; saturate anyway.
            SystemConfig::Disks { n, .. } => (2 * n).saturating_sub(3)..2 * n + 3,
        }
    }

    /// The time between QR steps a run takes unless told: one iteration of the map, 0.6
    /// for disks (the paper's), 0.1 for the classic Lorenz flow ([`Lorenz::default_tau`]).
    pub fn default_tau(&self) -> f64 {
        match *self {
            SystemConfig::Henon { .. } => 1.0,
            SystemConfig::Lorenz { sigma, rho, beta } => Lorenz::default_tau(sigma, rho, beta),
            SystemConfig::Disks { .. } => 0.6,
        }
    }

    /// Phase-space dimension D.
    pub fn dim(&self) -> usize {
        match self {
            SystemConfig::Henon { .. } => 2,
            SystemConfig::Lorenz { .. } => 3,
            // Saturating: an N beyond MAX_DISKS is refused by check_parameters, not wrapped.
            SystemConfig::Disks { n, .. } => n.saturating_mul(4),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunConfig {
    pub system: SystemConfig,
    /// Interval between re-orthonormalisations (one iteration for maps).
    pub tau: f64,
    /// Steps with re-orthonormalisation but no accumulation, to relax G onto the attractor.
    pub relax_steps: u64,
    /// Steps whose ln R_ii are accumulated into the spectrum.
    pub steps: u64,
    /// Number k of tangent vectors (k <= D).
    pub vectors: usize,
    pub seed: u64,
    /// Worker threads of the linear algebra. Not a setting of the results: any thread count
    /// gives the same bits (the QR's chunk grid is fixed, src/linalg), so a run may be
    /// continued on other threads ([`RunConfig::same_but_threads`]).
    pub threads: usize,
    /// Number of blocks for the standard error of the exponents.
    pub blocks: usize,
}

/// The smallest |b| of the Henon map that [`SystemConfig::check_parameters`] accepts: e^-16,
/// so that lambda_1 - lambda_2 per iteration stays below linalg's PRECISE_SPREAD of 18.
pub const MIN_HENON_B: f64 = 1.125_351_747_192_591_2e-7;

/// The most disks a run may have: 2^30, whose D = 4N doubles make 32 GB a vector.
pub const MAX_DISKS: usize = 1 << 30;

/// The longest time between two QR steps that [`RunConfig::validate`] accepts.
pub const MAX_TAU: f64 = 1e4;
/// The shortest: a growth of lambda tau per step must stand well above round-off (1e-16).
pub const MIN_TAU: f64 = 1e-9;
/// More threads than any machine this runs on has cores.
pub const MAX_THREADS: usize = 4096;

/// A thread count any stage accepts: 1 to [`MAX_THREADS`]. Checked before a stage writes
/// anything, also where a run continues on other threads.
pub fn check_threads(threads: usize) -> Result<()> {
    if threads == 0 || threads > MAX_THREADS {
        return Err(Error::param("threads", format!("must be between 1 and {MAX_THREADS}, got {threads}")));
    }
    Ok(())
}

impl RunConfig {
    /// The same run, perhaps on another number of threads (which the numbers do not depend
    /// on: a run may continue, and be replayed backward, on any).
    pub fn same_but_threads(&self, other: &RunConfig) -> bool {
        RunConfig { threads: other.threads, ..self.clone() } == *other
    }

    /// Run on `threads` threads from now on, if given.
    pub fn set_threads(&mut self, threads: Option<usize>) {
        if let Some(threads) = threads {
            self.threads = threads.max(1);
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.system.check_parameters()?;
        if matches!(self.system, SystemConfig::Disks { n: 0 | 1, .. }) {
            return Err(Error::param("n", "must be at least 2 disks (one disk alone never collides)"));
        }
        // The box as its N, density and aspect make it (a run.json may say otherwise only by
        // an edit); sides too large for that to be computed are the system's to refuse.
        if let SystemConfig::Disks { n, density, aspect, lx, ly } = self.system {
            if !(lx > 0.0 && lx.is_finite() && ly > 0.0 && ly.is_finite()) {
                return Err(Error::param("lx", format!("the box sides (--lx and --ly) must be positive numbers, got {lx} x {ly}")));
            }
            let (x, y) = box_sides(n, density, aspect);
            if x.is_finite() && y.is_finite() && !((lx - x).abs() <= 1e-9 * x.abs() && (ly - y).abs() <= 1e-9 * y.abs()) {
                return Err(Error::param("density", format!("the box {lx} x {ly} is not that of {n} disks at density {density} and aspect {aspect} ({x} x {y})")));
            }
        }
        let d = self.system.dim();
        if self.vectors == 0 || self.vectors > d {
            return Err(Error::param("vectors", format!("must be between 1 and D = {d}, got {}", self.vectors)));
        }
        if !(self.tau > 0.0 && self.tau.is_finite()) {
            return Err(Error::param("tau", format!("must be a positive number, got {}", self.tau)));
        }
        if self.tau < MIN_TAU {
            return Err(Error::param("tau", format!(
                "{:e} is so short that the tangent vectors change by round-off only between two QR steps (all exponents would come out 0); give at least {MIN_TAU:e}",
                self.tau
            )));
        }
        // Between two QR steps the tangent vectors grow like e^(lambda_1 tau) and overflow
        // beyond e^709: no chaotic system gets through a much longer interval in one piece.
        if self.tau > MAX_TAU {
            return Err(Error::param("tau", format!(
                "{:e} is longer than a QR interval can be (the tangent vectors grow like e^(lambda_1 tau) between two QR steps and overflow beyond e^709); give at most {MAX_TAU:e}",
                self.tau
            )));
        }
        if matches!(self.system, SystemConfig::Henon { .. }) && self.tau != 1.0 {
            return Err(Error::param("tau", "the Henon map advances one iteration per step: tau must be 1"));
        }
        if self.steps == 0 {
            return Err(Error::param("steps", "must be at least 1"));
        }
        if self.relax_steps.checked_add(self.steps).is_none_or(|total| total > 1 << 53) {
            return Err(Error::param("steps", format!("--relax-steps {} plus --steps {} is beyond any run (2^53 steps at most)", self.relax_steps, self.steps)));
        }
        check_threads(self.threads)?;
        if self.blocks < 2 {
            return Err(Error::param("blocks", "need at least 2 blocks for a standard error"));
        }

        Ok(())
    }

    /// Bytes a forward pass holds at least: G_n, the QR step's copy of it and its
    /// workspace (3 D k), R_n and the sums (2 k^2). The backward stage adds its segments.
    pub fn memory_bytes(&self) -> f64 {
        let (d, k) = (self.system.dim() as f64, self.vectors as f64);
        8.0 * (3.0 * d * k + 2.0 * k * k)
    }

    /// Refuse a run whose tangent vectors this machine cannot hold, before allocating them
    /// (an allocation that fails aborts the process without a word).
    fn check_memory(&self) -> Result<()> {
        let need = self.memory_bytes();
        let Some(have) = crate::machine::available_memory() else { return Ok(()) };
        if need <= have as f64 {
            return Ok(());
        }
        let d = self.system.dim();
        let which = if self.vectors == d { format!("all D = {d} vectors") } else { format!("k = {} of D = {d} vectors", self.vectors) };
        Err(Error::param(
            "vectors",
            format!(
                "{which} need about {} for the tangent vectors and the QR step, and this machine has {} available; \
                 a new run can follow the leading k vectors with --vectors k (about 24 D k bytes; a step then costs O(D k^2)), or a smaller system; \
                 an existing run (resumed, or its backward stage) needs a machine or job with that much memory",
                crate::store::run::human(need.min(u64::MAX as f64) as u64),
                crate::store::run::human(have)
            ),
        ))
    }

    /// The system in its initial state, made from the seed; refused first if the
    /// configuration is invalid or its tangent vectors would not fit in memory.
    pub fn build_system(&self) -> Result<Box<dyn DynamicalSystem>> {
        self.validate()?;
        self.check_memory()?;
        Ok(match self.system {
            SystemConfig::Henon { a, b } => {
                let mut rng = Rng::new(self.seed);
                let (x, y) = (0.2 * rng.uniform() - 0.1, 0.2 * rng.uniform() - 0.1);
                Box::new(Henon::new(a, b, x, y))
            }
            SystemConfig::Lorenz { sigma, rho, beta } => {
                // A point near the attractor, moved by the seed; the relaxation steps bring
                // it onto the attractor.
                let mut rng = Rng::new(self.seed);
                let x = [1.0 + rng.uniform(), 1.0 + rng.uniform(), 20.0 + rng.uniform()];
                Box::new(Lorenz::new(sigma, rho, beta, self.tau, x))
            }
            SystemConfig::Disks { n, lx, ly, .. } => Box::new(HardDisks::new(n, lx, ly, self.tau, self.seed)?),
        })
    }
}

/// The configurations embedded in the binary.
pub const PRESETS: [&str; 4] = ["default", "paper", "henon", "lorenz"];

impl RunConfig {
    /// A named preset: `default` (a small hard-disk system in the paper's geometry that still
    /// shows Lyapunov modes, 10-15 s end to end after the build), `paper` (the paper's 198-disk system,
    /// t_0 + t_omega = 2.5e5 steps of tau = 0.6 in all, section 5), `henon` or `lorenz`.
    pub fn preset(name: &str) -> Result<Self> {
        let disks = |n, relax_steps, steps, threads| -> Result<Self> {
            Ok(RunConfig {
                system: SystemConfig::disks(n, 0.7, 2.0 / 11.0)?,
                tau: 0.6,
                relax_steps,
                steps,
                vectors: 4 * n,
                seed: 1,
                threads,
                blocks: 20,
            })
        };
        match name {
            "default" => disks(40, 1000, 10_000, 1),
            // Two threads halve the QR step at D = 792 (`clv bench`).
            "paper" => disks(198, 10_000, 240_000, 2),
            "henon" => Ok(RunConfig {
                system: SystemConfig::henon(),
                tau: 1.0,
                relax_steps: 1000,
                steps: 1_000_000,
                vectors: 2,
                seed: 1,
                threads: 1,
                blocks: 20,
            }),
            "lorenz" => Ok(RunConfig {
                system: SystemConfig::lorenz(),
                tau: 0.1,
                relax_steps: 1000,
                steps: 100_000,
                vectors: 3,
                seed: 1,
                threads: 1,
                blocks: 20,
            }),
            other => Err(Error::param("preset", format!("unknown preset {other:?}; choose one of {}", PRESETS.join(", ")))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Henon and Lorenz parameters that leave the exponents undefined or the orbit unbounded
    /// are refused, naming the flag; a run.json edited to hold them is refused too.
    #[test]
    fn system_parameters_are_checked() {
        assert_eq!(SystemConfig::henon_with(1.2, -0.3).unwrap(), SystemConfig::Henon { a: 1.2, b: -0.3 });
        assert!(SystemConfig::lorenz_with(10.0, 0.5, 1.0).is_ok(), "a stable origin is a system too (the report warns)");
        let flag = |r: Result<SystemConfig>| match r {
            Err(Error::Param { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        assert_eq!(flag(SystemConfig::henon_with(f64::NAN, 0.3)), "henon-a");
        assert_eq!(flag(SystemConfig::henon_with(1.4, 0.0)), "henon-b");
        assert_eq!(flag(SystemConfig::henon_with(1.4, f64::INFINITY)), "henon-b");
        assert_eq!(flag(SystemConfig::lorenz_with(0.0, 28.0, 1.0)), "lorenz-sigma");
        assert_eq!(flag(SystemConfig::lorenz_with(10.0, f64::NAN, 1.0)), "lorenz-rho");
        assert_eq!(flag(SystemConfig::lorenz_with(10.0, 28.0, -1.0)), "lorenz-beta");
        // Too fast for the integrator's step count: named by what makes it so.
        assert_eq!(flag(SystemConfig::lorenz_with(10.0, 1e13, 1.0)), "lorenz-rho");
        assert_eq!(flag(SystemConfig::lorenz_with(1e7, 28.0, 1.0)), "lorenz-sigma");
        let mut config = RunConfig::preset("lorenz").unwrap();
        config.system = SystemConfig::Lorenz { sigma: -10.0, rho: 28.0, beta: 1.0 };
        assert!(config.validate().unwrap_err().to_string().contains("--lorenz-sigma"));
    }

    /// A box given by its sides must have positive, finite ones, and the error names them
    /// (it used to blame --density, which had not been given).
    #[test]
    fn box_sides_must_be_positive() {
        for (lx, ly) in [(-5.0, -5.0), (-1.0, 5.0), (0.0, 5.0), (5.0, f64::INFINITY), (f64::NAN, 5.0)] {
            let config = RunConfig { system: SystemConfig::disks_in_box(8, lx, ly), vectors: 32, ..RunConfig::preset("default").unwrap() };
            let err = config.validate().unwrap_err().to_string();
            assert!(err.contains("--lx") && err.contains("must be positive"), "{lx} x {ly}: {err}");
        }
        let fine = RunConfig { system: SystemConfig::disks_in_box(8, 5.0, 5.0), vectors: 32, ..RunConfig::preset("default").unwrap() };
        fine.validate().unwrap();
    }

    /// An N whose D = 4N does not fit a machine word wrapped to a small D (2^62 + 1 disks
    /// had D = 4, passed the memory check and hung while placing them): refused by N.
    #[test]
    fn more_disks_than_a_machine_holds_are_refused() {
        for n in [MAX_DISKS + 1, (1 << 62) + 1, usize::MAX] {
            let config = RunConfig { system: SystemConfig::disks_in_box(n, 10.0, 10.0), vectors: 4, ..RunConfig::preset("default").unwrap() };
            assert_eq!(config.system.dim(), n.saturating_mul(4));
            let err = config.validate().unwrap_err().to_string();
            assert!(err.contains("--n") && err.contains("give at most 1073741824"), "{n}: {err}");
        }
    }

    /// The configuration knows D before a system is built (to size stores and check
    /// memory); it must be the D the system's own implementation reports.
    #[test]
    fn the_configured_dimension_is_the_systems() {
        for name in PRESETS {
            let mut config = RunConfig::preset(name).unwrap();
            if let SystemConfig::Disks { .. } = config.system {
                config.system = SystemConfig::disks(8, 0.7, 1.0).unwrap();
                config.vectors = config.system.dim();
            }
            assert_eq!(config.build_system().unwrap().dim(), config.system.dim(), "preset {name}");
        }
    }

    #[test]
    fn presets_are_valid_and_unknown_names_are_refused() {
        for name in PRESETS {
            RunConfig::preset(name).unwrap().validate().unwrap();
        }
        let paper = RunConfig::preset("paper").unwrap();
        let SystemConfig::Disks { lx, ly, .. } = paper.system else { panic!() };
        // Paper section 5: Lx = 39.442544, Ly = 7.171372.
        assert!((lx - 39.442544).abs() < 1e-6 && (ly - 7.171372).abs() < 1e-6);
        assert!(RunConfig::preset("nope").unwrap_err().to_string().contains("default, paper, henon"));
        let mut none = RunConfig::preset("default").unwrap();
        none.system = SystemConfig::disks(0, 0.7, 1.0).unwrap();
        assert!(none.validate().unwrap_err().to_string().contains("--n"), "zero disks are refused, naming --n");
    }
}
