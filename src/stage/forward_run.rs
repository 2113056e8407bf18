//! The forward stage as a long job: writes a run directory, survives being killed.
//!
//! A new run writes run.json, then a checkpoint at step 0 and one every `checkpoint_every`
//! steps, with R_n at checkpoints (and every step of the window with `--store-r all`) and
//! the running spectrum. A resumed run discards an interrupted `.tmp` segment, continues from
//! the last checkpoint of the newest intact segment, and writes exactly what the
//! uninterrupted run would have written.

use super::forward::Forward;
use crate::error::{Error, Result};
use crate::report::{SpectrumReport, Statistics};
use crate::store::records::{encode_r, Checkpoint, Stats};
use crate::store::run::{write_atomic, RunDir, RunLock, RunMeta, StoreR};
use crate::store::schema::{CHECKPOINT, R, STATS};
use crate::store::run::gap_between;
use crate::store::repair::{discard_partial_segments, staged_chain, UNVERIFIED, first_checkpoint, last_checkpoints, read_last, supersede_from, triage, Hole, Triage};
use crate::store::sink::{Policy, Sink};
use crate::system::Invariants;
use super::signals::StopOnSignals;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Largest relative energy drift a run may accumulate (round-off over 1e8 collisions is far
/// below it; anything larger means the dynamics went wrong).
pub const ENERGY_TOLERANCE: f64 = 1e-8;

/// Stop at step `n` if the energy drifted from `energy0` by more than [`ENERGY_TOLERANCE`]
/// (relative): the dynamics has lost its accuracy, and no number from it may be reported.
pub fn check_energy(n: u64, energy0: f64, energy: f64) -> Result<()> {
    // Maps and dissipative flows conserve no energy: their invariant is NaN.
    if !energy0.is_finite() {
        return Ok(());
    }
    let drift = ((energy - energy0) / energy0).abs();
    // A non-finite energy (a blown-up trajectory) is no accuracy either: NaN fails `<=`.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    let accurate = drift <= ENERGY_TOLERANCE;
    if !accurate {
        return Err(Error::Dynamics(format!(
            "step {n}: the energy drifted by {drift:.2e} (relative) from its start value {energy0}; \
             the dynamics has lost its accuracy, so the run stops here rather than report wrong numbers"
        )));
    }
    Ok(())
}

/// How a forward job ended.
pub struct Outcome {
    pub report: SpectrumReport,
    /// The step a resumed run continued from.
    pub resumed_from: Option<u64>,
    /// The run was complete before this call; nothing was done.
    pub already_finished: bool,
}

/// What a person sees: a progress bar, and notices printed beside it (with no bar the
/// run is quiet and notices are only collected).
#[derive(Default)]
pub struct Feedback {
    pub bar: Option<ProgressBar>,
    pub notices: Vec<String>,
}

impl Feedback {
    fn notice(&mut self, msg: String) {
        if let Some(bar) = &self.bar {
            bar.suspend(|| crate::note!("clv: {msg}"));
        }
        self.notices.push(msg);
    }
}

/// Start a new run in `path`.
pub fn create(path: &Path, meta: &RunMeta, feedback: &mut Feedback) -> Result<Outcome> {
    meta.config.validate()?;
    meta.store.validate(&meta.config)?;
    meta.config.build_system()?; // refuse impossible systems, or too big ones, before anything is written
    let (dir, _lock) = RunDir::create(path, meta, "forward pass")?;
    let fwd = Forward::new(&meta.config)?;
    let energy0 = fwd.system.invariants().energy;
    drive(&dir, meta, fwd, energy0, 0.0, true, feedback).map(|report| Outcome { report, resumed_from: None, already_finished: false })
}

/// Put run.json in place if the run's creation was cut short just before (see
/// [`RunDir::complete_creation`]); [`resume`] does this first.
pub fn complete_creation(path: &Path, feedback: &mut Feedback) -> Result<()> {
    if RunDir::complete_creation(path)? {
        feedback.notice(format!("the run in {} was interrupted while it was being created; its run.json is now in place", path.display()));
    }
    Ok(())
}

/// Continue an interrupted run in `path` (or report a finished one), on `threads` threads
/// if given, else on the run's (the numbers do not depend on it).
pub fn resume(path: &Path, threads: Option<usize>, feedback: &mut Feedback) -> Result<Outcome> {
    let (dir, mut meta, _lock) = open_to_continue(path, feedback)?;
    if let Some(longer) = interrupted_extension(&dir, &meta)? {
        write_atomic(&dir.meta_path(), &crate::store::checked_json::to_vec(&longer)?)?;
        feedback.notice(format!(
            "the extension of {} from {} to {} steps was interrupted after the results of the shorter run went to {}; it goes on",
            path.display(),
            meta.config.steps,
            longer.config.steps,
            dir.previous_results(meta.config.steps).display()
        ));
        meta = longer;
    }
    meta.config.set_threads(threads);
    continue_locked(&dir, &meta, feedback)
}

/// The run.json of an extension cut off after it moved the shorter run's results aside and
/// before its new run.json was in place ([`extend`]): read from run.tmp when that was written
/// whole. Without it, finishing the run at its old length would write a spectrum.json beside
/// the one moved aside, and the extension would then be refused; so the extension's command
/// is asked for instead.
fn interrupted_extension(dir: &RunDir, meta: &RunMeta) -> Result<Option<RunMeta>> {
    if !dir.extension_interrupted(meta.config.steps) {
        return Ok(None);
    }
    let kept = dir.previous_results(meta.config.steps);
    let tmp = dir.path.join("run.tmp");
    let same_run = |m: &RunMeta| m.config.steps > meta.config.steps && crate::config::RunConfig { steps: meta.config.steps, ..m.config.clone() }.same_but_threads(&meta.config);
    let longer = std::fs::read(&tmp).ok().and_then(|bytes| crate::store::checked_json::from_slice::<RunMeta>(&tmp, &bytes).ok()).map(|(m, _)| m).filter(same_run);
    match longer {
        Some(longer) => Ok(Some(longer)),
        None => Err(Error::Other(format!(
            "an extension of the run in {} was interrupted: the results of its {} steps are already in {}; give the extension's command again \
             (`clv forward --resume {} --steps M` with its new length M, and its --clv-steps and --transient if it had them)",
            dir.path.display(),
            meta.config.steps,
            kept.display(),
            dir.path.display()
        ))),
    }
}

/// The run in `path`, locked for the forward pass, once it is sure this build can continue
/// it and its run.json still describes its segments.
fn open_to_continue(path: &Path, feedback: &mut Feedback) -> Result<(RunDir, RunMeta, RunLock)> {
    complete_creation(path, feedback)?;
    let (dir, meta) = RunDir::open(path)?;
    let lock = dir.lock("forward pass")?;
    meta.build.check_can_continue(path)?;
    dir.check_meta(&meta)?;
    check_bits_here(&dir, &meta, feedback)?;
    Ok((dir, meta, lock))
}

/// On a CPU whose features differ from those the run was made on, though not in a way that
/// should change the bits ([`crate::store::run::BuildInfo::simd_level`]: with or without
/// AVX-512), recompute the newest segment's last checkpoint interval first and refuse if it
/// differs in any bit, before anything is written: a continuation of other bits would make
/// a run that no machine can verify. Costs one interval, only there. A segment that cannot
/// be read is left to the repair that follows.
fn check_bits_here(dir: &RunDir, meta: &RunMeta, feedback: &mut Feedback) -> Result<()> {
    let here = crate::store::run::BuildInfo::current();
    if meta.build.same_cpu_features(&here) {
        return Ok(());
    }
    let Some(newest) = dir.segments()?.pop() else { return Ok(()) };
    match last_interval_difference(dir, meta, &newest.path) {
        Ok(Some(None)) => {
            feedback.notice(format!(
                "this machine's CPU ({}) is not the one the run was made on ({}); its last checkpoint interval, recomputed here, matches bit for bit",
                here.cpu_features.join(", "),
                meta.build.cpu_features.join(", ")
            ));
            Ok(())
        }
        Ok(Some(Some(why))) => Err(Error::Dynamics(format!(
            "{}: this machine's CPU ({}) is not the one the run was made on ({}), and it does not reproduce the run's last checkpoint interval in {} bit for bit ({why}); \
             continuing here would make a run no machine can verify: continue it on a machine like the one that made it",
            dir.path.display(),
            here.cpu_features.join(", "),
            meta.build.cpu_features.join(", "),
            newest.path.display()
        ))),
        _ => Ok(()),
    }
}

/// A run made longer: `steps` accumulated steps in all, a CLV window of `clv_steps` plus
/// `transient` at its new end (by default the window the run had).
#[derive(Clone, Copy, Debug, Default)]
pub struct Extension {
    pub steps: u64,
    pub clv_steps: Option<u64>,
    pub transient: Option<u64>,
}

/// Continue the run in `path` past the length it was made for, finished or not. The
/// trajectory, G_n and the exponent sums are those of a run made that long from the start,
/// bit for bit; only the blocks of the standard error differ (they double in length as the
/// run outgrows them, [`crate::statistics::Accumulator::limit_blocks`]). What was
/// computed for the shorter run and no longer describes this one (spectrum.json, and the
/// covariant vectors of the old window: clv_spectrum.json, backward.json, frames.mcap) is
/// moved into `path/previous-STEPS-steps/`, never overwritten, and so are the files or
/// directories in `also` (a report made from them, say) and the clv reports kept inside the
/// run (`clv analyze RUN --out RUN/report`).
pub fn extend(path: &Path, ext: Extension, threads: Option<usize>, also: &[&Path], feedback: &mut Feedback) -> Result<Outcome> {
    let (dir, mut meta, _lock) = open_to_continue(path, feedback)?;
    let old = meta.clone();
    if ext.steps < old.config.steps {
        return Err(Error::param("steps", format!(
            "{} is fewer than the {} steps the run in {} was made for; a run can be made longer, not shorter (the backward stage can use a shorter window: see --clv-steps)",
            ext.steps,
            old.config.steps,
            path.display()
        )));
    }
    meta.config.steps = ext.steps;
    meta.store.clv_steps = ext.clv_steps.unwrap_or(old.store.clv_steps);
    meta.store.transient = ext.transient.unwrap_or(old.store.transient);
    if meta.config.steps == old.config.steps {
        if meta != old {
            return Err(Error::param("clv-steps", format!(
                "the CLV window of the run in {} ({} + transient {} steps) can change only together with a longer --steps",
                path.display(),
                old.store.clv_steps,
                old.store.transient
            )));
        }
        meta.config.set_threads(threads);
        return continue_locked(&dir, &meta, feedback);
    }
    meta.store.validate(&meta.config)?;
    let (start, c) = (meta.store.window_start(&meta.config), meta.store.checkpoint_every);
    if let Some(oldest) = dir.segments()?.first().filter(|s| s.first > start / c * c) {
        return Err(Error::param("clv-steps", format!(
            "the CLV window plus transient ({} + {} steps) would start at step {start}, but the run keeps its steps only from {} on ({}); choose a shorter window",
            meta.store.clv_steps,
            meta.store.transient,
            oldest.first,
            oldest.path.display()
        )));
    }
    // The last sweep's frame file (or the .tmp of one interrupted) under another name: with
    // the rest inside the run directory; outside it, where it is, said.
    let mut with_sweep: Vec<PathBuf> = also.iter().map(|p| p.to_path_buf()).collect();
    if let Some(sweep) = crate::store::progress::last_sweep(path).ok().flatten()
        && let Some(file) = sweep.options.frames_file(path)
    {
        let tmp = crate::store::frames::tmp_path(&file);
        if sweep.options.frames_path.as_ref().is_some_and(|p| p.is_relative()) {
            // A killed sweep's lock file: stale, since no sweep runs while the run is locked.
            let _ = std::fs::remove_file(crate::store::frames::lock_path(&file));
            with_sweep.extend([file, tmp]);
        } else if file.exists() || tmp.exists() {
            let which = if sweep.done { &file } else { &tmp };
            feedback.notice(format!(
                "{} holds frames of the {}-step run (its last backward sweep); outside the run directory, it stays where it is, and a new sweep into {} needs it moved aside first",
                which.display(),
                old.config.steps,
                file.display()
            ));
        }
    }
    let inside = std::fs::read_dir(path).map_err(|e| Error::io(path, e))?.flatten().filter(|e| !RunDir::is_previous_results(&e.file_name())).map(|e| e.path());
    with_sweep.extend(inside.filter(|p| p.is_dir() && is_report(p)));
    let with_sweep: Vec<&Path> = with_sweep.iter().map(PathBuf::as_path).collect();
    // A report is moved under its lock: one being written now is refused, not torn.
    let report_locks = with_sweep.iter().filter(|p| is_report(p)).map(|p| crate::report::dir::lock_report(p)).collect::<Result<Vec<_>>>()?;
    let kept = dir.archive_results(&dir.previous_results(old.config.steps), &with_sweep)?;
    drop(report_locks);
    write_atomic(&dir.meta_path(), &crate::store::checked_json::to_vec(&meta)?)?;
    let mut msg = format!(
        "extending {} from {} to {} steps (CLV window {} + transient {} at the new end)",
        path.display(),
        old.config.steps,
        meta.config.steps,
        meta.store.clv_steps,
        meta.store.transient
    );
    if let Some(kept) = kept {
        msg += &format!("; the results of the {}-step run are kept in {}", old.config.steps, kept.display());
    }
    feedback.notice(msg);
    meta.config.set_threads(threads);
    continue_locked(&dir, &meta, feedback)
}

fn is_report(dir: &Path) -> bool {
    matches!(crate::report::dir::report_in(dir), crate::report::dir::ReportDir::Report { .. })
}

/// [`resume`] once the run's lock is held and `meta` is what run.json says.
fn continue_locked(dir: &RunDir, meta: &RunMeta, feedback: &mut Feedback) -> Result<Outcome> {
    let path = dir.path.as_path();
    // One guard for the whole resume: a signal between its drives is not lost.
    let _signals = StopOnSignals::install();
    discard_partial_segments(dir, &mut |msg| feedback.notice(msg))?;
    let Triage { holes, mut newest_intact, mut superseded, set_aside } = triage(dir, &meta.store, &meta.config, &mut |msg| feedback.notice(msg))?;
    for hole in &holes {
        if let Some(aside) = fill(dir, meta, hole, feedback)? {
            // The segments from the hole's next one on were set aside: the run is recomputed
            // from the end of the hole on, as a run damaged at its end would be.
            superseded.extend(aside);
            let newest = dir.segments()?.pop().ok_or_else(|| Error::Other(format!("the segments recomputed before {} are gone", hole.next.path.display())))?;
            newest_intact = Some(read_last(&newest.path)?.1);
            break;
        }
    }
    let staging = dir.path.join(UNVERIFIED);
    if staging.is_dir() {
        feedback.notice(format!("discarding {}: no repair is due any more", staging.display()));
        std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
    }
    let drop_superseded = || -> Result<()> {
        for aside in &superseded {
            std::fs::remove_file(aside).map_err(|e| Error::io(aside, e))?;
        }
        Ok(())
    };
    let recomputed = |report: SpectrumReport, from: u64| -> Result<Outcome> {
        drop_superseded()?;
        Ok(Outcome { report, resumed_from: Some(from), already_finished: false })
    };
    let total = meta.config.relax_steps + meta.config.steps;
    let Some(last) = newest_intact else {
        // Where triage set segments aside it has said why.
        let why = if superseded.is_empty() { "no intact checkpoint found; " } else { "" };
        feedback.notice(format!("{why}starting the run over from step 0"));
        let fwd = Forward::new(&meta.config)?;
        let energy0 = fwd.system.invariants().energy;
        return recomputed(drive(dir, meta, fwd, energy0, 0.0, true, feedback)?, 0);
    };
    let step = last.checkpoint.state.step;
    let fwd = Forward::resume(&meta.config, &last.checkpoint.state)?;
    if step >= total {
        let report = report_of(meta, &fwd, last.stats.energy_initial, last.stats.wall_seconds);
        let spectrum = dir.spectrum_path();
        // A write of it that was killed before its rename (rewritten whole below if needed).
        let _ = std::fs::remove_file(spectrum.with_extension("tmp"));
        let written = !spectrum.exists() || crate::report::SpectrumSummary::read(&spectrum).is_err();
        if !spectrum.exists() {
            // Killed after its last segment was finished, before the spectrum was written.
            feedback.notice(format!("the run was complete but {} was not written yet; writing it", spectrum.display()));
            write_spectrum(dir, &report)?;
        } else if let Err(e) = crate::report::SpectrumSummary::read(&spectrum) {
            // The spectrum is the last checkpoint's sums divided out: rewritten exactly, with
            // the damaged file kept aside for whoever wants to see what happened to it.
            let aside = spectrum.with_extension("json.damaged");
            std::fs::rename(&spectrum, &aside).map_err(|e| Error::io(&spectrum, e))?;
            feedback.notice(format!("{e}; rewrote it from the run's last checkpoint (the damaged file is kept as {})", aside.display()));
            write_spectrum(dir, &report)?;
        }
        let already_finished = holes.is_empty() && superseded.is_empty() && set_aside == 0 && !written;
        drop_superseded()?;
        return Ok(Outcome { report, resumed_from: Some(step), already_finished });
    }
    feedback.notice(format!("resuming {} at step {step} of {total}", path.display()));
    recomputed(drive(dir, meta, fwd, last.stats.energy_initial, last.stats.wall_seconds, false, feedback)?, step)
}

/// Recompute the steps of `hole` from the checkpoint before it, writing them as the run
/// wrote them but into [`UNVERIFIED`] (going on from what a stopped repair left there),
/// and go on (writing nothing) to the first checkpoint of the segment after it. Where the
/// recomputation arrives there bit for bit, or the checkpoint it started from is shown to
/// follow from the one before it (then the segments from the next one on are the odd ones
/// out: they are set aside first, and where they are kept is returned), its segments are
/// moved into the run; else they are discarded and the resume stops, with nothing after
/// the hole changed.
fn fill(dir: &RunDir, meta: &RunMeta, hole: &Hole, feedback: &mut Feedback) -> Result<Option<Vec<PathBuf>>> {
    let c = meta.store.checkpoint_every.max(1);
    let staging = dir.path.join(UNVERIFIED);
    let want = first_checkpoint(&hole.next.path)?.state;
    let next = hole.next.path.display();
    let why = match hole.after {
        Some(_) => "no intact segment holds the steps between".to_string(),
        None => format!("the backward stage needs the checkpoints from step {} on, no segment holds them, and there is none before them", meta.store.first_needed_checkpoint(&meta.config)),
    };
    let staged = staged_chain(&staging, hole, c, &mut |msg| feedback.notice(msg))?;
    let start = match staged {
        Some((_, last)) => Some(last),
        None => hole.after.as_ref().map(|a| read_last(&a.path).map(|(_, last)| last)).transpose()?,
    };
    let fresh = start.is_none();
    let (fwd, energy0, wall0) = match start {
        Some(last) => (Forward::resume(&meta.config, &last.checkpoint.state)?, last.stats.energy_initial, last.stats.wall_seconds),
        None => {
            let fwd = Forward::new(&meta.config)?;
            let energy0 = fwd.system.invariants().energy;
            (fwd, energy0, 0.0)
        }
    };
    let from = hole.after.as_ref().map_or(0, |a| a.last);
    let so_far = if fwd.step > from { format!(", going on from step {} where a stopped repair left it in {}", fwd.step, staging.display()) } else { String::new() };
    feedback.notice(format!("recomputing steps {from}..{} ({why}), to arrive at the first checkpoint of {next}{so_far}", want.step));
    std::fs::create_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
    let mut fwd = if fwd.step < hole.until || fresh {
        let span = Span { energy0, wall0, write_first: fresh, until: hole.until, into: staging.clone() };
        drive_to(dir, meta, fwd, &span, feedback)?
    } else {
        fwd
    };
    let signals = StopOnSignals::install();
    while fwd.step < want.step {
        if let Some(signal) = signals.requested() {
            let then = format!("the recomputation is kept in {} and checked when `clv forward --resume {}` goes on", staging.display(), dir.path.display());
            return Err(Error::Stopped { step: fwd.step, total: meta.config.relax_steps + meta.config.steps, run: dir.path.clone(), signal, then });
        }
        fwd.step()?;
    }
    let got = fwd.state();
    let differs = (got != want).then(|| want.first_difference(&got));
    if let (Some(why), Some(after)) = (&differs, &hole.after)
        && let Some(also) = follows_from_the_one_before(dir, meta, &after.path)?
    {
        std::fs::remove_dir_all(&staging).map_err(|e| Error::io(&staging, e))?;
        return Err(Error::Dynamics(format!(
            "the steps recomputed from the last checkpoint of {} do not arrive at the first checkpoint of {next} ({why}), and {also}: \
             one of the two files was altered or written by another build, and clv cannot tell which. \
             Nothing was changed; move the file you do not trust out of {} and resume again",
            after.path.display(),
            dir.path.display()
        )));
    }
    // Set aside before the new files go in: killed in between, the next resume finds no
    // segment after them to arrive at, and continues the run from them.
    let aside = match &differs {
        Some(why) => {
            feedback.notice(format!("the recomputed steps do not arrive at the first checkpoint of {next} ({why}); the segments from there on are recomputed too"));
            let aside = supersede_from(dir, &hole.next, &mut |msg| feedback.notice(msg))?;
            crate::store::fault::crash_point("repair-set-aside");
            Some(aside)
        }
        None => None,
    };
    let mut staged: Vec<PathBuf> = std::fs::read_dir(&staging).map_err(|e| Error::io(&staging, e))?.filter_map(|e| e.ok().map(|e| e.path())).collect();
    staged.sort();
    for path in staged {
        let to = dir.path.join(path.file_name().unwrap_or_default());
        std::fs::rename(&path, &to).map_err(|e| Error::io(&to, e))?;
    }
    crate::store::segment::sync_dir(&dir.path)?;
    std::fs::remove_dir(&staging).map_err(|e| Error::io(&staging, e))?;
    crate::store::sink::prune(&dir.path, meta.store.first_needed_checkpoint(&meta.config), meta.store.keep_segments)?;
    Ok(aside)
}

/// Where the last checkpoint of the segment `path` does not follow from the checkpoint
/// before it (in the segment, or the last of the segment before it), why, in words.
fn follows_from_the_one_before(dir: &RunDir, meta: &RunMeta, path: &Path) -> Result<Option<String>> {
    Ok(match last_interval_difference(dir, meta, path)? {
        None => Some("whether that checkpoint is right cannot be checked (no checkpoint just before it is kept)".into()),
        Some(difference) => difference.map(|d| format!("that checkpoint does not follow from the one before it either ({d})")),
    })
}

/// The last checkpoint of the segment `path` recomputed from the one before it: None where
/// no checkpoint just before it is kept, else how the two differ (None if in no bit).
fn last_interval_difference(dir: &RunDir, meta: &RunMeta, path: &Path) -> Result<Option<Option<String>>> {
    let mut checkpoints = last_checkpoints(path)?;
    if checkpoints.len() < 2 {
        let c = meta.store.checkpoint_every;
        let first = checkpoints.first().map_or(0, |cp| cp.state.step);
        // Not checked for a gap of R_n alone: only the checkpoints matter here.
        let before = dir.segments()?.into_iter().rfind(|s| s.last < first && !gap_between(s.last, first, c, None));
        match before {
            Some(seg) => checkpoints.insert(0, read_last(&seg.path)?.1.checkpoint),
            None => return Ok(None),
        }
    }
    let (before, last) = (&checkpoints[checkpoints.len() - 2], &checkpoints[checkpoints.len() - 1]);
    let mut fwd = Forward::resume(&meta.config, &before.state)?;
    while fwd.step < last.state.step {
        fwd.step()?;
    }
    let got = fwd.state();
    Ok(Some((got != last.state).then(|| last.state.first_difference(&got))))
}

fn report_of(meta: &RunMeta, fwd: &Forward, energy0: f64, wall: f64) -> SpectrumReport {
    let start = Invariants { energy: energy0, ..Default::default() };
    SpectrumReport::new(meta.config.clone(), &fwd.acc, Statistics::new(&meta.config, &start, &fwd.system.invariants(), wall))
}

fn drive(dir: &RunDir, meta: &RunMeta, fwd: Forward, energy0: f64, wall0: f64, write_first: bool, feedback: &mut Feedback) -> Result<SpectrumReport> {
    let started = Instant::now();
    let total = meta.config.relax_steps + meta.config.steps;
    let span = Span { energy0, wall0, write_first, until: total, into: dir.path.clone() };
    let fwd = drive_to(dir, meta, fwd, &span, feedback)?;
    crate::store::fault::crash_point("forward-done");
    let report = report_of(meta, &fwd, energy0, wall0 + started.elapsed().as_secs_f64());
    write_spectrum(dir, &report)?;
    Ok(report)
}

/// What a drive of the forward pass writes, and where.
struct Span {
    /// The energy at step 0, which the run's energy must keep.
    energy0: f64,
    /// Wall seconds the run took before this drive.
    wall0: f64,
    /// Write the checkpoint the drive starts from too (step 0 of a new run).
    write_first: bool,
    /// The step the drive ends at.
    until: u64,
    /// The directory the segments go to: the run's, or a repair's before it is verified.
    into: PathBuf,
}

/// Advance `fwd` to step `span.until`, writing what the run keeps of every step, and close
/// the segment there: at a checkpoint of its own where `until` is not one of the grid's (as
/// a stop on a signal does).
fn drive_to(dir: &RunDir, meta: &RunMeta, mut fwd: Forward, span: &Span, feedback: &mut Feedback) -> Result<Forward> {
    let Span { energy0, wall0, write_first, until, .. } = *span;
    let (config, store) = (&meta.config, &meta.store);
    let total = config.relax_steps + config.steps;
    let window = store.window_start(config);
    let policy = Policy {
        segment_checkpoints: store.segment_checkpoints,
        segment_bytes: store.segment_bytes,
        total_steps: total,
        prune_before: store.first_needed_checkpoint(config),
        keep_segments: store.keep_segments,
    };
    let mut sink = Sink::spawn(span.into.clone(), RunDir::meta_json(meta), policy)?;
    let started = Instant::now();
    let (d, k) = (fwd.system.dim(), config.vectors);
    let checkpoint = |fwd: &Forward, sink: &mut Sink| -> Result<()> {
        let n = fwd.step;
        let inv = fwd.system.invariants();
        check_energy(n, energy0, inv.energy)?;
        let stats = Stats {
            step: n,
            time: fwd.time(),
            exponents: fwd.acc.exponents(config.tau),
            stderr: fwd.acc.stderr(config.tau),
            energy: inv.energy,
            energy_initial: energy0,
            momentum: inv.momentum,
            collisions: inv.events,
            wall_seconds: wall0 + started.elapsed().as_secs_f64(),
        };
        sink.send(STATS.topic, n, stats.encode())?;
        let cp = Checkpoint { state: fwd.state(), time: fwd.time(), system: fwd.system.name().into(), d, k };
        sink.send(CHECKPOINT.topic, n, cp.encode())
    };
    if write_first {
        checkpoint(&fwd, &mut sink)?;
    }
    let signals = StopOnSignals::install();
    if let Some(bar) = &feedback.bar {
        bar.set_length(total);
        bar.set_position(fwd.step);
        // The rate is that of this drive's steps (a repair's drives start where they must).
        bar.reset_eta();
    }
    while fwd.step < until {
        fwd.step().map_err(|e| match e {
            Error::Param { name: "tau", msg } => Error::param(
                "tau",
                format!(
                    "{msg}. The run in {} keeps its steps before this one, but cannot pass it with its settings (--resume meets the same step): \
                     to start again with other settings, move {} aside or delete it",
                    dir.path.display(),
                    dir.path.display()
                ),
            ),
            e => e,
        })?;
        let n = fwd.step;
        if let Some(warning) = fwd.early_precision_warning(config.steps) {
            feedback.notice(format!("warning: {warning}"));
        }
        let is_cp = store.is_checkpoint(n, total);
        let r_sent = is_cp || (store.store_r == StoreR::All && n > window);
        if r_sent {
            sink.send(R.topic, n, encode_r(n, &fwd.r))?;
        }
        if is_cp {
            checkpoint(&fwd, &mut sink)?;
        }
        if let Some(bar) = &feedback.bar {
            bar.set_position(n);
        }
        if let Some(signal) = signals.requested().filter(|_| n < total) {
            // A checkpoint of its own here, with its R unless that went out above (an outside
            // reader of --store-r all would see it twice).
            if !is_cp {
                if !r_sent {
                    sink.send(R.topic, n, encode_r(n, &fwd.r))?;
                }
                checkpoint(&fwd, &mut sink)?;
            }
            sink.close_at_checkpoint()?;
            let then = format!("continue with `clv forward --resume {}`", dir.path.display());
            return Err(Error::Stopped { step: n, total, run: dir.path.clone(), signal, then });
        }
    }
    if fwd.step < total && !store.is_checkpoint(fwd.step, total) {
        let n = fwd.step;
        if !(store.store_r == StoreR::All && n > window) {
            sink.send(R.topic, n, encode_r(n, &fwd.r))?;
        }
        checkpoint(&fwd, &mut sink)?;
    }
    if fwd.step < total {
        sink.close_at_checkpoint()?;
    } else {
        sink.close()?;
    }
    Ok(fwd)
}

/// RUN_DIR/spectrum.json: the spectrum of a finished run, written last.
fn write_spectrum(dir: &RunDir, report: &SpectrumReport) -> Result<()> {
    write_atomic(&dir.spectrum_path(), &crate::store::checked_json::to_vec(report)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_energy_drift_beyond_the_tolerance_stops_the_run_naming_the_step() {
        assert!(check_energy(100, 16.0, 16.0 * (1.0 + 0.5 * ENERGY_TOLERANCE)).is_ok());
        assert!(check_energy(100, 16.0, f64::NAN).is_err() && check_energy(100, 16.0, f64::INFINITY).is_err(), "a blown-up trajectory stops the run");
        assert!(check_energy(100, f64::NAN, 3.0).is_ok(), "a map has no energy to conserve");
        let err = check_energy(300, 16.0, 16.0 * (1.0 + 2.0 * ENERGY_TOLERANCE)).unwrap_err().to_string();
        assert!(err.contains("step 300") && err.contains("energy drifted"), "{err}");
    }
}
