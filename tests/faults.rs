//! Faults a week-long run meets, injected into the real binary: SIGKILL at many points, a
//! full disk, a second writer, numerical blow-ups, damaged files and streams, bad input.
//! The promise under test: a fault costs at most the work since the last checkpoint, never a
//! finished file, and never produces a silently wrong number.

mod common;
use common::*;
use clv::rng::Rng;
use clv::store::fault::{CRASH_POINTS, CRASH_STATUS};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const RUN: [&str; 15] = ["forward", "--quiet", "--n", "16", "--aspect", "1", "--steps", "3000", "--relax-steps", "100", "--checkpoint-every", "50", "--clv-steps", "500", "--segment-checkpoints"];

fn forward_args(dir: &Path) -> Vec<String> {
    let mut a: Vec<String> = RUN.iter().map(|s| s.to_string()).collect();
    a.extend(["4".into(), "--out".into(), dir.display().to_string()]);
    a
}

fn reference(name: &str) -> (std::path::PathBuf, Contents) {
    let dir = scratch("faults", name).join("run");
    let args = forward_args(&dir);
    ok(clv(&args.iter().map(String::as_str).collect::<Vec<_>>()));
    let c = contents(&dir);
    (dir, c)
}

/// At least 20 distinct kill points over forward and backward (each stage killed once in
/// every trial, its resumption too when it is still running); every resumed run equals the
/// uninterrupted one bit for bit.
#[test]
fn sigkill_at_many_points_then_resume_is_bit_identical() {
    let started = std::time::Instant::now();
    let (dir, want) = reference("kill-ref");
    let forward_ms = started.elapsed().as_millis() as u64;
    let bwd_ref = dir.parent().unwrap().join("frames-ref.mcap");
    let started = std::time::Instant::now();
    ok(clv(&["backward", dir.to_str().unwrap(), "--quiet", "--out", bwd_ref.to_str().unwrap()]));
    let backward_ms = started.elapsed().as_millis() as u64;
    let want_frames = frames(&bwd_ref);
    // A sweep killed before it recorded itself leaves the finished sweep's record: --resume
    // is refused with the way on, and writes nothing.
    let other = dir.parent().unwrap().join("frames-other.mcap");
    let refused = clv(&["backward", dir.to_str().unwrap(), "--quiet", "--out", other.to_str().unwrap(), "--resume"]);
    assert!(!refused.status.success() && stderr(&refused).contains("has finished") && stderr(&refused).contains("give the command without --resume"), "{}", stderr(&refused));
    assert!(!other.exists() && !dir.parent().unwrap().join("frames-other.mcap.tmp").exists());
    // Each trial starts without a record, as the documented recovery (resume_flag) assumes.
    std::fs::remove_file(dir.join("backward.json")).unwrap();
    let mut rng = Rng::new(99);
    // Kill points spread over the stage's own duration on this machine (5 % .. 90 %), so
    // that they land before its end however fast the machine is.
    let mut at = |ms: u64, share: f64| (ms as f64 * (0.05 + share * rng.uniform() * 0.85)) as u64;
    let mut kills = 0;
    for trial in 0..12 {
        let run = scratch("faults", &format!("kill-f{trial}")).join("run");
        let args = forward_args(&run);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        kill_landing(&args, at(forward_ms, 1.0), || drop(std::fs::remove_dir_all(&run)));
        kills += 1;
        // A second kill, this time of the resuming process.
        let r = run.to_str().unwrap();
        kills += kill_after(&["forward", "--resume", r, "--quiet"], at(forward_ms, 0.5)) as usize;
        ok(clv(&["forward", "--resume", r, "--quiet"]));
        assert!(contents(&run) == want, "forward trial {trial}: resumed run differs");
    }
    for trial in 0..8 {
        let out = dir.parent().unwrap().join(format!("frames-{trial}.mcap"));
        let o = out.to_str().unwrap();
        kill_landing(&["backward", dir.to_str().unwrap(), "--quiet", "--out", o], at(backward_ms, 1.0), || {
            let _ = std::fs::remove_file(&out);
            let _ = std::fs::remove_file(dir.join("backward.json"));
        });
        kills += 1;
        // Kill the resuming process too, early (while it salvages the frames) or later.
        let again = [&["backward", dir.to_str().unwrap(), "--quiet", "--out", o][..], &resume_flag(&dir)].concat();
        kills += kill_after(&again, at(backward_ms, 0.5)) as usize;
        if !out.exists() {
            ok(clv(&[&["backward", dir.to_str().unwrap(), "--quiet", "--out", o][..], &resume_flag(&dir)].concat()));
        }
        assert!(frames(&out) == want_frames, "backward trial {trial}: frames differ after resume");
        let _ = std::fs::remove_file(dir.join("backward.json"));
    }
    assert!(kills >= 20, "only {kills} kills landed before the end of a stage");
}

/// A `clv run` killed at any durable step of writing its report (or the records before it)
/// is finished by the same command given again: what the killed writer left behind is its
/// own, not files of the user's that the report must not replace (an outside check found
/// the manifest's temporary file refused as such).
#[test]
fn clv_run_killed_while_writing_its_report_is_finished_by_the_same_command() {
    let out = scratch("faults", "run-report-crash");
    let o = out.to_str().unwrap();
    let args = ["run", "--n", "16", "--aspect", "1", "--steps", "1000", "--threads", "1", "--out", o, "--quiet"];
    ok(clv(&args));
    let mut landed = 0;
    for point in ["atomic-synced", "atomic-renamed"] {
        for n in 1..=4 {
            let at = format!("{point}#{n}");
            std::fs::remove_dir_all(out.join("report")).unwrap();
            if crashed(&clv_env(&args, &[("CLV_FAULT_CRASH_AT", at.as_str())]), &at) {
                landed += 1;
                let again = clv(&args);
                assert!(again.status.success(), "{at}: {}", stderr(&again));
            }
            assert!(out.join("report/summary.json").is_file() && out.join("report/index.html").is_file(), "{at}");
        }
    }
    assert!(landed >= 4, "only {landed} crashes landed");
}

/// An argument that is not UTF-8 (a Latin-1 directory name) is refused, named, with the way
/// out; it was a panic.
#[test]
fn an_argument_that_is_not_utf8_is_named() {
    use std::os::unix::ffi::OsStrExt;
    let base = scratch("faults", "latin1");
    let out = Command::new(env!("CARGO_BIN_EXE_clv")).arg("run").arg("--out").arg(base.join(std::ffi::OsStr::from_bytes(b"r\xe9sultats"))).output().unwrap();
    let err = stderr(&out);
    assert!(out.status.code() == Some(1) && err.contains("argument 3 of the command line") && err.contains("is not UTF-8") && !err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read_dir(&base).unwrap().count(), 0, "nothing written");
}

/// Did the process stop at the crash point it was given?
fn crashed(out: &std::process::Output, at: &str) -> bool {
    if out.status.code() == Some(CRASH_STATUS) {
        return true;
    }
    assert!(out.status.success(), "{at}: {}", stderr(out));
    false
}

/// A crash at every point between two durable steps of the store (fault::CRASH_POINTS, at
/// their first and third occurrence), in the forward stage, the backward stage and
/// a resuming backward stage: the documented way on (rerun the command that crashed, with
/// --resume) ends in the uninterrupted run's files and frames, bit for bit.
#[test]
fn a_crash_between_any_two_durable_steps_is_recovered() {
    let (dir, want) = reference("crash-ref");
    let d = dir.to_str().unwrap();
    let bwd_ref = dir.parent().unwrap().join("frames-ref.mcap");
    ok(clv(&["backward", d, "--quiet", "--out", bwd_ref.to_str().unwrap()]));
    let want_frames = frames(&bwd_ref);
    let mut reached = std::collections::BTreeSet::new();
    for point in CRASH_POINTS {
        for n in [1, 3] {
            let at = format!("{point}#{n}");
            let env = [("CLV_FAULT_CRASH_AT", at.as_str())];
            let run = scratch("faults", &format!("crash-{point}-{n}")).join("run");
            let r = run.to_str().unwrap();
            let args = forward_args(&run);
            let out = clv_env(&args.iter().map(String::as_str).collect::<Vec<_>>(), &env);
            if crashed(&out, &at) {
                reached.insert(*point);
                if at == "atomic-synced#1" {
                    // Killed while it was created: run.tmp but no run.json yet.
                    let seen = clv(&["inspect", r]);
                    assert!(stderr(&seen).contains(&format!("`clv forward --resume {r}` completes it")), "{}", stderr(&seen));
                }
                if *point == "segment-synced" {
                    // A segment cut short by a crash is what --resume recomputes, not damage.
                    let seen = ok(clv(&["inspect", r]));
                    let text = String::from_utf8_lossy(&seen.stdout);
                    assert!(text.contains("interrupted (discarded on --resume)") && text.contains("all finished files intact"), "{text}");
                }
                ok(clv(&["forward", "--resume", r, "--quiet"]));
            }
            assert!(contents(&run) == want, "forward crashed at {at}: the resumed run differs");

            let _ = std::fs::remove_file(dir.join("backward.json"));
            let f = dir.parent().unwrap().join(format!("crash-{point}-{n}.mcap"));
            let o = f.to_str().unwrap();
            if crashed(&clv_env(&["backward", d, "--quiet", "--out", o], &env), &at) {
                reached.insert(*point);
                // Crashed before its first record (while writing it), a sweep starts again.
                ok(clv(&[&["backward", d, "--quiet", "--out", o][..], &resume_flag(&dir)].concat()));
            }
            assert!(frames(&f) == want_frames, "backward crashed at {at}: the resumed frames differ");
            // Compared, each file goes: the 64 of them would hold most of a gigabyte.
            let _ = std::fs::remove_file(&f);
            let _ = std::fs::remove_dir_all(run.parent().unwrap());

            // A sweep stopped after its eighth segment (150 frames after the backward
            // transient of 250 steps), then its resumption crashed too.
            let _ = std::fs::remove_file(dir.join("backward.json"));
            let f = dir.parent().unwrap().join(format!("crash-resume-{point}-{n}.mcap"));
            let o = f.to_str().unwrap();
            assert!(crashed(&clv_env(&["backward", d, "--quiet", "--out", o], &[("CLV_FAULT_CRASH_AT", "frames-synced#8")]), "frames-synced#8"));
            if crashed(&clv_env(&["backward", d, "--quiet", "--out", o, "--resume"], &env), &at) {
                reached.insert(*point);
                ok(clv(&["backward", d, "--quiet", "--out", o, "--resume"]));
            }
            assert!(frames(&f) == want_frames, "resumed backward crashed at {at}: the frames differ");
            let _ = std::fs::remove_file(&f);
        }
    }
    // Only an extension moves results, and only a repair that meets altered segments sets
    // segments aside: tests/store.rs crashes them there.
    let missed: Vec<_> = CRASH_POINTS.iter().filter(|p| !reached.contains(*p) && !["result-moved", "repair-set-aside"].contains(*p)).collect();
    assert!(missed.is_empty(), "crash points never reached: {missed:?}");
}

/// A tmpfs mounted for one test, unmounted when dropped (also when the test fails).
struct Tmpfs<'a>(&'a Path);

impl<'a> Tmpfs<'a> {
    /// None where this process may not mount one (not root, not Linux): the test says so.
    fn mount(at: &'a Path, size: &str) -> Option<Self> {
        let mounted = Command::new("mount").args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"]).arg(at).output().is_ok_and(|o| o.status.success());
        if !mounted {
            eprintln!("SKIPPED: cannot mount a tmpfs here (needs root on Linux)");
        }
        mounted.then_some(Tmpfs(at))
    }

    fn resize(&self, size: &str) {
        ok(Command::new("mount").args(["-o", &format!("remount,size={size}")]).arg(self.0).output().unwrap());
    }
}

impl Drop for Tmpfs<'_> {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(self.0).output();
    }
}

