//! `clv analyze`: every analysis over a frame file or a stream on standard input.

use clap::Args;
use clv::{Error, Result};
use std::path::PathBuf;

#[derive(Args)]
pub struct AnalyzeArgs {
    /// Frames: a file written by `clv backward --out FILE`, - for standard input, or a run
    /// directory (the frame file its last `clv backward` sweep wrote: frames.mcap in it by default).
    pub source: PathBuf,
    /// Directory for index.html, figures (PNG, SVG) and tables (CSV, JSON).
    #[arg(long)]
    pub out: PathBuf,
    /// Vector statistics use the frames of the steps that are multiples of m (default: the
    /// CLV window's steps / 400, rounded down, so 400 to 800 frames, and a multiple of the
    /// stream's --vectors-every and of a frame file's --save-every).
    #[arg(long, allow_negative_numbers = true)]
    pub every: Option<u64>,
    /// Lyapunov indices (1-based) for the overlap figures, e.g. 1,200,370 (default: the
    /// paper's choice scaled to this system's D, the last ending before the mode steps).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub j: Option<Vec<usize>>,
    /// Window lengths Delta (steps) for finite-time exponents, e.g. 1,10,100 (default: 1, 2,
    /// 5, ... up to a quarter of the CLV window).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub deltas: Option<Vec<u64>>,
    /// Run only these analyses (comma-separated names, e.g. spectrum,localization; an unknown name lists those that apply).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Replace an earlier report in --out: once the first frame arrives, its files go and
    /// index.html says the report is incomplete until the new one is written (without it, a
    /// directory that holds files is refused).
    #[arg(long)]
    pub overwrite: bool,
    /// No progress bar or closing summary.
    #[arg(long)]
    pub quiet: bool,
}

pub fn analyze(args: &AnalyzeArgs) -> Result<()> {
    if args.source == std::path::Path::new("-") && std::io::IsTerminal::is_terminal(&std::io::stdin()) {
        return Err(Error::Other(
            "- reads a frame stream from standard input, which is a terminal; pipe one in (`clv backward RUN_DIR --out - | clv analyze - --out REPORT`) or give a frame file".into(),
        ));
    }
    super::no_stdout_directory(&args.out, "a report")?;
    if args.out.is_file() {
        return Err(Error::param("out", format!("{} is a file; the report needs a directory", args.out.display())));
    }
    // A report can be all that is left of a long run: never replace one by accident.
    if args.out.join("run.json").exists() {
        return Err(Error::param("out", format!("{} is a run directory; a report goes into a directory of its own (e.g. {})", args.out.display(), args.out.join("report").display())));
    }
    // Asked before the report's lock is taken, so that a refusal writes nothing into a
    // directory of other files, and again under it, where the answer holds.
    let refuse_files = || {
        let holds_files = std::fs::read_dir(&args.out).is_ok_and(|entries| entries.flatten().any(|e| e.file_name() != clv::report::dir::LOCK));
        if holds_files && !args.overwrite {
            clv::report::dir::refuse_if_being_written(&args.out)?;
            return Err(Error::param(
                "out",
                format!("{} already holds files (an earlier report?); choose another --out, or add --overwrite to replace them", args.out.display()),
            ));
        }
        Ok(())
    };
    refuse_files()?;
    let _lock = clv::report::dir::lock_report(&args.out)?;
    refuse_files()?;
    // --overwrite replaces the report: the earlier one's files go when the first frame
    // arrives (analyze::begin_report; a stream that brings none leaves the report as it
    // was). Other files in --out are not touched.
    // The number of frames is not known ahead (a stream on stdin): count and rate only.
    let bar = (!args.quiet).then(|| clv::report::progress::frames("analyze"));
    let mut on_frame = |frames: u64| {
        if let Some(bar) = &bar {
            bar.set_position(frames);
        }
    };
    let _signals = clv::stage::signals::ExplainOnSignals::install(&format!(
        "\nclv analyze: stopped by a signal; the report in {} is incomplete: give the same command with --overwrite to write it again",
        args.out.display()
    ));
    let result = clv::stage::analyze::analyze_source(&args.source, &args.out, args.every, args.j.clone(), args.deltas.clone(), &args.only, &mut on_frame);
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let clv::stage::analyze::Analysed { produced, frames, warnings } = result?;
    for w in &warnings {
        clv::note!("clv analyze: warning: {w}");
    }
    if !args.quiet {
        let figures: usize = produced.iter().map(|p| p.figures.len()).sum();
        clv::note!("clv analyze: {frames} frames, {} analyses, {figures} figures; open {}", produced.len(), args.out.join("index.html").display());
    }
    Ok(())
}
