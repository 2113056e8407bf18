//! Local exponents and the domination test (paper Sec. 6, the conclusion).
//!
//! The local CLV exponent Lambda_l(t_n) = ln |D phi^tau v^l(t_n)| / tau (every frame carries
//! them) fluctuates strongly. Frame n carries the growth over [t_n, t_(n+1)], the step
//! column says n; the paper (Sec. 6) writes the growth over [t_(n-1), t_n] as Lambda at
//! t_n, one step later than here. The fluctuations averaged over Delta steps it gives a finite-time exponent. The
//! Oseledec splitting is dominated if the finite-time exponents do not change their order for
//! any Delta beyond some finite Delta_0, so the fraction of windows in which an index i+1
//! overtakes index i must vanish as Delta grows.
//!
//! Written here: the time series of Lambda_l for a few indices (1, the selected j, the
//! smallest positive 2N-3), the statistics of their finite-time exponents per Delta, and the
//! swap fraction against Delta, over all adjacent pairs, over the pairs outside the null space
//! (whose six exponents are equal, so its pairs swap about half of the time for every Delta),
//! and for the pairs (j, j+1) of the selected indices.
//!
//! Needs every frame. Frames arrive newest first (the backward pass); windows are consecutive
//! blocks of Delta frames counted from the newest frame (window sums do not depend on the
//! order), and the time series are sorted by step before they are written. Memory: the few
//! plotted series plus the streaming [`DominationTest`], and the local exponents of the
//! frames before the first sampled one, on which the selected j are settled
//! ([`Context::settle`]).

use super::kernels::local::{finite_time_exponents, DominationTest};
use super::{save_figure, write_csv, Analysis, Context, Produced};
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::stage::frame::{on_stride, Frame};
use std::path::Path;

pub struct LocalExponents {
    ctx: Context,
    /// 0-based indices whose series are kept, ascending, from the first sampled frame on.
    idx: Vec<usize>,
    /// 0-based selected indices j (pairs (j, j+1) of the domination figure).
    js: Vec<usize>,
    /// The local exponents of the frames before the first sampled one, whose series wait for
    /// the indices ([`LocalExponents::choose`]).
    pending: Vec<Vec<f64>>,
    /// `idx` and `js` are chosen.
    chosen: bool,
    deltas: Vec<usize>,
    test: DominationTest,
    /// In arrival order (newest first).
    steps: Vec<u64>,
    times: Vec<f64>,
    series: Vec<Vec<f64>>,
    /// Frames whose step does not continue the sequence (step +- 1 in the stream's direction).
    breaks: u64,
    /// +1 or -1 once two frames have been seen (-1 for the backward stream).
    direction: Option<i128>,
}

/// 0-based index of the smallest positive exponent: 2N-3 for disks, else the last positive
/// exponent of the forward spectrum if known.
fn smallest_positive(ctx: &Context) -> Option<usize> {
    if ctx.is_disks() {
        return (ctx.n >= 2 && 2 * ctx.n - 4 < ctx.k).then(|| 2 * ctx.n - 4);
    }
    // The flow direction's exponent of Lorenz is zero, whatever sign its estimate has.
    let neutral = ctx.run.config.system.neutral();
    ctx.gs.as_ref().and_then(|g| (0..g.exponents.len()).rev().find(|&i| g.exponents[i] > 0.0 && !neutral.contains(&i))).filter(|&i| i < ctx.k)
}

/// Frames drawn in the figure of the local exponents: the newest this many.
const MAX_DRAWN: usize = 2000;

/// See [`super::Missing`].
pub fn left_out(_: &Context, missing: super::Missing) -> Option<&'static str> {
    (missing == super::Missing::ConsecutiveFrames).then_some("the finite-time exponents and the domination test of Sec. 6")
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    if ctx.k == 0 {
        return None;
    }
    // Windows of Delta steps need consecutive frames: a file of every m-th step has none.
    let deltas: Vec<usize> = if ctx.saved_every > 1 { Vec::new() } else { ctx.options.deltas.iter().map(|&d| d as usize).filter(|&d| d > 0).collect() };
    Some(Box::new(LocalExponents {
        ctx: ctx.clone(),
        series: Vec::new(),
        idx: Vec::new(),
        js: Vec::new(),
        pending: Vec::new(),
        chosen: false,
        test: DominationTest::new(ctx.k, &deltas).with_splits(&null_borders(ctx).iter().map(|&(_, i)| i).collect::<Vec<_>>()),
        deltas,
        steps: Vec::new(),
        times: Vec::new(),
        breaks: 0,
        direction: None,
    }))
}