/// A real full file system, where the other disk tests fake one (CLV_FAULT_DISK_FULL_AFTER):
/// a 1 MB tmpfs. Each stage is told beforehand how little space there is, stops with the
/// way on when the disk fills, and continues, once the file system is larger, to the
/// uninterrupted run's numbers and frames.
#[test]
fn a_real_full_file_system_stops_each_stage_and_resume_recovers() {
    let mnt = scratch("faults", "tmpfs").join("mnt");
    std::fs::create_dir_all(&mnt).unwrap();
    let Some(tmpfs) = Tmpfs::mount(&mnt, "1m") else { return };
    let (reference_dir, want) = reference("tmpfs-ref");
    let want_frames = reference_dir.parent().unwrap().join("frames.mcap");
    ok(clv(&["backward", reference_dir.to_str().unwrap(), "--quiet", "--out", want_frames.to_str().unwrap()]));

    let dir = mnt.join("run");
    let d = dir.to_str().unwrap();
    let args = forward_args(&dir);
    let out = clv(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let err = stderr(&out);
    assert!(err.contains("warning: this needs about") && err.contains("MB free"), "{err}");
    assert!(out.status.code() == Some(1) && err.contains("disk full") && err.contains(&format!("clv forward --resume {d}")) && !err.contains("panicked"), "{err}");
    for seg in (clv::store::RunDir { path: dir.clone() }).segments().unwrap() {
        clv::store::segment::read_segment(&seg.path, clv::store::segment::ReadMode::Strict, |_| Ok(())).unwrap();
    }
    tmpfs.resize("16m");
    ok(clv(&["forward", "--resume", d, "--quiet"]));
    assert!(contents(&dir) == want, "the run resumed after a full file system differs");

    // The frame file does not fit in what is left of 16 MB.
    let frames_file = mnt.join("frames.mcap");
    let out = clv(&["backward", d, "--quiet", "--out", frames_file.to_str().unwrap()]);
    let err = stderr(&out);
    assert!(out.status.code() == Some(1) && err.contains("disk full") && err.contains(&format!("clv backward {d} --resume")) && !err.contains("panicked"), "{err}");
    tmpfs.resize("64m");
    ok(clv(&["backward", d, "--quiet", "--out", frames_file.to_str().unwrap(), "--resume"]));
    assert!(frames(&frames_file) == frames(&want_frames), "the sweep resumed after a full file system differs");

    // The report, with 200 kB left: an incomplete report that says so (index.html), written
    // whole with --overwrite once there is space.
    let df = ok(Command::new("df").args(["-k", "--output=used"]).arg(&mnt).output().unwrap());
    let used_kb: u64 = String::from_utf8_lossy(&df.stdout).lines().nth(1).unwrap().trim().parse().unwrap();
    tmpfs.resize(&format!("{}k", used_kb + 200));
    let report = mnt.join("report");
    let out = clv(&["analyze", frames_file.to_str().unwrap(), "--out", report.to_str().unwrap(), "--quiet"]);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("disk full") && err.contains("again with --overwrite") && err.matches("clv: error").count() == 1 && !err.contains("panicked"), "{err}");
    assert!(!report.join("summary.json").exists());
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    // (The page naming the failed analyses, or where even that did not fit, the placeholder
    // written first, which names a full disk among what may have stopped it.)
    assert!(index.contains("<title>clv analyses: incomplete"), "{index:.300}");
    tmpfs.resize("128m");
    ok(clv(&["analyze", frames_file.to_str().unwrap(), "--out", report.to_str().unwrap(), "--overwrite", "--quiet"]));
    assert!(report.join("summary.json").exists());

    // A sweep whose segments go to a scratch file (past --memory) on a full file system: an
    // error that says so, not SIGBUS (the scratch file was sparse, and writing through its
    // mapping found no block).
    let df = ok(Command::new("df").args(["-k", "--output=used"]).arg(&mnt).output().unwrap());
    let used_kb: u64 = String::from_utf8_lossy(&df.stdout).lines().nth(1).unwrap().trim().parse().unwrap();
    tmpfs.resize(&format!("{}k", used_kb + 100));
    let out = clv(&["backward", d, "--quiet", "--memory", "0"]);
    let err = stderr(&out);
    assert!(out.status.code() == Some(1) && err.contains("disk full") && err.contains(".scratch-") && !err.contains("panicked"), "{:?}: {err}", out.status);
    tmpfs.resize("256m");
    ok(clv(&["backward", d, "--quiet", "--memory", "0", "--resume"]));
}

#[test]
fn disk_full_stops_with_a_clear_error_and_resume_recovers() {
    let (_, want) = reference("full-ref");
    // A disk too small for the run is pointed out before it starts.
    let dir = scratch("faults", "full-warned").join("run");
    let args = forward_args(&dir);
    let out = clv_env(&args.iter().map(String::as_str).collect::<Vec<_>>(), &[("CLV_FAULT_DISK_FREE", "100000")]);
    let err = stderr(&ok(out));
    assert!(err.contains("warning") && err.contains("100 kB free"), "{err}");
    assert!(contents(&dir) == want);
    for limit in ["20000", "400000", "900000"] {
        let dir = scratch("faults", &format!("full-{limit}")).join("run");
        let args = forward_args(&dir);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = clv_env(&args, &[("CLV_FAULT_DISK_FULL_AFTER", limit)]);
        let err = stderr(&out);
        assert!(!out.status.success(), "limit {limit}: should fail");
        assert!(err.contains("disk full") && err.contains(&format!("clv forward --resume {}", dir.display())) && !err.contains("RUN_DIR"), "{err}");
        assert!(!err.contains("panicked"));
        // Every finished segment is intact.
        for seg in (clv::store::RunDir { path: dir.clone() }).segments().unwrap() {
            clv::store::segment::read_segment(&seg.path, clv::store::segment::ReadMode::Strict, |_| Ok(())).unwrap();
        }
        ok(clv(&["forward", "--resume", dir.to_str().unwrap(), "--quiet"]));
        assert!(contents(&dir) == want, "limit {limit}: resumed run differs");
    }
    // A disk that fills early in a segment of a larger system fails a write under a message
    // header, which the MCAP writer hands on wrapped with its OS error lost (found on a 6 MB
    // tmpfs at these sizes): still a full disk, with the way to continue.
    for limit in ["5760000", "5840000"] {
        let dir = scratch("faults", &format!("full-n40-{limit}")).join("run");
        let args = ["forward", "--quiet", "--n", "40", "--aspect", "2/11", "--relax-steps", "200", "--steps", "6000", "--clv-steps", "300", "--out", dir.to_str().unwrap()];
        let out = clv_env(&args, &[("CLV_FAULT_DISK_FULL_AFTER", limit)]);
        let err = stderr(&out);
        assert!(out.status.code() == Some(1) && err.contains("disk full") && err.contains(&format!("clv forward --resume {}", dir.display())), "limit {limit}: {err}");
    }
    // A file-size limit (`ulimit -f` of 100 kB, below a segment's 200 kB) is met the same way,
    // not by SIGXFSZ killing the process without a word.
    let dir = scratch("faults", "file-size-limit").join("run");
    let args = forward_args(&dir).join(" ");
    let out = Command::new("bash").args(["-c", &format!("ulimit -f 100 && exec {} {args}", env!("CARGO_BIN_EXE_clv"))]).output().unwrap();
    let err = stderr(&out);
    assert!(out.status.code() == Some(1) && err.contains("file-size limit reached") && err.contains(&format!("clv forward --resume {}", dir.display())), "{:?}: {err}", out.status);
    ok(clv(&["forward", "--resume", dir.to_str().unwrap(), "--quiet"]));
    assert!(contents(&dir) == want, "resumed after the file-size limit, the run differs");
    // Analyses that fail on it leave a report that says so (no summary.json, the failed
    // analyses named in its page), which the same command with --overwrite writes whole.
    ok(clv(&["backward", dir.to_str().unwrap(), "--quiet"]));
    let report = dir.parent().unwrap().join("limited-report");
    let analyze = format!("{} analyze {} --out {} --quiet", env!("CARGO_BIN_EXE_clv"), dir.display(), report.display());
    let out = Command::new("bash").args(["-c", &format!("ulimit -f 20 && exec {analyze}")]).output().unwrap();
    let err = stderr(&out);
    // One error, that of the limit, with the way to continue (not one per analysis, each
    // saying to give the command again, which is refused without --overwrite).
    assert!(!out.status.success() && err.contains("file-size limit reached") && err.contains("again with --overwrite") && err.matches("clv: error").count() == 1, "{err}");
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(index.contains("<title>clv analyses: incomplete") && index.contains("Incomplete report.") && !report.join("summary.json").exists(), "{index:.300}");
    ok(clv(&["analyze", dir.to_str().unwrap(), "--out", report.to_str().unwrap(), "--overwrite", "--quiet"]));
    assert!(report.join("summary.json").exists());
    // The backward stage on a full disk: same promise.
    let (dir, _) = reference("full-bwd");
    let d = dir.to_str().unwrap();
    let full = dir.join("full.mcap");
    ok(clv(&["backward", d, "--quiet", "--out", full.to_str().unwrap()]));
    let part = dir.join("part.mcap");
    let out = clv_env(&["backward", d, "--quiet", "--out", part.to_str().unwrap()], &[("CLV_FAULT_DISK_FULL_AFTER", "2000000")]);
    assert!(!out.status.success() && stderr(&out).contains("disk full") && stderr(&out).contains(&format!("clv backward {d} --resume")), "{}", stderr(&out));
    ok(clv(&["backward", d, "--quiet", "--out", part.to_str().unwrap(), "--resume"]));
    assert!(frames(&part) == frames(&full));
    // Into a stream, a full disk mid-sweep (its progress record) leaves the stream cut short:
    // its reader must not take the frames sent so far for a whole stream.
    let report = dir.join("cut-report");
    let mut sweep = Command::new(env!("CARGO_BIN_EXE_clv"))
        .args(["backward", d, "--quiet", "--out", "-"])
        .env("CLV_FAULT_DISK_FULL_AFTER", "300000")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let analysis = Command::new(env!("CARGO_BIN_EXE_clv")).args(["analyze", "-", "--out", report.to_str().unwrap(), "--quiet"]).stdin(sweep.stdout.take().unwrap()).output().unwrap();
    let sweep = sweep.wait_with_output().unwrap();
    assert!(!sweep.status.success() && stderr(&sweep).contains("disk full"), "{}", stderr(&sweep));
    assert!(!analysis.status.success() && !report.join("summary.json").exists(), "a cut stream was analysed as whole: {}", stderr(&analysis));
    assert!(stderr(&analysis).contains("ends early"), "{}", stderr(&analysis));
    // A new sweep stopped by a full disk before its first segment, after a finished sweep
    // with other options: --resume continues the new one, not the finished one.
    ok(clv(&["backward", d, "--quiet", "--save-every", "0"]));
    let out = clv_env(&["backward", d, "--quiet", "--with-gs"], &[("CLV_FAULT_DISK_FULL_AFTER", "100000")]);
    assert!(!out.status.success() && stderr(&out).contains("disk full"), "{}", stderr(&out));
    ok(clv(&["backward", d, "--quiet", "--resume"]));
    let with_gs = dir.join("with-gs.mcap");
    ok(clv(&["backward", d, "--quiet", "--with-gs", "--out", with_gs.to_str().unwrap()]));
    assert!(frames(&dir.join("frames.mcap")) == frames(&with_gs), "the resumed sweep is not the one the disk stopped");
    // Flags that disagree with an interrupted sweep are named as flags.
    let out = clv_env(&["backward", d, "--quiet", "--with-gs"], &[("CLV_FAULT_DISK_FULL_AFTER", "100000")]);
    assert!(!out.status.success());
    let out = clv(&["backward", d, "--quiet", "--resume", "--transient", "7"]);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("--with-gs") && err.contains("--transient 7") && !err.contains("BackwardOptions"), "{err}");
}

/// `clv args` (a forward run into `run`) sent `signal` once its first segment is written:
/// its output and the step it says it stopped after (0 if it says none).
/// The child gets the signal's default disposition: under `nohup` (as the suite may run)
/// SIGHUP is inherited ignored, and clv rightly keeps it so.
fn stopped_after_a_segment<S: AsRef<std::ffi::OsStr>>(args: &[S], run: &Path, signal: libc::c_int) -> (std::process::Output, u64) {
    use std::os::unix::process::CommandExt;
    let mut command = Command::new(env!("CARGO_BIN_EXE_clv"));
    command.args(args).stdout(Stdio::null()).stderr(Stdio::piped());
    // SAFETY: signal(2) is async-signal-safe, as a pre_exec closure must be.
    unsafe {
        command.pre_exec(move || {
            libc::signal(signal, libc::SIG_DFL);
            Ok(())
        })
    };
    let child = command.spawn().unwrap();
    let started = std::time::Instant::now();
    while (clv::store::RunDir { path: run.to_path_buf() }).segments().map_or(true, |s| s.is_empty()) && started.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(10));
    }
    // SAFETY: a plain kill(2) of the child we spawned.
    unsafe { libc::kill(child.id() as libc::pid_t, signal) };
    let out = child.wait_with_output().unwrap();
    let step = stderr(&out).split("after step ").nth(1).and_then(|t| t.split(' ').next()).and_then(|n| n.parse().ok()).unwrap_or(0);
    (out, step)
}

/// A dropped ssh session sends SIGHUP to a job started without nohup: the forward stage stops
/// at a checkpoint of its own as for SIGTERM, and exits as by the signal (129).
#[test]
fn sighup_stops_the_forward_stage_at_a_checkpoint_too() {
    let run = scratch("faults", "hup").join("run");
    let args = ["forward", "--quiet", "--n", "16", "--aspect", "1", "--relax-steps", "30000", "--steps", "10000", "--checkpoint-every", "50", "--out", run.to_str().unwrap()];
    let (out, step) = stopped_after_a_segment(&args, &run, libc::SIGHUP);
    let err = stderr(&out);
    assert!(out.status.code() == Some(128 + libc::SIGHUP) && err.contains("stopped by a signal after step"), "{:?}: {err}", out.status);
    let dir = clv::store::RunDir { path: run.clone() };
    assert!(dir.partial_segments().unwrap().is_empty() && dir.segments().unwrap().last().unwrap().last == step, "the last segment ends at the stop");
    // Stopped while relaxing: inspect shows no spectrum of zeros.
    let shown = String::from_utf8_lossy(&clv(&["inspect", run.to_str().unwrap()]).stdout).into_owned();
    assert!(step < 30000 && shown.contains(&format!("relaxing: step {step} of the 30000 relaxation steps")) && !shown.contains("spectrum so far"), "{shown}");
}

