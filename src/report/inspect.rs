//! `clv inspect`: what a run directory or a frame file holds and whether it is intact.

use crate::error::Result;
use crate::store::records::{Checkpoint, Stats};
use crate::store::run::{human, RunDir, RunMeta, StoreR};
use crate::store::schema::{CHECKPOINT, R, STATS};
use crate::store::segment::{read_segment, RUN_METADATA};
use serde::Serialize;
use std::fmt::Write;
use std::path::Path;

#[derive(Debug, Serialize)]
pub struct SegmentReport {
    pub file: String,
    /// Its steps are not those its name says (renamed, or copied in under another name).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub misnamed: bool,
    pub first_step: u64,
    pub last_step: u64,
    pub bytes: u64,
    pub checkpoints: u64,
    pub r_matrices: u64,
    /// None if intact, else what is wrong (CRC, truncation, undecodable message, steps not
    /// those its name says).
    pub damage: Option<String>,
    /// With `--store-r all`, the step after which its run stored every step's R_n.
    #[serde(skip)]
    pub r_every_step_from: Option<u64>,
}

#[derive(Debug, Serialize)]
pub struct Inspection {
    pub run: RunMeta,
    pub total_steps: u64,
    /// Step of the newest intact checkpoint.
    pub steps_done: Option<u64>,
    pub finished: bool,
    /// An extension of the run was cut off while it moved the results aside
    /// ([`RunDir::extension_interrupted`]): its command, given again, finishes it.
    pub extension_interrupted: bool,
    /// A clv process holds the run's lock: it is being written now.
    pub running: bool,
    pub checkpoints: u64,
    pub segments: Vec<SegmentReport>,
    pub partial_segments: Vec<String>,
    /// Segments a repair set aside: damaged ones (`.corrupt`, kept for a look, safe to
    /// delete) and intact ones waiting for their replacements (`.superseded`).
    pub set_aside: Vec<String>,
    /// Directories with the results of the run before it was extended (`previous-N-steps`).
    pub previous: Vec<String>,
    pub disk_bytes: u64,
    /// Spectrum at the newest intact checkpoint (none while the run relaxes).
    pub exponents: Vec<f64>,
    pub stderr: Vec<f64>,
    /// What makes that spectrum less trustworthy than its errors say ([`crate::report::warnings`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Every finished segment reads back whole (an interrupted one is not counted as damage).
    pub intact: bool,
    /// The convergence tests of the exponents so far (from 4 completed blocks on).
    pub convergence: Option<Convergence>,
    /// run.json disagrees with the copy a segment was written with (or, where the other
    /// segments agree with it, that segment is another run's).
    pub meta_mismatch: Option<String>,
    /// The checksummed records beside the segments (spectrum.json, backward.json,
    /// clv_spectrum.json) that fail their check, with what to do.
    pub damaged_records: Vec<String>,
    /// Checkpoints missing between two segments (a segment moved out or deleted).
    pub gaps: Vec<String>,
    /// The backward sweep its progress record (backward.json) describes, if any.
    pub backward_sweep: Option<String>,
    /// With `--store-r all`, the steps of the window whose R_n no segment holds: they were
    /// computed before an extension moved the window's start earlier.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub r_not_stored: Option<String>,
    /// Why this build or machine cannot continue the run or run its backward stage (another
    /// build's numerics, another kind of CPU), if it cannot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_here: Option<String>,
}

/// [`crate::stage::analyze::kernels::convergence`] over the blocks completed so far.
#[derive(Debug, Serialize)]
pub struct Convergence {
    pub blocks: usize,
    pub block_steps: u64,
    pub tests: String,
    pub verdict: String,
}

