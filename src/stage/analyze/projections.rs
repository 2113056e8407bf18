//! Position and momentum content of the vectors (paper Figs. 6, 7 and 9).
//!
//! * Figs. 6, 7: eta_q(i) = <sum_n |dq_n|^2> and eta_p(i) = <sum_n |dp_n|^2>, the mean squared
//!   projections onto the configuration and momentum subspaces, for the GS vectors (Fig. 6)
//!   and the covariant vectors (Fig. 7). Symplectic symmetry: for GS vectors eta_q and eta_p
//!   are interchanged between conjugate indices i and 4N+1-i, for CLVs they agree.
//! * Fig. 9: <cos Theta>(i), the time average of the signed cosine of the angle between the
//!   2N-vectors dq and dp (see [`cos_theta`] for why signed): for GS vectors close to +1 for the
//!   smallest positive and -1 for the smallest negative exponents, for CLVs not.
//!
//! Each figure comes with an enlargement of the central (mode) part, as the paper's right
//! panels and insets. Averages run over the consumed frames (those of every m-th step, `--every`).

use super::kernels::projections::{cos_theta, eta_q_p};
use super::{save_figure, write_csv, Analysis, Context, Mean, Produced, CLV_COLOR, GS_COLOR};
use crate::error::Result;
use crate::report::plot::{Figure, Marker, Panels, PANEL};
use crate::stage::frame::Frame;
use std::path::Path;

/// eta_q or eta_p below this (|dq| or |dp| below 1e-12, the round-off of a unit vector):
/// cos Theta is undefined and the frame is left out of its average. Example: the GS null
/// vectors of a run started from G = identity are exactly position-only or momentum-only.
const ROUND_OFF_SQ: f64 = 1e-24;

/// Running averages of eta_q, eta_p and cos Theta for every vector of a set.
struct Acc {
    eta_q: Mean,
    eta_p: Mean,
    /// cos Theta is undefined when dq or dp vanishes (to round-off); such frames are left out
    /// of its average.
    cos_sum: Vec<f64>,
    cos_n: Vec<u64>,
}

impl Acc {
    fn new(k: usize) -> Self {
        Acc { eta_q: Mean::new(k), eta_p: Mean::new(k), cos_sum: vec![0.0; k], cos_n: vec![0; k] }
    }

    fn add(&mut self, vectors: &[f64], d: usize) {
        let (mut q, mut p) = (Vec::with_capacity(self.cos_n.len()), Vec::with_capacity(self.cos_n.len()));
        for (j, (s, n)) in self.cos_sum.iter_mut().zip(self.cos_n.iter_mut()).enumerate() {
            let x = &vectors[j * d..(j + 1) * d];
            let (eq, ep) = eta_q_p(x);
            q.push(eq);
            p.push(ep);
            // Below round-off of a unit vector (|dq| or |dp| < 1e-12) the angle is noise.
            let c = if eq.min(ep) < ROUND_OFF_SQ { f64::NAN } else { cos_theta(x) };
            if c.is_finite() {
                *s += c;
                *n += 1;
            }
        }
        self.eta_q.add(q);
        self.eta_p.add(p);
    }

    fn cos(&self) -> Vec<f64> {
        self.cos_sum.iter().zip(&self.cos_n).map(|(s, &n)| if n == 0 { f64::NAN } else { s / n as f64 }).collect()
    }
}

pub struct Projections {
    ctx: Context,
    clv: Acc,
    gs: Option<Acc>,
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    (missing == super::Missing::GsVectors && ctx.is_disks()).then_some("Fig. 6 and the GS curve of Fig. 9")
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    (ctx.is_disks() && ctx.d.is_multiple_of(4) && ctx.k > 0).then(|| {
        Box::new(Projections { ctx: ctx.clone(), clv: Acc::new(ctx.k), gs: ctx.with_gs.then(|| Acc::new(ctx.k)) }) as Box<dyn Analysis>
    })
}

/// Largest |a_i - b_(4N+1-i)| over i: the conjugate symmetry of a pair of spectra.
fn conjugate_asymmetry(a: &[f64], b: &[f64]) -> f64 {
    let d = a.len();
    (0..d).map(|i| (a[i] - b[d - 1 - i]).abs()).fold(0.0, f64::max)
}

