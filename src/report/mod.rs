//! What a person sees: the spectrum table and the JSON summary of a run.

pub mod combine;
pub mod dir;
pub mod inspect;
pub mod plot;
pub mod progress;

use crate::config::RunConfig;
use crate::statistics::{kaplan_yorke_dimension, Accumulator, BlockAverages, Estimate};
use crate::system::Invariants;
use serde::Serialize;
use std::fmt::Write;

/// Run statistics a user checks before trusting a spectrum.
#[derive(Clone, Debug, Serialize)]
pub struct Statistics {
    /// Accumulated steps (relaxation excluded).
    pub steps: u64,
    pub relax_steps: u64,
    /// Simulated time of the accumulated steps, steps * tau.
    pub simulated_time: f64,
    /// Collisions over the whole run, relaxation included (hard disks only: a map or a flow
    /// has none, and its JSON leaves the field out).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub collisions: Option<u64>,
    /// The collision frequency of a disk, 2 collisions / (N t) over the same time, relaxation
    /// included (each collision counts for both its disks, as in Enskog's theory): one
    /// computed from `collisions` and `simulated_time` would be too high by
    /// (relax + steps) / steps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub collision_frequency: Option<f64>,
    pub wall_seconds: f64,
    pub energy_initial: f64,
    pub energy_final: f64,
    /// |E_final - E_initial| / |E_initial| (NaN for systems without an energy).
    pub energy_drift: f64,
    pub momentum_final: [f64; 2],
}

impl Statistics {
    pub fn new(config: &RunConfig, start: &Invariants, end: &Invariants, wall_seconds: f64) -> Self {
        Statistics {
            steps: config.steps,
            relax_steps: config.relax_steps,
            simulated_time: config.steps as f64 * config.tau,
            collisions: matches!(config.system, crate::config::SystemConfig::Disks { .. }).then_some(end.events),
            collision_frequency: match config.system {
                crate::config::SystemConfig::Disks { n, .. } => Some(2.0 * end.events as f64 / (n as f64 * (config.relax_steps + config.steps) as f64 * config.tau)),
                _ => None,
            },
            wall_seconds,
            energy_initial: start.energy,
            energy_final: end.energy,
            energy_drift: ((end.energy - start.energy) / start.energy).abs(),
            momentum_final: end.momentum,
        }
    }
}

/// What makes a forward spectrum `exponents` (lambda_1 first, with standard errors
/// `stderr`) of `config`'s run less trustworthy than its errors say: a tau too long for a
/// double's digits ([`crate::linalg::precision_warning`]), a hard-disk null space not yet
/// settled ([`null_space_warning`]), or no sign of chaos ([`chaos_warning`]).
pub fn warnings(config: &RunConfig, exponents: &[f64], stderr: &[f64]) -> Vec<String> {
    crate::linalg::precision_warning(exponents, config.tau).into_iter().chain(null_space_warning(config, exponents)).chain(chaos_warning(config, exponents, stderr)).collect()
}

/// At or below this fraction of the largest |lambda_i| (and, for a map, below this many
/// e-foldings per iteration), lambda_1 is not taken for positive.
pub const CHAOS_TOLERANCE: f64 = 1e-3;