pub fn inspect(path: &Path) -> Result<Inspection> {
    let (dir, meta) = RunDir::open(path)?;
    let mut segments = Vec::new();
    // Segments whose embedded run.json agrees with run.json, and those that describe another.
    let (mut agreeing, mut disagreeing) = (0, Vec::new());
    let mut newest: Option<(Stats, Option<crate::statistics::Accumulator>)> = None;
    for seg in dir.segments()? {
        let (mut checkpoints, mut rs) = (0, 0);
        let (mut last_stats, mut last_acc) = (None, None);
        // The steps of its first message and its last checkpoint, which name the file.
        let (mut first, mut last) = (None, None);
        let result = read_segment(&seg.path, crate::store::segment::ReadMode::Strict, |m| {
            let bad = |e: String| crate::Error::corrupt(&seg.path, format!("step {}: {e}", m.step));
            let check = |r: std::result::Result<(), String>| r.map_err(bad);
            if m.topic != RUN_METADATA {
                first.get_or_insert(m.step);
            }
            if m.topic == CHECKPOINT.topic {
                let cp = Checkpoint::decode(m.data).map_err(bad)?;
                last_acc = Some(cp.state.acc);
                last = Some(m.step);
                checkpoints += 1;
            } else if m.topic == R.topic {
                check(crate::store::records::decode_r(m.data).map(|_| ()))?;
                rs += 1;
            } else if m.topic == STATS.topic {
                last_stats = Some(Stats::decode(m.data).map_err(|e| crate::Error::corrupt(&seg.path, e))?);
            }
            Ok(())
        });
        if let Err(e @ crate::Error::Io { .. }) = result {
            return Err(crate::Error::Other(format!("{e}: the file cannot be read, which is not damage (its permissions, the disk?); nothing was checked")));
        }
        if let Ok(report) = &result
            && let Some(theirs) = report.run_json.as_deref().and_then(|j| serde_json::from_str::<RunMeta>(j).ok())
        {
            if meta.same_trajectory(&theirs) {
                agreeing += 1;
            } else {
                disagreeing.push(seg.path.display().to_string());
            }
        }
        let mut misnamed = false;
        let damage = match result {
            Err(e) => Some(e.to_string()),
            Ok(_) => seg.misnamed(first.zip(last)).map(|why| {
                misnamed = true;
                format!("{why}; `clv forward --resume` sets it aside and recomputes what no other segment holds")
            }),
        };
        if damage.is_none()
            && let Some(s) = last_stats
                && newest.as_ref().is_none_or(|(n, _)| s.step > n.step) {
                    newest = Some((s, last_acc));
                }
        segments.push(SegmentReport {
            file: seg.path.file_name().unwrap_or_default().to_string_lossy().into(),
            misnamed,
            first_step: seg.first,
            last_step: seg.last,
            bytes: seg.bytes,
            checkpoints,
            r_matrices: rs,
            damage,
            r_every_step_from: seg.r_every_step_from(),
        });
    }
    // Where other segments agree with run.json, the ones that disagree are the odd ones out.
    let meta_mismatch = match (agreeing, disagreeing.as_slice()) {
        (_, []) => None,
        (0, [first, ..]) => Some(format!("run.json describes another run than {first} was written for (tau, system, seed, ...): it was edited or damaged; `clv forward --resume` puts the segment's copy beside it to restore it from")),
        (n, foreign) => Some(format!("{} written for another run than run.json and the other {n} segments: move {} out of the run directory (`clv forward --resume` then recomputes what is missing)", foreign.join(", "), if foreign.len() == 1 { "it" } else { "them" })),
    };
    let partial_segments: Vec<String> = dir.partial_segments()?.iter().map(|p| p.display().to_string()).collect();
    let mut disk_bytes = 0;
    let (mut set_aside, mut previous) = (Vec::new(), Vec::new());
    for entry in std::fs::read_dir(&dir.path).map_err(|e| crate::Error::io(&dir.path, e))?.flatten() {
        disk_bytes += entry.metadata().map(|m| m.len()).unwrap_or(0);
        let name = entry.file_name().to_string_lossy().into_owned();
        if crate::store::RunDir::is_previous_results(&entry.file_name()) && entry.path().is_dir() {
            previous.push(name.clone());
        }
        if name.ends_with(".mcap.corrupt") || name.ends_with(".mcap.superseded") {
            set_aside.push(name);
        }
    }
    set_aside.sort();
    // The frame file is checked against run.json only where run.json describes the run.
    let damaged_records = damaged_records(&dir, meta_mismatch.is_none().then_some(&meta));
    let backward_sweep = backward_sweep(&dir);
    let c = meta.store.checkpoint_every.max(1);
    // Gaps between the segments whose names can be believed; one that a misnamed segment's
    // name falls into is that segment's damage, named with it.
    let named: Vec<&SegmentReport> = segments.iter().filter(|s| !s.misnamed).collect();
    let claimed = |from: u64, to: u64| segments.iter().any(|s| s.misnamed && s.first_step <= to && from <= s.last_step);
    // Before the first segment only the checkpoints the backward stage starts from are
    // needed (older ones are pruned by design); a misnamed file there is set aside by
    // resume, whatever its name, so it covers nothing.
    let needed = meta.store.first_needed_checkpoint(&meta.config);
    let leading = named.first().filter(|s| s.first_step > needed).map(|s| {
        format!(
            "the checkpoints of steps {needed}..{}, from where the backward stage recomputes the run, are missing: no segment holds them (moved out, or deleted); `clv forward --resume {}` recomputes them from step 0 (there is no checkpoint before them)",
            s.first_step - 1,
            dir.path.display()
        )
    });
    let gaps: Vec<String> = leading
        .into_iter()
        .chain(named.windows(2)
        .filter_map(|w| {
            let r_from = r_every_step_between(w[0], w[1]);
            let from = crate::store::run::next_write_after(w[0].last_step, c, r_from);
            (w[1].first_step > from && !claimed(w[0].last_step + 1, w[1].first_step - 1)).then(|| {
                let what = if r_from.is_some_and(|start| w[1].first_step > start + 1) { "checkpoints and R_n" } else { "checkpoints" };
                format!("the {what} of steps {from}..{} are missing: no segment holds them (moved out, or deleted); `clv forward --resume {}` recomputes them", w[1].first_step - 1, dir.path.display())
            })
        }))
        .collect();
    let total_steps = meta.config.relax_steps + meta.config.steps;
    // A complete run's spectrum beside segments that end early: the newest are gone.
    let mut gaps = gaps;
    if let Some(newest_named) = named.last().filter(|s| s.last_step < total_steps)
        && dir.spectrum_path().exists()
        && !dir.extension_interrupted(meta.config.steps)
    {
        gaps.push(format!(
            "the run was complete ({} is there), but no segment holds its steps after {}: they were moved out or deleted; `clv forward --resume {}` recomputes them",
            dir.spectrum_path().display(),
            newest_named.last_step,
            dir.path.display()
        ));
    }
    let r_not_stored = r_not_stored(&meta, &segments);
    previous.sort_by_key(|n| n.trim_start_matches("previous-").trim_end_matches("-steps").parse::<u64>().unwrap_or(0));
    // During the relaxation nothing is accumulated: its zeros are no spectrum.
    let accumulating = newest.as_ref().filter(|(s, _)| s.step > meta.config.relax_steps);
    let (exponents, stderr) = accumulating.map(|(s, _)| (s.exponents.clone(), s.stderr.clone())).unwrap_or_default();
    let warnings = crate::report::warnings(&meta.config, &exponents, &stderr);
    let convergence = newest.as_ref().and_then(|(_, acc)| {
        let blocks = acc.as_ref()?.block_averages(meta.config.tau);
        let d = crate::stage::analyze::kernels::convergence::diagnose(&blocks.exponents, meta.config.system.neutral())?;
        Some(Convergence { blocks: d.blocks, block_steps: blocks.block_steps, tests: d.numbers(), verdict: d.verdict().to_string() })
    });
    Ok(Inspection {
        total_steps,
        steps_done: newest.as_ref().map(|(s, _)| s.step),
        finished: dir.spectrum_path().exists() && newest.as_ref().is_some_and(|(s, _)| s.step == total_steps),
        extension_interrupted: dir.extension_interrupted(meta.config.steps),
        running: dir.is_being_written(),
        checkpoints: segments.iter().map(|s| s.checkpoints).sum(),
        // A segment left unfinished by a kill is the expected trace of an interrupted run,
        // not damage: --resume discards and recomputes it.
        intact: segments.iter().all(|s| s.damage.is_none()) && meta_mismatch.is_none() && damaged_records.is_empty() && gaps.is_empty(),
        meta_mismatch,
        damaged_records,
        gaps,
        backward_sweep,
        r_not_stored,
        not_here: meta.build.differs_here(),
        segments,
        partial_segments,
        set_aside,
        previous,
        disk_bytes,
        exponents,
        stderr,
        warnings,
        convergence,
        run: meta,
    })
}

