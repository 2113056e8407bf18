//! The backward (Ginelli) stage: covariance, the Henon manifolds, GS = CLV spectra, the
//! bitwise recomputation check, out-of-core segments, resume after SIGKILL, and pipes.

mod common;
use common::{clv, frames, ok};

fn scratch(name: &str) -> PathBuf {
    common::scratch("backward", name)
}

use clv::stage::frame::Frame;
use clv::system::henon::Henon;
use clv::system::disks::HardDisks;
use clv::system::{DynamicalSystem, Snapshot, Tangent};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// A finished forward run with the given flags.
fn forward(name: &str, flags: &[&str]) -> PathBuf {
    let dir = scratch(name).join("run");
    ok(clv(&[&["forward", "--quiet", "--out", dir.to_str().unwrap()], flags].concat()));
    dir
}

fn backward_json(dir: &Path, flags: &[&str]) -> serde_json::Value {
    let out = ok(clv(&[&["backward", dir.to_str().unwrap(), "--quiet", "--json"], flags].concat()));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn unit(v: &[f64]) -> Vec<f64> {
    let n = dot(v, v).sqrt();
    v.iter().map(|x| x / n).collect()
}

fn vec_of(report: &serde_json::Value, key: &str) -> Vec<f64> {
    serde_json::from_value(report[key].clone()).unwrap()
}

const HENON: [&str; 12] = ["--system", "henon", "--steps", "3000", "--relax-steps", "100", "--clv-steps", "600", "--transient", "300", "--checkpoint-every", "100"];

/// v^1 lies along the unstable manifold (a vector iterated forward from far in the past) and
/// v^2 along the stable one (a vector iterated backward from far in the future); the CLV
/// exponents equal the GS ones.
#[test]
fn henon_clvs_are_the_manifold_directions() {
    let dir = forward("henon", &HENON);
    let report = backward_json(&dir, &["--with-gs"]);
    let fs = frames(&dir.join("frames.mcap"));
    assert_eq!(fs.len(), 601);
    let (clv_l, gs_l) = (vec_of(&report, "exponents"), vec_of(&report, "gs_exponents"));
    let err = vec_of(&report, "stderr");
    for i in 0..2 {
        assert!((clv_l[i] - gs_l[i]).abs() < 4.0 * err[i] + 0.02, "lambda_{}: CLV {} vs GS {}", i + 1, clv_l[i], gs_l[i]);
    }
    let m = 40;
    for at in [m, fs.len() / 2, fs.len() - 1 - m] {
        let x = |f: &Frame| (f.phase[0], f.phase[1]);
        // Unstable direction at `at`: iterate (1, 0) forward through the m previous points.
        let mut u = [1.0, 0.0];
        for f in &fs[at - m..at] {
            let (px, _) = x(f);
            u = [-2.0 * px * u[0] + Henon::B * u[1], u[0]];
            let n = (u[0] * u[0] + u[1] * u[1]).sqrt();
            u = [u[0] / n, u[1] / n];
        }
        // Stable direction: iterate (1, 0) backward with J^{-1} = [[0, 1], [1/b, 2x/b]] from m
        // points ahead (the Jacobian at step n uses x_n).
        let mut s = [1.0, 0.0];
        for f in fs[at..at + m].iter().rev() {
            let (px, _) = x(f);
            s = [s[1], (s[0] + 2.0 * px * s[1]) / Henon::B];
            let n = (s[0] * s[0] + s[1] * s[1]).sqrt();
            s = [s[0] / n, s[1] / n];
        }
        let f = &fs[at];
        let c1 = dot(f.v(0), &u).abs();
        let c2 = dot(f.v(1), &s).abs();
        assert!(c1 > 1.0 - 1e-10, "step {}: v1 . unstable = {c1}", f.step);
        assert!(c2 > 1.0 - 1e-10, "step {}: v2 . stable = {c2}", f.step);
        // The GS vector g^2 is orthogonal to g^1 = v^1, so it is not the stable direction.
        assert!(dot(f.g(1).unwrap(), &s).abs() < 1.0 - 1e-3);
        assert!(dot(f.g(0).unwrap(), f.v(0)).abs() > 1.0 - 1e-12, "v1 = g1");
    }
}

/// The Lorenz flow: exponents (0.9056, 0, -14.5723) (Sprott, Chaos and Time-Series Analysis, 2003), the GS ones summing to
/// -(sigma + 1 + beta) = -13.6667 exactly, and the CLV of the zero exponent parallel
/// to the vector field at every frame (the flow direction is covariant), where g^2 is not.
#[test]
fn lorenz_clvs_give_the_flow_direction() {
    use clv::system::lorenz::Lorenz;
    let dir = forward("lorenz", &["--system", "lorenz", "--steps", "20000", "--clv-steps", "2000", "--transient", "500"]);
    let report = backward_json(&dir, &["--with-gs"]);
    let divergence = -(Lorenz::SIGMA + 1.0 + Lorenz::BETA);
    // The GS sum is ln |det| of every step, exact to the integrator's 1e-6; the CLV sum
    // only converges to it (the CLVs are not orthogonal: their local growths do not add up
    // to the volume's step by step).
    for (key, tolerance) in [("gs_exponents", 1e-5), ("exponents", 0.02)] {
        let l = vec_of(&report, key);
        assert!((l.iter().sum::<f64>() - divergence).abs() < tolerance, "{key}: sum {} against {divergence}", l.iter().sum::<f64>());
        // Sprott's values; 2000 frames average them to a few hundredths.
        assert!((l[0] - 0.9056).abs() < 0.05 && l[1].abs() < 0.02 && (l[2] + 14.5723).abs() < 0.05, "{key}: {l:?}");
    }
    // Pesin's h_KS is lambda_1 alone: the flow direction's lambda_2, zero but measured with
    // either sign, is never counted.
    for (h, l) in [("ks_entropy", "exponents"), ("gs_ks_entropy", "gs_exponents")] {
        assert_eq!(report[h]["value"].as_f64(), Some(vec_of(&report, l)[0]), "{h}: {report}");
    }
    let fs = frames(&dir.join("frames.mcap"));
    assert_eq!(fs.len(), 2001);
    let lorenz = Lorenz::new(Lorenz::SIGMA, Lorenz::RHO, Lorenz::BETA, 0.1, [0.0; 3]);
    let (mut worst, mut gs_worst) = (1.0f64, 1.0f64);
    for f in &fs {
        let flow = unit(&lorenz.field([f.phase[0], f.phase[1], f.phase[2]]));
        worst = worst.min(dot(f.v(1), &flow).abs() / dot(f.v(1), f.v(1)).sqrt());
        gs_worst = gs_worst.min(dot(f.g(1).unwrap(), &flow).abs());
    }
    assert!(worst > 1.0 - 1e-9, "|cos(v^2, flow)| down to {worst}");
    // g^2 is orthogonal to g^1 = v^1, so it leaves the flow direction wherever v^1 is not
    // orthogonal to the flow.
    assert!(gs_worst < 0.9, "g^2 is not the flow direction: |cos| at least {gs_worst}");
}

/// Propagating v_n^j over tau gives a vector parallel to v_{n+1}^j, for every j outside the
/// degenerate (null-space) subspace.
fn check_covariance(system: &mut dyn DynamicalSystem, fs: &[Frame], skip: &[usize]) {
    let mut worst: f64 = 0.0;
    for pair in fs.windows(2).step_by(7) {
        let (a, b) = (&pair[0], &pair[1]);
        assert_eq!(a.step + 1, b.step);
        for j in (0..a.k).filter(|j| !skip.contains(j)) {
            system.restore(&Snapshot { phase: a.phase.clone(), events: 0 }).unwrap();
            let mut t = Tangent::zeros(a.d, 1);
            t.set_vector(system, 0, a.v(j));
            system.advance(&mut t).unwrap();
            assert_eq!(system.snapshot().phase, b.phase, "restored dynamics must reproduce the next phase point");
            let moved = unit(&t.vector(system, 0));
            worst = worst.max(1.0 - dot(&moved, b.v(j)).abs());
        }
    }
    assert!(worst < 1e-8, "covariance violated: 1 - |cos| up to {worst}");
}

#[test]
fn henon_clvs_are_covariant() {
    let dir = forward("henon-cov", &HENON);
    backward_json(&dir, &[]);
    let fs = frames(&dir.join("frames.mcap"));
    check_covariance(&mut Henon::new(Henon::A, Henon::B, 0.0, 0.0), &fs, &[]);
}

fn disk_case(name: &str, n: usize, steps: &str) -> (PathBuf, serde_json::Value, Vec<Frame>) {
    let ns = n.to_string();
    let dir = forward(name, &["--n", &ns, "--aspect", "1", "--steps", steps, "--relax-steps", "300", "--clv-steps", "600", "--transient", "600"]);
    let report = backward_json(&dir, &["--with-gs"]);
    let fs = frames(&dir.join("frames.mcap"));
    (dir, report, fs)
}

/// The GS spectrum over the frames' steps is the forward run's sums of ln R_ii between the
/// checkpoints at the window's ends (frame m carries the growth over [t_m, t_(m+1)]), and its
/// lambda_1 is the CLV one (v^1 = g^1).
#[test]
fn the_gs_spectrum_over_the_window_is_the_forward_runs_over_those_steps() {
    let dir = forward("gs-window", &["--n", "4", "--aspect", "1", "--steps", "900", "--relax-steps", "100", "--clv-steps", "300", "--transient", "200", "--checkpoint-every", "1"]);
    let report = backward_json(&dir, &[]);
    let (first, last) = (report["statistics"]["first_frame_step"].as_u64().unwrap(), report["statistics"]["last_frame_step"].as_u64().unwrap());
    let checkpoints = common::contents(&dir).checkpoints;
    let (a, b) = (&checkpoints[&first].acc.sum, &checkpoints[&(last + 1)].acc.sum);
    let window = vec_of(&report["gs_window"], "exponents");
    let t = (last + 1 - first) as f64 * 0.6;
    for i in 0..16 {
        assert!((window[i] * t - (b[i] - a[i])).abs() < 1e-9 * (1.0 + (b[i] - a[i]).abs()), "lambda_{} over the window: {} against the checkpoints' {}", i + 1, window[i], (b[i] - a[i]) / t);
    }
    assert!((window[0] - vec_of(&report, "exponents")[0]).abs() < 1e-12 * window[0], "{} {}", window[0], vec_of(&report, "exponents")[0]);
    assert_eq!(vec_of(&report["gs_window"], "stderr").len(), 16);
    // Each frame carries its own share, ln |[R_(m+1)]_ii| / tau: their mean is the window's
    // spectrum (what the spectrum analysis plots in Fig. 2).
    let fs = frames(&dir.join("frames.mcap"));
    assert_eq!(fs.len() as u64, last + 1 - first);
    let seen: serde_json::Value = serde_json::from_slice(&ok(clv(&["inspect", dir.join("frames.mcap").to_str().unwrap(), "--json"])).stdout).unwrap();
    assert_eq!(seen["with_gs_local"].as_u64(), Some(fs.len() as u64), "{seen}");
    for (i, want) in window.iter().enumerate().take(16) {
        let mean = fs.iter().map(|f| f.gs_local[i]).sum::<f64>() / fs.len() as f64;
        assert!((mean - want).abs() < 1e-12 * (1.0 + want.abs()), "lambda_{}: frames {mean}, gs_window {want}", i + 1);
    }
}

/// The CLV spectrum and its errors, recomputed from the frames' local exponents by batch
/// means in the order the sweep makes them (newest first; `block_len` frames a block, the
/// frames left over counted in the means only): clv_spectrum.json and the analyses' table
/// agree. 1000 frames in 20 blocks: a block plan from one frame fewer gave blocks of 49 and
/// other errors, and nothing noticed (a mutation check).
#[test]
fn the_clv_errors_are_the_batch_means_of_the_frames() {
    let dir = forward("clv-errors", &["--system", "henon", "--steps", "3000", "--relax-steps", "100", "--clv-steps", "999", "--transient", "300"]);
    let report = backward_json(&dir, &[]);
    let mut fs = frames(&dir.join("frames.mcap"));
    assert_eq!(fs.len(), 1000);
    fs.reverse();
    // The default --blocks 20.
    let len = clv::statistics::block_len(fs.len() as u64, 20) as usize;
    assert_eq!(len, 50);
    let table = clv_table(&dir);
    for (i, row) in table.iter().enumerate() {
        let local: Vec<f64> = fs.iter().map(|f| f.local[i]).collect();
        let mean = local.iter().sum::<f64>() / local.len() as f64;
        let means: Vec<f64> = local.chunks_exact(len).map(|b| b.iter().sum::<f64>() / len as f64).collect();
        let m = means.iter().sum::<f64>() / means.len() as f64;
        let stderr = (means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (means.len() * (means.len() - 1)) as f64).sqrt();
        let (lambda, err) = (vec_of(&report, "exponents")[i], vec_of(&report, "stderr")[i]);
        assert!((lambda - mean).abs() < 1e-12 * (1.0 + mean.abs()), "lambda_{}: {lambda} against the frames' {mean}", i + 1);
        assert!((err - stderr).abs() < 1e-12 * stderr, "stderr_{}: {err} against the frames' batch means' {stderr}", i + 1);
        assert!((row.0 - lambda).abs() < 1e-12 * (1.0 + lambda.abs()) && (row.1 - err).abs() < 1e-9 * err, "spectrum.csv's row {}: {row:?}", i + 1);
    }
}

/// spectrum.csv's (lambda_clv, stderr_clv) of a run's frames, by `clv analyze`.
fn clv_table(dir: &Path) -> Vec<(f64, f64)> {
    let rep = dir.parent().unwrap().join("report");
    ok(clv(&["analyze", dir.to_str().unwrap(), "--out", rep.to_str().unwrap(), "--only", "spectrum", "--quiet"]));
    let text = read_text(&rep.join("spectrum.csv"));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (l, e) = (col("lambda_clv"), col("stderr_clv"));
    lines.map(|row| row.split(',').map(|x| x.parse::<f64>().unwrap()).collect::<Vec<f64>>()).map(|r| (r[l], r[e])).collect()
}

fn check_disks(n: usize, steps: &str) {
    let (_, report, fs) = disk_case(&format!("disks-{n}"), n, steps);
    let d = 4 * n;
    let null: Vec<usize> = (2 * n - 3..2 * n + 3).collect();
    // Covariance for every vector outside the null space.
    let (lx, _) = clv::system::disks::box_sides(n, 0.7, 1.0);
    let mut sys = HardDisks::new(n, lx, lx, 0.6, 1).unwrap();
    check_covariance(&mut sys, &fs, &null);
    // CLV spectrum = GS spectrum within the errors (outside the null space, where the
    // Jordan block makes finite-time CLV averages decay only like ln t / t).
    let (l, g, e, ge) = (vec_of(&report, "exponents"), vec_of(&report, "gs_exponents"), vec_of(&report, "stderr"), vec_of(&report, "gs_stderr"));
    for i in (0..d).filter(|i| !null.contains(i)) {
        let tol = 4.0 * (e[i].powi(2) + ge[i].powi(2)).sqrt() + 0.02 * g[i].abs();
        assert!((l[i] - g[i]).abs() < tol, "N = {n}: lambda_{} CLV {} vs GS {}", i + 1, l[i], g[i]);
    }
    // The null space: translations e_1..e_3 are invariant (exponent 0), but e_(k+3) grows
    // like e_(k+3) - s e_k under backward iteration (s the backward time), so the last three
    // average -ln((1 + s2^2) / (1 + s1^2)) / (2 (s2 - s1)) over the window: with a
    // backward transient of 600 steps and 601 frames, s runs from 599 tau to 1200 tau.
    let (s1, s2): (f64, f64) = (599.0 * 0.6, 1200.0 * 0.6);
    let shear = -((1.0 + s2 * s2).ln() - (1.0 + s1 * s1).ln()) / (2.0 * (s2 - s1));
    for (i, l) in l.iter().enumerate().skip(2 * n - 3).take(3) {
        assert!(l.abs() < 1e-10, "N = {n}: lambda_{} = {l}", i + 1);
    }
    for (i, l) in l.iter().enumerate().skip(2 * n).take(3) {
        assert!((l / shear - 1.0).abs() < 1e-3, "N = {n}: lambda_{} = {l} against {shear}", i + 1);
    }
    for f in fs.iter().step_by(50) {
        // v^1 = g^1 and v^{2N-2} = g^{2N-2} up to sign (C starts as the identity).
        assert!(dot(f.v(0), f.g(0).unwrap()).abs() > 1.0 - 1e-10);
        let j = 2 * n - 3;
        assert!(dot(f.v(j), f.g(j).unwrap()).abs() > 1.0 - 1e-8, "v^(2N-2) . g^(2N-2) = {}", dot(f.v(j), f.g(j).unwrap()));
        // The six null-space CLVs lie in span{e_1..e_6}: orthogonal to the complement,
        // which is spanned by the GS vectors with nonzero exponents.
        for &j in &null {
            for i in (0..d).filter(|i| !null.contains(i)) {
                let x = dot(f.v(j), f.g(i).unwrap()).abs();
                assert!(x < 1e-9, "null CLV {} has a component {x} along g^{}", j + 1, i + 1);
            }
        }
    }
}

#[test]
fn disk_clvs_n4_are_covariant_and_match_gs() {
    check_disks(4, "6000");
}

#[test]
fn disk_clvs_n16_are_covariant_and_match_gs() {
    check_disks(16, "4000");
}

#[test]
fn altered_checkpoint_stops_the_backward_stage_naming_the_step() {
    use clv::store::schema::CHECKPOINT;
    use clv::store::segment::{read_segment, ReadMode};
    let dir = forward("altered", &HENON);
    let seg = (clv::store::RunDir { path: dir.clone() }).segments().unwrap().pop().unwrap();
    // Flip one bit of the phase point of the newest segment's second checkpoint.
    let mut steps = Vec::new();
    read_segment(&seg.path, ReadMode::Strict, |m| {
        if m.topic == CHECKPOINT.topic {
            steps.push(m.step);
        }
        Ok(())
    })
    .unwrap();
    let target = steps[1];
    common::alter_checkpoint(&dir, target, |cp| cp.state.system.phase[0] = f64::from_bits(cp.state.system.phase[0].to_bits() ^ 1));
    let out = clv(&["backward", dir.to_str().unwrap(), "--quiet"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "an altered checkpoint must stop the backward stage");
    assert!(err.contains(&format!("step {target}")) && err.contains("does not reproduce"), "{err}");
    assert!(!err.contains("panicked"));
}

#[test]
fn out_of_core_segments_and_random_c_give_consistent_results() {
    let dir = forward("ooc", &["--n", "8", "--aspect", "1", "--steps", "1500", "--clv-steps", "300", "--transient", "300"]);
    let d = dir.to_str().unwrap();
    let a = backward_json(&dir, &["--out", &format!("{d}/a.mcap")]);
    let b = backward_json(&dir, &["--out", &format!("{d}/b.mcap"), "--memory", "0"]);
    assert_eq!(a["exponents"], b["exponents"], "the scratch-file path must give the same bits");
    let (fa, fb) = (frames(&dir.join("a.mcap")), frames(&dir.join("b.mcap")));
    assert!(fa == fb);
    // A machine (or a job's memory limit) that offers less than --memory: out of core too,
    // and said so, rather than left to the OOM killer.
    let out = common::clv_env(&["backward", d, "--out", &format!("{d}/e.mcap")], &[("CLV_FAULT_MEMORY_AVAILABLE", "2000000")]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && err.contains("offered 1 MB, less than --memory's 4096 MB") && err.contains("scratch file"), "{err}");
    assert!(frames(&dir.join("e.mcap")) == fa);
    let out = clv(&["backward", d, "--out", &format!("{d}/f.mcap")]);
    assert!(out.status.success() && !String::from_utf8_lossy(&out.stderr).contains("scratch file"), "no note where memory suffices");
    // A generic (random) start converges to the same covariant vectors outside degenerate
    // subspaces: compare v^1 and the most stable vector.
    let c = backward_json(&dir, &["--out", &format!("{d}/c.mcap"), "--c-init", "random"]);
    let fc = frames(&dir.join("c.mcap"));
    for (x, y) in fa.iter().zip(&fc).step_by(20) {
        for j in [0, x.k - 1] {
            assert!(dot(x.v(j), y.v(j)).abs() > 1.0 - 1e-8, "v^{} differs between C starts", j + 1);
        }
    }
    let (la, lc) = (vec_of(&a, "exponents"), vec_of(&c, "exponents"));
    assert!((la[0] - lc[0]).abs() < 1e-6);
}

#[test]
fn killed_backward_resumes_to_identical_frames() {
    let dir = forward("resume", &["--n", "16", "--aspect", "1", "--steps", "6000", "--clv-steps", "1200", "--transient", "600"]);
    let d = dir.to_str().unwrap().to_string();
    let started = std::time::Instant::now();
    let want_report = backward_json(&dir, &["--out", &format!("{d}/full.mcap")]);
    let sweep_ms = started.elapsed().as_secs_f64() * 1e3;
    let want = frames(&dir.join("full.mcap"));
    // With --vectors-every m, the frames of the other steps come without V_n and G_n; with
    // --save-every s, the file keeps the frames of the steps that are multiples of s.
    let expect = |m: u64, s: u64| -> Vec<Frame> {
        want.iter().filter(|f| f.step % s == 0).map(|f| if f.step % m == 0 { f.clone() } else { Frame { v: Vec::new(), g: None, ..f.clone() } }).collect()
    };
    let mut interrupted = 0;
    // Kills at shares of the uninterrupted sweep's time on this machine (one after its end).
    for (trial, (share, every, save)) in [(0.7, 1, 1), (1.8, 1, 1), (0.35, 4, 1), (0.7, 4, 1), (0.55, 1, 3)].into_iter().enumerate() {
        let delay = (share * sweep_ms) as u64;
        let out = format!("{d}/part-{trial}.mcap");
        let (every_s, save_s) = (every.to_string(), save.to_string());
        let flags = ["--vectors-every", every_s.as_str(), "--save-every", save_s.as_str()];
        let _ = std::fs::remove_file(dir.join("backward.json"));
        let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args([&["backward", &d, "--quiet", "--out", &out][..], &flags].concat()).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay));
        child.kill().unwrap();
        child.wait().unwrap();
        if !Path::new(&out).exists() {
            interrupted += 1;
            if dir.join("backward.json").exists() {
                // The sweep continues with the options it was started with, never others.
                let refused = clv(&["backward", &d, "--quiet", "--out", &out, "--resume", "--vectors-every", "5"]);
                assert!(!refused.status.success() && common::stderr(&refused).contains("--resume"), "{}", common::stderr(&refused));
            }
            let report = backward_json(&dir, &[&["--out", out.as_str()][..], &common::resume_flag(&dir), &flags].concat());
            assert_eq!(report["exponents"], want_report["exponents"]);
        } else {
            backward_json(&dir, &[&["--out", &format!("{d}/again-{trial}.mcap")][..], &flags].concat());
        }
        assert!(frames(Path::new(&out)) == expect(every, save), "trial {trial}: frames after resume differ");
    }
    assert!(interrupted >= 1, "no kill landed before the end of the sweep");
}

