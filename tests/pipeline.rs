//! The whole pipeline: forward | backward | analyze through real pipes against the
//! in-process path, concurrent analyses against each analysis alone, and `clv run`.

mod common;
use common::{clv, ok};

fn scratch(name: &str) -> PathBuf {
    common::scratch("pipeline", name)
}

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

const RUN: [&str; 14] = ["forward", "--quiet", "--n", "10", "--aspect", "1", "--steps", "2000", "--clv-steps", "400", "--transient", "300", "--relax-steps", "200"];

/// A finished forward run of RUN in base/run.
fn forward_in(base: &Path) -> PathBuf {
    let run = base.join("run");
    ok(clv(&[&RUN[..], &["--out", run.to_str().unwrap()]].concat()));
    run
}

/// Tables every analysis writes whatever the system (compared byte for byte).
const TABLES: [&str; 2] = ["spectrum.csv", "localization.csv"];

#[test]
fn shell_pipes_give_the_same_numbers_as_files_and_concurrency_changes_nothing() {
    let base = scratch("pipes");
    let run = forward_in(&base);
    let r = run.to_str().unwrap();
    // Through real pipes: clv backward RUN --out - | clv analyze - --out DIR. The pipe
    // carries the frames newest first, the file gives them oldest first: with every 7th
    // frame sampled (by its step), both sample the same frames.
    let piped = base.join("piped");
    let mut backward = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", r, "--out", "-", "--with-gs", "--quiet"]).stdout(Stdio::piped()).spawn().unwrap();
    let analyze = Command::new(env!("CARGO_BIN_EXE_clv"))
        .args(["analyze", "-", "--out", piped.to_str().unwrap(), "--every", "7"])
        .stdin(backward.stdout.take().unwrap())
        .output()
        .unwrap();
    assert!(backward.wait().unwrap().success());
    assert!(analyze.status.success(), "{}", String::from_utf8_lossy(&analyze.stderr));
    // From a file written by the backward stage (into directories it makes).
    let frames = base.join("kept/frames/frames.mcap");
    ok(clv(&["backward", r, "--out", frames.to_str().unwrap(), "--with-gs", "--quiet"]));
    let filed = base.join("filed");
    ok(clv(&["analyze", frames.to_str().unwrap(), "--out", filed.to_str().unwrap(), "--every", "7"]));
    for t in TABLES {
        assert_eq!(read(&piped.join(t)), read(&filed.join(t)), "{t}: pipe and file differ");
    }
    // Each analysis alone gives the same numbers as all of them concurrently.
    for (name, table) in [("spectrum", "spectrum.csv"), ("localization", "localization.csv")] {
        let alone = base.join(format!("alone-{name}"));
        ok(clv(&["analyze", frames.to_str().unwrap(), "--out", alone.to_str().unwrap(), "--only", name, "--every", "7"]));
        assert_eq!(read(&alone.join(table)), read(&filed.join(table)), "{name}: alone and concurrent differ");
    }
    // --overwrite replaces a report: the files of the earlier one that the new one does not
    // write go, a file of the user's own stays.
    let again = base.join("alone-spectrum");
    std::fs::write(again.join("notes.txt"), "mine").unwrap();
    ok(clv(&["analyze", frames.to_str().unwrap(), "--out", again.to_str().unwrap(), "--only", "localization", "--every", "7", "--overwrite"]));
    assert!(!again.join("spectrum.csv").exists() && again.join("localization.csv").exists() && again.join("notes.txt").exists());
    let out = clv(&["analyze", frames.to_str().unwrap(), "--out", base.join("x").to_str().unwrap(), "--only", "nonsense"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--only") && err.contains("spectrum"), "{err}");
    // The CLV spectrum in the analysis equals the backward stage's own.
    let report: serde_json::Value = serde_json::from_str(&read(&run.join("clv_spectrum.json"))).unwrap();
    let first_row: Vec<f64> = read(&filed.join("spectrum.csv")).lines().nth(1).unwrap().split(',').map(|x| x.parse().unwrap()).collect();
    assert_eq!(first_row[4], report["exponents"][0].as_f64().unwrap());
    let html = read(&filed.join("index.html"));
    assert!(html.contains("fig2_spectrum.png") && html.contains("frames"));
    for png in ["fig2_spectrum.png", "fig5_localization.png", "fig5_localization_center.png", "fig8_mode_region.png"] {
        let bytes = std::fs::read(filed.join(png)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n") && bytes.len() > 5000, "{png}");
    }
}

#[test]
fn analyze_refuses_bad_sources_clearly() {
    let base = scratch("bad");
    let missing = base.join("missing.mcap");
    let out = clv(&["analyze", missing.to_str().unwrap(), "--out", base.join("o").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("missing.mcap"), "{err}");
    let junk = base.join("junk.mcap");
    std::fs::write(&junk, b"not an mcap file at all").unwrap();
    let out = clv(&["analyze", junk.to_str().unwrap(), "--out", base.join("o").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("junk.mcap") && !err.contains("panicked"), "{err}");
    // A directory that is no run, a run without frames, and a run segment instead of
    // frames: what to give or run instead.
    let err = common::stderr(&clv(&["analyze", base.to_str().unwrap(), "--out", base.join("o").to_str().unwrap()]));
    assert!(err.contains("is no run directory: give a frame file"), "{err}");
    let run = forward_in(&base);
    let err = common::stderr(&clv(&["analyze", run.to_str().unwrap(), "--out", base.join("o").to_str().unwrap()]));
    assert!(err.contains("a directory without a frame file") && err.contains("clv backward"), "{err}");
    // A forward run not finished yet: finish it first (its backward stage would refuse).
    let spectrum = run.join("spectrum.json");
    std::fs::rename(&spectrum, base.join("aside.json")).unwrap();
    let err = common::stderr(&clv(&["analyze", run.to_str().unwrap(), "--out", base.join("o").to_str().unwrap()]));
    assert!(err.contains("a forward run that has not finished") && err.contains(&format!("clv forward --resume {}", run.display())), "{err}");
    // An extension cut off after it moved the results aside: give its command again.
    let (dir, meta) = clv::store::RunDir::open(&run).unwrap();
    let previous = dir.previous_results(meta.config.steps);
    std::fs::create_dir_all(&previous).unwrap();
    std::fs::rename(base.join("aside.json"), previous.join("spectrum.json")).unwrap();
    let err = common::stderr(&clv(&["analyze", run.to_str().unwrap(), "--out", base.join("o").to_str().unwrap()]));
    assert!(err.contains("an extension of this run was interrupted") && err.contains(&previous.display().to_string()) && err.contains("--steps M"), "{err}");
    std::fs::rename(previous.join("spectrum.json"), &spectrum).unwrap();
    std::fs::remove_dir(&previous).unwrap();
    let segment = clv::store::RunDir { path: run.clone() }.segments().unwrap().remove(0).path;
    let err = common::stderr(&clv(&["analyze", segment.to_str().unwrap(), "--out", base.join("o").to_str().unwrap()]));
    assert!(err.contains("is a segment of a run directory") && err.contains("clv backward"), "{err}");
    // Piped in, too (it was called a stream whose writer sent no frames).
    let piped = Command::new(env!("CARGO_BIN_EXE_clv")).args(["analyze", "-", "--out", base.join("o").to_str().unwrap()]).stdin(std::fs::File::open(&segment).unwrap()).output().unwrap();
    let err = common::stderr(&piped);
    assert!(!piped.status.success() && err.contains("<stdin> is a segment of a run directory"), "{err}");
    // A report directory that holds files is not written over without --overwrite.
    let kept = base.join("kept");
    std::fs::create_dir_all(&kept).unwrap();
    std::fs::write(kept.join("index.html"), b"an earlier report").unwrap();
    let out = clv(&["analyze", junk.to_str().unwrap(), "--out", kept.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--out") && err.contains("--overwrite") && !err.contains("junk.mcap"), "{err}");
    assert_eq!(std::fs::read(kept.join("index.html")).unwrap(), b"an earlier report");
    let out = clv(&["analyze", junk.to_str().unwrap(), "--out", kept.to_str().unwrap(), "--overwrite"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("junk.mcap"), "--overwrite goes on to read the source");
    // An empty pipe (the command before it failed): said so, not reported as a damaged record.
    let out = Command::new(env!("CARGO_BIN_EXE_clv")).args(["analyze", "-", "--out", base.join("o").to_str().unwrap()]).stdin(Stdio::null()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("<stdin>") && err.contains("it is empty") && !err.contains("panicked"), "{err}");
    // --out a file: refused, the file left as it is.
    let file = base.join("a-file");
    std::fs::write(&file, b"kept").unwrap();
    let out = clv(&["analyze", junk.to_str().unwrap(), "--out", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--out") && err.contains("is a file"), "{err}");
    assert_eq!(std::fs::read(&file).unwrap(), b"kept");
    // Standard input on a terminal (script(1) gives it one) would wait for a stream forever.
    let cmd = format!("{} analyze - --out {}", env!("CARGO_BIN_EXE_clv"), base.join("t").display());
    let tty = Command::new("script").args(["-qec", &cmd, "/dev/null"]).stdin(Stdio::null()).output().expect("script(1) from util-linux");
    let text = String::from_utf8_lossy(&tty.stdout);
    assert!(!tty.status.success() && text.contains("standard input, which is a terminal"), "{text}");
}

/// The README's main command on the embedded default: every stage, every figure, and a
/// second start reuses the finished run instead of redoing it.
#[test]
fn clv_run_on_the_default_preset_writes_the_report() {
    let out = scratch("run");
    let o = out.to_str().unwrap();
    // A file system with (faked) no free space: the warning's estimate is what the run,
    // its records and its report then take.
    let first = ok(common::clv_env(&["run", "--out", o, "--quiet"], &[("CLV_FAULT_DISK_FREE", "1")]));
    let warning = String::from_utf8_lossy(&first.stderr).to_string();
    let estimate: f64 = warning.split("needs about ").nth(1).and_then(|r| r.split(" MB").next()?.parse().ok()).unwrap_or_else(|| panic!("no estimate in MB in {warning:?}"));
    fn bytes(dir: &Path) -> u64 {
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).map(|p| if p.is_dir() { bytes(&p) } else { std::fs::metadata(&p).unwrap().len() }).sum()
    }
    let used = bytes(&out) as f64 / 1e6;
    assert!(estimate >= used && estimate < 1.5 * used, "estimated {estimate} MB, used {used} MB");
    let html = read(&out.join("report/index.html"));
    let summary: serde_json::Value = serde_json::from_str(&read(&out.join("report/summary.json"))).unwrap();
    let produced = summary["produced"].as_array().unwrap();
    assert!(produced.len() >= 3, "{summary}");
    for p in produced {
        for f in p["figures"].as_array().unwrap() {
            let f = f.as_str().unwrap();
            assert!(html.contains(&format!("{f}.png")), "index.html lacks {f}");
            let png = std::fs::read(out.join(format!("report/{f}.png"))).unwrap();
            assert!(png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 5000, "{f}.png");
        }
    }
    assert!(summary["frames"].as_u64().unwrap() >= 1000);
    let again = ok(clv(&["run", "--out", o]));
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(err.contains("continuing the run"), "{err}");
    // The closing summary: lambda_1 and h_KS of both spectra and of the GS one over the CLV
    // window, with errors; lambda_1 is the same for CLV and GS over the same steps (v^1 = g^1).
    let summary = err.lines().find(|l| l.starts_with("clv run: lambda_1 = ")).unwrap_or_else(|| panic!("no summary in {err}"));
    assert!(summary.contains(" (GS), ") && summary.contains("h_KS = ") && summary.matches(" ± ").count() == 6, "{summary}");
    let lambda_1: Vec<&str> = summary.split(", ").take(3).map(|s| s.split(' ').find(|t| t.parse::<f64>().is_ok()).unwrap_or_default()).collect();
    assert_eq!(lambda_1[1], lambda_1[2], "{summary}");
    assert!(err.contains("clv run: convergence of the GS spectrum (20 blocks): "), "{err}");
    // Another preset into the same --out: refused, the run and its report left as they are.
    let other = clv(&["run", "--preset", "henon", "--out", o, "--quiet"]);
    let err = String::from_utf8_lossy(&other.stderr);
    // The way out first, and the first of the many differences the system's.
    let want = "holds a run of another configuration (--system disks in the run, henon asked for, ";
    let example = format!("more): give this one another --out (e.g. --out {o}-henon), or ask for that run's configuration");
    assert!(!other.status.success() && err.contains(want) && err.contains(&example), "{err}");
    assert_eq!(read(&out.join("report/index.html")), html);
    drop(first);
}

/// `clv run` takes settings of a run after its own options: a preset with another N keeps
/// all vectors (k = D follows N) and a window that follows --steps; what is not a setting of
/// a run (a stage's own option, or a disk flag for the Henon map) is refused, naming it.
#[test]
fn clv_run_takes_settings_that_change_the_preset() {
    let out = scratch("run-settings");
    let o = out.to_str().unwrap();
    ok(clv(&["run", "--out", o, "--quiet", "--n", "8", "--aspect", "1", "--steps", "300", "--relax-steps", "20"]));
    let run: serde_json::Value = serde_json::from_str(&read(&out.join("run/run.json"))).unwrap();
    assert_eq!((&run["config"]["system"]["n"], &run["config"]["vectors"], &run["config"]["steps"]), (&serde_json::json!(8), &serde_json::json!(32), &serde_json::json!(300)));
    // StoreConfig::for_run: a tenth of the 320 steps, half of that again as the transient.
    assert_eq!((&run["store"]["clv_steps"], &run["store"]["transient"]), (&serde_json::json!(32), &serde_json::json!(16)));
    assert!(out.join("report/index.html").exists());
    // The same run on two threads is the same run: continued, not refused.
    let again = ok(clv(&["run", "--out", o, "--n", "8", "--aspect", "1", "--steps", "300", "--relax-steps", "20", "--threads", "2"]));
    assert!(common::stderr(&again).contains("continuing the run"), "{}", common::stderr(&again));
    // More --steps extend the run: its window follows them, and the shorter run's report
    // and spectra are kept beside it, not overwritten.
    let report = read(&out.join("report/index.html"));
    let longer = ok(clv(&["run", "--out", o, "--n", "8", "--aspect", "1", "--steps", "500", "--relax-steps", "20"]));
    assert!(common::stderr(&longer).contains("extending the run in") && common::stderr(&longer).contains("from 300 to 500 steps"), "{}", common::stderr(&longer));
    let kept = out.join("run/previous-300-steps");
    assert_eq!(read(&kept.join("report/index.html")), report);
    assert!(kept.join("spectrum.json").exists() && kept.join("clv_spectrum.json").exists());
    let run: serde_json::Value = serde_json::from_str(&read(&out.join("run/run.json"))).unwrap();
    assert_eq!((&run["config"]["steps"], &run["store"]["clv_steps"]), (&serde_json::json!(500), &serde_json::json!(52)));
    let summary: serde_json::Value = serde_json::from_str(&read(&out.join("report/summary.json"))).unwrap();
    assert!(summary["frames"].as_u64().unwrap() >= 52, "{summary}");
    // `clv run`'s own options may also follow the settings, and so may --help.
    let help = ok(clv(&["run", "--n", "16", "-h"]));
    assert!(String::from_utf8_lossy(&help.stdout).contains("--preset"), "{}", common::stderr(&help));
    let quiet = ok(clv(&["run", "--n", "8", "--aspect", "1", "--steps", "500", "--relax-steps", "20", "--quiet", "--out", o]));
    assert!(quiet.stderr.is_empty(), "{}", common::stderr(&quiet));
    for (args, named) in [
        (vec!["run", "--out", o, "--steps", "300", "--out", o], "invalid --out: given twice"),
        (vec!["run", "--steps", "300", "--preset", "henon", "--config", o], "give --config or --preset, not both"),
        (vec!["run", "--steps", "300", "--out"], "invalid --out: needs a value"),
        (vec!["run", "--steps", "300", "--quiet=false"], "invalid --quiet: takes no value"),
        (vec!["run", "--out", o, "--steps", "300", "--resume", o], "--resume is not a setting of a run"),
        (vec!["run", "--out", o, "--preset", "henon", "--n", "5"], "--n: sets up hard disks"),
        (vec!["run", "--out", o, "--steps", "many"], "'many'"),
    ] {
        let r = clv(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(named), "{args:?}: {err}");
    }
    // The default preset's own disk settings do not stand in the way of another system.
    let lorenz = scratch("run-lorenz-from-default");
    ok(clv(&["run", "--preset", "default", "--system", "lorenz", "--steps", "200", "--relax-steps", "10", "--quiet", "--out", lorenz.to_str().unwrap()]));
    // Nor does its tau, the disks' default: the other system takes its own (it took 0.6).
    let run: serde_json::Value = serde_json::from_str(&read(&lorenz.join("run/run.json"))).unwrap();
    assert_eq!(run["config"]["tau"].as_f64(), Some(0.1), "{run}");
    // A configuration file's disk keys for the Henon map too (they were ignored).
    let file = out.join("henon.toml");
    std::fs::write(&file, "system = \"henon\"\nn = 40\nsteps = 100\n").unwrap();
    let henon = scratch("run-henon-disk-key");
    let r = clv(&["run", "--config", file.to_str().unwrap(), "--out", henon.to_str().unwrap(), "--quiet"]);
    assert!(!r.status.success() && common::stderr(&r).contains("henon.toml:2: invalid setting n: sets up hard disks") && !henon.join("run").exists(), "{}", common::stderr(&r));
    // A run without a CLV window is refused before its forward stage, which `clv run` could
    // not then finish.
    let none = scratch("run-no-window");
    let r = clv(&["run", "--out", none.to_str().unwrap(), "--quiet", "--n", "8", "--steps", "300", "--relax-steps", "20", "--clv-steps", "0"]);
    assert!(!r.status.success() && common::stderr(&r).contains("invalid --clv-steps") && !none.join("run").exists(), "{}", common::stderr(&r));
}

/// A stream continued with `backward --resume` lacks the frames the interrupted stream's
/// reader took: the backward stage says which, and the analyses of it say at the head of
/// index.html, in summary.json and on stderr that they describe the rest only. A whole
/// stream has no such warning.
#[test]
fn a_resumed_stream_is_reported_as_covering_part_of_the_window() {
    let base = scratch("resumed-stream");
    let run = forward_in(&base);
    let r = run.to_str().unwrap();
    // A reader that takes about half the stream (frames of 12.8 kB, segments of 100 frames)
    // and closes it: the sweep has saved progress for at least one segment by then.
    let mut producer = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", r, "--out", "-", "--quiet"]).stdout(Stdio::piped()).spawn().unwrap();
    let mut head = producer.stdout.take().unwrap();
    let mut buf = vec![0u8; 2_600_000];
    std::io::Read::read_exact(&mut head, &mut buf).unwrap();
    drop(head);
    assert_eq!(producer.wait().unwrap().code(), Some(141), "a stream its reader closed is no finished sweep");
    let report = base.join("report");
    let pipe = format!("{} backward {r} --resume --out - | {} analyze - --out {}", env!("CARGO_BIN_EXE_clv"), env!("CARGO_BIN_EXE_clv"), report.display());
    let out = Command::new("bash").args(["-c", &format!("set -o pipefail; {pipe}")]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let summary: serde_json::Value = serde_json::from_str(&read(&report.join("summary.json"))).unwrap();
    let (first, last) = (summary["first_step"].as_u64().unwrap(), summary["last_step"].as_u64().unwrap());
    // The window ends at step 1900: 200 + 2000 steps less the backward transient of 300.
    assert!(last < 1900, "the newest frames went to the first reader: {summary}");
    let not_sent = format!("frames of steps {}..1900 went to the reader of the interrupted stream", last + 1);
    assert!(err.contains(&not_sent), "backward: {err}");
    let warning = format!("covers steps {first}..{last} of the window {first}..1900");
    assert!(err.contains(&format!("clv analyze: warning: This stream {warning}")), "analyze: {err}");
    assert!(summary["warnings"][0].as_str().unwrap().contains(&warning), "{summary}");
    assert!(read(&report.join("index.html")).contains(&format!("<strong>Warning.</strong> This stream {warning}")));
    // The whole stream, started again: no warning.
    let whole = base.join("whole");
    let pipe = format!("{} backward {r} --out - --quiet | {} analyze - --out {}", env!("CARGO_BIN_EXE_clv"), env!("CARGO_BIN_EXE_clv"), whole.display());
    let out = Command::new("bash").args(["-c", &format!("set -o pipefail; {pipe}")]).output().unwrap();
    assert!(out.status.success() && !String::from_utf8_lossy(&out.stderr).contains("warning"));
    let summary: serde_json::Value = serde_json::from_str(&read(&whole.join("summary.json"))).unwrap();
    assert_eq!((summary["first_step"].as_u64(), summary["last_step"].as_u64(), summary["warnings"].as_array().map(Vec::len)), (Some(first), Some(1900), Some(0)));
    assert!(!read(&whole.join("index.html")).contains("<strong>Warning.</strong>"));
    // Frames without GS vectors: the report says what it leaves out for that, once.
    assert!(summary["left_out"].as_array().is_some_and(|l| l.len() == 1 && l[0].as_str().unwrap().starts_with("The frames carry no Gram-Schmidt vectors")), "{summary}");
    assert!(summary["left_out"][0].as_str().unwrap().contains("(the GS curve of Fig. 5; Figs. 3 and 4; Fig. 6 and the GS curve of Fig. 9; Table I)"), "{summary}");
    // With no backward transient the window ends one step before the run's last step (that
    // step is never a frame): a whole stream, and no warning.
    let t0 = base.join("t0");
    let pipe = format!("{} backward {r} --transient 0 --out - --quiet | {} analyze - --out {} --quiet", env!("CARGO_BIN_EXE_clv"), env!("CARGO_BIN_EXE_clv"), t0.display());
    let out = Command::new("bash").args(["-c", &format!("set -o pipefail; {pipe}")]).output().unwrap();
    assert!(out.status.success() && !String::from_utf8_lossy(&out.stderr).contains("warning"), "{}", String::from_utf8_lossy(&out.stderr));
    let summary: serde_json::Value = serde_json::from_str(&read(&t0.join("summary.json"))).unwrap();
    assert_eq!((summary["last_step"].as_u64(), summary["warnings"].as_array().map(Vec::len)), (Some(2199), Some(0)));
    // --resume of the finished sweep: no frames, and both ends say why.
    let pipe = format!("{} backward {r} --resume --out - | {} analyze - --out {}", env!("CARGO_BIN_EXE_clv"), env!("CARGO_BIN_EXE_clv"), base.join("none").display());
    let out = Command::new("bash").args(["-c", &pipe]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("finished earlier") && err.contains("this stream carries none"), "backward: {err}");
    assert!(err.contains("no frames in the stream") && err.contains("without --resume"), "analyze: {err}");
}

/// Run a study script of scripts/ on N = 8, 12, 16 with `args` into a fresh directory:
/// (its directory, the script's arguments, its table's rows by N), or None without numpy.
fn study(script: &str, name: &str, table: &str, args: &[&str]) -> Option<(std::path::PathBuf, Vec<String>, Vec<Vec<f64>>)> {
    if !common::python_has("numpy") {
        return None;
    }
    let base = scratch(name);
    let mut all: Vec<String> = ["--n", "8,12,16", "--clv-bin", env!("CARGO_BIN_EXE_clv"), "--out", base.to_str().unwrap()].iter().map(|s| s.to_string()).collect();
    all.extend(args.iter().map(|s| s.to_string()));
    ok(Command::new("python3").arg(study_script(script)).args(&all).output().unwrap());
    let rows: Vec<Vec<f64>> = read(&base.join(table)).lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    assert_eq!(rows.iter().map(|r| r[0]).collect::<Vec<_>>(), [8.0, 12.0, 16.0]);
    Some((base, all, rows))
}

fn study_script(script: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts").join(script)
}

/// A second study into the same directory is refused: its runs are never replaced.
fn refused_again(script: &str, args: &[String]) {
    let again = Command::new("python3").arg(study_script(script)).args(args).output().unwrap();
    assert!(!again.status.success() && String::from_utf8_lossy(&again.stderr).contains("exists"));
}

/// scripts/density.py: one row per density with the spectrum's lambda_1, h_KS / N and
/// lambda_(2N-3) (recomputed here from the kept runs), the measured collision frequency
/// within 10 % of Enskog's (N = 8 is small), and lambda_1 growing with the density.
#[test]
fn the_density_study_tabulates_the_spectrum_against_rho() {
    if !common::python_has("numpy") {
        return;
    }
    let base = scratch("density");
    let args = ["--n", "8", "--densities", "0.2,0.5,0.8", "--steps", "400", "--clv-bin", env!("CARGO_BIN_EXE_clv"), "--out", base.to_str().unwrap()];
    ok(Command::new("python3").arg(study_script("density.py")).args(args).output().unwrap());
    let text = read(&base.join("density.csv"));
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<Vec<f64>> = text.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    assert_eq!(rows.iter().map(|r| r[col("density")]).collect::<Vec<_>>(), [0.2, 0.5, 0.8]);
    for r in &rows {
        let run: serde_json::Value = serde_json::from_str(&read(&base.join(format!("runs/rho{}.json", r[0])))).unwrap();
        assert_eq!(r[col("lambda_1")], run["exponents"][0].as_f64().unwrap());
        assert_eq!(r[col("lambda_2N-3")], run["exponents"][12].as_f64().unwrap());
        assert!((r[col("h_KS_per_disk")] * 8.0 - run["ks_entropy"]["value"].as_f64().unwrap()).abs() < 1e-9);
        assert!((r[col("nu")] / r[col("nu_enskog")] - 1.0).abs() < 0.1, "collision frequency {r:?}");
    }
    assert!(rows.windows(2).all(|w| w[1][col("lambda_1")] > w[0][col("lambda_1")]), "lambda_1 against rho: {rows:?}");
    refused_again("density.py", &args.iter().map(|s| s.to_string()).collect::<Vec<_>>());
}

/// scripts/scaling.py: one row per N with the run's lambda_1 and the report's W_1, h_KS per
/// disk for the full spectra, and eta the slope of ln W_1 against ln N (recomputed here);
/// a second study into the same directory is refused.
#[test]
fn the_scaling_study_tabulates_and_fits_its_runs() {
    let Some((base, args, rows)) = study("scaling.py", "scaling", "scaling.csv", &["--steps", "600", "--clv-steps", "200", "--full-up-to", "12"]) else { return };
    for r in &rows {
        let n = r[0] as usize;
        let spectrum: serde_json::Value = serde_json::from_str(&read(&base.join(format!("runs/n{n}-run/spectrum.json")))).unwrap();
        assert_eq!(r[1], spectrum["exponents"][0].as_f64().unwrap());
        // localization.csv: i, i_over_D, W_gs, W_clv, stderr_gs, stderr_clv
        let first: Vec<f64> = read(&base.join(format!("runs/n{n}-report/localization.csv"))).lines().nth(1).unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!((r[3], r[4]), (first[3], first[5]));
        assert!(r[3] > 0.0 && r[3] <= 1.0 && r[4] > 0.0 && r[4] < 0.2 * r[3], "W_1 and its error: {r:?}");
        assert_eq!(r[5].is_finite(), n <= 12, "h_KS / N only for the full spectra: {r:?}");
    }
    let (x, y): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| (r[0].ln(), r[3].ln())).unzip();
    let (mx, my) = (x.iter().sum::<f64>() / 3.0, y.iter().sum::<f64>() / 3.0);
    let slope = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum::<f64>() / x.iter().map(|a| (a - mx).powi(2)).sum::<f64>();
    let fit: serde_json::Value = serde_json::from_str(&read(&base.join("fit.json"))).unwrap();
    assert!((fit["eta"].as_f64().unwrap() + slope).abs() < 1e-9, "{fit} against slope {slope}");
    assert!(fit["eta_stderr"].as_f64().unwrap() >= 0.0);
    for local in fit["local_eta"].as_array().unwrap() {
        assert!(local["eta_stderr"].as_f64().is_some_and(|e| e.is_finite() && e > 0.0), "{local}");
    }
    refused_again("scaling.py", &args);
}

/// scripts/hyperbolicity.py: one row per N with the quantiles of Psi (recomputed here from
/// the report's transversality.csv), a random-subspace baseline below Psi's median (the
/// splitting is more transversal than chance), the violations of E^u + E^0 + E^s
/// (from domination.csv), and the slopes of ln Psi against ln N; a second study into the
/// same directory is refused.
#[test]
fn the_hyperbolicity_study_tabulates_psi_against_n() {
    let Some((base, args, rows)) = study("hyperbolicity.py", "hyperbolicity", "hyperbolicity.csv", &["--steps", "400", "--clv-steps", "100", "--every", "2"]) else { return };
    let mut medians = Vec::new();
    for r in &rows {
        let n = r[0] as usize;
        let text = read(&base.join(format!("runs/n{n}-report/transversality.csv")));
        let mut psi: Vec<f64> = text.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse::<f64>().unwrap().to_degrees()).collect();
        psi.sort_by(f64::total_cmp);
        // 100 backward steps, V in the frames of every second one.
        assert_eq!((r[1], psi.len()), (51.0, 51));
        let median = psi[25];
        assert!((r[2] - psi[0]).abs() < 1e-9 && (r[4] - median).abs() < 1e-9, "min and median of {n}: {r:?}");
        assert!(r[2] <= r[3] && r[3] <= r[4] && r[2] > 0.0 && r[4] < 90.0, "{r:?}");
        assert!(r[7] > 0.0 && r[7] < r[4], "random subspaces of N = {n} are less transversal than E^u and E^s: {r:?}");
        // The domination test of the splitting E^u + E^0 + E^s, first and last window.
        let dom = read(&base.join(format!("runs/n{n}-report/domination.csv")));
        let head: Vec<&str> = dom.lines().next().unwrap().split(',').collect();
        let rows: Vec<Vec<f64>> = dom.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
        let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
        let worst = |row: &Vec<f64>| row[col("split_unstable_null")].max(row[col("split_null_stable")]);
        assert_eq!((r[8], r[9], r[10]), (worst(&rows[0]), worst(rows.last().unwrap()), rows.last().unwrap()[0]), "N = {n}");
        medians.push((r[0].ln(), median.ln()));
    }
    let (mx, my) = (medians.iter().map(|p| p.0).sum::<f64>() / 3.0, medians.iter().map(|p| p.1).sum::<f64>() / 3.0);
    let slope = medians.iter().map(|(a, b)| (a - mx) * (b - my)).sum::<f64>() / medians.iter().map(|(a, _)| (a - mx).powi(2)).sum::<f64>();
    let fit: serde_json::Value = serde_json::from_str(&read(&base.join("fit.json"))).unwrap();
    assert!((fit["slope_ln_median"].as_f64().unwrap() - slope).abs() < 1e-9, "{fit} against slope {slope}");
    refused_again("hyperbolicity.py", &args);
}

/// A Python user reads the frames with the mcap package, cbor2 and numpy and gets the same
/// CLV spectrum as the backward stage.
/// `--vectors-every m` forms V_n (and G_n) only for the steps n that are multiples of m: those frames are the
/// full stream's, bit for bit, every frame keeps its phase point and local exponents, and
/// the analyses of the sparse stream (which sample the frames of every m-th step by default) write every
/// table of the full stream analysed with `--every m`, byte for byte. An `--every` that is
/// not a multiple of m is refused before any analysis runs.
#[test]
fn vectors_for_every_mth_frame_give_the_analyses_of_the_full_stream() {
    let base = scratch("sparse");
    let run = forward_in(&base);
    let r = run.to_str().unwrap();
    let (full, sparse) = (base.join("full.mcap"), base.join("sparse.mcap"));
    ok(clv(&["backward", r, "--out", full.to_str().unwrap(), "--with-gs", "--quiet"]));
    ok(clv(&["backward", r, "--out", sparse.to_str().unwrap(), "--with-gs", "--quiet", "--vectors-every", "3"]));
    let (ff, fs) = (common::frames(&full), common::frames(&sparse));
    assert_eq!(ff.len(), 401);
    assert_eq!(ff.len(), fs.len());
    for (i, (a, b)) in ff.iter().zip(&fs).enumerate() {
        assert!(a.step == b.step && a.phase == b.phase && a.local == b.local, "frame {i}: phase point or local exponents differ");
        if a.step % 3 == 0 {
            assert!(a == b, "frame {i} (step {}) differs from the full stream's", a.step);
        } else {
            assert!(b.v.is_empty() && b.g.is_none(), "frame {i} carries vectors");
        }
    }
    let (full_report, sparse_report) = (base.join("full-report"), base.join("sparse-report"));
    ok(clv(&["analyze", full.to_str().unwrap(), "--out", full_report.to_str().unwrap(), "--every", "3"]));
    ok(clv(&["analyze", sparse.to_str().unwrap(), "--out", sparse_report.to_str().unwrap()]));
    let tables: Vec<String> = std::fs::read_dir(&full_report)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".csv"))
        .collect();
    assert!(tables.len() >= 10, "only {tables:?}");
    for t in &tables {
        assert_eq!(read(&full_report.join(t)), read(&sparse_report.join(t)), "{t}: the sparse stream's analysis differs");
    }
    let out = clv(&["analyze", sparse.to_str().unwrap(), "--out", base.join("x").to_str().unwrap(), "--every", "4"]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("--every") && err.contains("--vectors-every 3"), "{err}");
    assert!(!base.join("x").join("index.html").exists());
    // A stride that no frame of the stream is on is refused before anything is written.
    let out = clv(&["analyze", full.to_str().unwrap(), "--out", base.join("y").to_str().unwrap(), "--every", "300000"]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("--every") && err.contains("no step among them"), "{err}");
    assert!(!base.join("y").exists());
    // Where no stride can sample a frame with vectors, an explicit --every is not refused
    // with advice that cannot work: it goes on as the default does, and says to write the
    // frames again.
    let none = base.join("none.mcap");
    ok(clv(&["backward", r, "--out", none.to_str().unwrap(), "--quiet", "--vectors-every", "1000000"]));
    for (name, every) in [("n1", None), ("n2", Some("1000000")), ("n3", Some("2000000"))] {
        let report = base.join(name);
        let mut args = vec!["analyze", none.to_str().unwrap(), "--out", report.to_str().unwrap(), "--only", "localization"];
        args.extend(every.iter().flat_map(|m| ["--every", m]));
        let err = common::stderr(&ok(clv(&args)));
        assert!(err.contains("had no frame to read") && err.contains("write them again with smaller strides") && !err.contains("give a smaller"), "{every:?}: {err}");
        // Left out, not a table of NaN under a caption that states results.
        assert!(!report.join("localization.csv").exists() && !read(&report.join("summary.json")).contains("Localization"), "{every:?}");
    }
    // A frame file with no step of the window on its stride is refused before it is written.
    let empty = base.join("empty.mcap");
    let out = clv(&["backward", r, "--out", empty.to_str().unwrap(), "--quiet", "--save-every", "1000000"]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("invalid --save-every") && err.contains("would hold no frame") && !empty.exists(), "{err}");
    // A window length longer than the stream measures nothing, and the verdict on domination
    // is taken from the lengths that fit.
    let z = base.join("z");
    ok(clv(&["analyze", full.to_str().unwrap(), "--out", z.to_str().unwrap(), "--only", "local_exponents", "--deltas", "1,100000"]));
    let summary: serde_json::Value = serde_json::from_str(&read(&z.join("summary.json"))).unwrap();
    let caption = summary["produced"].as_array().unwrap().iter().find(|p| p["title"].as_str().is_some_and(|t| t.contains("Domination"))).unwrap()["caption"].as_str().unwrap().to_string();
    assert!(!caption.contains(": NaN") && !caption.contains("NaN of the windows") && !caption.contains("at Δ = 100000") && caption.contains("never violated"), "{caption}");
}

#[test]
fn python_reads_frame_files() {
    if !common::python_has("mcap, cbor2, numpy") {
        return;
    }
    let base = scratch("python");
    let run = forward_in(&base);
    let frames = base.join("f.mcap");
    let report: serde_json::Value = serde_json::from_slice(&ok(clv(&["backward", run.to_str().unwrap(), "--out", frames.to_str().unwrap(), "--with-gs", "--quiet", "--json"])).stdout).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/read_frames.py");
    let out = ok(Command::new("python3").arg(&script).arg(&frames).arg("--json").output().unwrap());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frames"], report["statistics"]["frames"]);
    assert_eq!(v["with_gs"], true);
    assert_eq!(v["run_seed"], 1);
    assert!(v["max_unit_norm_error"].as_f64().unwrap() < 1e-12);
    assert_eq!(v["frames_with_vectors"], v["frames"]);
    // A stream with V at every 4th step only.
    let sparse = base.join("sparse.mcap");
    ok(clv(&["backward", run.to_str().unwrap(), "--out", sparse.to_str().unwrap(), "--quiet", "--vectors-every", "4"]));
    let out = ok(Command::new("python3").arg(&script).arg(&sparse).arg("--json").output().unwrap());
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(s["frames"], v["frames"]);
    assert_eq!(s["frames_with_vectors"].as_u64().unwrap(), v["frames"].as_u64().unwrap().div_ceil(4));
    assert_eq!(s["mean_local_clv_exponents"], v["mean_local_clv_exponents"]);
    let py: Vec<f64> = serde_json::from_value(v["mean_local_clv_exponents"].clone()).unwrap();
    let rs: Vec<f64> = serde_json::from_value(report["exponents"].clone()).unwrap();
    for (a, b) in py.iter().zip(&rs) {
        assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "Python {a} vs clv {b}");
    }
}

/// `clv config` prints a file that `--config` reads back; command-line flags override it;
/// `clv run --config` runs the whole pipeline from a file.
#[test]
fn configuration_files_round_trip_and_flags_override_them() {
    let base = scratch("config");
    let file = base.join("default.toml");
    let printed = ok(clv(&["config", "--preset", "default"]));
    std::fs::write(&file, &printed.stdout).unwrap();
    let f = file.to_str().unwrap();
    let out = ok(clv(&["forward", "--config", f, "--n", "8", "--aspect", "1", "--vectors", "32", "--steps", "300", "--relax-steps", "10", "--json", "--quiet"]));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["config"]["system"]["n"], 8, "the flag overrides the file");
    assert_eq!(v["config"]["steps"], 300);
    assert_eq!(v["config"]["system"]["density"], 0.7, "the file provides what the flags do not");
    assert_eq!(v["config"]["blocks"], 20);
    // A boolean for a setting that takes a value is named as such, with its line.
    let boolean = base.join("boolean.toml");
    std::fs::write(&boolean, "steps = 100\nn = true\n").unwrap();
    let err = common::stderr(&clv(&["forward", "--config", boolean.to_str().unwrap(), "--out", base.join("b").to_str().unwrap(), "--quiet"]));
    assert!(err.contains("boolean.toml:2: n takes a value, not true or false"), "{err}");
    // false too: it was dropped, and the run took the default without a word.
    std::fs::write(&boolean, "steps = 100\nn = 8\nseed = false\n").unwrap();
    let refused = clv(&["forward", "--config", boolean.to_str().unwrap(), "--out", base.join("b").to_str().unwrap(), "--quiet"]);
    let err = common::stderr(&refused);
    assert!(!refused.status.success() && err.contains("boolean.toml:3: seed takes a value, not true or false") && !base.join("b").exists(), "{err}");
    // Named by its own line where another setting needs a partner (--lx needs --ly).
    std::fs::write(&boolean, "n = 4\nlx = 3\nly = 3\nseed = false\n").unwrap();
    let err = common::stderr(&clv(&["forward", "--config", boolean.to_str().unwrap(), "--steps", "10"]));
    assert!(err.contains("boolean.toml:4: seed takes a value, not true or false"), "{err}");
    // The box given by its sides on the command line replaces the file's density and aspect.
    let out = ok(clv(&["forward", "--config", f, "--n", "8", "--lx", "4", "--ly", "4", "--steps", "100", "--json", "--quiet"]));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((&v["config"]["system"]["lx"], &v["config"]["system"]["density"]), (&serde_json::json!(4.0), &serde_json::json!(0.5)));
    // A file's sides and the command line's density and aspect: both together replace the
    // sides; one alone would keep a default for the other, a box nobody asked for, and is
    // refused, in forward and run alike. A file that gives the box both ways is refused too.
    let square = base.join("square.toml");
    std::fs::write(&square, "n = 8\nsteps = 100\nrelax-steps = 10\nlx = 4\nly = 4\n").unwrap();
    let sq = square.to_str().unwrap();
    let out = ok(clv(&["forward", "--config", sq, "--density", "0.5", "--aspect", "1", "--json", "--quiet"]));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((&v["config"]["system"]["lx"], &v["config"]["system"]["aspect"]), (&serde_json::json!(4.0), &serde_json::json!(1.0)));
    for (cmd, flag) in [("forward", "--density"), ("forward", "--aspect"), ("run", "--density")] {
        let half = clv(&[cmd, "--config", sq, flag, "1", "--out", base.join("half").to_str().unwrap(), "--quiet"]);
        let err = common::stderr(&half);
        assert!(!half.status.success() && err.contains(&format!("invalid {flag}: the configuration file gives the box by its sides")), "{cmd} {flag}: {err}");
        assert!(!base.join("half").exists(), "nothing is written");
    }
    let both = base.join("both.toml");
    std::fs::write(&both, "n = 8\nsteps = 100\ndensity = 0.7\nlx = 4\nly = 4\n").unwrap();
    let refused = clv(&["forward", "--config", both.to_str().unwrap(), "--quiet"]);
    let err = common::stderr(&refused);
    assert!(!refused.status.success() && err.contains("both.toml:4: invalid setting lx: the box is given both by its sides"), "{err}");
    let twice = clv(&["forward", "--config", f, "--config", f, "--steps", "10"]);
    assert!(!twice.status.success() && common::stderr(&twice).contains("--config: given twice"), "{}", common::stderr(&twice));
    let small = base.join("small.toml");
    std::fs::write(&small, "[system]\nsystem = \"disks\"\nn = 8\naspect = 1\n[run]\nsteps = 600\nrelax-steps = 50\nvectors = 32\n[store]\nclv-steps = 100\ntransient = 50\n").unwrap();
    let out_dir = base.join("out");
    ok(clv(&["run", "--config", small.to_str().unwrap(), "--out", out_dir.to_str().unwrap(), "--quiet"]));
    assert!(out_dir.join("report/index.html").exists());
    let run: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out_dir.join("run/run.json")).unwrap()).unwrap();
    assert_eq!(run["config"]["system"]["n"], 8);
    assert_eq!((&run["store"]["clv_steps"], &run["store"]["transient"]), (&serde_json::json!(100), &serde_json::json!(50)), "the file's store settings are the run's");
    // ... and a preset's in `clv run`.
    let sides = base.join("sides");
    ok(clv(&["run", "--out", sides.to_str().unwrap(), "--quiet", "--n", "8", "--lx", "4", "--ly", "4", "--steps", "600", "--clv-steps", "100"]));
    let run: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(sides.join("run/run.json")).unwrap()).unwrap();
    assert_eq!((&run["config"]["system"]["lx"], &run["config"]["system"]["ly"]), (&serde_json::json!(4.0), &serde_json::json!(4.0)));
    // Settings after `clv run`'s own options change the file's, and the same file with
    // another window is refused in the same --out (the run and its report stay as they are).
    let changed = base.join("changed");
    ok(clv(&["run", "--config", small.to_str().unwrap(), "--out", changed.to_str().unwrap(), "--quiet", "--clv-steps", "80", "--seed", "5"]));
    let run: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(changed.join("run/run.json")).unwrap()).unwrap();
    // The file's transient stays: only what the command line names changes.
    assert_eq!((&run["store"]["clv_steps"], &run["store"]["transient"], &run["config"]["seed"]), (&serde_json::json!(80), &serde_json::json!(50), &serde_json::json!(5)));
    let refused = clv(&["run", "--config", small.to_str().unwrap(), "--out", changed.to_str().unwrap(), "--quiet", "--clv-steps", "90", "--seed", "5"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("another configuration (--clv-steps 80 in the run, 90 asked for): give this one another --out,"), "{err}");
    // Resuming with a file whose setting differs from the run's names the file's setting.
    let reseeded = base.join("reseeded.toml");
    std::fs::write(&reseeded, "n = 8\nseed = 9\n").unwrap();
    let out = clv(&["forward", "--resume", out_dir.join("run").to_str().unwrap(), "--config", reseeded.to_str().unwrap()]);
    let err = common::stderr(&out);
    assert!(!out.status.success() && err.contains("seed = 9 in ") && err.contains("reseeded.toml conflicts with the run"), "{err}");
    // A bad value in a file is reported as the file's, with its line, for forward and run alike.
    let bad = base.join("bad.toml");
    std::fs::write(&bad, "# a run\nseed = 3\nn = \"many\"\n").unwrap();
    for cmd in [vec!["forward", "--config", bad.to_str().unwrap()], vec!["run", "--config", bad.to_str().unwrap(), "--out", base.join("bad-out").to_str().unwrap()]] {
        let out = clv(&cmd);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("bad.toml:3: ") && err.contains("'many'") && err.contains("--n"), "{cmd:?}: {err}");
    }
    // ... also where the value parses but the run refuses it; the same value given on the
    // command line is the flag's.
    std::fs::write(&bad, "n = 8\nvectors = 999\n").unwrap();
    for cmd in [vec!["forward", "--config", bad.to_str().unwrap()], vec!["run", "--config", bad.to_str().unwrap(), "--out", base.join("bad-out").to_str().unwrap()]] {
        let out = clv(&cmd);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("bad.toml:2: invalid setting vectors: must be between 1 and D = 32"), "{cmd:?}: {err}");
    }
    let out = clv(&["forward", "--config", bad.to_str().unwrap(), "--vectors", "999"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("invalid --vectors") && !err.contains("bad.toml"), "{err}");
}

