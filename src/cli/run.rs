//! `clv run`: the whole pipeline on a preset or a configuration file, changed by settings
//! given as `clv forward` flags.

use super::forward::no_flags_of_other_systems;
use clv::store::run::flag_values;
use super::{config_keys, first_line, progress, Cli, Command};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, CommandFactory, FromArgMatches};
use clv::config::RunConfig;
use clv::stage::forward_run::Feedback;
use clv::store::run::{RunMeta, StoreConfig};
use clv::{Error, Result};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct RunArgs {
    /// Embedded configuration: default, paper, henon or lorenz.
    #[arg(long, default_value = "default")]
    pub preset: String,
    /// A configuration file (as printed by `clv config`) instead of a preset.
    #[arg(long, value_name = "FILE", conflicts_with = "preset")]
    pub config: Option<PathBuf>,
    /// Output directory: OUT/run (the run) and OUT/report (index.html, figures, tables). A
    /// report in OUT/report that is not of the run in OUT/run is refused, not replaced.
    #[arg(long, default_value = "clv-out")]
    pub out: PathBuf,
    /// No progress bars or notices.
    #[arg(long)]
    pub quiet: bool,
    /// Settings that change the preset's or the file's, as flags of `clv forward` after the
    /// others, e.g. `clv run --preset paper --steps 50000 --threads 4` (`clv config` lists
    /// them). The store's window (--clv-steps, --transient) follows --steps unless given.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, value_name = "SETTINGS")]
    pub settings: Vec<String>,
}

/// The flags of `clv forward` that set up `config` (a preset): the system (by density and
/// aspect) and the run, not the store, whose window then follows the run's length; all
/// vectors (k = D) by leaving --vectors out, so that they follow a changed --n, and the
/// system's default tau by leaving --tau out, so that it follows changed Lorenz parameters.
/// Parsed back they give `config`.
fn config_flags(config: &RunConfig) -> Vec<String> {
    let left_out = ["lx", "ly", "checkpoint_every", "segment_checkpoints", "segment_mb", "store_r", "clv_steps", "transient"];
    flag_values(config, &StoreConfig::for_run(config))
        .into_iter()
        .filter(|(id, _)| !left_out.contains(id) && (*id != "vectors" || config.vectors != config.system.dim()) && (*id != "tau" || config.tau != config.system.default_tau()))
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
        Some(path) => argv.extend(super::forward_flags_of_file(path)?),
        None => argv.extend(config_flags(&RunConfig::preset(&args.preset)?)),
    }
    for setting in &args.settings {
        if let Some(flag) = setting.strip_prefix("--") {
            let key = flag.split('=').next().unwrap_or_default();
            if !keys.iter().any(|k| k == key) {
                return Err(Error::Other(format!(
                    "--{key} is not a setting of a run; `clv run` takes --preset, --config, --out and --quiet of its own, and the settings --{}",
                    keys.join(", --")
                )));
            }
        }
    }
    argv.extend(args.settings.iter().cloned());
    let matches = Cli::command().try_get_matches_from(&argv).map_err(|e| Error::Other(format!("settings: {}", first_line(&e))))?;
    let Ok(Cli { command: Command::Forward(forward), .. }) = Cli::from_arg_matches(&matches) else {
        return Err(Error::Other("settings: not the flags of a run".into()));
    };
    let in_settings = |name: &str| super::names_flag(&args.settings, name);
    let given = |name: &str| matches.subcommand_matches("forward").and_then(|m| m.value_source(&name.replace('-', "_"))) == Some(clap::parser::ValueSource::CommandLine);
    // The file's keys too (a Henon run would ignore them), not the preset's own.
    let asked = |name: &str| given(name) && (args.config.is_some() || in_settings(name));
    no_flags_of_other_systems(forward.system, asked).map_err(|e| super::blame_file(e, args.config.as_deref(), in_settings))?;
    let in_file = |name: &str| given(name) && !in_settings(name);
    forward.box_from_command_line(in_settings, in_file).and_then(|f| f.meta()).map_err(|e| match (e, &args.config) {
        // A preset's value that the settings made wrong (its tau for another --system).
        (Error::Param { name, msg }, None) if !in_settings(name) => Error::Param { name, msg: format!("{msg} (--{name} comes from the preset {}; give --{name} among the settings)", args.preset) },
        (e, _) => super::blame_file(e, args.config.as_deref(), in_settings),
    })
}