/// Batch systems warn a job before its time limit with SIGUSR1 or SIGUSR2 when asked
/// (SLURM's `--signal=USR1@120`), whose default is to kill: the forward stage stops at a
/// checkpoint of its own instead, exits as by the signal, and `--resume` finishes the run to
/// the bits of one never stopped; the backward stage works on until the SIGTERM after them.
#[test]
fn batch_warning_signals_stop_at_a_checkpoint_as_sigterm_does() {
    let args = |dir: &Path| -> Vec<String> {
        ["forward", "--quiet", "--n", "16", "--aspect", "1", "--steps", "20000", "--checkpoint-every", "50", "--clv-steps", "200", "--out", dir.to_str().unwrap()].iter().map(|s| s.to_string()).collect()
    };
    let want = scratch("faults", "usr-ref").join("run");
    ok(clv(&args(&want).iter().map(String::as_str).collect::<Vec<_>>()));
    for (name, signal) in [("usr1", libc::SIGUSR1), ("usr2", libc::SIGUSR2)] {
        let run = scratch("faults", name).join("run");
        let (out, step) = stopped_after_a_segment(&args(&run), &run, signal);
        let err = stderr(&out);
        assert!(out.status.code() == Some(128 + signal) && err.contains("stopped by a signal after step") && err.contains("--resume"), "{name}: {:?}: {err}", out.status);
        let dir = clv::store::RunDir { path: run.clone() };
        assert!(step > 0 && dir.partial_segments().unwrap().is_empty() && dir.segments().unwrap().last().unwrap().last == step, "{name}: the last segment ends at the stop");
        ok(clv(&["forward", "--resume", run.to_str().unwrap(), "--quiet"]));
        assert_eq!(contents(&run).exponents, contents(&want).exponents, "{name}");
    }
    // The backward stage (streaming into a pipe nobody reads, so mid-sweep) keeps working
    // through the warnings, whose end would only lose the work until the SIGTERM after them.
    let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", want.to_str().unwrap(), "--quiet", "--out", "-"]).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let started = std::time::Instant::now();
    while !want.join("backward.json").exists() && started.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(2));
    }
    for signal in [libc::SIGUSR1, libc::SIGUSR2, libc::SIGXCPU] {
        // SAFETY: a plain kill(2) of the child we spawned.
        unsafe { libc::kill(child.id() as libc::pid_t, signal) };
    }
    std::thread::sleep(Duration::from_millis(300));
    assert!(child.try_wait().unwrap().is_none(), "a warning ended the backward stage");
    // SAFETY: as above.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(child.wait().unwrap().code(), Some(128 + libc::SIGTERM), "{err}");
    assert!(err.contains("clv backward: stopped by a signal"), "{err}");
}

/// A soft CPU-time limit (`ulimit -S -t`, the warning of SGE, PBS and LSF before their hard
/// one) sends SIGXCPU, whose default kills without a checkpoint: the forward stage stops at
/// a checkpoint of its own instead, from which `--resume` continues.
#[test]
fn a_soft_cpu_time_limit_stops_the_forward_stage_at_a_checkpoint() {
    use std::os::unix::process::CommandExt;
    let run = scratch("faults", "xcpu").join("run");
    let r = run.to_str().unwrap();
    let mut command = Command::new(env!("CARGO_BIN_EXE_clv"));
    command.args(["forward", "--quiet", "--n", "16", "--aspect", "1", "--relax-steps", "0", "--steps", "200000", "--checkpoint-every", "50", "--out", r]).stdout(Stdio::null()).stderr(Stdio::piped());
    // SAFETY: setrlimit(2) and signal(2) are async-signal-safe, as a pre_exec closure must be.
    unsafe {
        command.pre_exec(|| {
            let limit = libc::rlimit { rlim_cur: 1, rlim_max: 60 };
            libc::setrlimit(libc::RLIMIT_CPU, &limit);
            libc::signal(libc::SIGXCPU, libc::SIG_DFL);
            Ok(())
        })
    };
    let out = command.output().unwrap();
    let err = stderr(&out);
    assert!(out.status.code() == Some(128 + libc::SIGXCPU) && err.contains("stopped by a signal after step") && err.contains("--resume"), "{:?}: {err}", out.status);
    let step: u64 = err.split("after step ").nth(1).and_then(|t| t.split(' ').next()).and_then(|n| n.parse().ok()).unwrap();
    let dir = clv::store::RunDir { path: run.clone() };
    assert!(step > 0 && step < 200000 && dir.partial_segments().unwrap().is_empty() && dir.segments().unwrap().last().unwrap().last == step, "the last segment ends at the stop");
    let shown = String::from_utf8_lossy(&ok(clv(&["inspect", r])).stdout).into_owned();
    assert!(shown.contains(&format!("steps: {step} of 200000 (not finished: clv forward --resume)")) && shown.contains("all finished files intact"), "{shown}");
}

/// Stopped by SIGTERM inside the window of a --store-r all run, the forward stage writes its
/// own checkpoint at the stop, with one R_n there, not a second (an outside reader of the
/// stored R_n saw that step twice; an outside check).
#[test]
fn a_stop_inside_a_store_r_all_window_stores_each_r_once() {
    let run = scratch("faults", "term-r-all").join("run");
    let args = ["forward", "--quiet", "--n", "16", "--aspect", "1", "--relax-steps", "10", "--steps", "40000", "--clv-steps", "30000", "--transient", "10000", "--checkpoint-every", "50", "--store-r", "all", "--out", run.to_str().unwrap()];
    // A stop that lands on a checkpoint of the grid (one in 50) writes none of its own: again.
    let mut attempt = 0;
    let (out, step) = loop {
        let _ = std::fs::remove_dir_all(&run);
        let (out, step) = stopped_after_a_segment(&args, &run, libc::SIGTERM);
        attempt += 1;
        if step % 50 != 0 || attempt == 5 {
            break (out, step);
        }
    };
    assert!(out.status.code() == Some(128 + libc::SIGTERM) && step > 10 && step % 50 != 0, "{:?} at step {step}: {}", out.status, stderr(&out));
    let last = clv::store::RunDir { path: run.clone() }.segments().unwrap().pop().unwrap();
    let mut steps = Vec::new();
    clv::store::segment::read_segment(&last.path, clv::store::segment::ReadMode::Strict, |m| {
        if m.topic == clv::store::schema::R.topic {
            steps.push(m.step);
        }
        Ok(())
    })
    .unwrap();
    let mut once = steps.clone();
    once.dedup();
    assert!(once == steps && steps.last() == Some(&step), "R_n stored twice, or not at the stop ({step}): {steps:?}");
    ok(clv(&["forward", "--resume", run.to_str().unwrap(), "--quiet"]));
    // The stop's segment, damaged, is recomputed to the same files: it ends at the stop, off
    // the grid, and the next one begins right after it, so no gap shows where it was (it
    // was set aside and never recomputed, the R_n of its steps lost).
    let segments = || clv::store::RunDir { path: run.clone() }.segments().unwrap();
    let (want, names) = (contents(&run), segments().iter().map(|s| (s.first, s.last)).collect::<Vec<_>>());
    let at = segments().iter().position(|s| s.last == step).unwrap();
    let stopped = segments()[at].clone();
    let mut bytes = std::fs::read(&stopped.path).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x10;
    std::fs::write(&stopped.path, bytes).unwrap();
    let err = stderr(&ok(clv(&["forward", "--resume", run.to_str().unwrap()])));
    assert!(err.contains(&format!("recomputing steps {}..{}", names[at - 1].1, (step / 50 + 1) * 50)), "{err}");
    assert!(contents(&run) == want && segments().iter().map(|s| (s.first, s.last)).collect::<Vec<_>>() == names, "{err}");
    // Deleted, it is a gap of R_n (every step's is stored there) that inspect names and
    // resume fills (nothing noticed it: no checkpoint of the grid is missing).
    std::fs::remove_file(&segments()[at].path).unwrap();
    let seen = clv(&["inspect", run.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&seen.stdout).into_owned();
    assert!(!seen.status.success() && text.contains(&format!("the checkpoints and R_n of steps {}..{step} are missing", names[at - 1].1 + 1)), "{text}");
    ok(clv(&["forward", "--resume", run.to_str().unwrap(), "--quiet"]));
    assert!(contents(&run) == want && segments().iter().map(|s| (s.first, s.last)).collect::<Vec<_>>() == names);
}

/// A batch system's time limit sends SIGTERM before SIGKILL: the forward stage stops after
/// the step it is in, with a checkpoint there and its segment finished, so that the run
/// resumes from that very step (no interrupted segment, nothing recomputed) to the
/// uninterrupted run's exponents and covariant vectors, bit for bit.
#[test]
fn sigterm_stops_the_forward_stage_at_a_checkpoint_of_its_own() {
    let args = |dir: &Path| -> Vec<String> {
        ["forward", "--quiet", "--n", "16", "--aspect", "1", "--steps", "40000", "--checkpoint-every", "50", "--clv-steps", "300", "--out", dir.to_str().unwrap()].iter().map(|s| s.to_string()).collect()
    };
    let (want, run) = (scratch("faults", "term-ref").join("run"), scratch("faults", "term").join("run"));
    ok(clv(&args(&want).iter().map(String::as_str).collect::<Vec<_>>()));
    let (out, step) = stopped_after_a_segment(&args(&run), &run, libc::SIGTERM);
    let err = stderr(&out);
    assert!(out.status.code() == Some(128 + libc::SIGTERM) && err.contains("stopped by a signal after step") && err.contains("--resume"), "{:?}: {err}", out.status);
    let dir = clv::store::RunDir { path: run.clone() };
    assert!(dir.partial_segments().unwrap().is_empty(), "an interrupted segment was left");
    assert_eq!(dir.segments().unwrap().last().unwrap().last, step, "the last segment ends at the stop");
    let resumed = ok(clv(&["forward", "--resume", run.to_str().unwrap()]));
    assert!(stderr(&resumed).contains(&format!("resuming {} at step {step} of", run.display())), "{}", stderr(&resumed));
    assert_eq!(contents(&run).exponents, contents(&want).exponents);
    for d in [&want, &run] {
        ok(clv(&["backward", d.to_str().unwrap(), "--quiet"]));
    }
    assert!(frames(&run.join("frames.mcap")) == frames(&want.join("frames.mcap")));

    // After the forward loop, `clv run`'s backward stage ends at once on SIGTERM (a stop
    // there would have nothing to save), as death by the signal, saying how to continue.
    use std::io::{BufRead, Read};
    let out = scratch("faults", "term-run");
    let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(["run", "--out", out.to_str().unwrap(), "--steps", "4000"]).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let mut lines = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while lines.read_line(&mut line).unwrap() > 0 && !line.contains("backward pass and analyses") {
        line.clear();
    }
    // SAFETY: a plain kill(2) of the child we spawned.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let mut rest = String::new();
    lines.read_to_string(&mut rest).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(128 + libc::SIGTERM), "{status:?}");
    assert!(rest.contains("clv run: stopped by a signal") && rest.contains("give the same `clv run` command again"), "{rest}");
    let again = ok(clv(&["run", "--out", out.to_str().unwrap(), "--steps", "4000", "--quiet"]));
    assert!(out.join("report/index.html").is_file(), "{}", stderr(&again));

    // `clv backward` likewise: into a pipe nobody reads it stops mid-sweep for certain.
    let term_backward = |dir: &Path, out: &str, stdout: Stdio| {
        std::fs::remove_file(dir.join("backward.json")).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(["backward", dir.to_str().unwrap(), "--quiet", "--out", out]).stdout(stdout).stderr(Stdio::piped()).spawn().unwrap();
        let started = std::time::Instant::now();
        while !dir.join("backward.json").exists() && started.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(2));
        }
        // SAFETY: a plain kill(2) of the child we spawned.
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
        let mut err = String::new();
        child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
        (child.wait().unwrap().code(), err)
    };
    let (code, err) = term_backward(&want, "-", Stdio::piped());
    assert_eq!(code, Some(128 + libc::SIGTERM), "{err}");
    assert!(err.contains("clv backward: stopped by a signal; the frames streamed so far went to the reader"), "{err}");
    // inspect continues a stream into its reader, not into a batch job's log.
    let shown = String::from_utf8_lossy(&clv(&["inspect", want.to_str().unwrap()]).stdout).into_owned();
    assert!(shown.contains("(frames to a stream)") && shown.contains("--out - --save-every") && shown.contains("| clv analyze - --out REPORT` streams the whole window again") && shown.contains("with --resume it streams only the frames after"), "{shown}");
    // Into a file: the message, if the signal lands before the end, and --resume then
    // finishes the sweep to the same frames.
    let o = run.join("term.mcap");
    let (code, err) = term_backward(&run, o.to_str().unwrap(), Stdio::null());
    assert!(code != Some(128 + libc::SIGTERM) || err.contains("clv backward: stopped by a signal; its progress") && err.contains("--resume"), "{err}");
    ok(clv(&["backward", run.to_str().unwrap(), "--quiet", "--out", o.to_str().unwrap(), "--resume"]));
    assert!(frames(&o) == frames(&want.join("frames.mcap")));
    // In its forward pass, `clv run` stops as `clv forward` does, and says to run it again.
    let out = scratch("faults", "term-run-forward");
    let child = Command::new(env!("CARGO_BIN_EXE_clv")).args(["run", "--out", out.to_str().unwrap(), "--quiet", "--steps", "100000"]).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let started = std::time::Instant::now();
    while (clv::store::RunDir { path: out.join("run") }).segments().map_or(true, |s| s.is_empty()) && started.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(10));
    }
    // SAFETY: a plain kill(2) of the child we spawned.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let done = child.wait_with_output().unwrap();
    let err = stderr(&done);
    assert!(done.status.code() == Some(128 + libc::SIGTERM) && err.contains("of the forward pass") && err.contains("give the same `clv run` command again"), "{:?}: {err}", done.status);
}