/// The CLV error bars do not depend on how the frames are read: the report of the full
/// stream has the backward stage's own (clv_spectrum.json) to the bit, and a file of every
/// 10th frame counts its blocks in its own frames. Its means use a tenth of the local
/// exponents, which are nearly independent from step to step, so its errors are about
/// sqrt(10) times the full stream's (with its frames put into two blocks they came out about
/// ten times larger). Its default --every samples every frame of it that carries vectors.
#[test]
fn clv_error_bars_do_not_depend_on_how_the_frames_are_read() {
    let base = scratch("error-bars");
    let run = base.join("run");
    let r = run.to_str().unwrap();
    ok(clv(&["forward", "--n", "10", "--aspect", "1", "--steps", "4000", "--clv-steps", "2000", "--quiet", "--out", r]));
    let (full, sparse) = (base.join("full.mcap"), base.join("sparse.mcap"));
    ok(clv(&["backward", r, "--quiet", "--out", full.to_str().unwrap()]));
    let stage: serde_json::Value = serde_json::from_str(&read(&run.join("clv_spectrum.json"))).unwrap();
    ok(clv(&["backward", r, "--quiet", "--save-every", "10", "--out", sparse.to_str().unwrap()]));
    let column = |report: &Path, name: &str| -> Vec<f64> {
        let text = read(&report.join("spectrum.csv"));
        let mut lines = text.lines();
        let at = lines.next().unwrap().split(',').position(|h| h == name).unwrap();
        lines.map(|l| l.split(',').nth(at).unwrap().parse().unwrap()).collect()
    };
    let (full_report, sparse_report) = (base.join("full-report"), base.join("sparse-report"));
    ok(clv(&["analyze", full.to_str().unwrap(), "--out", full_report.to_str().unwrap(), "--quiet"]));
    ok(clv(&["analyze", sparse.to_str().unwrap(), "--out", sparse_report.to_str().unwrap(), "--quiet"]));
    let want: Vec<f64> = stage["stderr"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert_eq!(column(&full_report, "stderr_clv"), want, "the report of the full stream and the backward stage differ");
    let (a, b) = (column(&full_report, "stderr_clv"), column(&sparse_report, "stderr_clv"));
    let ratio = b.iter().zip(&a).map(|(b, a)| b / a).sum::<f64>() / a.len() as f64;
    assert!(ratio > 2.0 && ratio < 5.0, "the sparse file's errors are {ratio} times the full stream's on average, not about sqrt(10)");
    // 201 frames of the window 2000..4000 in the file, all with vectors: all are sampled.
    let summary: serde_json::Value = serde_json::from_str(&read(&sparse_report.join("summary.json"))).unwrap();
    assert_eq!(summary["options"]["every"], 10, "{}", summary["options"]);
    // Windows of Delta steps need consecutive frames: not computed from such a file.
    let titles: Vec<&str> = summary["produced"].as_array().unwrap().iter().filter_map(|p| p["title"].as_str()).collect();
    assert!(!titles.iter().any(|t| t.contains("Domination") || t.contains("Finite-time")), "{titles:?}");
    assert!(read(&sparse_report.join("index.html")).contains("are not computed"));
}


/// `clv run` writes its report only over a report of its own run: one left by another run
/// (its run directory deleted, or another run's report moved in) and files of the user's
/// are refused before anything is computed, naming OUT/report, and stay as they were; a
/// report of its run killed midway is written anew. A run directory as --out is refused.
#[test]
fn clv_run_writes_no_report_over_another_runs() {
    let base = scratch("run-report-owner");
    let small = ["--n", "8", "--steps", "600", "--relax-steps", "50", "--quiet"];
    let run = |out: &Path, extra: &[&str]| clv(&[&["run", "--out", out.to_str().unwrap()], &small[..], extra].concat());
    let refused = |out: &std::process::Output, named: &Path, what: &str| {
        let err = common::stderr(out);
        assert!(!out.status.success() && err.contains(&format!("{} already holds {what}", named.display())) && err.contains("choose another --out, or move or delete"), "{err}");
    };
    // The report of a run whose run directory is gone, under a new run of another seed.
    let k = base.join("k");
    ok(run(&k, &[]));
    // Another configuration in the same --out: refused, naming the settings as flags.
    let other = run(&k, &["--seed", "5"]);
    let err = common::stderr(&other);
    assert!(!other.status.success() && err.contains("holds a run of another configuration (--seed 1 in the run, 5 asked for): give this one another --out,"), "{err}");
    let index = read(&k.join("report/index.html"));
    std::fs::remove_dir_all(k.join("run")).unwrap();
    let again = run(&k, &["--seed", "7"]);
    refused(&again, &k.join("report"), "a report, but");
    assert!(!k.join("run").exists(), "a refused run computed something");
    assert_eq!(read(&k.join("report/index.html")), index);
    // ... and under a new run of the same seed: a new run is not the report's either.
    refused(&run(&k, &[]), &k.join("report"), "a report, but");
    // A file of the user's where a report would go.
    let l = base.join("l");
    std::fs::create_dir_all(l.join("report")).unwrap();
    std::fs::write(l.join("report/spectrum.csv"), "mine").unwrap();
    refused(&run(&l, &[]), &l.join("report"), "files that are not a report of clv");
    assert_eq!(read(&l.join("report/spectrum.csv")), "mine");
    assert!(!l.join("run").exists());
    // Another run's report moved in beside this run: refused, naming both runs.
    let (m, n) = (base.join("m"), base.join("n"));
    ok(run(&m, &[]));
    ok(run(&n, &["--seed", "7"]));
    std::fs::remove_dir_all(m.join("report")).unwrap();
    common::copy_dir(&n.join("report"), &m.join("report"));
    let theirs = read(&m.join("report/index.html"));
    let other = run(&m, &[]);
    refused(&other, &m.join("report"), "the report of another run");
    assert!(common::stderr(&other).contains("(--seed 7 in the report, 1 in the run)"), "{}", common::stderr(&other));
    assert_eq!(read(&m.join("report/index.html")), theirs);
    // This run's report killed midway (its page names the run): written anew.
    std::fs::remove_dir_all(m.join("report")).unwrap();
    let (_, meta) = clv::store::RunDir::open(&m.join("run")).unwrap();
    clv::report::dir::begin_report(&m.join("report"), "a killed clv run", Some(&meta.config)).unwrap();
    ok(run(&m, &[]));
    assert!(m.join("report/summary.json").exists());
    // Another run's report killed midway is not this run's.
    clv::report::dir::begin_report(&m.join("report"), "a killed clv run", Some(&clv::store::RunDir::open(&n.join("run")).unwrap().1.config)).unwrap();
    refused(&run(&m, &[]), &m.join("report"), "the report of another run");
    // A run directory as --out.
    let inside = run(&n.join("run"), &["--seed", "7"]);
    let err = common::stderr(&inside);
    assert!(!inside.status.success() && err.contains("is a run directory (it holds run.json)") && err.contains("--out"), "{err}");
    assert!(!n.join("run/run").exists() && !n.join("run/report").exists());
    // A run made longer by `clv forward --resume --steps` (with the window `clv run` asks
    // for that length) since its report: that report is the run's result at its earlier
    // length, kept beside that length's other results, and the report is written anew.
    let e = base.join("e");
    let longer = |steps: &str| clv(&["run", "--out", e.to_str().unwrap(), "--n", "8", "--steps", steps, "--relax-steps", "50", "--quiet"]);
    ok(longer("600"));
    ok(clv(&["forward", "--resume", e.join("run").to_str().unwrap(), "--steps", "800", "--clv-steps", "85", "--transient", "42", "--quiet"]));
    ok(longer("800"));
    assert!(e.join("run/previous-600-steps/report/summary.json").exists(), "the earlier report is kept");
    assert!(read(&e.join("report/index.html")).contains("\"steps\":800"), "the report is the longer run's");
    // Made longer keeping its window (as `clv forward --resume --steps` does by default),
    // the run is taken by `clv run` of its new length with that window, not refused as
    // another configuration.
    ok(clv(&["forward", "--resume", e.join("run").to_str().unwrap(), "--steps", "1000", "--quiet"]));
    ok(longer("1000"));
    assert!(e.join("run/previous-800-steps/report/summary.json").exists() && read(&e.join("report/index.html")).contains("\"steps\":1000"));
    // A window asked for that the run does not have is still another configuration.
    let other = clv(&["run", "--out", e.to_str().unwrap(), "--n", "8", "--steps", "1000", "--relax-steps", "50", "--clv-steps", "90", "--quiet"]);
    assert!(!other.status.success() && common::stderr(&other).contains("another configuration"), "{}", common::stderr(&other));
    // A file where the run or the report goes.
    for part in ["run", "report"] {
        let o = n.parent().unwrap().join(format!("file-as-{part}"));
        std::fs::create_dir_all(&o).unwrap();
        std::fs::write(o.join(part), "mine").unwrap();
        let out = run(&o, &[]);
        let err = common::stderr(&out);
        assert!(!out.status.success() && err.contains(&format!("{} is a file, where `clv run` keeps the {part}", o.join(part).display())), "{err}");
        assert_eq!(read(&o.join(part)), "mine");
        std::fs::remove_file(o.join(part)).unwrap();
        std::os::unix::fs::symlink(o.join("nowhere"), o.join(part)).unwrap();
        let err = common::stderr(&run(&o, &[]));
        assert!(err.contains(&format!("{} is a symbolic link to nothing", o.join(part).display())), "{err}");
    }
}

/// Indices given to --j twice are drawn once, in the order first given.
#[test]
fn repeated_j_indices_are_taken_once() {
    let base = scratch("repeated-j");
    let run = base.join("run");
    ok(clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "400", "--out", run.to_str().unwrap(), "--quiet"]));
    ok(clv(&["backward", run.to_str().unwrap(), "--quiet"]));
    let report = base.join("report");
    ok(clv(&["analyze", run.to_str().unwrap(), "--out", report.to_str().unwrap(), "--only", "spectrum", "--j", "2,2,1,2", "--quiet"]));
    let summary: serde_json::Value = serde_json::from_str(&read(&report.join("summary.json"))).unwrap();
    assert_eq!(summary["options"]["j"], serde_json::json!([2, 1]), "{summary}");
}

