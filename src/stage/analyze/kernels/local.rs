//! Finite-time local exponents and the domination test (paper Sec. 6, eq. for
//! Lambda_l^cov and the definition of a dominated Oseledec splitting).
//!
//! The local exponent Lambda_l(t_n) = ln |D phi^tau v^l| / tau fluctuates strongly; averaged
//! over a window of Delta steps it gives a finite-time exponent. The splitting is dominated if
//! the finite-time exponents never change order for Delta beyond some finite Delta_0, so the
//! fraction of windows in which index i+1 overtakes index i must reach zero as Delta grows.
//! Windows are consecutive and non-overlapping; a trailing partial window is dropped.

/// Finite-time exponents: means of `series` (one local exponent per step) over consecutive
/// windows of `delta` steps (paper Sec. 6, Lambda averaged over a finite time Delta tau).
/// A window containing a NaN gives NaN.
pub fn finite_time_exponents(series: &[f64], delta: usize) -> Vec<f64> {
    assert!(delta > 0, "window length must be positive");
    series.chunks_exact(delta).map(|w| w.iter().sum::<f64>() / delta as f64).collect()
}

/// Number of windows in which the finite-time exponent of `lower` (index i+1) exceeds that
/// of `upper` (index i), and the number of windows compared (both finite).
fn swap_counts(upper: &[f64], lower: &[f64], delta: usize) -> (u64, u64) {
    let a = finite_time_exponents(upper, delta);
    let b = finite_time_exponents(lower, delta);
    let mut swaps = 0;
    let mut total = 0;
    for (x, y) in a.iter().zip(&b) {
        if x.is_finite() && y.is_finite() {
            total += 1;
            swaps += u64::from(y > x);
        }
    }
    (swaps, total)
}

/// Fraction of windows of `delta` steps in which the finite-time exponent of index i+1
/// (`lower`) strictly exceeds that of index i (`upper`) (paper Sec. 6, domination). NaN if
/// no window has two finite values.
pub fn swap_fraction(upper: &[f64], lower: &[f64], delta: usize) -> f64 {
    let (s, t) = swap_counts(upper, lower, delta);
    if t == 0 { f64::NAN } else { s as f64 / t as f64 }
}

/// [`swap_fraction`] for every adjacent pair (i, i+1) of `series` (one time series per
/// index, in spectrum order); length = number of series - 1.
pub fn pair_swap_fractions<S: AsRef<[f64]>>(series: &[S], delta: usize) -> Vec<f64> {
    series.windows(2).map(|p| swap_fraction(p[0].as_ref(), p[1].as_ref(), delta)).collect()
}

/// For each Delta in `deltas`, the overall swap fraction: swapped windows over compared
/// windows, summed over all adjacent pairs of `series` (paper Sec. 6: domination requires
/// this to vanish for Delta > Delta_0). NaN for a Delta with no comparable windows.
pub fn overall_swap_fractions<S: AsRef<[f64]>>(series: &[S], deltas: &[usize]) -> Vec<f64> {
    deltas
        .iter()
        .map(|&delta| {
            let (s, t) = series
                .windows(2)
                .map(|p| swap_counts(p[0].as_ref(), p[1].as_ref(), delta))
                .fold((0, 0), |acc, x| (acc.0 + x.0, acc.1 + x.1));
            if t == 0 { f64::NAN } else { s as f64 / t as f64 }
        })
        .collect()
}

/// Streaming form of the domination test: feed the local exponents of all indices frame by
/// frame, read swap fractions per adjacent pair and per Delta without storing the series.
/// Gives the same numbers as [`pair_swap_fractions`] and [`overall_swap_fractions`].
#[derive(Clone, Debug)]
pub struct DominationTest {
    deltas: Vec<usize>,
    /// Per Delta: running window sums per index.
    sums: Vec<Vec<f64>>,
    /// Steps in the current window (the same for every Delta slot's indices).
    filled: Vec<usize>,
    /// Per Delta and adjacent pair: swapped and compared windows.
    swaps: Vec<Vec<u64>>,
    compared: Vec<Vec<u64>>,
    /// Per Delta: completed windows.
    windows: Vec<u64>,
    /// Splittings tested whole ([`DominationTest::with_splits`]): the last index of each
    /// upper block.
    splits: Vec<usize>,
    /// Per Delta and splitting: windows in which it is violated, and windows compared.
    split_violations: Vec<Vec<u64>>,
    split_compared: Vec<Vec<u64>>,
}

