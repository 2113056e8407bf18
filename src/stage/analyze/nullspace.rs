//! The null space (paper Sec. 5.4, Tables I and II).
//!
//! * Tables I and II: the projection matrices alpha_{i,k} = g^i . e_k (GS vectors) and
//!   beta_{i,k} = v^i . e_k (CLVs) of the six null-space vectors i = 2N-2..2N+3 onto the
//!   natural basis e_1..e_6, at one time: the earliest consumed frame, which plays the role of
//!   the paper's t_0 (frames arrive newest first, so this is the last one consumed).
//! * The time series of the largest principal angle between span{v^(2N-2)..v^(2N+3)} and
//!   span{e_1..e_6} (likewise for the GS vectors, and between the two null spans), which must
//!   vanish up to round-off, and of the row norms sqrt(sum_k beta_{i,k}^2), which must be 1.

use super::kernels::angles::max_principal_angle;
use super::kernels::nullspace::{null_projections, null_space_angle};
use super::{save_figure, write_csv, Analysis, Context, Produced};
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::stage::frame::Frame;
use serde::Serialize;
use std::path::Path;

/// The projection matrices at one time.
#[derive(Serialize)]
struct Snapshot {
    step: u64,
    time: f64,
    /// beta_{i,k}, rows i = 2N-2..2N+3.
    beta: Vec<[f64; 6]>,
    /// alpha_{i,k}, with GS vectors.
    alpha: Option<Vec<[f64; 6]>>,
}

/// The null-space check at one frame.
struct Row {
    step: u64,
    time: f64,
    angle_clv: f64,
    angle_gs: f64,
    /// Largest principal angle between the GS and the CLV null spans.
    angle_gs_clv: f64,
    norms_beta: [f64; 6],
    norms_alpha: [f64; 6],
}

pub struct NullSpace {
    ctx: Context,
    /// 0-based index of the first null vector, 2N-3 (the paper's 2N-2).
    first: usize,
    table: Option<Snapshot>,
    rows: Vec<Row>,
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    match missing {
        super::Missing::GsVectors => ctx.null_space().is_some().then_some("Table I"),
        super::Missing::AllVectors => (ctx.is_disks() && ctx.null_space().is_none()).then_some("the null space, Tables I and II"),
        super::Missing::ConsecutiveFrames => None,
    }
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    let null = ctx.null_space().filter(|_| ctx.d == 4 * ctx.n)?;
    Some(Box::new(NullSpace { ctx: ctx.clone(), first: null.start, table: None, rows: Vec::new() }))
}

fn row_norms(m: &[[f64; 6]]) -> [f64; 6] {
    std::array::from_fn(|i| m[i].iter().map(|x| x * x).sum::<f64>().sqrt())
}

/// log10 of a non-negative deviation, with exact zeros shown at 1e-18.
fn log10_floor(x: f64) -> f64 {
    x.max(1e-18).log10()
}