/// A stream with anything after its end (two streams concatenated, other output mixed in)
/// is not analysed as if it were whole: the rest would go unread without a word.
#[test]
fn data_after_a_streams_end_is_reported() {
    let base = scratch("trailing");
    let run = base.join("run");
    ok(clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "300", "--out", run.to_str().unwrap(), "--quiet"]));
    let stream = ok(clv(&["backward", run.to_str().unwrap(), "--out", "-", "--quiet"])).stdout;
    let analyze = |input: Vec<u8>, name: &str| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_clv"))
            .args(["analyze", "-", "--out", base.join(name).to_str().unwrap(), "--only", "spectrum", "--quiet"])
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // The reader stops at the first byte after the end: the rest meets a closed pipe.
        let _ = std::io::Write::write_all(&mut child.stdin.take().unwrap(), &input);
        child.wait_with_output().unwrap()
    };
    ok(analyze(stream.clone(), "whole"));
    let twice = analyze([stream.clone(), stream].concat(), "twice");
    let err = common::stderr(&twice);
    assert!(!twice.status.success() && err.contains("goes on after its end") && !base.join("twice/summary.json").exists(), "{err}");
}

/// The forward stage's warning of a --tau too long for a double's digits follows its
/// exponents into every later stage that shows them: inspect, the backward stage's table
/// and --json (the same R matrices), and the report, whose Fig. 2 would otherwise show
/// two spectra that agree because both are off; so does the warning of an unsettled null
/// space.
#[test]
fn a_precision_warning_follows_the_exponents_into_every_stage() {
    let base = scratch("tau-warned");
    let run = base.join("run");
    let r = run.to_str().unwrap();
    ok(clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "200", "--relax-steps", "20", "--tau", "2.5", "--quiet", "--out", r]));
    let text = |out: std::process::Output| String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(text(ok(clv(&["inspect", r]))).contains("warning: (lambda_1 - lambda_k) tau"));
    let table = text(ok(clv(&["backward", r, "--quiet"])));
    assert!(table.contains("warning (of the forward stage): (lambda_1 - lambda_k) tau"), "{table}");
    let v: serde_json::Value = serde_json::from_slice(&ok(clv(&["backward", r, "--quiet", "--json", "--out", base.join("f.mcap").to_str().unwrap()])).stdout).unwrap();
    assert!(v["warnings"][0].as_str().is_some_and(|w| w.contains("give a --tau below")), "{v}");
    let report = base.join("report");
    ok(clv(&["analyze", r, "--out", report.to_str().unwrap(), "--only", "spectrum", "--quiet"]));
    let summary: serde_json::Value = serde_json::from_str(&read(&report.join("summary.json"))).unwrap();
    assert!(summary["warnings"][0].as_str().is_some_and(|w| w.starts_with("The forward stage warned: (lambda_1")), "{summary}");
    assert!(summary["produced"][0]["caption"].as_str().is_some_and(|c| c.starts_with("The forward stage warned that (lambda_1")), "{summary}");
    // The default tau warns of nothing.
    let quiet = base.join("quiet");
    ok(clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "200", "--relax-steps", "20", "--quiet", "--out", quiet.to_str().unwrap()]));
    assert!(!text(ok(clv(&["backward", quiet.to_str().unwrap(), "--quiet"]))).contains("warning"));
    // A dilute gas relaxed too briefly: its null space has not settled, and that follows the
    // exponents likewise.
    let dilute = base.join("dilute");
    let d = dilute.to_str().unwrap();
    let table = text(ok(clv(&["forward", "--n", "8", "--density", "0.05", "--aspect", "1", "--steps", "100", "--relax-steps", "10", "--quiet", "--out", d])));
    assert!(table.contains("warning: the null-space exponents (i = 14..19)") && table.contains("give more --relax-steps (10 now"), "{table}");
    assert!(text(ok(clv(&["inspect", d]))).contains("warning: the null-space exponents"));
    assert!(text(ok(clv(&["backward", d, "--quiet"]))).contains("warning (of the forward stage): the null-space exponents"));
    let report = base.join("dilute-report");
    ok(clv(&["analyze", d, "--out", report.to_str().unwrap(), "--only", "spectrum", "--quiet"]));
    let summary: serde_json::Value = serde_json::from_str(&read(&report.join("summary.json"))).unwrap();
    assert!(summary["warnings"][0].as_str().is_some_and(|w| w.starts_with("The forward stage warned: the null-space exponents")), "{summary}");
    assert!(summary["produced"][0]["caption"].as_str().is_some_and(|c| c.starts_with("The forward stage warned that the null-space exponents")), "{summary}");
}

