//! The overlap, projection, null-space and local-exponent analyses on a real disk run: the
//! paper's symmetry claims, the exact null-space and triangularity properties, and the files
//! (figures, index.html) the analyses write.
//!
//! One run serves every test: N = 8 disks in a square box, 4000 steps, the last 600 as CLV
//! window (601 frames), backward with GS vectors, then `clv analyze`.

mod common;
use common::{clv, ok};
use clv::stage::analyze::kernels::localization::entropy;
use clv::stage::analyze::kernels::projections::eta_q_p;
use clv::stage::frame::Frame;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const N: usize = 8;
const D: usize = 4 * N;

/// The report directory of the shared run (made once).
fn report() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let base = Path::new(env!("CARGO_TARGET_TMPDIR")).join("analyses_a");
        let _ = std::fs::remove_dir_all(&base);
        std::fs::create_dir_all(&base).unwrap();
        let run = base.join("run");
        let n = N.to_string();
        ok(clv(&[
            "forward", "--quiet", "--out", run.to_str().unwrap(), "--n", &n, "--aspect", "1", "--steps", "4000", "--relax-steps", "300", "--clv-steps", "600",
            "--transient", "600",
        ]));
        ok(clv(&["backward", run.to_str().unwrap(), "--quiet", "--with-gs"]));
        let report = base.join("report");
        // The run directory stands for the frame file the backward stage wrote into it.
        ok(clv(&["analyze", run.to_str().unwrap(), "--out", report.to_str().unwrap()]));
        report
    })
}

struct Table {
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Table {
    fn read(name: &str) -> Table {
        let path = report().join(name);
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut lines = text.lines();
        let header = lines.next().unwrap().split(',').map(String::from).collect();
        let rows = lines.map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
        Table { header, rows }
    }

    fn col(&self, name: &str) -> Vec<f64> {
        let c = self.header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name} in {:?}", self.header));
        self.rows.iter().map(|r| r[c]).collect()
    }
}

fn summary() -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(report().join("summary.json")).unwrap()).unwrap()
}

/// Number of frames the vector statistics used, and the total.
fn frames() -> (f64, f64) {
    let s = summary();
    let total = s["frames"].as_f64().unwrap();
    (total / s["options"]["every"].as_f64().unwrap(), total)
}

/// The frames of the run, in time order.
fn all_frames() -> &'static [Frame] {
    static FRAMES: OnceLock<Vec<Frame>> = OnceLock::new();
    FRAMES.get_or_init(|| common::frames(&report().parent().unwrap().join("run").join("frames.mcap")))
}

/// Standard error of the mean of a correlated time series, from the spread of the means of
/// `blocks` consecutive blocks.
fn block_stderr(x: &[f64], blocks: usize) -> f64 {
    let len = x.len() / blocks;
    let means: Vec<f64> = x.chunks_exact(len).take(blocks).map(|c| c.iter().sum::<f64>() / len as f64).collect();
    let m = means.iter().sum::<f64>() / blocks as f64;
    (means.iter().map(|b| (b - m).powi(2)).sum::<f64>() / (blocks * (blocks - 1)) as f64).sqrt()
}

/// The null-space indices 2N-2..2N+3, 0-based.
fn null() -> Vec<usize> {
    (2 * N - 3..2 * N + 3).collect()
}

/// Blocks for the standard errors: 601 frames of tau = 0.6 give 10 blocks of 36 time units,
/// long against the decorrelation of the vectors (a few collision times).
const BLOCKS: usize = 10;
/// Allowed deviation in standard errors. With 10 blocks the error estimate is itself
/// uncertain by about 25 %; the run is deterministic, so this does not make the test flaky.
const Z: f64 = 4.0;