/// Killed after the finished frame file was renamed into place, before the progress record
/// said the sweep was done: resuming salvages from the finished file and ends with the same
/// frames; a finished file of another sweep is refused, not overwritten.
#[test]
fn killed_between_the_finished_file_and_its_record_resumes() {
    let dir = forward("rename", &["--n", "16", "--aspect", "1", "--steps", "6000", "--clv-steps", "1200", "--transient", "600"]);
    let d = dir.to_str().unwrap().to_string();
    let started = std::time::Instant::now();
    backward_json(&dir, &["--out", &format!("{d}/full.mcap")]);
    let sweep_ms = started.elapsed().as_secs_f64() * 1e3;
    let want = frames(&dir.join("full.mcap"));
    // The size the disk-space warning expects is the file's, within 10 %.
    let (run, meta) = clv::store::RunDir::open(&dir).unwrap();
    let mut opts = clv::stage::backward::BackwardOptions::for_run(&meta);
    opts.frames_path = Some(dir.join("full.mcap"));
    let (expected, actual) = (clv::stage::backward::frame_file_bytes(&run, &meta, &opts), std::fs::metadata(dir.join("full.mcap")).unwrap().len());
    assert!((expected as f64 / actual as f64 - 1.0).abs() < 0.1, "expected {expected} bytes, the file has {actual}");
    let (out, record) = (dir.join("part.mcap"), dir.join("backward.json"));
    let o = out.to_str().unwrap();
    // A sweep stopped with a progress record and its FILE.tmp: the state just before the end.
    let mut interim = None;
    for share in [0.5, 0.7, 0.3, 0.85, 0.2, 0.6] {
        let _ = std::fs::remove_file(&record);
        let _ = std::fs::remove_file(dir.join("part.mcap.tmp"));
        common::kill_after(&["backward", &d, "--quiet", "--out", o], (share * sweep_ms) as u64);
        if record.exists() && !out.exists() {
            interim = Some(std::fs::read(&record).unwrap());
            break;
        }
        let _ = std::fs::remove_file(&out);
    }
    let interim = interim.expect("no kill landed after a finished segment");
    let shown = String::from_utf8(clv(&["inspect", &d]).stdout).unwrap();
    assert!(shown.contains("backward sweep: interrupted after ") && shown.contains(&format!("(frames to {o})")) && shown.contains("--resume` continues it"), "{shown}");
    // Its FILE.tmp gone (a purged scratch directory): inspect says --resume cannot continue.
    let tmp = dir.join("part.mcap.tmp");
    std::fs::rename(&tmp, dir.join("aside.tmp")).unwrap();
    let shown = String::from_utf8(clv(&["inspect", &d]).stdout).unwrap();
    assert!(shown.contains("are gone, so --resume is refused") && !shown.contains("continues it"), "{shown}");
    std::fs::rename(dir.join("aside.tmp"), &tmp).unwrap();
    ok(clv(&["backward", &d, "--quiet", "--out", o, "--resume"]));
    let shown = String::from_utf8(clv(&["inspect", &d]).stdout).unwrap();
    assert!(shown.contains(&format!("backward sweep: finished, {} frames (frames to {o})", want.len())), "{shown}");
    assert!(frames(&out) == want);
    // Finished file in place, record not yet done.
    std::fs::write(&record, &interim).unwrap();
    ok(clv(&["backward", &d, "--quiet", "--out", o, "--resume"]));
    assert!(frames(&out) == want, "frames after resuming from the finished file differ");
    assert!(!dir.join("part.mcap.tmp.old").exists() && !dir.join("part.mcap.tmp").exists());
    // The same state, but FILE written by a sweep with other options.
    let other = dir.join("other.mcap");
    ok(clv(&["backward", &d, "--quiet", "--out", other.to_str().unwrap(), "--vectors-every", "3"]));
    std::fs::rename(&other, &out).unwrap();
    std::fs::write(&record, &interim).unwrap();
    let refused = clv(&["backward", &d, "--quiet", "--out", o, "--resume"]);
    let err = common::stderr(&refused);
    assert!(!refused.status.success() && err.contains("another backward sweep") && err.contains("part.mcap"), "{err}");
    assert!(out.exists(), "the other sweep's file is kept");
}