/// A run of a single block has no standard errors: NaN, written to JSON as null, which every
/// reader takes back as unknown (it was refused as a damaged file, with a repair that wrote
/// it again the same). A run too short for the default window is told which flags fit it.
#[test]
fn a_run_of_one_block_is_read_by_every_stage() {
    let base = scratch("one-block");
    let (one, two) = (base.join("one"), base.join("two"));
    let err = common::stderr(&clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "1", "--quiet", "--out", one.to_str().unwrap()]));
    assert!(err.contains("give --steps 2 or more") && err.contains("--transient 0"), "{err}");
    ok(clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "1", "--clv-steps", "1", "--transient", "0", "--quiet", "--out", one.to_str().unwrap()]));
    assert!(read(&one.join("spectrum.json")).contains("null"), "the test needs a run without errors");
    let table = String::from_utf8_lossy(&ok(clv(&["backward", one.to_str().unwrap(), "--quiet"])).stdout).into_owned();
    assert!(table.contains("NaN"), "{table}");
    ok(clv(&["analyze", one.to_str().unwrap(), "--out", base.join("report").to_str().unwrap(), "--quiet"]));
    // One frame: the report says why its errors are NaN.
    let summary = read(&base.join("report/summary.json"));
    assert!(summary.contains("no standard errors (NaN in the table): they need at least two blocks") && !summary.contains("agree within the errors"), "{summary:.2000}");
    ok(clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "40", "--seed", "2", "--quiet", "--out", two.to_str().unwrap()]));
    let combined = String::from_utf8_lossy(&ok(clv(&["combine", one.to_str().unwrap(), two.to_str().unwrap()])).stdout).into_owned();
    assert!(combined.contains("chi2/dof of the runs about the combined spectrum: not known"), "{combined}");
}

