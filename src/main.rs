//! The `clv` command line: parses flags into configurations and hands them to the stages.

use clap::parser::ValueSource;
use clap::{ArgMatches, Args, CommandFactory, FromArgMatches, Parser, Subcommand, ValueEnum};
use clv::config::{RunConfig, SystemConfig};
use clv::report::{inspect, SpectrumReport, Statistics};
use clv::stage::forward::Forward;
use clv::stage::forward_run::{self, Extension, Feedback};
use clv::store::run::{BuildInfo, RunMeta, StoreConfig, StoreR, FORMAT};
use clv::{Error, Result};
use indicatif::ProgressBar;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "clv", version, about = "Lyapunov spectra, Gram-Schmidt and covariant Lyapunov vectors of hard disks and maps")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Forward Gram-Schmidt pass: the Lyapunov spectrum; with --out, a resumable run directory.
    #[command(args_override_self = true)]
    Forward(ForwardArgs),
    /// Backward Ginelli pass over a finished run: covariant Lyapunov vectors, frame by frame.
    Backward(BackwardArgs),
    /// What a run directory or a frame file holds, and whether every file is intact.
    Inspect(InspectArgs),
    /// Every analysis of the paper over a frame stream (a file written by `clv backward`, or -).
    Analyze(AnalyzeArgs),
    /// The whole pipeline (forward, backward, all analyses) on an embedded preset.
    Run(RunArgs),
    /// One spectrum from independent runs of one system (other seeds): errors from the spread between them.
    Combine(CombineArgs),
    /// Measure kernels and stages side by side on this machine (medians, ratios, memory).
    Bench(BenchArgs),
    /// Print a configuration file to start from (keys are the flags of `clv forward`).
    Config(ConfigArgs),
}

#[derive(Args)]
struct CombineArgs {
    /// Finished runs: run directories or their spectrum.json files (e.g. runs/seed-*).
    #[arg(required = true)]
    runs: Vec<PathBuf>,
    /// Print one JSON object to stdout instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct ConfigArgs {
    /// Embedded configuration: default, paper, henon or lorenz.
    #[arg(long, default_value = "default")]
    preset: String,
}