#[test]
fn a_second_writer_is_refused_and_a_killed_one_leaves_no_stale_lock() {
    let dir = scratch("faults", "lock").join("run");
    let d = dir.to_str().unwrap().to_string();
    let mut first = Command::new(env!("CARGO_BIN_EXE_clv"))
        .args(["forward", "--quiet", "--n", "40", "--steps", "100000", "--out", &d])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    while !dir.join("run.json").exists() {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(200));
    let second = clv(&["forward", "--resume", &d, "--quiet"]);
    let err = stderr(&second);
    assert!(!second.status.success() && err.contains("another clv process"), "{err}");
    let third = clv(&["backward", &d, "--quiet"]);
    assert!(!third.status.success());
    // clv inspect says the run is being written, not that it was interrupted.
    let seen = String::from_utf8_lossy(&clv(&["inspect", &d]).stdout).into_owned();
    assert!(seen.contains("a clv process is writing it now") && !seen.contains("interrupted"), "{seen}");
    first.kill().unwrap();
    first.wait().unwrap();
    let seen = String::from_utf8_lossy(&clv(&["inspect", &d]).stdout).into_owned();
    assert!(seen.contains("not finished: clv forward --resume"), "{seen}");
    // The lock died with the process: resuming works (stopped early to keep the test short).
    let mut resumed = Command::new(env!("CARGO_BIN_EXE_clv")).args(["forward", "--resume", &d, "--quiet"]).stderr(Stdio::piped()).spawn().unwrap();
    std::thread::sleep(Duration::from_millis(700));
    let still_running = resumed.try_wait().unwrap().is_none();
    resumed.kill().ok();
    let out = resumed.wait_with_output().unwrap();
    assert!(still_running, "resume after a killed writer failed: {}", String::from_utf8_lossy(&out.stderr));
}

/// Start two clv processes at once (both spawned before either is waited for), and wait
/// for both.
fn at_once(a: &[String], b: &[String]) -> [std::process::Output; 2] {
    let start = |args: &[String]| Command::new(env!("CARGO_BIN_EXE_clv")).args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let (first, second) = (start(a), start(b));
    [first.wait_with_output().unwrap(), second.wait_with_output().unwrap()]
}

/// Of two writers of `thing` started at once, exactly one succeeded and the other was
/// refused as a second writer, naming it; the index of the one that succeeded.
fn one_refused(outs: &[std::process::Output; 2], thing: &Path) -> usize {
    let succeeded: Vec<usize> = (0..2).filter(|&i| outs[i].status.success()).collect();
    assert!(succeeded.len() == 1, "{} of two writers of {} succeeded: {:?} / {:?}", succeeded.len(), thing.display(), stderr(&outs[0]), stderr(&outs[1]));
    let err = stderr(&outs[1 - succeeded[0]]);
    let name = thing.file_name().unwrap().to_string_lossy();
    assert!(err.contains("another clv process is writing") && err.contains(&*name) && err.contains("wait for it to finish") && !err.contains("panicked"), "{err}");
    succeeded[0]
}

/// `clv forward` of a tiny run with `seed` into `out` (the races below need runs, quickly).
fn tiny_forward(seed: u64, out: &Path) -> Vec<String> {
    ["forward", "--quiet", "--n", "8", "--steps", "600", "--relax-steps", "50", "--seed", &seed.to_string(), "--out", out.to_str().unwrap()].map(String::from).to_vec()
}

fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}

/// Two tiny runs of different seeds (1, 2) in `base/run-1`, `base/run-2`.
fn two_runs(base: &Path) -> [std::path::PathBuf; 2] {
    [1, 2].map(|seed| {
        let dir = base.join(format!("run-{seed}"));
        ok(clv(&strs(&tiny_forward(seed, &dir))));
        dir
    })
}

/// Two `clv forward` passes of different runs started at once into one new directory: one
/// is refused as a second writer before it writes anything (run.json included), and the
/// directory holds the other's run whole, as if it had run alone.
#[test]
fn two_forward_passes_into_one_directory_at_once_leave_one_run() {
    let base = scratch("faults", "race-forward");
    let alone = [1, 2].map(|seed| {
        let dir = base.join(format!("alone-{seed}"));
        ok(clv(&strs(&tiny_forward(seed, &dir))));
        contents(&dir)
    });
    for trial in 0..4 {
        let dir = base.join(format!("race-{trial}"));
        let outs = at_once(&tiny_forward(1, &dir), &tiny_forward(2, &dir));
        let won = one_refused(&outs, &dir);
        let (_, meta) = clv::store::RunDir::open(&dir).unwrap();
        assert_eq!(meta.config.seed, won as u64 + 1, "trial {trial}: run.json is not the run of the process that succeeded");
        assert!(contents(&dir) == alone[won], "trial {trial}: the run differs from one written alone");
        let seen = String::from_utf8_lossy(&ok(clv(&["inspect", dir.to_str().unwrap()])).stdout).into_owned();
        assert!(seen.contains("all finished files intact"), "{seen}");
    }
}

/// Two backward sweeps of different runs started at once with the same --out: one is
/// refused as a second writer before it writes anything (its progress record included), and
/// the file holds the other's frames, intact, as if it had run alone; no FILE.tmp or lock
/// file is left.
#[test]
fn two_sweeps_into_one_frame_file_at_once_leave_one_sweeps_frames() {
    let base = scratch("faults", "race-backward");
    let runs = two_runs(&base);
    let sweep = |run: &Path, out: &Path| ["backward", run.to_str().unwrap(), "--quiet", "--out", out.to_str().unwrap()].map(String::from).to_vec();
    let alone = [0, 1].map(|i| {
        let out = base.join(format!("alone-{i}.mcap"));
        ok(clv(&strs(&sweep(&runs[i], &out))));
        std::fs::remove_file(runs[i].join("backward.json")).unwrap();
        frames(&out)
    });
    for trial in 0..4 {
        let shared = base.join(format!("shared-{trial}.mcap"));
        let outs = at_once(&sweep(&runs[0], &shared), &sweep(&runs[1], &shared));
        let won = one_refused(&outs, &shared);
        assert!(frames(&shared) == alone[won], "trial {trial}: the frames differ from those of the sweep alone");
        let seen = String::from_utf8_lossy(&ok(clv(&["inspect", shared.to_str().unwrap()])).stdout).into_owned();
        assert!(seen.contains("intact") && !seen.contains("DAMAGED"), "{seen}");
        assert!(!clv::store::frames::tmp_path(&shared).exists() && !base.join(format!("shared-{trial}.mcap.lock")).exists(), "trial {trial}: a temporary or lock file was left");
        assert!(!runs[1 - won].join("backward.json").exists(), "trial {trial}: the refused sweep left a progress record");
        std::fs::remove_file(runs[won].join("backward.json")).unwrap();
    }
}

/// Two `clv analyze` into one report directory started at once, replacing a report
/// (--overwrite) and into a new directory: one is refused as a second writer before it
/// writes or removes anything, and the report is the other's, exactly as written alone
/// (without the lock file).
#[test]
fn two_analyses_into_one_report_at_once_leave_one_report() {
    let base = scratch("faults", "race-analyze");
    let runs = two_runs(&base);
    let frame_files = [0, 1].map(|i| {
        let out = base.join(format!("f{i}.mcap"));
        ok(clv(&["backward", runs[i].to_str().unwrap(), "--quiet", "--out", out.to_str().unwrap()]));
        out
    });
    let analyze = |i: usize, out: &Path, overwrite: bool| {
        let mut a = ["analyze", frame_files[i].to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"].map(String::from).to_vec();
        a.extend(overwrite.then(|| "--overwrite".to_string()));
        a
    };
    let alone = [0, 1].map(|i| {
        let out = base.join(format!("alone-{i}"));
        ok(clv(&strs(&analyze(i, &out, false))));
        report_contents(&out, &[])
    });
    let replaced = base.join("replaced");
    std::fs::create_dir_all(&replaced).unwrap();
    for (trial, overwrite) in [true, true, false, false].into_iter().enumerate() {
        let rep = if overwrite { replaced.clone() } else { base.join(format!("new-{trial}")) };
        let outs = at_once(&analyze(0, &rep, overwrite), &analyze(1, &rep, overwrite));
        let won = one_refused(&outs, &rep);
        assert!(report_contents(&rep, &[]) == alone[won], "trial {trial}: the report is not the one written alone: {:?}", report_contents(&rep, &[]).keys());
    }
}

/// A new sweep must not strand the frames of an interrupted one: while RUN/backward.json
/// records an interrupted sweep into a file whose FILE.tmp exists, a sweep with other options
/// (a stream, or another file) is refused, naming the file and how to finish it; finished,
/// the file has the uninterrupted sweep's frames, and the stream runs.
#[test]
fn a_new_sweep_does_not_strand_an_interrupted_one() {
    let (dir, _) = reference("strand");
    let d = dir.to_str().unwrap();
    let whole = dir.join("whole.mcap");
    ok(clv(&["backward", d, "--quiet", "--out", whole.to_str().unwrap()]));
    let part = dir.join("part.mcap");
    let p = part.to_str().unwrap();
    assert!(crashed(&clv_env(&["backward", d, "--quiet", "--out", p], &[("CLV_FAULT_CRASH_AT", "frames-synced#8")]), "frames-synced#8"));
    for other in [vec!["backward", d, "--out", "-"], vec!["backward", d, "--out", dir.join("other.mcap").to_str().unwrap()]] {
        let out = clv(&other);
        let err = stderr(&out);
        assert!(!out.status.success(), "{other:?}: {err}");
        assert!(err.contains("interrupted backward sweep into") && err.contains(p) && err.contains("--resume"), "{err}");
    }
    ok(clv(&["backward", d, "--quiet", "--out", p, "--resume"]));
    assert!(frames(&part) == frames(&whole));
    ok(clv(&["backward", d, "--quiet", "--out", "-"]));
    // The refusal counts the frames the interrupted file keeps, not those the sweep formed.
    let tenth = dir.join("tenth.mcap");
    assert!(crashed(&clv_env(&["backward", d, "--quiet", "--save-every", "10", "--out", tenth.to_str().unwrap()], &[("CLV_FAULT_CRASH_AT", "frames-synced#8")]), "frames-synced#8"));
    let err = stderr(&clv(&["backward", d, "--out", "-"]));
    let mut kept = 0;
    clv::store::frames::read_frames(&dir.join("tenth.mcap.tmp"), |_| {
        kept += 1;
        Ok(clv::store::frames::Flow::Continue)
    })
    .unwrap();
    // The record's count (the file may hold a few frames more, synced after it): the frames
    // formed, and of them those on the stride of 10.
    let (before, after) = err.split_once(" frames, ").expect("a count of frames");
    let formed: u64 = before.rsplit(' ').next().unwrap().parse().unwrap();
    let said: usize = after.split(' ').next().unwrap().parse().unwrap();
    assert!(after.contains("of them kept in") && said > 0 && said <= kept && said as u64 <= formed.div_ceil(10) && said as u64 >= formed / 10, "{kept} frames in the file: {err}");
}

/// On a file system without locks (Lustre without flock, NFS without a lock manager) a run
/// is still possible: the stages warn that they cannot refuse a second writer, and work.
#[test]
fn a_file_system_without_locks_gets_a_warning_not_a_refusal() {
    let dir = scratch("faults", "no-locks").join("run");
    let d = dir.to_str().unwrap();
    let no_locks = [("CLV_FAULT_NO_LOCKS", "1")];
    let frames = dir.with_file_name("frames.mcap");
    let f = frames.to_str().unwrap();
    for args in [&["forward", "--n", "8", "--steps", "300", "--clv-steps", "100", "--transient", "50", "--out", d][..], &["backward", d, "--out", "-"][..], &["backward", d, "--out", f][..]] {
        let out = common::clv_env(&[args, &["--quiet"][..]].concat(), &no_locks);
        let err = stderr(&out);
        assert!(out.status.success(), "{err}");
        assert!(err.contains("cannot lock files") && err.contains("make sure only one runs"), "{err}");
    }
}

#[test]
fn numerical_faults_stop_the_run_naming_the_step() {
    // NaN in the tangent vectors of a checkpoint the run resumes from.
    let (dir, _) = reference("nan");
    let run = dir.to_str().unwrap();
    let last = *contents(&dir).checkpoints.keys().last().unwrap();
    std::fs::remove_file(dir.join("spectrum.json")).unwrap();
    // Resuming continues from the newest checkpoint; make the run look unfinished by
    // damaging that checkpoint's successor: simplest is to alter the newest one and drop
    // the newest segment's later content, so the altered one is what resume reads.
    let segs = clv::store::RunDir { path: dir.clone() }.segments().unwrap();
    let newest = segs.last().unwrap().clone();
    std::fs::remove_file(&newest.path).unwrap();
    let prev = segs[segs.len() - 2].last;
    alter_checkpoint(&dir, prev, |cp| cp.state.g[5] = f64::NAN);
    let out = clv(&["forward", "--resume", run, "--quiet"]);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains(&format!("step {}", prev + 1)) && err.contains("not finite"), "{err}");
    assert!(last > prev);
    // Two equal tangent vectors (the NaN above replaced): R is singular, at the second.
    alter_checkpoint(&dir, prev, |cp| {
        let d = cp.d;
        cp.state.g[5] = 0.5;
        let first: Vec<f64> = cp.state.g[..d].to_vec();
        cp.state.g[d..2 * d].copy_from_slice(&first);
    });
    let out = clv(&["forward", "--resume", run, "--quiet"]);
    assert!(!out.status.success() && stderr(&out).contains("found the first 32 tangent vectors linearly dependent"), "{}", stderr(&out));
    // A tau far too long for the flow: the error points at --tau.
    let out = clv(&["forward", "--system", "lorenz", "--tau", "100", "--steps", "5", "--quiet"]);
    assert!(!out.status.success() && stderr(&out).contains("smaller --tau"), "{}", stderr(&out));
    // So it does where the vectors overflow to infinity (hard disks, lambda_1 tau ~ 1000).
    let out = clv(&["forward", "--n", "4", "--aspect", "1", "--tau", "200", "--steps", "5", "--quiet"]);
    assert!(!out.status.success() && stderr(&out).contains("invalid --tau") && stderr(&out).contains("not finite") && stderr(&out).contains("smaller --tau"), "{}", stderr(&out));
    // With --out, the run directory is named as the one to move aside: a run with another
    // --tau is refused into it, and --resume meets the same step.
    let blown = scratch("faults", "blown").join("run");
    let out = clv(&["forward", "--n", "4", "--aspect", "1", "--tau", "200", "--steps", "5", "--quiet", "--out", blown.to_str().unwrap()]);
    assert!(!out.status.success() && stderr(&out).contains(&format!("move {} aside or delete it", blown.display())), "{}", stderr(&out));
    // Energy changed behind the run's back: the drift check stops it at the next checkpoint.
    alter_checkpoint(&dir, prev, |cp| {
        let n2 = cp.d / 2;
        cp.state.g = {
            let mut g = vec![0.0; cp.d * cp.k];
            for j in 0..cp.k {
                g[j * cp.d + j] = 1.0;
            }
            g
        };
        for x in &mut cp.state.system.phase[n2..] {
            *x *= 1.001;
        }
    });
    let out = clv(&["forward", "--resume", run, "--quiet"]);
    assert!(!out.status.success() && stderr(&out).contains("energy drifted"), "{}", stderr(&out));
    // Overlapping disks in the loaded state.
    alter_checkpoint(&dir, prev, |cp| {
        cp.state.system.phase[2] = cp.state.system.phase[0] + 0.3;
        cp.state.system.phase[3] = cp.state.system.phase[1];
    });
    let out = clv(&["forward", "--resume", run, "--quiet"]);
    assert!(!out.status.success() && stderr(&out).contains("overlap"), "{}", stderr(&out));
    assert!(!dir.join("spectrum.json").exists(), "no result may be written from a faulty state");
}