impl Analysis for Projections {
    fn name(&self) -> &'static str {
        "projections"
    }

    fn consume(&mut self, frame: &Frame) -> Result<()> {
        self.clv.add(&frame.v, frame.d);
        if let (Some(acc), Some(g)) = (self.gs.as_mut(), frame.g.as_ref()) {
            acc.add(g, frame.d);
        }
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let ctx = &self.ctx;
        let k = ctx.k;
        let nan = vec![f64::NAN; k];
        let stats = |a: Option<&Acc>| match a {
            Some(a) => (a.eta_q.mean(), a.eta_p.mean(), a.eta_q.std(), a.cos()),
            None => (nan.clone(), nan.clone(), nan.clone(), nan.clone()),
        };
        let (q_gs, p_gs, qs_gs, c_gs) = stats(self.gs.as_ref());
        let (q_cv, p_cv, qs_cv, c_cv) = stats(Some(&self.clv));
        write_csv(
            &out.join("projections.csv"),
            &["i", "i_over_D", "eta_q_gs", "eta_p_gs", "eta_q_gs_std", "cos_theta_gs", "eta_q_clv", "eta_p_clv", "eta_q_clv_std", "cos_theta_clv"],
            (0..k).map(|i| vec![(i + 1) as f64, ctx.reduced(i), q_gs[i], p_gs[i], qs_gs[i], c_gs[i], q_cv[i], p_cv[i], qs_cv[i], c_cv[i]]),
        )?;
        let idx: Vec<f64> = (1..=k).map(|i| i as f64).collect();
        let central = ctx.central_range();
        let full = k == ctx.d;
        let avg = ctx.averaged_over(frames);
        let second = central.map(|(a, b)| format!("; the second plot enlarges the central part, i = {}..{}", a + 1, b + 1)).unwrap_or_default();
        let tables = vec!["projections.csv".to_string()];

        // One figure and its central enlargement (Figs. 6, 7), eta_q in green and eta_p in
        // black as in the paper: blue and vermillion mean GS and CLV in the other figures.
        let plot = |stem: &str, title: &str, ylabel: &str, curves: &[(&str, &[f64])]| -> Result<Vec<String>> {
            let mut stems = Vec::new();
            let mut parts = vec![(stem.to_string(), title.to_string(), 0, k - 1, Marker::Line)];
            if let Some((a, b)) = central {
                parts.push((format!("{stem}_center"), format!("{title}: central part"), a, b, Marker::LinePoints));
            }
            for (s, t, a, b, marker) in parts {
                let mut fig = Figure::new(&t).x_label("i").y_label(ylabel);
                for ((label, y), color) in curves.iter().zip([2, 6]) {
                    fig.series(label, &idx[a..=b], &y[a..=b], marker).color(color);
                }
                save_figure(&fig, out, &s)?;
                stems.push(s);
            }
            Ok(stems)
        };

        let mut produced = Vec::new();
        if self.gs.is_some() {
            let figures = plot("fig6_eta_gs", "Gram-Schmidt vectors: η_q and η_p", "η", &[("η_q (GS)", &q_gs), ("η_p (GS)", &p_gs)])?;
            let sym = if full { format!(" Conjugate symmetry: max_i |η_q(i) - η_p(4N+1-i)| = {:.3e}.", conjugate_asymmetry(&q_gs, &p_gs)) } else { String::new() };
            produced.push(Produced {
                title: "Position and momentum content of the GS vectors (Fig. 6)".into(),
                caption: format!(
                    "η_q = <Σ_n |δq_n|^2> and η_p = <Σ_n |δp_n|^2> for the Gram-Schmidt vectors g^i against i, {avg}{second}. For GS vectors η_q and η_p are interchanged between i and 4N+1-i.{sym}"
                ),
                figures,
                tables: tables.clone(),
            });
        }
        let figures = plot("fig7_eta_clv", "Covariant vectors: η_q and η_p", "η", &[("η_q (CLV)", &q_cv), ("η_p (CLV)", &p_cv)])?;
        let sym = if full { format!(" Conjugate symmetry: max_i |η_q(i) - η_q(4N+1-i)| = {:.3e}.", conjugate_asymmetry(&q_cv, &q_cv)) } else { String::new() };
        // The last three null CLVs are sheared towards the position shifts (Figs. 2, 3).
        let shear = match self.ctx.null_shear() {
            Some(r) if r.end <= k => format!(
                " In the null space, i = {}..{}, η_q = 1: the first three covariant vectors are the position shifts E_k themselves, and the last three, i = {}..{} (η_q = {}), are E_(k+3) - s E_k after a backward time s, turned towards them as s grows, where those GS vectors are the momentum shifts E_(k+3): a property of the finite window, not of the dynamics (see Figs. 2 and 3).",
                r.start - 2,
                r.end,
                r.start + 1,
                r.end,
                r.clone().map(|i| format!("{:.4}", q_cv[i])).collect::<Vec<_>>().join(", ")
            ),
            _ => String::new(),
        };
        produced.push(Produced {
            title: "Position and momentum content of the covariant vectors (Fig. 7)".into(),
            caption: format!(
                "η_q = <Σ_n |δq_n|^2> and η_p = <Σ_n |δp_n|^2> for the covariant vectors v^i against i, {avg}{second}. For covariant vectors η_q(i) = η_q(4N+1-i).{sym}{shear}"
            ),
            figures,
            tables: tables.clone(),
        });
        let mut curves: Vec<(&str, &[f64], usize)> = Vec::new();
        if self.gs.is_some() {
            curves.push(("GS vectors", &c_gs, GS_COLOR));
        }
        curves.push(("covariant vectors", &c_cv, CLV_COLOR));
        let figures = fig9(&idx, &curves, central.zip(ctx.null_space()), out)?;
        let insets = match (central, ctx.null_space()) {
            (Some((a, b)), Some(null)) => format!(
                "; the second plot magnifies the mode-carrying region on either side of the null space, as the paper's insets, each panel on its own scale: i = {}..{} and {}..{} (the null space, where cos Θ is -1 or undefined, is only in the first plot, of every i)",
                a + 1,
                null.start,
                null.end + 1,
                b + 1
            ),
            _ => String::new(),
        };
        produced.push(Produced {
            title: "Angle between position and momentum perturbations (Fig. 9)".into(),
            caption: format!(
                "Time average of the signed cos Θ = δq · δp / (|δq| |δp|) of each vector against i{}, {avg}{insets}. For GS vectors it approaches +1 (-1) for the smallest positive (negative) exponents; for covariant vectors it does not.{}",
                if self.gs.is_some() { ", GS (blue) and covariant vectors (vermillion)" } else { ", covariant vectors" },
                match ctx.null_shear().filter(|_| full) {
                    Some(shear) => format!(
                        " In the null space, the covariant vectors i = {}..{} are E_(k+3) - s E_k after a backward time s (see Fig. 2), with δq = -s δp: their cos Θ = -1 is that finite-window shear, not dynamics; \
                         the null-space GS vectors are pure position or pure momentum directions, for which cos Θ is undefined (no point, nan in the table).",
                        shear.start + 1,
                        shear.end
                    ),
                    None => String::new(),
                }
            ),
            figures,
            tables,
        });
        Ok(produced)
    }
}