/// Checks that the time averages `a_i` (from the analysis CSV) satisfy a_i = b_(4N+1-i) for
/// the indices outside the null space: the per-frame difference series x_i(t) - y_c(t) must
/// average to the CSV difference, and that difference must lie within Z block standard
/// errors of zero. Prints and returns the largest |difference| and |difference| / stderr.
fn check_conjugate(what: &str, a: &[f64], b: &[f64], x: impl Fn(&Frame, usize) -> f64, y: impl Fn(&Frame, usize) -> f64) -> (f64, f64) {
    let fs = all_frames();
    let (mut worst, mut worst_z) = (0.0f64, 0.0f64);
    for i in (0..D).filter(|i| !null().contains(i)) {
        let c = D - 1 - i;
        let series: Vec<f64> = fs.iter().map(|f| x(f, i) - y(f, c)).collect();
        let mean = series.iter().sum::<f64>() / series.len() as f64;
        let diff = a[i] - b[c];
        assert!((mean - diff).abs() < 1e-12, "{what}: the analysis gives {diff} at i = {}, the frames {mean}", i + 1);
        let se = block_stderr(&series, BLOCKS);
        worst = worst.max(diff.abs());
        worst_z = worst_z.max(diff.abs() / se);
        assert!(diff.abs() < Z * se + 1e-12, "{what}: i = {}: {} vs {} at 4N+1-i = {} (difference {diff:.3e}, standard error {se:.3e})", i + 1, a[i], b[c], c + 1);
    }
    eprintln!("{what}: outside the null space max |difference| {worst:.3e}, max |difference| / stderr {worst_z:.2}");
    (worst, worst_z)
}

fn eta_q(v: &[f64]) -> f64 {
    eta_q_p(v).0
}

#[test]
fn clv_position_content_is_conjugate_symmetric() {
    assert_eq!(frames(), (601.0, 601.0), "every frame is used (every = 1)");
    let t = Table::read("projections.csv");
    let q = t.col("eta_q_clv");
    let (worst, _) = check_conjugate("CLV eta_q(i) = eta_q(4N+1-i)", &q, &q, |f, i| eta_q(f.v(i)), |f, c| eta_q(f.v(c)));
    // and not trivially: eta_q varies over the spectrum
    let spread = q.iter().copied().fold(f64::NEG_INFINITY, f64::max) - q.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(spread > 5.0 * worst, "spread {spread} vs asymmetry {worst}");
    // eta_q + eta_p = 1 for unit vectors
    for (a, b) in q.iter().zip(t.col("eta_p_clv")) {
        assert!((a + b - 1.0).abs() < 1e-12);
    }
    // In the null space every CLV has collapsed onto span{e_1, e_2, e_3} (position only):
    // backward iteration maps e_(k+3) to e_(k+3) - T e_k, so eta_p = O(1/T^2).
    for i in null() {
        assert!(q[i] > 1.0 - 1e-4, "null CLV {}: eta_q = {}", i + 1, q[i]);
    }
}

#[test]
fn gs_position_and_momentum_content_are_interchanged_between_conjugates() {
    // For GS vectors the symmetry holds at every time (g^(4N+1-i) = +-J g^i once the GS
    // basis has converged), not only on average: the per-frame differences are tiny (the
    // residue of the exponential convergence), the averages agree to round-off.
    let t = Table::read("projections.csv");
    let (q, p, c) = (t.col("eta_q_gs"), t.col("eta_p_gs"), t.col("cos_theta_gs"));
    let mut worst: f64 = 0.0;
    for i in 0..D {
        worst = worst.max((q[i] - p[D - 1 - i]).abs());
    }
    let mut worst_frame: f64 = 0.0;
    for f in all_frames() {
        for i in 0..D {
            let (a, b) = (eta_q_p(f.g(i).unwrap()), eta_q_p(f.g(D - 1 - i).unwrap()));
            worst_frame = worst_frame.max((a.0 - b.1).abs());
        }
    }
    let mut worst_cos: f64 = 0.0;
    for i in (0..D).filter(|i| !null().contains(i)) {
        worst_cos = worst_cos.max((c[i] + c[D - 1 - i]).abs());
    }
    eprintln!("GS eta_q(i) = eta_p(4N+1-i): max |difference| of the averages {worst:.3e}, of single frames {worst_frame:.3e}; cos Theta(i) = -cos Theta(4N+1-i) outside the null space: {worst_cos:.3e}");
    assert!(worst < 1e-10 && worst_frame < 1e-8 && worst_cos < 1e-10);
    // not symmetric in the CLV sense: eta_q^GS(i) != eta_q^GS(4N+1-i)
    assert!((q[0] - q[D - 1]).abs() > 0.5, "GS eta_q(1) = {} and eta_q(4N) = {} should differ", q[0], q[D - 1]);
    // the CLV cos Theta differs from the GS one (paper Fig. 9) but keeps the conjugate sign
    let cv = t.col("cos_theta_clv");
    assert!((cv[2 * N - 4] - c[2 * N - 4]).abs() > 0.01, "CLV and GS cos Theta at 2N-3: {} {}", cv[2 * N - 4], c[2 * N - 4]);
    assert!(cv[0] > 0.0 && cv[D - 1] < 0.0);
}

