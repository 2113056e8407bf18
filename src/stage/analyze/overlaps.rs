//! Orientation of the covariant vectors (paper Figs. 3, 4, 13 and 14): time averages of
//! absolute scalar products.
//!
//! * Fig. 3: <|g^i . v^i|> against i, GS and covariant vector of the same exponent (needs GS
//!   vectors in the frames); 1 for i = 1 and for i = 2N-2, where v^i = g^i.
//! * Fig. 4: <|v^j . g^i|> against i (needs GS vectors) for the selected j, or by default for
//!   hard disks the paper's four kinds (its j = 370, 393, 400, 700): the last unstable vector
//!   before the mode region, the unstable and stable mode vectors next to the null space, and
//!   a stable vector that is no mode. V_n = G_n C_n with upper-triangular C_n puts v^j into
//!   span{g^1..g^j}: the curve vanishes for i > j.
//! * Fig. 13: <|v^j . v^i|> against i (i != j) for the selected j (CLVs only).
//! * Fig. 14: the same for j in the mode region, restricted to the central part of the
//!   spectrum: the last index of each positive mode step (the mode table's,
//!   [`Context::settle`] at the first frame; the paper shows T and LP for n_x = 1, 2, 3), or
//!   2N-5 and 2N-3 where fewer than two are found.
//!
//! The absolute value is taken because only the direction of a tangent vector matters (the
//! paper, Sec. 5.1). Averages run over the consumed frames (those of every m-th step, `--every`).

use super::kernels::angles::{abs_dots_pairwise, abs_dots_with};
use super::kernels::modes::Step;
use super::{save_figure, write_csv, Analysis, Context, Mean, Produced};
use crate::error::Result;
use crate::report::plot::{Figure, Marker, Panels, PANEL};
use crate::stage::frame::Frame;
use std::path::Path;

pub struct Overlaps {
    ctx: Context,
    /// <|g^i . v^i|> (Fig. 3), with GS vectors.
    gv: Option<Mean>,
    /// Selected indices j (0-based) of Fig. 13, from the first frame on.
    js: Vec<usize>,
    /// Those of Fig. 4: the selected ones, or by default for hard disks the paper's four
    /// kinds (an unstable and a stable vector, each a mode and not).
    fig4_js: Vec<usize>,
    /// Mode indices j (0-based) of Fig. 14, from the first frame on.
    mode_js: Vec<usize>,
    /// The positive mode steps that `mode_js` end, at least two; empty where fewer were found
    /// and `mode_js` are the fixed 2N-5, 2N-3.
    mode_steps: Vec<Step>,
    /// The mode each of `mode_steps` is, where the first frame tells ([`super::mode_steps::clear_name`]).
    mode_names: Vec<Option<String>>,
    /// The indices are chosen ([`Overlaps::settle`]).
    settled: bool,
    /// The conjugate partners 4N+1-j of `js` (0-based), Fig. 13's second plot.
    conjugate_js: Vec<usize>,
    /// <|v^j . g^i|> per j of `fig4_js`, with GS vectors.
    vg: Option<Vec<Mean>>,
    /// Indices j with a CLV-CLV average: the union of `js`, `mode_js` and `conjugate_js`.
    vv_js: Vec<usize>,
    /// <|v^j . v^i|> per j of `vv_js` (Figs. 13, 14).
    vv: Vec<Mean>,
    /// With two vectors (the Henon map), |cos θ| = |v^1 . v^2| and |sin θ| = |g^2 . v^2|
    /// (NaN without GS vectors) of every frame in stream order, for their errors by batch
    /// means ([`Overlaps::one_angle`]).
    angle: Vec<[f64; 2]>,
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    match missing {
        super::Missing::GsVectors => Some("Figs. 3 and 4"),
        super::Missing::AllVectors => ctx.is_disks().then_some("the conjugate partners of Fig. 13, Fig. 14"),
        super::Missing::ConsecutiveFrames => None,
    }
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    if ctx.k == 0 {
        return None;
    }
    Some(Box::new(Overlaps {
        ctx: ctx.clone(),
        gv: ctx.with_gs.then(|| Mean::new(ctx.k)),
        vg: None,
        vv: Vec::new(),
        js: Vec::new(),
        fig4_js: Vec::new(),
        mode_js: Vec::new(),
        mode_steps: Vec::new(),
        mode_names: Vec::new(),
        settled: false,
        conjugate_js: Vec::new(),
        vv_js: Vec::new(),
        angle: Vec::new(),
    }))
}

impl Overlaps {
    /// The indices j, from the context settled at the first frame ([`Context::settle`]).
    fn settle(&mut self, frame: &Frame) {
        self.ctx.settle(frame);
        let ctx = &self.ctx;
        self.js = ctx.options.j.iter().map(|j| j - 1).filter(|&j| j < ctx.k).collect();
        // The paper's Fig. 13 has a second panel, the conjugate partners j* = 4N+1-j in the
        // stable subspace.
        if ctx.is_disks() && ctx.k == ctx.d {
            self.conjugate_js = self.js.iter().map(|&j| ctx.d - 1 - j).filter(|j| !self.js.contains(j)).collect();
        }
        // Fig. 14's j: a vector of each unstable mode (the paper's six panels: T and LP for
        // n_x = 1, 2, 3).
        let steps = super::mode_steps::positive(&ctx.modes, ctx.d);
        if steps.len() >= 2 {
            let candidates = super::mode_steps::candidates(ctx);
            self.mode_names = steps.iter().map(|s| super::mode_steps::clear_name(frame, s, &candidates)).collect();
            self.mode_steps = steps;
        }
        self.mode_js = match ctx.central_range() {
            Some(_) if !self.mode_steps.is_empty() => self.mode_steps.iter().map(|s| s.start + s.len - 1).collect(),
            Some(_) if ctx.n >= 3 => vec![2 * ctx.n - 6, 2 * ctx.n - 4],
            _ => Vec::new(),
        };
        self.fig4_js = match (ctx.j_default && ctx.is_disks() && ctx.k == ctx.d && ctx.n >= 4, self.js.last()) {
            (true, Some(&last)) => vec![last, 2 * ctx.n - 4, 2 * ctx.n + 3, ctx.d - super::paper_index(93, 2 * ctx.n - 3)],
            _ => self.js.clone(),
        };
        // A small system's last vector before the modes can be the smallest positive one.
        let mut seen = Vec::new();
        self.fig4_js.retain(|j| !seen.contains(j) && {
            seen.push(*j);
            true
        });
        self.vg = ctx.with_gs.then(|| self.fig4_js.iter().map(|_| Mean::new(ctx.k)).collect());
        self.vv_js = self.js.iter().chain(&self.mode_js).chain(&self.conjugate_js).copied().collect();
        self.vv_js.sort_unstable();
        self.vv_js.dedup();
        self.vv = self.vv_js.iter().map(|_| Mean::new(ctx.k)).collect();
        self.settled = true;
    }
}