/// Fig. 9: <cos Θ> against i over the whole spectrum, and where the spectrum has its
/// central part and null space (`zoom`: the central range and the null space, 0-based), the
/// paper's insets: the mode-carrying region on either side of the null space, i = a..2N-3
/// and 2N+4..b, one panel each on its own y scale (cos Θ is near +1 on one side and -1 on the
/// other: one scale for both would show neither).
fn fig9(idx: &[f64], curves: &[(&str, &[f64], usize)], zoom: Option<((usize, usize), std::ops::Range<usize>)>, out: &Path) -> Result<Vec<String>> {
    let mut fig = Figure::new("<cos Θ> between δq and δp").x_label("i").y_label("<cos Θ>");
    for &(label, y, color) in curves {
        fig.series(label, idx, y, Marker::Line).color(color);
    }
    fig.hline(0.0);
    save_figure(&fig, out, "fig9_cos_theta")?;
    let mut stems = vec!["fig9_cos_theta".to_string()];
    if let Some(((a, b), null)) = zoom {
        let mut panels = Panels::new("<cos Θ>: the mode-carrying region, magnified", 2);
        for (side, lo, hi) in [("unstable", a, null.start - 1), ("stable", null.end, b)] {
            let mut fig = Figure::new(&format!("{side} side, i = {}..{}", lo + 1, hi + 1)).size(PANEL.0, PANEL.1).x_label("i").y_label("<cos Θ>");
            for &(label, y, color) in curves {
                fig.series(label, &idx[lo..=hi], &y[lo..=hi], Marker::LinePoints).color(color);
            }
            panels.push(fig);
        }
        save_figure(&panels, out, "fig9_cos_theta_center")?;
        stems.push("fig9_cos_theta_center".into());
    }
    Ok(stems)
}

