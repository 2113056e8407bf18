//! Helpers shared by the integration tests: run the real binary, scratch directories, and
//! read back everything a run directory or frame file holds as decoded numbers.
#![allow(dead_code)]

use clv::stage::forward::ForwardState;
use clv::stage::frame::Frame;
use clv::store::frames::{read_frames, Flow};
use clv::store::records::{decode_r, Checkpoint, Stats};
use clv::store::schema::{CHECKPOINT, R, STATS};
use clv::store::segment::read_segment;
use clv::store::RunDir;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

pub fn clv(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_clv")).args(args).output().unwrap()
}

pub fn clv_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_clv")).args(args).envs(env.iter().copied()).output().unwrap()
}

/// Whether python3 can import `modules` (comma-separated); says so on stderr when it cannot
/// (.ci/run installs mcap, cbor2 and numpy, so CI runs every Python test).
pub fn python_has(modules: &str) -> bool {
    let has = Command::new("python3").args(["-c", &format!("import {modules}")]).output().map(|o| o.status.success()).unwrap_or(false);
    if !has {
        eprintln!("SKIPPED: python3 with {modules} is not available (.ci/run installs them)");
    }
    has
}

pub fn ok(out: Output) -> Output {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    out
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A fresh, empty directory for one test, under cargo's target/tmp. It is removed when the
/// test's thread ends, unless the test failed (its files stay for a look) or
/// CLV_KEEP_TEST_DATA is set: left behind, the suite's runs fill gigabytes, and a disk filled
/// by them fails every test after.
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = shared_scratch(group, name);
    MARK_FAILURES.call_once(|| {
        let report = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let _ = SCRATCH.try_with(|s| s.failed.set(true));
            report(info)
        }));
    });
    SCRATCH.with(|s| s.dirs.borrow_mut().push(dir.clone()));
    dir
}

/// A fresh, empty directory for what several tests of one binary share (made once, in a
/// `OnceLock`): kept, since the test that happens to make it may end before the others.
pub fn shared_scratch(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(group).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

static MARK_FAILURES: std::sync::Once = std::sync::Once::new();

/// The scratch directories one test (one thread of the test harness) made.
#[derive(Default)]
struct Scratch {
    dirs: std::cell::RefCell<Vec<PathBuf>>,
    failed: std::cell::Cell<bool>,
}

thread_local! {
    static SCRATCH: Scratch = Scratch::default();
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if self.failed.get() || std::env::var_os("CLV_KEEP_TEST_DATA").is_some() {
            return;
        }
        for dir in self.dirs.borrow().iter() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

pub fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        if e.path().is_file() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        } else if e.path().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        }
    }
}

/// Everything a finished run directory holds that must be bit-identical between runs
/// (decoded numbers: zstd bytes may differ; wall-clock time excluded).
#[derive(Debug, PartialEq)]
pub struct Contents {
    pub files: Vec<String>,
    pub checkpoints: BTreeMap<u64, ForwardState>,
    pub rs: BTreeMap<u64, Vec<f64>>,
    pub stats: BTreeMap<u64, (Vec<f64>, u64, u64)>,
    pub exponents: Vec<f64>,
}

pub fn contents(dir: &Path) -> Contents {
    let run = RunDir { path: dir.to_path_buf() };
    let mut c = Contents { files: vec![], checkpoints: BTreeMap::new(), rs: BTreeMap::new(), stats: BTreeMap::new(), exponents: vec![] };
    for seg in run.segments().unwrap() {
        c.files.push(seg.path.file_name().unwrap().to_string_lossy().into());
        read_segment(&seg.path, clv::store::segment::ReadMode::Strict, |m| {
            if m.topic == CHECKPOINT.topic {
                c.checkpoints.insert(m.step, Checkpoint::decode(m.data).unwrap().state);
            } else if m.topic == R.topic {
                c.rs.insert(m.step, clv::linalg::pack_upper(decode_r(m.data).unwrap().1.as_ref()));
            } else if m.topic == STATS.topic {
                let s = Stats::decode(m.data).unwrap();
                c.stats.insert(m.step, (s.exponents, s.energy.to_bits(), s.collisions));
            }
            Ok(())
        })
        .unwrap();
    }
    let spectrum: serde_json::Value = serde_json::from_slice(&std::fs::read(run.spectrum_path()).unwrap()).unwrap();
    c.exponents = serde_json::from_value(spectrum["exponents"].clone()).unwrap();
    c
}