/// Why lambda_1 is not clearly positive, if it is not: every exponent exactly 0 (no growth
/// at all: hard disks that never collided), within 3 standard errors of 0, at
/// most [`CHAOS_TOLERANCE`] of the largest |lambda_i|, or for a map below that per
/// iteration (an area-preserving Henon map's quasi-periodic orbits give lambda_1 = -lambda_2
/// decaying like ln t / t, as small as that after 2e4 iterations). With other parameters
/// the Henon map and the Lorenz flow settle on a stable fixed point or periodic orbit, whose
/// exponents these then are; a short run may not tell even at the classic parameters.
pub fn chaos_warning(config: &RunConfig, exponents: &[f64], stderr: &[f64]) -> Option<String> {
    use crate::config::SystemConfig;
    let lambda_1 = *exponents.first()?;
    let scale = exponents.iter().fold(0.0f64, |m, l| m.max(l.abs()));
    if scale == 0.0 {
        // Free flight shears the tangent vectors (dq += t dp), which grow only linearly: QR
        // steps of a shear give R_ii of exactly 1.
        return Some(match config.system {
            SystemConfig::Disks { .. } => "every exponent is exactly 0: no two disks collided in the run, and free flight only shears the tangent vectors, \
                 so this is no Lyapunov spectrum of the gas (nor its Kaplan-Yorke dimension): the box is far too large for its disks; raise --density, or give a smaller --lx and --ly"
                .into(),
            _ => "every exponent is exactly 0: no tangent vector grew or shrank, so this is no Lyapunov spectrum".into(),
        });
    }
    let sigma = stderr.first().copied().filter(|s| s.is_finite() && *s > 0.0);
    let map = matches!(config.system, SystemConfig::Henon { .. });
    let why = if lambda_1 <= CHAOS_TOLERANCE * scale {
        format!("at most {CHAOS_TOLERANCE:.0e} of the largest |lambda_i|, {scale:.3e}")
    } else if map && lambda_1 < CHAOS_TOLERANCE {
        format!("below {CHAOS_TOLERANCE:.0e} per iteration")
    } else if let Some(s) = sigma.filter(|&s| lambda_1 < 3.0 * s) {
        format!("within 3 standard errors of 0, {s:.1e} each")
    } else {
        return None;
    };
    // Hard disks are chaotic at every density, as are the classic Henon and Lorenz systems.
    let too_short = "these parameters are chaotic, so the run is too short to tell: extend it";
    let what = match config.system {
        SystemConfig::Henon { .. } if config.system != SystemConfig::henon() => {
            "with these parameters the orbit may not be chaotic but have settled on a stable periodic orbit (all exponents negative) or, with |b| = 1, a quasi-periodic one (both zero), whose exponents these then are; or the run is too short to tell; the paper's chaotic attractor has a = 1.4, b = 0.3"
        }
        SystemConfig::Lorenz { .. } if config.system != SystemConfig::lorenz() => {
            "with these parameters the orbit may not be chaotic but have settled on a stable fixed point (all exponents negative; with sigma = 10, beta = 8/3 every orbit does below rho = 24.06, after a chaotic transient above 13.93) or periodic orbit (lambda_1 = 0, along the flow; windows such as rho = 99.5..100.8, 160 or 350), whose exponents these then are, and the analyses that take lambda_2 for the flow direction's zero exponent do not apply; or the run is too short to tell; the classic chaotic parameters are sigma = 10, rho = 28, beta = 8/3"
        }
        _ => too_short,
    };
    let error = sigma.map(|s| format!(" ± {s:.1e}")).unwrap_or_default();
    Some(format!("lambda_1 = {lambda_1:.3e}{error} is not clearly positive ({why}): {what}"))
}

/// Above this fraction of lambda_1, a null-space exponent of hard disks is not round-off.
/// Settled runs have 1e-15 .. 1e-13 of it; 36 disks at density 0.05 after the default 100
/// relaxation steps had 3e-3 (a stress hunt; 1e-14 after 3000).
pub const NULL_SPACE_TOLERANCE: f64 = 1e-6;

/// Why the hard disks' six null-space exponents (i = 2N-2..2N+3), zero by symmetry, are
/// not zero to round-off, if they are not: the GS vectors settle into the null space only as
/// fast as the exponents beside it separate from zero, which is slow in a dilute gas or a
/// long thin box; until they have, the exponents next to the null space, h_KS and the mode
/// analyses carry the remainder.
pub fn null_space_warning(config: &RunConfig, exponents: &[f64]) -> Option<String> {
    let crate::config::SystemConfig::Disks { .. } = config.system else {
        return None;
    };
    let null = config.system.neutral();
    let lambda_1 = *exponents.first()?;
    let (i, worst) = exponents.get(null.clone())?.iter().enumerate().map(|(i, l)| (null.start + i, l.abs())).max_by(|a, b| a.1.total_cmp(&b.1))?;
    (lambda_1 > 0.0 && worst > NULL_SPACE_TOLERANCE * lambda_1).then(|| {
        format!(
            "the null-space exponents (i = {}..{}), zero by symmetry, are not zero to round-off: |lambda_{}| = {worst:.2e}, {:.1e} of lambda_1 (a settled run has about 1e-14): \
             the GS vectors had not settled into the null space when the exponents began to accumulate, which is slow where the exponents beside it are small (a dilute gas, a long thin box), \
             and the exponents next to it, h_KS and the mode analyses carry the rest; give more --relax-steps ({} now; ten times more, say)",
            null.start + 1,
            null.end,
            i + 1,
            worst / lambda_1,
            config.relax_steps
        )
    })
}