impl Analysis for NullSpace {
    fn name(&self) -> &'static str {
        "nullspace"
    }

    fn consume(&mut self, frame: &Frame) -> Result<()> {
        let d = frame.d;
        let (a, b) = (self.first * d, (self.first + 6) * d);
        let six_v = &frame.v[a..b];
        let beta = null_projections(six_v, &frame.phase);
        let angle_clv = null_space_angle(six_v, &frame.phase);
        let (alpha, angle_gs, angle_gs_clv) = match frame.g.as_ref() {
            Some(g) => {
                let six_g = &g[a..b];
                (Some(null_projections(six_g, &frame.phase)), null_space_angle(six_g, &frame.phase), max_principal_angle(six_g, six_v, d))
            }
            None => (None, f64::NAN, f64::NAN),
        };
        self.rows.push(Row {
            step: frame.step,
            time: frame.time,
            angle_clv,
            angle_gs,
            angle_gs_clv,
            norms_beta: row_norms(&beta),
            norms_alpha: alpha.as_deref().map_or([f64::NAN; 6], row_norms),
        });
        if self.table.as_ref().is_none_or(|t| frame.step < t.step) {
            self.table = Some(Snapshot { step: frame.step, time: frame.time, beta, alpha });
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let Some(table) = self.table.take() else {
            return Ok(Vec::new());
        };
        let n = self.ctx.n;
        let first = self.first;
        let with_gs = table.alpha.is_some();
        let matrix_csv = |name: &str, m: &[[f64; 6]]| {
            write_csv(
                &out.join(name),
                &["i", "e1", "e2", "e3", "e4", "e5", "e6", "row_norm"],
                m.iter().enumerate().map(|(r, row)| {
                    let mut x = vec![(first + r + 1) as f64];
                    x.extend(row);
                    x.push(row.iter().map(|c| c * c).sum::<f64>().sqrt());
                    x
                }),
            )
        };
        matrix_csv("nullspace_beta.csv", &table.beta)?;
        let mut tables = vec!["nullspace_beta.csv".to_string()];
        if let Some(alpha) = &table.alpha {
            matrix_csv("nullspace_alpha.csv", alpha)?;
            tables.push("nullspace_alpha.csv".into());
        }
        let json = serde_json::json!({
            "n": n,
            "indices": (first + 1..=first + 6).collect::<Vec<_>>(),
            "step": table.step,
            "time": table.time,
            "note": "alpha[r][k] = g^i . e_(k+1), beta[r][k] = v^i . e_(k+1) for i = indices[r] (paper Tables I and II), at the earliest frame consumed",
            "alpha": table.alpha,
            "beta": table.beta,
        });
        super::write_report_file(&out.join("nullspace_tables.json"), &serde_json::to_vec_pretty(&json).unwrap_or_default())?;
        tables.push("nullspace_tables.json".into());

        self.rows.sort_by_key(|r| r.step);
        let mut header: Vec<String> = ["step", "time", "angle_clv", "angle_gs", "angle_gs_clv"].map(String::from).to_vec();
        header.extend((0..6).map(|r| format!("norm_beta_{}", first + r + 1)));
        header.extend((0..6).map(|r| format!("norm_alpha_{}", first + r + 1)));
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        write_csv(
            &out.join("nullspace_series.csv"),
            &h,
            self.rows.iter().map(|r| {
                let mut x = vec![r.step as f64, r.time, r.angle_clv, r.angle_gs, r.angle_gs_clv];
                x.extend(r.norms_beta);
                x.extend(r.norms_alpha);
                x
            }),
        )?;
        tables.push("nullspace_series.csv".into());

        let t: Vec<f64> = self.rows.iter().map(|r| r.time).collect();
        let dev = |norms: &[f64; 6]| norms.iter().map(|x| (x - 1.0).abs()).fold(0.0, f64::max);
        let mut fig = Figure::new("Null space: deviation from span{e_1..e_6}").x_label("t").y_label("log10 angle (rad) or |1 - norm|");
        let max_angle = |f: fn(&Row) -> f64| self.rows.iter().map(f).fold(0.0, f64::max);
        fig.series("CLV: largest principal angle", &t, &self.rows.iter().map(|r| log10_floor(r.angle_clv)).collect::<Vec<_>>(), Marker::Line);
        fig.series("CLV: max |1 - row norm of β|", &t, &self.rows.iter().map(|r| log10_floor(dev(&r.norms_beta))).collect::<Vec<_>>(), Marker::Line);
        if with_gs {
            fig.series("GS: largest principal angle", &t, &self.rows.iter().map(|r| log10_floor(r.angle_gs)).collect::<Vec<_>>(), Marker::Line);
            fig.series("GS: max |1 - row norm of α|", &t, &self.rows.iter().map(|r| log10_floor(dev(&r.norms_alpha))).collect::<Vec<_>>(), Marker::Line);
            fig.series("GS vs CLV null spans: largest angle", &t, &self.rows.iter().map(|r| log10_floor(r.angle_gs_clv)).collect::<Vec<_>>(), Marker::Line);
        }
        save_figure(&fig, out, "nullspace_angle")?;

        let fmt_row = |m: &[[f64; 6]], r: usize| m[r].iter().map(|x| format!("{x:.3e}")).collect::<Vec<_>>().join(" ");
        let mut caption = format!(
            "Projections of the six null-space vectors i = {}..{} (2N-2..2N+3) onto e_1..e_6 at the earliest consumed frame (step {}, t = {}; the paper's t_0): β_(i,k) = v^i · e_k (Table II){}. Row i = {}: β = [{}]{}. The figure shows, for each of the {frames} consumed frames, log10 of the largest principal angle between span{{v^(2N-2)..v^(2N+3)}} and span{{e_1..e_6}}{} and of the largest deviation of a row norm from 1; both vanish up to round-off when the null vectors lie in the null space. The CLV angle sits above round-off because the six null CLVs are nearly linearly dependent: backward iteration turns e_(k+3) into e_(k+3) - T e_k, so the last three collapse onto span{{e_1, e_2, e_3}} like 1/T and the orthonormalisation amplifies round-off by about T. Maxima over time: CLV angle {:.2e}",
            first + 1,
            first + 6,
            table.step,
            format!("{:.6}", table.time).trim_end_matches('0').trim_end_matches('.'),
            if with_gs { " and α_(i,k) = g^i · e_k (Table I)" } else { "" },
            first + 1,
            fmt_row(&table.beta, 0),
            table.alpha.as_ref().map(|a| format!(", α = [{}]", fmt_row(a, 0))).unwrap_or_default(),
            if with_gs { " (likewise for the GS vectors, and between the two null spans)" } else { "" },
            max_angle(|r| r.angle_clv),
        );
        if with_gs {
            caption += &format!(
                ", GS angle {:.2e}, GS-CLV angle {:.2e} (the GS-CLV curve, dashed, runs on the CLV one wherever the GS null span is span{{e_1..e_6}} far more closely than the CLV one)",
                max_angle(|r| r.angle_gs),
                max_angle(|r| r.angle_gs_clv)
            );
        }
        caption += ".";
        if let Some(alpha) = &table.alpha {
            // The paper's Table I has entries of about 1e-6 here, "related to the duration of
            // the relaxation phase".
            let corner = alpha[..3].iter().flat_map(|row| row[3..].iter()).fold(0.0f64, |m, x| m.max(x.abs()));
            caption += &format!(" The entries α_(i,4..6) of rows i = {}..{}, which the paper prints at about 1e-6, are at most {corner:.1e} here", first + 1, first + 3);
            caption += if corner < 1e-10 { ": round-off, with the forward pass's start G_0 = identity (an independent implementation finds the same)." } else { "." };
        }
        Ok(vec![Produced { title: "Null space (Tables I, II)".into(), caption, figures: vec!["nullspace_angle".into()], tables }])
    }
}