#[test]
fn frames_flow_through_real_pipes_and_a_closed_pipe_ends_cleanly() {
    let dir = forward("pipe", &["--n", "8", "--aspect", "1", "--steps", "1500", "--clv-steps", "300", "--transient", "300"]);
    let d = dir.to_str().unwrap();
    backward_json(&dir, &["--out", &format!("{d}/file.mcap")]);
    let want = frames(&dir.join("file.mcap"));
    // backward --out - | (a reader of the MCAP stream on stdin)
    let mut producer = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", d, "--out", "-", "--quiet"]).stdout(Stdio::piped()).spawn().unwrap();
    let piped = producer.stdout.take().unwrap();
    let mut got = Vec::new();
    read_frames_from(piped, &mut got);
    assert!(producer.wait().unwrap().success());
    got.sort_by_key(|f| f.step);
    assert!(got == want, "the piped stream carries the same frames as the file");
    let clv_spectrum = std::fs::read(dir.join("clv_spectrum.json")).unwrap();
    // A reader that stops after a few bytes: the producer stops, says so and how to go on,
    // and exits as a writer killed by SIGPIPE would (141): the sweep is not done.
    let mut producer = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", d, "--out", "-"]).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut head = producer.stdout.take().unwrap();
    let mut buf = [0u8; 5000];
    std::io::Read::read_exact(&mut head, &mut buf).unwrap();
    drop(head);
    let out = producer.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{err}");
    assert!(err.contains("closed the stream") && err.contains("To start over, give the same command again without --resume"), "{err}");
    // --resume continues after the frames of the finished segments, as the record holds them.
    let recorded = match err.contains("With --resume the sweep would stream the whole window again: it finished no segment.") {
        true => "0",
        false => err.split("the sweep finished the segments of its first ").nth(1).and_then(|t| t.split(' ').next()).unwrap_or_else(|| panic!("{err}")),
    };
    let shown = String::from_utf8(clv(&["inspect", d]).stdout).unwrap();
    assert!(shown.contains(&format!("backward sweep: interrupted after {recorded} frames")), "{recorded}: {shown}");
    assert!(std::fs::read(dir.join("clv_spectrum.json")).unwrap() == clv_spectrum, "an unfinished sweep writes no CLV spectrum");
    // --json would put the spectrum into the frame stream: refused.
    let both = clv(&["backward", d, "--out", "-", "--json"]);
    assert!(!both.status.success() && String::from_utf8_lossy(&both.stderr).contains("--json"), "{}", String::from_utf8_lossy(&both.stderr));
    // Standard output on a terminal (script(1), from util-linux, gives it one): refused.
    let tty = Command::new("script").args(["-qec", &format!("{} backward {d} --out -", env!("CARGO_BIN_EXE_clv")), "/dev/null"]).output().expect("script(1) from util-linux");
    let text = String::from_utf8_lossy(&tty.stdout);
    assert!(!tty.status.success() && text.contains("standard output is a terminal"), "{text}");
    // A reader that closes before reading anything (a consumer that failed to start), with
    // frames larger than the stream's 1 MB write buffer, so that the write fails inside a
    // chunk (which leaves the MCAP writer unable to finish).
    let big = forward("pipe-big", &["--n", "100", "--relax-steps", "10", "--steps", "100", "--clv-steps", "20", "--transient", "20", "--checkpoint-every", "20"]);
    let mut producer = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", big.to_str().unwrap(), "--out", "-"]).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    drop(producer.stdout.take());
    let out = producer.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{err}");
    assert!(err.contains("closed the stream") && err.matches("error").count() == 1, "one error, no other failure: {err}");
}