#[test]
fn clv_localization_is_conjugate_symmetric() {
    // W_i = exp(<S_i>)/N, so W_i = W_(4N+1-i) means <S_i> = <S_(4N+1-i)>: compare
    // ln W_i - ln W_c with the block error of the entropy difference.
    let t = Table::read("localization.csv");
    let w = t.col("W_clv");
    let ln_w: Vec<f64> = w.iter().map(|x| (x * N as f64).ln()).collect();
    let (worst, _) = check_conjugate("CLV W_i = W_(4N+1-i) (as <S_i> - <S_c>)", &ln_w, &ln_w, |f, i| entropy(f.v(i)), |f, c| entropy(f.v(c)));
    let spread = ln_w.iter().copied().fold(f64::NEG_INFINITY, f64::max) - ln_w.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(spread > 3.0 * worst, "ln W should vary over the spectrum ({spread}) more than the asymmetry ({worst})");
    // Inside the null space single vectors are not determined (a degenerate subspace): W of
    // v^(2N-2..2N) (= GS vectors for C = identity) and of v^(2N+1..2N+3) need not pair up.
    let nw: Vec<String> = null().iter().map(|&i| format!("{:.4}", w[i])).collect();
    eprintln!("CLV W in the null space (not paired): {}", nw.join(" "));
    // The errors of W: W times the batch-means error of <S> over 20 blocks of the 601 frames
    // in the order the stream carries them, newest first (30 frames each; the oldest frame is
    // in no block), recomputed here.
    let e = t.col("stderr_clv");
    assert_eq!(frames(), (601.0, 601.0));
    for i in [0, N, 2 * N - 4, D - 1] {
        let s: Vec<f64> = all_frames().iter().rev().map(|f| entropy(f.v(i))).collect();
        let want = w[i] * block_stderr(&s, 20);
        assert!((e[i] - want).abs() < 1e-12 * want, "W_{} error {} against {want}", i + 1, e[i]);
    }
}