/// [`crate::store::run::r_every_step_between`] for the segments as inspect reads them.
fn r_every_step_between(a: &SegmentReport, b: &SegmentReport) -> Option<u64> {
    Some(a.r_every_step_from?.max(b.r_every_step_from?))
}

/// With `--store-r all`, the steps after the window's start whose R_n the intact segments
/// do not hold (but at their checkpoints): each segment stored them after the start of the
/// window its run had when it was written, and an extension can move that start earlier.
/// A segment written under a later start begins at a checkpoint, so the steps since the
/// segment before it count too, unless a segment is missing there (that is a gap, named
/// as damage). Nothing recomputes them: the backward stage does not read them.
fn r_not_stored(meta: &RunMeta, segments: &[SegmentReport]) -> Option<String> {
    if meta.store.store_r != StoreR::All {
        return None;
    }
    let now = meta.store.window_start(&meta.config);
    let c = meta.store.checkpoint_every.max(1);
    let named: Vec<&SegmentReport> = segments.iter().filter(|s| !s.misnamed).collect();
    let mut ranges: Vec<(u64, u64)> = Vec::new();
    for (k, s) in named.iter().enumerate() {
        let Some(then) = s.r_every_step_from.filter(|_| s.damage.is_none()) else { continue };
        let begin = match k.checked_sub(1).map(|p| named[p]) {
            Some(p) if !crate::store::run::gap_between(p.last_step, s.first_step, c, r_every_step_between(p, s)) => p.last_step + 1,
            _ => s.first_step,
        };
        let (from, to) = ((now + 1).max(begin), then.min(s.last_step));
        // Steps between checkpoints, not only checkpoints (whose R_n are stored).
        if from <= to && to - from + 1 > to / c - (from - 1) / c {
            match ranges.last_mut() {
                Some(last) if last.1 + 1 >= from => last.1 = last.1.max(to),
                _ => ranges.push((from, to)),
            }
        }
    }
    if ranges.is_empty() {
        return None;
    }
    let steps: Vec<String> = ranges.iter().map(|(a, b)| format!("{a}..{b}")).collect();
    Some(format!(
        "the R_n of steps {} are not stored (but at the checkpoints): the run computed them before an extension moved the start of the --store-r all window (--clv-steps, --transient) to step {now}. The backward stage recomputes every R_n and does not need them; a run made at once with its final settings stores them all",
        steps.join(", ")
    ))
}

