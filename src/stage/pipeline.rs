//! `clv run`: forward, backward and every analysis in one process, on an embedded preset
//! or a configuration file.
//!
//! The frames go straight from the backward sweep to the analyses over channels (nothing
//! but the run directory is written in between), so the whole pipeline runs in the memory
//! of one segment. A killed `clv run` resumes its forward pass when started again.

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
    if run_dir.join("run.json").exists() {
        let (_, stored) = RunDir::open(&run_dir)?;
        if let Some(ext) = extension(&stored, config, store) {
            say(format!("extending the run in {} from {} to {} steps", run_dir.display(), stored.config.steps, config.steps));
            forward_run::extend(&run_dir, ext, Some(config.threads), &[&report_dir], feedback)?;
        } else if !stored.config.same_but_threads(config) || stored.store != *store {
            // The threads are the process's, not the run's: the numbers do not depend on them.
            let json = |c: &RunConfig, s: &StoreConfig| format!("{}, store {}", serde_json::to_string(c).unwrap_or_default(), serde_json::to_string(s).unwrap_or_default());
            return Err(Error::param(
                "out",
                format!(
                    "{} holds a run of another configuration ({}), not of the one asked for ({}); choose another --out, or ask for that run's configuration to continue it (or for more --steps to extend it)",
                    run_dir.display(),
                    json(&stored.config, &stored.store),
                    json(config, store)
                ),
            ));
        } else {
            say(format!("continuing the run in {}", run_dir.display()));
            forward_run::resume(&run_dir, Some(config.threads), feedback)?;
        }
    } else {
        let meta = RunMeta { format: FORMAT.into(), config: config.clone(), store: store.clone(), build: BuildInfo::current() };
        say(format!("forward pass into {} ({})", run_dir.display(), meta.store.footprint(config).1));
        // On top of the run: the report (about 2 MB of figures and tables) and the backward
        // stage's progress record (C as hex, two copies while it is replaced).
        let k = config.vectors as u64;
        let beside = (2 << 20) + 2 * 16 * (k * (k + 1) / 2);
        if let Some(warning) = crate::store::run::space_warning(&run_dir, meta.store.footprint(config).0 + beside) {
            eprintln!("clv run: {warning}");
        }
        forward_run::create(&run_dir, &meta, feedback)?;
    }
    let (dir, meta) = RunDir::open(&run_dir)?;
    // Taken after the forward pass, which may move an earlier report aside (extend).
    let _report_lock = super::analyze::lock_report(&report_dir)?;
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

/// The extension that turns the stored run into the one asked for, if that is one: the same
/// system and settings with more steps, and the same store up to the CLV window.
fn extension(stored: &RunMeta, config: &RunConfig, store: &StoreConfig) -> Option<forward_run::Extension> {
    let longer = RunConfig { steps: config.steps, ..stored.config.clone() };
    let rewindowed = StoreConfig { clv_steps: store.clv_steps, transient: store.transient, ..stored.store.clone() };
    (config.steps > stored.config.steps && longer.same_but_threads(config) && rewindowed == *store)
        .then_some(forward_run::Extension { steps: config.steps, clv_steps: Some(store.clv_steps), transient: Some(store.transient) })
}
