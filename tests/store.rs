//! The run store under normal use and under faults: round trips, SIGKILL at random points
//! followed by --resume, truncated and corrupted segments, and MCAP validity.

mod common;
use clv::config::{RunConfig, SystemConfig};
use clv::rng::Rng;
use clv::stage::forward::Forward;
use clv::statistics::block_len;
use clv::store::records::Checkpoint;
use clv::store::RunDir;
use common::{clv, contents, copy_dir, kill_after, kill_landing, ok, Contents};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    common::scratch("store", name)
}

const RUN: [&str; 16] = [
    "forward", "--n", "36", "--aspect", "1", "--steps", "3000", "--relax-steps", "100",
    "--checkpoint-every", "50", "--segment-checkpoints", "4", "--clv-steps", "400", "--quiet",
];

/// The uninterrupted run every fault test compares with, made once per test binary, and
/// how long it took (milliseconds).
fn reference_run() -> &'static (PathBuf, Contents, f64) {
    static REF: std::sync::OnceLock<(PathBuf, Contents, f64)> = std::sync::OnceLock::new();
    REF.get_or_init(|| {
        let dir = common::shared_scratch("store", "reference").join("run");
        let started = std::time::Instant::now();
        let out = clv(&[&RUN[..], &["--out", dir.to_str().unwrap()]].concat());
        let ms = started.elapsed().as_secs_f64() * 1e3;
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let c = contents(&dir);
        (dir, c, ms)
    })
}

fn reference() -> (PathBuf, &'static Contents) {
    let (dir, c, _) = reference_run();
    (dir.clone(), c)
}

fn reference_ms() -> f64 {
    reference_run().2
}

/// A private copy of the reference run, for tests that change it.
fn reference_copy(name: &str) -> (PathBuf, &'static Contents) {
    let (dir, c) = reference();
    let copy = scratch(name).join("run");
    copy_dir(&dir, &copy);
    (copy, c)
}

#[test]
fn checkpoint_round_trip_continues_bit_identically() {
    let config = RunConfig {
        system: SystemConfig::disks(16, 0.7, 1.0).unwrap(),
        tau: 0.6,
        relax_steps: 5,
        steps: 60,
        vectors: 40,
        seed: 3,
        threads: 1,
        blocks: 7,
    };
    let mut a = Forward::new(&config).unwrap();
    while a.step < 30 {
        a.step().unwrap();
    }
    let cp = Checkpoint { state: a.state(), time: a.time(), system: "disks".into(), d: 64, k: 40 };
    let back = Checkpoint::decode(&cp.encode()).unwrap();
    assert_eq!(back, cp);
    let mut b = Forward::resume(&config, &back.state).unwrap();
    while a.step < 65 {
        a.step().unwrap();
        b.step().unwrap();
    }
    assert_eq!(a.state(), b.state());
    assert_eq!(a.acc.exponents(0.6), b.acc.exponents(0.6));
}