#[cfg(test)]
mod tests {
    use super::super::kernels::nullspace::null_vectors;
    use super::*;
    use super::super::testing::{self, out_dir as scratch};

    fn context(n: usize, with_gs: bool) -> Context {
        testing::context("disks", n, 4 * n, 5.0, 5.0, None, with_gs)
    }

    /// A phase point of n disks with zero total momentum (so e_1..e_6 are orthonormal).
    fn phase(n: usize, seed: u64) -> Vec<f64> {
        let mut g = vec![0.0; 4 * n];
        let mut x = seed as f64 + 0.5;
        let mut next = || {
            x = (x * 7.3 + 0.37).fract();
            x - 0.5
        };
        for x in g[..2 * n].iter_mut() {
            *x = 5.0 * (next() + 0.5);
        }
        for x in g[2 * n..].iter_mut() {
            *x = next();
        }
        for c in 0..2 {
            let mean: f64 = (0..n).map(|i| g[2 * n + 2 * i + c]).sum::<f64>() / n as f64;
            for i in 0..n {
                g[2 * n + 2 * i + c] -= mean;
            }
        }
        g
    }

    /// Vectors: unit vectors e_r of the standard basis outside the null block, the columns of
    /// `null` (6 vectors) at 2N-3..2N+2.
    fn frame(step: u64, n: usize, phase: Vec<f64>, null: &[f64], gs_null: Option<&[f64]>) -> Frame {
        let d = 4 * n;
        let first = 2 * n - 3;
        let build = |null: &[f64]| -> Vec<f64> {
            let mut v = vec![0.0; d * d];
            for j in 0..d {
                if j >= first && j < first + 6 {
                    v[j * d..(j + 1) * d].copy_from_slice(&null[(j - first) * d..(j - first + 1) * d]);
                } else {
                    v[j * d + j] = 1.0;
                }
            }
            v
        };
        Frame { step, time: 0.5 * step as f64, d, k: d, phase, v: build(null), local: vec![0.0; d], gs_local: Vec::new(), g: gs_null.map(build) }
    }

