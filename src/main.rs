//! The `clv` command line.

use clap::{Args, Parser, Subcommand, ValueEnum};
use clv::config::{RunConfig, SystemConfig};
use clv::report::{SpectrumReport, Statistics};
use clv::stage::forward::Forward;
use clv::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::time::Instant;

#[derive(Parser)]
#[command(name = "clv", version, about = "Lyapunov spectra, Gram-Schmidt and covariant Lyapunov vectors of hard disks and maps")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Forward Gram-Schmidt pass: the Lyapunov spectrum with standard errors.
    Forward(ForwardArgs),
    /// The main job on an embedded preset (today: the forward pass and its spectrum).
    Run(RunArgs),
}

#[derive(Args)]
struct RunArgs {
    /// Embedded configuration: default, paper or henon.
    #[arg(long, default_value = "default")]
    preset: String,
    /// Print one JSON object to stdout instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, ValueEnum)]
enum SystemKind {
    Henon,
    Disks,
}

#[derive(Args)]
struct ForwardArgs {
    /// The dynamical system.
    #[arg(long, value_enum, default_value = "disks")]
    system: SystemKind,
    /// Number of disks N (D = 4N).
    #[arg(long, default_value_t = 198)]
    n: usize,
    /// Number density rho = N/(Lx Ly).
    #[arg(long, default_value_t = 0.7)]
    density: f64,
    /// Aspect ratio Ly/Lx, as a number or a fraction such as 2/11.
    #[arg(long, default_value = "2/11", value_parser = parse_ratio)]
    aspect: f64,
    /// Box side Lx (with --ly, instead of --density and --aspect).
    #[arg(long, requires = "ly")]
    lx: Option<f64>,
    /// Box side Ly (with --lx).
    #[arg(long, requires = "lx")]
    ly: Option<f64>,
    /// Time between re-orthonormalisations (default 0.6 for disks, 1 for Henon).
    #[arg(long)]
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
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Threads for the linear algebra (recorded: results differ in the last bits).
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Blocks for the standard error.
    #[arg(long, default_value_t = 20)]
    blocks: usize,
    /// Print one JSON object to stdout instead of the table.
    #[arg(long)]
    json: bool,
}

fn parse_ratio(s: &str) -> std::result::Result<f64, String> {
    let value = match s.split_once('/') {
        Some((a, b)) => {
            let (a, b): (f64, f64) = (a.trim().parse().map_err(|e| format!("{e}"))?, b.trim().parse().map_err(|e| format!("{e}"))?);
            a / b
        }
        None => s.trim().parse().map_err(|e| format!("{e}"))?,
    };
    if value.is_finite() && value > 0.0 { Ok(value) } else { Err(format!("must be a positive number or fraction, got {s}")) }
}

impl ForwardArgs {
    fn config(&self) -> Result<RunConfig> {
        let (system, tau) = match self.system {
            SystemKind::Henon => (SystemConfig::henon(), self.tau.unwrap_or(1.0)),
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
}

fn progress(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} steps ({eta} left)")
            .expect("static template"),
    );
    bar.set_message(what.to_string());
    bar
}

fn forward(args: &ForwardArgs) -> Result<()> {
    spectrum(args.config()?, args.json)
}

fn run(args: &RunArgs) -> Result<()> {
    let config = RunConfig::preset(&args.preset)?;
    if !args.json {
        eprintln!("clv run: preset {:?}: {}", args.preset, serde_json::to_string(&config).unwrap_or_default());
    }
    spectrum(config, args.json)
}

fn spectrum(config: RunConfig, json: bool) -> Result<()> {
    let started = Instant::now();
    let mut fwd = Forward::new(&config)?;
    let start = fwd.system.invariants();
    let total = config.relax_steps + config.steps;
    let bar = progress(total, "forward");
    while fwd.step < total {
        fwd.step()?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let report = SpectrumReport {
        exponents: fwd.acc.exponents(config.tau),
        stderr: fwd.acc.stderr(config.tau),
        statistics: Statistics::new(&config, &start, &fwd.system.invariants(), started.elapsed().as_secs_f64()),
        config,
    };
    if json {
        println!("{}", serde_json::to_string(&report).map_err(|e| Error::Other(e.to_string()))?);
    } else {
        print!("{}", report.table());
    }
    Ok(())
}

fn main() {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Forward(args) => forward(args),
        Command::Run(args) => run(args),
    };
    if let Err(e) = result {
        eprintln!("clv: error: {e}");
        std::process::exit(1);
    }
}