#[test]
fn killed_runs_resume_to_identical_results() {
    let (_, want) = reference();
    assert!(want.files.len() >= 3, "the reference should span several segments: {:?}", want.files);
    // Pruning kept the window (last 400 + 200 steps) and two older segments only.
    assert!(want.checkpoints.keys().next().copied().unwrap() > 0);
    // Kills at shares of the uninterrupted run's time (each first kill lands: see
    // kill_landing), in one trial the resuming process killed again.
    let run_ms = reference_ms();
    for (trial, shares) in [vec![0.1], vec![0.45], vec![0.25, 0.55], vec![0.9]].into_iter().enumerate() {
        let dir = scratch(&format!("killed-{trial}")).join("run");
        let d = dir.to_str().unwrap().to_string();
        let first: Vec<&str> = [&RUN[..], &["--out", &d]].concat();
        kill_landing(&first, (shares[0] * run_ms) as u64, || drop(std::fs::remove_dir_all(&dir)));
        for share in &shares[1..] {
            kill_after(&["forward", "--resume", &d, "--quiet"], (share * run_ms) as u64);
        }
        let out = clv(&["forward", "--resume", dir.to_str().unwrap()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let got = contents(&dir);
        assert_eq!(got.files, want.files);
        assert!(got == *want, "trial {trial}: resumed run differs from the uninterrupted one");
    }
}

#[test]
fn resuming_a_finished_run_does_nothing_and_conflicts_are_refused() {
    let (dir, want) = reference_copy("finished");
    let d = dir.to_str().unwrap();
    let out = clv(&["forward", "--resume", d]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("already complete"));
    assert!(contents(&dir) == *want);
    let out = clv(&["forward", "--resume", d, "--steps", "2000"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--steps 2000 is fewer than the 3000 steps of the run") && err.contains("give more to extend it"), "{err}");
    let out = clv(&["forward", "--resume", d, "--clv-steps", "300"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--clv-steps 300 conflicts"), "a new window alone is refused: {err}");
    // Killed while run.json's temporary file was half written: nothing to resume, and
    // starting again in the same directory works.
    let fresh = scratch("half-created").join("run");
    std::fs::create_dir_all(&fresh).unwrap();
    std::fs::write(fresh.join("run.tmp"), b"{\"format\": \"clv-run").unwrap();
    let out = clv(&["forward", "--resume", fresh.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("interrupted while it was being created") && err.contains("clv forward --out"), "{err}");
    ok(clv(&[&RUN[..], &["--out", fresh.to_str().unwrap()]].concat()));
    assert!(contents(&fresh) == *want);
    // Killed between its last segment and spectrum.json: resuming writes the spectrum.
    let spectrum = |dir: &Path| -> serde_json::Value { serde_json::from_str(&std::fs::read_to_string(dir.join("spectrum.json")).unwrap()).unwrap() };
    let before = spectrum(&dir);
    std::fs::remove_file(dir.join("spectrum.json")).unwrap();
    let out = clv(&["forward", "--resume", d]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && err.contains("was not written yet"), "{err}");
    assert!(contents(&dir) == *want);
    let after = spectrum(&dir);
    assert_eq!((&after["exponents"], &after["stderr"], &after["statistics"]["collisions"]), (&before["exponents"], &before["stderr"], &before["statistics"]["collisions"]));
    let out = clv(&["forward", "--resume", d, "--n", "36", "--seed", "1"]);
    assert!(out.status.success(), "flags equal to the stored ones are fine: {}", String::from_utf8_lossy(&out.stderr));
    let out = clv(&[&RUN[..], &["--out", d]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("not empty (it holds a run: continue it with `clv forward --resume"), "{err}");
    assert!(!err.contains("clv: writing"), "refused, yet announced as being written: {err}");
    assert!(contents(&dir) == *want, "a refused command must not touch the run");
    // A directory of other files is no run to resume.
    let other = dir.with_file_name("other-files");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    let out = clv(&[&RUN[..], &["--out", other.to_str().unwrap()]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("holds files of something other than a run") && !err.contains("--resume"), "{err}");
    assert_eq!(std::fs::read_dir(&other).unwrap().count(), 1, "nothing was written");
}

fn damage(path: &Path, rng: &mut Rng, truncate: bool) -> String {
    let mut bytes = std::fs::read(path).unwrap();
    if truncate {
        let cut = rng.below(bytes.len());
        bytes.truncate(cut);
        std::fs::write(path, &bytes).unwrap();
        format!("cut at {cut}")
    } else {
        let at = rng.below(bytes.len());
        bytes[at] ^= 1 << rng.below(8);
        std::fs::write(path, &bytes).unwrap();
        format!("bit flipped at {at}")
    }
}

/// A run made longer with `--resume --steps` is the longer run made at once: the same
/// trajectory, G_n and exponent sums at every checkpoint both keep, the same spectrum and
/// covariant vectors, bit for bit. Only the standard error's blocks differ; they double in
/// length and stay between B and 2B. The shorter run's results are kept byte for byte, and
/// an extension killed at any durable step ends the same when repeated.
#[test]
fn an_extended_run_is_the_longer_run_and_keeps_the_shorter_ones_results() {
    const BASE: [&str; 14] = ["forward", "--n", "16", "--aspect", "1", "--relax-steps", "100", "--checkpoint-every", "50", "--segment-checkpoints", "4", "--blocks", "4", "--quiet"];
    let run = |dir: &Path, steps: &str, clv_steps: &str| ok(clv(&[&BASE[..], &["--steps", steps, "--clv-steps", clv_steps, "--out", dir.to_str().unwrap()]].concat()));
    let backward = |dir: &Path| ok(clv(&["backward", dir.to_str().unwrap(), "--quiet"]));
    let (short, long) = (scratch("extend-short").join("run"), scratch("extend-long").join("run"));
    // 530 + 100 steps end between two checkpoints: the extension continues from the run's
    // extra last checkpoint, which the longer run does not have. The longer window (800 +
    // 400 steps, from step 400) takes the backward stage across that step, and across step
    // 1156, where the 8 blocks of 132 steps become 4 of 264.
    run(&short, "530", "200");
    backward(&short);
    // A second sweep with other options: the first one's CLV spectrum is kept beside it, and
    // moves with it when the run is extended.
    ok(clv(&["backward", short.to_str().unwrap(), "--quiet", "--save-every", "0", "--c-init", "random"]));
    // A report kept inside the run (where `clv analyze RUN --out RUN` points) describes the
    // shorter run and goes with its results; a directory of the user's own stays.
    ok(clv(&["analyze", short.join("frames.mcap").to_str().unwrap(), "--out", short.join("report").to_str().unwrap(), "--only", "spectrum", "--quiet"]));
    std::fs::create_dir_all(short.join("notes")).unwrap();
    run(&long, "1500", "800");
    backward(&long);
    let before: BTreeMap<&str, Vec<u8>> = ["spectrum.json", "clv_spectrum.json", "clv_spectrum-1.json", "frames.mcap"].into_iter().map(|f| (f, std::fs::read(short.join(f)).unwrap())).collect();
    let extended = scratch("extend-crash-ref").join("run");
    copy_dir(&short, &extended);
    let extend = |dir: &Path, env: &[(&str, &str)]| common::clv_env(&["forward", "--resume", dir.to_str().unwrap(), "--steps", "1500", "--clv-steps", "800", "--quiet"], env);
    ok(extend(&extended, &[]));
    let kept = extended.join("previous-530-steps");
    assert!(kept.join("report/summary.json").exists() && !extended.join("report").exists() && extended.join("notes").is_dir(), "the report inside the run did not go with the shorter run's results");
    let shown = String::from_utf8(clv(&["inspect", extended.to_str().unwrap()]).stdout).unwrap();
    assert!(shown.contains("previous-530-steps/  the results of the run before it was extended"), "{shown}");
    for (f, bytes) in &before {
        assert!(std::fs::read(kept.join(f)).unwrap() == *bytes, "{f} of the shorter run is not kept as it was");
        assert!(!extended.join(f).exists() || *f == "spectrum.json", "{f} of the shorter run left in the run");
    }
    let (a, b) = (contents(&extended), contents(&long));
    assert_eq!(a.exponents, b.exponents, "spectrum");
    let common: Vec<u64> = b.checkpoints.keys().filter(|s| a.checkpoints.contains_key(s)).copied().collect();
    assert!(common.len() >= 24 && common.contains(&400) && common.contains(&1600) && a.checkpoints.contains_key(&630), "checkpoints {common:?}");
    for s in &common {
        let (x, y) = (&a.checkpoints[s], &b.checkpoints[s]);
        assert!(x.system == y.system && x.g == y.g && x.acc.sum == y.acc.sum, "checkpoint at step {s}");
    }
    let acc = &a.checkpoints[&1600].acc;
    assert!((4..8).contains(&acc.blocks.len()) && acc.block_len == 2 * block_len(530, 4), "{} blocks of {}", acc.blocks.len(), acc.block_len);
    backward(&extended);
    assert!(common::frames(&extended.join("frames.mcap")) == common::frames(&long.join("frames.mcap")), "covariant vectors");
    // Killed while it extends: repeating the command gives the same run.
    let want = contents(&extended);
    for at in ["result-moved#1", "result-moved#4", "atomic-synced#1", "atomic-renamed#1", "segment-synced#2", "segment-renamed#3", "forward-done#1", "atomic-renamed#2"] {
        let dir = scratch(&format!("extend-crash-{at}")).join("run");
        copy_dir(&short, &dir);
        let out = extend(&dir, &[("CLV_FAULT_CRASH_AT", at)]);
        assert_eq!(out.status.code(), Some(clv::store::fault::CRASH_STATUS), "{at} not reached: {}", common::stderr(&out));
        ok(extend(&dir, &[]));
        assert!(contents(&dir) == want, "extension killed at {at}");
        for (f, bytes) in &before {
            assert!(std::fs::read(dir.join("previous-530-steps").join(f)).unwrap() == *bytes, "{at}: {f}");
        }
    }
    // Killed after the shorter run's results went aside, before the new run.json was in
    // place: a plain --resume (what the stage's messages and inspect advise) finishes the
    // extension from run.tmp, instead of finishing the shorter run beside its moved results,
    // which then blocked the extension; without a whole run.tmp it asks for the extension's
    // command.
    let dir = scratch("extend-crash-plain-resume").join("run");
    copy_dir(&short, &dir);
    assert_eq!(extend(&dir, &[("CLV_FAULT_CRASH_AT", "atomic-synced#1")]).status.code(), Some(clv::store::fault::CRASH_STATUS));
    let torn = scratch("extend-crash-torn").join("run");
    copy_dir(&dir, &torn);
    let err = common::stderr(&ok(clv(&["forward", "--resume", dir.to_str().unwrap()])));
    assert!(err.contains("was interrupted after the results of the shorter run went to") && contents(&dir) == want, "{err}");
    std::fs::write(torn.join("run.tmp"), "{\"cut\": ").unwrap();
    let out = clv(&["forward", "--resume", torn.to_str().unwrap(), "--quiet"]);
    assert!(!out.status.success() && common::stderr(&out).contains("give the extension's command again"), "{}", common::stderr(&out));
    ok(extend(&torn, &[]));
    assert!(contents(&torn) == want, "the extension given again after a torn run.tmp");
    // Killed while the shorter run's results move aside, after spectrum.json went first: the
    // run is not taken for finished at its old length; a plain --resume and inspect ask for
    // the extension's command, and a backward sweep for the finished forward run first.
    let moving = scratch("extend-crash-moving").join("run");
    copy_dir(&short, &moving);
    assert_eq!(extend(&moving, &[("CLV_FAULT_CRASH_AT", "result-moved#1")]).status.code(), Some(clv::store::fault::CRASH_STATUS));
    assert!(moving.join("previous-530-steps/spectrum.json").exists() && !moving.join("spectrum.json").exists());
    let out = clv(&["forward", "--resume", moving.to_str().unwrap(), "--quiet"]);
    assert!(!out.status.success() && common::stderr(&out).contains("give the extension's command again"), "{}", common::stderr(&out));
    let shown = String::from_utf8(ok(clv(&["inspect", moving.to_str().unwrap()])).stdout).unwrap();
    assert!(shown.contains("an extension of it was interrupted: give the extension's command again"), "{shown}");
    let out = clv(&["backward", moving.to_str().unwrap(), "--quiet"]);
    assert!(!out.status.success() && common::stderr(&out).contains("no spectrum.json"), "{}", common::stderr(&out));
    ok(extend(&moving, &[]));
    assert!(contents(&moving) == want, "the extension given again after it was killed moving the results");
    // A full disk there: the message gives the extension's command, with its new length.
    let full = scratch("extend-full").join("run");
    copy_dir(&short, &full);
    let err = common::stderr(&extend(&full, &[("CLV_FAULT_DISK_FULL_AFTER", "100")]));
    assert!(err.contains("disk full") && err.contains(&format!("continue with `clv forward --resume {} --steps 1500 --clv-steps 800`", full.display())), "{err}");
    ok(extend(&full, &[]));
    assert!(contents(&full) == want, "the extension continued after a full disk");
}

/// With `--store-r all`, an extension whose window starts earlier than the one the run had
/// leaves the R_n of the steps in between unstored (they were computed before the window
/// reached them): `clv inspect` says which, as a note, not as damage; an extension that
/// keeps its window after the old one's start says nothing.
#[test]
fn inspect_names_the_r_n_an_earlier_window_never_stored() {
    let run = scratch("r-window-earlier").join("run");
    let r = run.to_str().unwrap();
    let inspect = |r: &str| -> (String, serde_json::Value) {
        let text = String::from_utf8(ok(clv(&["inspect", r])).stdout).unwrap();
        (text, serde_json::from_slice(&ok(clv(&["inspect", r, "--json"])).stdout).unwrap())
    };
    // 100 relaxation steps + 300: the window of 100 CLV steps + 50 of transient starts at 250.
    ok(clv(&["forward", "--n", "8", "--aspect", "1", "--steps", "300", "--clv-steps", "100", "--checkpoint-every", "20", "--store-r", "all", "--out", r, "--quiet"]));
    let (text, json) = inspect(r);
    assert!(!text.contains("note:") && json.get("r_not_stored").is_none(), "{text}");
    // Made longer with the window's length: it starts at 350, after the old start.
    let later = scratch("r-window-later").join("run");
    copy_dir(&run, &later);
    ok(clv(&["forward", "--resume", later.to_str().unwrap(), "--steps", "400", "--quiet"]));
    assert!(!inspect(later.to_str().unwrap()).0.contains("note:"));
    // 100 + 400 steps with 250 + 125: the window starts at 125, the run stored R_n from 251.
    ok(clv(&["forward", "--resume", r, "--steps", "400", "--clv-steps", "250", "--quiet"]));
    let (text, json) = inspect(r);
    assert!(text.contains("note: the R_n of steps 126..250 are not stored (but at the checkpoints)") && text.contains("(--clv-steps, --transient) to step 125"), "{text}");
    assert!(json["intact"] == true && json["r_not_stored"].as_str().is_some_and(|n| n.contains("126..250")), "{json}");
    // A segment deleted there is a gap, named as damage with the R_n it held (251..380 of
    // the old window), not taken into the note.
    let holed = scratch("r-window-holed").join("run");
    copy_dir(&run, &holed);
    std::fs::remove_file(holed.join("seg-000000000200-000000000380.mcap")).unwrap();
    let text = String::from_utf8(clv(&["inspect", holed.to_str().unwrap()]).stdout).unwrap();
    assert!(text.contains("the checkpoints and R_n of steps 200..380 are missing") && text.contains("note: the R_n of steps 126..180 are not stored"), "{text}");
    // Later (to 450), then earlier (to 210): the base run's 211..250 and the first extension's
    // 401..450 are missing, 251..400 stored. 401..419 lie between two segments (the one
    // written under the window of 450 begins at the checkpoint of 420).
    let twice = scratch("r-window-twice").join("run");
    let t = twice.to_str().unwrap();
    ok(clv(&["forward", "--n", "8", "--aspect", "1", "--steps", "300", "--clv-steps", "100", "--checkpoint-every", "20", "--store-r", "all", "--out", t, "--quiet"]));
    ok(clv(&["forward", "--resume", t, "--steps", "500", "--quiet"]));
    ok(clv(&["forward", "--resume", t, "--steps", "560", "--clv-steps", "300", "--transient", "150", "--quiet"]));
    let (text, _) = inspect(t);
    assert!(text.contains("note: the R_n of steps 211..250, 401..450 are not stored"), "{text}");
}

/// run.json edited by hand (or damaged) so that it describes another trajectory is refused
/// by both stages and named by `clv inspect`, against the copy every segment carries; the
/// copy put beside it restores the run. Lengths and windows may differ (an extension).
#[test]
fn an_edited_run_json_is_refused_and_restored_from_the_segments_copy() {
    let (dir, want) = reference_copy("edited-meta");
    let d = dir.to_str().unwrap();
    let meta = dir.join("run.json");
    let original = std::fs::read_to_string(&meta).unwrap();
    std::fs::remove_file(dir.join("spectrum.json")).unwrap();
    std::fs::write(&meta, original.replace("\"tau\": 0.6", "\"tau\": 0.5")).unwrap();
    for args in [vec!["forward", "--resume", d, "--quiet"], vec!["backward", d, "--quiet"], vec!["inspect", d]] {
        let out = clv(&args);
        let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(!out.status.success() && text.contains("run.json") && text.contains("edited or damaged"), "{args:?}: {text}");
    }
    assert!(!dir.join("spectrum.json").exists(), "nothing computed with the wrong tau");
    std::fs::rename(dir.join("run.json.from-segments"), &meta).unwrap();
    // Fields that leave the trajectory alone are covered by run.json's checksum: a changed
    // build (which would be blamed on another build) or length (which would extend the run
    // silently) is refused as an edit, with the same way out.
    let restored = std::fs::read_to_string(&meta).unwrap();
    for (from, to) in [("\"arch\": \"x86_64\"", "\"arch\": \"x87_64\""), ("\"steps\": 3000", "\"steps\": 3300")] {
        assert!(restored.contains(from), "{from} in {restored}");
        std::fs::write(&meta, restored.replace(from, to)).unwrap();
        for args in [vec!["forward", "--resume", d, "--quiet"], vec!["backward", d, "--quiet"], vec!["inspect", d]] {
            let out = clv(&args);
            let text = String::from_utf8_lossy(&out.stderr).to_string();
            assert!(!out.status.success() && text.contains("checksum") && text.contains("run.json.from-segments"), "{to}, {args:?}: {text}");
        }
        std::fs::rename(dir.join("run.json.from-segments"), &meta).unwrap();
    }
    assert!(!dir.join("spectrum.json").exists(), "nothing computed from an edited run.json");
    // Nor does removing the checksum with the edit pass: a run.json without one (an earlier
    // build's) must agree with the newest segment's copy.
    let mut v: serde_json::Value = serde_json::from_str(&restored).unwrap();
    v.as_object_mut().unwrap().remove("crc32");
    v["config"]["steps"] = 1500.into();
    std::fs::write(&meta, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    for args in [vec!["forward", "--resume", d, "--quiet"], vec!["backward", d, "--quiet"], vec!["inspect", d]] {
        let out = clv(&args);
        let text = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(!out.status.success() && text.contains("carries no checksum") && text.contains("run.json.from-segments"), "{args:?}: {text}");
    }
    v["config"]["steps"] = 3000.into();
    std::fs::write(&meta, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    ok(clv(&["inspect", d]));
    std::fs::rename(dir.join("run.json.from-segments"), &meta).unwrap();
    // Deleted, it is restored the same way.
    std::fs::remove_file(&meta).unwrap();
    let out = clv(&["forward", "--resume", d, "--quiet"]);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success() && err.contains("missing") && err.contains("run.json.from-segments"), "{err}");
    std::fs::rename(dir.join("run.json.from-segments"), &meta).unwrap();
    ok(clv(&["forward", "--resume", d, "--quiet"]));
    assert!(contents(&dir) == *want);
}

#[test]
fn damaged_segments_are_named_and_resume_falls_back() {
    let (dir, want) = reference();
    let mut rng = Rng::new(2024);
    let base = scratch("damaged");
    // Any single damage to any segment is detected, with the file named.
    for trial in 0..40 {
        let copy = base.join(format!("inspect-{trial}"));
        copy_dir(&dir, &copy);
        let segs = RunDir { path: copy.clone() }.segments().unwrap();
        let seg = &segs[rng.below(segs.len())];
        let what = damage(&seg.path, &mut rng, trial % 2 == 0);
        let out = clv(&["inspect", copy.to_str().unwrap()]);
        let text = String::from_utf8_lossy(&out.stdout);
        let name = seg.path.file_name().unwrap().to_string_lossy();
        assert!(!out.status.success(), "{what} in {name} went unnoticed");
        assert!(text.lines().any(|l| l.contains(&*name) && l.contains("corrupt")), "{what}: {text}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("clv forward --resume"), "the way to repair it is named");
        assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
    }
    // Damage to the newest segment: resume moves it aside and recomputes it.
    for trial in 0..4 {
        let copy = base.join(format!("resume-{trial}"));
        copy_dir(&dir, &copy);
        let newest = RunDir { path: copy.clone() }.segments().unwrap().pop().unwrap();
        let what = damage(&newest.path, &mut rng, trial % 2 == 0);
        let out = clv(&["forward", "--resume", copy.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{what}: {err}");
        assert!(err.contains("moving it aside"), "{what}: {err}");
        assert!(contents(&copy) == *want, "{what}: resumed run differs");
    }
    // Damage to an older segment of a finished run: resume recomputes only its steps, from
    // the checkpoint before it (bit-identical numbers), leaves the segments after it as they
    // are (the same files), and keeps only the damaged file aside.
    for trial in 0..4 {
        use std::os::unix::fs::MetadataExt;
        let copy = base.join(format!("repair-{trial}"));
        copy_dir(&dir, &copy);
        let segs = RunDir { path: copy.clone() }.segments().unwrap();
        // Not the oldest, which has no checkpoint before it (the next case).
        let seg = &segs[1 + rng.below(segs.len() - 2)];
        let inodes = |copy: &Path| -> BTreeMap<String, u64> {
            RunDir { path: copy.to_path_buf() }.segments().unwrap().iter().filter(|s| s.first != seg.first).map(|s| (s.path.file_name().unwrap().to_string_lossy().into_owned(), std::fs::metadata(&s.path).unwrap().ino())).collect()
        };
        let others = inodes(&copy);
        let what = damage(&seg.path, &mut rng, trial % 2 == 0);
        if trial == 0 {
            // The repair itself crashes after writing its first segment; the next one ends it.
            let out = common::clv_env(&["forward", "--resume", copy.to_str().unwrap()], &[("CLV_FAULT_CRASH_AT", "segment-renamed")]);
            assert_eq!(out.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", String::from_utf8_lossy(&out.stderr));
        }
        let out = clv(&["forward", "--resume", copy.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{what}: {err}");
        let i = segs.iter().position(|s| s == seg).unwrap();
        let recomputing = format!("recomputing steps {}..{} (no intact segment holds the steps between)", segs[i - 1].last, segs[i + 1].first);
        assert!(trial == 0 || (err.contains("moving it aside") && err.contains(&recomputing) && !err.contains("recomputed with the rest")), "{what}: {err}");
        assert!(contents(&copy) == *want, "{what}: repaired run differs");
        assert!(inodes(&copy) == others, "{what}: segments other than the damaged one were rewritten");
        let aside: Vec<String> = std::fs::read_dir(&copy).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).filter(|n| !n.ends_with(".mcap") && !n.ends_with(".json") && !n.starts_with('.')).collect();
        assert_eq!(aside, vec![seg.path.with_extension("mcap.corrupt").file_name().unwrap().to_string_lossy().into_owned()]);
        let seen = clv(&["inspect", copy.to_str().unwrap()]);
        let text = String::from_utf8_lossy(&seen.stdout);
        assert!(seen.status.success() && text.lines().any(|l| l.contains(&aside[0]) && l.contains("safe to delete")), "{text}");
    }
    // The backward stage meeting a damaged segment says how to repair it.
    let copy = base.join("backward-hint");
    copy_dir(&dir, &copy);
    let newest = RunDir { path: copy.clone() }.segments().unwrap().pop().unwrap();
    let len = std::fs::metadata(&newest.path).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&newest.path).unwrap().set_len(len / 2).unwrap();
    let out = clv(&["backward", copy.to_str().unwrap(), "--quiet", "--out", "-"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains(&*newest.path.to_string_lossy()) && err.contains("clv forward --resume"), "{err}");
}

#[test]
fn files_are_valid_mcap_for_the_crate_reader_with_embedded_schemas() {
    let (dir, _) = reference();
    let run = RunDir { path: dir.clone() };
    let seg = &run.segments().unwrap()[0];
    let bytes = std::fs::read(&seg.path).unwrap();
    let mut topics = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(m.channel.message_encoding, "cbor");
        assert_eq!(schema.encoding, "jsonschema");
        let text: serde_json::Value = serde_json::from_slice(&schema.data).unwrap();
        assert_eq!(text["x-topic"], m.channel.topic.as_str());
        *topics.entry(m.channel.topic.clone()).or_insert(0) += 1;
    }
    assert_eq!(topics.len(), 3, "{topics:?}");
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let meta_index = summary.metadata_indexes.iter().find(|i| i.name == "clv.run").unwrap();
    let meta = mcap::read::metadata(&bytes, meta_index).unwrap();
    let run_json: serde_json::Value = serde_json::from_str(&meta.metadata["run.json"]).unwrap();
    assert_eq!(run_json["config"]["system"]["n"], 36, "every file says how it was made");
}

#[test]
fn python_reader_reads_every_channel() {
    if !common::python_has("mcap, cbor2, numpy") {
        return;
    }
    let (dir, want) = reference();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/read_run.py");
    let out = Command::new("python3").arg(script).arg(&dir).arg("--json").output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["checkpoints"].as_u64().unwrap() as usize, want.checkpoints.len());
    assert_eq!(v["r_matrices"].as_u64().unwrap() as usize, want.rs.len());
    let last = *want.checkpoints.keys().last().unwrap();
    assert_eq!(v["last_step"], last);
    let exps: Vec<f64> = serde_json::from_value(v["exponents"].clone()).unwrap();
    assert_eq!(exps, want.stats[&last].0, "Python decodes the same bits");
    assert!(v["max_orthonormality_error"].as_f64().unwrap() < 1e-12, "G read by Python is orthonormal");
    assert!(v["r_upper_positive"].as_bool().unwrap());
}

#[test]
fn henon_runs_through_the_same_store() {
    let dir = scratch("henon").join("run");
    let d = dir.to_str().unwrap();
    let out = clv(&["forward", "--system", "henon", "--steps", "5000", "--relax-steps", "100", "--checkpoint-every", "100", "--out", d, "--quiet", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let want = contents(&dir);
    assert!((want.exponents[0] + want.exponents[1] - 0.3f64.ln()).abs() < 1e-12);
    // Lose the newest segment and the result; resume recomputes them identically.
    let run = RunDir { path: dir.clone() };
    std::fs::remove_file(run.segments().unwrap().pop().unwrap().path).unwrap();
    std::fs::remove_file(run.spectrum_path()).unwrap();
    assert!(clv(&["forward", "--resume", d, "--quiet"]).status.success());
    assert!(contents(&dir) == want, "resumed Henon run differs");
    let out = clv(&["inspect", d, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["finished"], true);
    assert_eq!(v["intact"], true);
    assert_eq!(v["steps_done"], 5100);
    // The text adds what the spectrum implies: h_KS = lambda_1 and D_KY = 1 + lambda_1 / |lambda_2|.
    let l: Vec<f64> = serde_json::from_value(v["exponents"].clone()).unwrap();
    let text = String::from_utf8(clv(&["inspect", d]).stdout).unwrap();
    let want = format!("whole run: h_KS = {:.5}, D_KY = {:.5}", l[0], 1.0 + l[0] / l[1].abs());
    assert!(text.contains(&format!("spectrum: lambda_1.. = {:.5}, {:.5}\n", l[0], l[1])), "a finished run's, each exponent once: {text}");
    assert!(text.contains(&want), "{text} lacks {want}");
    // And the convergence tests over the 20 blocks of 250 steps (two exponents, both vary).
    assert_eq!((&v["convergence"]["blocks"], &v["convergence"]["block_steps"]), (&serde_json::json!(20), &serde_json::json!(250)));
    assert!(text.contains("convergence (20 blocks of 250 steps): ") && text.contains(" of 2 exponents have |z| > 2"), "{text}");
}

/// A segment missing between two others (moved out, deleted) is a gap the backward stage
/// would stop at: `clv inspect` names the missing steps, and `clv forward --resume`
/// recomputes them and what follows, bit for bit. A segment of another run copied in over
/// one of this run's is named as the odd one out, not blamed on run.json.
#[test]
fn a_missing_or_foreign_segment_is_named_and_resume_restores_the_run() {
    let (dir, want) = reference_copy("gap");
    let d = dir.to_str().unwrap();
    let segments = RunDir { path: dir.clone() }.segments().unwrap();
    assert!(segments.len() >= 3, "{segments:?}");
    let middle = segments[segments.len() / 2].clone();
    let aside = dir.parent().unwrap().join("aside.mcap");
    std::fs::rename(&middle.path, &aside).unwrap();
    let out = clv(&["inspect", d]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success() && text.contains(&format!("steps {}..", middle.first)) && text.contains("are missing"), "{text}");
    ok(clv(&["forward", "--resume", d, "--quiet"]));
    assert!(contents(&dir) == *want, "the run recomputed across the gap differs");

    // The newest segment deleted from a complete run (inspect called it unfinished and
    // intact), and a write of spectrum.json killed before its rename (its .tmp was kept).
    let newest = segments.last().unwrap();
    std::fs::remove_file(&newest.path).unwrap();
    std::fs::write(dir.join("spectrum.tmp"), b"{").unwrap();
    let out = clv(&["inspect", d]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success() && text.contains(&format!("no segment holds its steps after {}", segments[segments.len() - 2].last)), "{text}");
    let err = common::stderr(&ok(clv(&["forward", "--resume", d])));
    assert!(contents(&dir) == *want && !dir.join("spectrum.tmp").exists() && !err.contains("already complete"), "{err}");
    std::fs::write(dir.join("spectrum.tmp"), b"{").unwrap();
    let err = common::stderr(&ok(clv(&["forward", "--resume", d])));
    assert!(!dir.join("spectrum.tmp").exists() && err.contains("already complete"), "{err}");
    std::fs::remove_file(dir.join("spectrum.json")).unwrap();
    let err = common::stderr(&ok(clv(&["forward", "--resume", d])));
    assert!(err.contains("was not written yet; writing it") && !err.contains("already complete") && contents(&dir) == *want, "{err}");

    // Another run's segment of the same steps in place of this one's.
    let other = scratch("gap-other").join("run");
    ok(clv(&[&RUN[..], &["--seed", "99", "--out", other.to_str().unwrap()]].concat()));
    let theirs = RunDir { path: other.clone() }.segments().unwrap().into_iter().find(|s| s.first == middle.first && s.last == middle.last).expect("same layout");
    std::fs::copy(&theirs.path, &middle.path).unwrap();
    let seen = String::from_utf8_lossy(&clv(&["inspect", d]).stdout).to_string();
    assert!(seen.contains(&format!("{} written for another run than run.json", middle.path.display())), "{seen}");
    for args in [vec!["backward", d, "--quiet"], vec!["forward", "--resume", d, "--quiet"]] {
        let out = clv(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        let name = middle.path.file_name().unwrap().to_string_lossy();
        assert!(!out.status.success() && err.contains(&*name) && err.contains("another run") && err.contains("move it out"), "{args:?}: {err}");
        assert!(!dir.join("run.json.from-segments").exists(), "run.json was blamed");
    }
    std::fs::remove_file(&middle.path).unwrap();
    ok(clv(&["forward", "--resume", d, "--quiet"]));
    assert!(contents(&dir) == *want);
}

/// Resume `dir` and compare it with `want`.
fn contents_after_resume_is(dir: &Path, want: &Contents) -> bool {
    ok(clv(&["forward", "--resume", dir.to_str().unwrap(), "--quiet"]));
    contents(dir) == *want
}

/// A hole in the segments is recomputed from the checkpoint before it, and the recomputation
/// must arrive at the next segment's first checkpoint bit for bit. Here that checkpoint was
/// altered in a file with valid CRCs (rewritten whole, as another build's numbers would be):
/// resume sees the difference, names it, and recomputes the segments from there on as well,
/// back to the undamaged run's numbers. With `--store-r all` the hole ends just before the
/// next segment's first R_n, not at a checkpoint of the grid.
#[test]
fn a_hole_is_recomputed_on_its_own_and_must_arrive_at_the_next_checkpoint() {
    use clv::store::schema::{CHECKPOINT, RUN_SCHEMAS};
    use clv::store::segment::{embedded_run_json, read_segment, ReadMode, SegmentWriter, RUN_METADATA};
    let (dir, want) = reference_copy("hole-differs");
    let d = dir.to_str().unwrap();
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    let (hole, next) = (&segs[segs.len() - 3], &segs[segs.len() - 2]);
    std::fs::remove_file(&hole.path).unwrap();
    let run_json = embedded_run_json(&next.path).unwrap();
    let mut messages = Vec::new();
    read_segment(&next.path, ReadMode::Strict, |m| {
        if m.topic != RUN_METADATA {
            messages.push((m.topic.to_string(), m.step, m.data.to_vec()));
        }
        Ok(())
    })
    .unwrap();
    let first = messages.iter().position(|(t, _, _)| t == CHECKPOINT.topic).unwrap();
    let mut cp = Checkpoint::decode(&messages[first].2).unwrap();
    cp.state.g[7] = -cp.state.g[7];
    messages[first].2 = cp.encode();
    std::fs::remove_file(&next.path).unwrap();
    let mut w = SegmentWriter::create(&dir, next.first, &run_json, &RUN_SCHEMAS).unwrap();
    for (topic, step, data) in &messages {
        w.write(topic, *step, data).unwrap();
    }
    assert_eq!(w.finish().unwrap(), next.path);
    // Killed once the segments from the altered one on are set aside, before the recomputed
    // ones go in: the next resume continues the run from the checkpoint before the hole.
    let crashed = common::clv_env(&["forward", "--resume", d], &[("CLV_FAULT_CRASH_AT", "repair-set-aside")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    assert!(contents_after_resume_is(&dir, want), "a repair killed between setting aside and moving in differs");
    let (dir, want) = reference_copy("hole-differs-2");
    let d = dir.to_str().unwrap();
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    let (hole, next) = (&segs[segs.len() - 3], &segs[segs.len() - 2]);
    std::fs::remove_file(&hole.path).unwrap();
    std::fs::remove_file(&next.path).unwrap();
    let mut w = SegmentWriter::create(&dir, next.first, &run_json, &RUN_SCHEMAS).unwrap();
    for (topic, step, data) in &messages {
        w.write(topic, *step, data).unwrap();
    }
    assert_eq!(w.finish().unwrap(), next.path);
    let err = common::stderr(&ok(clv(&["forward", "--resume", d])));
    assert!(err.contains(&format!("recomputing steps {}..{}", segs[segs.len() - 4].last, next.first)), "{err}");
    assert!(err.contains(&format!("do not arrive at the first checkpoint of {} (G_n element 7", next.path.display())) && err.contains("recomputed with the rest of the run"), "{err}");
    assert!(contents(&dir) == *want, "the run repaired past the altered checkpoint differs");
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".superseded")));

    // A damaged segment with the one after it gone: the hole reaches to the next segment,
    // not only to the damaged file's last step (one resume left the second one missing).
    let (dir, want) = reference_copy("hole-damaged-and-gone");
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    damage(&segs[segs.len() - 4].path, &mut Rng::new(3), true);
    std::fs::remove_file(&segs[segs.len() - 3].path).unwrap();
    ok(clv(&["forward", "--resume", dir.to_str().unwrap(), "--quiet"]));
    assert!(contents(&dir) == *want && clv(&["inspect", dir.to_str().unwrap()]).status.success(), "one resume did not restore the run");

    // --store-r all: the segments of the window begin with an R_n, right after the last step
    // of the segment before.
    let run = scratch("hole-r-all").join("run");
    let r = run.to_str().unwrap();
    ok(clv(&["forward", "--n", "8", "--aspect", "1", "--steps", "600", "--clv-steps", "200", "--checkpoint-every", "20", "--segment-checkpoints", "3", "--store-r", "all", "--out", r, "--quiet"]));
    let want = contents(&run);
    let segs = RunDir { path: run.clone() }.segments().unwrap();
    let (hole, next) = (&segs[segs.len() - 3], &segs[segs.len() - 2]);
    assert!(next.first == hole.last + 1 && next.first % 20 != 0, "{segs:?}");
    std::fs::remove_file(&hole.path).unwrap();
    let err = common::stderr(&ok(clv(&["forward", "--resume", r])));
    assert!(err.contains(&format!("recomputing steps {}..{}", segs[segs.len() - 4].last, (next.first / 20 + 1) * 20)) && !err.contains("recomputed with the rest"), "{err}");
    assert!(contents(&run) == want, "the run repaired with --store-r all differs");
    let steps = |segs: Vec<clv::store::run::SegmentFile>| segs.iter().map(|s| (s.first, s.last)).collect::<Vec<_>>();
    assert_eq!(steps(RunDir { path: run.clone() }.segments().unwrap()), steps(segs), "the segments are those of the undamaged run");
}

/// A copy of the segment `seg` written anew into the directory `into` (valid CRCs), with
/// only the messages `keep` accepts and the checkpoints changed by `change`, under the
/// name the writer gives it.
fn rewrite_segment(seg: &Path, into: &Path, keep: impl Fn(u64) -> bool, change: impl Fn(&mut Checkpoint)) -> PathBuf {
    use clv::store::schema::{CHECKPOINT, RUN_SCHEMAS};
    use clv::store::segment::{embedded_run_json, read_segment, ReadMode, SegmentWriter, RUN_METADATA};
    let run_json = embedded_run_json(seg).unwrap();
    let mut messages = Vec::new();
    read_segment(seg, ReadMode::Strict, |m| {
        if m.topic != RUN_METADATA && keep(m.step) {
            let mut data = m.data.to_vec();
            if m.topic == CHECKPOINT.topic {
                let mut cp = Checkpoint::decode(&data).unwrap();
                change(&mut cp);
                data = cp.encode();
            }
            messages.push((m.topic.to_string(), m.step, data));
        }
        Ok(())
    })
    .unwrap();
    std::fs::create_dir_all(into).unwrap();
    let mut w = SegmentWriter::create(into, messages[0].1, &run_json, &RUN_SCHEMAS).unwrap();
    for (topic, step, data) in &messages {
        w.write(topic, *step, data).unwrap();
    }
    w.finish().unwrap()
}

/// A repair changes nothing it cannot verify. Where the recomputation from the checkpoint
/// before a hole does not arrive at the next segment's first checkpoint, and that starting
/// checkpoint does not follow from the one before it either (here it was altered, in a file
/// with valid CRCs), resume stops, naming both files, and rewrites none of the segments
/// after the hole (it recomputed them all from the altered checkpoint). A copy of some of a
/// segment's steps put back beside it is set aside at no cost (it was taken for a hole,
/// then for a mismatch that recomputed the rest of the run).
#[test]
fn a_repair_changes_nothing_it_cannot_verify() {
    use std::os::unix::fs::MetadataExt;
    let inodes = |segs: &[clv::store::run::SegmentFile]| segs.iter().map(|s| std::fs::metadata(&s.path).map(|m| m.ino()).ok()).collect::<Vec<_>>();
    let (dir, _) = reference_copy("repair-unverifiable");
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    let (after, hole, next) = (&segs[segs.len() - 4], &segs[segs.len() - 3], &segs[segs.len() - 2]);
    let altered = rewrite_segment(&after.path, &scratch("repair-unverifiable-altered"), |_| true, |cp| {
        if cp.state.step == after.last {
            cp.state.g[3] = -cp.state.g[3];
        }
    });
    std::fs::rename(&altered, &after.path).unwrap();
    std::fs::remove_file(&hole.path).unwrap();
    let later = inodes(&segs[segs.len() - 2..]);
    let out = clv(&["forward", "--resume", dir.to_str().unwrap()]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains(&format!("recomputed from the last checkpoint of {} do not arrive at the first checkpoint of {}", after.path.display(), next.path.display())), "{err}");
    assert!(err.contains("does not follow from the one before it either (G_n element 3") && err.contains("clv cannot tell which"), "{err}");
    assert_eq!(inodes(&segs[segs.len() - 2..]), later, "segments after the hole were changed");
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".superseded")));
    // Nor is the hole filled with steps grown from the checkpoint in doubt: a second resume
    // stops the same way (it found the hole filled and the run complete).
    assert!(!hole.path.exists() && !dir.join(clv::store::repair::UNVERIFIED).exists());
    let again = clv(&["forward", "--resume", dir.to_str().unwrap()]);
    assert!(!again.status.success() && common::stderr(&again).contains("clv cannot tell which"), "{}", common::stderr(&again));

    // A file that cannot be read stops the resume before anything is moved: the damaged
    // segment beside it keeps its name.
    let (dir, _) = reference_copy("repair-unreadable");
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    damage(&segs[1].path, &mut Rng::new(5), false);
    std::fs::remove_file(&segs[3].path).unwrap();
    std::os::unix::fs::symlink(dir.join("nowhere"), &segs[3].path).unwrap();
    let out = clv(&["forward", "--resume", dir.to_str().unwrap()]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("nothing was changed") && segs[1].path.exists() && !segs[1].path.with_extension("mcap.corrupt").exists(), "{err}");

    let (dir, want) = reference_copy("repair-contained");
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    let seg = &segs[segs.len() - 3];
    let copy = rewrite_segment(&seg.path, &scratch("repair-contained-copy"), |step| step == seg.last, |_| ());
    let put_back = dir.join(copy.file_name().unwrap());
    std::fs::rename(&copy, &put_back).unwrap();
    let before = inodes(&segs);
    let err = common::stderr(&ok(clv(&["forward", "--resume", dir.to_str().unwrap()])));
    assert!(err.contains(&format!("{} holds steps {} holds too", put_back.display(), seg.path.display())) && !err.contains("recomputing"), "{err}");
    assert!(contents(&dir) == *want && inodes(&segs) == before && !put_back.exists(), "{err}");
}

/// A damaged segment of a run that is being made longer is repaired on the way: the
/// extension's command goes through at once, to the numbers of the run extended undamaged
/// (the old window, prunable once the run is longer, was pruned in the middle of the
/// repair, the segment it was to arrive at with it).
#[test]
fn a_damaged_run_is_repaired_while_it_is_made_longer() {
    let args = |dir: &Path| ["forward", "--n", "16", "--steps", "2010", "--checkpoint-every", "20", "--segment-checkpoints", "3", "--clv-steps", "800", "--transient", "200", "--quiet", "--out"].iter().map(|s| s.to_string()).chain([dir.display().to_string()]).collect::<Vec<_>>();
    let (clean, damaged) = (scratch("extend-damaged-clean").join("run"), scratch("extend-damaged").join("run"));
    for dir in [&clean, &damaged] {
        ok(clv(&args(dir).iter().map(String::as_str).collect::<Vec<_>>()));
    }
    let segs = RunDir { path: damaged.clone() }.segments().unwrap();
    damage(&segs[segs.len() / 2].path, &mut Rng::new(7), false);
    ok(clv(&["forward", "--resume", clean.to_str().unwrap(), "--steps", "3010", "--quiet"]));
    let out = ok(clv(&["forward", "--resume", damaged.to_str().unwrap(), "--steps", "3010"]));
    assert!(common::stderr(&out).contains("moving it aside"), "{}", common::stderr(&out));
    assert!(contents(&damaged) == contents(&clean), "the run repaired while extended differs");
}

/// A segment whose steps are not those its name says: two segments' names swapped, or a
/// stray copy under another name (which once made `clv inspect` report intact segments, or
/// steps "2800..2599" missing, while the backward stage stopped at the file and advised a
/// `clv forward --resume` that found nothing to do, or recomputed genuine segments, again
/// and again). Inspect names the file and what it holds; resume sets it aside and
/// recomputes only what no other segment holds (nothing, for the copy); the backward stage's
/// advice then leads to the undamaged run's CLV spectrum, bit for bit.
#[test]
fn a_misnamed_segment_is_named_and_resume_restores_the_run() {
    use clv::store::segment::final_name;
    let (clean, want) = reference_copy("misnamed-clean");
    ok(clv(&["backward", clean.to_str().unwrap(), "--quiet", "--save-every", "0"]));
    let clv_exponents = |dir: &Path| -> Vec<u64> {
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("clv_spectrum.json")).unwrap()).unwrap();
        v["exponents"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap().to_bits()).collect()
    };
    let want_clv = clv_exponents(&clean);
    for case in ["swapped", "stray copy"] {
        let (dir, _) = reference_copy(&format!("misnamed-{}", case.replace(' ', "-")));
        let d = dir.to_str().unwrap();
        let segs = RunDir { path: dir.clone() }.segments().unwrap();
        // Two adjacent segments inside the backward stage's window, neither the newest.
        let (a, b) = (&segs[segs.len() - 3], &segs[segs.len() - 2]);
        let misnamed: Vec<(PathBuf, (u64, u64))> = if case == "swapped" {
            let tmp = dir.join("swap.tmp");
            std::fs::rename(&a.path, &tmp).unwrap();
            std::fs::rename(&b.path, &a.path).unwrap();
            std::fs::rename(&tmp, &b.path).unwrap();
            vec![(a.path.clone(), (b.first, b.last)), (b.path.clone(), (a.first, a.last))]
        } else {
            let stray = dir.join(final_name(a.first, b.first));
            std::fs::copy(&a.path, &stray).unwrap();
            vec![(stray, (a.first, a.last))]
        };
        let seen = clv(&["inspect", d]);
        let text = String::from_utf8_lossy(&seen.stdout);
        assert!(!seen.status.success() && common::stderr(&seen).contains("clv forward --resume"), "{case}: {text}");
        for (path, (first, last)) in &misnamed {
            let name = path.file_name().unwrap().to_string_lossy();
            assert!(text.lines().any(|l| l.contains(&*name) && l.contains(&format!("it holds steps {first}..{last}, not steps")) && l.contains("as its name says")), "{case}: {text}");
        }
        assert!(!text.contains("are missing"), "{case}: a gap made up from a name: {text}");
        // The backward stage stops at the file, with the repair its advice names.
        let out = clv(&["backward", d, "--quiet", "--save-every", "0"]);
        let err = common::stderr(&out);
        assert!(!out.status.success() && misnamed.iter().any(|(p, _)| err.contains(&*p.to_string_lossy())) && err.contains(&format!("clv forward --resume {d}")), "{case}: {err}");
        let out = ok(clv(&["forward", "--resume", d]));
        let err = common::stderr(&out);
        for (path, _) in &misnamed {
            let aside = path.with_extension("mcap.corrupt");
            assert!(err.contains(&format!("moving it aside to {}", aside.display())) && aside.exists(), "{case}: {err}");
        }
        // Swapped names are written anew under their names; the stray copy's name is gone.
        assert_eq!(misnamed.iter().all(|(p, _)| p.exists()), case == "swapped", "{case}");
        // A stray copy costs no recomputation; swapped names cost their own steps.
        assert_eq!(err.contains(&format!("recomputing steps {}..{}", segs[segs.len() - 4].last, segs[segs.len() - 1].first)), case == "swapped", "{case}: {err}");
        assert!(!err.contains("resuming") && !err.contains("recomputed with the rest"), "{case}: {err}");
        assert!(contents(&dir) == *want, "{case}: the repaired run differs");
        let seen = clv(&["inspect", d]);
        assert!(seen.status.success(), "{case}: {}", String::from_utf8_lossy(&seen.stdout));
        ok(clv(&["backward", d, "--quiet", "--save-every", "0"]));
        assert!(clv_exponents(&dir) == want_clv, "{case}: the CLV spectrum differs from the undamaged run's");
        // A second resume finds nothing more to do.
        let again = common::stderr(&ok(clv(&["forward", "--resume", d])));
        assert!(again.contains("already complete") && !again.contains("moving it aside"), "{case}: {again}");
    }
}

/// Before the first segment, only the checkpoints from where the backward stage starts are
/// needed (the older ones are pruned by design). A stray copy named before the first segment
/// is set aside at no cost (it made resume start the run over); the segments the backward
/// stage starts from, deleted, are named by inspect and recomputed from step 0 (neither
/// inspect nor resume noticed, and backward's advice led nowhere).
#[test]
fn checkpoints_before_the_first_segment_are_missing_only_where_the_backward_stage_needs_them() {
    use clv::store::segment::final_name;
    let (clean, want) = reference_copy("leading-clean");
    ok(clv(&["backward", clean.to_str().unwrap(), "--quiet", "--save-every", "0"]));
    let clv_exponents = |dir: &Path| -> serde_json::Value { serde_json::from_slice::<serde_json::Value>(&std::fs::read(dir.join("clv_spectrum.json")).unwrap()).unwrap()["exponents"].clone() };
    let want_clv = clv_exponents(&clean);
    // A stray copy of a kept segment under a name before all of them.
    let (dir, _) = reference_copy("leading-stray");
    let d = dir.to_str().unwrap();
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    assert!(segs[0].first > 0, "the reference run keeps no segment from step 0: {segs:?}");
    let stray = dir.join(final_name(0, 150));
    std::fs::copy(&segs[1].path, &stray).unwrap();
    let err = common::stderr(&ok(clv(&["forward", "--resume", d])));
    assert!(err.contains("moving it aside") && !err.contains("follows") && !err.contains("step 0"), "{err}");
    assert!(contents(&dir) == *want && !stray.exists());
    // The oldest kept segments deleted, down past the step the backward stage starts from.
    let (dir, _) = reference_copy("leading-missing");
    let d = dir.to_str().unwrap();
    let segs = RunDir { path: dir.clone() }.segments().unwrap();
    let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("run.json")).unwrap()).unwrap();
    let (store, config) = (&meta["store"], &meta["config"]);
    let start = config["relax_steps"].as_u64().unwrap() + config["steps"].as_u64().unwrap() - store["clv_steps"].as_u64().unwrap() - store["transient"].as_u64().unwrap();
    let gone: Vec<_> = segs.iter().take_while(|s| s.first <= start).collect();
    assert!(gone.len() >= 2 && gone.len() < segs.len(), "{segs:?}");
    // Only the first of them missing is pruning's doing: no damage.
    std::fs::remove_file(&gone[0].path).unwrap();
    assert!(clv(&["inspect", d]).status.success());
    for s in &gone[1..] {
        std::fs::remove_file(&s.path).unwrap();
    }
    let seen = clv(&["inspect", d]);
    let text = String::from_utf8_lossy(&seen.stdout);
    assert!(!seen.status.success() && text.contains("from where the backward stage recomputes the run, are missing") && text.contains("recomputes them from step 0"), "{text}");
    let out = clv(&["backward", d, "--quiet", "--save-every", "0"]);
    assert!(!out.status.success() && common::stderr(&out).contains(&format!("`clv forward --resume {d}` recomputes it")), "{}", common::stderr(&out));
    // The repair stopped (killed) after it wrote two segments aside goes on from there.
    let crashed = common::clv_env(&["forward", "--resume", d], &[("CLV_FAULT_CRASH_AT", "segment-renamed#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    assert!(dir.join(clv::store::repair::UNVERIFIED).is_dir() && !segs.iter().any(|s| s.path.exists() && s.first <= start), "the unverified steps went into the run");
    let err = common::stderr(&ok(clv(&["forward", "--resume", d])));
    assert!(err.contains("going on from step") && err.contains("where a stopped repair left it"), "{err}");
    let next = segs.iter().find(|s| s.first > start).unwrap();
    assert!(err.contains(&format!("recomputing steps 0..{} (the backward stage needs the checkpoints from step", next.first)) && !err.contains("resuming"), "{err}");
    assert!(contents(&dir) == *want, "the recomputed run differs");
    ok(clv(&["backward", d, "--quiet", "--save-every", "0"]));
    assert!(clv_exponents(&dir) == want_clv, "the CLV spectrum differs from the undamaged run's");
}

/// A sweep into a frame file of its own name inside the run, interrupted, then the run
/// extended: the interrupted file goes with the shorter run's results into previous-*, so
/// that a new sweep into that name starts (before, the stranded FILE.tmp sent the user
/// between "continue with --resume" and "there is no sweep to continue").
#[test]
fn an_extension_keeps_an_interrupted_sweeps_own_frame_file_with_the_shorter_run() {
    let run = scratch("extend-interrupted").join("run");
    let r = run.to_str().unwrap();
    ok(clv(&["forward", "--n", "8", "--aspect", "1", "--steps", "600", "--clv-steps", "200", "--checkpoint-every", "20", "--out", r, "--quiet"]));
    let custom = run.join("custom.mcap");
    let crashed = common::clv_env(&["backward", r, "--out", custom.to_str().unwrap(), "--quiet"], &[("CLV_FAULT_CRASH_AT", "frames-synced#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    assert!(run.join("custom.mcap.tmp").exists());
    ok(clv(&["forward", "--resume", r, "--steps", "800", "--quiet"]));
    let previous = run.join("previous-600-steps");
    assert!(previous.join("custom.mcap.tmp").exists() && previous.join("backward.json").exists() && !run.join("custom.mcap.tmp").exists());
    assert!(!run.join("custom.mcap.lock").exists(), "the killed sweep's lock file stays behind");
    ok(clv(&["backward", r, "--out", custom.to_str().unwrap(), "--quiet"]));
    assert!(custom.exists());
    // Outside the run the file stays, named, with what a new sweep into it needs.
    let outside = run.with_file_name("outside.mcap");
    let crashed = common::clv_env(&["backward", r, "--out", outside.to_str().unwrap(), "--quiet"], &[("CLV_FAULT_CRASH_AT", "frames-synced#2")]);
    assert_eq!(crashed.status.code(), Some(clv::store::fault::CRASH_STATUS), "{}", common::stderr(&crashed));
    let extended = ok(clv(&["forward", "--resume", r, "--steps", "900"]));
    let err = common::stderr(&extended);
    assert!(err.contains("outside.mcap.tmp holds frames of the 800-step run") && err.contains("needs it moved aside first"), "{err}");
}

/// A report inside the run that an analysis is writing now is not moved, torn, into
/// previous-*: the extension is refused, naming it, and goes through once it is done.
#[test]
fn an_extension_does_not_move_a_report_being_written() {
    let run = scratch("extend-report-busy").join("run");
    let r = run.to_str().unwrap();
    ok(clv(&["forward", "--n", "8", "--aspect", "1", "--steps", "600", "--clv-steps", "200", "--out", r, "--quiet"]));
    ok(clv(&["backward", r, "--quiet"]));
    let report = run.join("report");
    ok(clv(&["analyze", r, "--out", report.to_str().unwrap(), "--only", "spectrum", "--quiet"]));
    let writing = clv::report::dir::lock_report(&report).unwrap();
    let out = clv(&["forward", "--resume", r, "--steps", "800", "--quiet"]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("another clv process is writing") && err.contains(&report.display().to_string()), "{err}");
    assert!(report.join("summary.json").exists() && run.join("spectrum.json").exists() && !run.join("previous-600-steps").exists(), "moved while refused");
    drop(writing);
    ok(clv(&["forward", "--resume", r, "--steps", "800", "--quiet"]));
    assert!(run.join("previous-600-steps/report/summary.json").exists());
}

/// The disk estimate printed before a run starts (and compared with the free space) is not
/// below what the finished run keeps, nor far above it: with checkpoints pruned down to the
/// backward window and the segments kept beside it, with and without every R_n stored.
/// (Measured: 3.6 MB estimated against 3.1 MB kept with --store-r all, 1.1 against 1.0 MB
/// without; the segments are compressed, the estimate is not.) Pruning removes whole
/// segments: with segments of 10 checkpoints the window's first segment starts 150 steps
/// (7 checkpoints) before the window, and is kept whole (an estimate of the window alone
/// was 27 checkpoints against 36 kept in an outside check).
#[test]
fn the_disk_estimate_covers_the_finished_run() {
    for (name, extra) in [("r-all", &["--store-r", "all"][..]), ("checkpoints", &[][..]), ("long-segments", &["--segment-checkpoints", "10"][..])] {
        let dir = scratch("footprint").join(name);
        let args = ["forward", "--n", "16", "--vectors", "64", "--steps", "2000", "--clv-steps", "100", "--transient", "50", "--checkpoint-every", "20", "--quiet", "--out", dir.to_str().unwrap()];
        let segment = if extra.contains(&"--segment-checkpoints") { &[][..] } else { &["--segment-checkpoints", "4"][..] };
        ok(clv(&[&args[..], segment, extra].concat()));
        let (_, meta) = RunDir::open(&dir).unwrap();
        let estimate = meta.store.footprint(&meta.config).bytes as f64;
        let kept: u64 = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().metadata().unwrap().len()).sum();
        let segments = std::fs::read_dir(&dir).unwrap().filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with("seg-")).count();
        assert!((3..=8).contains(&segments), "{name}: pruning should leave a few of the run's segments, found {segments}");
        let ratio = estimate / kept as f64;
        assert!((0.95..1.5).contains(&ratio), "{name}: estimated {estimate} bytes, the run keeps {kept} (ratio {ratio:.3})");
    }
}

/// Flip one bit of the seed in a segment's copy of run.json (a metadata record, outside any
/// chunk and its CRC; the data section's CRC still catches it).
fn flip_embedded_seed(path: &Path) {
    let mut bytes = std::fs::read(path).unwrap();
    let at = bytes.windows(9).position(|w| w == b"\"seed\":1,").expect("the copy of run.json names seed 1");
    bytes[at + 7] ^= 2;
    std::fs::write(path, bytes).unwrap();
}

/// A flipped bit in a segment's copy of run.json makes the segment damaged, not run.json
/// suspect: `clv forward --resume` recomputes the segment to the same numbers, whether
/// other segments agree with run.json (the newest and a middle one of the reference run)
/// or it is the run's only segment. (Before, the only segment's copy was offered as the
/// run.json to restore, and following that continued another seed's run; with other
/// segments, resume refused the segment as another run's.)
#[test]
fn a_damaged_copy_of_run_json_in_a_segment_is_repaired_not_believed() {
    for pick in ["newest", "middle"] {
        let (copy, want) = reference_copy(&format!("flipped-copy-{pick}"));
        let segs = RunDir { path: copy.clone() }.segments().unwrap();
        let seg = if pick == "newest" { segs.last() } else { segs.get(segs.len() / 2) }.unwrap();
        flip_embedded_seed(&seg.path);
        let out = clv(&["forward", "--resume", copy.to_str().unwrap()]);
        assert!(out.status.success(), "{pick}: {}", common::stderr(&out));
        assert!(contents(&copy) == *want, "{pick}: the repaired run differs");
        assert!(seg.path.with_extension("mcap.corrupt").exists() && !copy.join("run.json.from-segments").exists());
    }
    let dir = scratch("flipped-copy-only").join("run");
    let args = ["forward", "--n", "10", "--steps", "200", "--relax-steps", "20", "--checkpoint-every", "20", "--segment-checkpoints", "100", "--quiet", "--out", dir.to_str().unwrap()];
    ok(clv(&args));
    let want = contents(&dir);
    let only = RunDir { path: dir.clone() }.segments().unwrap();
    assert_eq!(only.len(), 1);
    flip_embedded_seed(&only[0].path);
    let out = clv(&["forward", "--resume", dir.to_str().unwrap()]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    assert!(contents(&dir) == want, "the repaired run differs");
}