/// Header names and rows of a table with one (mean, std) column pair per j.
fn per_j_table(ctx: &Context, js: &[usize], means: &[&Mean], what: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let mut header = vec!["i".to_string(), "i_over_D".to_string()];
    for j in js {
        header.push(format!("{what}{}_mean", j + 1));
        header.push(format!("{what}{}_std", j + 1));
    }
    let cols: Vec<(Vec<f64>, Vec<f64>)> = means.iter().map(|m| (m.mean(), m.std())).collect();
    let rows = (0..ctx.k)
        .map(|i| {
            let mut row = vec![(i + 1) as f64, ctx.reduced(i)];
            for (mean, std) in &cols {
                row.push(mean[i]);
                row.push(std[i]);
            }
            row
        })
        .collect();
    (header, rows)
}

fn csv(out: &Path, name: &str, header: &[String], rows: Vec<Vec<f64>>) -> Result<()> {
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    write_csv(&out.join(name), &h, rows)
}

/// The average with the entry i = j (trivially 1) blanked out, as in the paper's plots.
fn without_self(mean: &[f64], j: usize) -> Vec<f64> {
    mean.iter().enumerate().map(|(i, &x)| if i == j { f64::NAN } else { x }).collect()
}

impl Analysis for Overlaps {
    fn name(&self) -> &'static str {
        "overlaps"
    }

    fn consume(&mut self, frame: &Frame) -> Result<()> {
        let d = frame.d;
        if !self.settled {
            self.settle(frame);
        }
        if let (Some(gv), Some(g)) = (self.gv.as_mut(), frame.g.as_ref()) {
            gv.add(abs_dots_pairwise(g, &frame.v, d));
        }
        if let (Some(vg), Some(g)) = (self.vg.as_mut(), frame.g.as_ref()) {
            for (acc, &j) in vg.iter_mut().zip(&self.fig4_js) {
                acc.add(abs_dots_with(frame.v(j), g));
            }
        }
        for (acc, &j) in self.vv.iter_mut().zip(&self.vv_js) {
            acc.add(abs_dots_with(frame.v(j), &frame.v));
        }
        if d == 2 && frame.k == 2 {
            let sin = frame.g.as_ref().map_or(f64::NAN, |g| abs_dots_pairwise(g, &frame.v, d)[1]);
            self.angle.push([abs_dots_with(frame.v(1), &frame.v)[0], sin]);
        }
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let ctx = &self.ctx;
        let shared = Shared {
            idx: (1..=ctx.k).map(|i| i as f64).collect(),
            // a handful of indices (Lorenz's three) are points, not a continuum: a line between
            // them would look like data (as in Fig. 2)
            line: if ctx.k <= 8 { Marker::Points } else { Marker::Line },
            avg: ctx.averaged_over(frames),
            central: ctx.central_range(),
        };
        // Two vectors (the Henon map): every curve would have two points, and all would give
        // one angle; its numbers instead of the figures.
        let two = ctx.d == 2;
        let mut produced = Vec::new();
        if let Some(gv) = &self.gv {
            write_csv(
                &out.join("overlap_gs_clv.csv"),
                &["i", "i_over_D", "abs_g_dot_v_mean", "abs_g_dot_v_std"],
                (0..ctx.k).map(|i| vec![(i + 1) as f64, ctx.reduced(i), gv.mean()[i], gv.std()[i]]),
            )?;
            if !two {
                produced.push(self.fig3(gv, &shared, out)?);
            }
        }
        if let (Some(vg), false) = (&self.vg, self.fig4_js.is_empty()) {
            let means: Vec<&Mean> = vg.iter().collect();
            let (header, rows) = per_j_table(ctx, &self.fig4_js, &means, "abs_v");
            csv(out, "overlap_clv_gs.csv", &header, rows)?;
            if !two {
                produced.push(self.fig4(vg, &shared, out)?);
            }
        }
        if !self.vv_js.is_empty() {
            let means: Vec<&Mean> = self.vv.iter().collect();
            let (header, rows) = per_j_table(ctx, &self.vv_js, &means, "abs_v");
            csv(out, "overlap_clv_clv.csv", &header, rows)?;
            if !self.js.is_empty() && !two {
                produced.push(self.fig13(&shared, out)?);
            }
            if let (Some(central), false) = (shared.central, self.mode_js.is_empty()) {
                produced.push(self.fig14(central, &shared, out)?);
            }
        }
        if two {
            produced.push(self.one_angle(&shared));
        }
        Ok(produced)
    }
}

/// What the figures of [`Overlaps`] share.
struct Shared {
    /// The abscissa i = 1..k.
    idx: Vec<f64>,
    /// How a curve over all i is drawn.
    line: Marker,
    /// The captions' "averaged over N frames (...)".
    avg: String,
    /// The central (mode and null-space) part of the spectrum, 0-based and inclusive, if any.
    central: Option<(usize, usize)>,
}

impl Overlaps {
    /// <|v^j . v^i|> for j, where j is one of `vv_js`.
    fn vv_mean(&self, j: usize) -> Option<Vec<f64>> {
        self.vv_js.iter().position(|&x| x == j).map(|p| self.vv[p].mean())
    }

