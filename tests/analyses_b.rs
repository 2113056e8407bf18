//! The mode, transversality and Henon analyses (paper Table III, Figs. 1, 10-12, 15-17) on
//! small real runs: forward, backward --with-gs, analyze.

mod common;
use common::{clv, ok};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn scratch(name: &str) -> PathBuf {
    common::scratch("analyses_b", name)
}

/// forward, backward --with-gs, analyze; returns the report directory.
fn pipeline(name: &str, flags: &[&str]) -> PathBuf {
    let dir = scratch(name);
    let run = dir.join("run");
    let frames = dir.join("frames.mcap");
    let report = dir.join("report");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ok(clv(&[&["forward", "--quiet", "--out", &s(&run)], flags].concat()));
    ok(clv(&["backward", &s(&run), "--quiet", "--with-gs", "--out", &s(&frames)]));
    ok(clv(&["analyze", &s(&frames), "--out", &s(&report)]));
    report
}

use clv::report::dir::csv_cells as split_csv;

fn read_csv(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header = split_csv(lines.next().unwrap());
    lines.map(|l| header.iter().cloned().zip(split_csv(l)).collect()).collect()
}

fn num(row: &BTreeMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap_or_else(|e| panic!("{key} = {:?}: {e}", row[key]))
}

/// stem.png is a PNG of more than 5 kB, stem.svg exists, and index.html shows it.
fn check_figure(report: &Path, stem: &str) {
    let png = std::fs::read(report.join(format!("{stem}.png"))).unwrap_or_else(|e| panic!("{stem}.png: {e}"));
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n"), "{stem}.png is not a PNG");
    assert!(png.len() > 5000, "{stem}.png has only {} bytes", png.len());
    assert!(report.join(format!("{stem}.svg")).exists(), "{stem}.svg");
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(index.contains(&format!("src=\"{stem}.png\"")), "index.html does not show {stem}");
}

