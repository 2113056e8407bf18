//! Localization of the vectors (paper Fig. 5): W = exp(<S>)/N with the Shannon entropy
//! S = -sum_n mu_n ln mu_n of the per-disk weights mu_n = |dq_n|^2 + |dp_n|^2, for every CLV
//! and (with GS vectors in the frames) every GS vector. W = 1/N: on one disk; W = 1: spread
//! evenly over all disks.

use super::kernels::localization::LocalizationAverage;
use super::{save_figure, write_csv, Analysis, Context, Produced};
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::stage::frame::Frame;
use std::path::Path;

pub struct Localization {
    ctx: Context,
    clv: LocalizationAverage,
    gs: Option<LocalizationAverage>,
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    (missing == super::Missing::GsVectors && ctx.is_disks()).then_some("the GS curve of Fig. 5")
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    ctx.is_disks().then(|| {
        Box::new(Localization {
            ctx: ctx.clone(),
            clv: LocalizationAverage::new(ctx.n, ctx.k, ctx.block_len(true)),
            gs: ctx.with_gs.then(|| LocalizationAverage::new(ctx.n, ctx.k, ctx.block_len(true))),
        }) as Box<dyn Analysis>
    })
}

impl Analysis for Localization {
    fn name(&self) -> &'static str {
        "localization"
    }
    fn consume(&mut self, frame: &Frame) -> Result<()> {
        self.clv.add_frame(&frame.v);
        if let (Some(acc), Some(g)) = (self.gs.as_mut(), frame.g.as_ref()) {
            acc.add_frame(g);
        }
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let ctx = &self.ctx;
        let w_clv = self.clv.widths();
        let e_clv = self.clv.width_stderr();
        let nan = vec![f64::NAN; ctx.k];
        let (w_gs, e_gs) = self.gs.as_ref().map_or((nan.clone(), nan), |g| (g.widths(), g.width_stderr()));
        let x: Vec<f64> = (0..ctx.k).map(|i| ctx.reduced(i)).collect();
        write_csv(
            &out.join("localization.csv"),
            &["i", "i_over_D", "W_gs", "W_clv", "stderr_gs", "stderr_clv"],
            (0..ctx.k).map(|i| vec![(i + 1) as f64, x[i], w_gs[i], w_clv[i], e_gs[i], e_clv[i]]),
        )?;
        let mut fig = Figure::new("Localization W = exp(<S>)/N").x_label("i/4N").y_label("W");
        if self.gs.is_some() {
            fig.series("GS vectors", &x, &w_gs, Marker::Line);
        }
        fig.series("covariant vectors", &x, &w_clv, Marker::Line);
        save_figure(&fig, out, "fig5_localization")?;
        let mut figures = vec!["fig5_localization".to_string()];
        // The paper's inset: the central (mode and null-space) part, where the vectors spread.
        let central = ctx.central_range();
        if let Some((a, b)) = central {
            let idx: Vec<f64> = (a + 1..=b + 1).map(|i| i as f64).collect();
            let mut fig = Figure::new("Localization W: central part of the spectrum").x_label("i").y_label("W");
            if self.gs.is_some() {
                fig.series("GS vectors", &idx, &w_gs[a..=b], Marker::LinePoints);
            }
            fig.series("covariant vectors", &idx, &w_clv[a..=b], Marker::LinePoints);
            save_figure(&fig, out, "fig5_localization_center")?;
            figures.push("fig5_localization_center".into());
        }
        Ok(vec![Produced {
            title: "Localization (Fig. 5)".into(),
            caption: format!(
                "W = exp(<S>)/N, S = -sum_n mu_n ln mu_n, mu_n = |dq_n|^2 + |dp_n|^2, averaged over {frames} frames{}; {}. Small W: the perturbation lives on few disks.{}",
                if self.gs.is_some() { " for GS and covariant vectors" } else { " for covariant vectors (run the backward stage with --with-gs for GS vectors)" },
                match ctx.block_len(true) {
                    b if frames < 2 * b => format!("no standard errors (NaN in the table): they need at least two blocks of {b} frames"),
                    b => format!("standard errors from blocks of {b} frames"),
                },
                central.map_or(String::new(), |(a, b)| format!(" The second plot enlarges the central part, i = {}..{} (the paper's inset).", a + 1, b + 1))
            ),
            figures,
            tables: vec!["localization.csv".into()],
        }])
    }
}