impl DominationTest {
    /// Test for `n_indices` series and the window lengths `deltas` (in steps, each > 0).
    pub fn new(n_indices: usize, deltas: &[usize]) -> Self {
        assert!(deltas.iter().all(|&d| d > 0), "window lengths must be positive");
        let pairs = n_indices.saturating_sub(1);
        DominationTest {
            deltas: deltas.to_vec(),
            sums: vec![vec![0.0; n_indices]; deltas.len()],
            filled: vec![0; deltas.len()],
            swaps: vec![vec![0; pairs]; deltas.len()],
            compared: vec![vec![0; pairs]; deltas.len()],
            windows: vec![0; deltas.len()],
            splits: Vec::new(),
            split_violations: vec![Vec::new(); deltas.len()],
            split_compared: vec![Vec::new(); deltas.len()],
        }
    }

    /// Also test splittings whole: for each `c`, the indices ..=c against c+1.. . A window
    /// violates the splitting where some finite-time exponent of the lower block exceeds
    /// one of the upper block (max below > min above): the domination of E^u ⊕ E^0 ⊕ E^s
    /// needs every exponent of E^u above every one of E^0, not only the two neighbours at
    /// the border.
    pub fn with_splits(mut self, splits: &[usize]) -> Self {
        self.splits = splits.to_vec();
        self.split_violations = vec![vec![0; splits.len()]; self.deltas.len()];
        self.split_compared = vec![vec![0; splits.len()]; self.deltas.len()];
        self
    }

    /// Add one step: the local exponents of all indices at this time.
    pub fn push(&mut self, local: &[f64]) {
        for (w, &delta) in self.deltas.iter().enumerate() {
            let sums = &mut self.sums[w];
            assert_eq!(local.len(), sums.len());
            for (s, x) in sums.iter_mut().zip(local) {
                *s += x;
            }
            self.filled[w] += 1;
            if self.filled[w] == delta {
                self.windows[w] += 1;
                for (p, pair) in sums.windows(2).enumerate() {
                    if pair[0].is_finite() && pair[1].is_finite() {
                        self.compared[w][p] += 1;
                        self.swaps[w][p] += u64::from(pair[1] > pair[0]);
                    }
                }
                for (c, &split) in self.splits.iter().enumerate() {
                    let (upper, lower) = sums.split_at((split + 1).min(sums.len()));
                    if !lower.is_empty() && upper.iter().chain(lower).all(|x| x.is_finite()) {
                        let min_upper = upper.iter().copied().fold(f64::INFINITY, f64::min);
                        let max_lower = lower.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                        self.split_compared[w][c] += 1;
                        self.split_violations[w][c] += u64::from(max_lower > min_upper);
                    }
                }
                sums.iter_mut().for_each(|s| *s = 0.0);
                self.filled[w] = 0;
            }
        }
    }

    /// Swap fraction of each adjacent pair (i, i+1) for the `which`-th Delta.
    pub fn pair_fractions(&self, which: usize) -> Vec<f64> {
        fractions(&self.swaps[which], &self.compared[which])
    }

    /// Fraction of windows violating each splitting of [`DominationTest::with_splits`], for
    /// the `which`-th Delta (NaN where none was compared).
    pub fn split_fractions(&self, which: usize) -> Vec<f64> {
        fractions(&self.split_violations[which], &self.split_compared[which])
    }

    /// The number of completed windows for the `which`-th Delta: what each fraction is of.
    pub fn windows(&self, which: usize) -> u64 {
        self.windows[which]
    }

    /// Overall swap fraction over all pairs, one per Delta (in the order given to `new`).
    pub fn overall(&self) -> Vec<f64> {
        (0..self.deltas.len())
            .map(|w| {
                let s: u64 = self.swaps[w].iter().sum();
                let t: u64 = self.compared[w].iter().sum();
                if t == 0 { f64::NAN } else { s as f64 / t as f64 }
            })
            .collect()
    }
}

