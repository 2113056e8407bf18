//! `clv combine`: one spectrum from independent runs of one system (other seeds, as a batch
//! array job makes them), with an error from the spread between the runs and a check of
//! each run's own errors against that spread.
//!
//! Why between runs: independent trajectories are the one error estimate that needs no
//! assumption about correlation times. The weighted mean over runs of lengths T_r is the
//! exponent of the runs laid end to end. Its error is from the spread of the run means: a
//! run of length T_r scatters with variance s^2 / T_r, so s^2 is estimated by
//! sum_r T_r (lambda_r - lambda)^2 / (R - 1), and the error of the mean is
//! sqrt(s^2 / sum T) (for equal lengths the standard error of the mean of R numbers; for
//! unequal ones, the weights' own spread would make sum_r w_r^2 (lambda_r - lambda)^2
//! too small, by 10 times for lengths 1:40). With few runs, that error rests on R - 1
//! degrees of freedom; the table gives Student's factor for a one-sigma interval. chi^2 / dof = sum_r ((lambda_r -
//! lambda) / sigma_r)^2 / (R - 1), averaged over the exponents that vary, is about 1 when
//! every run's batch-means error sigma_r is right; clearly above 1, those errors are too
//! small (or the runs do not sample the same state).

use crate::config::RunConfig;
use crate::store::run::{differences, differences_summary, StoreConfig};
use crate::error::{Error, Result};
use crate::statistics::{ks_entropy, Estimate};
use serde::{Deserialize, Serialize};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// What combining needs of one run's spectrum.json.
#[derive(Clone, Debug, Deserialize)]
struct RunSpectrum {
    config: RunConfig,
    exponents: Vec<f64>,
    #[serde(deserialize_with = "crate::statistics::errors_or_nan")]
    stderr: Vec<f64>,
}