/// The last backward sweep as its progress record tells it: finished, or interrupted (which,
/// while its frame file is unfinished, blocks a sweep with other options until it is
/// resumed or given up).
fn backward_sweep(dir: &RunDir) -> Option<String> {
    use crate::stage::backward::Destination;
    let last = crate::store::progress::last_sweep(&dir.path).ok()??;
    let opts = &last.options;
    let out = match opts.destination() {
        Destination::Stream => "frames to a stream".to_string(),
        Destination::File { path, .. } => {
            let file = dir.path.join(path);
            let gone = if last.done && !file.exists() { ", which is gone (moved or deleted): `clv analyze` of the run refuses until it is back or written anew" } else { "" };
            format!("frames to {}{gone}", file.display())
        }
        Destination::Nowhere => "no frame file".to_string(),
    };
    Some(if last.done {
        format!("finished, {} frames ({out})", last.frames)
    } else if dir.is_being_written() {
        format!("running now ({out}; {} frames at the last record, C at step {})", last.frames, last.at)
    } else {
        // Its frames so far are kept in FILE.tmp, which a sweep with other options would strand.
        let tmp = opts.frames_file(&dir.path).map(|f| crate::store::frames::tmp_path(&f));
        let run = dir.path.display();
        let how = match (opts.destination(), &tmp) {
            // Into a batch job's log, the frames would be bytes nobody reads.
            (Destination::Stream, _) => format!(
                "`clv backward {run} {} | clv analyze - --out REPORT` streams the whole window again (a sweep that `clv run` started: the same `clv run` command); \
                 with --resume it streams only the frames after those it sent, for a reader that kept them",
                opts.as_flags()
            ),
            (_, Some(t)) if !t.exists() && last.frames > 0 => format!(
                "its frames so far ({}) are gone, so --resume is refused: give the sweep's command again without --resume to start it over",
                t.display()
            ),
            (_, Some(t)) if t.exists() => format!(
                "`clv backward {run} --resume` continues it; a sweep with other options is refused until then (it would strand the frames in {})",
                t.display()
            ),
            _ => format!("`clv backward {run} --resume` continues it"),
        };
        format!("interrupted after {} frames ({out}), C recorded at step {}: {how}", last.frames, last.at)
    })
}