#[test]
fn bad_input_gets_one_clear_error_and_writes_nothing() {
    let base = scratch("faults", "bad");
    let out_dir = base.join("never");
    let o = out_dir.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["forward", "--n", "198", "--density", "1.3", "--out", o], "--density"),
        (vec!["forward", "--n", "40", "--aspect", "0.01", "--out", o], "--"),
        (vec!["forward", "--n", "1", "--out", o], "--n"),
        // A negative count is a value of its flag, named, not an unknown argument.
        (vec!["forward", "--n", "-5", "--out", o], "invalid value '-5' for '--n <N>'"),
        (vec!["forward", "--seed", "-1", "--out", o], "invalid value '-1' for '--seed <SEED>'"),
        (vec!["forward", "--n", "4", "--vectors", "0", "--out", o], "--vectors"),
        (vec!["forward", "--n", "4", "--vectors", "17", "--out", o], "--vectors"),
        (vec!["forward", "--n", "4", "--tau", "0", "--out", o], "--tau"),
        (vec!["forward", "--n", "4", "--tau=-1", "--out", o], "--tau"),
        (vec!["forward", "--n", "4", "--tau", "1e-308", "--out", o], "--tau: 1e-308 is so short"),
        (vec!["forward", "--n", "4", "--threads", "4294967297", "--out", o], "--threads: must be between 1 and 4096"),
        (vec!["forward", "--n", "4", "--steps", "100", "--relax-steps", "10", "--checkpoint-every", "500", "--out", o], "--checkpoint-every"),
        (vec!["forward", "--n", "4", "--steps", "100", "--clv-steps", "90", "--transient", "50", "--out", o], "--clv-steps"),
        // A sum that wraps around u64 is still too long.
        (vec!["forward", "--n", "4", "--steps", "100", "--clv-steps", "100", "--transient", "18446744073709551600", "--out", o], "--clv-steps"),
        (vec!["forward", "--n", "4", "--tau", "1e300", "--steps", "1", "--relax-steps", "0", "--out", o], "--tau"),
        (vec!["forward", "--system", "rossler", "--out", o], "rossler"),
        // More memory than any machine has: refused, not aborted by a failed allocation.
        (vec!["forward", "--n", "100000000", "--steps", "100", "--out", o], "--vectors: all D = 400000000 vectors need about"),
        (vec!["forward", "--n", "4", "--relax-steps", "18446744073709551615", "--steps", "10", "--out", o], "--steps"),
        // A box given by its sides and by density at once; sides too large for the positions.
        (vec!["forward", "--n", "8", "--lx", "5", "--ly", "5", "--density", "0.5", "--out", o], "--density"),
        (vec!["forward", "--n", "8", "--lx", "1e300", "--ly", "1e300", "--out", o], "--lx: a box side of 1e300"),
        (vec!["forward", "--n", "8", "--lx", "0.5", "--ly", "5", "--out", o], "a larger --lx"),
    ];
    for (args, needle) in cases {
        let out = clv(&args);
        let err = stderr(&out);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(err.contains(needle) && !err.contains("panicked"), "{args:?}: {err}");
        assert!(!out_dir.exists(), "{args:?}: wrote {}", out_dir.display());
    }
    // A machine with little memory (faked): the run is refused with the way out.
    let out = clv_env(&["forward", "--n", "16", "--steps", "10", "--out", o], &[("CLV_FAULT_MEMORY_AVAILABLE", "100000")]);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("100 kB available") && err.contains("--vectors k") && !out_dir.exists(), "{err}");
    ok(clv_env(&["forward", "--n", "16", "--steps", "10", "--vectors", "4", "--quiet"], &[("CLV_FAULT_MEMORY_AVAILABLE", "100000")]));
    // A frame file where a run directory is expected (clv inspect reads both), and a run
    // from another format version.
    let (dir, _) = reference("bad-ref");
    let frames_file = dir.parent().unwrap().join("f.mcap");
    ok(clv(&["backward", dir.to_str().unwrap(), "--quiet", "--out", frames_file.to_str().unwrap()]));
    let out = clv(&["backward", dir.to_str().unwrap(), "--save-every", "0", "--out", base.join("none.mcap").to_str().unwrap()]);
    assert!(!out.status.success() && stderr(&out).contains("--save-every: 0 would keep no frame"), "{}", stderr(&out));
    for cmd in [vec!["backward", frames_file.to_str().unwrap()], vec!["forward", "--resume", frames_file.to_str().unwrap()]] {
        let out = clv(&cmd);
        let err = stderr(&out);
        assert!(!out.status.success() && err.contains("is a file") && err.contains("run directory"), "{cmd:?}: {err}");
    }
    // A file where a directory is to be written, and a file that is not MCAP at all.
    let plain = base.join("plain.txt");
    std::fs::write(&plain, b"not a run\n").unwrap();
    let p = plain.to_str().unwrap();
    for (cmd, needle) in [
        (vec!["forward", "--n", "4", "--steps", "100", "--clv-steps", "20", "--out", p], "--out: "),
        (vec!["run", "--out", p], "--out: "),
        (vec!["analyze", frames_file.to_str().unwrap(), "--out", p], "--out: "),
        (vec!["inspect", p], "not MCAP at all"),
        (vec!["forward", "--n", "4", "--steps", "100", "--clv-steps", "20", "--out", "-"], "--out: - is standard output"),
        (vec!["analyze", frames_file.to_str().unwrap(), "--out", "-"], "--out: - is standard output"),
        (vec!["run", "--out", "-"], "--out: - is standard output"),
        (vec!["analyze", p, "--out", base.join("r").to_str().unwrap()], "not MCAP at all"),
    ] {
        let out = clv(&cmd);
        let err = stderr(&out);
        assert!(!out.status.success() && err.contains(needle) && !err.contains("os error"), "{cmd:?}: {err}");
        assert_eq!(std::fs::read(&plain).unwrap(), b"not a run\n");
    }
    // A run made by a build with other numerics cannot be continued bit for bit: refused.
    let original = std::fs::read_to_string(dir.join("run.json")).unwrap();
    // So is one made on a CPU without AVX2 and FMA (faer's scalar paths add in other
    // orders); `clv inspect` says so beforehand, as a note: nothing is damaged.
    let without_fma = original.replacen("\"fma\"", "\"no-fma\"", 1);
    assert_ne!(without_fma, original, "run.json lists the CPU's features");
    for (json, needle) in [(original.replace("clv-numerics/", "clv-numerics-old/"), "clv-numerics-old/"), (without_fma, "no-fma")] {
        reseal(&dir.join("run.json"), &json);
        for cmd in [vec!["forward", "--resume", dir.to_str().unwrap()], vec!["backward", dir.to_str().unwrap()]] {
            let out = clv(&cmd);
            let err = stderr(&out);
            assert!(!out.status.success() && err.contains("another build") && err.contains("bit for bit") && err.contains(needle), "{cmd:?}: {err}");
        }
        let out = clv(&["inspect", dir.to_str().unwrap()]);
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && text.contains("note: neither `clv forward --resume` nor the backward stage can run on this machine") && text.contains(needle), "{text}");
        assert!(text.contains("made by: clv ") && text.contains("(not this machine and build: see the note below)"), "{text}");
    }
    // Made with AVX-512 and continued without, or the other way round: the same bits (faer's
    // two kinds of product kernels agree; src/store/run.rs), so nothing is refused.
    let other_avx512 = if original.contains("\"avx512f\"") {
        original.replacen(",\n      \"avx512f\"", "", 1)
    } else {
        original.replacen("\"fma\"", "\"fma\",\n      \"avx512f\"", 1)
    };
    assert_ne!(other_avx512, original);
    reseal(&dir.join("run.json"), &other_avx512);
    let text = String::from_utf8_lossy(&clv(&["inspect", dir.to_str().unwrap()]).stdout).into_owned();
    assert!(!text.contains("not this machine") && !text.contains("can run on this machine"), "{text}");
    ok(clv(&["backward", dir.to_str().unwrap(), "--quiet"]));
    std::fs::write(dir.join("run.json"), &original).unwrap();
    let out = clv(&["inspect", dir.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && !text.contains("can run on this machine") && !text.contains("not this machine"), "{text}");
    assert!(text.lines().any(|l| l.starts_with("made by: clv ") && l.contains(std::env::consts::ARCH)), "{text}");
    std::fs::write(dir.join("run.json"), &original).unwrap();
    reseal(&dir.join("run.json"), &original.replace("clv-run/1", "clv-run/99"));
    let out = clv(&["forward", "--resume", dir.to_str().unwrap()]);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("run.json") && err.contains("clv-run/99"), "{err}");
    // A run.json cut short: the segments' copy is put beside it, and restores the run.
    std::fs::write(dir.join("run.json"), &original[..original.len() / 2]).unwrap();
    for cmd in [vec!["forward", "--resume", dir.to_str().unwrap()], vec!["inspect", dir.to_str().unwrap()]] {
        let out = clv(&cmd);
        let err = stderr(&out);
        assert!(!out.status.success() && err.contains("run.json.from-segments") && err.contains("move it over run.json"), "{cmd:?}: {err}");
    }
    std::fs::rename(dir.join("run.json.from-segments"), dir.join("run.json")).unwrap();
    ok(clv(&["inspect", dir.to_str().unwrap()]));
    // On a CPU of other features (of the same level), a resume first recomputes the last
    // checkpoint interval: bit for bit, it goes on, saying so; where a bit differs (here a
    // checkpoint altered with valid CRCs, as another machine's numbers would look), it
    // refuses before it writes anything.
    let d = dir.to_str().unwrap();
    reseal(&dir.join("run.json"), &other_avx512);
    let out = ok(clv(&["forward", "--resume", d]));
    assert!(stderr(&out).contains("its last checkpoint interval, recomputed here, matches bit for bit"), "{}", stderr(&out));
    // A record of an earlier build, which listed AVX2, FMA and AVX-512 only: the same
    // machine, nothing recomputed.
    let mut earlier: serde_json::Value = serde_json::from_str(&original).unwrap();
    let listed = earlier["build"]["cpu_features"].as_array().unwrap().iter().filter(|f| ["avx2", "fma", "avx512f"].contains(&f.as_str().unwrap())).cloned().collect();
    earlier["build"]["cpu_features"] = serde_json::Value::Array(listed);
    reseal(&dir.join("run.json"), &earlier.to_string());
    let out = ok(clv(&["forward", "--resume", d]));
    assert!(!stderr(&out).contains("is not the one the run was made on"), "{}", stderr(&out));
    reseal(&dir.join("run.json"), &other_avx512);
    let last = (clv::store::RunDir { path: dir.clone() }).segments().unwrap().last().unwrap().last;
    common::alter_checkpoint(&dir, last, |cp| cp.state.system.phase[0] = f64::from_bits(cp.state.system.phase[0].to_bits() ^ 1));
    let files = |d: &Path| std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name()).collect::<std::collections::BTreeSet<_>>();
    let before = files(&dir);
    let out = clv(&["forward", "--resume", d]);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("does not reproduce the run's last checkpoint interval") && err.contains("a machine like the one that made it"), "{err}");
    assert_eq!(files(&dir), before, "nothing written");
}

