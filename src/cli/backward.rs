//! `clv backward`: the Ginelli pass over a finished run, frames to a file or standard output.

use super::{emit, print_json, progress};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, ValueEnum};
use clv::{Error, Result};
use clv::stage::backward::{self, BackwardOptions, CInit};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, ValueEnum)]
pub enum CInitArg {
    Identity,
    Random,
}

#[derive(Args)]
pub struct BackwardArgs {
    /// The run directory written by `clv forward --out`.
    pub dir: PathBuf,
    /// Where the frames go: a file, or - for standard output (an MCAP stream for `clv analyze -`).
    /// Default: RUN_DIR/frames.mcap.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Backward steps discarded before frames are emitted (default: the run's --transient; with 0 the frames still end one step before the run's last, whose local exponents would need the R after it).
    #[arg(long, allow_negative_numbers = true)]
    pub transient: Option<u64>,
    /// Initial upper-triangular C at the end of the window.
    #[arg(long, value_enum, default_value = "identity")]
    pub c_init: CInitArg,
    /// Include the Gram-Schmidt vectors G_n in every frame (for GS-CLV comparisons).
    #[arg(long)]
    pub with_gs: bool,
    /// Keep the frames of the steps that are multiples of m in the frame file (the stream on
    /// stdout always carries all); 0 without --out: no frame file, only the CLV spectrum.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub save_every: u64,
    /// Form the covariant vectors V_n = G_n C_n (a quarter of a backward step) only for the
    /// steps n that are multiples of m; the other frames carry the phase point and the local
    /// exponents. `clv analyze` then samples those frames (its --every: m by default, or a
    /// multiple of m), e.g. m = 62 for the paper's 25000 CLV steps (`clv run` does this itself).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub vectors_every: u64,
    /// Continue an interrupted backward sweep from its progress record.
    #[arg(long)]
    pub resume: bool,
    /// Memory budget in MB; segments that do not fit are kept in a scratch file instead.
    #[arg(long, default_value_t = 4096, allow_negative_numbers = true)]
    pub memory: u64,
    /// Threads for the recomputation and the sweep (default: the run's; the numbers do not
    /// depend on it).
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<usize>,
    /// Print one JSON object (CLV and GS spectra, statistics) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress bars or notices.
    #[arg(long)]
    pub quiet: bool,
}