/// How to compute a damaged CLV spectrum again: the recorded sweep again (its frames too), or
/// a sweep without frames, which then is the last sweep `clv analyze RUN_DIR` reads.
fn clv_spectrum_advice(dir: &RunDir) -> String {
    let run = dir.path.display();
    let alone = format!("`clv backward {run} --save-every 0` computes the spectrum alone, but then records a sweep without frames, so `clv analyze` needs the frame file by name");
    match crate::store::progress::last_sweep(&dir.path) {
        Ok(Some(last)) if last.options.frames_file(&dir.path).is_some() => {
            let file = last.options.frames_file(&dir.path).unwrap_or_default();
            let flags = last.options.flags_into(&file);
            format!("give the last sweep again, `clv backward {run} {flags}` (move {} aside first: it writes the frames again too); or {alone}", file.display())
        }
        _ => alone,
    }
}

/// What is wrong with the last finished sweep's frame file, if anything: cut short (checked
/// by its end only: `clv inspect FILE` reads every frame), or another run's or sweep's
/// (its metadata against the run's records; `meta`, the run.json that describes the run, or
/// None where run.json disagrees with the segments, which is then the damage to name).
fn frame_file_problem(dir: &RunDir, meta: Option<&RunMeta>) -> Option<String> {
    let last = crate::store::progress::last_sweep(&dir.path).ok()??;
    let file = last.options.frames_file(&dir.path).filter(|f| last.done && f.exists())?;
    let rewrite = crate::stage::backward::rewrite_advice(&file, Some(&last.options), Some(&dir.path));
    if !crate::store::frames::ends_whole(&file).unwrap_or(false) {
        return Some(format!(
            "{}, the frame file of the last backward sweep, is cut short (it does not end as a whole MCAP file); `clv inspect {}` counts its complete frames; {rewrite}",
            file.display(),
            file.display()
        ));
    }
    let mut info = crate::store::frames::StreamInfo::default();
    crate::store::frames::read_frames_with(&file, |i| {
        info = i;
        Ok(())
    }, |_| Ok(crate::store::frames::Flow::Stop))
    .ok()?;
    let why = crate::stage::backward::SweepFile { dir: dir.path.clone(), meta: meta?.clone(), options: Some(last.options.clone()) }.check(&info).err()?;
    Some(format!("{}, the frame file of the last backward sweep, is not its file: {why}; `clv analyze` reads it only by name; to write the sweep's own, {rewrite}", file.display()))
}