/// counts / totals, NaN where a total is 0.
fn fractions(counts: &[u64], totals: &[u64]) -> Vec<f64> {
    counts.iter().zip(totals).map(|(&s, &t)| if t == 0 { f64::NAN } else { s as f64 / t as f64 }).collect()
}

#[cfg(test)]
mod tests {
    use super::super::testutil::Rng;
    use super::*;

    /// A splitting can be violated by exponents that are not neighbours: index 0 falls
    /// below index 2 while the neighbours (1, 2) at the cut keep their order.
    #[test]
    fn a_splitting_is_tested_whole_not_only_at_its_border() {
        let mut t = DominationTest::new(3, &[1]).with_splits(&[1]);
        t.push(&[3.0, 2.0, 1.0]);
        t.push(&[0.5, 2.0, 1.0]);
        assert_eq!(t.pair_fractions(0), [0.5, 0.0], "the border pair (2, 3) never swaps");
        assert_eq!(t.split_fractions(0), [0.5], "yet in one window index 3 is above index 1");
    }

    fn noisy(mean: f64, sd: f64, len: usize, rng: &mut Rng) -> Vec<f64> {
        (0..len).map(|_| mean + sd * rng.normal()).collect()
    }

    #[test]
    fn window_means() {
        let s = [1.0, 3.0, 2.0, 4.0, 10.0];
        assert_eq!(finite_time_exponents(&s, 2), vec![2.0, 3.0]);
        assert!(finite_time_exponents(&[1.0, f64::NAN, 1.0, 1.0], 2)[0].is_nan());
    }

    #[test]
    fn dominated_pair_never_swaps() {
        let mut rng = Rng::new(20);
        let upper = noisy(1.0, 0.1, 5000, &mut rng);
        let lower = noisy(0.0, 0.1, 5000, &mut rng);
        for delta in [1, 10, 100] {
            assert_eq!(swap_fraction(&upper, &lower, delta), 0.0);
        }
        // reversed order swaps always
        assert_eq!(swap_fraction(&lower, &upper, 1), 1.0);
    }

    #[test]
    fn equivalent_noisy_series_swap_half_the_time() {
        let mut rng = Rng::new(21);
        let a = noisy(0.5, 1.0, 20000, &mut rng);
        let b = noisy(0.5, 1.0, 20000, &mut rng);
        let f = swap_fraction(&a, &b, 1);
        assert!((f - 0.5).abs() < 0.02, "{f}");
        let f = swap_fraction(&a, &b, 10);
        assert!((f - 0.5).abs() < 0.05, "{f}");
        // identical series: ties are not swaps
        assert_eq!(swap_fraction(&a, &a, 1), 0.0);
    }

    #[test]
    fn swaps_fade_with_window_and_streaming_agrees() {
        let mut rng = Rng::new(22);
        let len = 20000;
        let series = vec![noisy(0.3, 1.0, len, &mut rng), noisy(0.2, 1.0, len, &mut rng), noisy(0.0, 1.0, len, &mut rng)];
        let deltas = [1, 10, 100, 1000];
        let overall = overall_swap_fractions(&series, &deltas);
        assert!(overall.windows(2).all(|w| w[1] < w[0]), "{overall:?}");
        assert!(overall[0] > 0.4 && overall[3] < 0.1, "{overall:?}");

        let mut test = DominationTest::new(3, &deltas);
        for t in 0..len {
            let frame: Vec<f64> = series.iter().map(|s| s[t]).collect();
            test.push(&frame);
        }
        assert_eq!(test.overall(), overall);
        for (w, &delta) in deltas.iter().enumerate() {
            assert_eq!(test.pair_fractions(w), pair_swap_fractions(&series, delta));
        }
        // NaN windows are skipped, not counted
        let mut nan = series.clone();
        nan[1][0] = f64::NAN;
        let p = pair_swap_fractions(&nan, len);
        assert!(p.iter().all(|x| x.is_nan()));
    }
}