#[test]
fn null_space_vectors_span_the_null_space() {
    let series = Table::read("nullspace_series.csv");
    assert_eq!(series.rows.len() as f64, frames().0);
    for name in ["angle_clv", "angle_gs", "angle_gs_clv"] {
        let max = series.col(name).into_iter().fold(0.0, f64::max);
        eprintln!("null space: max over time of {name} = {max:.3e}");
        assert!(max < 1e-8, "{name} reaches {max:.3e}");
    }
    for r in 0..6 {
        for m in ["beta", "alpha"] {
            let name = format!("norm_{m}_{}", 2 * N - 2 + r);
            let dev = series.col(&name).into_iter().map(|x| (x - 1.0).abs()).fold(0.0, f64::max);
            assert!(dev < 1e-9, "{name}: |1 - norm| up to {dev:.3e}");
        }
    }
    // The tables: the rows of alpha (orthonormal GS vectors in an orthonormal basis) form an
    // orthogonal matrix; the rows of beta lie in their span (principal angles between the row
    // spaces vanish): beta = X alpha with X = beta alpha^T, and X invertible.
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(report().join("nullspace_tables.json")).unwrap()).unwrap();
    let alpha: Vec<Vec<f64>> = serde_json::from_value(json["alpha"].clone()).unwrap();
    let beta: Vec<Vec<f64>> = serde_json::from_value(json["beta"].clone()).unwrap();
    for i in 0..6 {
        for j in 0..6 {
            let d: f64 = (0..6).map(|k| alpha[i][k] * alpha[j][k]).sum();
            assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-8, "alpha rows {i}, {j}: {d}");
        }
    }
    let x: Vec<Vec<f64>> = (0..6).map(|i| (0..6).map(|j| (0..6).map(|k| beta[i][k] * alpha[j][k]).sum()).collect()).collect();
    let mut resid: f64 = 0.0;
    for i in 0..6 {
        for k in 0..6 {
            let back: f64 = (0..6).map(|j| x[i][j] * alpha[j][k]).sum();
            resid = resid.max((back - beta[i][k]).abs());
        }
    }
    // The table is at the earliest frame; the backward sweep started (C = identity) at the
    // end of the transient, T = (last frame + transient - step) tau before it.
    let step = json["step"].as_f64().unwrap();
    let t_back = (summary()["last_step"].as_f64().unwrap() + 600.0 - step) * 0.6;
    let det = determinant(x.clone());
    eprintln!(
        "null space tables at step {step}: |beta - (beta alpha^T) alpha| = {resid:.3e}, det(beta alpha^T) = {det:.4e}, T^-3 = {:.4e} (T = {t_back})",
        t_back.powi(-3)
    );
    assert!(resid < 1e-9);
    // v^(2N-2) = g^(2N-2) (paper, Sec. 5.4 and conclusion); with C = identity also the next
    // two (paper Table II): equal rows up to sign.
    for r in 0..3 {
        let s = if alpha[r][0] * beta[r][0] < 0.0 { -1.0 } else { 1.0 };
        for k in 0..6 {
            assert!((alpha[r][k] - s * beta[r][k]).abs() < 1e-8, "null row {r}: alpha {:?} beta {:?}", alpha[r], beta[r]);
        }
    }
    // The Jordan block of the null space (paper eqs. "first", "second"): the last three
    // CLVs start as the GS vectors at the end (pure e_4..e_6 mixtures) and are iterated back
    // over T: v ~ sum_k c_k (e_(k+3) - T e_k), so their e_4..e_6 part is 1/T of their e_1..e_3
    // part (the paper's factors 10^-5, 10^-6), and det X = +-T^-3.
    for (r, row) in beta.iter().enumerate().skip(3) {
        let q = row[..3].iter().map(|x| x * x).sum::<f64>().sqrt();
        let p = row[3..].iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((p / q * t_back - 1.0).abs() < 1e-6, "null CLV row {r}: |p| / |q| = {} vs 1/T = {}", p / q, 1.0 / t_back);
    }
    assert!((det.abs() * t_back.powi(3) - 1.0).abs() < 1e-4, "det {det:.4e} vs T^-3 {:.4e}", t_back.powi(-3));
}

/// Determinant by Gaussian elimination with partial pivoting.
fn determinant(mut a: Vec<Vec<f64>>) -> f64 {
    let n = a.len();
    let mut det = 1.0;
    for c in 0..n {
        let p = (c..n).max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs())).unwrap();
        if p != c {
            a.swap(p, c);
            det = -det;
        }
        det *= a[c][c];
        if a[c][c] == 0.0 {
            return 0.0;
        }
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            let pivot = a[c].clone();
            for (x, p) in a[r].iter_mut().zip(&pivot).skip(c) {
                *x -= f * p;
            }
        }
    }
    det
}