#[derive(Args)]
struct BenchArgs {
    /// Disks N of the benchmark system (D = 4N).
    #[arg(long, default_value_t = 198)]
    n: usize,
    /// Tangent vectors (default D).
    #[arg(long)]
    vectors: Option<usize>,
    /// Threads for the linear algebra.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Repetitions of each measurement.
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// System sizes N for the collision-rate measurement (k = 0).
    #[arg(long, value_delimiter = ',', default_value = "198,1980,19800")]
    collision_sizes: Vec<usize>,
    /// Skip the peak-memory measurement (child processes).
    #[arg(long)]
    no_rss: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SystemKind {
    Henon,
    Lorenz,
    Disks,
}

#[derive(Clone, Copy, ValueEnum)]
enum StoreRArg {
    Checkpoints,
    All,
}

#[derive(Args)]
struct ForwardArgs {
    /// Read settings from a configuration file (TOML; keys are these flags, e.g. `steps =
    /// 1000`); flags on the command line override it. `clv config` prints one.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// The dynamical system.
    #[arg(long, value_enum, default_value = "disks")]
    system: SystemKind,
    /// Number of disks N (D = 4N).
    #[arg(long, default_value_t = 198)]
    n: usize,
    /// Number density rho = N/(Lx Ly).
    #[arg(long, default_value_t = 0.7, allow_negative_numbers = true)]
    density: f64,
    /// Aspect ratio Ly/Lx, as a number or a fraction such as 2/11.
    #[arg(long, default_value = "2/11", value_parser = parse_ratio, allow_negative_numbers = true)]
    aspect: f64,
    /// Box side Lx (with --ly, instead of --density and --aspect).
    #[arg(long, requires = "ly", allow_negative_numbers = true)]
    lx: Option<f64>,
    /// Box side Ly (with --lx).
    #[arg(long, requires = "lx", allow_negative_numbers = true)]
    ly: Option<f64>,
    /// Time between re-orthonormalisations (default 0.6 for disks, 1 for Henon, 0.1 for Lorenz).
    #[arg(long, allow_negative_numbers = true)]
    tau: Option<f64>,
    /// Relaxation steps before accumulation.
    #[arg(long, default_value_t = 100)]
    relax_steps: u64,
    /// Accumulated steps.
    #[arg(long, default_value_t = 1000)]
    steps: u64,
    /// Number k of tangent vectors (default: all, k = D).
    #[arg(long)]
    vectors: Option<usize>,
    /// Seed of the initial state (positions on the start lattice, velocities).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Threads for the QR step and the tangent updates (2 halves a step at D = 792; the
    /// numbers do not depend on it).
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Blocks for the standard error.
    #[arg(long, default_value_t = 20)]
    blocks: usize,
    /// Write a run directory (checkpoints, R matrices, running spectrum) for the backward stage.
    #[arg(long, conflicts_with = "resume")]
    out: Option<PathBuf>,
    /// Continue the interrupted run in this directory (its configuration is read from it); with a larger --steps, make the run longer.
    #[arg(long)]
    resume: Option<PathBuf>,
    /// Steps between checkpoints.
    #[arg(long, default_value_t = 100)]
    checkpoint_every: u64,
    /// Checkpoints per segment file.
    #[arg(long, default_value_t = 10)]
    segment_checkpoints: u64,
    /// Close a segment file once it holds this many MB.
    #[arg(long, default_value_t = 1024)]
    segment_mb: u64,
    /// Which R matrices to store: at checkpoints, or at every step of the CLV window too.
    #[arg(long, value_enum, default_value = "checkpoints")]
    store_r: StoreRArg,
    /// Steps at the end of the run for which covariant vectors are wanted (default steps/10).
    #[arg(long)]
    clv_steps: Option<u64>,
    /// Backward-sweep steps discarded before the CLV window (default clv-steps/2).
    #[arg(long)]
    transient: Option<u64>,
    /// Print one JSON object to stdout instead of the table.
    #[arg(long)]
    json: bool,
    /// No progress bar or notices.
    #[arg(long)]
    quiet: bool,
}

#[derive(Clone, Copy, ValueEnum)]
enum CInitArg {
    Identity,
    Random,
}

#[derive(Args)]
struct BackwardArgs {
    /// The run directory written by `clv forward --out`.
    dir: PathBuf,
    /// Where the frames go: a file, or - for standard output (an MCAP stream for `clv analyze -`).
    /// Default: RUN_DIR/frames.mcap.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Backward steps discarded before frames are emitted (default: the run's --transient).
    #[arg(long)]
    transient: Option<u64>,
    /// Initial upper-triangular C at the end of the window.
    #[arg(long, value_enum, default_value = "identity")]
    c_init: CInitArg,
    /// Include the Gram-Schmidt vectors G_n in every frame (for GS-CLV comparisons).
    #[arg(long)]
    with_gs: bool,
    /// Keep the frames of the steps that are multiples of m in the frame file (the stream on
    /// stdout always carries all); 0 without --out: no frame file, only the CLV spectrum.
    #[arg(long, default_value_t = 1)]
    save_every: u64,
    /// Form the covariant vectors V_n = G_n C_n (a quarter of a backward step) only for the
    /// steps n that are multiples of m; the other frames carry the phase point and the local
    /// exponents. `clv analyze` then samples those frames (its --every: m by default, or a
    /// multiple of m), e.g. m = 62 for the paper's 25000 CLV steps (`clv run` does this itself).
    #[arg(long, default_value_t = 1)]
    vectors_every: u64,
    /// Continue an interrupted backward sweep from its progress record.
    #[arg(long)]
    resume: bool,
    /// Memory budget in MB; segments that do not fit are kept in a scratch file instead.
    #[arg(long, default_value_t = 4096)]
    memory: u64,
    /// Threads for the recomputation and the sweep (default: the run's; the numbers do not
    /// depend on it).
    #[arg(long)]
    threads: Option<usize>,
    /// Print one JSON object (CLV and GS spectra, statistics) instead of the table.
    #[arg(long)]
    json: bool,
    /// No progress bars or notices.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct InspectArgs {
    /// A run directory, or a frame file written by `clv backward --out FILE`.
    dir: PathBuf,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct AnalyzeArgs {
    /// Frames: a file written by `clv backward --out FILE`, - for standard input, or a run
    /// directory (the frames.mcap that `clv backward RUN_DIR` wrote into it).
    source: PathBuf,
    /// Directory for index.html, figures (PNG, SVG) and tables (CSV, JSON).
    #[arg(long)]
    out: PathBuf,
    /// Vector statistics use the frames of the steps that are multiples of m (default: about
    /// 400 frames, and a multiple of the stream's --vectors-every).
    #[arg(long)]
    every: Option<u64>,
    /// Lyapunov indices (1-based) for the overlap figures, e.g. 1,200,370 (default: the
    /// paper's choice scaled to this system's D).
    #[arg(long, value_delimiter = ',')]
    j: Option<Vec<usize>>,
    /// Window lengths Delta (steps) for finite-time exponents, e.g. 1,10,100 (default: 1, 2,
    /// 5, ... up to a quarter of the CLV window).
    #[arg(long, value_delimiter = ',')]
    deltas: Option<Vec<u64>>,
    /// Run only these analyses (comma-separated names, e.g. spectrum,localization; an unknown name lists those that apply).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Replace the files of an earlier report in --out (without it, a directory that holds
    /// files is refused).
    #[arg(long)]
    overwrite: bool,
    /// No progress bar or closing summary.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct RunArgs {
    /// Embedded configuration: default, paper or henon.
    #[arg(long, default_value = "default")]
    preset: String,
    /// A configuration file (as printed by `clv config`) instead of a preset.
    #[arg(long, value_name = "FILE", conflicts_with = "preset")]
    config: Option<PathBuf>,
    /// Output directory: OUT/run (the run) and OUT/report (index.html, figures, tables).
    #[arg(long, default_value = "clv-out")]
    out: PathBuf,
    /// No progress bars or notices.
    #[arg(long)]
    quiet: bool,
    /// Settings that change the preset's or the file's, as flags of `clv forward` after the
    /// others, e.g. `clv run --preset paper --steps 50000 --threads 4` (`clv config` lists
    /// them). The store's window (--clv-steps, --transient) follows --steps unless given.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, value_name = "SETTINGS")]
    settings: Vec<String>,
}

fn parse_ratio(s: &str) -> std::result::Result<f64, String> {
    let num = |x: &str| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}"));
    let value = match s.split_once('/') {
        Some((a, b)) => num(a)? / num(b)?,
        None => num(s)?,
    };
    if value.is_finite() && value > 0.0 { Ok(value) } else { Err(format!("must be a positive number or fraction, got {s}")) }
}

impl ForwardArgs {
    fn config(&self) -> Result<RunConfig> {
        let (system, tau) = match self.system {
            SystemKind::Henon => (SystemConfig::henon(), self.tau.unwrap_or(1.0)),
            SystemKind::Lorenz => (SystemConfig::lorenz(), self.tau.unwrap_or(0.1)),
            SystemKind::Disks => {
                let system = match (self.lx, self.ly) {
                    (Some(lx), Some(ly)) => SystemConfig::disks_in_box(self.n, lx, ly),
                    _ => SystemConfig::disks(self.n, self.density, self.aspect)?,
                };
                (system, self.tau.unwrap_or(0.6))
            }
        };
        let vectors = self.vectors.unwrap_or(system.dim());
        let config = RunConfig {
            system,
            tau,
            relax_steps: self.relax_steps,
            steps: self.steps,
            vectors,
            seed: self.seed,
            threads: self.threads,
            blocks: self.blocks,
        };
        config.validate()?;
        Ok(config)
    }

