//! Transversality of the Oseledec splitting (paper Sec. 5.6, Figs. 15, 16, 17; hard disks).
//!
//! * Fig. 15: distributions over frames of the smallest principal angle Phi between every
//!   mode subspace E^(X) (the 2- and 4-fold steps next to the null space found by
//!   [`super::Context::settle`] at the first frame, positive side) and its conjugate subspace E^(X)*, and of
//!   the smallest principal angle Psi between E^u = v^1 + ... + v^(2N-3) and
//!   E^s = v^(2N+4) + ... + v^(4N) (m = 2N-3 CLVs each). Psi > 0 in every frame is the
//!   (partial) hyperbolicity of the paper's conclusion.
//! * Fig. 16: distributions of Theta = arccos |v^i . v^j| for pairs of CLVs in
//!   F^(J) = v^1 + ... + v^J (the unstable subspace without the mode-affected directions,
//!   J = 370 for D = 792) with index separations i - j in {1, 2, 4, 20, 50, 100, 200, 300}:
//!   1, 2 and 4 as they are (they probe neighbours), the larger ones scaled by D/792; those
//!   >= J are dropped.
//! * Fig. 17: the minimum of Theta over all pairs and frames for every separation 1..J-1.
//!
//! Principal angles cost ~160 ms per frame at D = 792, so the analysis uses the frames of every m-th step.

use super::kernels::angles;
use super::kernels::modes::Step;
use super::kernels::vecset;
use super::mode_steps;
use super::{save_figure, write_csv, Analysis, Context, Produced};
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::stage::frame::Frame;
use std::f64::consts::FRAC_PI_2;
use std::path::Path;

/// The paper's separations i - j of Fig. 16 (D = 792).
pub const PAPER_SEPARATIONS: [usize; 8] = [1, 2, 4, 20, 50, 100, 200, 300];
/// Histogram bins on [0, pi/2] (1 degree wide).
pub const THETA_BINS: usize = 90;
/// Angles below this are recomputed from the difference of the unit vectors (arccos of a
/// dot product near 1 loses digits).
const SMALL: f64 = 1e-3;