/// The run's checksummed records that exist and fail their check ([`crate::store::checked_json`]).
fn damaged_records(dir: &RunDir, meta: Option<&RunMeta>) -> Vec<String> {
    let run = dir.path.display();
    let records = [
        (dir.spectrum_path(), format!("`clv forward --resume {run}` rewrites it from the run's last checkpoint")),
        (dir.progress_path(), format!("the backward sweep it records cannot be resumed: delete it (and the sweep's FRAMES.mcap.tmp, if one is left; move a finished FRAMES.mcap aside), then `clv backward {run}` without --resume starts the sweep over")),
        (dir.clv_spectrum_path(), clv_spectrum_advice(dir)),
    ];
    // The CLV spectra of earlier sweeps kept beside it: a damaged one is reported only.
    let kept = dir.earlier_clv_spectra().into_iter().map(|p| (p, "the CLV spectrum of an earlier sweep, kept for reference: nothing recomputes it but that sweep again".to_string()));
    records
        .into_iter()
        .chain(kept)
        .filter_map(|(path, what_to_do)| {
            let e = crate::store::checked_json::read::<serde_json::Value>(&path).err().filter(|_| path.exists())?;
            Some(format!("{e}; {what_to_do}"))
        })
        .chain(frame_file_problem(dir, meta))
        .collect()
}

