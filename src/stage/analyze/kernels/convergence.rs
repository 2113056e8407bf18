//! Is a time average converged, and can its batch-means errors be trusted? Both questions
//! are answered from the block averages a_b^i (block b = 1..B, exponent i) that the
//! standard errors come from.
//!
//! * Drift: z_i = (mean of the newer half of the blocks - mean of the older half) / the
//!   standard error of that difference, a Student t with 2 (h - 1) degrees of freedom for
//!   halves of h blocks. A stationary run with independent blocks has |z_i| > 2 for a
//!   fraction P(|t| > 2) of the exponents (4.6 % for many blocks, 18 % for halves of two);
//!   a run still settling has many more.
//! * Drift of h_KS: the same z for the sum of the positive exponents, one statistic whose
//!   block averages carry the exponents' correlations with each other in their own spread,
//!   so that its Student t is exact for a stationary run; it flags a drift at a two-sided
//!   chance below 1 %. It catches what the count misses: many exponents moving the same
//!   way, each within its errors (a run still relaxing).
//! * Independence: r_1, the lag-1 autocorrelation of consecutive block averages, averaged over
//!   the exponents. Independent blocks give about -1/B, with a spread of about 1/sqrt(B) for
//!   one exponent. Blocks shorter than the correlation time make r_1 clearly positive; their
//!   standard errors are then too small.
//!
//! Exponents that vanish by symmetry (the `neutral` indices: a null space, a flow's
//! direction) and any whose block averages do not vary beyond round-off are left out: their
//! z and r_1 would measure round-off, or, for the covariant vectors of a null space, the
//! drift that a finite backward window builds into them (e_(k+3) - s e_k).

use crate::statistics::{standard_error, student_t_two_sided};

/// The drift and independence tests over the exponents that vary.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostics {
    /// Exponents tested (those whose block averages vary beyond round-off).
    pub tested: usize,
    /// Fraction of them with |z| > 2.
    pub drifting: f64,
    /// The largest |z| and its exponent (0-based).
    pub max_z: f64,
    pub max_z_index: usize,
    /// z of the sum of the positive exponents (NaN without positive exponents).
    pub sum_z: f64,
    /// That sum is h_KS: the k exponents reach the non-positive ones (else it is the sum of
    /// the leading k only, [`crate::statistics::ks_entropy`]).
    pub sum_is_h_ks: bool,
    /// Mean lag-1 autocorrelation of consecutive block averages.
    pub r1: f64,
    /// Blocks used.
    pub blocks: usize,
    /// The block averages of all k exponents sum to a constant (k = D with a constant
    /// Jacobian determinant: ln b for Henon, -(sigma + 1 + beta) for Lorenz, 0 for hard
    /// disks), so one tested exponent follows from the others: Henon's two have z_2 = -z_1,
    /// and counted as two they made "both drift" a 6 % event that the count took for 0.4 %
    /// (11 alarms in 200 stationary runs, found by an outside check).
    pub constrained: bool,
}

impl Diagnostics {
    /// r_1 of independent blocks (its expectation, -1/B, plus two standard deviations of
    /// one exponent's r_1): above it the blocks are correlated.
    pub fn r1_limit(&self) -> f64 {
        -1.0 / self.blocks as f64 + 2.0 / (self.blocks as f64).sqrt()
    }

    /// Degrees of freedom of z for halves of h blocks: 2 (h - 1).
    fn dof(&self) -> f64 {
        2.0 * ((self.blocks / 2) as f64 - 1.0)
    }

    /// P(|z| > 2) for one exponent of a stationary run: the drift test's chance rate.
    pub fn chance(&self) -> f64 {
        student_t_two_sided(2.0, self.dof())
    }

    /// P(|t| > |sum_z|) for a stationary run: h_KS's drift at this chance or less counts
    /// below 1 %.
    pub fn sum_chance(&self) -> f64 {
        if self.sum_z.is_finite() { student_t_two_sided(self.sum_z.abs(), self.dof()) } else { 1.0 }
    }

    /// Whether the exponents drift: four times the chance rate of them with |z| > 2 (a
    /// margin for the exponents' correlations with each other, such as a symplectic
    /// spectrum's mirrored pairs), in a count that chance gives with probability below 1 %
    /// (so that one exponent of a run with k = 1 that strays by chance does not count),
    /// one exponent and one stray fewer where their sum is fixed ([`Diagnostics::constrained`]).
    /// Or h_KS drifts ([`Diagnostics::sum_chance`] below 1 %).
    pub fn drifts(&self) -> bool {
        let count = (self.drifting * self.tested as f64).round() as usize;
        let (count, tested) = if self.constrained { (count.saturating_sub(1), self.tested - 1) } else { (count, self.tested) };
        let by_count = tested > 0 && count as f64 > 4.0 * self.chance() * tested as f64 && binomial_tail(count, tested, self.chance()) < 0.01;
        by_count || self.sum_chance() < 0.01
    }