/// `scripts/SCRIPT` on a run of `forward` (the forward flags, seed 1) and its frames of
/// `backward --with-gs`: its JSON report. The same on the frames of seed 2 must fail, so that
/// the check can fail at all.
fn independent_check(script: &str, forward: &[&str]) -> Option<serde_json::Value> {
    if !common::python_has("mcap, cbor2, numpy") {
        return None;
    }
    let base = scratch(script);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts").join(script);
    let run_with = |seed: &str| {
        let run = base.join(format!("run-{seed}"));
        let frames = base.join(format!("frames-{seed}.mcap"));
        ok(clv(&[forward, &["--seed", seed, "--quiet", "--out", run.to_str().unwrap()]].concat()));
        ok(clv(&["backward", run.to_str().unwrap(), "--out", frames.to_str().unwrap(), "--with-gs", "--quiet"]));
        (run, frames)
    };
    let ((run, frames), (_, other)) = (run_with("1"), run_with("2"));
    let out = Command::new("python3").arg(&script).arg(&run).arg(&other).output().unwrap();
    assert!(!out.status.success() && common::stderr(&out).contains("disagreement"), "{}", common::stderr(&out));
    let out = ok(Command::new("python3").arg(&script).arg(&run).arg(&frames).output().unwrap());
    Some(serde_json::from_slice(&out.stdout).unwrap())
}

