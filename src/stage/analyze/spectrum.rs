//! The Lyapunov spectrum (paper Figs. 2 and 8): the forward GS spectrum against the backward
//! CLV spectrum (time average of the local exponents of the frames), against i/4N, and the
//! mode region with each positive exponent beside its conjugate partner.

use super::{save_figure, write_csv, Analysis, Context, Produced, CLV_COLOR, GS_COLOR};
use crate::config::SystemConfig;
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::statistics::{ks_entropy, Accumulator, Estimate};
use crate::stage::frame::Frame;
use std::path::Path;

pub struct Spectrum {
    ctx: Context,
    acc: Accumulator,
    /// The frames' local GS exponents: the GS spectrum over the same steps as the CLV one.
    acc_gs: Accumulator,
    /// Frames without local GS exponents (written before frames carried them).
    without_gs: u64,
    /// Oldest and newest step consumed.
    steps: Option<(u64, u64)>,
    /// Sum over the frames of the local exponent the shear model gives the three trailing
    /// null-space CLVs ([`frame_null_shear`]): lambda_clv_null_shear is its mean, as
    /// lambda_clv is the mean of the frames' local exponents.
    shear_sum: f64,
}

/// The CLV exponent a finite window gives the three trailing null-space vectors: backward
/// iteration from t_omega turns e_(k+3) into e_(k+3) - s e_k after the backward time s (the
/// exact identity D phi^t e_(k+3) = t e_k + e_(k+3) of a free flight in the null space), a growth of sqrt(1 + s^2)
/// and not exponential; the time average over s1..s2 is
/// -ln((1 + s2^2) / (1 + s1^2)) / (2 (s2 - s1)), which vanishes only like ln t / t.
pub fn null_shear_exponent(s1: f64, s2: f64) -> f64 {
    -((1.0 + s2 * s2).ln() - (1.0 + s1 * s1).ln()) / (2.0 * (s2 - s1))
}

/// The shear model's local exponent of the frame of `step`, over [t_step, t_(step+1)], at
/// the backward times (total - step - 1) tau .. (total - step) tau from the run's end
/// (step `total`, where the backward pass starts). The mean over consecutive frames is
/// [`null_shear_exponent`] over their whole span; over the frames of a file of every m-th
/// step it is not.
fn frame_null_shear(step: u64, total: u64, tau: f64) -> f64 {
    let s = (total as f64 - step as f64) * tau;
    null_shear_exponent(s - tau, s)
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    (missing == super::Missing::AllVectors && ctx.is_disks()).then_some("Fig. 8, the mode region with its conjugate pairs")
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    let acc = Accumulator::new(ctx.k, ctx.block_len(false));
    Some(Box::new(Spectrum { ctx: ctx.clone(), acc_gs: acc.clone(), acc, without_gs: 0, steps: None, shear_sum: 0.0 }))
}

