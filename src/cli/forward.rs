//! `clv forward`: the Gram-Schmidt pass, in memory or into a run directory that can be
//! resumed and extended; its flags define a run (`clv run` and configuration files reuse them).

use super::{emit, print_json, progress};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, ValueEnum};
use clv::config::{RunConfig, SystemConfig};
use clv::system::henon::Henon;
use clv::system::lorenz::Lorenz;
use clv::report::{SpectrumReport, Statistics};
use clv::stage::forward::Forward;
use clv::stage::forward_run::{self, Extension, Feedback};
use clv::store::run::{flag_values, BuildInfo, RunMeta, StoreConfig, StoreR, FORMAT};
use clv::{Error, Result};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SystemKind {
    Henon,
    Lorenz,
    Disks,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum StoreRArg {
    Checkpoints,
    All,
}

#[derive(Args, Clone)]
pub struct ForwardArgs {
    /// Read settings from a configuration file (TOML; keys are these flags, e.g. `steps =
    /// 1000`); flags on the command line override it. `clv config` prints one.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The dynamical system.
    #[arg(long, value_enum, default_value = "disks")]
    pub system: SystemKind,
    /// Number of disks N (D = 4N).
    #[arg(long, default_value_t = 198, allow_negative_numbers = true)]
    pub n: usize,
    /// Number density rho = N/(Lx Ly).
    #[arg(long, default_value_t = 0.7, allow_negative_numbers = true)]
    pub density: f64,
    /// Aspect ratio Ly/Lx, as a number or a fraction such as 2/11.
    #[arg(long, default_value = "2/11", value_parser = parse_ratio, allow_negative_numbers = true)]
    pub aspect: f64,
    /// Box side Lx (with --ly, instead of --density and --aspect).
    #[arg(long, requires = "ly", allow_negative_numbers = true)]
    pub lx: Option<f64>,
    /// Box side Ly (with --lx).
    #[arg(long, requires = "lx", allow_negative_numbers = true)]
    pub ly: Option<f64>,
    /// The Henon map's a in x' = a - x^2 + b y (default 1.4, the paper's).
    #[arg(long, value_parser = parse_number, allow_negative_numbers = true)]
    pub henon_a: Option<f64>,
    /// The Henon map's b, its Jacobian's determinant up to sign (default 0.3, the paper's).
    #[arg(long, value_parser = parse_number, allow_negative_numbers = true)]
    pub henon_b: Option<f64>,
    /// The Lorenz flow's sigma in x' = sigma (y - x) (default 10).
    #[arg(long, value_parser = parse_number, allow_negative_numbers = true)]
    pub lorenz_sigma: Option<f64>,
    /// The Lorenz flow's rho in y' = x (rho - z) - y (default 28; with the other two at their
    /// defaults every orbit ends on a stable fixed point below 24.06, and periodic windows
    /// such as 99.5..100.8, 160 and 350 interrupt the chaos above 24.74).
    #[arg(long, value_parser = parse_number, allow_negative_numbers = true)]
    pub lorenz_rho: Option<f64>,
    /// The Lorenz flow's beta in z' = x y - beta z, as a number or a fraction (default 8/3).
    #[arg(long, value_parser = parse_number, allow_negative_numbers = true)]
    pub lorenz_beta: Option<f64>,
    /// Time between re-orthonormalisations (default 0.6 for disks, 1 for Henon, 0.1 for
    /// Lorenz at its classic parameters and shorter in proportion for faster fields).
    #[arg(long, allow_negative_numbers = true)]
    pub tau: Option<f64>,
    /// Relaxation steps before accumulation.
    #[arg(long, default_value_t = 100, allow_negative_numbers = true)]
    pub relax_steps: u64,
    /// Accumulated steps.
    #[arg(long, default_value_t = 1000, allow_negative_numbers = true)]
    pub steps: u64,
    /// Number k of tangent vectors (default: all, k = D).
    #[arg(long, allow_negative_numbers = true)]
    pub vectors: Option<usize>,
    /// Seed of the initial state (positions on the start lattice, velocities).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub seed: u64,
    /// Threads for the QR step and the tangent updates (2 halves a step at D = 792; the
    /// numbers do not depend on it).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub threads: usize,
    /// Blocks for the standard error (batch means): each block is steps / blocks steps long (rounded down), so a run has at least this many complete blocks and fewer than twice as many; with fewer steps than blocks, each step is a block.
    #[arg(long, default_value_t = 20, allow_negative_numbers = true)]
    pub blocks: usize,
    /// Write a run directory (checkpoints, R matrices, running spectrum) for the backward stage.
    #[arg(long, conflicts_with = "resume")]
    pub out: Option<PathBuf>,
    /// Continue the interrupted run in this directory (its configuration is read from it); with a larger --steps, make the run longer.
    #[arg(long)]
    pub resume: Option<PathBuf>,
    /// Steps between checkpoints (default 100, or the whole run where it is shorter).
    #[arg(long, allow_negative_numbers = true)]
    pub checkpoint_every: Option<u64>,
    /// Checkpoints per segment file.
    #[arg(long, default_value_t = 10, allow_negative_numbers = true)]
    pub segment_checkpoints: u64,
    /// Close a segment file once it holds this many MB.
    #[arg(long, default_value_t = 1024, allow_negative_numbers = true)]
    pub segment_mb: u64,
    /// Which R matrices to store: at checkpoints, or at every step of the CLV window too (for
    /// reading them outside clv; the backward stage recomputes and checks them).
    #[arg(long, value_enum, default_value = "checkpoints")]
    pub store_r: StoreRArg,
    /// Steps at the end of the run for which covariant vectors are wanted (default a tenth of relax-steps + steps, at most 2/3 of steps).
    #[arg(long, allow_negative_numbers = true)]
    pub clv_steps: Option<u64>,
    /// Backward-sweep steps discarded before the CLV window (default clv-steps/2; with 0 the window still ends one step before the run's last, whose local exponents would need the R after it).
    #[arg(long, allow_negative_numbers = true)]
    pub transient: Option<u64>,
    /// Print one JSON object to stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress bar or notices.
    #[arg(long)]
    pub quiet: bool,
}

/// A finite number, or a fraction such as 8/3.
fn parse_number(s: &str) -> std::result::Result<f64, String> {
    let num = |x: &str| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}"));
    let value = match s.split_once('/') {
        Some((a, b)) => num(a)? / num(b)?,
        None => num(s)?,
    };
    if value.is_finite() { Ok(value) } else { Err(format!("must be a finite number or fraction, got {s}")) }
}