    /// Figs. 3, 4 and 13 of two vectors (D = 2, the Henon map), in words: their curves would
    /// have two points each and all give the angle θ between v^1 and v^2, since v^1 = ±g^1
    /// and g^2 is normal to it: |v^1 · v^2| = |v^2 · g^1| = |cos θ|, |g^2 · v^2| = |sin θ|.
    fn one_angle(&self, shared: &Shared) -> Produced {
        let cos = self.vv_mean(0).and_then(|m| m.get(1).copied()).or_else(|| self.vv_mean(1).map(|m| m[0]));
        let sin = self.gv.as_ref().and_then(|gv| gv.mean().get(1).copied());
        let block = self.ctx.block_len(true) as usize;
        let error = |c: usize| {
            // Frames without G (a file of both kinds) give no sine: blocks over those with one.
            let series: Vec<f64> = self.angle.iter().map(|a| a[c]).filter(|x| !x.is_nan()).collect();
            match crate::statistics::batch_stderr(&series, block) {
                e if e.is_finite() => format!(" ± {e:.4}"),
                _ => String::new(),
            }
        };
        let mut numbers = Vec::new();
        if let Some(c) = cos {
            numbers.push(format!("<|v^1 · v^2|> = <|cos θ|> = {c:.4}{} (Fig. 13; Fig. 4's <|v^2 · g^1|> is the same, as v^1 = ±g^1)", error(0)));
        }
        if let Some(s) = sin {
            numbers.push(format!("<|g^2 · v^2|> = <|sin θ|> = {s:.4}{} (Fig. 3 at i = 2, and Fig. 4's <|v^2 · g^2|>; Fig. 3 is 1 at i = 1)", error(1)));
        }
        if self.angle.len() >= 2 * block {
            numbers.push(format!("standard errors from blocks of {block} frames"));
        }
        let tables = [(self.gv.is_some(), "overlap_gs_clv.csv"), (self.vg.is_some() && !self.fig4_js.is_empty(), "overlap_clv_gs.csv"), (!self.vv_js.is_empty(), "overlap_clv_clv.csv")];
        Produced {
            title: "Angle between the two covariant vectors (Figs. 3, 4 and 13 for D = 2)".into(),
            caption: if self.ctx.k < 2 {
                "With D = 2 and one vector (k = 1) the curves of Figs. 3, 4 and 13 would have one point each, |g^1 · v^1| = 1 (v^1 = ±g^1), so they are left out; the angle θ between the unstable and the stable covariant vector needs both (--vectors 2).".into()
            } else {
                format!(
                    "With D = 2 the curves of Figs. 3, 4 and 13 would have two points each, and all give one number, the angle θ between the unstable covariant vector v^1 and the stable one v^2 (g^1 = ±v^1, g^2 normal to it), so they are left out: {}, {}.{}",
                    numbers.join("; "),
                    shared.avg,
                    if self.ctx.system == "henon" { " Fig. 1 draws both vectors at a point of the attractor." } else { "" }
                )
            },
            figures: Vec::new(),
            tables: tables.into_iter().filter(|(has, _)| *has).map(|(_, t)| t.to_string()).collect(),
        }
    }

    /// Fig. 3, <|g^i . v^i|> against i (and its central part); its table is written by
    /// [`Analysis::finish`].
    fn fig3(&self, gv: &Mean, shared: &Shared, out: &Path) -> Result<Produced> {
        let ctx = &self.ctx;
        let (idx, central) = (&shared.idx, shared.central);
        let mean = gv.mean();
        // The indices whose covariant vectors do not converge, marked where the caption says
        // why (with the central part).
        let shear = central.and(ctx.null_shear());
        let plot = |title: &str, (a, b): (usize, usize), line: Marker, stem: &str| {
            let mut fig = Figure::new(title).x_label("i").y_label("<|g^i · v^i|>");
            fig.series("<|g^i · v^i|>", &idx[a..=b], &mean[a..=b], line);
            if let Some(s) = &shear {
                fig.series(&format!("not converged (i = {}..{}, see caption)", s.start + 1, s.end), &idx[s.clone()], &mean[s.clone()], Marker::Points).color(6 /* black */).open_markers(true);
            }
            save_figure(&fig, out, stem)
        };
        plot("GS and covariant vectors of the same exponent: <|g^i · v^i|>", (0, ctx.k - 1), shared.line, "fig3_gs_clv_overlap")?;
        let mut figures = vec!["fig3_gs_clv_overlap".to_string()];
        if let Some(central) = central {
            plot("<|g^i · v^i|>: central part of the spectrum", central, Marker::LinePoints, "fig3_gs_clv_overlap_center")?;
            figures.push("fig3_gs_clv_overlap_center".into());
        }
        Ok(Produced {
            title: "Gram-Schmidt versus covariant vectors (Fig. 3)".into(),
            caption: format!(
                "Time average of |g^i · v^i| for the GS and covariant vectors of the same exponent λ_i against i, {}{}.{}",
                shared.avg,
                central.map(|(a, b)| format!("; the second plot enlarges the central (mode and null-space) part, i = {}..{}", a + 1, b + 1)).unwrap_or_default(),
                match (central, ctx.null_shear()) {
                    (Some(_), Some(shear)) => fig3_null_space(ctx.n, shear, &mean),
                    _ => String::new(),
                }
            ),
            figures,
            tables: vec!["overlap_gs_clv.csv".into()],
        })
    }

    /// Fig. 4, <|v^j . g^i|> against i for the j of `fig4_js` (its table, overlap_clv_gs.csv,
    /// is written by [`Analysis::finish`]).
    fn fig4(&self, vg: &[Mean], shared: &Shared, out: &Path) -> Result<Produced> {
        let ctx = &self.ctx;
        let selected = self.fig4_js == self.js;
        // The paper's four kinds in its arrangement: unstable left, stable right, the
        // vectors that are no mode above the mode vectors.
        let order: Vec<usize> = if !selected && vg.len() == 4 { vec![0, 3, 1, 2] } else { (0..vg.len()).collect() };
        let mut panels = Panels::new("Covariant vector v^j against all GS vectors: <|v^j · g^i|>", 2);
        for p in order {
            let j = self.fig4_js[p];
            let mut fig = Figure::new(&format!("j = {}", j + 1)).size(PANEL.0, PANEL.1).x_label("i").y_label("<|v^j · g^i|>");
            fig.series("", &shared.idx, &vg[p].mean(), shared.line);
            panels.push(fig);
        }
        save_figure(&panels, out, "fig4_clv_gs_overlap")?;
        // The vectors next to the null space are mode vectors where the report found mode
        // steps there (the paper's are); a small system may have none.
        let in_mode = |j: usize| ctx.modes.as_ref().is_ok_and(|m| m.iter().any(|(s, _)| (s.start..s.start + s.len).contains(&j)));
        let modes_next = ctx.n >= 2 && in_mode(2 * ctx.n - 4) && in_mode(2 * ctx.n + 3);
        let next = if modes_next { "mode vector" } else { "vector (no mode step there in this report)" };
        let which = if selected {
            "the selected covariant vectors".to_string()
        } else {
            format!(
                "the covariant vectors of the paper's j = 370, 393, 400 and 700: the last unstable vector before the mode region, the unstable and the stable {next} next to the null space (2N-3, 2N+4), and a stable vector that is no mode, the conjugate 4N+1-j of the paper's 93 scaled (its curve may step at i = {})",
                ctx.d - self.fig4_js.last().copied().unwrap_or_default()
            )
        };
        let arranged = if !selected && vg.len() == 4 {
            if modes_next {
                "arranged as the paper's: unstable vectors left, stable right, the vectors that are no mode at the top, the mode vectors below"
            } else {
                "arranged as the paper's: unstable vectors left, stable right, the vectors next to the null space below"
            }
        } else {
            "left to right, then top to bottom"
        };
        Ok(Produced {
            title: "Covariant vectors in the GS basis (Fig. 4)".into(),
            caption: format!(
                "Time average of |v^j · g^i| against i for {which}, j = {}, {}; one panel per j, {arranged}. Since V = G C with upper-triangular C, v^j lies in span{{g^1..g^j}}: the curves vanish for i > j.",
                list(&self.fig4_js),
                shared.avg
            ),
            figures: vec!["fig4_clv_gs_overlap".into()],
            tables: vec!["overlap_clv_gs.csv".into()],
        })
    }