/// A reader that takes every frame but closes the pipe before the stream's closing records
/// (its summary, more than a pipe's buffer holds) got a stream a reader calls damaged: the
/// producer says so and exits 141, though the sweep itself finished.
#[test]
fn a_stream_closed_before_its_summary_is_no_success() {
    let dir = forward("pipe-summary", &["--n", "4", "--aspect", "1", "--steps", "3000", "--clv-steps", "1500", "--transient", "50"]);
    let d = dir.to_str().unwrap();
    let whole = clv(&["backward", d, "--out", "-", "--quiet"]);
    assert!(whole.status.success(), "{}", String::from_utf8_lossy(&whole.stderr));
    let bytes = whole.stdout;
    // MCAP records after the 8-byte magic: opcode, u64 length, content; the summary follows
    // the Data End record (opcode 0x0F).
    let mut at = 8;
    while bytes[at] != 0x0f {
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    let summary_start = at + 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    assert!(bytes.len() - summary_start > 96 << 10, "the closing records exceed a pipe's buffer: {} bytes", bytes.len() - summary_start);
    let mut producer = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", d, "--out", "-", "--quiet"]).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut reader = producer.stdout.take().unwrap();
    let mut got = vec![0u8; summary_start];
    std::io::Read::read_exact(&mut reader, &mut got).unwrap();
    drop(reader);
    let out = producer.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{err}");
    assert!(err.contains("closing records") && err.contains("the sweep finished") && err.contains("clv_spectrum.json"), "{err}");
    assert!(got == bytes[..summary_start], "every frame came, as in the whole stream");
}

fn read_frames_from(input: impl std::io::Read, into: &mut Vec<Frame>) {
    clv::store::segment::read_stream(Path::new("<pipe>"), input, clv::store::segment::ReadMode::Strict, |m| {
        if m.topic == clv::store::schema::FRAME.topic {
            into.push(Frame::decode(m.data).unwrap());
        }
        Ok(())
    })
    .unwrap();
}

/// With `--store-r all` the frames are those of a run that stores R at checkpoints only,
/// and a stored R_n altered (in a valid segment) stops the backward stage, naming the step.
#[test]
fn stored_r_matrices_give_the_same_frames() {
    let flags = ["--n", "8", "--aspect", "1", "--steps", "1500", "--clv-steps", "300", "--transient", "300"];
    let plain = forward("store-r-plain", &flags);
    let all = forward("store-r-all", &[&flags[..], &["--store-r", "all"]].concat());
    let count_r = |dir: &Path| -> u64 {
        let out = ok(clv(&["inspect", dir.to_str().unwrap(), "--json"]));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["segments"].as_array().unwrap().iter().map(|s| s["r_matrices"].as_u64().unwrap()).sum()
    };
    // Both store R at checkpoints; `all` adds every other step of the 600-step window.
    let extra = count_r(&all) - count_r(&plain);
    assert!(extra >= 600 - 600 / 100 - 1, "R of every window step is stored: {extra} more than at checkpoints");
    let (a, b) = (backward_json(&plain, &[]), backward_json(&all, &[]));
    assert_eq!(a["exponents"], b["exponents"]);
    assert!(frames(&plain.join("frames.mcap")) == frames(&all.join("frames.mcap")));
    // One bit of R_1400's last packed entry, a step between checkpoints in the window.
    common::alter_message(&all, clv::store::schema::R.topic, 1400, |data| {
        let (step, mut r) = clv::store::records::decode_r(data).unwrap();
        let k = r.ncols();
        r[(k - 1, k - 1)] = f64::from_bits(r[(k - 1, k - 1)].to_bits() ^ 1);
        clv::store::records::encode_r(step, &r)
    });
    let out = clv(&["backward", all.to_str().unwrap(), "--quiet", "--out", all.join("again.mcap").to_str().unwrap()]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("R_n at step 1400 stored in") && err.contains("is not the recomputed one"), "{err}");
    assert!(!err.contains("panicked"));
}

/// A run on two threads gives the frames of the same run on one, bit for bit: the QR step
/// and the tangent replay do not depend on the thread count, and the backward stage moves
/// the recomputation between one and two threads as the sweep works and waits, with every
/// segment checked against its stored checkpoint. D = k = 264 is large enough for the QR
/// to split its work.
#[test]
fn two_threads_give_the_frames_of_one() {
    let flags = ["--n", "66", "--density", "0.7", "--relax-steps", "20", "--steps", "400", "--clv-steps", "200", "--transient", "100", "--checkpoint-every", "50"];
    let one = forward("threads-1", &[&flags[..], &["--threads", "1"]].concat());
    let two = forward("threads-2", &[&flags[..], &["--threads", "2"]].concat());
    let (r1, r2) = (backward_json(&one, &["--with-gs"]), backward_json(&two, &["--with-gs"]));
    assert_eq!(r1["statistics"]["frames"], 201);
    assert_eq!(r1["exponents"], r2["exponents"]);
    let (f1, f2) = (frames(&one.join("frames.mcap")), frames(&two.join("frames.mcap")));
    assert_eq!(f1.len(), 201);
    assert!(f1 == f2, "the frames of the two-thread run differ from the one-thread run");
    // The threads are the process's, not the run's: the one-thread run replayed on two, and
    // a one-thread run cut short and continued on two, give the same run and frames.
    let on_two = one.parent().unwrap().join("on-two.mcap");
    ok(clv(&["backward", one.to_str().unwrap(), "--quiet", "--with-gs", "--threads", "2", "--out", on_two.to_str().unwrap()]));
    assert!(frames(&on_two) == f1, "the one-thread run replayed on two threads");
    std::fs::remove_file(&on_two).unwrap();
    // A sweep cut short on one thread and resumed on two.
    let cut_sweep = one.parent().unwrap().join("cut-sweep.mcap");
    let c = cut_sweep.to_str().unwrap();
    let crashed = common::clv_env(&["backward", one.to_str().unwrap(), "--quiet", "--with-gs", "--out", c], &[("CLV_FAULT_CRASH_AT", "frames-synced#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    ok(clv(&["backward", one.to_str().unwrap(), "--quiet", "--with-gs", "--out", c, "--resume", "--threads", "2"]));
    assert!(frames(&cut_sweep) == f1, "a sweep resumed on two threads");
    std::fs::remove_file(&cut_sweep).unwrap();
    let cut = scratch("threads-cut").join("run");
    // Segments of two checkpoints, so that the crash leaves finished ones to continue from.
    let args = [&["forward", "--quiet", "--out", cut.to_str().unwrap(), "--threads", "1", "--segment-checkpoints", "2"], &flags[..]].concat();
    let crashed = common::clv_env(&args, &[("CLV_FAULT_CRASH_AT", "segment-renamed#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    ok(clv(&["forward", "--resume", cut.to_str().unwrap(), "--threads", "2", "--quiet"]));
    assert_eq!(common::contents(&cut).exponents, common::contents(&one).exponents, "a run continued on two threads");
    // Its backward stage verifies every recomputed segment against the checkpoints written
    // on either number of threads.
    let (cut_report, cut_frames) = (backward_json(&cut, &["--with-gs"]), frames(&cut.join("frames.mcap")));
    assert_eq!(cut_report["exponents"], r1["exponents"]);
    assert!(cut_frames == f1, "the frames of the run continued on two threads");
    // Too few or too many threads are refused before anything is written: the last sweep's
    // record and its frame file stay as they were (a refusal after them left a sweep that
    // never ran for `analyze` and `inspect` to find).
    let record = std::fs::read(one.join("backward.json")).unwrap();
    for threads in ["0", "5000"] {
        let other = one.join("other.mcap");
        let refused = clv(&["backward", one.to_str().unwrap(), "--threads", threads, "--out", other.to_str().unwrap(), "--quiet"]);
        assert!(!refused.status.success() && common::stderr(&refused).contains("invalid --threads: must be between 1 and 4096"), "{}", common::stderr(&refused));
        assert!(std::fs::read(one.join("backward.json")).unwrap() == record && !other.exists() && !one.join("other.mcap.tmp").exists());
        let refused = clv(&["forward", "--resume", cut.to_str().unwrap(), "--steps", "100000", "--threads", threads, "--quiet"]);
        assert!(!refused.status.success() && common::stderr(&refused).contains("invalid --threads"), "{}", common::stderr(&refused));
    }
}

/// The sweep reuses a frame's buffers once its consumer has dropped it: a consumer that lets
/// most frames go sees the same frames, bit for bit, as one that keeps every frame (so that
/// no buffer is ever reused), V and G alike.
#[test]
fn reused_frame_buffers_give_the_frames_of_fresh_ones() {
    use clv::stage::backward::{self, BackwardOptions};
    use clv::store::frames::Flow;
    use clv::store::run::RunDir;
    use std::sync::Arc;
    let dir = forward("reuse", &["--n", "16", "--relax-steps", "10", "--steps", "120", "--clv-steps", "60", "--transient", "20", "--checkpoint-every", "25"]);
    let (_, meta) = RunDir::open(&dir).unwrap();
    let mut opts = BackwardOptions::for_run(&meta);
    opts.with_gs = true;
    opts.save_every = 0;
    let sweep = |keep: &dyn Fn(u64) -> bool| {
        let (mut seen, mut kept) = (Vec::new(), Vec::new());
        backward::run(&dir, &opts, false, u64::MAX, None, &mut |f: Arc<Frame>| {
            seen.push((f.step, f.v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), f.g.as_ref().unwrap().iter().map(|x| x.to_bits()).collect::<Vec<_>>()));
            if keep(f.step) {
                kept.push(f);
            }
            Ok(Flow::Continue)
        }, &mut |_, _| {})
        .unwrap();
        seen
    };
    let reused = sweep(&|step| step % 7 == 0);
    let fresh = sweep(&|_| true);
    assert_eq!(reused.len(), 61);
    assert!(reused == fresh, "frames built in reused buffers differ from frames built in fresh ones");
}

/// A sweep with other options does not replace the CLV spectrum of an earlier one: that is
/// kept as clv_spectrum-1.json (and named); a sweep with the same options replaces its own.
#[test]
fn an_earlier_sweeps_clv_spectrum_is_kept_beside_a_new_one() {
    let dir = forward("kept-spectrum", &["--n", "8", "--aspect", "1", "--steps", "600", "--clv-steps", "100"]);
    let d = dir.to_str().unwrap();
    backward_json(&dir, &["--save-every", "0"]);
    let first = std::fs::read(dir.join("clv_spectrum.json")).unwrap();
    let out = ok(clv(&["backward", d, "--save-every", "0", "--c-init", "random"]));
    assert!(common::stderr(&out).contains("kept as") && common::stderr(&out).contains("clv_spectrum-1.json"), "{}", common::stderr(&out));
    assert_eq!(std::fs::read(dir.join("clv_spectrum-1.json")).unwrap(), first);
    let second = std::fs::read(dir.join("clv_spectrum.json")).unwrap();
    assert_ne!(second, first);
    backward_json(&dir, &["--save-every", "0", "--c-init", "random"]);
    assert!(!dir.join("clv_spectrum-2.json").exists(), "the same sweep again replaces its own spectrum");
}

/// A sweep that writes no frame file records none, and `clv analyze RUN_DIR` then refuses
/// to stand in an earlier sweep's frames.mcap for it, naming the sweep and how to write a
/// file: after `--save-every 0`, after a stream, when the sweep's file is gone, and while
/// it is unfinished. A `--save-every 0` sweep continues with `--resume` as such (no stream
/// on standard output), and a record of an earlier build (the default file named with
/// --save-every 0) still continues.
#[test]
fn analyze_run_dir_reads_only_the_last_sweeps_own_file() {
    let dir = forward("last-sweep-file", &["--n", "8", "--steps", "600", "--relax-steps", "50", "--clv-steps", "100"]);
    let d = dir.to_str().unwrap();
    let base = dir.parent().unwrap().to_path_buf();
    let analyze = |name: &str| {
        let rep = base.join(name);
        (clv(&["analyze", d, "--out", rep.to_str().unwrap(), "--only", "spectrum", "--quiet"]), rep)
    };
    let refused = |(out, rep): (std::process::Output, PathBuf), what: &str| {
        let err = common::stderr(&out);
        assert!(!out.status.success() && err.contains("the run's last backward sweep") && err.contains(what) && err.contains(&format!("clv backward {d} --out")), "{err}");
        assert!(!rep.exists(), "a refused analysis wrote {}", rep.display());
    };
    ok(clv(&["backward", d, "--transient", "20", "--c-init", "random", "--quiet"]));
    let (out, rep) = analyze("first");
    ok(out);
    assert!(read_text(&rep.join("index.html")).contains("frames.mcap"));
    // Only the CLV spectrum: no frame file recorded, in the progress record or the spectrum.
    ok(clv(&["backward", d, "--save-every", "0", "--quiet"]));
    let spectrum: serde_json::Value = serde_json::from_str(&read_text(&dir.join("clv_spectrum.json"))).unwrap();
    let record: serde_json::Value = serde_json::from_str(&read_text(&dir.join("backward.json"))).unwrap();
    for options in [&spectrum["options"], &record["options"]] {
        assert!(options["frames_path"].is_null() && options["no_frames"] == true, "{options}");
    }
    refused(analyze("spectrum-only"), "computed only the CLV spectrum (`--save-every 0`)");
    let shown = String::from_utf8(clv(&["inspect", d]).stdout).unwrap();
    assert!(shown.contains("backward sweep: finished, ") && shown.contains("(no frame file)"), "{shown}");
    let (out, _) = analyze("spectrum-only-2");
    assert!(common::stderr(&out).contains("frames.mcap is an earlier sweep's"), "{}", common::stderr(&out));
    // Interrupted after its first segment, it continues with --resume alone, to the same spectrum.
    let crashed = common::clv_env(&["backward", d, "--save-every", "0", "--quiet"], &[("CLV_FAULT_CRASH_AT", "atomic-renamed#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    let resumed = ok(clv(&["backward", d, "--resume", "--quiet"]));
    assert!(!resumed.stdout.starts_with(b"\x89MCAP"), "a resumed sweep without frames streamed them");
    let again: serde_json::Value = serde_json::from_str(&read_text(&dir.join("clv_spectrum.json"))).unwrap();
    assert_eq!(again["exponents"], spectrum["exponents"]);
    // A record of an earlier build named the default file with --save-every 0: it still
    // continues, and still wrote no file.
    let mut legacy = record.clone();
    legacy["options"]["frames_path"] = "frames.mcap".into();
    legacy["options"].as_object_mut().unwrap().remove("no_frames");
    legacy.as_object_mut().unwrap().remove("crc32");
    common::reseal(&dir.join("backward.json"), &legacy.to_string());
    ok(clv(&["backward", d, "--resume", "--quiet"]));
    refused(analyze("legacy"), "computed only the CLV spectrum");
    // A stream.
    let streamed = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", d, "--out", "-", "--quiet"]).stdout(Stdio::piped()).output().unwrap();
    assert!(streamed.status.success() && streamed.stdout.starts_with(b"\x89MCAP"));
    refused(analyze("stream"), "streamed its frames");
    // The advice repeats what the sweep computed (GS vectors, V_n every 2nd step, its
    // transient and start), as a
    // stream first (`clv run`'s sweep is one), and says how large the file would be.
    let streamed = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", d, "--out", "-", "--with-gs", "--vectors-every", "2", "--transient", "20", "--c-init", "random", "--quiet"]).stdout(Stdio::piped()).output().unwrap();
    assert!(streamed.status.success());
    let (out, _) = analyze("stream-gs");
    let err = common::stderr(&out);
    let same = "--with-gs --vectors-every 2 --transient 20 --c-init random";
    let stream = format!("`clv backward {d} {same} --out - | clv analyze - --out REPORT`; or write a frame file with `clv backward {d} {same} --out {d}/NAME.mcap` (about ");
    assert!(!out.status.success() && err.contains(&stream), "{err}");
    // A file outside the run: read while it is there, refused once it is gone.
    let outside = base.join("outside.mcap");
    ok(clv(&["backward", d, "--out", outside.to_str().unwrap(), "--quiet"]));
    let (out, rep) = analyze("outside");
    ok(out);
    assert!(read_text(&rep.join("index.html")).contains("outside.mcap"));
    std::fs::remove_file(&outside).unwrap();
    refused(analyze("gone"), &format!("wrote {}, which is gone", outside.display()));
    refused(analyze("gone"), "analyse it by name: `clv analyze FILE --out REPORT`");
    // An unfinished sweep into a file: continue it first.
    let crashed = common::clv_env(&["backward", d, "--out", outside.to_str().unwrap(), "--quiet"], &[("CLV_FAULT_CRASH_AT", "atomic-renamed#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    let (out, rep) = analyze("unfinished");
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("has not finished writing") && err.contains(&format!("clv backward {d} --resume")), "{err}");
    assert!(!rep.exists());
    // Without a sweep record (a run of a build before them): the run's frames.mcap, as before.
    std::fs::remove_file(base.join("outside.mcap.tmp")).unwrap();
    std::fs::remove_file(dir.join("backward.json")).unwrap();
    ok(analyze("no-record").0);
}

/// `clv analyze RUN_DIR` reads the frame file the last sweep recorded only if it holds that
/// run's frames from that sweep: another run's file copied over it, or an earlier sweep's
/// restored over it, is refused, naming what differs (and `clv inspect RUN_DIR` finds it);
/// by its name either is read.
#[test]
fn analyze_run_dir_refuses_a_file_of_another_run_or_sweep() {
    let flags = ["--n", "8", "--steps", "600", "--relax-steps", "50", "--clv-steps", "100"];
    let (one, two) = (forward("foreign-frames-1", &flags), forward("foreign-frames-2", &[&flags[..], &["--seed", "2"]].concat()));
    for dir in [&one, &two] {
        ok(clv(&["backward", dir.to_str().unwrap(), "--quiet"]));
    }
    let analyze = |source: &Path, name: &str| {
        let rep = one.parent().unwrap().join(name);
        (clv(&["analyze", source.to_str().unwrap(), "--out", rep.to_str().unwrap(), "--only", "spectrum", "--quiet"]), rep)
    };
    let refused = |(out, rep): (std::process::Output, PathBuf), what: &str| {
        let err = common::stderr(&out);
        assert!(!out.status.success() && err.contains(what) && err.contains("analyse the file by name"), "{err}");
        assert!(!rep.exists(), "a refused analysis wrote {}", rep.display());
    };
    std::fs::copy(one.join("frames.mcap"), two.join("frames.mcap")).unwrap();
    refused(analyze(&two, "foreign-run"), "holds another run's frames (--seed 2 in run.json, 1 in the file)");
    let seen = clv(&["inspect", two.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&seen.stdout).to_string();
    assert!(!seen.status.success() && text.contains("is not its file: it holds another run's frames"), "{text}");
    ok(analyze(&two.join("frames.mcap"), "foreign-run-by-name").0);
    let other = one.join("other.mcap");
    ok(clv(&["backward", one.to_str().unwrap(), "--out", other.to_str().unwrap(), "--transient", "20", "--quiet"]));
    ok(analyze(&one, "last-sweep").0);
    std::fs::copy(one.join("frames.mcap"), &other).unwrap();
    refused(analyze(&one, "earlier-sweep"), "did not write it: another sweep did");
}

fn read_text(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The size `clv backward --out FILE` warns about when the disk is short is the size of the
/// file it writes (frames are stored uncompressed): with GS vectors, every third frame kept,
/// vectors in every other step's frame.
#[test]
fn the_frame_file_estimate_is_the_files_size() {
    let dir = forward("frame-estimate", &["--n", "16", "--vectors", "64", "--steps", "300", "--clv-steps", "90", "--transient", "20"]);
    let file = dir.join("sampled.mcap");
    ok(clv(&["backward", dir.to_str().unwrap(), "--quiet", "--with-gs", "--save-every", "3", "--vectors-every", "2", "--out", file.to_str().unwrap()]));
    let (run, meta) = clv::store::RunDir::open(&dir).unwrap();
    let mut opts = clv::stage::backward::BackwardOptions::for_run(&meta);
    (opts.with_gs, opts.save_every, opts.vectors_every, opts.frames_path) = (true, 3, 2, Some(file.clone()));
    let estimate = clv::stage::backward::frame_file_bytes(&run, &meta, &opts) as f64;
    let size = std::fs::metadata(&file).unwrap().len() as f64;
    let with_vectors = frames(&file).iter().filter(|f| !f.v.is_empty()).count();
    assert!(with_vectors > 5 && with_vectors < frames(&file).len(), "the file should mix frames with and without vectors");
    assert!((0.97..1.03).contains(&(estimate / size)), "estimated {estimate} bytes, the file has {size}");
}

/// A sweep into a file outside the run, interrupted, then the run made longer: the sweep's
/// record went with the shorter run's results, so its FILE.tmp cannot be continued, and a
/// new sweep into the same file says so (it advised a --resume that found no sweep).
#[test]
fn an_interrupted_sweep_of_a_run_made_longer_since_is_named() {
    let dir = forward("outside-extended", &["--n", "8", "--aspect", "1", "--steps", "600", "--relax-steps", "50", "--clv-steps", "100", "--checkpoint-every", "20"]);
    let d = dir.to_str().unwrap();
    let file = dir.parent().unwrap().join("outside.mcap");
    let f = file.to_str().unwrap();
    let crashed = common::clv_env(&["backward", d, "--out", f, "--quiet"], &[("CLV_FAULT_CRASH_AT", "atomic-renamed#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    assert!(dir.parent().unwrap().join("outside.mcap.tmp").exists());
    ok(clv(&["forward", "--resume", d, "--steps", "700", "--quiet"]));
    let again = clv(&["backward", d, "--out", f, "--quiet"]);
    let err = common::stderr(&again);
    assert!(!again.status.success() && err.contains("of this run as it was with 600 steps, before it was made longer: that sweep cannot be continued") && err.contains("delete the file"), "{err}");
    std::fs::remove_file(dir.parent().unwrap().join("outside.mcap.tmp")).unwrap();
    ok(clv(&["backward", d, "--out", f, "--quiet"]));
}