/// Frames of a file, in time order.
pub fn frames(path: &Path) -> Vec<Frame> {
    let mut all = Vec::new();
    let (_, damage) = read_frames(path, |f| {
        all.push(f);
        Ok(Flow::Continue)
    })
    .unwrap();
    assert!(damage.is_none(), "{damage:?}");
    all.sort_by_key(|f| f.step);
    all
}

/// Rewrite the checkpoint at `step` of a run with `change` applied (through the real codec).
pub fn alter_checkpoint(dir: &Path, step: u64, change: impl Fn(&mut Checkpoint)) {
    alter_message(dir, CHECKPOINT.topic, step, |data| {
        let mut cp = Checkpoint::decode(data).unwrap();
        change(&mut cp);
        cp.encode()
    });
}

/// Rewrite the run segment holding `step` with its message of `topic` at that step replaced
/// by `change` of it (a valid segment: CRCs and index are written anew).
pub fn alter_message(dir: &Path, want: &str, step: u64, change: impl Fn(&[u8]) -> Vec<u8>) {
    use clv::store::schema::RUN_SCHEMAS;
    use clv::store::segment::{SegmentWriter, RUN_METADATA};
    let run = RunDir { path: dir.to_path_buf() };
    let seg = run.segments().unwrap().into_iter().find(|s| s.first <= step && step <= s.last).unwrap();
    let mut messages = Vec::new();
    let report = read_segment(&seg.path, clv::store::segment::ReadMode::Strict, |m| {
        if m.topic != RUN_METADATA {
            messages.push((m.topic.to_string(), m.step, m.data.to_vec()));
        }
        Ok(())
    })
    .unwrap();
    let tmpdir = dir.join("rewrite");
    std::fs::create_dir_all(&tmpdir).unwrap();
    let mut w = SegmentWriter::create(&tmpdir, seg.first, report.run_json.as_deref().unwrap(), &RUN_SCHEMAS).unwrap();
    for (topic, s, data) in &messages {
        let data = if topic == want && *s == step {
            change(data)
        } else {
            data.clone()
        };
        w.write(topic, *s, &data).unwrap();
    }
    let written = w.finish().unwrap();
    std::fs::rename(written, &seg.path).unwrap();
    std::fs::remove_dir_all(&tmpdir).unwrap();
}

/// Start clv, SIGKILL it after `delay_ms`; true if it was still running (the kill landed).
pub fn kill_after(args: &[&str], delay_ms: u64) -> bool {
    let mut child = Command::new(env!("CARGO_BIN_EXE_clv")).args(args).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    std::thread::sleep(Duration::from_millis(delay_ms));
    let running = child.try_wait().unwrap().is_none();
    let _ = child.kill();
    child.wait().unwrap();
    running
}

/// Write `json` to `path` with a valid checksum: a record as another build or format
/// version would have written it (an edit without one is refused as damage).
pub fn reseal(path: &Path, json: &str) {
    let value: serde_json::Value = serde_json::from_str(json).unwrap();
    std::fs::write(path, clv::store::checked_json::to_vec(&value).unwrap()).unwrap();
}

/// How a person continues a killed `clv backward`, as its messages say: with --resume when
/// the sweep recorded itself (RUN/backward.json), without when it was killed before that.
pub fn resume_flag(run: &Path) -> Vec<&'static str> {
    if run.join("backward.json").exists() { vec!["--resume"] } else { Vec::new() }
}

/// Kill `args` after `delay_ms`; while the process ends before the kill (machines and their
/// load vary), clear what it wrote with `reset` and try again with half the delay.
pub fn kill_landing(args: &[&str], mut delay_ms: u64, reset: impl Fn()) {
    while !kill_after(args, delay_ms) {
        assert!(delay_ms > 0, "{args:?} ends before it can be killed");
        delay_ms /= 2;
        reset();
    }
}