impl Inspection {
    pub fn text(&self) -> String {
        let mut s = String::new();
        let c = &self.run.config;
        let _ = writeln!(s, "run: {} (D = {}, k = {}), tau = {}, seed {}", serde_json::to_string(&c.system).unwrap_or_default(), c.system.dim(), c.vectors, c.tau, c.seed);
        let _ = writeln!(
            s,
            "steps: {} of {} ({}), checkpoint every {}, CLV window {} + transient {}",
            self.steps_done.map_or("none".into(), |x| x.to_string()),
            self.total_steps,
            match (self.finished, self.running, self.extension_interrupted) {
                (_, true, _) => "a clv process is writing it now",
                (true, false, _) => "finished",
                (false, false, true) => "an extension of it was interrupted: give the extension's command again, clv forward --resume RUN_DIR --steps M with its new length M (and its --clv-steps and --transient if it had them)",
                (false, false, false) => "not finished: clv forward --resume",
            },
            self.run.store.checkpoint_every,
            self.run.store.clv_steps,
            self.run.store.transient
        );
        let b = &self.run.build;
        let numerics = b.numerics.split(" (").next().unwrap_or_default();
        let _ = writeln!(
            s,
            "made by: clv {} ({numerics}) on {} with {}{}",
            b.clv_version,
            b.arch,
            if b.cpu_features.is_empty() { "no features listed".to_string() } else { format!("{} ({})", b.cpu_features.join(", "), b.simd_level()) },
            if self.not_here.is_some() { " (not this machine and build: see the note below)" } else { "" }
        );
        let _ = writeln!(s, "files: {} segments, {} checkpoints, {} on disk", self.segments.len(), self.checkpoints, human(self.disk_bytes));
        for seg in &self.segments {
            let state = seg.damage.as_deref().unwrap_or("intact");
            let plural = if seg.checkpoints == 1 { "" } else { "s" };
            let _ = writeln!(s, "  {}  steps {}..{}  {} checkpoint{plural}, {} R  {}  {state}", seg.file, seg.first_step, seg.last_step, seg.checkpoints, seg.r_matrices, human(seg.bytes));
        }
        let partial = if self.running { "being written" } else { "interrupted (discarded on --resume)" };
        for p in &self.partial_segments {
            let _ = writeln!(s, "  {p}  {partial}");
        }
        for name in &self.set_aside {
            let why = if name.ends_with(".corrupt") { "damaged or misnamed, set aside by a repair; not read, safe to delete" } else { "set aside by an interrupted repair; removed by the next --resume" };
            let _ = writeln!(s, "  {name}  {why}");
        }
        for name in &self.previous {
            let _ = writeln!(s, "  {name}/  the results of the run before it was extended");
        }
        if let Some(step) = self.steps_done.filter(|&s| s <= self.run.config.relax_steps) {
            let _ = writeln!(s, "relaxing: step {step} of the {} relaxation steps, no exponent accumulated yet", self.run.config.relax_steps);
        }
        if !self.exponents.is_empty() {
            // The whole run's numbers once it is finished, else those of the steps so far.
            let so_far = if self.finished { "" } else { " so far" };
            let show: Vec<String> = self.exponents.iter().take(4).map(|x| format!("{x:.5}")).collect();
            let last = match self.exponents.len() {
                k if k > 4 => format!(" ... lambda_k = {:.5}", self.exponents[k - 1]),
                _ => String::new(),
            };
            let _ = writeln!(s, "spectrum{so_far}: lambda_1.. = {}{last}", show.join(", "));
            let mut sums = Vec::new();
            if let Some(h) = crate::statistics::ks_entropy(&self.exponents, self.run.config.system.neutral()) {
                sums.push(format!("h_KS = {h:.5}"));
            }
            if let Some(d) = crate::statistics::kaplan_yorke_dimension(&self.exponents, self.run.config.system.dim()) {
                sums.push(format!("D_KY = {d:.5}"));
            }
            if !sums.is_empty() {
                let _ = writeln!(s, "{}: {}", if self.finished { "whole run" } else { "so far" }, sums.join(", "));
            }
            for w in &self.warnings {
                let _ = writeln!(s, "warning: {w}");
            }
            if let Some(c) = &self.convergence {
                let _ = writeln!(s, "convergence{so_far} ({} blocks of {} steps): {}; {}", c.blocks, c.block_steps, c.tests, c.verdict);
            }
        }
        if let Some(b) = &self.backward_sweep {
            let _ = writeln!(s, "backward sweep: {b}");
        }
        if let Some(r) = &self.r_not_stored {
            let _ = writeln!(s, "note: {r}");
        }
        if let Some(why) = &self.not_here {
            let _ = writeln!(
                s,
                "note: neither `clv forward --resume` nor the backward stage can run on this machine with this build ({why}): \
                 they reproduce the run's numbers bit for bit only with a build of its numerics on a CPU of its x86-64 level, with or without AVX-512 (on a cluster: nodes of that level)"
            );
        }
        if let Some(m) = &self.meta_mismatch {
            let _ = writeln!(s, "DAMAGE: {m}");
        }
        for m in self.damaged_records.iter().chain(&self.gaps) {
            let _ = writeln!(s, "DAMAGE: {m}");
        }
        let verdict = if self.intact {
            // Segments and records are read whole; a frame file, of up to terabytes, only
            // by its end.
            "all finished files intact (a frame file checked by its end: `clv inspect FILE.mcap` reads every frame)"
        } else if self.segments.iter().all(|s| s.damage.is_none()) {
            "DAMAGE FOUND outside the segments (see above)"
        } else {
            "DAMAGE FOUND (see above): `clv forward --resume` recomputes the damaged segments"
        };
        let _ = writeln!(s, "{verdict}");
        s
    }
}