    fn meta(&self) -> Result<RunMeta> {
        let config = self.config()?;
        let mut store = StoreConfig::for_run(&config);
        store.checkpoint_every = self.checkpoint_every;
        store.segment_checkpoints = self.segment_checkpoints;
        store.segment_bytes = self.segment_mb.saturating_mul(1 << 20);
        store.store_r = match self.store_r {
            StoreRArg::Checkpoints => StoreR::Checkpoints,
            StoreRArg::All => StoreR::All,
        };
        if let Some(c) = self.clv_steps {
            store.clv_steps = c;
            store.transient = (c / 2).max(1);
        }
        if let Some(t) = self.transient {
            store.transient = t;
        }
        store.validate(&config)?;
        Ok(RunMeta { format: FORMAT.into(), config, store, build: BuildInfo::current() })
    }
}

/// The values of the flags that define a run, as they would be given on the command line.
fn flag_values(m: &RunMeta) -> Vec<(&'static str, String)> {
    let c = &m.config;
    let mut v = vec![
        ("tau", c.tau.to_string()),
        ("relax_steps", c.relax_steps.to_string()),
        ("steps", c.steps.to_string()),
        ("vectors", c.vectors.to_string()),
        ("seed", c.seed.to_string()),
        ("blocks", c.blocks.to_string()),
        ("checkpoint_every", m.store.checkpoint_every.to_string()),
        ("segment_checkpoints", m.store.segment_checkpoints.to_string()),
        ("segment_mb", (m.store.segment_bytes >> 20).to_string()),
        ("store_r", format!("{:?}", m.store.store_r)),
        ("clv_steps", m.store.clv_steps.to_string()),
        ("transient", m.store.transient.to_string()),
    ];
    match &c.system {
        SystemConfig::Henon { .. } => v.push(("system", "henon".into())),
        SystemConfig::Lorenz { .. } => v.push(("system", "lorenz".into())),
        SystemConfig::Disks { n, lx, ly, density, aspect } => v.extend([
            ("system", "disks".into()),
            ("n", n.to_string()),
            ("lx", lx.to_string()),
            ("ly", ly.to_string()),
            ("density", density.to_string()),
            ("aspect", aspect.to_string()),
        ]),
    }
    v
}

/// Refuse flags given with --resume that disagree with the stored run, except a longer
/// --steps (with a new --clv-steps or --transient): that extends the run.
fn check_resume_flags(args: &ForwardArgs, matches: &ArgMatches, dir: &std::path::Path) -> Result<Option<Extension>> {
    let (_, stored) = clv::store::RunDir::open(dir)?;
    let given: Vec<&str> = flag_values(&stored)
        .iter()
        .map(|(id, _)| *id)
        .chain(["system"])
        .filter(|id| matches.value_source(id) == Some(ValueSource::CommandLine))
        .collect();
    let extending = given.contains(&"steps") && args.steps > stored.config.steps;
    if given.is_empty() {
        return Ok(None);
    }
    let wanted_meta = args.meta()?;
    let wanted = flag_values(&wanted_meta);
    let stored_flags = flag_values(&stored);
    for id in given {
        if extending && ["steps", "clv_steps", "transient"].contains(&id) {
            continue;
        }
        let w = wanted.iter().find(|(k, _)| *k == id).map(|(_, v)| v.as_str());
        let s = stored_flags.iter().find(|(k, _)| *k == id).map(|(_, v)| v.as_str());
        if w != s {
            let flag = id.replace('_', "-");
            let extend = if id == "steps" { ", give a larger --steps to extend it" } else { "" };
            return Err(Error::param(
                "resume",
                format!(
                    "--{flag} {} conflicts with the run in {}, which was made with --{flag} {}; drop the flag to resume it{extend}, or start a new run with --out",
                    w.unwrap_or("?"),
                    dir.display(),
                    s.unwrap_or("(not set)")
                ),
            ));
        }
    }
    // A new --clv-steps brings its default transient, as in a new run.
    let transient = args.transient.or(args.clv_steps.map(|_| wanted_meta.store.transient));
    Ok(extending.then_some(Extension { steps: args.steps, clv_steps: args.clv_steps, transient }))
}

fn progress(what: &str, quiet: bool) -> Option<ProgressBar> {
    if quiet {
        return None;
    }
    Some(clv::report::progress::steps(what))
}

fn print_report(report: &SpectrumReport, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string(report).map_err(|e| Error::Other(e.to_string()))?);
    } else {
        print!("{}", report.table());
    }
    Ok(())
}