/// A positive number or fraction.
fn parse_ratio(s: &str) -> std::result::Result<f64, String> {
    match parse_number(s) {
        Ok(value) if value > 0.0 => Ok(value),
        _ => Err(format!("must be a positive number or fraction, got {s}")),
    }
}

impl ForwardArgs {
    /// The box as the command line gives it (`given` tells which flags it names), over a
    /// configuration file's or a preset's (`in_file`): its --lx and --ly, or its --density and
    /// --aspect (then a file's sides yield). Both ways at once are refused, on the command
    /// line or in a file, and so is half of density and aspect over a file's sides: which
    /// shape or density the box should keep would be a guess.
    pub fn box_from_command_line(&self, given: impl Fn(&str) -> bool, in_file: impl Fn(&str) -> bool) -> Result<ForwardArgs> {
        let sides = |named: &dyn Fn(&str) -> bool| named("lx") || named("ly");
        let shape = |named: &dyn Fn(&str) -> bool| named("density") || named("aspect");
        if sides(&given) && shape(&given) {
            return Err(Error::param("lx", "give the box either by its sides (--lx and --ly) or by --density and --aspect, not both"));
        }
        if sides(&in_file) && shape(&in_file) {
            return Err(Error::param("lx", "the box is given both by its sides (lx, ly) and by density or aspect; keep one of the two"));
        }
        if sides(&in_file) && shape(&given) && !(given("density") && given("aspect")) {
            let (flag, other) = if given("density") { ("density", "aspect") } else { ("aspect", "density") };
            return Err(Error::param(
                flag,
                format!("the configuration file gives the box by its sides (lx, ly), and --{flag} alone would take the default --{other} with it; give both --density and --aspect, or --lx and --ly"),
            ));
        }
        let mut args = self.clone();
        if shape(&given) {
            (args.lx, args.ly) = (None, None);
        }
        Ok(args)
    }