pub fn backward(args: &BackwardArgs, matches: &ArgMatches) -> Result<()> {
    use clv::store::frames::{FrameStdout, Flow};
    if let Some(threads) = args.threads {
        clv::config::check_threads(threads)?;
    }
    let (dir, meta) = clv::store::RunDir::open(&args.dir)?;
    let (opts, to_stdout) = options(args, matches, &meta)?;
    if !args.quiet {
        warn_if_no_vectors(&meta, &opts, to_stdout);
    }
    warn_if_short_of_space(args, &dir, &meta, &opts);
    let stream_meta = backward::stream_info(&dir, &meta, &opts).metadata();
    let mut stdout = if to_stdout { Some(FrameStdout::new(&stream_meta)?) } else { None };
    // Two bars: segments recomputed (from the checkpoints) and frames emitted by the sweep.
    let bars = (!args.quiet).then(|| {
        let multi = clv::report::progress::multi();
        let recompute = multi.add(progress("recompute", false).expect("not quiet"));
        recompute.set_length(meta.store.clv_steps + meta.store.transient);
        let sweep = multi.add(progress("sweep (frames)", false).expect("not quiet"));
        sweep.set_length(backward::Window::of(&meta, &opts).map_or(0, |w| w.last + 1 - w.first));
        (multi, recompute, sweep)
    });
    let mut consumer = |frame: std::sync::Arc<clv::stage::frame::Frame>| -> Result<Flow> {
        match stdout.as_mut() {
            Some(out) => out.write(&frame),
            None => Ok(Flow::Continue),
        }
    };
    let mut on_progress = |recomputed: u64, frames: u64| {
        if let Some((_, recompute, sweep)) = &bars {
            recompute.set_position(recomputed);
            sweep.set_position(frames);
        }
    };
    let explain = if to_stdout {
        "the frames streamed so far went to the reader: give the same command again for the whole window (the sweep starts over), or with --resume for only the frames after those, if the reader kept them".to_string()
    } else {
        format!("its progress up to its last finished segment is recorded in {}: give the same command with --resume to continue", args.dir.display())
    };
    let _signals = clv::stage::signals::ExplainOnSignals::install(&format!("\nclv backward: stopped by a signal; {explain}"));
    let report = backward::run(&args.dir, &opts, args.resume, args.memory.saturating_mul(1 << 20), args.threads, &mut consumer, &mut on_progress)?;
    if let Some((multi, recompute, sweep)) = &bars {
        recompute.finish_and_clear();
        sweep.finish_and_clear();
        let _ = multi.clear();
    }
    let delivered = stdout.map_or(Ok(true), FrameStdout::finish)?;
    for note in report.notes.iter().filter(|_| !args.quiet) {
        clv::note!("clv: {note}");
    }
    // Not a notice: the CLV spectrum of an unfinished sweep is not written.
    if report.statistics.stopped_early {
        let recorded = clv::store::progress::last_sweep(&args.dir).ok().flatten().map_or(0, |s| s.frames);
        return Err(Error::ReaderClosed { frames: report.statistics.frames, recorded });
    }
    if !delivered {
        return Err(Error::OutputClosed {
            what: format!("the frame stream's closing records (after all its {} frames) were written", report.statistics.frames),
            then: format!(
                "the sweep finished and its CLV spectrum is saved ({}), but the reader got a stream cut short; if it was to keep the stream, give the same command again without --resume",
                dir.clv_spectrum_path().display()
            ),
        });
    }
    if args.json {
        print_json(&report)?;
    } else if !to_stdout {
        emit(&clv::report::backward_table(&report))?;
    }
    Ok(())
}

/// The sweep's options: those of the flags, or, with --resume, those the interrupted sweep
/// was started with and the flags given again; and whether the frames go to standard output.
fn options(args: &BackwardArgs, matches: &ArgMatches, meta: &clv::store::RunMeta) -> Result<(BackwardOptions, bool)> {
    let given = |id: &str| matches.value_source(id) == Some(ValueSource::CommandLine);
    // A resumed sweep continues with the options it was started with; flags given again
    // must agree with them (the stage refuses a contradiction).
    let stored = if args.resume { clv::store::progress::stored_options(&args.dir) } else { None };
    let mut opts = stored.clone().unwrap_or_else(|| BackwardOptions::for_run(meta));
    if stored.is_none() || given("transient") {
        opts.transient = args.transient.unwrap_or(BackwardOptions::for_run(meta).transient);
    }
    if stored.is_none() || given("c_init") {
        opts.c_init = match args.c_init {
            CInitArg::Identity => CInit::Identity,
            CInitArg::Random => CInit::Random,
        };
    }
    if stored.is_none() || given("with_gs") {
        opts.with_gs = args.with_gs;
    }
    let to_stdout = match (&stored, given("out")) {
        (Some(s), false) => s.streams(),
        _ => args.out.as_deref() == Some(std::path::Path::new("-")),
    };
    if to_stdout && args.json {
        return Err(Error::param("json", "prints the CLV spectrum on standard output, which --out - gives to the frame stream; leave out --json (the spectrum is written to clv_spectrum.json in the run directory), or write the frames to a file"));
    }
    if to_stdout && std::io::IsTerminal::is_terminal(&std::io::stdout()) {
        return Err(Error::param("out", "- writes a binary MCAP stream, and standard output is a terminal; pipe it into `clv analyze -` (or another reader), or give a file"));
    }
    if stored.is_none() || given("out") {
        opts.frames_path = match (to_stdout, args.out.clone()) {
            (true, _) => None,
            (false, out) => Some(recorded_frames_path(&args.dir, out)?),
        };
    }
    if given("save_every") && args.save_every == 0 && given("out") && !to_stdout {
        return Err(Error::param("save-every", "0 would keep no frame in the file --out names; give m >= 1 (the frames of the steps that are multiples of m), or leave out --out to compute only the CLV spectrum"));
    }
    if stored.is_none() || given("save_every") || given("out") {
        // Resuming with --out FILE again keeps the stored --save-every unless it is given.
        let stored_save = stored.as_ref().map(|s| s.save_every).filter(|&s| s > 0);
        opts.save_every = match (to_stdout, given("save_every"), stored_save) {
            (true, _, _) => 0,
            (false, false, Some(s)) => s,
            _ => args.save_every,
        };
        // A sweep that keeps no frame writes no file, and records none (`clv analyze RUN_DIR`
        // must not take an earlier sweep's frames.mcap for its frames).
        opts.no_frames = !to_stdout && opts.save_every == 0;
        if opts.no_frames {
            opts.frames_path = None;
        } else if !to_stdout && opts.frames_path.is_none() {
            // --save-every m on resuming a sweep that kept none: into the default file.
            opts.frames_path = Some(recorded_frames_path(&args.dir, None)?);
        }
    }
    if stored.is_none() || given("vectors_every") {
        opts.vectors_every = args.vectors_every;
    }
    Ok((opts, to_stdout))
}