/// The separations of Fig. 16 for this D within F^(J): 1, 2, 4 as they are, the paper's
/// larger ones scaled by D/792 (at least 1), without duplicates, all < J.
pub fn separations(d: usize, j: usize) -> Vec<usize> {
    let mut out: Vec<usize> = PAPER_SEPARATIONS
        .iter()
        .map(|&s| if s <= 4 { s } else { ((s as f64 * d as f64 / 792.0).round() as usize).max(1) })
        .filter(|&s| s < j)
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Random pairs of subspaces [`random_psi`] draws for the baseline of Psi: the smallest
/// angle's distribution is wide (8 pairs gave 0.24 and 0.52 degrees at N = 40), and 41
/// pairs take about 4 s at N = 198.
pub const RANDOM_PAIRS: usize = 41;

/// The median over `pairs` pairs of random m-dimensional subspaces of R^d (spanned by
/// Gaussian vectors, seeded) of their smallest principal angle: what Psi would be without
/// any structure. Psi's baseline draws them in the d = 4N - 6 dimensions orthogonal to the
/// null space, where E^u and E^s lie (the scalar products with the null space are conserved
/// by the tangent flow, so they vanish on a covariant vector that grows or shrinks
/// exponentially): there two of
/// dimension m = 2N - 3 fill the space exactly, and their angle closes like 1/N, about
/// 0.5 rad / m (medians of 200 pairs, N = 16 .. 100). So it says how much of Psi's distance
/// from zero is dynamics.
pub fn random_psi(d: usize, m: usize, pairs: usize, seed: u64) -> f64 {
    let mut rng = crate::rng::Rng::new(seed);
    let mut angles: Vec<f64> = (0..pairs)
        .map(|_| {
            let a: Vec<f64> = (0..d * m).map(|_| rng.normal()).collect();
            let b: Vec<f64> = (0..d * m).map(|_| rng.normal()).collect();
            angles::min_principal_angle(&a, &b, d)
        })
        .collect();
    angles.sort_by(f64::total_cmp);
    angles.get(angles.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Theta statistics over frames: histograms for selected separations, minimum and mean for
/// every separation (Figs. 16 and 17).
#[derive(Clone, Debug)]
pub struct ThetaStats {
    /// Number J of leading CLVs considered.
    pub j: usize,
    pub seps: Vec<usize>,
    /// Counts per separation of `seps`, THETA_BINS bins on [0, pi/2].
    pub hist: Vec<Vec<u64>>,
    /// Minimum Theta for separation s at index s (index 0 unused).
    pub min: Vec<f64>,
    sum: Vec<f64>,
    count: Vec<u64>,
}

impl ThetaStats {
    pub fn new(j: usize, seps: Vec<usize>) -> Self {
        let hist = vec![vec![0; THETA_BINS]; seps.len()];
        ThetaStats { j, seps, hist, min: vec![f64::INFINITY; j.max(1)], sum: vec![0.0; j.max(1)], count: vec![0; j.max(1)] }
    }

    pub fn bin_width() -> f64 {
        FRAC_PI_2 / THETA_BINS as f64
    }

    /// Bin of an angle in [0, pi/2].
    pub fn bin_of(theta: f64) -> usize {
        ((theta / Self::bin_width()) as usize).min(THETA_BINS - 1)
    }

    /// Fold in the first J vectors of a column-major set of vectors of length d.
    pub fn add_frame(&mut self, v: &[f64], d: usize) {
        let j = self.j;
        if j < 2 {
            return;
        }
        let f = &v[..j * d];
        let gram = vecset::mul_tn(vecset::as_mat(f, d), vecset::as_mat(f, d));
        for a in 0..j {
            for b in a + 1..j {
                let c = gram[(a, b)].abs() / (gram[(a, a)] * gram[(b, b)]).sqrt();
                let mut theta = c.min(1.0).acos();
                if theta.is_nan() || theta < SMALL {
                    theta = angles::vector_angle(vecset::col(f, d, a), vecset::col(f, d, b));
                }
                if !theta.is_finite() {
                    continue;
                }
                let s = b - a;
                self.min[s] = self.min[s].min(theta);
                self.sum[s] += theta;
                self.count[s] += 1;
                if let Some(h) = self.seps.iter().position(|&x| x == s) {
                    self.hist[h][Self::bin_of(theta)] += 1;
                }
            }
        }
    }

    /// Mean Theta for separation s.
    pub fn mean(&self, s: usize) -> f64 {
        self.sum[s] / self.count[s] as f64
    }

    /// Probability density of histogram h (count / (total * bin width)).
    pub fn density(&self, h: usize) -> Vec<f64> {
        let total: u64 = self.hist[h].iter().sum();
        self.hist[h].iter().map(|&c| c as f64 / (total.max(1) as f64 * Self::bin_width())).collect()
    }
}

pub struct Transversality {
    ctx: Context,
    /// m = 2N-3: dimension of E^u and E^s.
    m: usize,
    /// The context's mode steps on the positive side (from the first frame on), labelled by
    /// the first frame's classification.
    steps: Vec<Step>,
    labels: Vec<String>,
    frame_steps: Vec<u64>,
    psi: Vec<f64>,
    /// Per mode step, per frame.
    phi: Vec<Vec<f64>>,
    /// Created at the first frame (F^(J) ends before the first mode step).
    theta: Option<ThetaStats>,
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    (missing == super::Missing::AllVectors && ctx.is_disks()).then_some("the angles between Oseledec subspaces of Figs. 15-17")
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    if !ctx.is_disks() || ctx.k != ctx.d || ctx.d < 8 {
        return None;
    }
    Some(Box::new(Transversality {
        ctx: ctx.clone(),
        m: ctx.d / 2 - 3,
        steps: Vec::new(),
        labels: Vec::new(),
        frame_steps: Vec::new(),
        psi: Vec::new(),
        phi: Vec::new(),
        theta: None,
    }))
}

fn step_range(s: &Step) -> String {
    format!("i = {}..{}", s.start + 1, s.start + s.len)
}

fn deg(x: f64) -> f64 {
    x.to_degrees()
}

impl Analysis for Transversality {
    fn name(&self) -> &'static str {
        "transversality"
    }

    fn consume(&mut self, frame: &Frame) -> Result<()> {
        let d = frame.d;
        if self.theta.is_none() {
            self.ctx.settle(frame);
            self.steps = mode_steps::positive(&self.ctx.modes, d);
            let candidates = mode_steps::candidates(&self.ctx);
            self.phi = vec![Vec::new(); self.steps.len()];
            let j = mode_steps::f_size(d, &self.steps);
            self.theta = Some(ThetaStats::new(j, separations(d, j)));
            self.labels = self
                .steps
                .iter()
                .map(|s| match mode_steps::clear_name(frame, s, &candidates) {
                    Some(name) => format!("{name} ({})", step_range(s)),
                    None => format!("{}-fold step ({})", s.len, step_range(s)),
                })
                .collect();
        }
        self.frame_steps.push(frame.step);
        self.psi.push(angles::min_angle_unstable_stable(&frame.v, d, self.m));
        for (s, phi) in self.steps.iter().zip(self.phi.iter_mut()) {
            phi.push(angles::min_angle_conjugate(&frame.v, d, s.start, s.len));
        }
        if let Some(theta) = self.theta.as_mut() {
            theta.add_frame(&frame.v, d);
        }
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let ctx = &self.ctx;
        let n = ctx.n;
        let mut produced = Vec::new();
        let labels: Vec<String> = if self.labels.len() == self.steps.len() { self.labels.clone() } else { self.steps.iter().map(step_range).collect() };

        // Fig. 15
        let mut header = vec!["step".to_string(), "psi_unstable_stable".to_string()];
        header.extend(self.steps.iter().map(|s| format!("phi_{}_{}", s.start + 1, s.start + s.len)));
        let header: Vec<&str> = header.iter().map(|s| s.as_str()).collect();
        write_csv(
            &out.join("transversality.csv"),
            &header,
            (0..self.psi.len()).map(|f| {
                let mut row = vec![self.frame_steps[f] as f64, self.psi[f]];
                row.extend(self.phi.iter().map(|p| p[f]));
                row
            }),
        )?;
        let stats = |v: &[f64]| {
            let fin: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
            let min = fin.iter().copied().fold(f64::INFINITY, f64::min);
            (min, fin.iter().sum::<f64>() / fin.len().max(1) as f64)
        };
        let bins = 45;
        let mut fig = Figure::new("Minimum principal angles between conjugate Oseledec subspaces").x_label("angle (rad)").y_label("probability density").x_range(0.0, FRAC_PI_2);
        let (pmin, pmean) = stats(&self.psi);
        fig.histogram(&format!("Psi: E^u = v^1..v^{} vs E^s", self.m), &self.psi, bins, 0.0, FRAC_PI_2, true);
        let mut mode_text = Vec::new();
        for (label, phi) in labels.iter().zip(&self.phi) {
            let (min, mean) = stats(phi);
            fig.histogram(&format!("Phi {label}"), phi, bins, 0.0, FRAC_PI_2, true);
            mode_text.push(format!("Φ for {label}: min {:.1}° ({min:.3} rad), mean {:.1}° ({mean:.3} rad)", deg(min), deg(mean)));
        }
        save_figure(&fig, out, "fig15_transversality")?;
        produced.push(Produced {
            title: "Transversality of conjugate subspaces (Fig. 15)".into(),
            caption: format!(
                "Distributions over {frames} frames of the smallest principal angle Ψ between E^u = v^1..v^{} and E^s = v^{}..v^{} (min {:.2}° = {pmin:.4} rad, mean {:.1}° = {pmean:.3} rad{}; between random subspaces of these dimensions in the 4N-6 = {} dimensions orthogonal to the null space, where E^u and E^s lie, it would be {:.2}°, the median of {RANDOM_PAIRS} pairs) and of the smallest principal angle Φ between each mode subspace next to the null space and its conjugate subspace ({}). Angles from QR bases and the SVD of Q^T Q* (sines for small angles).",
                self.m,
                2 * n + 4,
                4 * n,
                deg(pmin),
                deg(pmean),
                if pmin > 0.0 { "; Ψ > 0 in every frame: E^u and E^s are transversal" } else { "" },
                2 * self.m,
                deg(random_psi(2 * self.m, self.m, RANDOM_PAIRS, 1)),
                if mode_text.is_empty() { "no mode steps were detected".to_string() } else { mode_text.join("; ") }
            ),
            figures: vec!["fig15_transversality".into()],
            tables: vec!["transversality.csv".into()],
        });

        // Figs. 16, 17: of pairs of vectors in F^(J), none where it holds fewer than two.
        let th = &self.theta.clone().unwrap_or_else(|| ThetaStats::new(0, Vec::new()));
        if th.seps.is_empty() {
            produced[0].caption += " Figs. 16 and 17 (angles between pairs of covariant vectors in F^(J)) are left out: F^(J) holds fewer than two vectors here.";
            return Ok(produced);
        }
        let w = ThetaStats::bin_width();
        let mut header = vec!["theta_lo".to_string(), "theta_hi".to_string()];
        header.extend(th.seps.iter().map(|s| format!("density_sep_{s}")));
        let header: Vec<&str> = header.iter().map(|s| s.as_str()).collect();
        let dens: Vec<Vec<f64>> = (0..th.seps.len()).map(|h| th.density(h)).collect();
        write_csv(
            &out.join("theta_histograms.csv"),
            &header,
            (0..THETA_BINS).map(|b| {
                let mut row = vec![b as f64 * w, (b + 1) as f64 * w];
                row.extend(dens.iter().map(|d| d[b]));
                row
            }),
        )?;
        let mut fig = Figure::new(&format!("Θ = arccos|v^i·v^j| in F^({}) for separations i - j", th.j)).x_label("Θ (rad)").y_label("probability density").x_range(0.0, FRAC_PI_2);
        for (h, s) in th.seps.iter().enumerate() {
            let mut x: Vec<f64> = (0..THETA_BINS).map(|b| b as f64 * w).collect();
            let mut y = dens[h].clone();
            x.push(FRAC_PI_2);
            y.push(*y.last().unwrap_or(&0.0));
            fig.series(&format!("i - j = {s}"), &x, &y, Marker::Steps);
        }
        save_figure(&fig, out, "fig16_theta_distributions")?;
        produced.push(Produced {
            title: "Angles between covariant vectors (Fig. 16)".into(),
            caption: format!(
                "Distributions of Θ = arccos|v^i·v^j| over {frames} frames for pairs of covariant vectors in F^({}) = v^1..v^{} (the unstable subspace without the mode directions) with index separations i - j = {} (the paper's 1, 2, 4, 20, 50, 100, 200, 300 for D = 792; the larger ones scaled to D = {}, dropped where they fall on a smaller one or reach beyond F).{}",
                th.j,
                th.j,
                th.seps.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", "),
                ctx.d,
                match (th.seps.first(), dens.first()) {
                    (Some(1), Some(d)) => first_bin(d, &th.hist[0], w),
                    _ => String::new(),
                }
            ),
            figures: vec!["fig16_theta_distributions".into()],
            tables: vec!["theta_histograms.csv".into()],
        });

        // Fig. 17
        let seps: Vec<usize> = (1..th.j).filter(|&s| th.count[s] > 0).collect();
        write_csv(&out.join("theta_min.csv"), &["separation", "min_theta", "mean_theta"], seps.iter().map(|&s| vec![s as f64, th.min[s], th.mean(s)]))?;
        let x: Vec<f64> = seps.iter().map(|&s| s as f64).collect();
        let y: Vec<f64> = seps.iter().map(|&s| th.min[s].log10()).collect();
        let mut fig = Figure::new(&format!("Minimum Θ over {frames} frames, F^({})", th.j)).x_label("i - j").y_label("log10 min Θ (rad)");
        fig.series("log10 min Θ", &x, &y, Marker::LinePoints);
        save_figure(&fig, out, "fig17_theta_min")?;
        let at1 = seps.first().map_or(f64::NAN, |&s| th.min[s]);
        produced.push(Produced {
            title: "Minimum angle between covariant vectors (Fig. 17)".into(),
            caption: format!(
                "Minimum of Θ = arccos|v^i·v^j| over all pairs in F^({}) and {frames} frames as a function of i - j (log scale; min Θ for i - j = 1: {:.3e} rad). Small angles are computed from |v^i ∓ v^j|, not from the arccos of the dot product.",
                th.j, at1
            ),
            figures: vec!["fig17_theta_min".into()],
            tables: vec!["theta_min.csv".into()],
        });
        Ok(produced)
    }
}

/// Angles the first five bins of Fig. 16 must hold for [`first_bin`] to say whether the
/// density falls toward zero (a few counts would decide it by chance).
const FIRST_BINS_MIN: u64 = 50;

/// Whether the density of Θ for i - j = 1 falls toward Θ = 0, the paper's finding for N = 198
/// (Sec. 5.6, on Fig. 16: "the distribution for i-j = 1 seems to converge to zero for Θ → 0"): its first bin
/// against the mean of the next four, where those five bins hold at least [`FIRST_BINS_MIN`]
/// angles (`counts`). Below half the mean it falls; below 85 % it dips but stays far from
/// zero; above, it is flat there.
fn first_bin(density: &[f64], counts: &[u64], width: f64) -> String {
    let next = &density[1..density.len().min(5)];
    let mean = next.iter().sum::<f64>() / next.len() as f64;
    let held: u64 = counts.iter().take(1 + next.len()).sum();
    let finding = if held < FIRST_BINS_MIN {
        format!("{held} angles in these bins are too few to tell whether it falls toward Θ = 0")
    } else if density[0] < 0.5 * mean {
        "it falls toward Θ = 0, as the paper's for N = 198".to_string()
    } else if density[0] < 0.85 * mean {
        format!("it dips in the first bin ({:.0} % below) but stays far from zero, where the paper's (N = 198) seems to converge to zero", 100.0 * (1.0 - density[0] / mean))
    } else {
        "it does not fall toward Θ = 0 here, where the paper's (N = 198) does".to_string()
    };
    format!(
        " For i - j = 1 the density in the first bin (Θ < {:.1}°) is {:.3}, against {mean:.3} in the next {} bins: {finding} (Fig. 17 gives the smallest Θ).",
        width.to_degrees(),
        density[0],
        next.len()
    )
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    /// The conjugate-mode angles are those of the blocks the mode table settles on: an LP
    /// pair the exponents see, widened to its quadruplet, gives the quadruplet's phi.
    #[test]
    fn a_widened_lp_step_is_taken_whole() {
        let Planted { ctx, frame, at, .. } = split_lp_quadruplet();
        let mut t = new(&ctx).unwrap();
        t.consume(&frame).unwrap();
        let out = out_dir("widened-transversality");
        t.finish(&out, 1).unwrap();
        let header = std::fs::read_to_string(out.join("transversality.csv")).unwrap();
        assert!(header.starts_with(&format!("step,psi_unstable_stable,phi_{}_{}\n", at + 1, at + 4)), "{header}");
    }

    /// F^(J) of Figs. 16-17 ends before the first mode step, also one found by its vectors
    /// only.
    #[test]
    fn f_j_ends_before_an_lp_block_found_by_its_vectors() {
        let Planted { ctx, frame, at, .. } = lp_block_found_by_its_vectors();
        let mut t = new(&ctx).unwrap();
        t.consume(&frame).unwrap();
        let out = out_dir("lp-by-vectors-transversality");
        let produced = t.finish(&out, 1).unwrap();
        assert!(produced.iter().any(|p| p.caption.contains(&format!("F^({at}) = v^1..v^{at}"))), "{:?}", produced.iter().map(|p| &p.caption).collect::<Vec<_>>());
    }

    #[test]
    fn first_bin_says_whether_the_density_falls_toward_zero() {
        let falls = first_bin(&[0.137, 0.270, 0.292, 0.358, 0.4, 0.5], &[14, 27, 29, 36, 40, 50], 0.0175);
        assert!(falls.contains("is 0.137, against 0.330 in the next 4 bins: it falls toward Θ = 0, as the paper's"), "{falls}");
        let flat = first_bin(&[0.564, 0.5, 0.6, 0.55, 0.5], &[56, 50, 60, 55, 50], 0.0175);
        assert!(flat.contains("it does not fall toward Θ = 0 here"), "{flat}");
        // The N = 100 report's numbers: 38 % below the next bins, far from zero.
        let dips = first_bin(&[0.403, 0.707, 0.625, 0.627, 0.626], &[4030, 7070, 6250, 6270, 6260], 0.0175);
        assert!(dips.contains("against 0.646 in the next 4 bins: it dips in the first bin (38 % below) but stays far from zero"), "{dips}");
        // One angle in each of bins 2-5 and none in the first decides nothing; nor does an
        // empty histogram.
        let few = first_bin(&[0.0, 0.28, 0.28, 0.28, 0.28], &[0, 1, 1, 1, 1], 0.0175);
        assert!(few.contains("4 angles in these bins are too few to tell"), "{few}");
        assert!(first_bin(&[0.0; 5], &[0; 5], 0.0175).contains("0 angles in these bins are too few"));
    }

    #[test]
    fn separations_follow_the_paper_and_scale() {
        assert_eq!(separations(792, 370), PAPER_SEPARATIONS.to_vec());
        assert_eq!(separations(160, 75), vec![1, 2, 4, 10, 20, 40, 61]); // 20 scales to 4
        assert_eq!(separations(24, 3), vec![1, 2]);
        let steps = [Step { start: 70, len: 2, mean: 0.1 }, Step { start: 84, len: 2, mean: -0.1 }];
        assert_eq!(mode_steps::f_size(160, &steps), 70);
        assert_eq!(mode_steps::f_size(792, &[]), 370);
    }

    /// The random baseline of Psi: two lines in the plane are apart by pi/4 on median
    /// (uniform angles on [0, pi/2]); for m = 2N - 3 in d = 4N - 6 it closes like 1/N, as
    /// the numpy sampling of scripts/hyperbolicity.py found (medians of 200 pairs: 1.02
    /// degrees at N = 16, 0.24 at 64), far below the 4N dimensions' (6.4 and 1.5 degrees:
    /// six dimensions to spare).
    #[test]
    fn random_subspaces_close_like_one_over_n() {
        let lines = random_psi(2, 1, 201, 3);
        assert!((lines - std::f64::consts::FRAC_PI_4).abs() < 0.15, "{lines}");
        let (p16, p64) = (random_psi(58, 29, 41, 1).to_degrees(), random_psi(250, 125, 41, 1).to_degrees());
        assert!((0.5..2.0).contains(&p16) && (0.12..0.5).contains(&p64), "{p16} {p64}");
        assert!(p16 / p64 > 2.5, "{p16} / {p64} for four times the disks");
        assert!(random_psi(64, 29, 41, 1).to_degrees() > 3.0 * p16, "six dimensions to spare open the angle");
        assert_eq!(random_psi(58, 29, 9, 1), random_psi(58, 29, 9, 1), "seeded");
    }

    /// Vectors in one plane at angles j delta: Theta(v^i, v^j) = |i - j| delta exactly.
    #[test]
    fn theta_histogram_of_known_angles_lands_in_the_right_bins() {
        let (d, j, delta) = (6, 5, 0.1);
        let v: Vec<f64> = (0..d).flat_map(|c| {
            let a = c as f64 * delta;
            let mut e = vec![0.0; d];
            (e[0], e[1]) = (a.cos(), -a.sin());
            e
        }).collect();
        let mut th = ThetaStats::new(j, separations(d, j));
        assert_eq!(th.seps, vec![1, 2, 4]);
        th.add_frame(&v, d);
        th.add_frame(&v, d);
        for (h, &s) in th.seps.iter().enumerate() {
            let want = ThetaStats::bin_of(s as f64 * delta);
            assert_eq!(want, [5, 11, 22][h]); // 0.1, 0.2, 0.4 rad in 1-degree bins
            for (b, &c) in th.hist[h].iter().enumerate() {
                assert_eq!(c, if b == want { 2 * (j - s) as u64 } else { 0 }, "separation {s}, bin {b}");
            }
            let dens = th.density(h);
            assert!((dens[want] * ThetaStats::bin_width() - 1.0).abs() < 1e-12);
        }
        for s in 1..j {
            assert!((th.min[s] - s as f64 * delta).abs() < 1e-14 && (th.mean(s) - s as f64 * delta).abs() < 1e-14);
        }
        // a tiny angle is resolved (arccos of the dot product would give 0 or 1.5e-8)
        let a: f64 = 1e-11;
        let w = [1.0, 0.0, a.cos(), a.sin()];
        let mut th = ThetaStats::new(2, vec![1]);
        th.add_frame(&w, 2);
        assert!((th.min[1] - a).abs() < 1e-20, "{}", th.min[1]);
    }

    fn run(n: usize, frames: &[Frame], name: &str) -> (OutDir, Vec<Produced>) {
        let d = 4 * n;
        let ctx = context("disks", n, d, 10.0, 2.0, Some(spectrum(n, 2)), false);
        let out = out_dir(name);
        let mut a = new(&ctx).expect("disks, all vectors");
        for f in frames {
            a.consume(f).unwrap();
        }
        let produced = a.finish(&out, frames.len() as u64).unwrap();
        (out, produced)
    }

    /// Psi is between E^u = v^1..v^(2N-3) and E^s = v^(2N+4)..v^(4N), the null space
    /// v^(2N-2)..v^(2N+3) in neither: the null space's first and last vectors made parallel
    /// leave Psi at pi/2, the last unstable and the first stable vector made parallel close
    /// it (a Psi that took one null vector into each subspace passed every other test).
    #[test]
    fn psi_leaves_the_null_space_out() {
        let n = 6;
        let phase = phase(n, 10.0, 2.0, &mut Rng::new(7));
        let frames = [frame(2, phase.clone(), unit_vectors_with(n, &[(2 * n - 3, 2 * n + 2)]), None), frame(1, phase, unit_vectors_with(n, &[(2 * n - 4, 2 * n + 3)]), None)];
        let (out, _) = run(n, &frames, "psi-border");
        let rows = read_csv(&out.join("transversality.csv"));
        let psi = |r: usize| rows[r]["psi_unstable_stable"].parse::<f64>().unwrap();
        assert!((psi(0) - FRAC_PI_2).abs() < 1e-14, "null vectors are in neither subspace: {}", psi(0));
        assert!(psi(1).abs() < 1e-14, "v^(2N-3) is unstable and v^(2N+4) stable: {}", psi(1));
    }

    /// The 4N unit vectors (column-major), vector b of each pair (a, b) set to vector a.
    fn unit_vectors_with(n: usize, same: &[(usize, usize)]) -> Vec<f64> {
        let d = 4 * n;
        let identity: Vec<f64> = (0..d * d).map(|i| if i % (d + 1) == 0 { 1.0 } else { 0.0 }).collect();
        let mut v = identity.clone();
        for &(a, b) in same {
            v[b * d..(b + 1) * d].copy_from_slice(&identity[a * d..(a + 1) * d]);
        }
        v
    }

    /// Orthogonal conjugate subspaces give pi/2, identical ones 0, for the mode pair and for
    /// E^u vs E^s.
    #[test]
    fn orthogonal_and_identical_conjugate_subspaces() {
        let n = 6;
        let mut rng = Rng::new(5);
        let phase = phase(n, 10.0, 2.0, &mut rng);
        // mode pair at 0-based 7, 8; conjugates 15, 16 made equal to them
        let frames = [frame(2, phase.clone(), unit_vectors_with(n, &[]), None), frame(1, phase, unit_vectors_with(n, &[(7, 16), (8, 15)]), None)];
        let (out, produced) = run(n, &frames, "conjugate");
        let rows = read_csv(&out.join("transversality.csv"));
        assert_eq!(rows.len(), 2);
        let get = |r: usize, c: &str| rows[r][c].parse::<f64>().unwrap();
        // the pair 8, 9 (paper indices), possibly widened to a four-fold block containing it
        let phis: Vec<&String> = rows[0].keys().filter(|k| k.starts_with("phi_")).collect();
        assert_eq!(phis.len(), 1, "{phis:?}");
        let phi = phis[0].as_str();
        assert!((get(0, "psi_unstable_stable") - FRAC_PI_2).abs() < 1e-14);
        assert!((get(0, phi) - FRAC_PI_2).abs() < 1e-14);
        assert!(get(1, phi).abs() < 1e-14);
        assert!(get(1, "psi_unstable_stable").abs() < 1e-14);
        for stem in ["fig15_transversality", "fig16_theta_distributions", "fig17_theta_min"] {
            assert!(is_png(&out.join(format!("{stem}.png"))), "{stem}");
        }
        assert_eq!(produced.len(), 3);
        // identity frame: all angles pi/2; second frame the same within F^(J); J ends before
        // the mode step
        let first: usize = phi.split('_').nth(1).unwrap().parse().unwrap();
        let mins = read_csv(&out.join("theta_min.csv"));
        assert_eq!(mins.len(), first - 2);
        assert!(mins.iter().all(|r| (r["min_theta"].parse::<f64>().unwrap() - FRAC_PI_2).abs() < 1e-14));
    }
}
