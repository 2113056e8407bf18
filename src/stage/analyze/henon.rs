//! The Henon map picture (paper Sec. 4, Fig. 1): the attractor, a finite stretch of the
//! stable manifold, and the GS and covariant vectors at one point "0".
//!
//! * Attractor: the phase points of all frames.
//! * Point 0: among the middle half of the frames (in time) and near the middle of the
//!   picture (|x| < 1), the one where v^1 and v^2 are closest to 45 degrees apart: near
//!   homoclinic tangencies they nearly coincide, and where they are orthogonal g^2 = v^2, so
//!   either extreme would hide what the figure shows (CLVs are not GS vectors).
//! * Stable manifold through point 0: a short straight segment of half-length eps along
//!   the stable covariant vector v^2 at the point x_n reached n steps after point 0 (its local
//!   stable manifold, to first order), mapped n times backward with the inverse map
//!   x = y', y = (x' - a + y'^2)/b. Backward iteration stretches the stable direction by
//!   about e^{|lambda_2|} = 5 per step and contracts the error of the straight segment, so the
//!   image is a long piece of W^s(point 0) through point 0, tangent to v^2 there. The segment
//!   is refined adaptively (midpoints inserted where images are far apart) and eps is doubled
//!   until the piece inside the plotting box has a sensible length; points leaving the box
//!   are dropped (the Henon stable manifold is unbounded).
//! * At point 0: the CLVs v^1 (along the attractor, which is the unstable manifold) and v^2
//!   (along the stable manifold), and the orthogonal GS vectors g^1 = v^1, g^2 when the
//!   frames carry them.

use super::{save_figure, write_csv, write_text_csv, Analysis, Context, Produced};
use crate::config::SystemConfig;
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::stage::frame::Frame;
use crate::system::henon::Henon;
use std::path::Path;

/// Backward iterations from the base point of the stable segment to point 0.
pub const BACKWARD_STEPS: usize = 8;
/// Cap on the number of points of the refined stable-manifold curve.
const MAX_POINTS: usize = 40_000;

struct Point {
    step: u64,
    x: [f64; 2],
    /// v^1 and v^2 (v^2 missing if k = 1).
    v: Vec<f64>,
    g: Option<Vec<f64>>,
}

pub struct HenonPicture {
    a: f64,
    b: f64,
    /// The forward run's lambda_1 <= 0: the frames are a stable orbit, not a strange
    /// attractor, and v^1 is not the unstable direction.
    stable_orbit: bool,
    points: Vec<Point>,
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    (missing == super::Missing::AllVectors && ctx.system == "henon").then_some("Fig. 1: the stable manifold is drawn along v^2")
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    // The stable manifold is drawn along v^2: both vectors are needed.
    if ctx.system != "henon" || ctx.d != 2 || ctx.k != 2 {
        return None;
    }
    let (a, b) = match ctx.run.config.system {
        SystemConfig::Henon { a, b } => (a, b),
        _ => (Henon::A, Henon::B),
    };
    let stable_orbit = ctx.gs.as_ref().and_then(|g| g.exponents.first()).is_some_and(|&l| l <= 0.0);
    Some(Box::new(HenonPicture { a, b, stable_orbit, points: Vec::new() }))
}

/// A box [x0, x1] x [y0, y1].
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    pub x: (f64, f64),
    pub y: (f64, f64),
}

impl Bounds {
    fn of(points: impl Iterator<Item = [f64; 2]>, pad: f64) -> Bounds {
        let mut b = Bounds { x: (f64::INFINITY, f64::NEG_INFINITY), y: (f64::INFINITY, f64::NEG_INFINITY) };
        for p in points {
            b.x = (b.x.0.min(p[0]), b.x.1.max(p[0]));
            b.y = (b.y.0.min(p[1]), b.y.1.max(p[1]));
        }
        let (wx, wy) = ((b.x.1 - b.x.0).max(1e-3), (b.y.1 - b.y.0).max(1e-3));
        Bounds { x: (b.x.0 - pad * wx, b.x.1 + pad * wx), y: (b.y.0 - pad * wy, b.y.1 + pad * wy) }
    }
    fn contains(&self, p: [f64; 2]) -> bool {
        p[0] >= self.x.0 && p[0] <= self.x.1 && p[1] >= self.y.0 && p[1] <= self.y.1
    }
    fn width(&self) -> f64 {
        (self.x.1 - self.x.0).max(self.y.1 - self.y.0)
    }
}

fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
    (p[0] - q[0]).hypot(p[1] - q[1])
}

/// A piece of the stable manifold of the map with parameters `ab` = (a, b): f^-n of the
/// segment base + t dir, |t| <= eps, as (t, point) pairs in parameter order, refined so that
/// consecutive points inside `bounds` are at most `h` apart (up to [`MAX_POINTS`]).
pub fn stable_curve(ab: (f64, f64), base: [f64; 2], dir: [f64; 2], n: usize, eps: f64, h: f64, bounds: &Bounds) -> Vec<(f64, [f64; 2])> {
    let (a, b) = ab;
    let image = |t: f64| {
        let mut p = [base[0] + t * dir[0], base[1] + t * dir[1]];
        for _ in 0..n {
            p = Henon::inverse(a, b, p);
        }
        p
    };
    let mut curve: Vec<(f64, [f64; 2])> = (0..=64).map(|i| eps * (i as f64 / 32.0 - 1.0)).map(|t| (t, image(t))).collect();
    loop {
        let mut next = Vec::with_capacity(curve.len() * 2);
        let mut inserted = false;
        for w in curve.windows(2) {
            let ((ta, pa), (tb, pb)) = (w[0], w[1]);
            next.push((ta, pa));
            let inside = bounds.contains(pa) || bounds.contains(pb);
            if inside && dist(pa, pb) > h && (tb - ta) > 1e-14 * eps && curve.len() + next.len() < MAX_POINTS {
                let t = 0.5 * (ta + tb);
                next.push((t, image(t)));
                inserted = true;
            }
        }
        next.push(*curve.last().expect("non-empty"));
        curve = next;
        if !inserted || curve.len() >= MAX_POINTS {
            return curve;
        }
    }
}

/// Length of the parts of a curve lying inside `bounds`.
fn inside_length(curve: &[(f64, [f64; 2])], bounds: &Bounds) -> f64 {
    curve.windows(2).filter(|w| bounds.contains(w[0].1) && bounds.contains(w[1].1)).map(|w| dist(w[0].1, w[1].1)).sum()
}