    #[test]
    fn exact_null_vectors_give_identity_and_zero_angle() {
        let n = 5;
        let d = 4 * n;
        let mut a = new(&context(n, true)).unwrap();
        // Frames newest first: steps 12, 11, 10. GS null vectors = e_1..e_6 in reverse order
        // and with signs: alpha is an anti-diagonal pattern of +-1.
        for step in [12u64, 11, 10] {
            let p = phase(n, step);
            let e = null_vectors(&p);
            let mut rev = vec![0.0; 6 * d];
            for c in 0..6 {
                let s = if c % 2 == 0 { 1.0 } else { -1.0 };
                for r in 0..d {
                    rev[c * d + r] = s * e[(5 - c) * d + r];
                }
            }
            a.consume(&frame(step, n, p, &e, Some(&rev))).unwrap();
        }
        let out = scratch("exact");
        let produced = a.finish(&out, 3).unwrap();
        assert_eq!(produced[0].figures, ["nullspace_angle"]);
        assert!(produced[0].caption.contains("step 10"), "{}", produced[0].caption);
        // The reversed GS vectors put e_6, e_5, e_4 into rows 2N-2..2N: not the paper's 1e-6.
        assert!(produced[0].caption.contains("which the paper prints at about 1e-6, are at most 1.0e0 here.") && !produced[0].caption.contains("round-off, with"), "{}", produced[0].caption);
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("nullspace_tables.json")).unwrap()).unwrap();
        assert_eq!(json["step"], 10, "the table is taken at the earliest frame");
        assert_eq!(json["indices"], serde_json::json!([8, 9, 10, 11, 12, 13]));
        let beta: Vec<Vec<f64>> = serde_json::from_value(json["beta"].clone()).unwrap();
        let alpha: Vec<Vec<f64>> = serde_json::from_value(json["alpha"].clone()).unwrap();
        for r in 0..6 {
            for c in 0..6 {
                assert!((beta[r][c] - if r == c { 1.0 } else { 0.0 }).abs() < 1e-14, "beta[{r}][{c}] = {}", beta[r][c]);
                let s = if r % 2 == 0 { 1.0 } else { -1.0 };
                assert!((alpha[r][c] - if r + c == 5 { s } else { 0.0 }).abs() < 1e-14, "alpha[{r}][{c}] = {}", alpha[r][c]);
            }
        }
        let series = std::fs::read_to_string(out.join("nullspace_series.csv")).unwrap();
        let rows: Vec<Vec<f64>> = series.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
        assert_eq!(rows.iter().map(|r| r[0]).collect::<Vec<_>>(), [10.0, 11.0, 12.0], "sorted by step");
        for r in &rows {
            assert!(r[2] < 1e-12 && r[3] < 1e-12 && r[4] < 1e-12, "angles {:?}", &r[2..5]);
            assert!(r[5..17].iter().all(|x| (x - 1.0).abs() < 1e-14));
        }
        let beta_csv = std::fs::read_to_string(out.join("nullspace_beta.csv")).unwrap();
        assert!(beta_csv.starts_with("i,e1,e2,e3,e4,e5,e6,row_norm\n8,"), "{beta_csv}");
        let first: Vec<f64> = beta_csv.lines().nth(1).unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        assert!((first[1] - 1.0).abs() < 1e-14 && (first[7] - 1.0).abs() < 1e-14, "{first:?}");
    }

    #[test]
    fn gs_rows_in_the_span_of_e1_to_e3_are_called_round_off() {
        let n = 4;
        let p = phase(n, 5);
        let e = null_vectors(&p);
        let mut a = new(&context(n, true)).unwrap();
        a.consume(&frame(3, n, p, &e, Some(&e))).unwrap();
        let out = scratch("corner");
        let caption = a.finish(&out, 1).unwrap().remove(0).caption;
        assert!(caption.contains("are at most 0.0e0 here: round-off, with the forward pass's start G_0 = identity"), "{caption}");
    }

    #[test]
    fn a_vector_outside_the_null_space_is_seen() {
        let n = 4;
        let d = 4 * n;
        let p = phase(n, 3);
        let mut six = null_vectors(&p);
        // tilt the fourth null vector by angle a towards a direction orthogonal to N
        let e = six.clone();
        let mut x: Vec<f64> = (0..d).map(|r| ((r * 13 % 7) as f64) - 3.0).collect();
        for c in 0..6 {
            let col = &e[c * d..(c + 1) * d];
            let dot: f64 = x.iter().zip(col).map(|(a, b)| a * b).sum();
            x.iter_mut().zip(col).for_each(|(a, b)| *a -= dot * b);
        }
        let nx = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        let a: f64 = 1e-3;
        for r in 0..d {
            six[3 * d + r] = a.cos() * e[3 * d + r] + a.sin() * x[r] / nx;
        }
        let mut an = new(&context(n, false)).unwrap();
        an.consume(&frame(7, n, p, &six, None)).unwrap();
        let out = scratch("tilt");
        an.finish(&out, 1).unwrap();
        let series = std::fs::read_to_string(out.join("nullspace_series.csv")).unwrap();
        let row: Vec<f64> = series.lines().nth(1).unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        assert!((row[2] - a).abs() < 1e-12, "angle {}", row[2]);
        assert!(row[3].is_nan(), "no GS vectors");
        assert!((row[5 + 3] - a.cos()).abs() < 1e-12, "row norm of the tilted vector {}", row[8]);
        assert!(!out.join("nullspace_alpha.csv").exists());
    }

    #[test]
    fn not_for_maps_or_partial_sets() {
        let mut ctx = context(4, false);
        ctx.k = 10; // fewer than 2N+3 = 11 vectors
        assert!(new(&ctx).is_none());
        let mut ctx = context(4, false);
        ctx.system = "henon".into();
        assert!(new(&ctx).is_none());
    }
}