/// N = 40 disks in the paper's thin box (density 0.7, aspect 2/11): the T(1,0) pair sits
/// next to the null space, LP(1,0) next to it; E^u and E^s are transversal in every frame.
#[test]
fn disk_modes_and_transversality() {
    let n = 40;
    let started = Instant::now();
    let report = pipeline("disks", &["--n", "40", "--density", "0.7", "--aspect", "2/11", "--steps", "6000", "--clv-steps", "600", "--transient", "600"]);
    let elapsed = started.elapsed().as_secs_f64();
    eprintln!("disk pipeline (forward, backward, analyze): {elapsed:.1} s");

    // Mode table: a T(1,0) among the steps adjacent to the null space (paper indices
    // 2N-3 = 77 on the positive side, 2N+4 = 84 on the negative side).
    let modes = read_csv(&report.join("modes.csv"));
    for m in &modes {
        eprintln!("mode: {m:?}");
    }
    let adjacent: Vec<_> = modes.iter().filter(|m| m["last"] == (2 * n - 3).to_string() || m["first"] == (2 * n + 4).to_string()).collect();
    let t1 = adjacent.iter().find(|m| m["kind"] == "T" && m["n_x"] == "1").unwrap_or_else(|| panic!("no T(1,0) next to the null space: {modes:?}"));
    assert!(num(t1, "fraction_gs") > 0.5, "{t1:?}");
    assert!(num(t1, "agreement") > 0.5, "{t1:?}");
    // Next to it, LP(1,0) at 2N-8..2N-5 and its conjugate: exponents spread like the smooth
    // spectrum's (no exponent test sees them), found by their vectors.
    for (first, last) in [(2 * n - 8, 2 * n - 5), (2 * n + 6, 2 * n + 9)] {
        let lp = modes.iter().find(|m| m["first"] == first.to_string() && m["last"] == last.to_string()).unwrap_or_else(|| panic!("no step at {first}..{last}: {modes:?}"));
        assert_eq!((lp["name"].as_str(), lp["detection"].as_str()), ("LP(1,0)", "vectors"), "{lp:?}");
        assert!(num(lp, "beyond_chance") > 0.3 && num(lp, "agreement") > 0.5, "{lp:?}");
    }
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(report.join("modes.json")).unwrap()).unwrap();
    assert_eq!(json["modes"].as_array().unwrap().len(), modes.len());

    // Fig. 10 fits: the pair's GS and CLV vectors are clean sinusoids (relative rms residual
    // well below 1).
    let fits = read_csv(&report.join("modes_fits.csv"));
    let first = &t1["first"];
    for row in fits.iter().filter(|r| &r["first"] == first && r["scope"] == "mean") {
        eprintln!("fit: {} {} {}: A(dq_y) = {:.4}, rel. residual {:.3}; A(dp_y) = {:.4}, rel. residual {:.3}", row["source"], row["i"], row["scope"], num(row, "amp_dqt"), num(row, "rel_resid_dqt"), num(row, "amp_dpt"), num(row, "rel_resid_dpt"));
        assert!(num(row, "rel_resid_dqt") < 0.5, "{row:?}");
    }

    // Hyperbolicity: the smallest principal angle between E^u and E^s is positive in every
    // analysed frame.
    let angles = read_csv(&report.join("transversality.csv"));
    assert!(angles.len() > 100, "{} frames", angles.len());
    let psi: Vec<f64> = angles.iter().map(|r| num(r, "psi_unstable_stable")).collect();
    let (min, mean) = (psi.iter().copied().fold(f64::INFINITY, f64::min), psi.iter().sum::<f64>() / psi.len() as f64);
    eprintln!("Psi(E^u, E^s) over {} frames: min {min:.4} rad, mean {mean:.4} rad", psi.len());
    assert!(psi.iter().all(|&p| p.is_finite() && p > 0.0), "E^u and E^s touch: min Psi = {min}");
    let phi_key = format!("phi_{}_{}", t1["first"], t1["last"]);
    if t1["first"].parse::<usize>().unwrap() < 2 * n {
        let phi: Vec<f64> = angles.iter().map(|r| num(r, &phi_key)).collect();
        eprintln!("Phi(T(1,0)): min {:.4} rad", phi.iter().copied().fold(f64::INFINITY, f64::min));
        assert!(phi.iter().all(|&p| p > 0.0));
    }
    let theta_min = read_csv(&report.join("theta_min.csv"));
    let min1 = num(&theta_min[0], "min_theta");
    eprintln!("min Theta for i - j = 1: {min1:.3e} rad; for i - j = {}: {:.3e}", theta_min.last().unwrap()["separation"], num(theta_min.last().unwrap(), "min_theta"));
    assert!(theta_min.iter().all(|r| num(r, "min_theta") >= 0.0 && num(r, "min_theta") <= std::f64::consts::FRAC_PI_2));

    // F^(J) of Figs. 16-17 and the last selected j of Figs. 4 and 13 (the paper's 370) are
    // the last unstable vector before the mode region: J = 2N-9, just before LP(1,0).
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(index.contains(&format!("F^({})", 2 * n - 9)), "F^(J) should end before LP(1,0)");
    assert!(index.contains(&format!("selected covariant vectors j = 1, 39, {}, and", 2 * n - 9)), "Fig. 13's default j (the paper's 1, 200, 370 scaled)");
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(report.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["options"]["j"], serde_json::json!([1, 39, 2 * n - 9]), "summary.json's options are the figures'");

    let t_stem = format!("fig10_T1_i{}", t1["last"]);
    let mut stems = vec!["fig15_transversality".to_string(), "fig16_theta_distributions".into(), "fig17_theta_min".into(), "modes_dispersion".into()];
    if t1["side"] == "+" {
        stems.extend([format!("{t_stem}_dqy"), format!("{t_stem}_dpy")]);
    }
    for stem in &stems {
        check_figure(&report, stem);
    }
    for table in ["modes.csv", "modes.json", "modes_dispersion.csv", "transversality.csv", "theta_histograms.csv", "theta_min.csv"] {
        assert!(index.contains(&format!("href=\"{table}\"")), "index.html does not link {table}");
    }

    // The same system in the box turned by 90 degrees (L_y = 11/2 L_x) has the same pair,
    // now along y: T(0,1), with the same exponent within the errors and a Fig. 10 of dq_x
    // against q_y.
    let turned = pipeline("disks-turned", &["--n", "40", "--density", "0.7", "--aspect", "11/2", "--steps", "6000", "--clv-steps", "600", "--transient", "600"]);
    let modes = read_csv(&turned.join("modes.csv"));
    let t01 = modes.iter().find(|m| m["side"] == t1["side"] && m["first"] == t1["first"]).unwrap_or_else(|| panic!("no step at {}: {modes:?}", t1["first"]));
    assert_eq!((t01["name"].as_str(), t01["consistent"].as_str()), ("T(0,1)", "true"), "{t01:?}");
    assert_eq!(t01["k"], t1["k"]);
    let error = |report: &Path, m: &BTreeMap<String, String>| -> f64 {
        let spectrum = read_csv(&report.join("spectrum.csv"));
        num(&spectrum[m["first"].parse::<usize>().unwrap() - 1], "stderr_gs")
    };
    let (e1, e2) = (error(&report, t1), error(&turned, t01));
    assert!((num(t1, "lambda") - num(t01, "lambda")).abs() < 4.0 * e1.hypot(e2), "T(1,0) {t1:?}, T(0,1) {t01:?}");
    check_figure(&turned, &format!("fig10_T0_1_i{}_dqx", t01["last"]));
}