#[cfg(test)]
mod tests {
    use super::*;
    use super::super::testing::{self, column, out_dir as scratch, read_table as read_csv};

    fn context(n: usize, with_gs: bool) -> Context {
        testing::context("disks", n, 4 * n, 5.0, 5.0, None, with_gs)
    }

    /// A unit vector of dimension d = 4N with dq = a u and dp = b w (u, w unit 2N-vectors).
    fn vector(d: usize, a: f64, u: &[f64], b: f64, w: &[f64]) -> Vec<f64> {
        let norm = (a * a + b * b).sqrt();
        u.iter().map(|x| a * x / norm).chain(w.iter().map(|x| b * x / norm)).take(d).collect()
    }

    #[test]
    fn constructed_vectors_give_known_eta_and_cos() {
        let n = 3;
        let d = 4 * n;
        let h = 2 * n;
        let u: Vec<f64> = (0..h).map(|i| if i == 0 { 1.0 } else { 0.0 }).collect();
        let w: Vec<f64> = (0..h).map(|i| if i == 1 { 1.0 } else { 0.0 }).collect();
        let minus_u: Vec<f64> = u.iter().map(|x| -x).collect();
        let theta: f64 = 0.7; // dp at angle theta to dq
        let tilted: Vec<f64> = (0..h).map(|i| theta.cos() * u[i] + theta.sin() * w[i]).collect();
        // Column j of every frame (the rest are copies of column 0):
        //  0: pure dq                  eta_q = 1, cos NaN (left out)
        //  1: dq = dp                  eta_q = 1/2, cos = 1
        //  2: dp = -dq / 2 in frame 1, dp = +dq / 2 in frame 2: eta_q = 0.8, <cos> = 0
        //  3: |dq| = 2 |dp| at angle theta: eta_q = 0.8, cos = cos theta
        //  4: pure dq in frame 1, dq = dp in frame 2: eta_q = 3/4, <cos> = 1 (NaN left out)
        //  5: dp of round-off size 1e-14 |dq|: cos undefined (NaN), eta_q = 1
        let make = |second: bool| -> Vec<f64> {
            let mut cols = vec![
                vector(d, 1.0, &u, 0.0, &w),
                vector(d, 1.0, &u, 1.0, &u),
                vector(d, 2.0, &u, 1.0, if second { &u } else { &minus_u }),
                vector(d, 2.0, &u, 1.0, &tilted),
                if second { vector(d, 1.0, &u, 1.0, &u) } else { vector(d, 1.0, &u, 0.0, &w) },
                vector(d, 1.0, &u, 1e-14, &u),
            ];
            while cols.len() < d {
                cols.push(cols[0].clone());
            }
            cols.concat()
        };
        let ctx = context(n, true);
        let mut a = new(&ctx).unwrap();
        for (s, second) in [(2u64, false), (1, true)] {
            let v = make(second);
            // GS vectors: CLVs with dq and dp swapped, so eta_q^GS = eta_p^CLV
            let g: Vec<f64> = v.chunks(d).flat_map(|c| c[h..].iter().chain(&c[..h]).copied().collect::<Vec<_>>()).collect();
            a.consume(&Frame { step: s, time: s as f64, d, k: d, phase: vec![0.0; d], v, local: vec![0.0; d], gs_local: Vec::new(), g: Some(g) }).unwrap();
        }
        let out = scratch("known");
        let produced = a.finish(&out, 2).unwrap();
        let stems: Vec<&String> = produced.iter().flat_map(|p| &p.figures).collect();
        assert_eq!(stems.len(), 6, "{stems:?}");
        assert!(produced[..2].iter().all(|p| p.caption.contains("the second plot enlarges the central part, i = ")));
        // Fig. 9's insets: the mode-carrying region on either side of the null space (N = 3:
        // i = 4..9), one panel each.
        assert!(produced[2].caption.contains("as the paper's insets, each panel on its own scale: i = 1..3 and 10..12"), "{}", produced[2].caption);
        let svg = std::fs::read_to_string(out.join("fig9_cos_theta_center.svg")).unwrap();
        assert!(svg.contains(">unstable side, i = 1..3</text>") && svg.contains(">stable side, i = 10..12</text>"), "{svg}");
        let t = read_csv(&out.join("projections.csv"));
        let (q, p, c) = (column(&t, "eta_q_clv"), column(&t, "eta_p_clv"), column(&t, "cos_theta_clv"));
        let want_q = [1.0, 0.5, 0.8, 0.8, 0.75, 1.0];
        let want_c = [f64::NAN, 1.0, 0.0, theta.cos(), 1.0, f64::NAN];
        for j in 0..6 {
            assert!((q[j] - want_q[j]).abs() < 1e-15, "eta_q[{j}] = {}", q[j]);
            assert!((q[j] + p[j] - 1.0).abs() < 1e-15);
            if want_c[j].is_nan() {
                assert!(c[j].is_nan(), "cos[{j}] = {}", c[j]);
            } else {
                assert!((c[j] - want_c[j]).abs() < 1e-15, "cos[{j}] = {} want {}", c[j], want_c[j]);
            }
        }
        // eta_q sample std over the two frames: 0 for column 0, |1 - 1/2| / sqrt(2) for column 4 (eta_q = 1, then 1/2)
        let s = column(&t, "eta_q_clv_std");
        assert!(s[0].abs() < 1e-15 && (s[4] - 0.5 / 2f64.sqrt()).abs() < 1e-15, "{s:?}");
        let (qg, pg) = (column(&t, "eta_q_gs"), column(&t, "eta_p_gs"));
        for j in 0..5 {
            assert!((qg[j] - p[j]).abs() < 1e-15 && (pg[j] - q[j]).abs() < 1e-15);
        }
        // swapping dq and dp keeps the signed cosine
        assert!((column(&t, "cos_theta_gs")[3] - theta.cos()).abs() < 1e-15);
    }

