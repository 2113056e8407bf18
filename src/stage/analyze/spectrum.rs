//! The Lyapunov spectrum (paper Figs. 2 and 8): the forward GS spectrum against the backward
//! CLV spectrum (time average of the local exponents of the frames), against i/4N, and the
//! mode region with each positive exponent beside its conjugate partner.

use super::{save_figure, write_csv, Analysis, Context, Produced};
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::stage::forward::{ks_entropy, Accumulator, Estimate};
use crate::stage::frame::Frame;
use std::path::Path;

pub struct Spectrum {
    ctx: Context,
    acc: Accumulator,
    /// Oldest and newest step consumed.
    steps: Option<(u64, u64)>,
}

/// The CLV exponent a finite window gives the three trailing null-space vectors: backward
/// iteration from t_omega turns e_(k+3) into e_(k+3) - s e_k after the backward time s (the
/// exact identity D phi^t e_(k+3) = t e_k + e_(k+3), PHYSICS.md), a growth of sqrt(1 + s^2)
/// and not exponential; the time average over s1..s2 is
/// -ln((1 + s2^2) / (1 + s1^2)) / (2 (s2 - s1)), which vanishes only like ln t / t.
pub fn null_shear_exponent(s1: f64, s2: f64) -> f64 {
    -((1.0 + s2 * s2).ln() - (1.0 + s1 * s1).ln()) / (2.0 * (s2 - s1))
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    Some(Box::new(Spectrum { ctx: ctx.clone(), acc: Accumulator::new(ctx.k, ctx.block_len(false)), steps: None }))
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
        self.steps = Some(self.steps.map_or((frame.step, frame.step), |(a, b)| (a.min(frame.step), b.max(frame.step))));
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let ctx = &self.ctx;
        let (clv, clv_err) = (self.acc.exponents(1.0), self.acc.stderr(1.0));
        let nan = vec![f64::NAN; ctx.k];
        let (gs, gs_err) = ctx.gs.as_ref().map_or((nan.clone(), nan), |g| (g.exponents.clone(), g.stderr.clone()));
        let x: Vec<f64> = (0..ctx.k).map(|i| ctx.reduced(i)).collect();
        write_csv(
            &out.join("spectrum.csv"),
            &["i", "i_over_D", "lambda_gs", "stderr_gs", "lambda_clv", "stderr_clv"],
            (0..ctx.k).map(|i| vec![(i + 1) as f64, x[i], gs[i], gs_err[i], clv[i], clv_err[i]]),
        )?;
        let reduced = if ctx.is_disks() { "i/4N" } else { "i/D" };
        // A line between a handful of exponents (the Henon map's two) would look like data.
        let marker = if ctx.k <= 8 { Marker::Points } else { Marker::Line };
        let mut fig = Figure::new("Lyapunov spectrum: GS forward, CLV backward").x_label(reduced).y_label("λ_i");
        fig.series("GS (forward)", &x, &gs, marker);
        fig.series("CLV (backward)", &x, &clv, marker);
        fig.hline(0.0);
        save_figure(&fig, out, "fig2_spectrum")?;
        // The spectrum.json of builds before h_KS was reported has the exponents but no error.
        let neutral = ctx.run.as_ref().map_or(0..0, |m| m.config.system.neutral());
        let gs_h = ctx.gs.as_ref().and_then(|g| g.ks_entropy.or_else(|| ks_entropy(&g.exponents, neutral.clone()).map(|value| Estimate { value, stderr: f64::NAN })));
        let mut produced = vec![Produced {
            title: "Lyapunov spectrum (Fig. 2)".into(),
            caption: format!(
                "Forward Gram-Schmidt exponents (time average of ln R_ii) and backward covariant exponents (time average of the local CLV exponents over {frames} frames) against the reduced index {reduced}. \
                 Kolmogorov-Sinai entropy h_KS, the sum of the positive exponents (Pesin's identity): {} (GS), {} (CLV).",
                Estimate::or_unknown(gs_h),
                Estimate::or_unknown(self.acc.ks_entropy(1.0, neutral)),
            ) + &ctx.run.as_ref().map_or(String::new(), |run| {
                format!(
                    " The GS averages are over the whole run ({} steps), the CLV averages over the frames' steps only: they differ by that window's own fluctuation, which the CLV errors measure. \
                     The backward stage gives the GS spectrum over the frames' steps too (`gs_window` in RUN_DIR/clv_spectrum.json, and the table `clv backward` prints), the comparison like for like.",
                    run.config.steps
                )
            }),
            figures: vec!["fig2_spectrum".into()],
            tables: vec!["spectrum.csv".into()],
        }];
        if let (true, Some(run), Some((first, last))) = (ctx.is_disks() && ctx.k == ctx.d && ctx.n >= 2, ctx.run.as_ref(), self.steps) {
            // Frame m carries the exponent over [t_m, t_(m+1)], at backward times
            // (total - m - 1) tau .. (total - m) tau from the window's end.
            let total = run.config.relax_steps + run.config.steps;
            let (s1, s2) = ((total - last - 1) as f64 * ctx.tau, (total - first) as f64 * ctx.tau);
            let measured: Vec<String> = (2 * ctx.n..2 * ctx.n + 3).map(|i| format!("{:.4e}", clv[i])).collect();
            produced[0].caption += &format!(
                " The last three null-space CLV exponents (i = 2N+1..2N+3) are not zero in a finite window: backward iteration turns e_(k+3) into e_(k+3) - s e_k, \
                 a growth like the backward time s, not exponential, so over s = {s1:.1}..{s2:.1} they average -ln((1 + s2²)/(1 + s1²)) / (2 (s2 - s1)) = {:.4e}; measured {}.",
                null_shear_exponent(s1, s2),
                measured.join(", ")
            );
        }
        if ctx.is_disks() && ctx.k == ctx.d {
            // The mode region: positive exponents next to the null space, with the negated
            // conjugate exponents at the same index (conjugate pairing: lambda_i = -lambda_{4N+1-i}).
            let last = 2 * ctx.n - 4; // 0-based index of lambda_{2N-3}, the smallest positive
            let first = ctx.central_range().map_or(0, |(first, _)| first);
            let idx: Vec<f64> = (first..=last).map(|i| (i + 1) as f64).collect();
            let pick = |v: &[f64], conj: bool| -> Vec<f64> { (first..=last).map(|i| if conj { -v[ctx.d - 1 - i] } else { v[i] }).collect() };
            let mut fig = Figure::new("Mode region: λ_i and -λ_(4N+1-i)").x_label("i").y_label("λ");
            fig.series("GS λ_i", &idx, &pick(&gs, false), Marker::LinePoints);
            fig.series("GS -λ_(4N+1-i)", &idx, &pick(&gs, true), Marker::Points);
            fig.series("CLV λ_i", &idx, &pick(&clv, false), Marker::LinePoints);
            fig.series("CLV -λ_(4N+1-i)", &idx, &pick(&clv, true), Marker::Points);
            save_figure(&fig, out, "fig8_mode_region")?;
            produced.push(Produced {
                title: "Mode region of the spectrum (Fig. 8)".into(),
                caption: format!(
                    "The positive exponents λ_{}..λ_{} next to the null space, with the negated conjugate exponents at the same index (paper Fig. 8). Steps of equal exponents are where Lyapunov modes may sit; the mode table says which steps were found and what they are. {}",
                    first + 1,
                    last + 1,
                    typical_error(&gs_err[first..=last], &clv_err[first..=last])
                ),
                figures: vec!["fig8_mode_region".into()],
                tables: vec![],
            });
        }
        Ok(produced)
    }
}