impl Analysis for HenonPicture {
    fn name(&self) -> &'static str {
        "henon"
    }
    fn sampled(&self) -> bool {
        false
    }

    fn consume(&mut self, frame: &Frame) -> Result<()> {
        let k = frame.k.min(2);
        self.points.push(Point {
            step: frame.step,
            x: [frame.phase[0], frame.phase[1]],
            // Empty where the stream carries no vectors (`--vectors-every`; `clv run` forms
            // them for every frame of a Henon run): the point still belongs to the attractor.
            v: frame.v.get(..2 * k).unwrap_or_default().to_vec(),
            g: frame.g.as_ref().map(|g| g[..2 * k].to_vec()),
        });
        Ok(())
    }

    fn finish(mut self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        self.points.sort_by_key(|p| p.step);
        let pts = &self.points;
        if pts.is_empty() {
            return Ok(Vec::new());
        }
        write_csv(&out.join("henon_attractor.csv"), &["step", "x", "y"], pts.iter().map(|p| vec![p.step as f64, p.x[0], p.x[1]]))?;
        let bounds = Bounds::of(pts.iter().map(|p| p.x), 0.15);
        let quarter = pts.len() / 4;
        let score = |p: &Point| {
            let sine = if p.v.len() >= 4 { (p.v[0] * p.v[3] - p.v[1] * p.v[2]).abs() } else { 0.0 };
            if p.x[0].abs() < 1.0 { -(sine - std::f64::consts::FRAC_1_SQRT_2).abs() - 0.01 * p.x[0].abs() } else { -1.0 - p.x[0].abs() }
        };
        let i0 = (quarter..pts.len() - quarter).max_by(|&i, &j| score(&pts[i]).total_cmp(&score(&pts[j]))).unwrap_or(0);
        let zero = &pts[i0];

        // Stable manifold through point 0, from the latest frame with vectors at most
        // BACKWARD_STEPS steps later (a frame file with --save-every m holds every m-th step).
        let base = pts[i0..].iter().take_while(|p| p.step - zero.step <= BACKWARD_STEPS as u64).filter(|p| p.v.len() >= 4).last().unwrap_or(zero);
        let n = (base.step - zero.step) as usize;
        let mut curve = Vec::new();
        let mut eps_used = f64::NAN;
        if base.v.len() >= 4 {
            let dir = [base.v[2], base.v[3]];
            let h = bounds.width() / 400.0;
            let target = 2.0 * bounds.width();
            let mut eps = 1e-9;
            loop {
                curve = stable_curve((self.a, self.b), base.x, dir, n, eps, h, &bounds);
                eps_used = eps;
                if inside_length(&curve, &bounds) >= target || eps >= 0.05 {
                    break;
                }
                eps *= 2.0;
            }
        }
        let kept: Vec<(f64, [f64; 2])> = curve.iter().copied().filter(|(_, p)| bounds.contains(*p)).collect();
        write_csv(&out.join("henon_stable_manifold.csv"), &["t", "x", "y"], kept.iter().map(|(t, p)| vec![*t, p[0], p[1]]))?;
        // Break the line wherever the curve leaves the box.
        let (mut mx, mut my) = (Vec::new(), Vec::new());
        for (_, p) in &curve {
            let (x, y) = if bounds.contains(*p) { (p[0], p[1]) } else { (f64::NAN, f64::NAN) };
            mx.push(x);
            my.push(y);
        }

        // Vectors at point 0.
        let mut rows = Vec::new();
        let mut vec_of = |name: &str, set: &[f64], j: usize| -> Option<(f64, f64)> {
            let v = set.get(2 * j..2 * j + 2)?;
            rows.push(vec![name.to_string(), zero.step.to_string(), format!("{:e}", zero.x[0]), format!("{:e}", zero.x[1]), format!("{:e}", v[0]), format!("{:e}", v[1])]);
            Some((v[0], v[1]))
        };
        let clv: Vec<(f64, f64)> = (0..2).filter_map(|j| vec_of(&format!("v{}", j + 1), &zero.v, j)).collect();
        let gs: Vec<(f64, f64)> = match zero.g.as_ref() {
            Some(g) => (0..2).filter_map(|j| vec_of(&format!("g{}", j + 1), g, j)).collect(),
            None => Vec::new(),
        };
        write_text_csv(&out.join("henon_vectors.csv"), &["vector", "step", "x", "y", "dx", "dy"], &rows)?;

        // GS arrows shorter than the CLV arrows: g^1 = v^1 would hide v^1
        let scaled = |v: &[(f64, f64)], len: f64| -> Vec<(f64, f64)> { v.iter().map(|&(x, y)| (len * bounds.width() * x, len * bounds.width() * y)).collect() };
        let from = |m: usize| vec![(zero.x[0], zero.x[1]); m];
        let ax: Vec<f64> = pts.iter().map(|p| p.x[0]).collect();
        let ay: Vec<f64> = pts.iter().map(|p| p.x[1]).collect();
        // Equal scales: g^1 and g^2 must be seen orthogonal, as they are.
        let mut fig = Figure::new("Henon attractor, stable manifold, GS and covariant vectors").x_label("x").y_label("y").x_range(bounds.x.0, bounds.x.1).y_range(bounds.y.0, bounds.y.1).size(900, 700).equal_aspect();
        // The report's colours: GS blue, covariant vermillion (the paper: blue and red).
        fig.series("attractor (frames)", &ax, &ay, Marker::Cloud).grey();
        if !kept.is_empty() {
            fig.series("stable manifold through point 0", &mx, &my, Marker::Line).color(2);
        }
        fig.arrows("covariant vectors v^1, v^2", &from(clv.len()), &scaled(&clv, 0.18)).color(1);
        if !gs.is_empty() {
            fig.arrows("GS vectors g^1, g^2", &from(gs.len()), &scaled(&gs, 0.1)).color(0);
        }
        save_figure(&fig, out, "fig1_henon")?;
        Ok(vec![Produced {
            title: "Hénon map (Fig. 1)".into(),
            caption: format!(
                "The attractor ({frames} frame points), a stretch of the stable manifold through point 0 (step {}, at ({:.4}, {:.4})): a segment of half-length {:.1e} along v^2 at the point {n} steps later mapped {n} times backward with the inverse map ({} curve points inside the box), and at point 0 the covariant vectors{} as arrows. {}{}.",
                zero.step,
                zero.x[0],
                zero.x[1],
                eps_used,
                kept.len(),
                if gs.is_empty() { "" } else { " and the orthogonal Gram-Schmidt vectors" },
                if self.stable_orbit {
                    "With λ_1 <= 0 (see the warning above) the frames are a stable periodic orbit, not a strange attractor: v^1 is its least contracting direction, v^2 its most contracting one, along the curve"
                } else {
                    "v^1 lies along the attractor (the unstable manifold), v^2 along the stable manifold"
                },
                if gs.is_empty() { " (run the backward stage with --with-gs for the GS vectors)" } else { "; g^1 = v^1, g^2 is orthogonal to it and not the stable direction" }
            ),
            figures: vec!["fig1_henon".into()],
            tables: vec!["henon_attractor.csv".into(), "henon_stable_manifold.csv".into(), "henon_vectors.csv".into()],
        }])
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    fn step(p: [f64; 2]) -> [f64; 2] {
        [Henon::A - p[0] * p[0] + Henon::B * p[1], p[0]]
    }

    /// At the fixed point with its stable eigenvector the curve passes through the point,
    /// leaves it along the eigenvector, and every curve point maps forward n times back onto
    /// the initial segment (the inverse map is right).
    #[test]
    fn stable_curve_at_the_fixed_point() {
        let (a, b) = (Henon::A, Henon::B);
        let x = 0.883896268;
        let x = x - (a - x * x + b * x - x) / (-2.0 * x + b - 1.0); // one Newton step
        let mu = 0.15594632f64; // stable eigenvalue of [[-2x, b], [1, 0]]: eigenvector (mu, 1)
        let dir = [mu / mu.hypot(1.0), 1.0 / mu.hypot(1.0)];
        let bounds = Bounds { x: (-3.0, 3.0), y: (-3.0, 3.0) };
        let (n, eps) = (4, 1e-4);
        let curve = stable_curve((a, b), [x, x], dir, n, eps, 1e-3, &bounds);
        assert!(curve.len() > 100);
        assert!(curve.windows(2).all(|w| w[0].0 < w[1].0));
        let zero = curve.iter().find(|(t, _)| *t == 0.0).expect("t = 0 is sampled").1;
        assert!(dist(zero, [x, x]) < 1e-12);
        for &(t, p) in &curve {
            let mut q = p;
            for _ in 0..n {
                q = step(q);
            }
            let want = [x + t * dir[0], x + t * dir[1]];
            assert!(dist(q, want) < 1e-9 * (1.0 + dist(p, [0.0, 0.0])), "t = {t}");
        }
        // near the fixed point the curve is the eigenvector line
        let near = curve.iter().filter(|(_, p)| dist(*p, [x, x]) < 1e-2 && dist(*p, [x, x]) > 1e-4);
        for (_, p) in near {
            let (dx, dy) = (p[0] - x, p[1] - x);
            let cross = (dx * dir[1] - dy * dir[0]).abs() / dx.hypot(dy);
            assert!(cross < 1e-2, "{cross}");
        }
    }

    /// A frame file that keeps every 3rd step (`--save-every 3`): the stable manifold still
    /// passes through point 0, mapped back by the steps between its frames, not by the
    /// frames' count.
    #[test]
    fn the_stable_manifold_passes_through_point_0_when_frames_skip_steps() {
        let ctx = context("henon", 0, 2, 0.0, 0.0, None, false);
        let mut a = new(&ctx).expect("henon");
        let mut p = [0.1, 0.1];
        for _ in 0..100 {
            p = step(p);
        }
        for s in 0..120u64 {
            if s % 3 == 0 {
                let (c, si) = ((s as f64).cos(), (s as f64).sin());
                a.consume(&frame(1000 + s, p.to_vec(), vec![c, si, -si, c], None)).unwrap();
            }
            p = step(p);
        }
        let out = out_dir("henon-skip");
        a.finish(&out, 40).unwrap();
        let zero = &read_csv(&out.join("henon_vectors.csv"))[0];
        let at: Vec<f64> = ["x", "y"].iter().map(|c| zero[*c].parse().unwrap()).collect();
        let curve = read_csv(&out.join("henon_stable_manifold.csv"));
        let t0 = curve.iter().find(|r| r["t"].parse::<f64>().unwrap() == 0.0).expect("t = 0 is inside the box");
        let got: Vec<f64> = ["x", "y"].iter().map(|c| t0[*c].parse().unwrap()).collect();
        assert!(dist([got[0], got[1]], [at[0], at[1]]) < 1e-8, "the curve's t = 0 is {got:?}, point 0 is {at:?}");
    }

    #[test]
    fn hand_made_frames_write_the_picture() {
        let ctx = context("henon", 0, 2, 0.0, 0.0, None, true);
        let mut a = new(&ctx).expect("henon");
        let mut p = [0.1, 0.1];
        for _ in 0..100 {
            p = step(p);
        }
        for s in 0..40u64 {
            let (c, si) = ((s as f64).cos(), (s as f64).sin());
            let v = vec![c, si, -si, c];
            a.consume(&frame(1000 - s, p.to_vec(), v.clone(), Some(v))).unwrap();
            p = step(p);
        }
        let out = out_dir("henon");
        let produced = a.finish(&out, 40).unwrap();
        assert_eq!(produced.len(), 1);
        assert!(is_png(&out.join("fig1_henon.png")) && out.join("fig1_henon.svg").exists());
        let attractor = read_csv(&out.join("henon_attractor.csv"));
        assert_eq!(attractor.len(), 40);
        let vectors = read_csv(&out.join("henon_vectors.csv"));
        let names: Vec<&str> = vectors.iter().map(|r| r["vector"].as_str()).collect();
        assert_eq!(names, ["v1", "v2", "g1", "g2"]);
        assert!(!read_csv(&out.join("henon_stable_manifold.csv")).is_empty());
        assert!(new(&context("disks", 4, 16, 3.0, 3.0, None, false)).is_none());
        assert!(produced[0].caption.contains("v^1 lies along the attractor (the unstable manifold)"), "{}", produced[0].caption);
        // A forward run without chaos: the frames are a stable orbit, and the caption says so.
        let mut ctx = context("henon", 0, 2, 0.0, 0.0, None, true);
        ctx.gs = Some(crate::report::SpectrumSummary { exponents: vec![-0.16, -1.04], stderr: vec![1e-10; 2], ks_entropy: None, blocks: None, warnings: Vec::new() });
        let mut a = new(&ctx).expect("henon");
        for s in 0..4u64 {
            a.consume(&frame(1000 - s, p.to_vec(), vec![1.0, 0.0, 0.0, 1.0], None)).unwrap();
            p = step(p);
        }
        let produced = a.finish(&out_dir("henon-stable"), 4).unwrap();
        assert!(produced[0].caption.contains("the frames are a stable periodic orbit, not a strange attractor"), "{}", produced[0].caption);
    }
}