fn forward(args: &ForwardArgs, matches: &ArgMatches) -> Result<()> {
    no_disk_flags_for_henon(args.system, |id| matches.value_source(id) == Some(ValueSource::CommandLine))?;
    if let Some(dir) = &args.resume {
        let mut feedback = Feedback { bar: progress("forward", args.quiet), notices: Vec::new() };
        forward_run::complete_creation(dir, &mut feedback)?;
        let extension = check_resume_flags(args, matches, dir)?;
        let threads = (matches.value_source("threads") == Some(ValueSource::CommandLine)).then_some(args.threads);
        if threads == Some(0) {
            return Err(Error::param("threads", "must be at least 1"));
        }
        let outcome = match extension {
            Some(ext) => forward_run::extend(dir, ext, threads, &[], &mut feedback)?,
            None => forward_run::resume(dir, threads, &mut feedback)?,
        };
        if let Some(bar) = &feedback.bar {
            bar.finish_and_clear();
        }
        if outcome.already_finished && !args.quiet {
            eprintln!("clv: the run in {} is already complete; nothing to do", dir.display());
        }
        return print_report(&outcome.report, args.json);
    }
    if let Some(dir) = &args.out {
        if dir.is_file() {
            return Err(Error::param("out", format!("{} is a file; a run needs a directory (a new path, or an empty directory)", dir.display())));
        }
        let meta = args.meta()?;
        if !args.quiet {
            eprintln!("clv: configuration: {}", serde_json::to_string(&meta.config).unwrap_or_default());
            eprintln!("clv: writing {}: {}", dir.display(), meta.store.footprint(&meta.config).1);
        }
        if let Some(warning) = clv::store::run::space_warning(dir, meta.store.footprint(&meta.config).0) {
            eprintln!("clv: {warning}");
        }
        let mut feedback = Feedback { bar: progress("forward", args.quiet), notices: Vec::new() };
        let outcome = forward_run::create(dir, &meta, &mut feedback)?;
        if let Some(bar) = &feedback.bar {
            bar.finish_and_clear();
        }
        return print_report(&outcome.report, args.json);
    }
    spectrum(args.config()?, args.json, args.quiet)
}

/// The flags of `clv forward` that set up `config` (a preset): the system (by density and
/// aspect) and the run, not the store, whose window then follows the run's length; all
/// vectors (k = D) by leaving --vectors out, so that they follow a changed --n. Parsed back
/// they give `config`.
fn config_flags(config: &RunConfig) -> Vec<String> {
    let meta = RunMeta { format: FORMAT.into(), config: config.clone(), store: StoreConfig::for_run(config), build: BuildInfo::current() };
    let left_out = ["lx", "ly", "checkpoint_every", "segment_checkpoints", "segment_mb", "store_r", "clv_steps", "transient"];
    flag_values(&meta)
        .into_iter()
        .filter(|(id, _)| !left_out.contains(id) && (*id != "vectors" || config.vectors != config.system.dim()))
        .chain([("threads", config.threads.to_string())])
        .flat_map(|(id, value)| [format!("--{}", id.replace('_', "-")), value])
        .collect()
}