impl Analysis for Spectrum {
    fn name(&self) -> &'static str {
        "spectrum"
    }
    fn sampled(&self) -> bool {
        false
    }
    fn consume(&mut self, frame: &Frame) -> Result<()> {
        self.acc.add_logs(frame.local.iter().copied());
        if frame.gs_local.is_empty() {
            self.without_gs += 1;
        } else {
            self.acc_gs.add_logs(frame.gs_local.iter().copied());
        }
        self.steps = Some(self.steps.map_or((frame.step, frame.step), |(a, b)| (a.min(frame.step), b.max(frame.step))));
        let config = &self.ctx.run.config;
        self.shear_sum += frame_null_shear(frame.step, config.relax_steps + config.steps, self.ctx.tau);
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let ctx = &self.ctx;
        let (clv, clv_err) = (self.acc.exponents(1.0), self.acc.stderr(1.0));
        let nan = vec![f64::NAN; ctx.k];
        let (run_gs, run_gs_err) = ctx.gs.as_ref().map_or((nan.clone(), nan.clone()), |g| (g.exponents.clone(), g.stderr.clone()));
        // Like for like when every frame carried its GS exponents; the whole run's otherwise.
        let same_steps = self.without_gs == 0 && frames > 0;
        let (window_gs, window_gs_err) = if same_steps { (self.acc_gs.exponents(1.0), self.acc_gs.stderr(1.0)) } else { (nan.clone(), nan) };
        let (gs, gs_err) = if same_steps { (&window_gs, &window_gs_err) } else { (&run_gs, &run_gs_err) };
        let x: Vec<f64> = (0..ctx.k).map(|i| ctx.reduced(i)).collect();
        let neutral = ctx.run.config.system.neutral();
        // The finite window's exponent of the three trailing null-space CLVs (see the caption).
        let trailing = ctx.null_shear();
        let shear = match (&trailing, self.steps) {
            (Some(_), Some((first, last))) => {
                // Frame m carries the exponent over [t_m, t_(m+1)], at backward times
                // (total - m - 1) tau .. (total - m) tau from the run's end: the frames span
                // s1..s2, every step of it where they are consecutive.
                let total = ctx.run.config.relax_steps + ctx.run.config.steps;
                let s = |m: u64| (total as f64 - m as f64) * ctx.tau;
                Some((s(last) - ctx.tau, s(first), self.shear_sum / frames as f64, frames == last - first + 1))
            }
            _ => None,
        };
        let predicted = |i: usize| match shear {
            Some((_, _, mean, _)) if trailing.as_ref().is_some_and(|t| t.contains(&i)) => mean,
            _ => f64::NAN,
        };
        write_csv(
            &out.join("spectrum.csv"),
            &["i", "i_over_D", "lambda_gs", "stderr_gs", "lambda_gs_window", "stderr_gs_window", "lambda_clv", "stderr_clv", "zero_by_symmetry", "lambda_clv_null_shear"],
            (0..ctx.k).map(|i| vec![(i + 1) as f64, x[i], run_gs[i], run_gs_err[i], window_gs[i], window_gs_err[i], clv[i], clv_err[i], f64::from(u8::from(neutral.contains(&i))), predicted(i)]),
        )?;
        let reduced = if ctx.is_disks() { "i/4N" } else { "i/D" };
        // A line between a handful of exponents (the Henon map's two) would look like data.
        let marker = if ctx.k <= 8 { Marker::Points } else { Marker::Line };
        let mut fig = Figure::new("Lyapunov spectrum: GS forward, CLV backward").x_label(reduced).y_label("λ_i");
        // As points, the symbols of Fig. 8: open for GS, filled for CLV, both seen where they agree.
        fig.series(if same_steps { "GS (forward), same steps" } else { "GS (forward), whole run" }, &x, gs, marker).color(GS_COLOR).open_markers(true);
        fig.series("CLV (backward)", &x, &clv, marker).color(CLV_COLOR).open_markers(false);
        fig.hline(0.0);
        save_figure(&fig, out, "fig2_spectrum")?;
        // The spectrum.json of builds before h_KS was reported has the exponents but no error.
        let run_h = ctx.gs.as_ref().and_then(|g| g.ks_entropy.or_else(|| ks_entropy(&g.exponents, neutral.clone()).map(|value| Estimate { value, stderr: f64::NAN })));
        let clv_h = Estimate::or_unknown(self.acc.ks_entropy(1.0, neutral.clone()));
        let caption = if same_steps {
            format!(
                "Forward Gram-Schmidt exponents (time average of ln R_ii) and backward covariant exponents (time average of the local CLV exponents), both over the same {frames} frames' steps, against the reduced index {reduced}: \
                 {}. Kolmogorov-Sinai entropy h_KS, the sum of the positive exponents (Pesin's identity): {} (GS), {clv_h} (CLV). \
                 The GS spectrum over the whole forward run ({} steps) is more precise (columns lambda_gs, stderr_gs of spectrum.csv; the figure's GS spectrum is lambda_gs_window): h_KS = {}.",
                if clv_err.iter().all(|e| e.is_nan()) {
                    "too few frames for standard errors (NaN in the table), so whether they agree within them is not tested"
                } else {
                    "they agree within the errors wherever the spectrum is not degenerate"
                },
                Estimate::or_unknown(self.acc_gs.ks_entropy(1.0, neutral)),
                ctx.run.config.steps,
                Estimate::or_unknown(run_h),
            )
        } else {
            format!(
                "Forward Gram-Schmidt exponents (time average of ln R_ii) and backward covariant exponents (time average of the local CLV exponents over {frames} frames) against the reduced index {reduced}. \
                 Kolmogorov-Sinai entropy h_KS, the sum of the positive exponents (Pesin's identity): {} (GS), {clv_h} (CLV).",
                Estimate::or_unknown(run_h),
            ) + &format!(
                " The GS averages are over the whole run ({} steps), the CLV averages over the frames' steps only: they differ by that window's own fluctuation, which the CLV errors measure. \
                 These frames were written before they carried their GS exponents; the backward stage gives the GS spectrum over the frames' steps (`gs_window` in RUN_DIR/clv_spectrum.json), the comparison like for like.",
                ctx.run.config.steps
            )
        };
        // Agreement of two spectra both off by the same lost digits (or the same unsettled
        // null space) proves nothing: the warnings come first.
        let warned: Vec<String> = ctx.gs.iter().flat_map(|g| &g.warnings).map(|w| format!("The forward stage warned that {w}. ")).collect();
        let caption = warned.concat() + &caption;
        let mut produced = vec![Produced {
            title: "Lyapunov spectrum (Fig. 2)".into(),
            caption,
            figures: vec!["fig2_spectrum".into()],
            tables: vec!["spectrum.csv".into()],
        }];
        if let Some((s1, s2, mean, consecutive)) = shear {
            let measured: Vec<String> = trailing.clone().unwrap_or_default().map(|i| format!("{:.4e}", clv[i])).collect();
            let average = if consecutive {
                format!("over s = {s1:.1}..{s2:.1} they average -ln((1 + s2²)/(1 + s1²)) / (2 (s2 - s1)) = {mean:.4e}")
            } else {
                format!("over the {frames} frames' steps, within s = {s1:.1}..{s2:.1}, the mean of each step's -ln((1 + s²)/(1 + (s - τ)²)) / (2τ) is {mean:.4e}")
            };
            produced[0].caption += &format!(
                " The last three null-space CLV exponents (i = 2N+1..2N+3) are not zero in a finite window: backward iteration turns e_(k+3) into e_(k+3) - s e_k, \
                 a growth like the backward time s, not exponential, so {average}; measured {}.",
                measured.join(", ")
            );
            produced[0].caption += " In spectrum.csv, zero_by_symmetry marks the null space, where the CLV errors measure this drift, not noise, and lambda_clv_null_shear gives the predicted values.";
        }
        if marker == Marker::Points {
            produced[0].caption += " Drawn as points, GS open and CLV filled: a line between so few exponents would look like data.";
        }
        if ctx.k == ctx.d {
            produced[0].caption += &exact_sum(&ctx.run.config.system, ctx.tau, &run_gs, &run_gs_err);
        }
        if ctx.is_disks() && ctx.k == ctx.d {
            // The mode region: positive exponents next to the null space, with the negated
            // conjugate exponents at the same index (conjugate pairing: lambda_i = -lambda_{4N+1-i}).
            let last = 2 * ctx.n - 4; // 0-based index of lambda_{2N-3}, the smallest positive
            let first = ctx.central_range().map_or(0, |(first, _)| first);
            let idx: Vec<f64> = (first..=last).map(|i| (i + 1) as f64).collect();
            let pick = |v: &[f64], conj: bool| -> Vec<f64> { (first..=last).map(|i| if conj { -v[ctx.d - 1 - i] } else { v[i] }).collect() };
            let plotted = |err: &[f64]| plotted_errors(err, first..=last);
            // The paper's symbols: open for GS, filled for CLV; the lines join the λ_i.
            let mut fig = Figure::new("Mode region: λ_i and -λ_(4N+1-i)").x_label("i").y_label("λ");
            fig.series("CLV λ_i", &idx, &pick(&clv, false), Marker::LinePoints).color(CLV_COLOR).open_markers(false);
            fig.series("CLV -λ_(4N+1-i)", &idx, &pick(&clv, true), Marker::Points).color(CLV_COLOR).open_markers(false);
            fig.series("GS λ_i", &idx, &pick(gs, false), Marker::LinePoints).color(GS_COLOR).open_markers(true);
            fig.series("GS -λ_(4N+1-i)", &idx, &pick(gs, true), Marker::Points).color(GS_COLOR).open_markers(true);
            save_figure(&fig, out, "fig8_mode_region")?;
            produced.push(Produced {
                title: "Mode region of the spectrum (Fig. 8)".into(),
                caption: format!(
                    "The positive exponents λ_{}..λ_{} next to the null space, with the negated conjugate exponents at the same index (paper Fig. 8): as there, open symbols for the GS exponents, filled ones for the CLV exponents (in the report's GS and CLV colours, blue and vermillion), lines joining the λ_i, the conjugates -λ_(4N+1-i) unjoined; the GS exponents are those of {}. Steps of equal or nearly equal exponents are where Lyapunov modes may sit (in a small system the four exponents of an LP mode can differ by many standard errors); the mode table says which steps were found, what they are and how far each one's exponents spread. {}",
                    first + 1,
                    last + 1,
                    if same_steps { "the frames' steps, as the CLV ones" } else { "the whole run" },
                    typical_error(&plotted(gs_err), &plotted(&clv_err))
                ),
                figures: vec!["fig8_mode_region".into()],
                tables: vec![],
            });
        }
        Ok(produced)
    }
}