    /// Fig. 13, <|v^j . v^i|> against i (i != j) for the selected j, and in a second plot for
    /// their conjugate partners `conjugate_js` (table overlap_clv_clv.csv).
    fn fig13(&self, shared: &Shared, out: &Path) -> Result<Produced> {
        let ctx = &self.ctx;
        let mut figures = Vec::new();
        for (title, js, stem) in [("Covariant vectors", &self.js, "fig13_clv_overlap"), ("Covariant vectors of the conjugate partners", &self.conjugate_js, "fig13_clv_overlap_conjugate")] {
            if js.is_empty() {
                continue;
            }
            let mut fig = Figure::new(&format!("{title}: <|v^j · v^i|>, i != j")).x_label("i").y_label("<|v^j · v^i|>");
            for &j in js {
                if let Some(m) = self.vv_mean(j) {
                    fig.series(&format!("j = {}", j + 1), &shared.idx, &without_self(&m, j), shared.line);
                }
            }
            save_figure(&fig, out, stem)?;
            figures.push(stem.to_string());
        }
        Ok(Produced {
            title: "Scalar products between covariant vectors (Fig. 13)".into(),
            caption: format!(
                "Time average of |v^j · v^i| against i (i != j) for the selected covariant vectors j = {}{}, {}.{}",
                list(&self.js),
                if self.conjugate_js.is_empty() { String::new() } else { format!(", and in the second plot for their conjugate partners j = {} (4N+1-j, as the paper's right-hand panels)", list(&self.conjugate_js)) },
                shared.avg,
                // A map's or Lorenz's stable and unstable subspaces are one vector each.
                if ctx.is_disks() { " The null space 2N-2..2N+3 is orthogonal to all other covariant vectors. Vectors of the same (stable or unstable) subspace are not orthogonal." } else { "" }
            ),
            figures,
            tables: vec!["overlap_clv_clv.csv".into()],
        })
    }

    /// Fig. 14, <|v^j . v^i|> (i != j) for the mode vectors `mode_js` in the mode regime, with
    /// how far they overlap as the paper finds ([`mode_overlaps`]; table overlap_clv_clv.csv).
    fn fig14(&self, central: (usize, usize), shared: &Shared, out: &Path) -> Result<Produced> {
        let ctx = &self.ctx;
        // The paper restricts the abscissa to the mode regime: the steps, their
        // conjugates and the null space between them, with a margin.
        let (a, b) = match self.mode_steps.iter().map(|s| s.start).min() {
            Some(first) => (first.saturating_sub(4), ctx.d - 1 - first.saturating_sub(4)),
            None => central,
        };
        // Nearest the null space first, two to a row: the paper's arrangement where T and LP
        // steps alternate from the null space on (T(1,0) and LP(1,0) in the top row).
        let mut panels = Panels::new("Mode vectors: <|v^j · v^i|> in the mode regime, i != j", 2);
        for &j in self.mode_js.iter().rev() {
            if let Some(m) = self.vv_mean(j) {
                let y = without_self(&m, j);
                // The step's range names its row in the mode table, which says what it is.
                let title = match self.mode_steps.iter().position(|s| (s.start..s.start + s.len).contains(&j)) {
                    Some(p) => {
                        let s = &self.mode_steps[p];
                        let name = self.mode_names.get(p).cloned().flatten().map(|n| format!("{n}, ")).unwrap_or_default();
                        format!("j = {} ({name}step i = {}..{})", j + 1, s.start + 1, s.start + s.len)
                    }
                    None => format!("j = {}", j + 1),
                };
                let mut fig = Figure::new(&title).size(PANEL.0, PANEL.1).x_label("i").y_label("<|v^j · v^i|>");
                fig.series("", &shared.idx[a..=b], &y[a..=b], Marker::LinePoints);
                panels.push(fig);
            }
        }
        save_figure(&panels, out, "fig14_mode_overlap")?;
        Ok(Produced {
            title: "Scalar products of mode vectors (Fig. 14)".into(),
            caption: format!(
                "Time average of |v^j · v^i| for j = {} ({}) against i = {}..{} (i != j), {}, one panel per j, two to a row, from the j nearest the null space (the paper's six panels have T(n,0) left and LP(n,0) right, n = 1, 2, 3 downwards, the order the steps alternate in).{}",
                list(&self.mode_js),
                if !self.mode_steps.is_empty() {
                    "the last index of each positive mode step, found as the mode table finds them; each panel's title gives its step's first and last index, its row in the mode table, which says what the step is"
                } else {
                    "2N-5 and 2N-3, the positive indices next to the null space, where the slowest modes sit if the system has any; fewer than two mode steps were found to choose by"
                },
                a + 1,
                b + 1,
                shared.avg,
                mode_overlaps(ctx.d, &self.mode_steps, |j| self.vv_mean(j)),
            ),
            figures: vec!["fig14_mode_overlap".into()],
            tables: vec!["overlap_clv_clv.csv".into()],
        })
    }
}