    /// What the tests say, in words.
    pub fn verdict(&self) -> &'static str {
        match (self.drifts(), self.r1 > self.r1_limit()) {
            (false, false) => "no test finds a drift or correlated blocks",
            (true, _) => "the exponents still drift: the run is too short for its standard errors; extend it",
            (false, true) => "the blocks are correlated: the standard errors are too small; extend the run (its blocks then grow)",
        }
    }

    /// The numbers of both tests, for a report line.
    pub fn numbers(&self) -> String {
        let sum = if self.sum_z.is_finite() {
            format!("{}: z = {:+.1} (as large by chance: {:.1} %)", if self.sum_is_h_ks { "h_KS" } else { "sum of the k (all positive) exponents" }, self.sum_z, 100.0 * self.sum_chance())
        } else {
            "h_KS: no positive exponent to test".to_string()
        };
        format!(
            "{:.0} % of {} exponents have |z| > 2 (by chance {:.0} %; largest |z| = {:.1}, i = {}); {sum}; r_1 = {:+.3} (limit {:+.3})",
            100.0 * self.drifting,
            self.tested,
            100.0 * self.chance(),
            self.max_z,
            self.max_z_index + 1,
            self.r1,
            self.r1_limit()
        )
    }
}

/// P(X >= x) for X binomial with n trials of probability p.
fn binomial_tail(x: usize, n: usize, p: f64) -> f64 {
    let ln_choose = |k: usize| -> f64 { (1..=k).map(|j| ((n - k + j) as f64 / j as f64).ln()).sum() };
    (x..=n).map(|k| (ln_choose(k) + k as f64 * p.ln() + (n - k) as f64 * (1.0 - p).ln()).exp()).sum::<f64>().min(1.0)
}

/// The running estimate after each block: running[b][i] = mean of a_1^i..a_(b+1)^i.
pub fn running(blocks: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut sum = vec![0.0; blocks.first().map_or(0, Vec::len)];
    blocks
        .iter()
        .enumerate()
        .map(|(b, a)| {
            for (s, x) in sum.iter_mut().zip(a) {
                *s += x;
            }
            sum.iter().map(|s| s / (b + 1) as f64).collect()
        })
        .collect()
}

/// Both tests over `blocks` (oldest first; at least 4, else None), leaving out the `neutral`
/// indices.
pub fn diagnose(blocks: &[Vec<f64>], neutral: std::ops::Range<usize>) -> Option<Diagnostics> {
    let nb = blocks.len();
    let k = blocks.first()?.len();
    if nb < 4 {
        return None;
    }
    let column = |i: usize| -> Vec<f64> { blocks.iter().map(|a| a[i]).collect() };
    let spreads: Vec<f64> = (0..k).map(|i| crate::statistics::sample_std(&column(i))).collect();
    let scale = spreads.iter().cloned().fold(0.0, f64::max);
    let varies: Vec<usize> = (0..k).filter(|&i| spreads[i] > 1e-9 * scale && scale > 0.0 && !neutral.contains(&i)).collect();
    if varies.is_empty() {
        return None;
    }
    let (mut drifting, mut max_z, mut max_z_index, mut r1) = (0usize, 0.0f64, 0usize, 0.0);
    for &i in &varies {
        let x = column(i);
        let z = halves_z(&x);
        if z.abs() > 2.0 {
            drifting += 1;
        }
        if z.abs() > max_z {
            (max_z, max_z_index) = (z.abs(), i);
        }
        let m = x.iter().sum::<f64>() / nb as f64;
        let var: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
        r1 += x.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum::<f64>() / var;
    }
    let tested = varies.len();
    let positive: Vec<usize> = varies.iter().copied().filter(|&i| column(i).iter().sum::<f64>() > 0.0).collect();
    let sums: Vec<f64> = blocks.iter().map(|a| positive.iter().map(|&i| a[i]).sum()).collect();
    let sum_z = if positive.is_empty() { f64::NAN } else { halves_z(&sums) };
    let sum_is_h_ks = (0..k).any(|i| neutral.contains(&i) || column(i).iter().sum::<f64>() <= 0.0);
    // Lorenz's integrator keeps the sum to about 1e-7 of it, a thousandth of the spreads.
    let totals: Vec<f64> = blocks.iter().map(|a| a.iter().sum()).collect();
    let constrained = tested >= 2 && crate::statistics::sample_std(&totals) < 1e-3 * scale;
    Some(Diagnostics { tested, drifting: drifting as f64 / tested as f64, max_z, max_z_index, sum_z, sum_is_h_ks, r1: r1 / tested as f64, blocks: nb, constrained })
}