/// The sum of the whole run's GS exponents against the value the dynamics fixes exactly
/// (the time average of ln |det J| per unit time): 0 for hard disks (symplectic: phase-space
/// volume is kept), ln |b| per iteration for the Henon map, -(sigma + 1 + beta) for the Lorenz
/// flow (its constant divergence); for the Henon map also lambda_1 against the literature.
fn exact_sum(system: &SystemConfig, tau: f64, lambda: &[f64], err: &[f64]) -> String {
    let (exact, why) = match *system {
        SystemConfig::Disks { .. } => (0.0, "phase-space volume is kept".to_string()),
        SystemConfig::Henon { b, .. } => (b.abs().ln() / tau, format!("ln |b| = ln {}, det J = -b", b.abs())),
        SystemConfig::Lorenz { sigma, beta, .. } => (-(sigma + 1.0 + beta), format!("-(σ + 1 + β), the flow's divergence, with σ = {sigma}, β = {beta:.6}; the integrator's steps keep it up to their error")),
    };
    let sum: f64 = lambda.iter().sum();
    if !sum.is_finite() {
        return String::new();
    }
    let mut s = if exact == 0.0 {
        format!(" Sum of the whole run's GS exponents: {sum:.2e}, exactly 0 ({why}).")
    } else {
        format!(" Sum of the whole run's GS exponents: {sum:.9}, exactly {exact:.9} ({why}).")
    };
    // J. C. Sprott, Chaos and Time-Series Analysis (Oxford, 2003), Appendix A: the Henon map
    // at a = 1.4, b = 0.3 (in the form x' = 1 - a x^2 + y, y' = b x, conjugate to ours by
    // a scaling, which keeps the exponents).
    match *system {
        SystemConfig::Henon { a, b } if a == 1.4 && b == 0.3 && tau == 1.0 && err[0] > 0.0 => {
            s += &format!(" λ_1 = {:.6} ± {:.1e} against 0.41922 in the literature (Sprott, Chaos and Time-Series Analysis, 2003), {:.1} standard errors apart.", lambda[0], err[0], (lambda[0] - 0.41922).abs() / err[0]);
        }
        SystemConfig::Henon { a, b } if a == 1.4 && b == 0.3 && tau == 1.0 => {
            s += &format!(" λ_1 = {:.6}, without a standard error from so short a run, against 0.41922 in the literature (Sprott, Chaos and Time-Series Analysis, 2003).", lambda[0]);
        }
        _ => {}
    }
    s
}