/// Fig. 3's caption on the null space of N disks, from <|g^i . v^i|> (`mean`): which of its
/// values of 1 hold for any start of the backward pass and which come from C = identity, and
/// the values at i = 2N+1..2N+3.
fn fig3_null_space(n: usize, shear: std::ops::Range<usize>, mean: &[f64]) -> String {
    let kept = (2 * n - 2..2 * n).all(|i| (mean[i] - 1.0).abs() < 1e-9);
    format!(
        " It is 1 at i = 1 and i = 2N-2 = {}, where v^i = g^i for any start (the paper).{} At i = {}..{} (black open rings: not converged) it is {}: those covariant vectors are E_(k+3) - s E_k after a backward time s (see Fig. 2), turned towards the position shifts E_k as s grows, while those GS vectors are the momentum shifts E_(k+3), so that it vanishes like 1/s in a long window: a dip of the finite window, not of the dynamics.",
        2 * n - 2,
        if kept {
            format!(
                " It is 1 at i = {}, {} too, by the backward stage's start: the null space's exponents are equal, so the backward iteration does not turn its covariant vectors within it, and with C = identity (`--c-init identity`, the default) they keep the GS directions (`--c-init random` gives others).",
                2 * n - 1,
                2 * n
            )
        } else {
            String::new()
        },
        shear.start + 1,
        shear.end,
        shear.clone().map(|i| format!("{:.2e}", mean[i])).collect::<Vec<_>>().join(", ")
    )
}

/// Fig. 14's finding measured, where the paper states it (Sec. 5.6, on Fig. 14): "each vector representing
/// a T or LP-mode has significant contributions to the scalar product only for covariant
/// vectors belonging to the same degenerate exponent and -- to a lesser extent -- the
/// corresponding conjugate (negative) exponents". For the last vector j of each step: its
/// largest average overlap inside its step, inside the conjugate step, and anywhere else.
fn mode_overlaps(d: usize, steps: &[Step], mean_of: impl Fn(usize) -> Option<Vec<f64>>) -> String {
    let mut rows = Vec::new();
    let (mut as_paper, mut not) = (Vec::new(), Vec::new());
    for step in steps {
        let j = step.start + step.len - 1;
        let Some(m) = mean_of(j) else { continue };
        let own = step.start..step.start + step.len;
        let conjugate = d - step.start - step.len..d - step.start;
        let max_over = |keep: &dyn Fn(usize) -> bool| (0..d).filter(|&i| i != j && keep(i)).map(|i| m[i]).fold(f64::NAN, f64::max);
        let (same, conj, rest) = (max_over(&|i| own.contains(&i)), max_over(&|i| conjugate.contains(&i)), max_over(&|i| !own.contains(&i) && !conjugate.contains(&i)));
        rows.push(format!("j = {}: {same:.3}, {conj:.3}, {rest:.3}", j + 1));
        let above = |a: f64, b: f64| a.partial_cmp(&b) == Some(std::cmp::Ordering::Greater);
        let departure = if !above(same, conj) {
            Some("its conjugate step more than its own, unlike the paper, where the own step's overlap is the larger".to_string())
        } else if !above(same, rest) {
            Some("another index more than its own step, unlike the paper".to_string())
        } else if !above(conj, rest) {
            // The paper's LP(3,0) has no conjugate peak at all; one that stands out of the
            // background but below a neighbour of the step is another finding.
            let others: Vec<f64> = (0..d).filter(|&i| i != j && !own.contains(&i) && !conjugate.contains(&i)).map(|i| m[i]).collect();
            let background = crate::statistics::median(&others);
            let rest_at = (0..d).filter(|&i| i != j && !own.contains(&i) && !conjugate.contains(&i)).find(|&i| m[i] == rest).unwrap_or(j);
            if above(conj, 2.0 * background) {
                let beside = rest_at + step.len >= own.start && rest_at < own.end + step.len;
                Some(format!(
                    "a conjugate peak, {conj:.3} against a median of {background:.3} elsewhere, but a larger overlap with i = {}{}",
                    rest_at + 1,
                    if beside { ", beside its own step" } else { "" }
                ))
            } else {
                Some(format!("no conjugate peak above the median of {background:.3} elsewhere, as the paper's LP(3,0)"))
            }
        } else {
            None
        };
        match departure {
            None => as_paper.push(j),
            Some(how) => not.push(format!("j = {} ({how})", j + 1)),
        }
    }
    if rows.is_empty() {
        return String::new();
    }
    let mut s = format!(" Largest average overlap of each j inside its own step, inside the conjugate step and anywhere else: {}.", rows.join("; "));
    match (as_paper.is_empty(), not.is_empty()) {
        (_, true) => s += " In that order for every j, as the paper finds.",
        (true, false) => s += &format!(" In the paper's order (own step, then conjugate step, then the rest) for no j: {}.", not.join("; ")),
        (false, false) => s += &format!(" In the paper's order (own step, then conjugate step, then the rest) for j = {}, not for {}.", list(&as_paper), not.join("; ")),
    }
    s
}