fn point(row: &BTreeMap<String, String>) -> [f64; 2] {
    [num(row, "x"), num(row, "y")]
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// |cos| of the angle between the chord from a to b and the unit vector u.
fn chord_cos(a: [f64; 2], b: [f64; 2], u: [f64; 2]) -> f64 {
    ((b[0] - a[0]) * u[0] + (b[1] - a[1]) * u[1]).abs() / dist(a, b)
}

/// The Henon picture: v^1 at point 0 lies along the attractor, v^2 along the drawn stable
/// manifold, which passes through point 0.
#[test]
fn henon_picture() {
    let report = pipeline("henon", &["--system", "henon", "--steps", "3000", "--clv-steps", "600", "--transient", "300"]);
    check_figure(&report, "fig1_henon");
    let attractor = read_csv(&report.join("henon_attractor.csv"));
    assert_eq!(attractor.len(), 601);
    let vectors = read_csv(&report.join("henon_vectors.csv"));
    let get = |name: &str| vectors.iter().find(|r| r["vector"] == name).unwrap_or_else(|| panic!("{name} missing"));
    let (v1, v2, g1, g2) = (get("v1"), get("v2"), get("g1"), get("g2"));
    let unit = |r: &BTreeMap<String, String>| [num(r, "dx"), num(r, "dy")];
    let x0 = point(v1);
    let steps: Vec<f64> = attractor.iter().map(|r| num(r, "step")).collect();
    assert!(steps.windows(2).all(|w| w[1] == w[0] + 1.0), "attractor rows in time order");
    let pts: Vec<[f64; 2]> = attractor.iter().map(point).collect();
    let i0 = pts.iter().position(|&p| p == x0).expect("point 0 is a frame");
    assert_eq!(steps[i0].to_string(), v1["step"]);

    // The attractor's local direction at point 0 from neighbouring frames: the nearest frame
    // on the same leaf, i.e. whose two previous points stay as close to those of point 0 (a
    // frame on another leaf has a diverging past: backward iteration stretches the stable
    // direction about five-fold per step).
    let m = 2;
    let leaf = (m..pts.len())
        .filter(|&j| j != i0 && i0 >= m)
        .filter(|&j| (1..=m).all(|s| dist(pts[j - s], pts[i0 - s]) <= 1.5 * dist(pts[j], x0)))
        .min_by(|&a, &b| dist(pts[a], x0).total_cmp(&dist(pts[b], x0)))
        .expect("a frame on the leaf of point 0");
    let c1 = chord_cos(x0, pts[leaf], unit(v1));
    eprintln!("point 0 = {x0:?} (step {}); neighbour on its leaf at distance {:.3}: |cos(chord, v^1)| = {c1:.6}", v1["step"], dist(pts[leaf], x0));
    assert!(c1 > 0.99, "v^1 is not along the attractor: |cos| = {c1}");
    // ... and the stable direction is not
    let c2 = chord_cos(x0, pts[leaf], unit(v2));
    assert!(c2 < 0.9, "v^2 along the attractor too: |cos| = {c2}");

    // GS: g^1 = v^1, g^2 orthogonal to g^1 and not the stable direction.
    let (u1, u2, w1, w2) = (unit(v1), unit(v2), unit(g1), unit(g2));
    assert!((u1[0] * w1[0] + u1[1] * w1[1]).abs() > 1.0 - 1e-12);
    assert!((w1[0] * w2[0] + w1[1] * w2[1]).abs() < 1e-12);
    assert!((u2[0] * w2[0] + u2[1] * w2[1]).abs() < 1.0 - 1e-3);

    // The stable-manifold stretch passes through point 0, tangent to v^2 there.
    let curve: Vec<[f64; 2]> = read_csv(&report.join("henon_stable_manifold.csv")).iter().map(point).collect();
    assert!(curve.len() > 200, "{} points", curve.len());
    let at = (0..curve.len()).min_by(|&a, &b| dist(curve[a], x0).total_cmp(&dist(curve[b], x0))).unwrap();
    assert!(dist(curve[at], x0) < 1e-8, "the stable manifold misses point 0 by {}", dist(curve[at], x0));
    for nb in [at.checked_sub(1), Some(at + 1)].into_iter().flatten().filter(|&j| j < curve.len()) {
        let c = chord_cos(x0, curve[nb], u2);
        eprintln!("stable manifold chord of length {:.4} at point 0: |cos(chord, v^2)| = {c:.6}", dist(curve[nb], x0));
        assert!(dist(curve[nb], x0) < 0.05 && c > 0.99, "chord {:.4} long, |cos| = {c}", dist(curve[nb], x0));
    }
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    for table in ["henon_attractor.csv", "henon_stable_manifold.csv", "henon_vectors.csv"] {
        assert!(index.contains(&format!("href=\"{table}\"")), "index.html does not link {table}");
    }
    // no disk analyses on a map
    assert!(!report.join("modes.csv").exists() && !report.join("transversality.csv").exists());
}