/// Damage anywhere in a frame file (magic, headers, chunk payload, CRCs, footer) is named
/// with the file; a stream cut mid-record is analysed up to the cut and then reported.
#[test]
fn damaged_frame_files_and_cut_streams_are_reported() {
    let (dir, _) = reference("frames-damage");
    let file = dir.parent().unwrap().join("frames.mcap");
    ok(clv(&["backward", dir.to_str().unwrap(), "--quiet", "--out", file.to_str().unwrap()]));
    let bytes = std::fs::read(&file).unwrap();
    let mut rng = Rng::new(5);
    let positions: Vec<usize> = [0, 3, 8, 20, bytes.len() / 2, bytes.len() - 30, bytes.len() - 9, bytes.len() - 1].into_iter().chain((0..16).map(|_| rng.below(bytes.len()))).collect();
    for (i, at) in positions.into_iter().enumerate() {
        let mut damaged = bytes.clone();
        if i % 3 == 2 {
            damaged.truncate(at);
        } else {
            damaged[at] ^= 1 << rng.below(8);
        }
        let path = dir.parent().unwrap().join(format!("damaged-{i}.mcap"));
        std::fs::write(&path, &damaged).unwrap();
        let report = dir.parent().unwrap().join(format!("an-{i}"));
        let out = clv(&["analyze", path.to_str().unwrap(), "--out", report.to_str().unwrap()]);
        let err = stderr(&out);
        assert!(!out.status.success(), "damage {i} at byte {at} went unnoticed");
        assert!(err.contains(&format!("damaged-{i}.mcap")) && !err.contains("panicked"), "{err}");
        // A report made of the frames before the damage says so at its head and stays
        // unfinished (no summary.json, as the exit status says); no frame of a damaged chunk
        // reaches it (chunks are checked whole before their messages are read).
        assert!(!report.join("summary.json").exists(), "damage {i} at byte {at}: a finished report");
        if let Ok(index) = std::fs::read_to_string(report.join("index.html")) {
            assert!(index.contains("<title>clv analyses: incomplete") && index.contains("The stream ends early or is damaged"), "damage {i} at byte {at}: {index:.400}");
        }
        // clv inspect finds the same damage.
        let seen = clv(&["inspect", path.to_str().unwrap()]);
        assert!(!seen.status.success() && !stderr(&seen).contains("panicked"), "inspect missed damage {i} at byte {at}");
        std::fs::remove_file(&path).unwrap();
    }
    // ... and summarises the intact file.
    let seen = ok(clv(&["inspect", file.to_str().unwrap(), "--json"]));
    let v: serde_json::Value = serde_json::from_slice(&seen.stdout).unwrap();
    let want = frames(&file);
    assert_eq!(v["frames"].as_u64(), Some(want.len() as u64));
    assert_eq!(v["with_vectors"], v["frames"]);
    assert!(v["damage"].is_null() && v["backward"]["vectors_every"] == 1, "{v}");
    // A stream that ends mid-record on stdin.
    let cut = &bytes[..bytes.len() * 2 / 3];
    // The same cut as the FILE.tmp of a sweep still writing it: called unfinished, not damaged.
    let tmp = dir.parent().unwrap().join("cut.mcap.tmp");
    std::fs::write(&tmp, cut).unwrap();
    let seen = clv(&["inspect", tmp.to_str().unwrap()]);
    assert!(!seen.status.success() && stderr(&seen).contains("an unfinished frame file"), "{}", stderr(&seen));
    let text = String::from_utf8_lossy(&seen.stdout);
    assert!(text.contains("unfinished, as a sweep writing it now") && !text.contains("DAMAGED"), "{text}");
    // Its hint names the file to continue, and the run where the file's record places it
    // (outside a run the recorded path is absolute: the run stays a placeholder).
    assert!(stderr(&seen).contains(&format!("`clv backward RUN_DIR --out {} --resume`", tmp.with_extension("").display())), "{}", stderr(&seen));
    let inside = dir.join("frames.mcap");
    ok(clv(&["backward", dir.to_str().unwrap(), "--quiet", "--out", inside.to_str().unwrap()]));
    let inside_tmp = dir.join("frames.mcap.tmp");
    std::fs::write(&inside_tmp, &std::fs::read(&inside).unwrap()[..cut.len()]).unwrap();
    let seen = clv(&["inspect", inside_tmp.to_str().unwrap()]);
    assert!(stderr(&seen).contains(&format!("`clv backward {} --out {} --resume`", dir.display(), inside.display())), "{}", stderr(&seen));
    std::fs::remove_file(&inside_tmp).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_clv"))
        .args(["analyze", "-", "--out", dir.parent().unwrap().join("cut").to_str().unwrap()])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(child.stdin.as_mut().unwrap(), cut).unwrap();
    drop(child.stdin.take());
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("complete frames") && err.contains("<stdin>"), "{err}");
}

/// A bit flipped anywhere in the segment the backward stage reads: it stops with an error
/// that names the file and the repair, or, where the damage is outside what it reads, gives
/// the undamaged run's exponents. It never panics, aborts, or reports other numbers.
#[test]
fn a_damaged_segment_stops_the_backward_stage_and_names_the_repair() {
    let (dir, _) = reference("segment-damage");
    let clean = ok(clv(&["backward", dir.to_str().unwrap(), "--quiet", "--json", "--save-every", "0"]));
    let want: serde_json::Value = serde_json::from_slice(&clean.stdout).unwrap();
    let mut segments: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|x| x == "mcap")).collect();
    segments.sort();
    let newest = segments.last().unwrap().file_name().unwrap().to_owned();
    let bytes = std::fs::read(dir.join(&newest)).unwrap();
    let mut rng = Rng::new(11);
    let (mut stopped, mut trials) = (0, 0);
    for i in 0..12 {
        let copy = dir.parent().unwrap().join(format!("damaged-{i}"));
        copy_dir(&dir, &copy);
        let _ = std::fs::remove_file(copy.join("backward.json"));
        let mut damaged = bytes.clone();
        let at = rng.below(bytes.len());
        damaged[at] ^= 1 << rng.below(8);
        std::fs::write(copy.join(&newest), &damaged).unwrap();
        let out = clv(&["backward", copy.to_str().unwrap(), "--quiet", "--json", "--save-every", "0"]);
        let err = stderr(&out);
        trials += 1;
        match out.status.code() {
            Some(0) => {
                let got: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
                assert_eq!(got["exponents"], want["exponents"], "damage at byte {at} changed the numbers");
            }
            Some(1) => {
                stopped += 1;
                assert!(err.contains(newest.to_str().unwrap()) && err.contains("clv forward --resume"), "damage at byte {at}: {err}");
            }
            code => panic!("damage at byte {at}: exit {code:?}: {err}"),
        }
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(stopped > trials / 2, "only {stopped} of {trials} flipped bits were noticed");
}

/// A segment that cannot be read (a directory in its place here, a file without read
/// permission when not run as root) is not damage: resume and inspect stop and say so,
/// and nothing is moved aside or recomputed.
#[test]
fn an_unreadable_segment_is_not_taken_for_damage() {
    let (dir, before) = reference("unreadable");
    let d = dir.to_str().unwrap();
    let mut segments: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|x| x == "mcap")).collect();
    segments.sort();
    let first = segments[0].clone();
    let kept = dir.parent().unwrap().join("kept.mcap");
    let as_root = unsafe { libc::geteuid() } == 0;
    let make_unreadable = |how: usize| {
        if how == 0 {
            std::fs::rename(&first, &kept).unwrap();
            std::fs::create_dir(&first).unwrap();
        } else {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&first, std::fs::Permissions::from_mode(0o000)).unwrap();
        }
    };
    let restore = |how: usize| {
        if how == 0 {
            std::fs::remove_dir(&first).unwrap();
            std::fs::rename(&kept, &first).unwrap();
        } else {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&first, std::fs::Permissions::from_mode(0o644)).unwrap();
        }
    };
    for how in if as_root { vec![0] } else { vec![0, 1] } {
        make_unreadable(how);
        let out = clv(&["forward", "--resume", d, "--quiet"]);
        let err = stderr(&out);
        assert!(!out.status.success() && err.contains(first.file_name().unwrap().to_str().unwrap()) && err.contains("nothing was changed"), "{err}");
        let out = clv(&["inspect", d]);
        assert!(!out.status.success() && stderr(&out).contains("cannot be read"), "{}", stderr(&out));
        restore(how);
        assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().contains(".corrupt")), "a segment was set aside");
        assert!(contents(&dir) == before, "the run changed");
    }
}