/// What `clv run` runs: the preset or the configuration file, changed by the settings on
/// its command line, read through `clv forward`'s flags.
fn run_meta(args: &RunArgs) -> Result<RunMeta> {
    let keys = config_keys();
    let mut argv = vec!["clv".to_string(), "forward".to_string()];
    match &args.config {
        Some(path) => {
            argv.extend(clv::report::config_file::expand(path, &keys)?);
            // A bad value in the file is the file's error, not the command line's.
            Cli::try_parse_from(&argv).map_err(|e| Error::Other(format!("{}: {}", path.display(), first_line(&e))))?;
        }
        None => argv.extend(config_flags(&RunConfig::preset(&args.preset)?)),
    }
    for setting in &args.settings {
        if let Some(flag) = setting.strip_prefix("--") {
            let key = flag.split('=').next().unwrap_or_default();
            if !keys.iter().any(|k| k == key) {
                return Err(Error::param(
                    "settings",
                    format!("--{key} is not a setting of a run; give `clv run` its own options (--preset, --config, --out, --quiet) before the settings, which are: --{}", keys.join(", --")),
                ));
            }
        }
    }
    argv.extend(args.settings.iter().cloned());
    let matches = Cli::command().try_get_matches_from(&argv).map_err(|e| Error::Other(format!("settings: {}", first_line(&e))))?;
    let Ok(Cli { command: Command::Forward(forward), .. }) = Cli::from_arg_matches(&matches) else {
        return Err(Error::Other("settings: not the flags of a run".into()));
    };
    no_disk_flags_for_henon(forward.system, |id| args.settings.iter().any(|s| s == &format!("--{id}") || s.starts_with(&format!("--{id}="))))?;
    forward.meta()
}

/// Refuse a flag that sets up hard disks (`given` tells which were given) for the Henon map,
/// which would otherwise ignore it.
fn no_disk_flags_for_henon(system: SystemKind, given: impl Fn(&str) -> bool) -> Result<()> {
    match ["n", "density", "aspect", "lx", "ly"].into_iter().find(|id| given(id)) {
        Some(flag) if system != SystemKind::Disks => Err(Error::param(flag, "sets up hard disks; the Henon map and the Lorenz flow (--system henon, lorenz) have no such setting")),
        _ => Ok(()),
    }
}

fn first_line(e: &clap::Error) -> String {
    e.to_string().lines().next().unwrap_or_default().trim_start_matches("error: ").to_string()
}

/// The settings a configuration file may hold: the flags of `clv forward` that define a run.
fn config_keys() -> Vec<String> {
    let cmd = Cli::command();
    let forward = cmd.find_subcommand("forward").expect("forward exists");
    forward
        .get_arguments()
        .filter_map(|a| a.get_long())
        .filter(|l| !["config", "out", "resume", "json", "quiet", "help"].contains(l))
        .map(String::from)
        .collect()
}

fn run(args: &RunArgs) -> Result<()> {
    let RunMeta { config, store, .. } = run_meta(args)?;
    if args.out.is_file() {
        return Err(Error::param("out", format!("{} is a file; `clv run` writes a directory (run/ and report/ in it)", args.out.display())));
    }
    let quiet = args.quiet;
    let mut say = |msg: String| {
        if !quiet {
            eprintln!("clv run: {msg}");
        }
    };
    let origin = match &args.config {
        Some(path) => format!("{}", path.display()),
        None => format!("preset {:?}", args.preset),
    };
    let changed = if args.settings.is_empty() { String::new() } else { format!(" with {}", args.settings.join(" ")) };
    say(format!("{origin}{changed}: {}", serde_json::to_string(&config).unwrap_or_default()));
    let mut feedback = Feedback { bar: progress("forward", args.quiet), notices: Vec::new() };
    let started = Instant::now();
    let result = clv::stage::pipeline::run(&config, &store, &args.out, &mut feedback, &mut say).map_err(|e| match e {
        Error::Stopped { step, total, run } => Error::Other(format!(
            "stopped by a signal after step {step} of {total} of the forward pass; everything up to it is saved in {}: give the same `clv run` command again to continue",
            run.display()
        )),
        e => e,
    })?;
    if let Some(bar) = &feedback.bar {
        bar.finish_and_clear();
    }
    let clv_report = &result.clv;
    use clv::stage::forward::Estimate;
    let first = |v: &[f64], e: &[f64]| Estimate::or_unknown(v.first().zip(e.first()).map(|(&value, &stderr)| Estimate { value, stderr }));
    say(format!(
        "lambda_1 = {} (GS), {} (CLV); h_KS = {} (GS), {} (CLV)",
        first(&clv_report.gs_exponents, &clv_report.gs_stderr),
        first(&clv_report.exponents, &clv_report.stderr),
        Estimate::or_unknown(clv_report.gs_ks_entropy),
        Estimate::or_unknown(clv_report.ks_entropy)
    ));
    let gs = clv::report::SpectrumSummary::read(&result.run_dir.join("spectrum.json")).ok();
    if let Some(d) = gs.and_then(|g| g.blocks).and_then(|b| clv::stage::analyze::kernels::convergence::diagnose(&b.exponents)) {
        say(format!("convergence of the GS spectrum ({} blocks): {}", d.blocks, d.verdict()));
    }
    let figures: usize = result.produced.iter().map(|p| p.figures.len()).sum();
    say(format!(
        "done in {:.0} s: {} frames analysed, {figures} figures; open {}",
        started.elapsed().as_secs_f64(),
        result.clv.statistics.frames,
        result.report_dir.join("index.html").display()
    ));
    Ok(())
}

