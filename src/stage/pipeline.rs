//! `clv run`: forward, backward and every analysis in one process, on an embedded preset
//! or a configuration file.
//!
//! The frames go straight from the backward sweep to the analyses over channels (nothing
//! but the run directory is written in between), so the whole pipeline runs in the memory
//! of the backward stage's two segments and the analyses' queues of frames. A killed `clv run` resumes its forward pass when started again.

use super::analyze::{registry, Analyzer, Context, Produced};
use super::backward::{self, BackwardOptions};
use super::forward_run::{self, Feedback};
use crate::config::RunConfig;
use crate::error::{Error, Result};
use crate::store::frames::Flow;
use crate::store::run::{BuildInfo, RunMeta, StoreConfig, FORMAT};
use crate::store::RunDir;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub struct PipelineResult {
    pub run_dir: PathBuf,
    pub report_dir: PathBuf,
    pub produced: Vec<Produced>,
    pub clv: backward::BackwardReport,
}

/// Run the configuration with these store settings into `out`: `out/run` (the run
/// directory) and `out/report` (index.html, figures, tables).
pub fn run(config: &RunConfig, store: &StoreConfig, out: &Path, feedback: &mut Feedback, say: &mut dyn FnMut(String)) -> Result<PipelineResult> {
    let run_dir = out.join("run");
    let report_dir = out.join("report");
    if store.clv_steps == 0 {
        return Err(Error::param(
            "clv-steps",
            "0 keeps no window of the run for covariant vectors, and `clv run` computes them and analyses them: give at least 1, or leave it out \
             for the default (a tenth of --relax-steps + --steps, at most 2/3 of --steps); for the Gram-Schmidt spectrum alone, `clv forward --clv-steps 0` runs the forward stage only"
                .to_string(),
        ));
    }
    if out.join("run.json").exists() {
        return Err(Error::param(
            "out",
            format!(
                "{} is a run directory (it holds run.json); `clv run` would put a second run and its report inside it (run/ and report/): \
                 give --out a directory of its own (a new one, or the one that holds run/ and report/ of a `clv run`); \
                 this run is continued with `clv forward --resume {}` and analysed with `clv backward {} --out - | clv analyze - --out REPORT`",
                out.display(),
                out.display(),
                out.display()
            ),
        ));
    }
    for (dir, what) in [(&run_dir, "the run"), (&report_dir, "the report")] {
        if dir.exists() && !dir.is_dir() {
            return Err(Error::param("out", format!("{} is a file, where `clv run` keeps {what} (OUT/run and OUT/report are its directories): move it, or give another --out", dir.display())));
        }
        if !dir.exists() && dir.symlink_metadata().is_ok() {
            return Err(Error::param("out", format!("{} is a symbolic link to nothing, where `clv run` keeps {what}: remove it (or make its target), or give another --out", dir.display())));
        }
    }
    let stored = match run_dir.join("run.json").exists() {
        true => Some(RunDir::open(&run_dir)?.1),
        false => None,
    };
    if let Some(steps) = check_report(&report_dir, &run_dir, stored.as_ref())? {
        // The run was made longer since (`clv forward --resume --steps`): its report of
        // then is kept beside the results of that length, as `clv run` keeps them itself.
        let kept = RunDir { path: run_dir.clone() }.previous_results(steps).join("report");
        if kept.exists() {
            return Err(Error::param("out", format!(
                "{} holds the report of the run in {} as it was with {steps} steps, and {} exists already; move one of them, then give the command again",
                report_dir.display(),
                run_dir.display(),
                kept.display()
            )));
        }
        say(format!("the report in {} is of the run as it was with {steps} steps: kept as {}", report_dir.display(), kept.display()));
        if let Some(parent) = kept.parent() {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        std::fs::rename(&report_dir, &kept).map_err(|e| Error::io(&report_dir, e))?;
    }
    if let Some(stored) = stored {
        if let Some(ext) = extension(&stored, config, store) {
            say(format!("extending the run in {} from {} to {} steps", run_dir.display(), stored.config.steps, config.steps));
            forward_run::extend(&run_dir, ext, Some(config.threads), &[&report_dir], feedback)?;
        } else if !stored.config.same_but_threads(config) || stored.store != *store {
            // The threads are the process's, not the run's: the numbers do not depend on them.
            // The way out first: after `clv run`, `clv run --preset lorenz` differs in 17 settings.
            let differ = crate::store::run::differences((&stored.config, &stored.store, "in the run"), (config, store, "asked for"));
            let example = match crate::store::run::flag_values(config, store).into_iter().find(|(id, _)| *id == "system") {
                Some((_, system)) if differ.iter().any(|d| d.starts_with("--system ")) => format!(" (e.g. --out {}-{system})", out.display()),
                _ => String::new(),
            };
            let shown = crate::store::run::differences_summary(differ);
            return Err(Error::param(
                "out",
                format!(
                    "{} holds a run of another configuration ({shown}): give this one another --out{example}, or ask for that run's configuration to continue it (or for more --steps to extend it)",
                    run_dir.display()
                ),
            ));
        } else {
            say(format!("continuing the run in {}", run_dir.display()));
            forward_run::resume(&run_dir, Some(config.threads), feedback)?;
        }
    } else {
        let meta = RunMeta { format: FORMAT.into(), config: config.clone(), store: store.clone(), build: BuildInfo::current() };
        say(format!("forward pass into {} ({})", run_dir.display(), meta.store.footprint(config)));
        // On top of the run: the report (about 2 MB of figures and tables) and the backward
        // stage's progress record (C as hex, two copies while it is replaced).
        let k = config.vectors as u64;
        let beside = (2 << 20) + 2 * 16 * (k * (k + 1) / 2);
        if let Some(warning) = crate::store::run::short_of_space(&run_dir, meta.store.footprint(config).bytes + beside) {
            crate::note!("clv run: {warning}");
        }
        forward_run::create(&run_dir, &meta, feedback)?;
    }
    let (dir, meta) = RunDir::open(&run_dir)?;
    // Taken after the forward pass, which may move an earlier report aside (extend).
    let _report_lock = crate::report::dir::lock_report(&report_dir)?;
    let mut opts = BackwardOptions::for_run(&meta);
    opts.with_gs = true;
    opts.save_every = 0;
    opts.vectors_every = super::analyze::vectors_every_for(&meta);
    let info = backward::stream_info(&dir, &meta, &opts);
    say("backward pass and analyses".into());
    let mut analyzer: Option<Analyzer> = None;
    let source = format!("clv run, in-process stream of {}", run_dir.display());
    let mut consumer = |frame: Arc<super::frame::Frame>| -> Result<Flow> {
        if analyzer.is_none() {
            let ctx = Context::new(&info, &frame, &source, None, None, None)?;
            let analyses = registry(&ctx);
            analyzer = Some(Analyzer::start(ctx, analyses, &report_dir)?);
        }
        analyzer.as_mut().expect("started").feed(frame)
    };
    let bar = feedback.bar.clone();
    if let Some(bar) = &bar {
        bar.set_length(meta.store.clv_steps + meta.store.transient);
        bar.set_position(0);
        bar.set_message("backward + analyses");
    }
    let mut on_progress = |recomputed: u64, _frames: u64| {
        if let Some(bar) = &bar {
            bar.set_position(recomputed);
        }
    };
    let clv = backward::run(&run_dir, &opts, false, 4096 << 20, Some(config.threads), &mut consumer, &mut on_progress)?;
    let produced = match analyzer {
        Some(a) => a.finish(None)?.produced,
        None => Vec::new(),
    };
    Ok(PipelineResult { run_dir, report_dir, produced, clv })
}

/// Refuse, before anything is computed, to write the report into `report_dir` over files
/// that are not a report of the run in `run_dir` (`stored`; None: there is none yet, the
/// run is new): a report can be all that is left of a long run. A report of this run,
/// finished or killed midway (`clv run` given again after an interruption), is written anew;
/// a finished one of this run with fewer steps (made longer since by `clv forward --resume
/// --steps`) is the run's earlier result: its step count is returned, for keeping it.
fn check_report(report_dir: &Path, run_dir: &Path, stored: Option<&RunMeta>) -> Result<Option<u64>> {
    use crate::report::dir::{report_in, ReportDir};
    let found = report_in(report_dir);
    let what = match (&found, stored) {
        (ReportDir::Empty, _) => return Ok(None),
        (ReportDir::Report { run: Some(run), .. }, Some(stored)) if run.same_but_threads(&stored.config) => return Ok(None),
        // Of this run before it was made longer.
        (ReportDir::Report { run: Some(run), finished: true }, Some(stored)) if run.steps < stored.config.steps && RunConfig { steps: stored.config.steps, ..run.clone() }.same_but_threads(&stored.config) => {
            return Ok(Some(run.steps));
        }
        // Killed midway by a build whose incomplete page named no run: its files are partial.
        (ReportDir::Report { run: None, finished: false }, Some(_)) => return Ok(None),
        (ReportDir::Report { .. }, None) => format!("a report, but {} holds no run (a new run starts there): the report is of another run", run_dir.display()),
        (ReportDir::Report { run: Some(run), .. }, Some(stored)) => format!(
            "the report of another run than the one in {} ({})",
            run_dir.display(),
            crate::store::run::differences((run, &stored.store, "in the report"), (&stored.config, &stored.store, "in the run")).join(", ")
        ),
        (ReportDir::Report { run: None, .. }, Some(_)) => format!("a report that names no run, not one of the run in {}", run_dir.display()),
        (ReportDir::Other, _) => "files that are not a report of clv (no index.html of one)".to_string(),
    };
    Err(Error::param(
        "out",
        format!(
            "{} already holds {what}, and `clv run` would write its report over it; choose another --out, or move or delete {} first",
            report_dir.display(),
            report_dir.display()
        ),
    ))
}

/// The extension that turns the stored run into the one asked for, if that is one: the same
/// system and settings with more steps, and the same store up to the CLV window.
fn extension(stored: &RunMeta, config: &RunConfig, store: &StoreConfig) -> Option<forward_run::Extension> {
    let longer = RunConfig { steps: config.steps, ..stored.config.clone() };
    let rewindowed = StoreConfig { clv_steps: store.clv_steps, transient: store.transient, ..stored.store.clone() };
    (config.steps > stored.config.steps && longer.same_but_threads(config) && rewindowed == *store)
        .then_some(forward_run::Extension { steps: config.steps, clv_steps: Some(store.clv_steps), transient: Some(store.transient) })
}