/// A reader that has gone before the table is printed (`clv forward ... | head -0`): the
/// results of a run without --out never arrived, so the command says so and exits as a
/// writer killed by SIGPIPE (141), not 0; no panic.
#[test]
fn a_closed_standard_output_is_no_success() {
    for args in [&["forward", "--n", "8", "--aspect", "1", "--steps", "5000", "--quiet"][..], &["forward", "--n", "8", "--aspect", "1", "--steps", "5000", "--quiet", "--json"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = stderr(&out);
        assert!(out.status.code() == Some(141) && err.contains("closed it before the output was written whole") && err.contains("--out DIR") && !err.contains("panicked"), "{args:?}: {:?} {err}", out.status);
    }
    // Help and the version are output too: unwritten, they are no success either.
    for args in [&["--help"][..], &["forward", "--help"], &["--version"]] {
        let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_clv")).args(args).stdout(full).output().unwrap();
        let err = stderr(&out);
        assert!(out.status.code() == Some(1) && err.contains("writing to standard output failed") && !err.contains("panicked"), "{args:?}: {:?} {err}", out.status);
    }
    // A full disk where standard output goes (a batch job's log over quota): the run itself
    // finished, and resuming it, as a full disk's message would say, has nothing to do.
    let run = scratch("faults", "stdout-full").join("run");
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_clv")).args(["forward", "--n", "8", "--aspect", "1", "--steps", "200", "--quiet", "--out", run.to_str().unwrap()]).stdout(full).output().unwrap();
    let err = stderr(&out);
    assert!(out.status.code() == Some(1) && err.contains("the files it wrote are complete") && !err.contains("--resume"), "{:?} {err}", out.status);
    assert!(String::from_utf8_lossy(&ok(clv(&["inspect", run.to_str().unwrap()])).stdout).contains("(finished)"));
}

/// A run directory the user cannot write: the backward stage says so and how to go on.
/// Run as `nobody` through setpriv when the tests run as root (root writes anywhere).
#[test]
fn a_read_only_run_directory_is_named_with_the_way_out() {
    use std::os::unix::fs::PermissionsExt;
    let as_root = unsafe { libc::geteuid() } == 0;
    if as_root && !Path::new("/usr/bin/setpriv").exists() {
        eprintln!("skipped: running as root without setpriv");
        return;
    }
    // Under /tmp: `nobody` must be able to reach the run and the binary.
    let base = std::env::temp_dir().join(format!("clv-read-only-{}", std::process::id()));
    let run = base.join("run");
    std::fs::create_dir_all(&base).unwrap();
    ok(clv(&["forward", "--n", "8", "--aspect", "1", "--steps", "300", "--clv-steps", "50", "--quiet", "--out", run.to_str().unwrap()]));
    let exe = base.join("clv");
    std::fs::copy(env!("CARGO_BIN_EXE_clv"), &exe).unwrap();
    let analysed = base.join("f.mcap");
    ok(clv(&["backward", run.to_str().unwrap(), "--quiet", "--out", analysed.to_str().unwrap()]));
    std::fs::set_permissions(&analysed, std::fs::Permissions::from_mode(0o644)).unwrap();
    for entry in std::fs::read_dir(&run).unwrap() {
        std::fs::set_permissions(entry.unwrap().path(), std::fs::Permissions::from_mode(0o644)).unwrap();
    }
    std::fs::set_permissions(&base, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::set_permissions(&run, std::fs::Permissions::from_mode(0o555)).unwrap();
    let frames = std::env::temp_dir().join(format!("clv-read-only-{}.mcap", std::process::id()));
    let as_user = |args: &[&str]| {
        if as_root {
            Command::new("/usr/bin/setpriv").args(["--reuid=65534", "--regid=65534", "--clear-groups", exe.to_str().unwrap()]).args(args).output().unwrap()
        } else {
            Command::new(&exe).args(args).output().unwrap()
        }
    };
    let out = as_user(&["backward", run.to_str().unwrap(), "--quiet", "--out", frames.to_str().unwrap()]);
    // A report into it: the way out too, not a bare OS error.
    let report = as_user(&["analyze", analysed.to_str().unwrap(), "--quiet", "--out", run.join("rep").to_str().unwrap()]);
    std::fs::set_permissions(&run, std::fs::Permissions::from_mode(0o755)).unwrap();
    let _ = std::fs::remove_dir_all(&base);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("is not writable") && err.contains("cp -r"), "{err}");
    let err = stderr(&report);
    assert!(!report.status.success() && err.contains("give --out a directory you can write"), "{err}");
}

/// The small JSON records beside the segments carry checksums: one changed digit in the
/// backward progress record or in spectrum.json is refused (and named by `clv inspect`),
/// never continued from; `clv forward --resume` rewrites a damaged spectrum.json exactly.
#[test]
fn damaged_or_edited_records_are_refused_not_continued_from() {
    let (dir, _) = reference("records");
    let d = dir.to_str().unwrap();
    let want = dir.parent().unwrap().join("want.mcap");
    ok(clv(&["backward", d, "--quiet", "--out", want.to_str().unwrap()]));
    let out = dir.parent().unwrap().join("part.mcap");
    let o = out.to_str().unwrap();
    assert!(crashed(&clv_env(&["backward", d, "--quiet", "--out", o], &[("CLV_FAULT_CRASH_AT", "frames-synced#8")]), "frames-synced#8"));
    let record = dir.join("backward.json");
    let text = std::fs::read_to_string(&record).unwrap();
    let at: serde_json::Value = serde_json::from_str(&text).unwrap();
    let at = at["at"].as_u64().unwrap();
    std::fs::write(&record, text.replacen(&format!("\"at\": {at}"), &format!("\"at\": {}", at - 50), 1)).unwrap();
    let refused = clv(&["backward", d, "--quiet", "--out", o, "--resume"]);
    let err = stderr(&refused);
    assert!(!refused.status.success() && err.contains("backward.json") && err.contains("edited or damaged") && err.contains("without --resume"), "{err}");
    let seen = String::from_utf8_lossy(&clv(&["inspect", d]).stdout).to_string();
    assert!(seen.contains("DAMAGE") && seen.contains("backward.json") && !seen.contains("all finished files intact"), "{seen}");
    // The way out it names: the sweep again from the start, to the same frames.
    std::fs::remove_file(dir.parent().unwrap().join("part.mcap.tmp")).unwrap();
    ok(clv(&["backward", d, "--quiet", "--out", o]));
    assert!(frames(&out) == frames(&want));
    // `clv analyze RUN` reads the frame file the run's last sweep wrote.
    let rep = dir.parent().unwrap().join("report");
    ok(clv(&["analyze", d, "--out", rep.to_str().unwrap(), "--only", "spectrum", "--quiet"]));
    assert!(std::fs::read_to_string(rep.join("index.html")).unwrap().contains("part.mcap"));
    // A record cut short (no longer JSON) of a sweep into the run's own frames.mcap: the way
    // out names the frames that sweep left, which would stop the new sweep too.
    assert!(crashed(&clv_env(&["backward", d, "--quiet"], &[("CLV_FAULT_CRASH_AT", "frames-synced#8")]), "frames-synced#8"));
    let text = std::fs::read(&record).unwrap();
    std::fs::write(&record, &text[..text.len() / 2]).unwrap();
    let refused = clv(&["backward", d, "--quiet", "--resume"]);
    let left = dir.join("frames.mcap.tmp");
    assert!(!refused.status.success() && stderr(&refused).contains(&format!("delete {} (the frames it left)", left.display())), "{}", stderr(&refused));
    std::fs::remove_file(&left).unwrap();
    ok(clv(&["backward", d, "--quiet"]));
    assert!(frames(&dir.join("frames.mcap")) == frames(&want));
    // The finished sweep's CLV spectrum damaged: --resume names it and where the fix is.
    let spectrum = dir.join("clv_spectrum.json");
    let good = std::fs::read(&spectrum).unwrap();
    std::fs::write(&spectrum, &good[..good.len() / 2]).unwrap();
    let refused = clv(&["backward", d, "--quiet", "--resume"]);
    assert!(!refused.status.success() && stderr(&refused).contains(&format!("`clv inspect {d}` says how to compute it again")), "{}", stderr(&refused));
    std::fs::write(&spectrum, good).unwrap();

    let spectrum = dir.join("spectrum.json");
    let good = std::fs::read(&spectrum).unwrap();
    let lambda_1 = serde_json::from_slice::<serde_json::Value>(&good).unwrap()["exponents"][0].to_string();
    let text = String::from_utf8(good.clone()).unwrap();
    let digit = lambda_1.as_bytes()[0] as char;
    let other = if digit == '4' { "3" } else { "4" };
    std::fs::write(&spectrum, text.replacen(&lambda_1, &format!("{other}{}", &lambda_1[1..]), 1)).unwrap();
    for cmd in [vec!["backward", d, "--quiet", "--save-every", "0"], vec!["combine", d, d]] {
        let refused = clv(&cmd);
        let err = stderr(&refused);
        assert!(!refused.status.success() && err.contains("spectrum.json") && err.contains("edited or damaged") && err.contains("clv forward --resume"), "{cmd:?}: {err}");
    }
    let seen = String::from_utf8_lossy(&clv(&["inspect", d]).stdout).to_string();
    assert!(seen.contains("DAMAGE") && seen.contains("spectrum.json"), "{seen}");
    ok(clv(&["forward", "--resume", d, "--quiet"]));
    // The same numbers, all but the wall-clock time (up to the last checkpoint, not to the
    // writing of the file) and so the checksum.
    let comparable = |bytes: &[u8]| {
        let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
        v["statistics"]["wall_seconds"] = serde_json::Value::Null;
        v["crc32"] = serde_json::Value::Null;
        v
    };
    assert!(comparable(&std::fs::read(&spectrum).unwrap()) == comparable(&good), "the rewritten spectrum.json differs from the original");
    assert!(dir.join("spectrum.json.damaged").exists());
    // Removing the checksum with the edit does not pass either: the run's records carry one.
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(&spectrum).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("crc32");
    v["exponents"][0] = serde_json::json!(9.5);
    std::fs::write(&spectrum, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    let refused = clv(&["backward", d, "--quiet", "--save-every", "0"]);
    assert!(!refused.status.success() && stderr(&refused).contains("carries no checksum"), "{}", stderr(&refused));
    // --out may not name the run's own files (frames would replace them, or they the frames).
    for name in ["clv_spectrum.json", "backward.tmp", "seg-000000000000-000000000050.mcap", "notes", "previous-3000-steps/frames.mcap"] {
        let out = dir.join(name);
        let refused = clv(&["backward", d, "--quiet", "--out", out.to_str().unwrap()]);
        assert!(!refused.status.success() && stderr(&refused).contains("where only frame files ending in .mcap"), "{name}: {}", stderr(&refused));
    }
    // Nor is a report written into the run directory.
    let refused = clv(&["analyze", want.to_str().unwrap(), "--out", d, "--overwrite", "--quiet"]);
    assert!(!refused.status.success() && stderr(&refused).contains("is a run directory"), "{}", stderr(&refused));
}

/// A sweep's frame file is found by the run, not by the directory the command runs in: a
/// resume from elsewhere, or of a moved run, continues the run's own file; the interrupted
/// file of another run is refused, not spliced in; --resume with no sweep recorded is
/// refused instead of starting one with other options; and a refused sweep leaves no record.
#[test]
fn a_resumed_sweep_continues_its_own_frames_only() {
    let (dir, _) = reference("own-frames");
    let base = dir.parent().unwrap().to_path_buf();
    let d = dir.to_str().unwrap();
    ok(clv(&["backward", d, "--quiet", "--with-gs"]));
    let want = frames(&dir.join("frames.mcap"));
    std::fs::remove_file(dir.join("frames.mcap")).unwrap();
    std::fs::remove_file(dir.join("backward.json")).unwrap();
    // --resume with nothing recorded: refused, and nothing started.
    let refused = clv(&["backward", d, "--quiet", "--resume"]);
    let err = stderr(&refused);
    assert!(!refused.status.success() && err.contains("--resume") && err.contains("no backward sweep"), "{err}");
    assert!(!dir.join("backward.json").exists());
    // Started here, with the default file inside the run, then the run moved and resumed
    // from another working directory.
    let run_in = |cwd: &Path, args: &[&str], env: &[(&str, &str)]| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_clv"));
        c.args(args).current_dir(cwd).envs(env.iter().copied());
        c.output().unwrap()
    };
    assert!(crashed(&run_in(&base, &["backward", "run", "--quiet", "--with-gs"], &[("CLV_FAULT_CRASH_AT", "frames-synced#8")]), "frames-synced#8"));
    let moved = base.join("moved");
    std::fs::rename(&dir, &moved).unwrap();
    // On another number of threads, as on another node: the same sweep.
    ok(run_in(Path::new("/"), &["backward", moved.to_str().unwrap(), "--quiet", "--resume", "--threads", "2"], &[]));
    assert!(frames(&moved.join("frames.mcap")) == want, "the moved run's resumed frames differ");
    // Another run's interrupted file in place of this run's: refused with the way out.
    let (other, _) = {
        let dir = scratch("faults", "own-frames-other").join("run");
        let mut args = forward_args(&dir);
        args.extend(["--seed".into(), "7".into()]);
        ok(clv(&args.iter().map(String::as_str).collect::<Vec<_>>()));
        (dir, ())
    };
    let m = moved.to_str().unwrap();
    for run in [m, other.to_str().unwrap()] {
        let _ = std::fs::remove_file(Path::new(run).join("frames.mcap"));
        // After its eighth segment: 150 frames past the backward transient of 250 steps.
        assert!(crashed(&clv_env(&["backward", run, "--quiet", "--with-gs"], &[("CLV_FAULT_CRASH_AT", "frames-synced#8")]), "frames-synced#8"));
    }
    std::fs::copy(other.join("frames.mcap.tmp"), moved.join("frames.mcap.tmp")).unwrap();
    let refused = clv(&["backward", m, "--quiet", "--resume"]);
    let err = stderr(&refused);
    assert!(!refused.status.success() && err.contains("another run") && err.contains("without --resume"), "{err}");
    // ...and left where it is, for the sweep it belongs to.
    assert!(moved.join("frames.mcap.tmp").exists() && !moved.join("frames.mcap.tmp.old").exists());
    // A refused --out leaves no record behind.
    std::fs::remove_file(moved.join("backward.json")).unwrap();
    let taken = base.join("taken.mcap");
    std::fs::write(&taken, b"someone's file").unwrap();
    let refused = clv(&["backward", m, "--quiet", "--out", taken.to_str().unwrap()]);
    assert!(!refused.status.success() && stderr(&refused).contains("already exists"), "{}", stderr(&refused));
    assert_eq!(std::fs::read(&taken).unwrap(), b"someone's file");
    assert!(!moved.join("backward.json").exists(), "a refused sweep left a progress record");
}

/// A finished Henon run in `base/run` and the frame file of its backward sweep (the report
/// tests below need frames, quickly).
fn henon_frames(base: &Path) -> std::path::PathBuf {
    let run = base.join("run");
    let r = run.to_str().unwrap();
    ok(clv(&["forward", "--system", "henon", "--steps", "3000", "--out", r, "--quiet"]));
    ok(clv(&["backward", r, "--with-gs", "--quiet"]));
    run.join("frames.mcap")
}

/// The report files of `dir` (names and bytes), leaving out `except`.
fn report_contents(dir: &Path, except: &[&str]) -> std::collections::BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| !except.contains(&name.as_str()))
        .map(|name| (name.clone(), std::fs::read(dir.join(&name)).unwrap()))
        .collect()
}

/// `clv analyze --overwrite` removes only the earlier report's own files, whatever its
/// summary.json (edited, or from elsewhere) lists, and writes its files in place of
/// symbolic links found in the report, never through them.
#[test]
fn an_overwritten_report_touches_no_file_outside_it() {
    let base = scratch("faults", "report-outside");
    let frames = henon_frames(&base);
    let f = frames.to_str().unwrap();
    let rep = base.join("report");
    ok(clv(&["analyze", f, "--out", rep.to_str().unwrap(), "--quiet"]));
    let outside = ["victim.txt", "absolute.txt", "picture.png", "picture.svg", "linked.csv", "linked.png"];
    for name in outside {
        std::fs::write(base.join(name), name).unwrap();
    }
    std::fs::write(rep.join(".hidden"), "mine").unwrap();
    let summary_path = rep.join("summary.json");
    let mut summary: serde_json::Value = serde_json::from_slice(&std::fs::read(&summary_path).unwrap()).unwrap();
    let absolute = base.join("absolute.txt").display().to_string();
    summary["produced"][0]["tables"].as_array_mut().unwrap().extend(["../victim.txt", absolute.as_str(), ".hidden", "."].map(serde_json::Value::from));
    summary["produced"][0]["figures"].as_array_mut().unwrap().push("../picture".into());
    std::fs::write(&summary_path, serde_json::to_vec(&summary).unwrap()).unwrap();
    for (link, target) in [("spectrum.csv", "../linked.csv"), ("fig2_spectrum.png", "../linked.png")] {
        std::fs::remove_file(rep.join(link)).unwrap();
        std::os::unix::fs::symlink(target, rep.join(link)).unwrap();
    }
    ok(clv(&["analyze", f, "--out", rep.to_str().unwrap(), "--overwrite", "--quiet"]));
    for name in outside {
        assert_eq!(std::fs::read_to_string(base.join(name)).unwrap_or_default(), name, "{name} outside the report was changed");
    }
    assert_eq!(std::fs::read_to_string(rep.join(".hidden")).unwrap(), "mine");
    for name in ["spectrum.csv", "fig2_spectrum.png"] {
        assert!(std::fs::symlink_metadata(rep.join(name)).unwrap().is_file(), "{name} is still a link");
    }
    assert!(std::fs::read_to_string(rep.join("spectrum.csv")).unwrap().starts_with("i,"));
    // Nor does a report leave temporary files behind.
    assert!(std::fs::read_dir(&rep).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".clv-tmp")));
}