fn bench(args: &BenchArgs) -> Result<()> {
    let opts = clv::bench::BenchOptions {
        n: args.n,
        k: args.vectors,
        threads: args.threads,
        reps: args.reps,
        collision_sizes: args.collision_sizes.clone(),
        exe: if args.no_rss { None } else { std::env::current_exe().ok() },
    };
    let report = clv::bench::run(&opts, &mut |what| eprintln!("clv bench: {what}"))?;
    if args.json {
        println!("{}", serde_json::to_string(&report).map_err(|e| Error::Other(e.to_string()))?);
    } else {
        print!("{}", report.table());
    }
    Ok(())
}

fn analyze(args: &AnalyzeArgs) -> Result<()> {
    if args.source == std::path::Path::new("-") && std::io::IsTerminal::is_terminal(&std::io::stdin()) {
        return Err(Error::Other(
            "- reads a frame stream from standard input, which is a terminal; pipe one in (`clv backward RUN_DIR --out - | clv analyze - --out REPORT`) or give a frame file".into(),
        ));
    }
    if args.out.is_file() {
        return Err(Error::param("out", format!("{} is a file; the report needs a directory", args.out.display())));
    }
    // A report can be all that is left of a long run: never replace one by accident.
    let holds_files = std::fs::read_dir(&args.out).is_ok_and(|mut entries| entries.next().is_some());
    if holds_files && !args.overwrite {
        return Err(Error::param(
            "out",
            format!("{} already holds files (an earlier report?); choose another --out, or add --overwrite to replace them", args.out.display()),
        ));
    }
    // The number of frames is not known ahead (a stream on stdin): count and rate only.
    let bar = (!args.quiet).then(|| clv::report::progress::frames("analyze"));
    let mut on_frame = |frames: u64| {
        if let Some(bar) = &bar {
            bar.set_position(frames);
        }
    };
    let result = clv::stage::analyze::analyze_source(&args.source, &args.out, args.every, args.j.clone(), args.deltas.clone(), &args.only, &mut on_frame);
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let clv::stage::analyze::Analysed { produced, frames, warnings } = result?;
    for w in &warnings {
        eprintln!("clv analyze: warning: {w}");
    }
    if !args.quiet {
        let figures: usize = produced.iter().map(|p| p.figures.len()).sum();
        eprintln!("clv analyze: {frames} frames, {} analyses, {figures} figures; open {}", produced.len(), args.out.join("index.html").display());
    }
    Ok(())
}

/// The forward pass in memory, nothing written.
fn spectrum(config: RunConfig, json: bool, quiet: bool) -> Result<()> {
    let started = Instant::now();
    let mut fwd = Forward::new(&config)?;
    let start = fwd.system.invariants();
    let total = config.relax_steps + config.steps;
    let bar = progress("forward", quiet);
    if let Some(bar) = &bar {
        bar.set_length(total);
    }
    while fwd.step < total {
        fwd.step()?;
        if let Some(bar) = &bar {
            bar.inc(1);
        }
    }
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let statistics = Statistics::new(&config, &start, &fwd.system.invariants(), started.elapsed().as_secs_f64());
    let report = SpectrumReport::new(config, &fwd.acc, statistics);
    print_report(&report, json)
}