/// "1, 8, 15": 1-based indices for captions.
fn list(js: &[usize]) -> String {
    js.iter().map(|j| (j + 1).to_string()).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::super::Options;
    use super::*;
    use super::super::testing::{self, column, out_dir as scratch, read_table as read_csv};

    fn context(system: &str, n: usize, d: usize, with_gs: bool, j: Vec<usize>) -> Context {
        let mut ctx = testing::context(system, n, d, 5.0, 5.0, None, with_gs);
        ctx.options = Options { every: 1, j, deltas: vec![1, 2] };
        ctx
    }

    fn frame(step: u64, d: usize, v: Vec<f64>, g: Option<Vec<f64>>) -> Frame {
        testing::frame(step, vec![1.0; d], v, g)
    }

    fn identity(d: usize) -> Vec<f64> {
        (0..d * d).map(|x| if x % (d + 1) == 0 { 1.0 } else { 0.0 }).collect()
    }

    /// Fig. 14 takes the mode steps the mode table finds, also a block found by its vectors
    /// only: its panel is the block's last index.
    #[test]
    fn fig14_takes_an_lp_block_found_by_its_vectors() {
        let testing::Planted { ctx, frame, at, .. } = testing::lp_block_found_by_its_vectors();
        let mut o = new(&ctx).unwrap();
        o.consume(&frame).unwrap();
        let out = scratch("lp-by-vectors-overlaps");
        let produced = o.finish(&out, 1).unwrap();
        let fig14 = produced.iter().find(|p| p.title.contains("Fig. 14")).expect("Fig. 14");
        assert!(fig14.caption.contains("found as the mode table finds them"), "{}", fig14.caption);
        let header = std::fs::read_to_string(out.join("overlap_clv_clv.csv")).unwrap();
        assert!(header.lines().next().unwrap().contains(&format!("abs_v{}_mean", at + 4)), "Fig. 14 takes the LP block's last index: {header:.200}");
        let svg = std::fs::read_to_string(out.join("fig14_mode_overlap.svg")).unwrap();
        // The planted block is an LP mode of the smallest wave vector, and the panel says so.
        let title = format!("j = {} (LP(1,0), step i = {}..{})", at + 4, at + 1, at + 4);
        assert!(svg.contains(&title), "the panel names its mode and its step's row in the mode table, {title}: {}", svg.split("<text").filter(|t| t.contains("j = ")).collect::<Vec<_>>().join(" | "));
    }

    #[test]
    fn equal_sets_overlap_one_and_gs_basis_is_triangular() {
        // d = 16 (N = 4 disks), G = identity, V = G with alternating signs: |g^i . v^i| = 1,
        // |v^j . g^i| = delta_ij, |v^j . v^i| = delta_ij.
        let d = 16;
        let ctx = context("disks", 4, d, true, vec![1, 5]);
        let mut a = new(&ctx).unwrap();
        let g = identity(d);
        let v: Vec<f64> = g.iter().enumerate().map(|(x, &y)| if (x / d) % 2 == 1 { -y } else { y }).collect();
        for step in (0..5).rev() {
            a.consume(&frame(step, d, v.clone(), Some(g.clone()))).unwrap();
        }
        let out = scratch("equal");
        let produced = a.finish(&out, 5).unwrap();
        let stems: Vec<&String> = produced.iter().flat_map(|p| &p.figures).collect();
        for stem in ["fig3_gs_clv_overlap", "fig3_gs_clv_overlap_center", "fig4_clv_gs_overlap", "fig13_clv_overlap", "fig13_clv_overlap_conjugate", "fig14_mode_overlap"] {
            assert!(stems.iter().any(|s| *s == stem), "{stem} missing from {stems:?}");
            assert!(out.join(format!("{stem}.png")).exists());
        }
        let t3 = read_csv(&out.join("overlap_gs_clv.csv"));
        assert!(column(&t3, "abs_g_dot_v_mean").iter().all(|&x| x == 1.0));
        assert!(column(&t3, "abs_g_dot_v_std").iter().all(|&x| x == 0.0));
        // Fig. 3 marks the three indices that do not converge, 2N+1..2N+3 = 9..11, in both
        // plots, and says so.
        let fig3 = produced.iter().find(|p| p.title.contains("Fig. 3")).unwrap();
        assert!(fig3.caption.contains("At i = 9..11 (black open rings: not converged)"), "{}", fig3.caption);
        for stem in ["fig3_gs_clv_overlap", "fig3_gs_clv_overlap_center"] {
            let svg = std::fs::read_to_string(out.join(format!("{stem}.svg"))).unwrap();
            let marks = svg.split("<g fill=\"none\" stroke=\"#000000\" stroke-width=\"1\" clip-path").nth(1).and_then(|g| g.split("</g>").next()).unwrap_or_else(|| panic!("{stem}: no marks"));
            assert_eq!(marks.matches("<circle").count(), 3, "{stem}: {marks}");
            assert!(svg.contains("not converged (i = 9..11, see caption)"), "{stem}");
        }
        let t4 = read_csv(&out.join("overlap_clv_gs.csv"));
        for j in [1usize, 5] {
            let c = column(&t4, &format!("abs_v{j}_mean"));
            for (i, &x) in c.iter().enumerate() {
                assert_eq!(x, if i + 1 == j { 1.0 } else { 0.0 }, "j = {j}, i = {}", i + 1);
            }
        }
        // CLV-CLV: the selected j, the mode indices 2N-5 = 3, 2N-3 = 5, and the conjugates
        // 4N+1-j = 16, 12 of the selected j
        let t13 = read_csv(&out.join("overlap_clv_clv.csv"));
        for j in [1usize, 3, 5, 12, 16] {
            let c = column(&t13, &format!("abs_v{j}_mean"));
            assert_eq!(c.iter().sum::<f64>(), 1.0);
            assert_eq!(c[j - 1], 1.0);
        }
    }

    #[test]
    fn fig14_states_the_papers_order_only_where_it_is_measured() {
        // D = 12; steps 3..4 (j = 4, conjugate 9..10) and 5..6 (j = 6, conjugate 7..8).
        let d = 12;
        let steps = [Step { start: 2, len: 2, mean: 0.2 }, Step { start: 4, len: 2, mean: 0.1 }];
        let mut means = [vec![0.05; d], vec![0.05; d]];
        means[0][2] = 0.5; // own step of j = 4
        means[0][9] = 0.3; // its conjugate step
        means[1][4] = 0.2; // own step of j = 6
        means[1][6] = 0.4; // its conjugate step, larger: not the paper's order
        let caption = mode_overlaps(d, &steps, |j| Some(means[usize::from(j == 5)].clone()));
        assert!(caption.contains("j = 4: 0.500, 0.300, 0.050; j = 6: 0.200, 0.400, 0.050."), "{caption}");
        assert!(caption.contains("for j = 4, not for j = 6 (its conjugate step more than its own, unlike the paper"), "{caption}");
        means[1][6] = 0.04; // no conjugate peak
        let caption = mode_overlaps(d, &steps, |j| Some(means[usize::from(j == 5)].clone()));
        assert!(caption.contains("not for j = 6 (no conjugate peak above the median of 0.050 elsewhere, as the paper's LP(3,0))"), "{caption}");
        // A conjugate peak out of the background, below the step's neighbour i = 4 (the
        // default run's LP(1,0): 0.103 against a median of 0.034, below 0.208 at i = 71).
        means[1][6] = 0.12;
        means[1][3] = 0.15;
        let caption = mode_overlaps(d, &steps, |j| Some(means[usize::from(j == 5)].clone()));
        assert!(caption.contains("not for j = 6 (a conjugate peak, 0.120 against a median of 0.050 elsewhere, but a larger overlap with i = 4, beside its own step)"), "{caption}");
        means[1][3] = 0.05;
        means[1][6] = 0.1;
        let caption = mode_overlaps(d, &steps, |j| Some(means[usize::from(j == 5)].clone()));
        assert!(caption.contains("In that order for every j, as the paper finds."), "{caption}");
        assert_eq!(mode_overlaps(d, &[], |_| None), "");
    }

    #[test]
    fn known_angles_are_averaged_over_frames() {
        // Henon-like 2-d example: v^1 = (1, 0), v^2 = (cos a, sin a) with a different angle in
        // each frame; G = identity. <|v^1 . v^2|> is the mean of |cos a|; <|g^2 . v^2|> the
        // mean of |sin a|.
        let d = 2;
        let ctx = context("henon", 0, d, true, vec![1]);
        let mut a = new(&ctx).unwrap();
        let angles = [0.3f64, 2.0, -1.1];
        for (s, x) in angles.iter().enumerate() {
            a.consume(&frame(s as u64, d, vec![1.0, 0.0, x.cos(), x.sin()], Some(identity(2)))).unwrap();
        }
        let out = scratch("angles");
        let produced = a.finish(&out, 3).unwrap();
        // no central part or mode figure for a map
        assert!(produced.iter().all(|p| !p.figures.iter().any(|f| f.contains("center") || f.contains("fig14"))));
        let mean = |f: fn(f64) -> f64| angles.iter().map(|&x| f(x).abs()).sum::<f64>() / 3.0;
        let t13 = read_csv(&out.join("overlap_clv_clv.csv"));
        assert!((column(&t13, "abs_v1_mean")[1] - mean(f64::cos)).abs() < 1e-15);
        let t3 = read_csv(&out.join("overlap_gs_clv.csv"));
        let g = column(&t3, "abs_g_dot_v_mean");
        assert_eq!(g[0], 1.0);
        assert!((g[1] - mean(f64::sin)).abs() < 1e-15);
        // D = 2: no two-point figures, one entry that gives the angle's numbers with all three
        // tables.
        assert_eq!(produced.len(), 1, "{produced:?}");
        let p = &produced[0];
        assert!(p.figures.is_empty() && p.tables == ["overlap_gs_clv.csv", "overlap_clv_gs.csv", "overlap_clv_clv.csv"], "{p:?}");
        assert!(p.caption.contains(&format!("<|cos θ|> = {:.4}", mean(f64::cos))) && p.caption.contains(&format!("<|sin θ|> = {:.4}", mean(f64::sin))), "{}", p.caption);
        assert!(!std::fs::read_dir(&*out).unwrap().any(|e| e.unwrap().file_name().to_string_lossy().ends_with(".png")));
    }

    /// With one of the Henon map's two vectors there is no angle: no one-point figures, a
    /// caption that says what is missing (it indexed a second vector that is not there).
    #[test]
    fn one_vector_of_two_gives_no_figures_and_no_angle() {
        let mut ctx = context("henon", 0, 2, true, vec![1]);
        ctx.k = 1;
        let mut a = new(&ctx).unwrap();
        for step in 0..3 {
            a.consume(&frame(step, 2, vec![1.0, 0.0], Some(vec![1.0, 0.0]))).unwrap();
        }
        let out = scratch("one-vector");
        let produced = a.finish(&out, 3).unwrap();
        assert!(produced.len() == 1 && produced[0].figures.is_empty() && produced[0].caption.contains("needs both (--vectors 2)"), "{produced:?}");
    }

    /// The angle's averages carry errors by batch means: blocks of the context's 50 frames
    /// (1000 steps in 20 blocks), over the frames in stream order.
    #[test]
    fn the_angle_has_batch_means_errors() {
        let d = 2;
        let ctx = context("henon", 0, d, true, vec![1]);
        let mut a = new(&ctx).unwrap();
        let mut rng = crate::rng::Rng::new(5);
        let angles: Vec<f64> = (0..230).map(|_| 3.0 * rng.uniform()).collect();
        for (s, x) in angles.iter().enumerate() {
            a.consume(&frame(s as u64, d, vec![1.0, 0.0, x.cos(), x.sin()], Some(identity(2)))).unwrap();
        }
        let out = scratch("angle-errors");
        let p = a.finish(&out, 230).unwrap().remove(0);
        for f in [f64::cos, f64::sin] {
            let series: Vec<f64> = angles.iter().map(|&x| f(x).abs()).collect();
            let means: Vec<f64> = series.chunks_exact(50).map(|b| b.iter().sum::<f64>() / 50.0).collect();
            assert_eq!(means.len(), 4, "the last 30 frames make no whole block");
            let m = means.iter().sum::<f64>() / 4.0;
            let e = (means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / 3.0 / 4.0).sqrt();
            let mean = series.iter().sum::<f64>() / 230.0;
            assert!(p.caption.contains(&format!("{mean:.4} ± {e:.4}")), "{e} in {}", p.caption);
        }
        assert!(p.caption.contains("standard errors from blocks of 50 frames"), "{}", p.caption);
    }

    #[test]
    fn without_gs_only_clv_overlaps() {
        let d = 16;
        let ctx = context("disks", 4, d, false, vec![2]);
        let mut a = new(&ctx).unwrap();
        a.consume(&frame(0, d, identity(d), None)).unwrap();
        let out = scratch("overlaps-nogs");
        let produced = a.finish(&out, 1).unwrap();
        let stems: Vec<&String> = produced.iter().flat_map(|p| &p.figures).collect();
        assert_eq!(stems, ["fig13_clv_overlap", "fig13_clv_overlap_conjugate", "fig14_mode_overlap"]);
        assert!(!out.join("overlap_gs_clv.csv").exists());
    }

    /// Fig. 4 shows by default the paper's four kinds of vector (its j = 370, 393, 400,
    /// 700: the last unstable one before the modes, the unstable and stable mode vectors next
    /// to the null space, a stable one that is no mode), scaled; a given j replaces them.
    #[test]
    fn fig4_takes_the_papers_four_kinds_by_default() {
        let (n, d) = (10, 40);
        let fig4 = |default: bool| {
            let mut ctx = context("disks", n, d, true, vec![1, 9, 16]);
            ctx.gs = Some(testing::spectrum(n, 2));
            ctx.j_default = default;
            let mut a = new(&ctx).unwrap();
            a.consume(&frame(0, d, identity(d), Some(identity(d)))).unwrap();
            let out = scratch(&format!("overlaps-fig4-{default}"));
            let produced = a.finish(&out, 1).unwrap();
            let header = std::fs::read_to_string(out.join("overlap_clv_gs.csv")).unwrap().lines().next().unwrap().to_string();
            // One panel per j, in reading order.
            let svg = std::fs::read_to_string(out.join("fig4_clv_gs_overlap.svg")).unwrap();
            let mut panels: Vec<(usize, usize)> = (1..=d).filter_map(|j| svg.find(&format!(">j = {j}</text>")).map(|at| (at, j))).collect();
            panels.sort_unstable();
            let panels: Vec<usize> = panels.into_iter().map(|(_, j)| j).collect();
            (produced.into_iter().find(|p| p.title.contains("Fig. 4")).expect("Fig. 4").caption, header, panels)
        };
        // 2N-3 = 17 positive exponents, a T step at 16..17: the last before it is 15; the
        // paper's 93 of 393 scales to 4, whose conjugate is 37.
        let (caption, header, panels) = fig4(true);
        assert!(caption.contains("paper's j = 370, 393, 400 and 700") && caption.contains("j = 15, 17, 24, 37,") && caption.contains("step at i = 4)"), "{caption}");
        assert!(caption.contains("the stable mode vector next to the null space") && caption.contains("the mode vectors below"), "{caption}");
        assert!(header.contains("abs_v15_mean,abs_v15_std,abs_v17_mean,abs_v17_std,abs_v24_mean,abs_v24_std,abs_v37_mean"), "{header}");
        // The paper's arrangement: 370 and 700 at the top, 393 and 400 below.
        assert_eq!(panels, [15, 37, 17, 24], "{caption}");
        let (caption, header, panels) = fig4(false);
        assert!(caption.contains("the selected covariant vectors, j = 1, 9, 16,"), "{caption}");
        assert!(header.contains("abs_v1_mean,abs_v1_std,abs_v9_mean,abs_v9_std,abs_v16_mean"), "{header}");
        assert_eq!(panels, [1, 9, 16]);
    }

    /// With no mode steps to end before, a small system's last default j is its smallest
    /// positive exponent's, also Fig. 4's unstable mode vector: each is shown once.
    #[test]
    fn fig4_shows_each_index_once() {
        let (n, d) = (4, 16);
        let mut ctx = context("disks", n, d, true, vec![1]);
        ctx.j_default = true;
        let mut a = new(&ctx).unwrap();
        a.consume(&frame(0, d, identity(d), Some(identity(d)))).unwrap();
        let out = scratch("overlaps-fig4-small");
        let produced = a.finish(&out, 1).unwrap();
        // Without the forward spectrum there are no mode steps: the vectors next to the null
        // space are not called mode vectors.
        let caption = &produced.iter().find(|p| p.title.contains("Fig. 4")).expect("Fig. 4").caption;
        assert!(caption.contains("the stable vector (no mode step there in this report) next to the null space") && !caption.contains("mode vectors below"), "{caption}");
        let header = std::fs::read_to_string(out.join("overlap_clv_gs.csv")).unwrap().lines().next().unwrap().to_string();
        assert_eq!(header, "i,i_over_D,abs_v5_mean,abs_v5_std,abs_v12_mean,abs_v12_std,abs_v16_mean,abs_v16_std");
    }

    /// Fig. 14 takes the last index of each of the two positive mode steps nearest the null
    /// space when two are found, wherever they are; with fewer it keeps the paper's 2N-5 and
    /// 2N-3.
    #[test]
    fn the_mode_figure_follows_the_detected_steps() {
        let (n, d, lx, ly) = (10, 40, 14.0, 3.0);
        // Random vectors but for an LP(1,0) quadruplet at 0-based 9..12: a step of the
        // exponents there stays only if its vectors are a mode of its size.
        let mut rng = testing::Rng::new(3);
        let phase = testing::phase(n, lx, ly, &mut rng);
        let mut v = testing::random_set(d, &mut rng);
        testing::plant(&mut v, d, 9, &testing::mode_vectors(lx, ly, crate::stage::analyze::kernels::modes::ModeKind::LP, 1, &phase, 0.5, &[0, 1, 2, 3]));
        // The captions of Figs. 14 and 13, with the default j.
        let captions = |gs: crate::report::SpectrumSummary| {
            let mut ctx = testing::context("disks", n, d, lx, ly, None, false);
            ctx.options = Options { every: 1, j: vec![1], deltas: vec![1, 2] };
            ctx.gs = Some(gs);
            ctx.j_default = true;
            let mut a = new(&ctx).unwrap();
            a.consume(&Frame { phase: phase.clone(), ..frame(0, d, v.clone(), None) }).unwrap();
            let out = scratch(&format!("overlaps-steps-{}", ctx.gs.as_ref().unwrap().exponents[9]));
            let produced = a.finish(&out, 1).unwrap();
            let caption = |stem: &str| produced.iter().find(|p| p.figures.iter().any(|f| f == stem)).unwrap_or_else(|| panic!("{stem}")).caption.clone();
            (caption("fig14_mode_overlap"), caption("fig13_clv_overlap"))
        };
        // A T step at 16..17 (paper indices) only: the paper's pair. The paper's j = 1, 200,
        // 370 of 393 scale to 1, 9 and 16 of 2N-3 = 17, and 16 moves before the step.
        let one = testing::spectrum(n, 2);
        let (fig14, fig13) = captions(one.clone());
        assert!(fig14.contains("j = 15, 17 (2N-5 and 2N-3"), "{fig14}");
        assert!(fig13.contains("selected covariant vectors j = 1, 9, 15, and"), "{fig13}");
        // and a four-fold step at 10..13 besides: its end, 13, and 17; the default j end
        // before it.
        let mut two = one;
        let m = 2 * n - 3;
        for i in 9..13 {
            two.exponents[i] = 0.6;
            two.exponents[d - 1 - i] = -0.6;
        }
        let (fig14, fig13) = captions(two);
        assert!(fig14.contains("j = 13, 17 (the last index of each positive mode step"), "{fig14} (m = {m})");
        assert!(fig13.contains("selected covariant vectors j = 1, 9, and"), "{fig13}");
    }
}