#[test]
fn overlaps_show_the_triangular_structure() {
    // Fig. 3: v^1 = g^1 and v^(2N-2) = g^(2N-2) up to sign at every frame.
    let t = Table::read("overlap_gs_clv.csv");
    let m = t.col("abs_g_dot_v_mean");
    assert!(m[0] > 1.0 - 1e-10 && m[2 * N - 3] > 1.0 - 1e-8, "<|g.v|> at 1: {}, at 2N-2: {}", m[0], m[2 * N - 3]);
    assert!(m.iter().all(|&x| (0.0..=1.0 + 1e-12).contains(&x)));
    assert!(m[D / 4] < 0.99, "a generic CLV differs from its GS vector");
    // Fig. 4: v^j lies in span{g^1..g^j}, so <|v^j . g^i|> = 0 for i > j; the null-space
    // CLVs are orthogonal to every GS vector outside the null space.
    let t = Table::read("overlap_clv_gs.csv");
    let js: Vec<usize> = t.header.iter().filter_map(|h| h.strip_prefix("abs_v")?.strip_suffix("_mean")?.parse().ok()).collect();
    assert!(!js.is_empty());
    let mut worst: f64 = 0.0;
    for &j in &js {
        let c = t.col(&format!("abs_v{j}_mean"));
        worst = c[j..].iter().fold(worst, |w, &x| w.max(x));
        if null().contains(&(j - 1)) {
            for i in (0..D).filter(|i| !null().contains(i)) {
                assert!(c[i] < 1e-9, "null CLV {j} has <|v . g^{}|> = {}", i + 1, c[i]);
            }
        }
        let norm: f64 = c.iter().map(|x| x * x).sum();
        assert!(norm > 0.2, "|v^{j}| components in the GS basis too small: {norm}");
    }
    eprintln!("Fig. 4 triangularity: max over selected j of <|v^j . g^i|> for i > j = {worst:.3e} (j = {js:?})");
    assert!(worst < 1e-10);
    // Figs. 13/14: CLV-CLV, |v^j . v^j| = 1 and the null space orthogonal to the rest.
    let t = Table::read("overlap_clv_clv.csv");
    for h in t.header.iter().filter(|h| h.ends_with("_mean")) {
        let j: usize = h.strip_prefix("abs_v").unwrap().strip_suffix("_mean").unwrap().parse().unwrap();
        let c = t.col(h);
        assert!((c[j - 1] - 1.0).abs() < 1e-12);
        if !null().contains(&(j - 1)) {
            for &i in &null() {
                assert!(c[i] < 1e-9, "CLV {j} and null CLV {}: {}", i + 1, c[i]);
            }
        }
    }
}

/// The spectrum's caption gives h_KS (Pesin) for both spectra: the sums of the positive
/// exponents of spectrum.csv, each with an error.
#[test]
fn ks_entropy_is_the_sum_of_the_positive_exponents() {
    let s = summary();
    let caption = s["produced"][0]["caption"].as_str().unwrap();
    let stated = caption.split("Pesin's identity): ").nth(1).unwrap_or_else(|| panic!("no h_KS in {caption:?}"));
    let spectrum = Table::read("spectrum.csv");
    for (part, column) in stated.split(", ").zip(["lambda_gs_window", "lambda_clv"]) {
        let (value, rest) = part.split_once(" ± ").unwrap_or_else(|| panic!("no error in {part:?}"));
        let value: f64 = value.parse().unwrap();
        let error: f64 = rest.split(' ').next().unwrap().parse().unwrap();
        let positive: f64 = spectrum.col(column).iter().filter(|&&l| l > 0.0).sum();
        assert!((value - positive).abs() < 1e-6 * positive, "{column}: h_KS {value}, positive exponents sum to {positive}");
        assert!(error > 0.0 && error < 0.05 * value, "{column}: error {error} of h_KS {value}");
    }
}

/// spectrum.csv marks the null space, and gives the finite window's shear exponent of its
/// last three CLVs, which the measured ones follow (the caption's numbers).
#[test]
fn the_null_space_is_marked_with_its_predicted_clv_exponents() {
    let spectrum = Table::read("spectrum.csv");
    let (zero, shear, clv) = (spectrum.col("zero_by_symmetry"), spectrum.col("lambda_clv_null_shear"), spectrum.col("lambda_clv"));
    let null: Vec<usize> = (0..4 * N).filter(|&i| zero[i] == 1.0).collect();
    assert_eq!(null, (2 * N - 3..2 * N + 3).collect::<Vec<_>>(), "the paper's 2N-2..2N+3");
    for i in 0..4 * N {
        if (2 * N..2 * N + 3).contains(&i) {
            assert!(shear[i] < 0.0 && (clv[i] / shear[i] - 1.0).abs() < 1e-2, "lambda_{}: {} measured, {} predicted", i + 1, clv[i], shear[i]);
        } else {
            assert!(shear[i].is_nan(), "lambda_{}", i + 1);
        }
    }
}