fn backward(args: &BackwardArgs, matches: &ArgMatches) -> Result<()> {
    use clv::stage::backward::{self, BackwardOptions, CInit};
    use clv::store::frames::{FrameStdout, Flow};
    if args.threads == Some(0) {
        return Err(Error::param("threads", "must be at least 1"));
    }
    let (dir, meta) = clv::store::RunDir::open(&args.dir)?;
    let given = |id: &str| matches.value_source(id) == Some(ValueSource::CommandLine);
    // A resumed sweep continues with the options it was started with; flags given again
    // must agree with them (the stage refuses a contradiction).
    let stored = if args.resume { backward::stored_options(&args.dir) } else { None };
    let mut opts = stored.clone().unwrap_or_else(|| BackwardOptions::for_run(&meta));
    if stored.is_none() || given("transient") {
        opts.transient = args.transient.unwrap_or(BackwardOptions::for_run(&meta).transient);
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
        (Some(s), false) => s.frames_path.is_none(),
        _ => args.out.as_deref() == Some(std::path::Path::new("-")),
    };
    if to_stdout && std::io::IsTerminal::is_terminal(&std::io::stdout()) {
        return Err(Error::param("out", "- writes a binary MCAP stream, and standard output is a terminal; pipe it into `clv analyze -` (or another reader), or give a file"));
    }
    if stored.is_none() || given("out") {
        opts.frames_path = if to_stdout { None } else { Some(args.out.clone().unwrap_or_else(|| clv::store::RunDir { path: args.dir.clone() }.frames_path())) };
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
    }
    if stored.is_none() || given("vectors_every") {
        opts.vectors_every = args.vectors_every;
    }
    if let Some(path) = &opts.frames_path
        && let Some(warning) = clv::store::run::space_warning(path, backward::frame_file_bytes(&meta, &opts)) {
            eprintln!("clv: {warning} (--save-every m keeps one frame in m)");
        }
    let stream_meta = backward::stream_info(&dir, &meta, &opts).metadata();
    let mut stdout = if to_stdout { Some(FrameStdout::new(&stream_meta)?) } else { None };
    // Two bars: segments recomputed (from the checkpoints) and frames emitted by the sweep.
    let bars = (!args.quiet).then(|| {
        let multi = clv::report::progress::multi();
        let recompute = multi.add(progress("recompute", false).expect("not quiet"));
        recompute.set_length(meta.store.clv_steps + meta.store.transient);
        let sweep = multi.add(progress("sweep (frames)", false).expect("not quiet"));
        sweep.set_length(meta.store.clv_steps.saturating_sub(opts.transient.saturating_sub(meta.store.transient)) + 1);
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
    let report = backward::run(&args.dir, &opts, args.resume, args.memory << 20, args.threads, &mut consumer, &mut on_progress)?;
    if let Some((multi, recompute, sweep)) = &bars {
        recompute.finish_and_clear();
        sweep.finish_and_clear();
        let _ = multi.clear();
    }
    if let Some(out) = stdout {
        out.finish()?;
    }
    for note in report.notes.iter().filter(|_| !args.quiet) {
        eprintln!("clv: {note}");
    }
    if report.statistics.stopped_early && !args.quiet {
        eprintln!("clv: the reader closed the stream after {} frames; stopped (continue later with --resume)", report.statistics.frames);
    }
    if args.json {
        println!("{}", serde_json::to_string(&report).map_err(|e| Error::Other(e.to_string()))?);
    } else if !to_stdout {
        println!("{:>6}  {:>14}  {:>10}  {:>14}  {:>10}", "i", "lambda_i (CLV)", "stderr", "lambda_i (GS)", "stderr");
        for i in 0..report.exponents.len() {
            println!(
                "{:>6}  {:>14.8}  {:>10.2e}  {:>14.8}  {:>10.2e}",
                i + 1,
                report.exponents[i],
                report.stderr[i],
                report.gs_exponents.get(i).copied().unwrap_or(f64::NAN),
                report.gs_stderr.get(i).copied().unwrap_or(f64::NAN)
            );
        }
        use clv::stage::forward::Estimate;
        println!("KS entropy (sum of the positive exponents): {} (CLV), {} (GS)", Estimate::or_unknown(report.ks_entropy), Estimate::or_unknown(report.gs_ks_entropy));
        let st = &report.statistics;
        println!("{} frames (steps {}..{}), {} steps recomputed in {} segments, {:.1} s", st.frames, st.first_frame_step, st.last_frame_step, st.recomputed_steps, st.segments, st.wall_seconds);
    }
    Ok(())
}

/// An inspection as one JSON object, or as its text.
fn print_inspection<T: serde::Serialize>(found: &T, text: String, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string(found).map_err(|e| Error::Other(e.to_string()))?);
    } else {
        print!("{text}");
    }
    Ok(())
}

fn inspect_cmd(args: &InspectArgs) -> Result<()> {
    if args.dir.is_file() {
        let found = inspect::inspect_frames(&args.dir)?;
        print_inspection(&found, found.text(), args.json)?;
        return match &found.damage {
            None => Ok(()),
            Some(_) => Err(Error::Other(format!(
                "{}: damaged or cut short; its {} complete frames can still be analysed, and `clv backward RUN_DIR --out FILE --resume` continues a sweep that was interrupted",
                args.dir.display(),
                found.frames
            ))),
        };
    }
    let found = inspect::inspect(&args.dir)?;
    print_inspection(&found, found.text(), args.json)?;
    if found.intact { Ok(()) } else { Err(Error::Other(format!("{}: damaged files found (see above); repair them with `clv forward --resume {}`", args.dir.display(), args.dir.display()))) }
}