/// `args` with `clv run`'s own options that were given among the settings (`clv run --steps
/// 4000 --quiet`) taken out of them; one given both before and among them is refused.
fn own_options_moved(args: &RunArgs, matches: &ArgMatches) -> Result<RunArgs> {
    let mut moved = RunArgs { preset: args.preset.clone(), config: args.config.clone(), out: args.out.clone(), quiet: args.quiet, settings: Vec::new() };
    let mut seen: Vec<&str> = Vec::new();
    let mut rest = args.settings.iter();
    while let Some(setting) = rest.next() {
        if setting == "-h" || setting == "--help" {
            let mut cli = Cli::command();
            cli.build();
            if let Some(run) = cli.find_subcommand_mut("run") {
                let _ = run.print_help();
            }
            std::process::exit(0);
        }
        let (flag, inline) = match setting.split_once('=') {
            Some((flag, value)) => (flag, Some(value.to_string())),
            None => (setting.as_str(), None),
        };
        let own = ["--quiet", "--out", "--preset", "--config"].into_iter().find(|f| *f == flag);
        let Some(own) = own else {
            moved.settings.push(setting.clone());
            continue;
        };
        let id = &own[2..];
        if matches.value_source(id) == Some(ValueSource::CommandLine) || seen.contains(&id) {
            return Err(Error::param(id, "given twice; give it once"));
        }
        seen.push(id);
        if own == "--quiet" {
            if inline.is_some() {
                return Err(Error::param("quiet", "takes no value: give --quiet alone"));
            }
            moved.quiet = true;
            continue;
        }
        let value = inline.or_else(|| rest.next().cloned()).ok_or_else(|| Error::param(id, "needs a value"))?;
        match own {
            "--out" => moved.out = value.into(),
            "--preset" => moved.preset = value,
            _ => moved.config = Some(value.into()),
        }
    }
    let named = |id: &str| seen.contains(&id) || matches.value_source(id) == Some(ValueSource::CommandLine);
    if named("preset") && named("config") {
        return Err(Error::param("config", "a configuration file replaces the preset; give --config or --preset, not both"));
    }
    Ok(moved)
}

/// `clv run`'s CLV window and checkpoint interval follow --steps, but a run made longer by
/// `clv forward --resume --steps` kept its own: for that run, given again with its steps and
/// no window asked for, the run's window is taken (it was refused as another
/// configuration); and a run shorter than 100 steps keeps its interval when made longer.
fn window_of_the_run_in_out(args: &RunArgs, config: &RunConfig, mut store: StoreConfig) -> StoreConfig {
    let asked = |key: &str| super::names_flag(&args.settings, key) || args.config.as_deref().is_some_and(|file| super::config_file::line_of(file, key).is_some());
    let Ok((_, stored)) = clv::store::RunDir::open(&args.out.join("run")) else { return store };
    // A run shorter than 100 steps checkpoints at its ends: made longer, it keeps that
    // interval (the default of the longer run's length would make it another run).
    let longer = RunConfig { steps: config.steps, ..stored.config.clone() };
    if !asked("checkpoint-every") && longer.same_but_threads(config) {
        store.checkpoint_every = stored.store.checkpoint_every;
    }
    if !(asked("clv-steps") || asked("transient")) && stored.config.same_but_threads(config) {
        store.clv_steps = stored.store.clv_steps;
        store.transient = stored.store.transient;
    }
    store
}

pub fn run(args: &RunArgs, matches: &ArgMatches) -> Result<()> {
    let args = &own_options_moved(args, matches)?;
    let RunMeta { config, store, .. } = run_meta(args)?;
    let store = window_of_the_run_in_out(args, &config, store);
    super::no_stdout_directory(&args.out, "the run and its report")?;
    if args.out.is_file() {
        return Err(Error::param("out", format!("{} is a file; `clv run` writes a directory (run/ and report/ in it)", args.out.display())));
    }
    let quiet = args.quiet;
    let mut say = |msg: String| {
        if !quiet {
            clv::note!("clv run: {msg}");
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
    // The forward pass stops cleanly on a signal itself (below); afterwards one ends the
    // process, and the backward pass and analyses start over when the command is given again.
    let _signals = clv::stage::signals::ExplainOnSignals::install(&format!(
        "\nclv run: stopped by a signal; the forward pass is saved in {} up to its last checkpoint: give the same `clv run` command again to continue (the backward pass and the analyses start over)",
        args.out.join("run").display()
    ));
    let result = clv::stage::pipeline::run(&config, &store, &args.out, &mut feedback, &mut say).map_err(|e| match e {
        Error::Stopped { step, total, run, signal, .. } => Error::Stopped { step, total, run, signal, then: "give the same `clv run` command again to continue".into() },
        e => e,
    })?;
    if let Some(bar) = &feedback.bar {
        bar.finish_and_clear();
    }
    let clv_report = &result.clv;
    use clv::statistics::Estimate;
    let first = |v: &[f64], e: &[f64]| Estimate::or_unknown(v.first().zip(e.first()).map(|(&value, &stderr)| Estimate { value, stderr }));
    let window = clv_report.gs_window.as_ref();
    say(format!(
        "lambda_1 = {} (GS), {} (CLV), {} (GS over the CLV window); h_KS = {} (GS), {} (CLV), {} (GS over the CLV window)",
        first(&clv_report.gs_exponents, &clv_report.gs_stderr),
        first(&clv_report.exponents, &clv_report.stderr),
        window.map_or("unknown".into(), |w| first(&w.exponents, &w.stderr)),
        Estimate::or_unknown(clv_report.gs_ks_entropy),
        Estimate::or_unknown(clv_report.ks_entropy),
        Estimate::or_unknown(window.and_then(|w| w.ks_entropy))
    ));
    let gs = clv::report::SpectrumSummary::read(&clv::store::RunDir { path: result.run_dir.clone() }.spectrum_path()).ok();
    // The forward stage's warnings, which its own table would print (also atop the report).
    for w in gs.iter().flat_map(|g| &g.warnings) {
        say(format!("warning: {w}"));
    }
    if let Some(d) = gs.and_then(|g| g.blocks).and_then(|b| clv::stage::analyze::kernels::convergence::diagnose(&b.exponents, config.system.neutral())) {
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