/// Mean, sample standard deviation (NaN for one value), minimum and maximum of the finite
/// values.
fn stats(x: &[f64]) -> [f64; 4] {
    let f: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
    if f.is_empty() {
        return [f64::NAN; 4];
    }
    let mean = f.iter().sum::<f64>() / f.len() as f64;
    [mean, crate::statistics::sample_std(&f), f.iter().copied().fold(f64::INFINITY, f64::min), f.iter().copied().fold(f64::NEG_INFINITY, f64::max)]
}

/// Mean of the finite entries (NaN if none).
fn finite_mean(x: impl IntoIterator<Item = f64>) -> f64 {
    let (s, n) = x.into_iter().filter(|v| v.is_finite()).fold((0.0, 0u64), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Frames whose local exponents are held at most before the indices are chosen without a
/// sampled frame.
const PENDING_MAX: usize = 4096;

impl LocalExponents {
    /// The indices of the series: 1, the selected j of the context settled at the first
    /// sampled frame (`frame`; None: the default j as it is), the smallest positive exponent.
    fn choose(&mut self, frame: Option<&Frame>) {
        if let Some(frame) = frame {
            self.ctx.settle(frame);
        }
        let ctx = &self.ctx;
        self.js = ctx.options.j.iter().map(|j| j - 1).filter(|&j| j < ctx.k).collect();
        self.idx = std::iter::once(0).chain(self.js.iter().copied()).chain(smallest_positive(ctx)).collect();
        self.idx.sort_unstable();
        self.idx.dedup();
        self.series = self.idx.iter().map(|&i| self.pending.iter().map(|local| local[i]).collect()).collect();
        self.pending = Vec::new();
        self.chosen = true;
    }

    /// What the plotted indices are, for a caption: "the largest exponent, i = 1; the
    /// selected indices, j = 5; the smallest positive exponent, i = 7".
    fn roles(&self) -> String {
        let smallest = smallest_positive(&self.ctx);
        let mut roles = vec![if smallest == Some(0) { "the largest and smallest positive exponent, i = 1".to_string() } else { "the largest exponent, i = 1".to_string() }];
        let js: Vec<String> = self.js.iter().map(|j| (j + 1).to_string()).collect();
        if !js.is_empty() {
            roles.push(format!("the selected {}, j = {}", if js.len() == 1 { "index" } else { "indices" }, js.join(", ")));
        }
        if let Some(i) = smallest.filter(|&i| i > 0) {
            roles.push(format!("the smallest positive exponent, i = {}", i + 1));
        }
        roles.join("; ")
    }

    /// The 0-based pairs (i, i+1) with both indices in the null space (disks only).
    fn in_null(&self, i: usize) -> bool {
        let null = self.ctx.run.config.system.neutral();
        self.ctx.is_disks() && null.contains(&i) && null.contains(&(i + 1))
    }
}

/// The pairs at the borders of the null space of disks with all D vectors, (2N-3, 2N-2)
/// between E^u and E^0 and (2N+3, 2N+4) between E^0 and E^s (1-based), as the 0-based index
/// i of their first member. The same
/// i are the last indices of the upper blocks of the splittings E^u | E^0 ⊕ E^s and
/// E^u ⊕ E^0 | E^s.
fn null_borders(ctx: &Context) -> Vec<(&'static str, usize)> {
    match ctx.null_space() {
        // The splitting is tested whole: E^s needs all its vectors.
        Some(null) if ctx.k == ctx.d => vec![("border_unstable_null", null.start - 1), ("border_null_stable", null.end - 1)],
        _ => Vec::new(),
    }
}

impl Analysis for LocalExponents {
    fn name(&self) -> &'static str {
        "local_exponents"
    }

    fn sampled(&self) -> bool {
        false
    }

    fn consume(&mut self, frame: &Frame) -> Result<()> {
        if let Some(&last) = self.steps.last() {
            let diff = frame.step as i128 - last as i128;
            let dir = *self.direction.get_or_insert(diff.signum());
            if diff != dir || dir == 0 {
                self.breaks += 1;
            }
        }
        self.test.push(&frame.local);
        self.steps.push(frame.step);
        self.times.push(frame.time);
        if !self.chosen {
            if on_stride(frame.step, self.ctx.options.every) && !frame.v.is_empty() {
                self.choose(Some(frame));
            } else if self.pending.len() < PENDING_MAX {
                self.pending.push(frame.local.clone());
                return Ok(());
            } else {
                self.choose(None);
            }
        }
        for (s, &i) in self.series.iter_mut().zip(&self.idx) {
            s.push(frame.local[i]);
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        if !self.chosen {
            self.choose(None);
        }
        let ctx = &self.ctx;
        if self.steps.is_empty() {
            return Ok(Vec::new());
        }
        let names: Vec<String> = self.idx.iter().map(|i| format!("{}", i + 1)).collect();
        let caveat = if ctx.saved_every > 1 {
            format!(
                " This frame file holds the frames of the steps that are multiples of {} only, so the finite-time exponents and the domination test, which need consecutive steps, are not computed: analyse the whole stream (`clv backward RUN_DIR --out - | clv analyze -`) for them.",
                ctx.saved_every
            )
        } else if self.breaks > 0 {
            format!(" Warning: the steps of {} frames do not continue the sequence of their predecessor (frames missing or out of order); windows straddle those gaps.", self.breaks)
        } else {
            String::new()
        };

        let mut produced = vec![self.series_entry(out, frames, &names, &caveat)?];
        if self.deltas.is_empty() {
            return Ok(produced);
        }
        let frames_n = self.steps.len();
        let too_long: Vec<usize> = self.deltas.iter().copied().filter(|&dl| dl > frames_n).collect();
        let unfilled = if too_long.is_empty() {
            String::new()
        } else {
            format!(" No window of Δ = {too_long:?} fits in the {frames_n} frames: their rows hold 0 windows and NaN.")
        };
        produced.push(self.finite_time_entry(out, &names, &unfilled, &caveat)?);
        // Of pairs of neighbouring exponents, none with one vector.
        if self.ctx.k >= 2 {
            produced.push(self.domination_entry(out, frames, &unfilled, &caveat)?);
        }
        Ok(produced)
    }
}

impl LocalExponents {
    /// The time series of the local exponents (in time order) and their figure.
    fn series_entry(&self, out: &Path, frames: u64, names: &[String], caveat: &str) -> Result<Produced> {
        // Time series, in time order.
        let mut order: Vec<usize> = (0..self.steps.len()).collect();
        order.sort_by_key(|&p| self.steps[p]);
        let mut header = vec!["step".to_string(), "time".to_string()];
        header.extend(names.iter().map(|i| format!("lambda_{i}")));
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        write_csv(
            &out.join("local_exponents.csv"),
            &h,
            order.iter().map(|&p| {
                let mut row = vec![self.steps[p] as f64, self.times[p]];
                row.extend(self.series.iter().map(|s| s[p]));
                row
            }),
        )?;
        // A longer series drawn whole is a solid band in which one exponent hides the other.
        let drawn = &order[order.len().saturating_sub(MAX_DRAWN)..];
        let t: Vec<f64> = drawn.iter().map(|&p| self.times[p]).collect();
        let mut fig = Figure::new("Local covariant exponents Λ_i(t)").x_label("t").y_label("Λ_i");
        for (s, name) in self.series.iter().zip(names) {
            let y: Vec<f64> = drawn.iter().map(|&p| s[p]).collect();
            fig.series(&format!("i = {name}"), &t, &y, Marker::Line);
        }
        fig.hline(0.0);
        save_figure(&fig, out, "local_exponents")?;
        Ok(Produced {
            title: "Local exponents (Sec. 6)".into(),
            caption: format!(
                "Local covariant exponents Λ_i(t_n) = ln |Dφ^τ v^i(t_n)| / τ for i = {} ({}) over {}.{caveat}",
                names.join(", "),
                self.roles(),
                if drawn.len() < order.len() { format!("the newest {} of the {frames} frames (the table holds all)", drawn.len()) } else { format!("all {frames} frames") }
            ),
            figures: vec!["local_exponents".into()],
            tables: vec!["local_exponents.csv".into()],
        })
    }

    /// Finite-time exponents: windows of Delta frames from the newest frame on, as in the
    /// domination test; the table for every Delta, the figure for one.
    fn finite_time_entry(&self, out: &Path, names: &[String], unfilled: &str, caveat: &str) -> Result<Produced> {
        let frames_n = self.steps.len();
        let mut rows = Vec::new();
        for (s, &i) in self.series.iter().zip(&self.idx) {
            for &delta in &self.deltas {
                let w = finite_time_exponents(s, delta);
                let [mean, std, min, max] = stats(&w);
                rows.push(vec![(i + 1) as f64, delta as f64, w.len() as f64, mean, std, min, max]);
            }
        }
        write_csv(&out.join("finite_time_exponents.csv"), &["i", "delta", "windows", "mean", "std", "min", "max"], rows)?;
        // The finite-time exponents of the largest Delta with at least 10 windows.
        let show = self.deltas.iter().copied().filter(|&dl| frames_n / dl >= 10).max().unwrap_or(self.deltas[0]);
        let mut fig = Figure::new(&format!("Finite-time exponents, Δ = {show} steps")).x_label("t").y_label("Λ_i averaged over Δ");
        let windows = frames_n / show;
        // Window w covers arrival positions w*Delta..(w+1)*Delta; its earliest time is the last.
        let mut starts: Vec<f64> = (0..windows).rev().map(|w| self.times[(w + 1) * show - 1]).collect();
        // A step curve ends at its last point: the newest window's end closes it, one window
        // length after its start, so that its value is drawn as the others are.
        let end = match starts.as_slice() {
            [.., before, last] => 2.0 * last - before,
            _ => self.times[0],
        };
        starts.push(end);
        for (s, name) in self.series.iter().zip(names) {
            let mut y = finite_time_exponents(s, show);
            y.reverse();
            y.extend(y.last().copied());
            fig.series(&format!("i = {name}"), &starts, &y, Marker::Steps);
        }
        fig.hline(0.0);
        save_figure(&fig, out, "finite_time_exponents")?;
        Ok(Produced {
            title: "Finite-time exponents (Sec. 6)".into(),
            caption: format!(
                "Local exponents averaged over consecutive windows of Δ = {show} steps (counted from the newest frame) for i = {}; the table gives mean, standard deviation (NaN from a single window), minimum and maximum over the windows for every Δ = {:?}.{unfilled}{caveat}",
                names.join(", "),
                self.deltas
            ),
            figures: vec!["finite_time_exponents".into()],
            tables: vec!["finite_time_exponents.csv".into()],
        })
    }

    /// The domination test: swap fractions of neighbouring exponents against Delta, and the
    /// splitting E^u ⊕ E^0 ⊕ E^s tested whole ([`splitting_verdict`]).
    fn domination_entry(&self, out: &Path, frames: u64, unfilled: &str, caveat: &str) -> Result<Produced> {
        let ctx = &self.ctx;
        let frames_n = self.steps.len();
        let overall = self.test.overall();
        let pairs: Vec<Vec<f64>> = (0..self.deltas.len()).map(|w| self.test.pair_fractions(w)).collect();
        let outside: Vec<f64> = pairs.iter().map(|p| finite_mean(p.iter().enumerate().filter(|(i, _)| !self.in_null(*i)).map(|(_, &x)| x))).collect();
        let sel: Vec<usize> = self.js.iter().copied().filter(|&j| j + 1 < ctx.k).collect();
        let borders = null_borders(ctx);
        let splits: Vec<Vec<f64>> = (0..self.deltas.len()).map(|w| self.test.split_fractions(w)).collect();
        let mut header = vec!["delta".to_string(), "windows".to_string(), "overall".to_string(), "outside_null".to_string()];
        header.extend(sel.iter().map(|j| format!("pair_{}_{}", j + 1, j + 2)));
        header.extend(borders.iter().map(|(name, _)| name.to_string()));
        header.extend(borders.iter().map(|(name, _)| name.replace("border", "split")));
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        write_csv(
            &out.join("domination.csv"),
            &h,
            self.deltas.iter().enumerate().map(|(w, &dl)| {
                let mut row = vec![dl as f64, self.test.windows(w) as f64, overall[w], outside[w]];
                row.extend(sel.iter().map(|&j| pairs[w][j]));
                row.extend(borders.iter().map(|&(_, i)| pairs[w][i]));
                row.extend(splits[w].iter().copied());
                row
            }),
        )?;
        let mut header = vec!["i".to_string()];
        header.extend(self.deltas.iter().map(|dl| format!("delta_{dl}")));
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        write_csv(
            &out.join("domination_pairs.csv"),
            &h,
            (0..ctx.k.saturating_sub(1)).map(|i| std::iter::once((i + 1) as f64).chain(pairs.iter().map(|p| p[i])).collect()),
        )?;
        let x: Vec<f64> = self.deltas.iter().map(|&dl| (dl as f64).log10()).collect();
        let mut fig = Figure::new("Domination test: fraction of windows with λ_(i+1) > λ_i").x_label("log10 Δ (steps)").y_label("swap fraction");
        fig.series("all adjacent pairs", &x, &overall, Marker::LinePoints);
        if ctx.is_disks() {
            fig.series("pairs outside the null space", &x, &outside, Marker::LinePoints);
        }
        for &j in &sel {
            let y: Vec<f64> = pairs.iter().map(|p| p[j]).collect();
            fig.series(&format!("pair ({}, {})", j + 1, j + 2), &x, &y, Marker::LinePoints);
        }
        let split_names = ["E^u below E^0 somewhere", "E^0 below E^s somewhere"];
        let border_curves: Vec<(String, Vec<f64>)> = (0..borders.len()).map(|c| (split_names[c].to_string(), splits.iter().map(|p| p[c]).collect())).collect();
        match border_curves.as_slice() {
            // one curve drawn over the other would hide it (both are zero once dominated)
            [(_, ya), (_, yb)] if ya == yb => {
                fig.series("E^u below E^0, or E^0 below E^s, somewhere", &x, ya, Marker::LinePoints);
            }
            curves => {
                for (label, y) in curves {
                    fig.series(label, &x, y, Marker::LinePoints);
                }
            }
        }
        fig.hline(0.0);
        save_figure(&fig, out, "domination")?;
        // The longest window length that fits in the frames (NaN rows measure nothing).
        let longest = (0..self.deltas.len()).rev().find(|&w| self.deltas[w] <= frames_n).unwrap_or(0);
        let borders_text = splitting_verdict(ctx, &self.deltas, &borders, &splits, frames_n);
        Ok(Produced {
            title: "Domination of the Oseledec splitting (Sec. 6)".into(),
            caption: format!(
                "Fraction of windows of Δ steps in which the finite-time exponent of index i+1 exceeds that of index i, against Δ: pooled over {}{}{}; from all {frames} frames. A dominated splitting needs this to vanish beyond a finite Δ_0{}. Overall fraction at Δ = {}: {:.3e}{}.{borders_text}{unfilled}{caveat}",
                if ctx.k == 2 { "the one adjacent pair".to_string() } else { format!("all {} adjacent pairs", ctx.k.saturating_sub(1)) },
                if ctx.is_disks() { ", averaged over the pairs outside the null space" } else { "" },
                if ctx.k > 2 { ", and for the pairs (j, j+1) of the selected indices" } else { "" },
                if ctx.is_disks() { " (degenerate exponents, as in the null space and the modes, swap for every Δ)" } else { "" },
                self.deltas[0],
                overall[0],
                if longest > 0 { format!("; at Δ = {}: {:.3e} (from {} windows; domination.csv gives every Δ's count)", self.deltas[longest], overall[longest], self.test.windows(longest)) } else { String::new() },
            ),
            figures: vec!["domination".into()],
            tables: vec!["domination.csv".into(), "domination_pairs.csv".into()],
        })
    }
}

/// Domination of E^u ⊕ E^0 ⊕ E^s in words: the smallest measured Delta from which neither
/// splitting (`splits`, per Delta, of the `borders`) is violated again.
fn splitting_verdict(ctx: &Context, deltas: &[usize], borders: &[(&'static str, usize)], splits: &[Vec<f64>], frames_n: usize) -> String {
    if borders.is_empty() {
        return String::new();
    }
    let at = |w: usize| splits[w].iter().map(|x| format!("{x:.3e}")).collect::<Vec<_>>().join(" and ");
    let quiet = |w: usize| splits[w].iter().all(|&x| x == 0.0);
    let (u, s) = (borders[0].1 + 1, borders[1].1 + 2);
    let names = format!(
        "the splitting E^u ⊕ E^0 ⊕ E^s (every finite-time exponent of E^u = 1..{u} above every one of E^0 = {}..{}, and every one of E^0 above every one of E^s = {s}..{}, tested whole, not only the border pairs ({u}, {}) and ({}, {s}))",
        u + 1,
        s - 1,
        ctx.k,
        u + 1,
        s - 1
    );
    // Only the window lengths that fit in the frames measure anything.
    let measured: Vec<usize> = (0..deltas.len()).filter(|&w| deltas[w] <= frames_n).collect();
    match measured.iter().position(|&from| measured.iter().filter(|&&w| w >= from).all(|&w| quiet(w))) {
        Some(0) => format!(" For {names}: never violated, not even in single steps; it is dominated in these frames."),
        Some(p) => format!(
            " For {names}: violated in {} of the windows at Δ = {} and in none from Δ = {} on; it is dominated in these frames, with Δ_0 <= {}.",
            at(measured[0]),
            deltas[measured[0]],
            deltas[measured[p]],
            deltas[measured[p]]
        ),
        None => match measured.last() {
            Some(&w) => format!(" For {names}: still violated at Δ = {}, in {} of the windows; no domination is seen in these frames.", deltas[w], at(w)),
            None => format!(" No window length Δ fits in the {frames_n} frames, so nothing is said about the splitting E^u ⊕ E^0 ⊕ E^s."),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::super::Options;
    use super::*;
    use super::super::testing::{self, column, out_dir as scratch, read_table as read_csv};

    fn context(n: usize, j: Vec<usize>, deltas: Vec<u64>) -> Context {
        let mut ctx = testing::context("disks", n, 4 * n, 5.0, 5.0, None, false);
        ctx.options = Options { every: 7, j, deltas };
        ctx
    }

    /// Deterministic noise in [-0.5, 0.5).
    fn noise(s: u64, i: usize) -> f64 {
        let mut z = s.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (i as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 31)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    fn frame(step: u64, local: Vec<f64>) -> Frame {
        let k = local.len();
        Frame { step, time: 0.6 * step as f64, d: k, k, phase: vec![0.0; k], v: vec![0.0; k * k], local, gs_local: Vec::new(), g: None }
    }

    /// The indices are settled at the first sampled frame (step 14 of every 7th, from 19
    /// down), yet the series start at the newest frame: the frames before it, which carry no
    /// vectors, are held until then.
    #[test]
    fn frames_before_the_first_sampled_one_keep_their_series() {
        let ctx = context(3, vec![5], vec![1]);
        let mut a = new(&ctx).unwrap();
        for step in (0..20u64).rev() {
            let mut f = frame(step, (0..12).map(|i| step as f64 + 0.01 * i as f64).collect());
            if step % 7 != 0 {
                f.v.clear();
            }
            a.consume(&f).unwrap();
        }
        let out = scratch("held");
        a.finish(&out, 20).unwrap();
        let t = read_csv(&out.join("local_exponents.csv"));
        assert_eq!(column(&t, "step"), (0..20).map(|s| s as f64).collect::<Vec<_>>());
        assert_eq!(column(&t, "lambda_5"), (0..20).map(|s| s as f64 + 0.01 * 4.0).collect::<Vec<_>>());
    }

    /// A long series is drawn by its newest MAX_DRAWN frames (the table keeps all), and the
    /// captions say which indices are drawn and why, with one pair in the singular.
    #[test]
    fn a_long_henon_series_is_drawn_by_its_newest_frames() {
        let mut ctx = testing::context("henon", 0, 2, 5.0, 5.0, None, false);
        ctx.options = Options { every: 1, j: vec![2], deltas: vec![1, 5] };
        ctx.gs = Some(crate::report::SpectrumSummary { exponents: vec![0.42, -1.62], stderr: vec![1e-3; 2], ks_entropy: None, blocks: None, warnings: Vec::new() });
        let mut a = new(&ctx).unwrap();
        let len = MAX_DRAWN as u64 + 500;
        for step in (0..len).rev() {
            a.consume(&frame(step, vec![0.42 + noise(step, 0), -1.62 + noise(step, 1)])).unwrap();
        }
        let out = scratch("long-henon");
        let produced = a.finish(&out, len).unwrap();
        let caption = &produced[0].caption;
        assert!(caption.contains(&format!("for i = 1, 2 (the largest and smallest positive exponent, i = 1; the selected index, j = 2) over the newest {MAX_DRAWN} of the {len} frames (the table holds all)")), "{caption}");
        assert_eq!(read_csv(&out.join("local_exponents.csv")).1.len(), len as usize);
        assert!(produced[2].caption.contains("pooled over the one adjacent pair"), "{}", produced[2].caption);
    }

    #[test]
    fn windows_longer_than_the_stream_are_said_to_be_empty() {
        let ctx = context(3, vec![1], vec![2, 50]);
        let mut a = new(&ctx).unwrap();
        for step in (0..20u64).rev() {
            a.consume(&frame(step, (0..12).map(|i| (12 - i) as f64 + noise(step, i)).collect())).unwrap();
        }
        let out = scratch("too-long");
        let produced = a.finish(&out, 20).unwrap();
        let said: Vec<bool> = produced.iter().map(|p| p.caption.contains("No window of Δ = [50] fits in the 20 frames")).collect();
        assert_eq!(said, [false, true, true], "local exponents, finite-time exponents, domination");
        let ft = read_csv(&out.join("finite_time_exponents.csv"));
        let row = ft.1.iter().find(|r| r[1] == 50.0).unwrap();
        assert!(row[2] == 0.0 && row[3].is_nan());
    }

    #[test]
    fn strictly_ordered_exponents_never_swap_and_null_pairs_do() {
        // N = 3, D = 12. Outside the null space (0-based 3..8) Lambda_i = (12 - i) + noise with
        // |noise| < 0.5: always ordered. Inside, equal means: they swap.
        let n = 3;
        let d = 12;
        let ctx = context(n, vec![1, 3], vec![1, 5, 25]);
        let mut a = new(&ctx).unwrap();
        assert!(!a.sampled());
        let len = 500u64;
        for step in (0..len).rev() {
            let local: Vec<f64> = (0..d)
                .map(|i| {
                    let base = if (3..9).contains(&i) { 0.0 } else { (d - i) as f64 - if i > 8 { 12.0 } else { 0.0 } };
                    base + 0.99 * noise(step, i)
                })
                .collect();
            a.consume(&frame(step, local)).unwrap();
        }
        let out = scratch("ordered");
        let produced = a.finish(&out, len).unwrap();
        let stems: Vec<&String> = produced.iter().flat_map(|p| &p.figures).collect();
        assert_eq!(stems, ["local_exponents", "finite_time_exponents", "domination"]);
        assert!(!produced.iter().any(|p| p.caption.contains("Warning")));
        let dom = read_csv(&out.join("domination.csv"));
        assert_eq!(column(&dom, "delta"), [1.0, 5.0, 25.0]);
        assert!(column(&dom, "outside_null").iter().all(|&x| x == 0.0), "{:?}", dom.1);
        assert!(column(&dom, "pair_1_2").iter().all(|&x| x == 0.0));
        // pair (3, 4): lambda_3 = 10 +- 0.5 against the null space: never swaps
        assert!(column(&dom, "pair_3_4").iter().all(|&x| x == 0.0));
        // the borders of the null space (2N-3, 2N-2) = (3, 4) and (2N+3, 2N+4) = (9, 10)
        assert_eq!(column(&dom, "border_unstable_null"), column(&dom, "pair_3_4"));
        assert!(column(&dom, "border_null_stable").iter().all(|&x| x == 0.0));
        let caption = &produced[2].caption;
        assert!(caption.contains("E^u = 1..3 above every one of E^0 = 4..9, and every one of E^0 above every one of E^s = 10..12, tested whole, not only the border pairs (3, 4) and (9, 10)): never violated") && caption.contains("it is dominated"), "{caption}");
        assert_eq!(column(&dom, "split_unstable_null"), column(&dom, "border_unstable_null"), "lambda_3 is E^u's smallest");
        assert!(column(&dom, "split_null_stable").iter().all(|&x| x == 0.0));
        // five null pairs of 11 swap about half the time at Delta = 1
        let overall = column(&dom, "overall");
        assert!((overall[0] - 0.5 * 5.0 / 11.0).abs() < 0.05, "{overall:?}");
        let pairs = read_csv(&out.join("domination_pairs.csv"));
        let d1 = column(&pairs, "delta_1");
        for (i, &x) in d1.iter().enumerate() {
            if (3..8).contains(&i) {
                assert!(x > 0.3 && x < 0.7, "null pair {} swaps {x}", i + 1);
            } else {
                assert_eq!(x, 0.0, "pair {}", i + 1);
            }
        }
        // time series sorted by step; indices 1, 3 and 2N-3 = 3 (deduplicated)
        let ts = read_csv(&out.join("local_exponents.csv"));
        assert_eq!(ts.0, ["step", "time", "lambda_1", "lambda_3"]);
        let steps = column(&ts, "step");
        assert!(steps.windows(2).all(|w| w[1] == w[0] + 1.0) && steps[0] == 0.0);
        let l1 = column(&ts, "lambda_1");
        assert!((l1[7] - (12.0 + 0.99 * noise(7, 0))).abs() < 1e-15);
        // finite-time exponents: 500 / 25 = 20 windows, mean over all of lambda_1
        let ft = read_csv(&out.join("finite_time_exponents.csv"));
        let row = ft.1.iter().find(|r| r[0] == 1.0 && r[1] == 25.0).unwrap();
        assert_eq!(row[2], 20.0);
        let mean1 = l1.iter().sum::<f64>() / len as f64;
        assert!((row[3] - mean1).abs() < 1e-12);
        assert!(row[5] > 11.5 && row[6] < 12.5);
    }

    /// Lorenz's flow-direction exponent is zero whatever the sign of its estimate: the
    /// smallest positive exponent is lambda_1.
    #[test]
    fn the_smallest_positive_exponent_is_not_a_neutral_one() {
        let mut gs = testing::spectrum(4, 2);
        gs.exponents = vec![0.9, 5.5e-3, -14.5];
        gs.stderr = vec![1e-3; 3];
        let ctx = testing::context("lorenz", 0, 3, 0.0, 0.0, Some(gs), false);
        assert_eq!(smallest_positive(&ctx), Some(0));
    }

    /// A smallest positive exponent that fluctuates through zero swaps with the null space
    /// in short windows and not in long ones: the caption gives the Delta_0 it finds; one that
    /// sits at zero swaps at every Delta: no domination.
    #[test]
    fn the_borders_of_the_null_space_are_tested_for_domination() {
        let (n, d) = (3, 12);
        for (lambda_3, said) in [(0.3, "in none from Δ = 25 on"), (0.0, "still violated at Δ = 25")] {
            let mut a = new(&context(n, vec![1], vec![1, 5, 25])).unwrap();
            for step in (0..500u64).rev() {
                let local: Vec<f64> = (0..d)
                    .map(|i| match i {
                        2 => lambda_3 + 2.0 * noise(step, i),
                        3..=8 => 0.0,
                        _ => (d - i) as f64 - if i > 8 { 12.0 } else { 0.0 } + 0.99 * noise(step, i),
                    })
                    .collect();
                a.consume(&frame(step, local)).unwrap();
            }
            let out = scratch(&format!("borders-{lambda_3}"));
            let produced = a.finish(&out, 500).unwrap();
            let border = column(&read_csv(&out.join("domination.csv")), "border_unstable_null");
            assert!(border[0] > 0.2, "{border:?}");
            assert!(produced[2].caption.contains(said), "{}", produced[2].caption);
        }
    }

    #[test]
    fn a_swapping_pair_is_counted_and_gaps_are_reported() {
        // Two exponents alternating in order every step: at Delta = 1 they swap in half the
        // windows, at Delta = 2 the sums tie and never swap.
        let ctx = Context { system: "henon".into(), n: 0, ..context(1, vec![1], vec![1, 2]) };
        let ctx = Context { d: 2, k: 2, ..ctx };
        let mut a = new(&ctx).unwrap();
        for step in [9u64, 8, 7, 6, 4, 3, 2, 1] {
            let x = if step % 2 == 0 { 1.0 } else { -1.0 };
            a.consume(&frame(step, vec![x, -x])).unwrap();
        }
        let out = scratch("swap");
        let produced = a.finish(&out, 8).unwrap();
        assert!(produced.iter().all(|p| p.caption.contains("Warning: the steps of 1 frames")), "a gap between 6 and 4");
        let dom = read_csv(&out.join("domination.csv"));
        assert_eq!(column(&dom, "overall"), [0.5, 0.0]);
        assert_eq!(column(&dom, "pair_1_2"), [0.5, 0.0]);
    }
}