/// An independent implementation (scripts/verify_henon.py: numpy, from the checkpoint of step
/// 0 alone) of the Henon map, its QR iteration and Ginelli's backward pass agrees with the
/// run and its frames to round-off: spectra, G_n, V_n, local exponents, covariance.
#[test]
fn an_independent_henon_implementation_agrees() {
    let Some(v) = independent_check("verify_henon.py", &["forward", "--system", "henon", "--steps", "2000", "--relax-steps", "100"]) else { return };
    assert!(v["agree"] == true && v["frames"].as_u64() > Some(200), "{v}");
}

/// The covariant vectors of a hard-disk run are covariant by finite differences of the flow
/// (scripts/verify_disks.py: its own event-driven integrator, no tangent-space code), and
/// satisfy the exact identities of G_n and V_n in every frame.
#[test]
fn hard_disk_vectors_are_covariant_by_finite_differences() {
    let forward = ["forward", "--n", "8", "--aspect", "2/11", "--steps", "600", "--relax-steps", "100", "--clv-steps", "100"];
    let Some(v) = independent_check("verify_disks.py", &forward) else { return };
    assert!(v["agree"] == true && v["sampled"].as_u64() == Some(8), "{v}");
}

/// The tables of a hard-disk report agree with scripts/verify_report.py, which recomputes them
/// from the frames with its own numpy code (spectrum, localization, projections, overlaps,
/// null space, Theta minima and histograms, local and finite-time exponents, domination,
/// convergence, and the Lyapunov modes of a second, larger system that has them), on the
/// frames of every 3rd step as the report samples them; a report with one number of any of
/// these tables altered (relative 1e-6) is exactly that one disagreement. The captions' numbers
/// are checked too, and one altered in index.html (or a phrase reworded) is exactly one
/// disagreement naming the caption.
#[test]
fn an_independent_recomputation_agrees_with_the_report_tables() {
    if !common::python_has("mcap, cbor2, numpy") {
        return;
    }
    let base = scratch("verify-report");
    let (run, frames, report) = (base.join("run"), base.join("frames.mcap"), base.join("report"));
    // --store-r all with --clv-steps + --transient = --steps: R_n is kept at every measured
    // step 101..700, so that the script recomputes the forward GS spectrum from it (--run).
    ok(clv(&["forward", "--n", "8", "--aspect", "2/11", "--steps", "600", "--relax-steps", "100", "--clv-steps", "300", "--transient", "300", "--store-r", "all", "--seed", "1", "--quiet", "--out", run.to_str().unwrap()]));
    ok(clv(&["backward", run.to_str().unwrap(), "--out", frames.to_str().unwrap(), "--with-gs", "--quiet"]));
    ok(clv(&["analyze", frames.to_str().unwrap(), "--every", "3", "--out", report.to_str().unwrap(), "--quiet"]));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/verify_report.py");
    let verify = |report: &Path, frames: &Path| Command::new("python3").arg(&script).arg(report).arg(frames).output().unwrap();
    let verify_with_run = |report: &Path, frames: &Path| Command::new("python3").arg(&script).arg(report).arg(frames).arg("--run").arg(&run).output().unwrap();
    let out = ok(verify_with_run(&report, &frames));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["agree"] == true && v["every"] == 3 && v["sampled"].as_u64() == Some(100), "{v}");
    // lambda_gs and stderr_gs from the run's R_n (steps 101..700, 20 blocks of 30), against
    // spectrum.csv, the run's spectrum.json and the frame file's copy of it.
    assert!(v["forward_r"]["steps"] == serde_json::json!([101, 700]) && v["forward_r"]["blocks"] == 20 && v["forward_r"]["block_steps"] == 30, "{v}");
    for (table, columns) in [("spectrum.csv", &["lambda_gs", "stderr_gs"][..]), ("run/spectrum.json", &["exponents", "stderr", "blocks.block_steps", "blocks.exponents[19]"]), ("frames/spectrum.json", &["exponents", "stderr"])] {
        assert!(v["checked"][table].as_f64().is_some_and(|d| d < 1e-12), "{table}: {v}");
        for column in columns {
            assert!(v["columns"][table].as_array().unwrap().iter().any(|c| c == column), "{table} {column}: {v}");
        }
    }
    let all_checked = |v: &serde_json::Value, tables: &[&str]| {
        for table in tables {
            assert!(v["checked"][table].as_f64().is_some_and(|d| d < 1e-12), "{table}: {v}");
        }
    };
    all_checked(&v, &["spectrum.csv", "local_exponents.csv", "finite_time_exponents.csv", "domination.csv", "localization.csv", "projections.csv", "overlap_gs_clv.csv", "overlap_clv_gs.csv", "overlap_clv_clv.csv", "nullspace_alpha.csv", "nullspace_beta.csv", "theta_min.csv", "theta_histograms.csv", "convergence_gs.csv", "convergence_clv.csv", "convergence_tests.csv", "modes.csv", "modes.json", "transversality.csv", "nullspace_series.csv", "nullspace_tables.json", "domination_pairs.csv"]);
    // The errors are checked too: batch means (stderr columns, in "checked" above) and the
    // _std columns, sample deviations over the frames (Welford's sums in clv: a constant's is 0).
    for (table, columns) in [("spectrum.csv", &["stderr_clv", "stderr_gs_window", "stderr_gs"][..]), ("localization.csv", &["stderr_gs", "stderr_clv"]), ("projections.csv", &["eta_q_gs_std", "eta_q_clv_std"]), ("overlap_gs_clv.csv", &["abs_g_dot_v_std"]), ("overlap_clv_gs.csv", &["abs_v12_std"]), ("overlap_clv_clv.csv", &["abs_v7_std"]), ("local_exponents.csv", &["time", "lambda_1"]), ("finite_time_exponents.csv", &["windows", "mean", "std", "min", "max"]), ("domination.csv", &["overall", "outside_null", "border_unstable_null", "split_null_stable"]), ("convergence_clv.csv", &["t", "lambda_1"]), ("convergence_tests.csv", &["tested", "h_ks_z", "h_ks_chance", "r1"]), ("theta_histograms.csv", &["theta_lo", "density_sep_1", "density_sep_8"]), ("spectrum.csv", &["i_over_D", "zero_by_symmetry", "lambda_clv_null_shear"]), ("transversality.csv", &["psi_unstable_stable"]), ("nullspace_series.csv", &["time", "angle_clv", "angle_gs", "angle_gs_clv", "norm_beta_17", "norm_alpha_14"]), ("nullspace_tables.json", &["step", "indices", "e1", "e6"]), ("domination_pairs.csv", &["delta_1", "delta_50"])] {
        for column in columns {
            assert!(v["columns"][table].as_array().unwrap().iter().any(|c| c == column), "{table} {column}: {v}");
        }
    }
    for table in ["projections.csv", "overlap_gs_clv.csv", "overlap_clv_gs.csv", "overlap_clv_clv.csv"] {
        assert!(v["checked_std"][table].as_f64().is_some_and(|d| d < 1e-12), "{table}: {v}");
    }
    // A file of every third step (--save-every 3): lambda_clv averages the frames it holds,
    // and so must the shear model's prediction of the last three null-space exponents (clv
    // gave the average over the whole span of steps, 1.4e-3 relative off, until 2026-11-27).
    let (sparse, sparse_report) = (base.join("frames-every-3.mcap"), base.join("report-every-3"));
    ok(clv(&["backward", run.to_str().unwrap(), "--out", sparse.to_str().unwrap(), "--with-gs", "--save-every", "3", "--quiet"]));
    ok(clv(&["analyze", sparse.to_str().unwrap(), "--every", "3", "--out", sparse_report.to_str().unwrap(), "--quiet"]));
    let s: serde_json::Value = serde_json::from_slice(&ok(verify(&sparse_report, &sparse)).stdout).unwrap();
    assert!(s["agree"] == true && s["frames"] == 100 && s["columns"]["spectrum.csv"].as_array().unwrap().iter().any(|c| c == "lambda_clv_null_shear"), "{s}");
    // Frames without GS vectors: the report's GS columns are NaN, and checked to be.
    let (covariant, covariant_report) = (base.join("frames-clv.mcap"), base.join("report-clv"));
    ok(clv(&["backward", run.to_str().unwrap(), "--out", covariant.to_str().unwrap(), "--quiet"]));
    ok(clv(&["analyze", covariant.to_str().unwrap(), "--every", "3", "--out", covariant_report.to_str().unwrap(), "--quiet"]));
    let cv: serde_json::Value = serde_json::from_slice(&ok(verify(&covariant_report, &covariant)).stdout).unwrap();
    assert!(cv["agree"] == true && cv["columns"]["localization.csv"].as_array().unwrap().iter().any(|c| c == "W_gs"), "{cv}");

    // The N = 8 system has no mode steps. N = 40 in the paper's box has a T(1,0) pair and an
    // LP(1,0) quadruplet next to it (and their mirrors): the mode table, the sine fits, the
    // reconstructed L and P vectors, the dispersion table and the per-disk pattern tables.
    let (modes_run, modes_frames, modes_report) = (base.join("modes-run"), base.join("modes-frames.mcap"), base.join("modes-report"));
    ok(clv(&["forward", "--n", "40", "--aspect", "2/11", "--steps", "600", "--relax-steps", "100", "--clv-steps", "60", "--seed", "1", "--quiet", "--out", modes_run.to_str().unwrap()]));
    ok(clv(&["backward", modes_run.to_str().unwrap(), "--out", modes_frames.to_str().unwrap(), "--with-gs", "--quiet"]));
    ok(clv(&["analyze", modes_frames.to_str().unwrap(), "--every", "3", "--out", modes_report.to_str().unwrap(), "--quiet"]));
    let m: serde_json::Value = serde_json::from_slice(&ok(verify(&modes_report, &modes_frames)).stdout).unwrap();
    assert!(m["agree"] == true && m["mode_steps"].as_array().is_some_and(|s| s.len() >= 4), "{m}");
    let pattern = |prefix: &str| m["checked"].as_object().unwrap().keys().find(|t| t.starts_with(prefix)).cloned().unwrap_or_else(|| panic!("no {prefix}* table: {m}"));
    let (fig10, lp) = (pattern("fig10_T"), pattern("LP"));
    all_checked(&m, &["modes.csv", "modes.json", "modes_fits.csv", "modes_lp.csv", "modes_dispersion.csv", &fig10, &lp, "theta_min.csv", "theta_histograms.csv", "transversality.csv"]);
    // Fig. 15's Phi of each positive mode step beside Psi.
    let phis: Vec<String> = m["columns"]["transversality.csv"].as_array().unwrap().iter().filter_map(|c| c.as_str()).filter(|c| c.starts_with("phi_")).map(String::from).collect();
    assert!(phis.len() >= 2, "{m}");

    // N = 100 in a square box: T(1,0) and T(0,1) are degenerate by symmetry, one step of
    // four exponents (i = 194..197 with this seed), and Fig. 10 shows each wave vector's
    // pure T vector reconstructed inside it, with dq along k as a check.
    let (square_run, square_frames, square_report) = (base.join("square-run"), base.join("square-frames.mcap"), base.join("square-report"));
    ok(clv(&["forward", "--n", "100", "--aspect", "1", "--steps", "800", "--relax-steps", "200", "--clv-steps", "30", "--seed", "1", "--quiet", "--out", square_run.to_str().unwrap()]));
    ok(clv(&["backward", square_run.to_str().unwrap(), "--out", square_frames.to_str().unwrap(), "--with-gs", "--quiet"]));
    ok(clv(&["analyze", square_frames.to_str().unwrap(), "--every", "3", "--out", square_report.to_str().unwrap(), "--quiet"]));
    let sq: serde_json::Value = serde_json::from_slice(&ok(verify(&square_report, &square_frames)).stdout).unwrap();
    assert!(sq["agree"] == true, "{sq}");
    let square_fig10: Vec<&String> = sq["checked"].as_object().unwrap().keys().filter(|t| t.starts_with("fig10_T")).collect();
    assert_eq!(square_fig10.len(), 2, "one table per wave vector of T(1,0)+T(0,1): {sq}");
    all_checked(&sq, &["modes.csv", "modes.json", square_fig10[0].as_str(), square_fig10[1].as_str()]);
    for (table, check) in [("fig10_T1_i197.csv", "dqx_clv"), ("fig10_T0_1_i197.csv", "dqy_clv")] {
        assert!(sq["columns"][table].as_array().is_some_and(|c| c.iter().any(|c| c == check)), "{table} {check}: {sq}");
    }

    // One number of one table off by a relative 1e-6 (in a copy of the report, the other
    // tables as written): exactly that one disagreement, and exit 1. Rows are counted from 1
    // after the header (in a table of indices i = 1, 2, ..., row i is index i); the message
    // names a table of frames by the row's step.
    let fields = |line: &str| -> Vec<String> {
        // split at the commas outside quotes ("T(1,0)"), keeping the quotes so that the
        // altered line is written back as it was (report::dir::csv_cells drops them)
        let (mut out, mut cell, mut quoted) = (Vec::new(), String::new(), false);
        for ch in line.chars() {
            match ch {
                ',' if !quoted => out.push(std::mem::take(&mut cell)),
                _ => {
                    quoted ^= ch == '"';
                    cell.push(ch);
                }
            }
        }
        out.push(cell);
        out
    };
    let copy = |report: &Path| {
        let altered = report.with_extension("altered");
        common::copy_dir(report, &altered);
        altered
    };
    let (altered, modes_altered) = (copy(&report), copy(&modes_report));
    let is_the_one = |out: &std::process::Output, what: &str| {
        let err = common::stderr(out);
        assert!(out.status.code() == Some(1) && err.contains(&format!("disagreement: {what} ")), "{what}: {err}");
        assert_eq!(err.lines().filter(|l| l.starts_with("disagreement")).count(), 1, "{err}");
    };
    let altered_by = |verify: &dyn Fn(&Path, &Path) -> std::process::Output, (report, altered, frames): (&Path, &Path, &Path), file: &str, column: &str, i: usize| {
        let table = read(&report.join(file));
        let mut lines: Vec<String> = table.lines().map(str::to_string).collect();
        let at = fields(&lines[0]).iter().position(|c| c == column).unwrap();
        let mut cells = fields(&lines[i]);
        if lines[0].starts_with("i,") {
            assert_eq!(cells[0], i.to_string());
        }
        let row = if lines[0].starts_with("step,") { cells[0].clone() } else { i.to_string() };
        let x: f64 = cells[at].parse().unwrap();
        assert!(x != 0.0 && x.is_finite(), "{file} {column} {i}: {x} does not change by a relative 1e-6");
        cells[at] = format!("{:e}", x * (1.0 + 1e-6));
        lines[i] = cells.join(",");
        std::fs::write(altered.join(file), lines.join("\n") + "\n").unwrap();
        let out = verify(altered, frames);
        std::fs::copy(report.join(file), altered.join(file)).unwrap();
        is_the_one(&out, &format!("{file} {column} {row}"));
    };
    let one_altered = |files: (&Path, &Path, &Path), file: &str, column: &str, i: usize| altered_by(&verify, files, file, column, i);
    // The row of a column's largest value (a histogram's densities are mostly 0).
    let largest = |report: &Path, file: &str, column: &str| {
        let table = read(&report.join(file));
        let at = fields(table.lines().next().unwrap()).iter().position(|c| c == column).unwrap();
        let values: Vec<f64> = table.lines().skip(1).map(|l| fields(l)[at].parse().unwrap()).collect();
        1 + (0..values.len()).max_by(|&a, &b| values[a].total_cmp(&values[b])).unwrap()
    };
    let small = (report.as_path(), altered.as_path(), frames.as_path());
    // lambda_3 of the forward run altered: against the R_n of the run (--run), exactly that
    // one disagreement.
    altered_by(&verify_with_run, small, "spectrum.csv", "lambda_gs", 3);
    for (file, column, row) in [
        ("localization.csv", "W_clv", 2),
        ("spectrum.csv", "stderr_clv", 3),
        ("spectrum.csv", "stderr_gs", 3),
        ("theta_histograms.csv", "density_sep_2", largest(&report, "theta_histograms.csv", "density_sep_2")),
        ("convergence_clv.csv", "lambda_1", 2),
        ("convergence_gs.csv", "lambda_5", 3),
        ("convergence_tests.csv", "h_ks_chance", 2),
        ("spectrum.csv", "i_over_D", 5),
        ("spectrum.csv", "zero_by_symmetry", 14),
        ("spectrum.csv", "lambda_clv_null_shear", 17),
        ("domination_pairs.csv", "delta_5", largest(&report, "domination_pairs.csv", "delta_5")),
        ("transversality.csv", "psi_unstable_stable", 4),
        ("nullspace_series.csv", "norm_beta_17", 2),
    ] {
        one_altered(small, file, column, row);
    }
    // A row deleted, or renumbered, is a disagreement too (the comparisons take their rows
    // from the report itself), and so is a column nothing recomputes.
    for (file, change, what) in [
        ("localization.csv", "delete", "localization.csv rows: missing [(7,)]"),
        ("local_exponents.csv", "delete", "local_exponents.csv rows: missing"),
        ("projections.csv", "renumber", "projections.csv rows: missing [(7,)]; repeated [(8,)]"),
        ("overlap_gs_clv.csv", "column", "overlap_gs_clv.csv column extra is not recomputed here"),
    ] {
        let table = read(&report.join(file));
        let mut lines: Vec<String> = table.lines().map(str::to_string).collect();
        match change {
            "delete" => {
                lines.remove(7);
            }
            "renumber" => lines[7] = lines[7].replacen("7,", "8,", 1),
            _ => lines.iter_mut().enumerate().for_each(|(r, l)| l.push_str(if r == 0 { ",extra" } else { ",1" })),
        }
        std::fs::write(altered.join(file), lines.join("\n") + "\n").unwrap();
        let out = verify(&altered, &frames);
        std::fs::copy(report.join(file), altered.join(file)).unwrap();
        assert!(out.status.code() == Some(1) && common::stderr(&out).contains(what), "{file} {change}: {}", common::stderr(&out));
    }
    // nullspace_tables.json: beta's largest entry of its first row (the others are round-off,
    // which a relative 1e-6 does not move beyond the tolerance).
    let mut json: serde_json::Value = serde_json::from_str(&read(&report.join("nullspace_tables.json"))).unwrap();
    let row = json["beta"][0].as_array().unwrap().clone();
    let k = (0..6).max_by(|&a, &b| row[a].as_f64().unwrap().abs().total_cmp(&row[b].as_f64().unwrap().abs())).unwrap();
    json["beta"][0][k] = serde_json::json!(row[k].as_f64().unwrap() * (1.0 + 1e-6));
    std::fs::write(altered.join("nullspace_tables.json"), serde_json::to_vec_pretty(&json).unwrap()).unwrap();
    is_the_one(&verify(&altered, &frames), &format!("nullspace_tables.json e{} 1", k + 1));
    std::fs::copy(report.join("nullspace_tables.json"), altered.join("nullspace_tables.json")).unwrap();
    let with_modes = (modes_report.as_path(), modes_altered.as_path(), modes_frames.as_path());
    one_altered(with_modes, "modes.csv", "fraction_gs", 1);
    one_altered(with_modes, "modes.csv", "resolved", 2);
    one_altered(with_modes, "modes_fits.csv", "resid_dpt", 2);
    one_altered(with_modes, "modes_lp.csv", "overlap", 3);
    one_altered(with_modes, "modes_dispersion.csv", "stderr", 1);
    one_altered(with_modes, &fig10, "dqy_clv", 3);
    one_altered(with_modes, &lp, "fig12_P_dp_over_p_gs", 4);
    one_altered(with_modes, "transversality.csv", &phis[0], 3);
    // modes.json: the same number as modes.csv's, in its rows.
    let mut json: serde_json::Value = serde_json::from_str(&read(&modes_report.join("modes.json"))).unwrap();
    let x = json["modes"][0]["lambda"].as_f64().unwrap();
    json["modes"][0]["lambda"] = serde_json::json!(x * (1.0 + 1e-6));
    std::fs::write(modes_altered.join("modes.json"), serde_json::to_vec_pretty(&json).unwrap()).unwrap();
    is_the_one(&verify(&modes_altered, &modes_frames), "modes.json lambda 1");
    std::fs::copy(modes_report.join("modes.json"), modes_altered.join("modes.json")).unwrap();

    // The captions' numbers are checked too (against the recomputation, at their printed
    // precision): h_KS, the null-shear prediction, the median errors, the convergence tests,
    // Psi, Phi and Theta, the null space, the modes found and their overlaps.
    let captions = |v: &serde_json::Value, title: &str, what: &str| {
        assert!(v["captions"][title].as_array().is_some_and(|c| c.iter().any(|c| c.as_str().is_some_and(|c| c.starts_with(what)))), "{title}: {what}: {v}");
    };
    for (title, what) in [
        ("Lyapunov spectrum (Fig. 2)", "h_KS (CLV)"),
        ("Lyapunov spectrum (Fig. 2)", "h_KS error (GS, whole run)"),
        ("Lyapunov spectrum (Fig. 2)", "null-shear prediction"),
        ("Lyapunov spectrum (Fig. 2)", "null-shear measured"),
        ("Mode region of the spectrum (Fig. 8)", "median stderr (CLV)"),
        ("Convergence of the spectra (beyond the paper)", "CLV z of h_KS"),
        ("Null space (Tables I, II)", "largest angle_clv"),
        ("Transversality of conjugate subspaces (Fig. 15)", "min Psi (rad)"),
        ("Angles between covariant vectors (Fig. 16)", "first bin density"),
        ("Minimum angle between covariant vectors (Fig. 17)", "min Theta"),
        ("Domination of the Oseledec splitting (Sec. 6)", "overall at"),
    ] {
        captions(&v, title, what);
    }
    captions(&s, "Lyapunov spectrum (Fig. 2)", "null-shear frames"); // the words for frames of every third step
    for (title, what) in [
        ("Lyapunov modes (Table III)", "i = "),
        ("Scalar products of mode vectors (Fig. 14)", "j = "),
        ("Transversality of conjugate subspaces (Fig. 15)", "Phi i = "),
        ("Dispersion of the Lyapunov modes (beyond the paper)", "T slope c"),
        ("Transverse mode T(1,0) (Fig. 10)", "k"),
        ("Longitudinal-momentum mode LP(1,0) (Figs. 11, 12)", "rms across / along"),
        ("Longitudinal-momentum mode LP(1,0) (Figs. 11, 12)", "figures with points off scale"),
    ] {
        captions(&m, title, what);
    }
    captions(&sq, "Transverse mode T(1,0) of T(1,0)+T(0,1) (Fig. 10)", "overlaps");
    // A number of a caption altered in its last printed digit, or a phrase reworded, in a
    // copy of index.html: exactly that one disagreement, naming the caption, and exit 1.
    let caption_altered = |(report, altered, frames): (&Path, &Path, &Path), from: &str, to: &str, what: &str| {
        let page = read(&report.join("index.html"));
        assert_eq!(page.matches(from).count(), 1, "{from}");
        std::fs::write(altered.join("index.html"), page.replace(from, to)).unwrap();
        let out = verify(altered, frames);
        std::fs::copy(report.join("index.html"), altered.join("index.html")).unwrap();
        is_the_one(&out, &format!("caption '{what}'"));
    };
    // The text of a page between the first `start` and the next `end`.
    let between = |page: &str, start: &str, end: &str| -> String {
        let a = page.find(start).unwrap_or_else(|| panic!("{start}")) + start.len();
        page[a..a + page[a..].find(end).unwrap()].to_string()
    };
    let page = read(&report.join("index.html"));
    // h_KS of the CLV spectrum ("X ± E (GS), Y ± E (CLV)"), 6 decimals: the last one off by 2.
    let h = between(&page, " (GS), ", " ± ");
    caption_altered(small, &format!(" (GS), {h} ± "), &format!(" (GS), {:.6} ± ", h.parse::<f64>().unwrap() + 2e-6), "Lyapunov spectrum (Fig. 2)");
    // The null-shear prediction "= X;" (4 decimals of its mantissa).
    let p = between(&page, "(2 (s2 - s1)) = ", "e");
    caption_altered(small, &format!("(2 (s2 - s1)) = {p}e"), &format!("(2 (s2 - s1)) = {:.4}e", p.parse::<f64>().unwrap() - 2e-4), "Lyapunov spectrum (Fig. 2)");
    caption_altered(small, "Median standard errors of the plotted exponents", "Median errors of the plotted exponents", "Mode region of the spectrum (Fig. 8)");
    let psi = between(&page, "(min ", "° = ");
    caption_altered(small, &format!("(min {psi}° = "), &format!("(min {:.2}° = ", psi.parse::<f64>().unwrap() + 0.02), "Transversality of conjugate subspaces (Fig. 15)");
    let modes_page = read(&modes_report.join("index.html"));
    let lambda = between(&modes_page, ", λ = ", " ");
    caption_altered(with_modes, &format!(", λ = {lambda} "), &format!(", λ = {:.4} ", lambda.parse::<f64>().unwrap() + 2e-4), "Lyapunov modes (Table III)");
    // Fig. 10's k (4 decimals) and Figs. 11-12's rms check of the GS vector (2 decimals).
    let k = between(&modes_page, "in the same colours, k = ", ". Fits");
    caption_altered(with_modes, &format!("colours, k = {k}. Fits"), &format!("colours, k = {:.4}. Fits", k.parse::<f64>().unwrap() + 2e-4), "Transverse mode T(1,0) (Fig. 10)");
    let rms = between(&modes_page, "rms δq_y / rms δq_x = GS ", ",");
    caption_altered(with_modes, &format!("rms δq_y / rms δq_x = GS {rms},"), &format!("rms δq_y / rms δq_x = GS {:.2},", rms.parse::<f64>().unwrap() + 0.02), "Longitudinal-momentum mode LP(1,0) (Figs. 11, 12)");
}