/// The combined spectrum, as `clv combine --json` prints it.
#[derive(Clone, Debug, Serialize)]
pub struct Combined {
    pub runs: Vec<PathBuf>,
    /// The runs' common configuration (steps: the sum over the runs; seed and relax_steps:
    /// the first run's, each run's in `seeds` and `relax_steps`).
    pub config: RunConfig,
    pub seeds: Vec<u64>,
    /// Each run's steps and relaxation steps, in the order of `runs`.
    pub steps: Vec<u64>,
    pub relax_steps: Vec<u64>,
    pub exponents: Vec<f64>,
    /// Standard error from the spread between the runs.
    pub stderr: Vec<f64>,
    /// chi^2 per degree of freedom of the runs' exponents about the combined one, with
    /// their own errors (NaN where an exponent does not vary).
    pub chi2_per_dof: Vec<f64>,
    /// Mean of `chi2_per_dof` over the exponents that vary, those that vanish by symmetry left
    /// out (a flow's zero exponent telescopes: its batch-means errors are far too large, and
    /// Lorenz's chi^2/dof of 0.02 pulled the mean from 0.75 to 0.51).
    pub mean_chi2_per_dof: f64,
    /// h_KS of the combined exponents, its error from the runs' h_KS.
    pub ks_entropy: Option<Estimate>,
    /// Student's t for a one-sigma (68.3 %) interval from the R - 1 degrees of freedom of
    /// the errors: stderr times this is the interval's half width (1.84 for two runs).
    pub t_one_sigma: f64,
    /// What makes the combined exponents less trustworthy than their errors say
    /// ([`crate::report::warnings`]); absent when nothing does.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Read `paths` (run directories or spectrum.json files) and combine them.
pub fn combine(paths: &[PathBuf]) -> Result<Combined> {
    if paths.len() < 2 {
        return Err(Error::Other("clv combine needs at least two runs (run directories or their spectrum.json files)".into()));
    }
    let runs: Vec<RunSpectrum> = paths.iter().map(|p| read(p)).collect::<Result<_>>()?;
    let first = &runs[0].config;
    for (run, path) in runs.iter().zip(paths).skip(1) {
        let same = RunConfig { steps: first.steps, seed: first.seed, threads: first.threads, blocks: first.blocks, relax_steps: first.relax_steps, system: first.system.clone(), ..run.config.clone() };
        if same != *first || !run.config.system.same_system(&first.system) {
            // Named by their flags; the store's follow --steps, and may differ with it.
            let free = ["steps", "seed", "blocks", "relax-steps", "checkpoint-every", "segment-checkpoints", "segment-mb", "store-r", "clv-steps", "transient"];
            let (here, there) = (format!("in {}", paths[0].display()), format!("in {}", path.display()));
            let store = StoreConfig::for_run;
            let differ: Vec<String> = differences((first, &store(first), &here), (&run.config, &store(&run.config), &there))
                .into_iter()
                .filter(|d| !free.iter().any(|f| d.starts_with(&format!("--{f} "))))
                .collect();
            let differ = if differ.is_empty() { format!("{} against {}", serde_json::to_string(first).unwrap_or_default(), serde_json::to_string(&run.config).unwrap_or_default()) } else { differences_summary(differ) };
            return Err(Error::Other(format!(
                "{} is a run of another system or setting than {}: {differ}; runs combine where they differ only in --seed, --steps, --relax-steps and --blocks",
                path.display(),
                paths[0].display()
            )));
        }
    }
    for a in 0..runs.len() {
        if let Some(b) = (a + 1..runs.len()).find(|&b| runs[b].config.seed == runs[a].config.seed) {
            return Err(Error::Other(format!(
                "{} and {} have the same seed ({}): they follow the same trajectory and are not independent; give each run its own --seed",
                paths[a].display(),
                paths[b].display(),
                runs[a].config.seed
            )));
        }
    }
    // In the order of their seeds (all differ), so that the sums' rounding and the combined
    // configuration's seed do not depend on the order the runs were named in.
    let mut named: Vec<(RunSpectrum, PathBuf)> = runs.into_iter().zip(paths.iter().cloned()).collect();
    named.sort_by_key(|(run, _)| run.config.seed);
    let (runs, paths): (Vec<RunSpectrum>, Vec<PathBuf>) = named.into_iter().unzip();
    let first = &runs[0].config;
    let weights: Vec<f64> = runs.iter().map(|r| r.config.steps as f64).collect();
    let (mut exponents, mut stderr, mut chi2) = (Vec::new(), Vec::new(), Vec::new());
    let scale = runs.iter().flat_map(|r| &r.exponents).map(|l| l.abs()).fold(0.0, f64::max);
    for i in 0..first.vectors {
        let x: Vec<f64> = runs.iter().map(|r| r.exponents[i]).collect();
        let s: Vec<f64> = runs.iter().map(|r| r.stderr[i]).collect();
        let (mean, err) = weighted_mean(&x, &weights);
        exponents.push(mean);
        stderr.push(err);
        chi2.push(chi2_per_dof(&x, &s, mean, scale));
    }
    let neutral = first.system.neutral();
    let varying: Vec<f64> = chi2.iter().enumerate().filter(|(i, c)| c.is_finite() && !neutral.contains(i)).map(|(_, c)| *c).collect();
    // NaN (null in --json) where no exponent has errors in every run (a run of one block).
    let mean_chi2_per_dof = varying.iter().sum::<f64>() / varying.len() as f64;
    let ks = ks_entropy(&exponents, neutral.clone()).map(|value| {
        // Each run's sum over the exponents counted in the combined spectrum.
        let counted = |i: usize, c: f64| c > 0.0 && !neutral.contains(&i);
        let per_run: Vec<f64> = runs.iter().map(|r| r.exponents.iter().zip(&exponents).enumerate().filter(|(i, (_, c))| counted(*i, **c)).map(|(_, (x, _))| x).sum()).collect();
        Estimate { value, stderr: weighted_mean(&per_run, &weights).1 }
    });
    let config = RunConfig { steps: runs.iter().map(|r| r.config.steps).sum(), ..first.clone() };
    Ok(Combined {
        warnings: crate::report::warnings(&config, &exponents, &stderr),
        runs: paths,
        config,
        seeds: runs.iter().map(|r| r.config.seed).collect(),
        steps: runs.iter().map(|r| r.config.steps).collect(),
        relax_steps: runs.iter().map(|r| r.config.relax_steps).collect(),
        t_one_sigma: crate::statistics::student_t_quantile(1.0 - ONE_SIGMA, (runs.len() - 1) as f64),
        exponents,
        stderr,
        chi2_per_dof: chi2,
        mean_chi2_per_dof,
        ks_entropy: ks,
    })
}

fn read(path: &Path) -> Result<RunSpectrum> {
    let file = if path.is_dir() { path.join("spectrum.json") } else { path.to_path_buf() };
    let bytes = std::fs::read(&file).map_err(|e| match (path.is_dir(), e.kind()) {
        (true, std::io::ErrorKind::NotFound) if crate::store::run::RunDir { path: path.to_path_buf() }.is_being_written() => {
            Error::Other(format!("{} has no spectrum.json yet: another clv process is writing the run; combine it when that has finished", path.display()))
        }
        (true, std::io::ErrorKind::NotFound) if path.join("run.json").exists() => {
            Error::Other(format!("{} has no spectrum.json: the run is not finished; finish it with `clv forward --resume {}`", path.display(), path.display()))
        }
        (true, std::io::ErrorKind::NotFound) => Error::Other(format!(
            "{} is not a run directory (it has neither spectrum.json nor run.json); give the directories `clv forward --out` wrote (for `clv run`, OUT/run)",
            path.display()
        )),
        _ => Error::io(&file, e),
    })?;
    if bytes.starts_with(b"\x89MCAP") {
        return Err(Error::Other(format!(
            "{} is an MCAP file (frames or a run's segment), not a spectrum; give the run directory, or its spectrum.json",
            file.display()
        )));
    }
    let (run, _): (RunSpectrum, _) = crate::store::checked_json::from_slice(&file, &bytes).map_err(|e| {
        // Another of clv's files is intact, only not a spectrum.
        let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let sweep = name.strip_prefix("clv_spectrum").and_then(|rest| rest.strip_suffix(".json")).is_some_and(|n| n.is_empty() || n.strip_prefix('-').is_some_and(|n| n.parse::<u32>().is_ok()));
        if ["run.json", "summary.json", "backward.json"].contains(&name.as_str()) || sweep {
            Error::Other(format!("{} is clv's {name}, not a run's spectrum.json; give the run directory, or its spectrum.json", file.display()))
        } else {
            Error::Other(format!("{e}; a spectrum.json written by `clv forward --out` is expected (a damaged one is rewritten by `clv forward --resume RUN_DIR`)"))
        }
    })?;
    if run.exponents.len() != run.stderr.len() || run.exponents.len() != run.config.vectors {
        return Err(Error::corrupt(&file, format!("{} exponents and {} errors for k = {}", run.exponents.len(), run.stderr.len(), run.config.vectors)));
    }
    Ok(run)
}

/// The probability of a normal deviate within one standard deviation of its mean.
const ONE_SIGMA: f64 = 0.682_689_492_137_086;

/// The mean of `x` weighted by the lengths `w` (x_r scatters with variance s^2 / w_r), and
/// its error sqrt(s^2 / sum w), with s^2 = sum_r w_r (x_r - mean)^2 / (R - 1) unbiased.
fn weighted_mean(x: &[f64], w: &[f64]) -> (f64, f64) {
    let total: f64 = w.iter().sum();
    let mean = x.iter().zip(w).map(|(x, w)| x * w).sum::<f64>() / total;
    let s2 = x.iter().zip(w).map(|(x, w)| w * (x - mean).powi(2)).sum::<f64>() / (x.len() - 1) as f64;
    (mean, (s2 / total).sqrt())
}

/// sum_r ((x_r - mean) / s_r)^2 / (R - 1); NaN where the runs' own errors are round-off
/// against `scale`, the spectrum's largest |lambda| (an exponent fixed by a symmetry, such
/// as the null space of a Hamiltonian system).
fn chi2_per_dof(x: &[f64], s: &[f64], mean: f64, scale: f64) -> f64 {
    if s.iter().any(|s| s.is_nan() || *s <= 1e-9 * scale) {
        return f64::NAN;
    }
    x.iter().zip(s).map(|(x, s)| ((x - mean) / s).powi(2)).sum::<f64>() / (x.len() - 1) as f64
}

impl Combined {
    /// A plain-text table: index, combined exponent, error between runs, chi^2 / dof.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{:>6}  {:>14}  {:>10}  {:>9}", "i", "lambda_i", "stderr", "chi2/dof");
        for (i, ((x, e), c)) in self.exponents.iter().zip(&self.stderr).zip(&self.chi2_per_dof).enumerate() {
            let c = if c.is_finite() { format!("{c:9.2}") } else { format!("{:>9}", "-") };
            let _ = writeln!(s, "{:>6}  {:>14.8}  {:>10.2e}  {c}", i + 1, x, e);
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        if let Some(h) = self.ks_entropy {
            let _ = writeln!(s, "KS entropy (sum of the positive exponents): {h}");
        }
        let _ = writeln!(
            s,
            "{} runs (seeds {}), {} steps in all; errors from the spread between the runs, on {} degree{} of freedom{}",
            self.runs.len(),
            self.seeds.iter().map(u64::to_string).collect::<Vec<_>>().join(", "),
            self.config.steps,
            self.runs.len() - 1,
            if self.runs.len() == 2 { "" } else { "s" },
            if self.runs.len() <= 10 {
                format!(": a one-sigma (68 %) interval is {:.2} stderr wide on either side (Student's t); more runs make the errors surer", self.t_one_sigma)
            } else {
                String::new()
            }
        );
        if self.relax_steps.iter().any(|&r| r != self.relax_steps[0]) {
            let list = self.relax_steps.iter().map(u64::to_string).collect::<Vec<_>>().join(", ");
            let _ = writeln!(s, "the runs relaxed for different numbers of steps ({list}): one too short to reach the steady state biases the mean, and chi2/dof above 1 shows it");
        }
        if self.mean_chi2_per_dof.is_nan() {
            let _ = writeln!(s, "mean chi2/dof of the runs about the combined spectrum: not known, no exponent has errors in every run (a run of one block has none)");
        } else {
            let _ = writeln!(
                s,
                "mean chi2/dof of the runs about the combined spectrum, with their own errors, over the exponents that do not vanish by symmetry: {:.2} (about 1 when each run's batch-means errors are right)",
                self.mean_chi2_per_dof
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal lengths: the plain mean and the standard error of the mean of R numbers; a
    /// run twice as long counts twice, as if the runs were laid end to end.
    #[test]
    fn weighted_mean_is_the_mean_of_the_runs_laid_end_to_end() {
        let (m, e) = weighted_mean(&[1.0, 2.0, 3.0, 4.0], &[1.0; 4]);
        assert_eq!(m, 2.5);
        let sd = (((1.5f64).powi(2) * 2.0 + (0.5f64).powi(2) * 2.0) / 3.0).sqrt();
        assert!((e - sd / 2.0).abs() < 1e-15);
        let (m, _) = weighted_mean(&[1.0, 4.0], &[2.0, 1.0]);
        assert_eq!(m, (1.0 + 1.0 + 4.0) / 3.0);
    }

    /// Runs of unequal lengths, each scattering with variance 1 / T_r: the squared error
    /// is on average that of the runs laid end to end, 1 / sum T (unbiased), for lengths
    /// 1:40 as for 1:2:3. (The spread of the weights alone gave a tenth of it for 1:40.)
    #[test]
    fn the_error_of_unequal_runs_is_that_of_their_total_length() {
        let mut rng = crate::rng::Rng::new(9);
        for lengths in [vec![1.0, 40.0], vec![1.0, 2.0, 3.0]] {
            let trials = 40_000;
            let total: f64 = lengths.iter().sum();
            let (mut err2, mut mean2) = (0.0, 0.0);
            for _ in 0..trials {
                let x: Vec<f64> = lengths.iter().map(|t| rng.normal() / t.sqrt()).collect();
                let (m, e) = weighted_mean(&x, &lengths);
                err2 += e * e / trials as f64;
                mean2 += m * m / trials as f64;
            }
            assert!((err2 * total - 1.0).abs() < 0.05 && (mean2 * total - 1.0).abs() < 0.05, "{lengths:?}: {} {}", err2 * total, mean2 * total);
        }
    }

    /// chi^2/dof of normal draws with their true error is about 1 on average; with errors
    /// three times too small it is about 9; fixed exponents give NaN.
    #[test]
    fn chi2_measures_whether_the_errors_are_right() {
        let mut rng = crate::rng::Rng::new(4);
        let (mut right, mut small) = (0.0, 0.0);
        for _ in 0..2000 {
            let x: Vec<f64> = (0..5).map(|_| 2.0 + 0.1 * rng.normal()).collect();
            let m = x.iter().sum::<f64>() / 5.0;
            right += chi2_per_dof(&x, &[0.1; 5], m, 2.0) / 2000.0;
            small += chi2_per_dof(&x, &[0.1 / 3.0; 5], m, 2.0) / 2000.0;
        }
        assert!((right - 1.0).abs() < 0.08 && (small - 9.0).abs() < 0.7, "{right} {small}");
        assert!(chi2_per_dof(&[1e-16, -1e-16], &[1e-17, 1e-17], 0.0, 2.0).is_nan());
    }
}