/// What a frame file (written by `clv backward --out FILE`) holds.
#[derive(Debug, Serialize)]
pub struct FrameFileInspection {
    pub frames: u64,
    /// Steps of the oldest and newest frame.
    pub steps: Option<(u64, u64)>,
    /// Phase-space dimension D and number of vectors k.
    pub d: usize,
    pub k: usize,
    /// Frames that carry V_n (all but those `--vectors-every` skipped), and G_n.
    pub with_vectors: u64,
    pub with_gs: u64,
    /// Frames that carry their local GS exponents (none in files before 2026-11-25).
    pub with_gs_local: u64,
    /// The backward stage's options, as the stream records them (`backward.json`).
    pub backward: Option<serde_json::Value>,
    /// None if the file reads back whole, else where it ends or what is wrong.
    pub damage: Option<String>,
    /// The file is a sweep's FILE.tmp: written now, or left by an interrupted sweep, so an
    /// end inside a chunk is its expected state, not damage.
    pub unfinished: bool,
    /// The run directory the sweep belongs to, where the file's own record places it (a
    /// frame file inside the run records its path relative to it).
    pub run_dir: Option<std::path::PathBuf>,
}

/// Read a frame file whole (every CRC checked) and summarise it.
pub fn inspect_frames(path: &Path) -> Result<FrameFileInspection> {
    let unfinished = path.extension().is_some_and(|e| e == "tmp");
    let mut found = FrameFileInspection { frames: 0, steps: None, d: 0, k: 0, with_vectors: 0, with_gs: 0, with_gs_local: 0, backward: None, damage: None, unfinished, run_dir: None };
    let mut backward_json = None;
    let damage = crate::store::frames::read_frames_with(
        path,
        |info| {
            backward_json = info.backward_json;
            Ok(())
        },
        |f| {
            found.frames += 1;
            found.steps = Some(found.steps.map_or((f.step, f.step), |(lo, hi)| (lo.min(f.step), hi.max(f.step))));
            (found.d, found.k) = (f.d, f.k);
            found.with_vectors += u64::from(!f.v.is_empty());
            found.with_gs += u64::from(f.g.is_some());
            found.with_gs_local += u64::from(!f.gs_local.is_empty());
            Ok(crate::store::frames::Flow::Continue)
        },
    )?;
    if found.frames == 0 {
        return Err(crate::Error::Other(format!(
            "{} holds no frames{}: `clv inspect` reads a run directory or a frame file written by `clv backward --out FILE`",
            path.display(),
            damage.map(|d| format!(" ({d})")).unwrap_or_default()
        )));
    }
    found.backward = backward_json.and_then(|j| serde_json::from_str::<serde_json::Value>(&j).ok());
    found.damage = damage;
    let recorded = found.backward.as_ref().and_then(|b| b["frames_path"].as_str()).map(std::path::PathBuf::from);
    let file = if unfinished { path.with_extension("") } else { path.to_path_buf() };
    found.run_dir = recorded.and_then(|r| crate::store::frames::run_dir_of(&file, &r));
    Ok(found)
}

impl FrameFileInspection {
    pub fn text(&self) -> String {
        let mut s = String::new();
        let steps = self.steps.map_or("none".into(), |(lo, hi)| format!("{lo}..{hi}"));
        let _ = writeln!(s, "frame file: {} frames, steps {steps}, D = {}, k = {}", self.frames, self.d, self.k);
        let _ = writeln!(s, "covariant vectors V_n in {} frames, Gram-Schmidt vectors G_n in {}, local GS exponents in {}", self.with_vectors, self.with_gs, self.with_gs_local);
        if let Some(b) = &self.backward {
            let _ = writeln!(s, "backward options: {b}");
        }
        let state = match (&self.damage, self.unfinished) {
            (None, _) => "intact".to_string(),
            (Some(d), true) => format!("unfinished, as a sweep writing it now or one interrupted leaves it: {d}"),
            (Some(d), false) => format!("DAMAGED: {d}"),
        };
        let _ = writeln!(s, "{state}");
        s
    }
}