/// The frame file --out names (the run's frames.mcap without it), as the progress record
/// keeps it. Directly in the run directory, only a frame file's name: the run's own files
/// (run.json, the segments, the records and their temporary names) are not to be replaced
/// by frames, nor frames by them.
fn recorded_frames_path(run: &Path, out: Option<PathBuf>) -> Result<PathBuf> {
    let path = out.unwrap_or_else(|| clv::store::RunDir { path: run.to_path_buf() }.frames_path());
    let recorded = BackwardOptions::record_frames_path(run, &path)?;
    let name = recorded.to_string_lossy().to_string();
    let in_previous = recorded.is_relative() && recorded.components().next().is_some_and(|c| clv::store::RunDir::is_previous_results(c.as_os_str()));
    if in_previous || (recorded.components().count() == 1 && (!name.ends_with(".mcap") || name.starts_with("seg-"))) {
        return Err(Error::param("out", format!(
            "{} would be {name} in the run directory, where only frame files ending in .mcap (other than the run's seg-*.mcap) may go, beside the run's own files; give such a name (frames.mcap is the default), or a path outside the run directory",
            path.display()
        )));
    }
    Ok(recorded)
}

/// Frames that keep no V_n at all leave the analyses of vector statistics nothing: said
/// now, not when the report comes out empty.
fn warn_if_no_vectors(meta: &clv::store::RunMeta, opts: &BackwardOptions, to_stdout: bool) {
    if let Ok(window) = backward::Window::of(meta, opts)
        && let Some((oldest, newest)) = window.frame_steps(opts)
    {
        use clv::stage::frame::{lcm, multiples_in};
        let m = opts.vectors_every.max(1);
        let kept = if to_stdout { 1 } else { opts.save_every };
        let l = lcm(m, kept);
        if m > 1 && multiples_in(oldest, newest, l) == 0 {
            let saved = if kept > 1 { format!(" in a file of the frames of every {kept}-th step (--save-every {kept})") } else { String::new() };
            clv::note!("clv: warning: no frame of steps {oldest}..{newest} will carry covariant vectors: --vectors-every {m}{saved} keeps V_n only at the steps that are multiples of {l}; the CLV spectrum and the local exponents do not need them, the analyses of vector statistics do");
        }
    }
}

/// A frame file that may not fit on its file system is announced before the sweep starts.
fn warn_if_short_of_space(args: &BackwardArgs, dir: &clv::store::RunDir, meta: &clv::store::RunMeta, opts: &BackwardOptions) {
    // Only for a sweep that will write (--resume of none, or of a finished one, does not).
    let writes = !args.resume || clv::store::progress::last_sweep(&args.dir).ok().flatten().is_some_and(|last| !last.done);
    if let Some(path) = opts.frames_file(&args.dir).filter(|_| writes)
        && let Some(warning) = clv::store::run::short_of_space(&path, backward::frame_file_bytes(dir, meta, opts))
    {
        clv::note!("clv: {warning} (--save-every m keeps one frame in m)");
    }
}