/// The result of a forward pass, as printed by `clv forward --json`.
#[derive(Clone, Debug, Serialize)]
pub struct SpectrumReport {
    pub config: RunConfig,
    /// lambda_1 >= ... >= lambda_k.
    pub exponents: Vec<f64>,
    /// Standard error of each exponent (block averages).
    pub stderr: Vec<f64>,
    /// h_KS, the sum of the positive exponents outside those that vanish by symmetry
    /// (Pesin's identity, [`crate::statistics::ks_entropy`]); None when all k are positive.
    pub ks_entropy: Option<Estimate>,
    /// D_KY (Kaplan-Yorke); None when the k exponents do not decide it.
    pub kaplan_yorke_dimension: Option<f64>,
    pub statistics: Statistics,
    /// The block averages behind `stderr`.
    pub blocks: BlockAverages,
    /// What makes the exponents less trustworthy than their errors say ([`warnings`]: a tau
    /// too long for a double's digits, an unsettled null space); absent when nothing does.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

impl SpectrumReport {
    /// The report of a forward pass whose exponents are accumulated in `acc`.
    pub fn new(config: RunConfig, acc: &Accumulator, statistics: Statistics) -> Self {
        let exponents = acc.exponents(config.tau);
        SpectrumReport {
            warnings: warnings(&config, &exponents, &acc.stderr(config.tau)),
            stderr: acc.stderr(config.tau),
            ks_entropy: acc.ks_entropy(config.tau, config.system.neutral()),
            kaplan_yorke_dimension: kaplan_yorke_dimension(&exponents, config.system.dim()),
            exponents,
            statistics,
            blocks: acc.block_averages(config.tau),
            config,
        }
    }