/// The command line with a `--config FILE` of `clv forward` expanded into flags, placed
/// before the command line's own so that those override the file.
fn expand_config(raw: Vec<String>) -> Result<Vec<String>> {
    if raw.get(1).map(String::as_str) != Some("forward") {
        return Ok(raw);
    }
    let mut rest = Vec::new();
    let mut file = None;
    let mut it = raw[2..].iter();
    while let Some(a) = it.next() {
        if a == "--config" {
            file = it.next().cloned();
        } else if let Some(f) = a.strip_prefix("--config=") {
            file = Some(f.to_string());
        } else {
            rest.push(a.clone());
        }
    }
    let Some(file) = file else { return Ok(raw) };
    let mut argv = raw[..2].to_vec();
    argv.extend(clv::report::config_file::expand(std::path::Path::new(&file), &config_keys())?);
    // A bad value in the file is the file's error, not the command line's.
    if let Err(e) = Cli::try_parse_from(&argv) {
        return Err(Error::Other(format!("{file}: {}", first_line(&e))));
    }
    argv.extend(rest);
    Ok(argv)
}

/// One malloc arena for the whole process (glibc). With one arena per thread, the writer
/// thread's chunk buffers and the simulation's 5-8 MB checkpoint buffers fragment two heaps,
/// and resident memory crept up with run length: +8.6 % between 20 and 600 steps at D = 792,
/// +1.1 % with one arena (`clv bench`). The forward step allocates nothing and the others
/// little, so sharing the arena cost no measurable time (forward step 21.0 against 20.9 ms).
fn one_malloc_arena() {
    const M_ARENA_MAX: i32 = -8;
    mallopt(M_ARENA_MAX, 1); // before any other thread exists
}

/// glibc's mallopt(3); nothing elsewhere.
fn mallopt(param: i32, value: i32) {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        unsafe extern "C" {
            fn mallopt(param: i32, value: i32) -> i32;
        }
        // SAFETY: a plain call of glibc's mallopt with one of its documented parameters.
        unsafe { mallopt(param, value) };
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    let _ = (param, value);
}

/// Serve allocations of 1 MB and more from mmap, so that they go back to the system when
/// freed. For the forward stage only: it allocates its large buffers (checkpoint encodings,
/// the segment writer's chunks) at checkpoints, and from the heap their freed blocks
/// fragmented it, so that its peak memory crept with the segments written (52-56 MB for 20
/// steps against 56-58.5 MB for 200, with checkpoints every 5 steps in segments of 2;
/// 49.0-51.5 against 52.2-52.3 MB from mmap; 1030 steps of the paper's system took
/// 15.2-15.6 s against 14.7-15.6 s, the same within this machine's noise, with a peak of
/// 52-54 MB against 56-58 MB). The backward stage and
/// the analyses allocate a frame's vectors every step, where fresh mapped pages cost page
/// faults (a backward pipe took 4 % longer), so they keep glibc's default.
fn large_allocations_from_mmap() {
    const M_MMAP_THRESHOLD: i32 = -3;
    mallopt(M_MMAP_THRESHOLD, 1 << 20);
}

fn main() {
    one_malloc_arena();
    let argv = match expand_config(std::env::args().collect()) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("clv: error: {e}");
            std::process::exit(1);
        }
    };
    let matches = Cli::command().get_matches_from(argv);
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    let result = match &cli.command {
        Command::Forward(args) => {
            large_allocations_from_mmap();
            forward(args, matches.subcommand_matches("forward").expect("subcommand parsed"))
        }
        Command::Backward(args) => backward(args, matches.subcommand_matches("backward").expect("subcommand parsed")),
        Command::Inspect(args) => inspect_cmd(args),
        Command::Analyze(args) => analyze(args),
        Command::Run(args) => run(args),
        Command::Combine(args) => clv::report::combine::combine(&args.runs).and_then(|c| {
            if args.json {
                println!("{}", serde_json::to_string(&c).map_err(|e| Error::Other(e.to_string()))?);
            } else {
                print!("{}", c.table());
            }
            Ok(())
        }),
        Command::Bench(args) => bench(args),
        Command::Config(args) => RunConfig::preset(&args.preset).map(|c| {
            print!("{}", clv::report::config_file::render(&args.preset, &c, &clv::store::run::StoreConfig::for_run(&c)));
        }),
    };
    if std::env::var_os("CLV_REPORT_PEAK_RSS").is_some()
        && let Some(kb) = clv::bench::peak_rss_kb() {
            eprintln!("clv-peak-rss-kb: {kb}");
        }
    if let Err(e) = result {
        eprintln!("clv: error: {e}");
        std::process::exit(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `clv run` on a preset without settings runs exactly the preset, with the store
    /// settings derived from it, as it did before it took settings (so that it continues
    /// the runs it made then).
    #[test]
    fn a_preset_read_through_its_flags_is_the_preset() {
        for preset in clv::config::PRESETS {
            let args = RunArgs { preset: preset.into(), config: None, out: "clv-out".into(), quiet: true, settings: Vec::new() };
            let meta = run_meta(&args).unwrap();
            let want = RunConfig::preset(preset).unwrap();
            assert_eq!(meta.config, want, "{preset}");
            assert_eq!(meta.store, StoreConfig::for_run(&want), "{preset}");
        }
    }
}