    #[test]
    fn only_for_disks_and_clv_only_without_gs() {
        let mut ctx = context(2, false);
        ctx.system = "henon".into();
        assert!(new(&ctx).is_none());
        let ctx = context(2, false);
        let mut a = new(&ctx).unwrap();
        let d = 8;
        let v: Vec<f64> = (0..d * d).map(|x| if x % (d + 1) == 0 { 1.0 } else { 0.0 }).collect();
        a.consume(&Frame { step: 0, time: 0.0, d, k: d, phase: vec![0.0; d], v, local: vec![0.0; d], gs_local: Vec::new(), g: None }).unwrap();
        let out = scratch("projections-nogs");
        let produced = a.finish(&out, 1).unwrap();
        assert_eq!(produced.len(), 2, "Figs. 7 and 9 only");
        let t = read_csv(&out.join("projections.csv"));
        assert!(column(&t, "eta_q_gs").iter().all(|x| x.is_nan()));
        // unit vectors: the first 2N are pure dq
        let q = column(&t, "eta_q_clv");
        assert!(q[..4].iter().all(|&x| x == 1.0) && q[4..].iter().all(|&x| x == 0.0));
        // With k < D there is no central part to enlarge, and no caption says there is.
        let mut ctx = context(2, false);
        ctx.k = 4;
        let mut a = new(&ctx).unwrap();
        a.consume(&Frame { step: 0, time: 0.0, d, k: 4, phase: vec![0.0; d], v: (0..d * 4).map(|x| if x % (d + 1) == 0 { 1.0 } else { 0.0 }).collect(), local: vec![0.0; 4], gs_local: Vec::new(), g: None }).unwrap();
        let produced = a.finish(&scratch("projections-k4"), 1).unwrap();
        assert!(produced.iter().all(|p| p.figures.len() == 1 && !p.caption.contains("second plot")), "{produced:?}");
    }

    #[test]
    fn asymmetry_measure() {
        assert_eq!(conjugate_asymmetry(&[0.1, 0.5, 0.9], &[0.9, 0.5, 0.1]), 0.0);
        assert!((conjugate_asymmetry(&[0.1, 0.5, 0.9], &[0.9, 0.4, 0.1]) - 0.1).abs() < 1e-15);
    }
}