    /// A plain-text table: index, exponent, error; then the sum and, for a full spectrum of a
    /// symplectic system, the conjugate-pair sums lambda_i + lambda_{D+1-i}.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let l = &self.exponents;
        let full = self.config.vectors == self.config.system.dim() && self.config.system.dim().is_multiple_of(4);
        let _ = writeln!(s, "{:>6}  {:>14}  {:>10}{}", "i", "lambda_i", "stderr", if full { "   lambda_i + lambda_(D+1-i)" } else { "" });
        for (i, (x, e)) in l.iter().zip(&self.stderr).enumerate() {
            let pair = if full && i < l.len() / 2 { format!("   {:>+12.3e}", x + l[l.len() - 1 - i]) } else { String::new() };
            let _ = writeln!(s, "{:>6}  {:>14.8}  {:>10.2e}{pair}", i + 1, x, e);
        }
        let st = &self.statistics;
        let k = l.len();
        let sum = l.iter().sum::<f64>();
        if k == self.config.system.dim() {
            let _ = writeln!(s, "sum of exponents: {sum:+.3e}");
        } else {
            let _ = writeln!(s, "sum of the leading k = {k} exponents: {sum:+.3e}");
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        if let Some(h) = self.ks_entropy {
            let per = match self.config.system {
                crate::config::SystemConfig::Disks { n, .. } => format!(", {:.6} per disk", h.value / n as f64),
                _ => String::new(),
            };
            let _ = writeln!(s, "KS entropy (sum of the positive exponents): {h}{per}");
        }
        if let Some(d) = self.kaplan_yorke_dimension {
            let _ = writeln!(s, "Kaplan-Yorke dimension: {d:.6} (of D = {})", self.config.system.dim());
        }
        if let Some(d) = crate::stage::analyze::kernels::convergence::diagnose(&self.blocks.exponents, self.config.system.neutral()) {
            let _ = writeln!(s, "convergence ({} blocks of {} steps): {}; {}", d.blocks, self.blocks.block_steps, d.numbers(), d.verdict());
        }
        // Times as n tau: 1.8, not the 1.7999999999999998 the product rounds to.
        let time = |t: f64| if t != 0.0 && !(1e-3..1e9).contains(&t.abs()) { format!("{t:e}") } else { format!("{t:.6}").trim_end_matches('0').trim_end_matches('.').to_string() };
        let t = time(st.simulated_time);
        let _ = write!(s, "{} steps (t = {t}), ", st.steps);
        let each = st.collision_frequency.map(|f| format!(" ({f:.4} per disk and unit time)")).unwrap_or_default();
        match st.collisions {
            Some(c) if st.relax_steps > 0 => {
                let all = time((st.relax_steps + st.steps) as f64 * self.config.tau);
                let _ = writeln!(s, "{c} collisions{each} in t = {all} with the {} relaxation steps, {:.1} s wall, energy drift {:.1e}", st.relax_steps, st.wall_seconds, st.energy_drift);
            }
            Some(c) => {
                let _ = writeln!(s, "{c} collisions{each}, {:.1} s wall, energy drift {:.1e}", st.wall_seconds, st.energy_drift);
            }
            None => {
                let _ = writeln!(s, "{:.1} s wall", st.wall_seconds);
            }
        }
        s
    }
}

/// The spectrum part of a report file (spectrum.json, clv_spectrum.json).
#[derive(Clone, Debug, serde::Deserialize)]
pub struct SpectrumSummary {
    pub exponents: Vec<f64>,
    #[serde(deserialize_with = "crate::statistics::errors_or_nan")]
    pub stderr: Vec<f64>,
    /// Absent from the files of builds before it was reported.
    #[serde(default)]
    pub ks_entropy: Option<Estimate>,
    /// Absent from the files of builds before they were kept.
    #[serde(default)]
    pub blocks: Option<BlockAverages>,
    /// What the forward stage warned of ([`SpectrumReport::warnings`]).
    #[serde(default)]
    pub warnings: Vec<String>,
}

impl SpectrumSummary {
    pub fn read(path: &std::path::Path) -> crate::Result<Self> {
        crate::store::checked_json::read(path).map(|(s, _)| s)
    }
}

/// The backward stage's plain-text table: the CLV exponents beside the GS ones over the
/// same steps (like for like) and over the whole run (the better estimate of the GS
/// exponents), with errors, the KS entropies, warnings and the sweep's statistics.
pub fn backward_table(report: &crate::stage::backward::BackwardReport) -> String {
    let window = report.gs_window.as_ref();
    let at = |v: Option<&Vec<f64>>, i: usize| v.and_then(|v| v.get(i)).copied().unwrap_or(f64::NAN);
    let mut table = format!("{:>6}  {:>14}  {:>10}  {:>14}  {:>10}  {:>14}  {:>10}\n", "i", "lambda_i (CLV)", "stderr", "(GS, window)", "stderr", "(GS, run)", "stderr");
    for i in 0..report.exponents.len() {
        let _ = writeln!(
            table,
            "{:>6}  {:>14.8}  {:>10.2e}  {:>14.8}  {:>10.2e}  {:>14.8}  {:>10.2e}",
            i + 1,
            report.exponents[i],
            report.stderr[i],
            at(window.map(|w| &w.exponents), i),
            at(window.map(|w| &w.stderr), i),
            at(Some(&report.gs_exponents), i),
            at(Some(&report.gs_stderr), i)
        );
    }
    let _ = writeln!(
        table,
        "KS entropy (sum of the positive exponents): {} (CLV), {} (GS over the same steps), {} (GS over the run)",
        Estimate::or_unknown(report.ks_entropy),
        Estimate::or_unknown(window.and_then(|w| w.ks_entropy)),
        Estimate::or_unknown(report.gs_ks_entropy)
    );
    for w in &report.warnings {
        let _ = writeln!(table, "warning (of the forward stage): {w}");
    }
    let st = &report.statistics;
    let when = if report.earlier { " by the sweep that finished earlier" } else { "" };
    let _ = writeln!(table, "{} frames (steps {}..{}), {} steps recomputed in {} segments{when}, {:.1} s", st.frames, st.first_frame_step, st.last_frame_step, st.recomputed_steps, st.segments, st.wall_seconds);
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The null-space warning: for hard disks only, from the largest |lambda| of i =
    /// 2N-2..2N+3 against lambda_1, naming it and the relaxation to lengthen.
    #[test]
    fn an_unsettled_null_space_is_named() {
        let mut config = RunConfig::preset("default").unwrap();
        config.system = crate::config::SystemConfig::disks(4, 0.7, 1.0).unwrap();
        let mut l = vec![2.0, 1.5, 1.0, 0.5, 0.25, 3e-15, -1e-14, 2e-15, 0.0, -1e-15, 1e-15, -0.25, -0.5, -1.0, -1.5, -2.0];
        assert!(null_space_warning(&config, &l).is_none(), "round-off is settled");
        l[6] = -4e-5;
        let w = null_space_warning(&config, &l).expect("2e-5 of lambda_1");
        assert!(w.contains("(i = 6..11)") && w.contains("|lambda_7| = 4.00e-5") && w.contains("2.0e-5 of lambda_1") && w.contains("--relax-steps (1000 now"), "{w}");
        assert_eq!(warnings(&config, &l, &[1e-3; 16]), vec![w]);
        assert!(null_space_warning(&config, &l[..5]).is_none(), "k < 2N+3: the null space is not among the exponents");
        config.system = crate::config::SystemConfig::Lorenz { sigma: 10.0, rho: 28.0, beta: 8.0 / 3.0 };
        assert!(null_space_warning(&config, &[0.9, 1e-3, -14.5]).is_none(), "a flow's zero exponent converges like 1/T");
    }

    /// No clearly positive exponent: a warning that names lambda_1 and why it is not (at
    /// most 1e-3 of the largest |lambda|, for a map below 1e-3 per iteration, or within 3
    /// standard errors of 0), and what the orbit may have settled on or, at the classic
    /// parameters, that the run is too short; chaos passes.
    #[test]
    fn a_spectrum_without_chaos_is_named() {
        let mut henon = RunConfig::preset("henon").unwrap();
        assert!(chaos_warning(&henon, &[0.42, -1.62], &[4e-4, 4e-4]).is_none());
        let w = chaos_warning(&henon, &[-0.09, -1.11], &[0.29, 0.29]).expect("three steps of the paper's map");
        assert!(w.contains("lambda_1 = -9.000e-2 ± 2.9e-1") && w.contains("these parameters are chaotic, so the run is too short"), "{w}");
        henon.system = crate::config::SystemConfig::henon_with(1.0, 0.3).unwrap();
        let w = chaos_warning(&henon, &[-0.161, -1.043], &[7e-11, 7e-11]).expect("a periodic orbit");
        assert!(w.contains("lambda_1 = -1.610e-1") && w.contains("at most 1e-3 of the largest") && w.contains("periodic orbit") && w.contains("a = 1.4, b = 0.3"), "{w}");
        assert_eq!(warnings(&henon, &[-0.161, -1.043], &[7e-11, 7e-11]), vec![w]);
        // |b| = 1, a quasi-periodic orbit: lambda_1 = -lambda_2 is the largest |lambda| itself
        // (an outside check's a = 0.3, b = -1: 2.3e-4 +- 8.8e-5 after 2e4 iterations).
        henon.system = crate::config::SystemConfig::henon_with(0.3, -1.0).unwrap();
        let w = chaos_warning(&henon, &[2.3e-4, -2.3e-4], &[8.8e-5, 8.8e-5]).expect("quasi-periodic");
        assert!(w.contains("below 1e-3 per iteration") && w.contains("quasi-periodic"), "{w}");
        let mut lorenz = RunConfig::preset("lorenz").unwrap();
        assert!(chaos_warning(&lorenz, &[0.906, 1e-4, -14.57], &[0.01, 0.01, 0.01]).is_none());
        lorenz.system = crate::config::SystemConfig::lorenz_with(10.0, 100.5, 8.0 / 3.0).unwrap();
        let w = chaos_warning(&lorenz, &[0.052, -0.3, -14.0], &[0.053, 0.05, 0.05]).expect("a periodic window, inside its errors");
        assert!(w.contains("within 3 standard errors of 0") && w.contains("fixed point") && w.contains("lambda_2 for the flow direction"), "{w}");
        assert!(chaos_warning(&lorenz, &[0.5, -0.3, -14.0], &[f64::NAN; 3]).is_none(), "no errors, no statistical test");
        assert!(chaos_warning(&lorenz, &[], &[]).is_none(), "nothing measured yet");
        // Exactly zero: nothing grew (hard disks that never collided: R_ii = 1 in every step).
        let w = chaos_warning(&lorenz, &[0.0, 0.0, 0.0], &[0.0; 3]).expect("no growth");
        assert!(w.starts_with("every exponent is exactly 0: no tangent vector grew"), "{w}");
        let disks = RunConfig::preset("default").unwrap();
        let w = chaos_warning(&disks, &[0.0; 160], &[0.0; 160]).expect("no collision");
        assert!(w.contains("no two disks collided") && w.contains("raise --density"), "{w}");
    }

    /// The collision frequency counts each collision for both disks, over the relaxation too.
    #[test]
    fn collision_frequency_is_per_disk_over_the_whole_run() {
        let config = RunConfig::preset("default").unwrap();
        let (start, end) = (Invariants { energy: 40.0, momentum: [0.0; 2], events: 0 }, Invariants { energy: 40.0, momentum: [0.0; 2], events: 66_000 });
        let st = Statistics::new(&config, &start, &end, 1.0);
        let t = (config.relax_steps + config.steps) as f64 * config.tau;
        assert_eq!(st.collision_frequency, Some(2.0 * 66_000.0 / (40.0 * t)));
        let henon = RunConfig::preset("henon").unwrap();
        assert_eq!(Statistics::new(&henon, &start, &end, 1.0).collision_frequency, None);
    }
}