    pub fn config(&self) -> Result<RunConfig> {
        let system = match self.system {
            SystemKind::Henon => SystemConfig::henon_with(self.henon_a.unwrap_or(Henon::A), self.henon_b.unwrap_or(Henon::B))?,
            SystemKind::Lorenz => {
                let (sigma, rho, beta) = (self.lorenz_sigma.unwrap_or(Lorenz::SIGMA), self.lorenz_rho.unwrap_or(Lorenz::RHO), self.lorenz_beta.unwrap_or(Lorenz::BETA));
                SystemConfig::lorenz_with(sigma, rho, beta)?
            }
            SystemKind::Disks => match (self.lx, self.ly) {
                (Some(lx), Some(ly)) => SystemConfig::disks_in_box(self.n, lx, ly),
                _ => SystemConfig::disks(self.n, self.density, self.aspect)?,
            },
        };
        let tau = self.tau.unwrap_or(system.default_tau());
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

    pub fn meta(&self) -> Result<RunMeta> {
        let config = self.config()?;
        let mut store = StoreConfig::for_run(&config);
        if let Some(c) = self.checkpoint_every {
            store.checkpoint_every = c;
        }
        store.segment_checkpoints = self.segment_checkpoints;
        store.segment_bytes = self.segment_mb.saturating_mul(1 << 20);
        store.store_r = match self.store_r {
            StoreRArg::Checkpoints => StoreR::Checkpoints,
            StoreRArg::All => StoreR::All,
        };
        if let Some(c) = self.clv_steps {
            store.clv_steps = c;
            store.transient = StoreConfig::transient_for(c);
        }
        if let Some(t) = self.transient {
            store.transient = t;
        }
        store.validate(&config)?;
        Ok(RunMeta { format: FORMAT.into(), config, store, build: BuildInfo::current() })
    }
}

/// Refuse flags given with --resume that disagree with the stored run, except a longer
/// --steps (with a new --clv-steps or --transient): that extends the run.
fn check_resume_flags(args: &ForwardArgs, matches: &ArgMatches, dir: &std::path::Path) -> Result<Option<Extension>> {
    let (_, stored) = clv::store::RunDir::open(dir)?;
    // The stored run's system, unless --system names another (then refused below): the
    // flags given are checked against it.
    let mut args = args.clone();
    if !from_command_line(matches, "system") {
        args.system = SystemKind::of(&stored.config.system);
    }
    no_flags_of_other_systems(args.system, |flag| from_command_line(matches, flag))?;
    let given: Vec<&str> = flag_values(&stored.config, &stored.store)
        .iter()
        .map(|(id, _)| *id)
        .chain(["system"])
        .filter(|id| matches.value_source(id) == Some(ValueSource::CommandLine))
        .collect();
    let extending = given.contains(&"steps") && args.steps > stored.config.steps;
    if given.is_empty() {
        return Ok(None);
    }
    if given.contains(&"steps") && args.steps < stored.config.steps {
        let (setting, drop) = match args.config.as_ref().filter(|_| !on_command_line("steps")) {
            Some(file) => (format!("steps = {} in {}", args.steps, file.display()), "leave out --config (or that setting)"),
            None => (format!("--steps {}", args.steps), "drop --steps"),
        };
        return Err(Error::param(
            "resume",
            format!("{setting} is fewer than the {} steps of the run in {}: a run is not made shorter; {drop} to resume it, or give more to extend it", stored.config.steps, dir.display()),
        ));
    }
    // The settings not given are the run's, so that checking the given ones together blames
    // none of the flags' defaults (--resume --steps 1 was refused for its --clv-steps).
    let c = &stored.config;
    let not_given = |id: &str| !from_command_line(matches, id);
    if not_given("steps") {
        args.steps = c.steps;
    }
    if not_given("relax-steps") {
        args.relax_steps = c.relax_steps;
    }
    if not_given("seed") {
        args.seed = c.seed;
    }
    if not_given("blocks") {
        args.blocks = c.blocks;
    }
    if not_given("checkpoint-every") {
        args.checkpoint_every = Some(stored.store.checkpoint_every);
    }
    if not_given("tau") && SystemKind::of(&c.system) == args.system {
        args.tau = Some(c.tau);
    }
    if SYSTEM_FLAGS.iter().all(|(flag, _)| not_given(flag)) && SystemKind::of(&c.system) == args.system {
        match c.system {
            SystemConfig::Disks { n, lx, ly, .. } => (args.n, args.lx, args.ly) = (n, Some(lx), Some(ly)),
            SystemConfig::Henon { a, b } => (args.henon_a, args.henon_b) = (Some(a), Some(b)),
            SystemConfig::Lorenz { sigma, rho, beta } => (args.lorenz_sigma, args.lorenz_rho, args.lorenz_beta) = (Some(sigma), Some(rho), Some(beta)),
        }
        if not_given("vectors") {
            args.vectors = Some(c.vectors);
        }
    }
    let wanted_meta = args.meta()?;
    let wanted = flag_values(&wanted_meta.config, &wanted_meta.store);
    let stored_flags = flag_values(&stored.config, &stored.store);
    for id in given {
        if extending && ["steps", "clv_steps", "transient"].contains(&id) {
            continue;
        }
        let w = wanted.iter().find(|(k, _)| *k == id).map(|(_, v)| v.as_str());
        let s = stored_flags.iter().find(|(k, _)| *k == id).map(|(_, v)| v.as_str());
        if w != s {
            let flag = id.replace('_', "-");
            let extend = if id == "steps" { ", give a larger --steps to extend it" } else { "" };
            let (setting, drop) = match args.config.as_ref().filter(|_| !on_command_line(&flag)) {
                Some(file) => (format!("{flag} = {} in {}", w.unwrap_or("?"), file.display()), "leave out --config (or that setting)"),
                None => (format!("--{flag} {}", w.unwrap_or("?")), "drop the flag"),
            };
            return Err(Error::param(
                "resume",
                format!(
                    "{setting} conflicts with the run in {}, which was made with --{flag} {}; {drop} to resume it{extend}, or start a new run with --out",
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

/// The flags that set up one system, and that system.
const SYSTEM_FLAGS: [(&str, SystemKind); 10] = [
    ("n", SystemKind::Disks),
    ("density", SystemKind::Disks),
    ("aspect", SystemKind::Disks),
    ("lx", SystemKind::Disks),
    ("ly", SystemKind::Disks),
    ("henon-a", SystemKind::Henon),
    ("henon-b", SystemKind::Henon),
    ("lorenz-sigma", SystemKind::Lorenz),
    ("lorenz-rho", SystemKind::Lorenz),
    ("lorenz-beta", SystemKind::Lorenz),
];

impl SystemKind {
    fn of(system: &SystemConfig) -> SystemKind {
        match system {
            SystemConfig::Henon { .. } => SystemKind::Henon,
            SystemConfig::Lorenz { .. } => SystemKind::Lorenz,
            SystemConfig::Disks { .. } => SystemKind::Disks,
        }
    }

    fn described(self) -> &'static str {
        match self {
            SystemKind::Henon => "the Henon map (--system henon)",
            SystemKind::Lorenz => "the Lorenz flow (--system lorenz)",
            SystemKind::Disks => "hard disks (--system disks)",
        }
    }
}

/// Refuse a flag that sets up another system than `system` (`given` tells which flags were
/// given, by their names on the command line), which would otherwise ignore it.
pub fn no_flags_of_other_systems(system: SystemKind, given: impl Fn(&str) -> bool) -> Result<()> {
    match SYSTEM_FLAGS.into_iter().find(|&(flag, owner)| owner != system && given(flag)) {
        Some((flag, owner)) => {
            let has = if system == SystemKind::Disks { "have" } else { "has" };
            Err(Error::param(flag, format!("sets up {}; {} {has} no such setting", owner.described(), system.described())))
        }
        None => Ok(()),
    }
}

/// Whether `matches` has --`flag` from the command line (or a configuration file expanded
/// into it); clap names the flag --a-b by the id a_b.
fn from_command_line(matches: &ArgMatches, flag: &str) -> bool {
    matches.value_source(&flag.replace('-', "_")) == Some(ValueSource::CommandLine)
}

pub fn forward(args: &ForwardArgs, matches: &ArgMatches) -> Result<()> {
    forward_checked(args, matches).map_err(|e| super::blame_file(e, args.config.as_deref(), on_command_line))
}

/// Whether the user's own command line (not a configuration file) names the flag --`name`.
fn on_command_line(name: &str) -> bool {
    super::names_flag(std::env::args(), name)
}

fn forward_checked(args: &ForwardArgs, matches: &ArgMatches) -> Result<()> {
    let in_file = |name: &str| matches.value_source(name) == Some(ValueSource::CommandLine) && !on_command_line(name);
    let args = &args.box_from_command_line(on_command_line, in_file)?;
    if let Some(dir) = &args.resume {
        let mut feedback = Feedback { bar: progress("forward", args.quiet), notices: Vec::new() };
        forward_run::complete_creation(dir, &mut feedback)?;
        let extension = check_resume_flags(args, matches, dir)?;
        let threads = (matches.value_source("threads") == Some(ValueSource::CommandLine)).then_some(args.threads);
        if let Some(threads) = threads {
            clv::config::check_threads(threads)?;
        }
        let outcome = match extension {
            Some(ext) => forward_run::extend(dir, ext, threads, &[], &mut feedback)?,
            None => forward_run::resume(dir, threads, &mut feedback)?,
        };
        if let Some(bar) = &feedback.bar {
            bar.finish_and_clear();
        }
        if outcome.already_finished && !args.quiet {
            clv::note!("clv: the run in {} is already complete; nothing to do", dir.display());
        }
        return print_report(&outcome.report, args.json);
    }
    no_flags_of_other_systems(args.system, |flag| from_command_line(matches, flag))?;
    if let Some(dir) = &args.out {
        super::no_stdout_directory(dir, "a run directory")?;
        if dir.is_file() {
            return Err(Error::param("out", format!("{} is a file; a run needs a directory (a new path, or an empty directory)", dir.display())));
        }
        let meta = args.meta()?;
        // Refused before it is announced (create checks again, under the lock).
        clv::store::RunDir::check_empty(dir, "forward pass")?;
        if !args.quiet {
            clv::note!("clv: configuration: {}", serde_json::to_string(&meta.config).unwrap_or_default());
            clv::note!("clv: writing {}: {}", dir.display(), meta.store.footprint(&meta.config));
        }
        if let Some(warning) = clv::store::run::short_of_space(dir, meta.store.footprint(&meta.config).bytes) {
            clv::note!("clv: {warning}");
        }
        let mut feedback = Feedback { bar: progress("forward", args.quiet), notices: Vec::new() };
        let outcome = forward_run::create(dir, &meta, &mut feedback)?;
        if let Some(bar) = &feedback.bar {
            bar.finish_and_clear();
        }
        return print_report(&outcome.report, args.json);
    }
    let config = args.config()?;
    if !args.quiet {
        clv::note!("clv: configuration: {}", serde_json::to_string(&config).unwrap_or_default());
    }
    spectrum(config, args.json, args.quiet)
}

fn print_report(report: &SpectrumReport, json: bool) -> Result<()> {
    if json { print_json(report) } else { emit(&report.table()) }
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
    // As often as a stored run checks it (at its checkpoints, by default), and at the end.
    let check_every = StoreConfig::for_run(&config).checkpoint_every;
    while fwd.step < total {
        fwd.step()?;
        if let Some(warning) = fwd.early_precision_warning(config.steps).filter(|_| !quiet) {
            let say = || clv::note!("clv: warning: {warning}");
            bar.as_ref().map_or_else(say, |bar| bar.suspend(say));
        }
        if fwd.step % check_every == 0 || fwd.step == total {
            forward_run::check_energy(fwd.step, start.energy, fwd.system.invariants().energy)?;
        }
        if let Some(bar) = &bar {
            bar.inc(1);
        }
    }
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let statistics = Statistics::new(&config, &start, &fwd.system.invariants(), started.elapsed().as_secs_f64());
    let report = SpectrumReport::new(config, &fwd.acc, statistics);
    print_report(&report, json).map_err(|e| match e {
        Error::OutputClosed { what, .. } => Error::OutputClosed { what, then: "this run kept nothing else, and its results are lost: give --out DIR to keep them in a run directory".into() },
        e => e,
    })
}
