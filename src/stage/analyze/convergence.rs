//! Convergence of the spectra (beyond the paper, which quotes its exponents without saying
//! how it knows they converged): the running estimates lambda_i(t) of the forward GS
//! exponents (from the block averages in spectrum.json) and of the CLV exponents (from the
//! frames), with the drift and block-independence tests of [`kernels::convergence`]. This is
//! what a user reads before deciding to extend a run (`clv forward --resume RUN --steps N`).

use super::kernels::convergence::{diagnose, running, Diagnostics};
use super::{save_figure, write_csv, Analysis, Context, Produced};
use crate::config::SystemConfig;
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::statistics::{standard_error, Accumulator};
use crate::stage::frame::Frame;
use std::path::Path;

pub struct Convergence {
    ctx: Context,
    clv: Accumulator,
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    Some(Box::new(Convergence { ctx: ctx.clone(), clv: Accumulator::new(ctx.k, ctx.block_len(false)) }))
}

impl Analysis for Convergence {
    fn name(&self) -> &'static str {
        "convergence"
    }
    fn sampled(&self) -> bool {
        false
    }
    fn consume(&mut self, frame: &Frame) -> Result<()> {
        self.clv.add_logs(frame.local.iter().copied());
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, _frames: u64) -> Result<Vec<Produced>> {
        let ctx = &self.ctx;
        let mut clv = self.clv.block_averages(1.0);
        // Frames arrive newest first: put the blocks in time order. A frame's local exponent
        // is already a rate, so a block of L frames spans L tau.
        clv.exponents.reverse();
        let gs = ctx.gs.as_ref().and_then(|g| g.blocks.clone());
        let mut figures = Vec::new();
        let mut tables = Vec::new();
        let mut sentences = Vec::new();
        let mut tests = Vec::new();
        let mut shown = 0;
        let spectra = [("GS", "gs", gs, "the forward run after its relaxation"), ("CLV", "clv", Some(clv), "the CLV window, oldest frames first")];
        for (id, (label, stem, blocks, span)) in spectra.into_iter().enumerate() {
            let Some(blocks) = blocks.filter(|b| !b.exponents.is_empty()) else {
                sentences.push(format!("{label}: no block averages (a run written before they were kept, or a stream shorter than one block)."));
                continue;
            };
            let run = running(&blocks.exponents);
            let dt = blocks.block_steps as f64 * ctx.tau;
            let t: Vec<f64> = (1..=run.len()).map(|b| b as f64 * dt).collect();
            let header: Vec<String> = std::iter::once("t".to_string()).chain((1..=ctx.k).map(|i| format!("lambda_{i}"))).collect();
            let header: Vec<&str> = header.iter().map(String::as_str).collect();
            let table = format!("convergence_{stem}.csv");
            write_csv(&out.join(&table), &header, run.iter().zip(&t).map(|(r, &t)| std::iter::once(t).chain(r.iter().copied()).collect()))?;
            tables.push(table);
            let last = run.last().cloned().unwrap_or_default();
            let sigma: Vec<f64> = (0..ctx.k).map(|i| standard_error(&blocks.exponents.iter().map(|a| a[i]).collect::<Vec<_>>())).collect();
            let mut fig = Figure::new(&format!("Convergence of the {label} exponents")).x_label(&format!("t (time over {span})")).y_label("(λ_i(t) - λ_i(T)) / σ_i");
            // The running mean of a converged run strays from the final one by sigma
            // sqrt(T/t - 1) (independent blocks): twice that bounds 95 % of it.
            let t_end = t.last().copied().unwrap_or(1.0);
            let envelope: Vec<f64> = t.iter().map(|&t| 2.0 * (t_end / t - 1.0).sqrt()).collect();
            fig.series("+2 sqrt(T/t - 1)", &t, &envelope, Marker::Line).grey();
            fig.series("-2 sqrt(T/t - 1)", &t, &envelope.iter().map(|e| -e).collect::<Vec<_>>(), Marker::Line).grey();
            shown = shown.max(selected(&last).len());
            for i in selected(&last) {
                let y: Vec<f64> = run.iter().map(|r| (r[i] - last[i]) / sigma[i]).collect();
                fig.series(&format!("i = {}", i + 1), &t, &y, Marker::LinePoints);
            }
            fig.hline(0.0);
            let fig_stem = format!("convergence_{stem}");
            save_figure(&fig, out, &fig_stem)?;
            figures.push(fig_stem);
            match diagnose(&blocks.exponents, ctx.run.config.system.neutral()) {
                Some(d) => {
                    sentences.push(verdict(label, &d, blocks.block_steps));
                    tests.push(vec![id as f64, d.blocks as f64, blocks.block_steps as f64, d.tested as f64, d.drifting, d.max_z, (d.max_z_index + 1) as f64, d.sum_z, d.sum_chance(), d.r1, d.r1_limit()]);
                }
                None => sentences.push(format!("{label}: {} blocks, too few to test (at least 4).", blocks.exponents.len())),
            }
        }
        write_csv(
            &out.join("convergence_tests.csv"),
            &["spectrum_0gs_1clv", "blocks", "block_steps", "tested", "drifting_fraction", "max_abs_z", "max_z_index", "h_ks_z", "h_ks_chance", "r1", "r1_limit"],
            tests,
        )?;
        tables.push("convergence_tests.csv".into());
        Ok(vec![Produced {
            title: "Convergence of the spectra (beyond the paper)".into(),
            caption: format!(
                "Running estimates λ_i(t) after each block of the standard error's batch means, as deviations from the final value in units of its standard error σ_i, for {} \
                 (all exponents in the tables). A converged run with independent blocks stays within ±2 sqrt(T/t - 1) of it, 95 % of the time. Drift test: z_i compares the newer half of the blocks with the older half; a stationary run with independent blocks has |z| > 2 for the fraction chance gives (a Student t with 2 (h - 1) degrees of freedom for halves of h blocks; about 5 % \
                 of the exponents for many blocks), and the run counts as drifting from four times that on (a margin for the exponents' correlations with each other, which make the count a poor measure), \
                 or where the same z of h_KS, the sum of the positive exponents, is as large by chance in less than 1 % of stationary runs (its own spread holds those correlations; it catches many exponents moving the same way, each within its errors). Independence test: r_1, the lag-1 autocorrelation of consecutive block averages, averaged over the exponents, is about -1/B for independent blocks; \
                 above -1/B + 2/sqrt(B) the blocks are shorter than the correlation time. {} {}",
                match shown {
                    0 | 1 => "the largest exponent",
                    2 => "the largest and the smallest positive exponent",
                    _ => "the largest, a middle and the smallest positive exponent",
                },
                match ctx.run.config.system {
                    SystemConfig::Disks { .. } => "Exponents that vanish by symmetry (the null space, whose last three CLV exponents drift by construction: see Fig. 2) and any constant up to round-off are not tested.",
                    SystemConfig::Lorenz { .. } => "The exponent of the flow direction, zero by symmetry, and any constant up to round-off are not tested.",
                    SystemConfig::Henon { .. } => "Exponents constant up to round-off are not tested.",
                },
                sentences.join(" ")
            ),
            figures,
            tables,
        }])
    }
}