/// Frames of the k < D leading vectors: the report says once what needs all D and is left
/// out (the mode steps, the Oseledec angles), rather than figures going missing unsaid.
#[test]
fn a_report_of_k_leading_vectors_says_what_it_leaves_out() {
    let base = scratch("k-leading");
    let run = base.join("run");
    ok(clv(&["forward", "--n", "4", "--aspect", "1", "--steps", "300", "--relax-steps", "20", "--vectors", "8", "--quiet", "--out", run.to_str().unwrap()]));
    ok(clv(&["backward", run.to_str().unwrap(), "--with-gs", "--quiet"]));
    let report = base.join("report");
    ok(clv(&["analyze", run.to_str().unwrap(), "--out", report.to_str().unwrap(), "--quiet"]));
    let summary: serde_json::Value = serde_json::from_str(&read(&report.join("summary.json"))).unwrap();
    let left_out = summary["left_out"].as_array().unwrap();
    assert!(left_out.len() == 1 && left_out[0].as_str().unwrap().contains("k = 8 leading of D = 16"), "{summary}");
    // Each analysis names what it leaves out: 8 < 2N + 3 = 11 vectors also miss the null space.
    let said = left_out[0].as_str().unwrap();
    for what in ["Fig. 8, the mode region", "the conjugate partners of Fig. 13, Fig. 14", "the null space, Tables I and II", "the mode steps of Table III", "Figs. 15-17"] {
        assert!(said.contains(what), "{what} not in {said}");
    }
    assert!(read(&report.join("index.html")).contains("<strong>Not in this report.</strong>"));
}