#[test]
fn local_exponents_agree_with_the_spectrum_and_domination_improves() {
    let ts = Table::read("local_exponents.csv");
    let (_, total) = frames();
    assert_eq!(ts.rows.len() as f64, total);
    let steps = ts.col("step");
    assert!(steps.windows(2).all(|w| w[1] == w[0] + 1.0), "every frame, in time order");
    let spectrum = Table::read("spectrum.csv");
    let clv = spectrum.col("lambda_clv");
    for h in ts.header.iter().filter(|h| h.starts_with("lambda_")) {
        let i: usize = h["lambda_".len()..].parse().unwrap();
        let s = ts.col(h);
        let mean = s.iter().sum::<f64>() / s.len() as f64;
        assert!((mean - clv[i - 1]).abs() < 1e-9 * clv[i - 1].abs().max(1.0), "lambda_{i}: series mean {mean} vs spectrum {}", clv[i - 1]);
    }
    let s = summary();
    let captions: Vec<&str> = s["produced"].as_array().unwrap().iter().map(|p| p["caption"].as_str().unwrap()).collect();
    assert!(!captions.iter().any(|c| c.contains("Warning")), "frames should arrive without gaps");
    let dom = Table::read("domination.csv");
    let out = dom.col("outside_null");
    let deltas = dom.col("delta");
    eprintln!("domination: Delta {deltas:?}, overall {:?}, outside the null space {out:?}", dom.col("overall"));
    assert!(out[out.len() - 1] < out[0], "swaps must become rarer for longer windows: {out:?}");
    let p12 = dom.col("pair_1_2");
    assert!(p12[p12.len() - 1] <= p12[0]);
    // Every fraction says how many windows it is of: all frames cut into windows of Delta.
    let windows = dom.col("windows");
    assert_eq!(deltas[0], 1.0);
    for (w, d) in windows.iter().zip(&deltas) {
        assert!(w * d <= windows[0] && windows[0] < (w + 1.0) * d, "{w} windows of {d} from {} frames", windows[0]);
    }
}

#[test]
fn figures_exist_and_are_linked() {
    let index = std::fs::read_to_string(report().join("index.html")).unwrap();
    for stem in [
        "fig3_gs_clv_overlap",
        "fig3_gs_clv_overlap_center",
        "fig4_clv_gs_overlap",
        "fig13_clv_overlap",
        "fig14_mode_overlap",
        "fig6_eta_gs",
        "fig6_eta_gs_center",
        "fig7_eta_clv",
        "fig7_eta_clv_center",
        "fig9_cos_theta",
        "fig9_cos_theta_center",
        "nullspace_angle",
        "local_exponents",
        "finite_time_exponents",
        "domination",
    ] {
        let png = std::fs::read(report().join(format!("{stem}.png"))).unwrap_or_else(|e| panic!("{stem}.png: {e}"));
        assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "{stem}.png is not a PNG");
        assert!(png.len() > 5000, "{stem}.png has only {} bytes", png.len());
        let svg = std::fs::read_to_string(report().join(format!("{stem}.svg"))).unwrap();
        assert!(svg.contains("<svg"));
        assert!(index.contains(&format!("src=\"{stem}.png\"")), "index.html does not show {stem}");
    }
    for table in ["overlap_gs_clv.csv", "overlap_clv_gs.csv", "overlap_clv_clv.csv", "projections.csv", "nullspace_alpha.csv", "nullspace_beta.csv", "nullspace_tables.json", "nullspace_series.csv", "local_exponents.csv", "finite_time_exponents.csv", "domination.csv", "domination_pairs.csv"] {
        assert!(report().join(table).exists(), "{table} missing");
        assert!(index.contains(&format!("href=\"{table}\"")), "index.html does not link {table}");
    }
}