/// Largest, middle and smallest positive exponent (0-based), or the first if none is
/// positive; an exponent below a hundredth of the largest counts as zero (a null space's
/// round-off, or a flow's zero exponent in a finite run).
fn selected(lambda: &[f64]) -> Vec<usize> {
    let largest = lambda.iter().cloned().fold(0.0, f64::max);
    let p = lambda.iter().filter(|&&l| l > 0.01 * largest).count();
    let mut v = if p == 0 { vec![0] } else { vec![0, (p - 1) / 2, p - 1] };
    v.dedup();
    v
}

/// One sentence per spectrum: the numbers and what they mean.
fn verdict(label: &str, d: &Diagnostics, block_steps: u64) -> String {
    let verdict = d.verdict();
    let mut s = format!("{label}: {} blocks of {block_steps} steps; {}. {}{}.", d.blocks, d.numbers(), verdict[..1].to_uppercase(), &verdict[1..]);
    if d.r1 > 0.0 {
        s += &format!(" Were the block averages an AR(1) sequence with this r_1, the standard errors would be too small by a factor {:.2}.", ((1.0 + d.r1) / (1.0 - d.r1)).sqrt());
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stage::analyze::testing::{context, frame, out_dir, spectrum};
    use crate::statistics::BlockAverages;

    /// The GS blocks of spectrum.json and the CLV blocks of the frames each give a running
    /// table whose last row is the plain mean, and a verdict; a settling GS run is told to
    /// be extended, stationary CLV frames are not.
    #[test]
    fn tables_and_verdicts_follow_the_blocks() {
        let n = 4;
        let d = 4 * n;
        let mut gs = spectrum(n, 2);
        let settle = |b: usize| 0.3 * (-(b as f64) / 6.0).exp();
        gs.blocks = Some(BlockAverages {
            block_steps: 50,
            exponents: (0..20).map(|b| gs.exponents.iter().enumerate().map(|(i, l)| l + if *l != 0.0 { settle(b) + 0.01 * ((b * 7 + i) % 5) as f64 } else { 0.0 }).collect()).collect(),
        });
        let ctx = context("disks", n, d, 4.0, 4.0, Some(gs.clone()), false);
        let mut a = new(&ctx).unwrap();
        let mut rng = crate::rng::Rng::new(5);
        for step in 0..1000 {
            let mut f = frame(step, vec![0.0; d], vec![0.0; d * d], None);
            f.local = (0..d).map(|i| (d / 2) as f64 - i as f64 - 0.5 + 0.3 * rng.normal()).collect();
            a.consume(&f).unwrap();
        }
        let dir = out_dir("convergence");
        let produced = a.finish(&dir, 1000).unwrap();
        let caption = &produced[0].caption;
        assert!(caption.contains("GS: 20 blocks of 50 steps") && caption.contains("still drift"), "{caption}");
        assert!(caption.contains("CLV: 20 blocks of 50 steps") && caption.contains("No test finds a drift or correlated blocks"), "{caption}");
        let gs_table = std::fs::read_to_string(dir.join("convergence_gs.csv")).unwrap();
        let last: Vec<f64> = gs_table.lines().last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        let blocks = &gs.blocks.as_ref().unwrap().exponents;
        assert_eq!(last[0], 20.0 * 50.0 * 0.6);
        for i in 0..d {
            let mean = blocks.iter().map(|b| b[i]).sum::<f64>() / 20.0;
            assert!((last[i + 1] - mean).abs() < 1e-12, "lambda_{}", i + 1);
        }
        assert_eq!(std::fs::read_to_string(dir.join("convergence_tests.csv")).unwrap().lines().count(), 3);
    }

    #[test]
    fn selected_indices_span_the_positive_exponents() {
        assert_eq!(selected(&[3.0, 2.0, 1.0, 0.0, -1.0]), vec![0, 1, 2]);
        assert_eq!(selected(&[0.4, -1.6]), vec![0]);
        assert_eq!(selected(&[0.9, 1e-4, -14.5]), vec![0], "a flow's zero exponent");
        assert_eq!(selected(&[3.0, 2.0, 1.0, 1e-15, -1e-15, -1.0]), vec![0, 1, 2], "a null space");
        assert_eq!(selected(&[-0.1, -0.2]), vec![0]);
    }
}