/// (mean of the newer half - mean of the older half) / the standard error of that
/// difference, for a series in time order (the middle element of an odd count left out).
fn halves_z(x: &[f64]) -> f64 {
    let half = x.len() / 2;
    let (old, new) = (&x[..half], &x[x.len() - half..]);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    (mean(new) - mean(old)) / standard_error(old).hypot(standard_error(new))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// 40 blocks of 30 exponents, each block average `level(b, i)` plus noise that is
    /// independent from block to block, or an AR(1) process with coefficient `ar`.
    fn blocks(level: impl Fn(usize, usize) -> f64, ar: f64, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = Rng::new(seed);
        let mut noise = vec![0.0; 30];
        (0..40)
            .map(|b| {
                (0..30)
                    .map(|i| {
                        noise[i] = ar * noise[i] + (1.0 - ar * ar).sqrt() * rng.normal();
                        level(b, i) + 0.1 * noise[i]
                    })
                    .collect()
            })
            .collect()
    }

    /// One exponent of a k = 1 run straying by chance is no drift; a quarter of 154 is.
    #[test]
    fn drift_needs_more_strays_than_chance_gives() {
        assert!((binomial_tail(0, 10, 0.3) - 1.0).abs() < 1e-12);
        assert!((binomial_tail(2, 2, 0.3) - 0.09).abs() < 1e-12);
        assert!((binomial_tail(1, 3, 0.5) - 0.875).abs() < 1e-12);
        let d = |tested: usize, count: usize| Diagnostics { tested, drifting: count as f64 / tested as f64, max_z: 3.0, max_z_index: 0, sum_z: 0.5, sum_is_h_ks: true, r1: 0.0, blocks: 20, constrained: false };
        assert!((d(1, 0).chance() - 0.0608).abs() < 1e-3, "t with 18 degrees of freedom: {}", d(1, 0).chance());
        assert!(!d(1, 1).drifts() && !d(2, 1).drifts() && !d(154, 20).drifts());
        assert!(d(154, 40).drifts() && d(20, 10).drifts());
        // Halves of 3 blocks: |t| > 2 for 11.6 % by chance, so 16 % is no drift.
        let few = Diagnostics { blocks: 7, ..d(58, 9) };
        assert!(few.chance() > 0.11 && !few.drifts());
        // Two exponents of a fixed sum both stray together: one stray of one exponent.
        assert!(d(2, 2).drifts() && !Diagnostics { constrained: true, ..d(2, 2) }.drifts());
        assert!(Diagnostics { constrained: true, ..d(154, 40) }.drifts());
    }

    /// Two exponents whose block averages sum to a constant (Henon's, to ln b) are
    /// recognised as constrained, and their stationary runs raise the alarm at about the 1 %
    /// of h_KS's test (here lambda_1) instead of the 5-6 % of "both stray" (which is one).
    #[test]
    fn exponents_of_a_fixed_sum_count_once() {
        let henon = |seed: u64| {
            let mut rng = Rng::new(seed);
            (0..20).map(|_| {
                let a = 0.42 + 0.01 * rng.normal();
                vec![a, 0.3f64.ln() - a]
            }).collect::<Vec<_>>()
        };
        assert!(diagnose(&henon(1), 0..0).unwrap().constrained);
        assert!(!diagnose(&blocks(|_, i| 3.0 - 0.1 * i as f64, 0.0, 1), 0..0).unwrap().constrained);
        let alarms = (0..2000).filter(|&seed| diagnose(&henon(seed), 0..0).unwrap().drifts()).count();
        assert!(alarms <= 40, "{alarms} alarms in 2000 stationary runs");
    }

    #[test]
    fn running_estimates_are_cumulative_means() {
        let r = running(&[vec![1.0, 4.0], vec![3.0, 0.0], vec![5.0, 2.0]]);
        assert_eq!(r, vec![vec![1.0, 4.0], vec![2.0, 2.0], vec![3.0, 2.0]]);
    }

    /// Stationary, independent blocks pass both tests over many seeds: about 5 % of the
    /// exponents drift by chance, and r_1 stays below its limit.
    #[test]
    fn a_stationary_run_with_independent_blocks_passes() {
        let mut drifting = 0.0;
        for seed in 0..20 {
            let d = diagnose(&blocks(|_, i| 3.0 - 0.1 * i as f64, 0.0, seed), 0..0).unwrap();
            assert_eq!((d.tested, d.blocks), (30, 40));
            // All 30 positive: their sum is no h_KS, unless the last reach the null space.
            assert!(!d.sum_is_h_ks && diagnose(&blocks(|_, i| 3.0 - 0.1 * i as f64, 0.0, seed), 27..33).unwrap().sum_is_h_ks);
            assert!(d.r1 < d.r1_limit(), "seed {seed}: r1 = {}", d.r1);
            drifting += d.drifting / 20.0;
        }
        assert!((0.02..0.09).contains(&drifting), "{drifting}");
    }

    /// Exponents that all move the same way, each within its errors (a rise of one standard
    /// error of its halves' difference each), are no drift by their count but are one by
    /// h_KS. Stationary runs whose exponents share most of their noise (as neighbours in a
    /// spectrum move together, which spoils the count's binomial chance) raise h_KS's alarm
    /// at its nominal 1 %: its own spread holds the correlation.
    #[test]
    fn a_common_drift_within_the_errors_is_caught_by_h_ks() {
        let series = |rise: f64, common: f64, seed: u64| {
            let mut rng = Rng::new(seed);
            (0..40)
                .map(|b| {
                    let shared = rng.normal();
                    (0..30).map(|i| 3.0 - 0.1 * i as f64 + rise * b as f64 / 39.0 + 0.1 * (common * shared + (1.0 - common * common).sqrt() * rng.normal())).collect::<Vec<f64>>()
                })
                .collect::<Vec<_>>()
        };
        // The halves' difference of one exponent has a standard error of 0.1 sqrt(2/20).
        let rise = 2.0 * 0.1 * (2.0f64 / 20.0).sqrt();
        let (mut by_count, mut by_sum) = (0, 0);
        for seed in 0..20 {
            let d = diagnose(&series(rise, 0.0, seed), 0..0).unwrap();
            let count = (d.drifting * d.tested as f64).round() as usize;
            by_count += usize::from(d.drifting > 4.0 * d.chance() && binomial_tail(count, d.tested, d.chance()) < 0.01);
            by_sum += usize::from(d.sum_chance() < 0.01 && d.drifts());
        }
        assert!(by_sum == 20 && by_count <= 8, "a common drift caught by h_KS in {by_sum}, by the count in {by_count} of 20 seeds");
        let alarms = (1000..3000).filter(|&seed| diagnose(&series(0.0, 0.9, seed), 0..0).unwrap().sum_chance() < 0.01).count();
        assert!((8..=35).contains(&alarms), "{alarms} false alarms of h_KS in 2000 stationary runs (1 % is 20)");
    }

    /// A run still settling (exponents relaxing towards their values) drifts, and blocks
    /// shorter than the correlation time (AR(1) with coefficient 0.8) fail the r_1 test.
    #[test]
    fn drift_and_correlated_blocks_are_caught() {
        let d = diagnose(&blocks(|b, i| 3.0 - 0.1 * i as f64 + 0.5 * (-(b as f64) / 15.0).exp(), 0.0, 1), 0..0).unwrap();
        assert!(d.drifting > 0.9 && d.max_z > 5.0, "{d:?}");
        let d = diagnose(&blocks(|_, i| 3.0 - 0.1 * i as f64, 0.8, 2), 0..0).unwrap();
        assert!(d.r1 > d.r1_limit() + 0.2, "{d:?}");
    }

    /// Exponents constant up to round-off (a null space) are not tested; too few blocks give
    /// no verdict.
    #[test]
    fn round_off_exponents_and_short_runs_are_left_out() {
        let mut b = blocks(|_, i| 1.0 - 0.1 * i as f64, 0.0, 3);
        for (n, a) in b.iter_mut().enumerate() {
            a[7] = 1e-16 * (n % 3) as f64;
        }
        assert_eq!(diagnose(&b, 0..0).unwrap().tested, 29);
        assert_eq!(diagnose(&b[..3], 0..0), None);
        // a drifting exponent inside the neutral range (a null-space CLV's shear) is not tested
        for (n, a) in b.iter_mut().enumerate() {
            a[9] = -0.01 * n as f64;
        }
        assert!(diagnose(&b, 0..0).unwrap().max_z > 5.0);
        let d = diagnose(&b, 7..10).unwrap();
        assert!(d.tested == 27 && d.max_z < 5.0, "{d:?}");
    }
}