/// A report killed while `clv analyze --overwrite` writes it is marked incomplete (index.html
/// says so and how to regenerate it; no summary.json), holds none of the earlier report's
/// files, and the same command again leaves exactly the files of an uninterrupted run. So
/// for `clv run`, whose report is found in that state: it writes the report again.
#[test]
fn an_interrupted_overwrite_says_so_and_the_command_again_gives_a_clean_report() {
    let base = scratch("faults", "report-interrupted");
    let frames = henon_frames(&base);
    let stream = ok(clv(&["backward", base.join("run").to_str().unwrap(), "--with-gs", "--out", "-", "--quiet"])).stdout;
    let rep = base.join("report");
    let r = rep.to_str().unwrap();
    // The earlier report: every analysis, and a file of the user's own.
    ok(clv(&["analyze", frames.to_str().unwrap(), "--out", r, "--quiet"]));
    std::fs::write(rep.join("notes.txt"), "mine").unwrap();
    let args = |out: &str| ["analyze", "-", "--out", out, "--overwrite", "--only", "spectrum,henon", "--quiet"].map(String::from);
    let analyze = |out: &str| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(args(out)).stdin(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
        std::io::Write::write_all(child.stdin.as_mut().unwrap(), &stream).unwrap();
        drop(child.stdin.take());
        child.wait_with_output().unwrap()
    };
    // Half the stream, and a kill once the analyses have started on it.
    let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(args(r)).stdin(Stdio::piped()).spawn().unwrap();
    std::io::Write::write_all(child.stdin.as_mut().unwrap(), &stream[..stream.len() / 2]).unwrap();
    let started = std::time::Instant::now();
    while rep.join("summary.json").exists() || rep.join("local_exponents.csv").exists() {
        assert!(started.elapsed() < Duration::from_secs(60), "the analyses did not start on half a stream");
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let html = std::fs::read_to_string(rep.join("index.html")).unwrap();
    assert!(html.contains("Incomplete report") && html.contains("--overwrite"), "{html}");
    // The new analyses write at the end of the stream: nothing of either report is left but
    // the manifest of what the killed one wrote (its page), and its lock file (the lock died
    // with it).
    assert_eq!(report_contents(&rep, &[]).into_keys().collect::<Vec<_>>(), [".clv-lock", ".clv-writing", "index.html", "notes.txt"]);
    // Killed later, it would have written tables too, listed in its manifest before they
    // were written: the next report removes them although no summary.json names them.
    std::fs::write(rep.join("modes.csv"), "a table of the killed report").unwrap();
    let mut manifest = std::fs::OpenOptions::new().append(true).open(rep.join(".clv-writing")).unwrap();
    std::io::Write::write_all(&mut manifest, b"modes.csv\n").unwrap();
    // The same command again, and the same into a new directory.
    let out = analyze(r);
    assert!(out.status.success(), "{}", stderr(&out));
    let clean = base.join("clean");
    let out = analyze(clean.to_str().unwrap());
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(rep.join("notes.txt")).unwrap(), "mine");
    let (got, want) = (report_contents(&rep, &["notes.txt"]), report_contents(&clean, &[]));
    assert!(!got.contains_key("modes.csv") && !got.contains_key(".clv-writing"), "{:?}", got.keys());
    assert_eq!(got.keys().collect::<Vec<_>>(), want.keys().collect::<Vec<_>>());
    assert!(got == want, "the regenerated report differs from an uninterrupted one");

    // `clv run` finds its report as a killed analysis leaves it: it analyses again.
    let out = base.join("clv-run");
    let o = out.to_str().unwrap();
    ok(clv(&["run", "--preset", "henon", "--steps", "3000", "--out", o, "--quiet"]));
    let report = out.join("report");
    let before = report_contents(&report, &[]);
    clv::report::dir::begin_report(&report, "a killed clv run", None).unwrap();
    assert!(!report.join("summary.json").exists() && !report.join("fig1_henon.png").exists());
    ok(clv(&["run", "--preset", "henon", "--steps", "3000", "--out", o, "--quiet"]));
    assert!(report_contents(&report, &[]) == before, "clv run did not write its report again");
}

/// Window lengths of which none fits in the frames are refused, naming --deltas and the
/// longest that fits, rather than giving a table of NaN; one that fits among them is kept.
#[test]
fn finite_time_windows_longer_than_the_stream_are_refused() {
    let base = scratch("faults", "report-deltas");
    let frames = henon_frames(&base);
    let f = frames.to_str().unwrap();
    let rep = base.join("report");
    let out = clv(&["analyze", f, "--out", rep.to_str().unwrap(), "--deltas", "100000,5000"]);
    let err = stderr(&out);
    assert!(!out.status.success() && err.contains("invalid --deltas") && err.contains("give lengths up to"), "{err}");
    assert!(!rep.join("index.html").exists(), "a refused report was written");
    ok(clv(&["analyze", f, "--out", rep.to_str().unwrap(), "--deltas", "100000,5", "--only", "local_exponents", "--quiet"]));
}

/// A finished sweep's frame file cut short: `clv inspect RUN` names it (by its end, without
/// reading the frames), `clv inspect FILE` and `clv analyze` give the command that writes it
/// whole, `--resume` says the sweep finished and recomputes nothing, and that command,
/// given once the file is moved aside, writes the same frames again.
#[test]
fn a_cut_frame_file_is_named_and_written_whole_again() {
    let (dir, _) = reference("cut-frames");
    let d = dir.to_str().unwrap();
    let file = dir.join("frames.mcap");
    ok(clv(&["backward", d, "--save-every", "5", "--transient", "100", "--quiet"]));
    let whole = frames(&file);
    let len = std::fs::metadata(&file).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&file).unwrap().set_len(len / 2).unwrap();
    let seen = clv(&["inspect", d]);
    let text = String::from_utf8_lossy(&seen.stdout).to_string();
    assert!(!seen.status.success() && text.contains("frames.mcap, the frame file of the last backward sweep, is cut short"), "{text}");
    let report = dir.parent().unwrap().join("cut-report");
    for out in [clv(&["inspect", file.to_str().unwrap()]), clv(&["analyze", d, "--out", report.to_str().unwrap(), "--only", "spectrum", "--quiet"])] {
        let err = stderr(&out);
        assert!(!out.status.success() && err.contains(&format!("move {} aside and give its sweep again", file.display())), "{err}");
    }
    let err = stderr(&clv(&["inspect", file.to_str().unwrap()]));
    let command = err.split('`').nth(1).expect("a command in backquotes").to_string();
    assert!(command.starts_with(&format!("clv backward {d} --out {} --save-every 5", file.display())) && command.contains("--transient 100"), "{command}");
    let resumed = ok(clv(&["backward", d, "--resume"]));
    assert!(stderr(&resumed).contains("finished earlier: nothing was recomputed"), "{}", stderr(&resumed));
    let table = String::from_utf8_lossy(&resumed.stdout);
    assert!(table.contains("segments by the sweep that finished earlier"), "the statistics are the earlier sweep's: {table}");
    assert_eq!(std::fs::metadata(&file).unwrap().len(), len / 2);
    std::fs::rename(&file, dir.join("frames.cut.mcap")).unwrap();
    let args: Vec<&str> = command.split_whitespace().skip(1).chain(["--quiet"]).collect();
    ok(clv(&args));
    assert!(frames(&file) == whole, "the frames written again differ");
    ok(clv(&["inspect", d]));
    // A file of every 5th step measures no windows of consecutive frames, and its report's
    // options say so (they listed the default lengths).
    let every_fifth = dir.parent().unwrap().join("every-fifth");
    ok(clv(&["analyze", d, "--out", every_fifth.to_str().unwrap(), "--only", "local_exponents", "--quiet"]));
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(every_fifth.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["options"]["deltas"], serde_json::json!([]), "{summary}");
    assert!(summary["left_out"].as_array().unwrap().iter().any(|l| l.as_str().unwrap().contains("finite-time exponents")), "{summary}");
    // Lengths asked for there are refused before anything is written.
    let asked = dir.parent().unwrap().join("every-fifth-deltas");
    let out = clv(&["analyze", d, "--out", asked.to_str().unwrap(), "--deltas", "5", "--quiet"]);
    assert!(!out.status.success() && stderr(&out).contains("invalid --deltas") && stderr(&out).contains("multiples of 5") && !asked.exists(), "{}", stderr(&out));
    // Damaged from its start (no complete frame, or no MCAP at all): the same command.
    for bytes in [&b""[..], b"hello\n"] {
        std::fs::write(&file, bytes).unwrap();
        let fresh = dir.parent().unwrap().join(format!("cut-report-{}", bytes.len()));
        let err = stderr(&clv(&["analyze", d, "--out", fresh.to_str().unwrap(), "--quiet"]));
        assert!(err.contains(&format!("move {} aside and give its sweep again: `{command}", file.display())), "{err}");
    }
    // An interrupted sweep's FILE.tmp given to analyze: the sweep to continue, and the file
    // it finishes (not FILE.tmp) for the one given again.
    let tmp = dir.join("frames.mcap.tmp");
    ok(clv(&["backward", d, "--save-every", "5", "--out", dir.join("again.mcap").to_str().unwrap(), "--quiet"]));
    let bytes = std::fs::read(dir.join("again.mcap")).unwrap();
    std::fs::write(&tmp, &bytes[..bytes.len() / 2]).unwrap();
    let err = stderr(&clv(&["analyze", tmp.to_str().unwrap(), "--out", dir.parent().unwrap().join("tmp-report").to_str().unwrap(), "--quiet"]));
    assert!(err.contains(&format!("the unfinished file of an interrupted sweep into {}: continue that sweep with `clv backward", file.display())) && err.contains(&format!("--out {} ", file.display())), "{err}");
}

/// `clv run` killed (SIGKILL, no chance to clean up) while its forward stage writes segments,
/// and again while its backward stage and analyses run: the same command given again
/// finishes the job, and the report is the one an uninterrupted run writes (every table and
/// figure byte for byte; index.html but for the line that names the run directory).
#[test]
fn clv_run_killed_in_any_stage_is_finished_by_the_same_command() {
    let base = scratch("faults", "run-sigkill");
    let (want, out) = (base.join("want"), base.join("killed"));
    let args = |dir: &Path| -> Vec<String> { ["run", "--out", dir.to_str().unwrap(), "--steps", "4000", "--quiet"].iter().map(|s| s.to_string()).collect() };
    ok(clv(&strs(&args(&want))));
    // Start the command, SIGKILL it as soon as `reached` holds: whether it was still running.
    let kill_when = |reached: &dyn Fn() -> bool| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(args(&out)).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        let started = std::time::Instant::now();
        while !reached() && child.try_wait().unwrap().is_none() && started.elapsed() < Duration::from_secs(120) {
            std::thread::sleep(Duration::from_millis(1));
        }
        let running = child.try_wait().unwrap().is_none();
        let _ = child.kill();
        child.wait().unwrap();
        running
    };
    let run = out.join("run");
    let has_segment = || std::fs::read_dir(&run).is_ok_and(|d| d.flatten().any(|e| e.file_name().to_string_lossy().starts_with("seg-") && e.file_name().to_string_lossy().ends_with(".mcap")));
    assert!(kill_when(&has_segment), "the forward stage ended before the kill");
    assert!(!run.join("spectrum.json").exists(), "killed in the forward stage, the run is not finished");
    let forward_done = || run.join("spectrum.json").exists();
    let landed = kill_when(&forward_done);
    assert!(!landed || !out.join("report/summary.json").exists(), "a killed job left a finished report");
    ok(clv(&strs(&args(&out))));
    assert_same_reports(&want, &out);
}

/// The reports of two `clv run --out` directories hold the same files, byte for byte
/// (index.html but for the line that names the run directory).
fn assert_same_reports(want: &Path, got: &Path) {
    let report = |dir: &Path| -> std::collections::BTreeMap<String, Vec<u8>> {
        std::fs::read_dir(dir.join("report"))
            .unwrap()
            .flatten()
            .map(|e| (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap()))
            .map(|(name, bytes)| {
                let bytes = if name == "index.html" { String::from_utf8(bytes).unwrap().lines().filter(|l| !l.starts_with("<p>Source:")).collect::<Vec<_>>().join("\n").into_bytes() } else { bytes };
                (name, bytes)
            })
            .collect()
    };
    let (a, b) = (report(want), report(got));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>(), "the files of the two reports");
    for (name, bytes) in &a {
        assert!(b[name] == *bytes, "{name} differs from the uninterrupted run's");
    }
}

/// `clv run` on a real full disk (a tmpfs, as above), filled first in its forward stage and
/// then while it writes the report: each time the same command, given again once there is
/// space, continues, and the report is the one an uninterrupted run writes.
#[test]
fn clv_run_on_a_real_full_disk_is_finished_by_the_same_command() {
    let base = scratch("faults", "run-full");
    let (want, mnt) = (base.join("want"), base.join("mnt"));
    std::fs::create_dir_all(&mnt).unwrap();
    let Some(tmpfs) = Tmpfs::mount(&mnt, "2m") else { return };
    let args = |dir: &Path| -> Vec<String> { ["run", "--out", dir.to_str().unwrap(), "--steps", "4000", "--quiet"].iter().map(|s| s.to_string()).collect() };
    ok(clv(&strs(&args(&want))));
    let job = mnt.join("job");
    let again = "give the same `clv run` command again";
    let out = clv(&strs(&args(&job)));
    assert!(out.status.code() == Some(1) && stderr(&out).contains("disk full") && stderr(&out).contains(again), "{}", stderr(&out));
    // Room for the run directory (as large as the uninterrupted one's) and 1 MB, half of
    // what the report takes.
    let du = ok(Command::new("du").arg("-sk").arg(want.join("run")).output().unwrap());
    let run_kb: u64 = String::from_utf8_lossy(&du.stdout).split_whitespace().next().unwrap().parse().unwrap();
    tmpfs.resize(&format!("{}k", run_kb + 1024));
    let out = clv(&strs(&args(&job)));
    assert!(out.status.code() == Some(1) && stderr(&out).contains("disk full") && stderr(&out).contains(again), "{}", stderr(&out));
    assert!(job.join("run/spectrum.json").exists() && !job.join("report/summary.json").exists(), "the forward stage finished, the report did not");
    tmpfs.resize("256m");
    ok(clv(&strs(&args(&job))));
    assert_same_reports(&want, &job);
}