/// The median standard errors of the plotted exponents, in words: the figure has no error
/// bars, and whether two neighbours differ is a question of them.
fn typical_error(gs: &[f64], clv: &[f64]) -> String {
    let median = |v: &[f64]| {
        let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied()
    };
    match (median(gs), median(clv)) {
        (Some(g), Some(c)) => format!("Median standard errors of the plotted exponents: {g:.1e} (GS), {c:.1e} (CLV); all errors are in spectrum.csv."),
        (None, Some(c)) => format!("Median standard error of the plotted CLV exponents: {c:.1e}; all errors are in spectrum.csv."),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stage::analyze::testing::{context, frame, out_dir, spectrum};

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
        let mut a = new(&ctx).unwrap();
        let mut want_clv = 0.0;
        let frames = 200; // four blocks of the 50 frames a context without a run gets
        for step in 0..frames {
            let mut f = frame(step, vec![0.0; d], vec![0.0; d * d], None);
            f.local = (0..d).map(|i| (d / 2) as f64 - i as f64 - 0.5 + if step / 50 % 2 == 0 { 0.25 } else { -0.25 }).collect();
            want_clv += f.local.iter().filter(|&&l| l > 0.0).sum::<f64>() / frames as f64;
            a.consume(&f).unwrap();
        }
        let produced = a.finish(&out_dir("spectrum-h"), frames).unwrap();
        let caption = &produced[0].caption;
        assert!(caption.contains(&format!("identity): {want_gs:.6} (GS), {want_clv:.6} ± ")), "{caption}");
    }
}