/// The errors of the exponents Fig. 8 plots: λ_i for i in `shown` (0-based) and their
/// conjugates λ_(D+1-i).
fn plotted_errors(err: &[f64], shown: std::ops::RangeInclusive<usize>) -> Vec<f64> {
    let d = err.len();
    shown.flat_map(|i| [err[i], err[d - 1 - i]]).collect()
}

/// The median standard errors of the plotted exponents, in words: the figure has no error
/// bars, and whether two neighbours differ is a question of them.
fn typical_error(gs: &[f64], clv: &[f64]) -> String {
    let median = |v: &[f64]| Some(crate::statistics::median(v)).filter(|m| m.is_finite());
    match (median(gs), median(clv)) {
        (Some(g), Some(c)) => format!("Median standard errors of the plotted exponents: {g:.1e} (GS), {c:.1e} (CLV); all errors are in spectrum.csv."),
        (None, Some(c)) => format!("Median standard error of the plotted CLV exponents: {c:.1e}; all errors are in spectrum.csv."),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fig. 8's quoted error is the median over the plotted exponents, the negated
    /// conjugates' included (it was over the positive ones only).
    #[test]
    fn the_mode_regions_error_covers_the_conjugates_too() {
        // D = 8, showing i = 1..2 (0-based 1..=2) and their conjugates 6, 5.
        let err = [9.0, 1.0, 2.0, 9.0, 9.0, 4.0, 3.0, 9.0];
        assert_eq!(plotted_errors(&err, 1..=2), [1.0, 3.0, 2.0, 4.0]);
        assert!(typical_error(&plotted_errors(&err, 1..=2), &[1.0]).contains("2.5e0 (GS)"));
    }
    use crate::stage::analyze::testing::{context, frame, out_dir, spectrum};

    #[test]
    fn exact_sums_of_the_spectrum() {
        let henon = exact_sum(&SystemConfig::henon(), 1.0, &[0.4185, 0.3f64.ln() - 0.4185], &[3.7e-4, 3.7e-4]);
        assert!(henon.contains(&format!("exactly {:.9} (ln |b| = ln 0.3", 0.3f64.ln())) && henon.contains("1.9 standard errors apart"), "{henon}");
        let disks = exact_sum(&SystemConfig::disks_in_box(4, 5.0, 5.0), 0.6, &[1.0, 0.0, -1.0 + 3e-12], &[0.0; 3]);
        assert!(disks.contains("Sum of the whole run's GS exponents: 3.00e-12, exactly 0 (phase-space volume is kept)."), "{disks}");
        let lorenz = exact_sum(&SystemConfig::lorenz(), 0.01, &[0.9, 0.0, -14.57], &[0.0; 3]);
        assert!(lorenz.contains(&format!("exactly {:.9}", -(10.0 + 1.0 + 8.0 / 3.0))), "{lorenz}");
        assert_eq!(exact_sum(&SystemConfig::henon(), 1.0, &[f64::NAN, 0.0], &[0.0; 2]), "", "no GS spectrum");
        let one_block = exact_sum(&SystemConfig::henon(), 1.0, &[1.27, 0.3f64.ln() - 1.27], &[f64::NAN; 2]);
        assert!(one_block.contains("without a standard error") && !one_block.contains("NaN"), "{one_block}");
    }

    /// h_KS of both spectra in the caption: the CLV one from the frames' local exponents with
    /// its block error; the GS one from a spectrum.json of a build before h_KS was recorded,
    /// summed from its exponents, without an error.
    #[test]
    fn caption_gives_h_ks_of_both_spectra() {
        let n = 4;
        let d = 4 * n;
        let gs = spectrum(n, 2);
        let want_gs: f64 = gs.exponents.iter().filter(|&&l| l > 0.0).sum();
        let ctx = context("disks", n, d, 4.0, 4.0, Some(gs), false);
        let neutral = ctx.run.config.system.neutral();
        let mut a = new(&ctx).unwrap();
        let mut want_clv = 0.0;
        let frames = 200; // four blocks of the context's 50 frames
        for step in 0..frames {
            let mut f = frame(step, vec![0.0; d], vec![0.0; d * d], None);
            f.local = (0..d).map(|i| (d / 2) as f64 - i as f64 - 0.5 + if step / 50 % 2 == 0 { 0.25 } else { -0.25 }).collect();
            want_clv += f.local.iter().enumerate().filter(|&(i, &l)| l > 0.0 && !neutral.contains(&i)).map(|(_, l)| l).sum::<f64>() / frames as f64;
            a.consume(&f).unwrap();
        }
        let produced = a.finish(&out_dir("spectrum-h"), frames).unwrap();
        let caption = &produced[0].caption;
        assert!(caption.contains(&format!("identity): {want_gs:.6} (GS), {want_clv:.6} ± ")), "{caption}");
    }

    /// With only the leading k >= 2N+3 vectors the last three null-space CLV exponents are
    /// there, and spectrum.csv gives their predicted shear exponent too.
    #[test]
    fn the_null_shear_is_given_for_leading_vectors_that_reach_it() {
        use crate::store::run::{BuildInfo, RunMeta, StoreConfig, FORMAT};
        let n = 4;
        let d = 4 * n;
        let mut config = crate::config::RunConfig::preset("default").unwrap();
        config.system = crate::config::SystemConfig::disks(n, 0.7, 1.0).unwrap();
        config.vectors = 2 * n + 3;
        let mut ctx = context("disks", n, d, 4.0, 4.0, None, false);
        ctx.k = config.vectors;
        ctx.run = RunMeta { format: FORMAT.into(), store: StoreConfig::for_run(&config), config: config.clone(), build: BuildInfo::current() };
        let mut a = new(&ctx).unwrap();
        let total = config.relax_steps + config.steps;
        for step in [total - 20, total - 10] {
            let mut f = frame(step, vec![0.0; d], vec![0.0; d * ctx.k], None);
            f.k = ctx.k;
            f.local = vec![0.0; ctx.k];
            a.consume(&f).unwrap();
        }
        let out = out_dir("spectrum-null-shear-k");
        a.finish(&out, 2).unwrap();
        let rows = crate::stage::analyze::testing::read_csv(&out.join("spectrum.csv"));
        assert_eq!(rows.len(), ctx.k);
        // the mean of the two frames' steps, at backward times 19..20 tau and 9..10 tau
        let tau = ctx.tau;
        // The closed form -ln((1 + s2^2) / (1 + s1^2)) / (2 (s2 - s1)), written out here so
        // that a wrong formula in the function cannot pass (a mutation check).
        let shear = |s1: f64, s2: f64| -((1.0 + s2 * s2) / (1.0 + s1 * s1)).ln() / (2.0 * (s2 - s1));
        assert!((null_shear_exponent(0.0, tau) + (1.0 + tau * tau).ln() / (2.0 * tau)).abs() < 1e-15);
        let want = (shear(19.0 * tau, 20.0 * tau) + shear(9.0 * tau, 10.0 * tau)) / 2.0;
        for (i, row) in rows.iter().enumerate() {
            let shear: f64 = row["lambda_clv_null_shear"].parse().unwrap();
            if i >= 2 * n {
                assert!((shear - want).abs() < 1e-15, "lambda_{}: {shear}", i + 1);
            } else {
                assert!(shear.is_nan(), "lambda_{}: {shear}", i + 1);
            }
        }
    }

    /// A frame file of every third step (`clv backward --save-every 3`): lambda_clv averages
    /// the local exponents of the frames it holds, each over one step, so the prediction is
    /// the mean of the model's exponent over those frames, which the frames' own exponents
    /// (the model's here) give; the time average over the whole span of steps is another
    /// number (by 1e-3 relative in the pipeline test's run).
    #[test]
    fn the_null_shear_of_a_file_of_every_third_step_is_the_mean_over_its_frames() {
        let n = 4;
        let d = 4 * n;
        let ctx = context("disks", n, d, 4.0, 4.0, None, false);
        let total = ctx.run.config.relax_steps + ctx.run.config.steps;
        let trailing = ctx.null_shear().unwrap();
        let tau = ctx.tau;
        let mut a = new(&ctx).unwrap();
        let steps: Vec<u64> = (0..40).map(|j| total - 60 - 3 * j).collect(); // newest first
        let mut want = 0.0;
        for &step in &steps {
            let mut f = frame(step, vec![0.0; d], vec![0.0; d * d], None);
            let model = null_shear_exponent((total - step - 1) as f64 * tau, (total - step) as f64 * tau);
            for i in trailing.clone() {
                f.local[i] = model;
            }
            want += model / steps.len() as f64;
            a.consume(&f).unwrap();
        }
        let out = out_dir("spectrum-null-shear-every-third");
        a.finish(&out, steps.len() as u64).unwrap();
        let rows = crate::stage::analyze::testing::read_csv(&out.join("spectrum.csv"));
        let span = null_shear_exponent((total - steps[0] - 1) as f64 * tau, (total - steps[39]) as f64 * tau);
        assert!((span - want).abs() > 1e-6 * want.abs(), "the span's average {span} is not the frames' {want}");
        for i in trailing {
            let (shear, clv): (f64, f64) = (rows[i]["lambda_clv_null_shear"].parse().unwrap(), rows[i]["lambda_clv"].parse().unwrap());
            assert!((shear - want).abs() < 1e-15 && (shear - clv).abs() < 1e-15, "lambda_{}: predicted {shear}, measured {clv}, mean over the frames {want}", i + 1);
        }
    }

    /// Frames that carry their local GS exponents give the GS spectrum over the same steps as
    /// the CLV one: it is what Fig. 2 shows, in its own columns of spectrum.csv beside the
    /// whole run's; one frame without them (an older file) falls back to the whole run's.
    #[test]
    fn the_figure_compares_gs_and_clv_over_the_same_steps() {
        let n = 4;
        let d = 4 * n;
        let ctx = context("disks", n, d, 4.0, 4.0, Some(spectrum(n, 2)), false);
        let gs_local = |step: u64, i: usize| (d / 2) as f64 - i as f64 - 0.5 + if step.is_multiple_of(3) { 0.3 } else { -0.15 };
        for missing in [false, true] {
            let mut a = new(&ctx).unwrap();
            let mut want = vec![0.0; d];
            for step in 0..60u64 {
                let mut f = frame(step, vec![0.0; d], vec![0.0; d * d], None);
                f.local = vec![1.0; d];
                if !(missing && step == 17) {
                    f.gs_local = (0..d).map(|i| gs_local(step, i)).collect();
                }
                for (w, g) in want.iter_mut().zip(&f.gs_local) {
                    *w += g / 60.0;
                }
                a.consume(&f).unwrap();
            }
            let out = out_dir(&format!("spectrum-window-{missing}"));
            let produced = a.finish(&out, 60).unwrap();
            let rows = crate::stage::analyze::testing::read_csv(&out.join("spectrum.csv"));
            for (i, row) in rows.iter().enumerate() {
                let window: f64 = row["lambda_gs_window"].parse().unwrap();
                if missing {
                    assert!(window.is_nan(), "{row:?}");
                } else {
                    assert!((window - want[i]).abs() < 1e-12, "lambda_{}: {window} against {}", i + 1, want[i]);
                }
                assert_eq!(row["lambda_gs"], crate::stage::analyze::csv_number(spectrum(n, 2).exponents[i]));
            }
            assert_eq!(produced[0].caption.contains("both over the same 60 frames' steps"), !missing, "{}", produced[0].caption);
            // Fig. 8 in the paper's symbols: open for GS (blue), filled for CLV (vermillion).
            let svg = std::fs::read_to_string(out.join("fig8_mode_region.svg")).unwrap();
            let groups: Vec<&str> = svg.lines().filter(|l| l.starts_with("<g ")).collect();
            let (gs, clv): (Vec<&str>, Vec<&str>) = (groups.iter().filter(|g| g.contains("#0072b2")).copied().collect(), groups.iter().filter(|g| g.contains("#d55e00")).copied().collect());
            assert!(gs.len() == 4 && gs.iter().all(|g| g.starts_with("<g fill=\"none\" stroke=\"#0072b2\"")), "{gs:?}");
            assert!(clv.len() == 4 && clv.iter().all(|g| g.starts_with("<g fill=\"#d55e00\"")), "{clv:?}");
        }
    }
}
