//! The `clv` command line: flags are parsed into configurations and handed to the stages.
//! Each subcommand's file holds its flags and what it does with them; this one the command
//! table, the expansion of `--config FILE`, and what the subcommands share.

mod analyze;
mod backward;
mod bench;
mod config_file;
mod forward;
mod inspect;
mod run;

use analyze::AnalyzeArgs;
use backward::BackwardArgs;
use bench::BenchArgs;
use clap::{ArgMatches, Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use clv::config::RunConfig;
use clv::{Error, Result};
use forward::ForwardArgs;
use indicatif::ProgressBar;
use inspect::InspectArgs;
use run::RunArgs;
use std::path::PathBuf;

#[derive(Parser)]
#[command(name = "clv", version, about = "Lyapunov spectra, Gram-Schmidt and covariant Lyapunov vectors of hard disks and maps")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

// One Command is parsed per process: its size does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
pub enum Command {
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
pub struct CombineArgs {
    /// Finished runs: run directories or their spectrum.json files (e.g. runs/seed-*).
    #[arg(required = true)]
    pub runs: Vec<PathBuf>,
    /// Print one JSON object to stdout instead of the table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args)]
pub struct ConfigArgs {
    /// Embedded configuration: default, paper, henon or lorenz.
    #[arg(long, default_value = "default")]
    pub preset: String,
}

/// A progress bar for `what`, unless the command is --quiet.
pub fn progress(what: &str, quiet: bool) -> Option<ProgressBar> {
    if quiet {
        return None;
    }
    Some(clv::report::progress::steps(what))
}

/// The one line of a clap error that says what is wrong (without usage and hints).
/// The first line of clap's message, with the list a line ending in ':' introduces (the
/// missing arguments of "the following required arguments were not provided:").
pub fn first_line(e: &clap::Error) -> String {
    let text = e.to_string();
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let first = lines.next().unwrap_or_default().trim_start_matches("error: ").to_string();
    if first.ends_with(':') {
        let list: Vec<&str> = lines.take_while(|l| l.starts_with('-') || l.starts_with('<')).collect();
        return format!("{first} {}", list.join(", "));
    }
    first
}

/// The settings a configuration file may hold: the flags of `clv forward` that define a run.
pub fn config_keys() -> Vec<String> {
    let cmd = Cli::command();
    let forward = cmd.find_subcommand("forward").expect("forward exists");
    forward
        .get_arguments()
        .filter_map(|a| a.get_long())
        .filter(|l| !["config", "out", "resume", "json", "quiet", "help"].contains(l))
        .map(String::from)
        .collect()
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
        let given = if a == "--config" { it.next().cloned() } else { a.strip_prefix("--config=").map(String::from) };
        match (given, &file) {
            (Some(_), Some(first)) => return Err(Error::param("config", format!("given twice (first {first}); one file holds a run's settings, and flags after it change them"))),
            (Some(f), None) => file = Some(f),
            (None, _) => rest.push(a.clone()),
        }
    }
    let Some(file) = file else { return Ok(raw) };
    let mut argv = raw[..2].to_vec();
    argv.extend(forward_flags_of_file(std::path::Path::new(&file))?);
    argv.extend(rest);
    // Kept for the command, which names the file in errors of the values it gave.
    argv.extend(["--config".to_string(), file]);
    Ok(argv)
}

/// The flags of `clv forward` a configuration file gives. A value clap refuses is the
/// file's error, named with its line, not the command line's.
pub fn forward_flags_of_file(file: &std::path::Path) -> Result<Vec<String>> {
    let flags = config_file::expand(file, &config_keys())?;
    let parse = |flags: &[String]| Cli::try_parse_from(["clv".to_string(), "forward".to_string()].iter().chain(flags));
    if let Err(e) = parse(&flags) {
        // The setting clap names, if the file gives it; else the first that fails alone
        // (which may be one that only needs another: --lx without --ly).
        let named = e.get(clap::error::ContextKind::InvalidArg).map(|a| a.to_string()).and_then(|a| Some(a.strip_prefix("--")?.split([' ', '=']).next()?.to_string()));
        let given = |k: &str| flags.iter().any(|f| *f == format!("--{k}") || f.starts_with(&format!("--{k}=")));
        let alone = || flags.iter().find(|f| parse(std::slice::from_ref(f)).is_err()).and_then(|f| f.strip_prefix("--")).and_then(|f| f.split('=').next()).map(String::from);
        let key = named.filter(|k| given(k)).or_else(alone);
        let key = key.as_deref();
        let line = key.and_then(|k| config_file::line_of(file, k)).map(|l| format!(":{l}")).unwrap_or_default();
        let boolean = |k: &&str| (e.kind() == clap::error::ErrorKind::InvalidValue && flags.contains(&format!("--{k}"))) || flags.contains(&format!("--{k}=false"));
        if let Some(k) = key.filter(boolean) {
            return Err(Error::Other(format!("{}{line}: {k} takes a value, not true or false (those are for switches)", file.display())));
        }
        return Err(Error::Other(format!("{}{line}: {}", file.display(), first_line(&e))));
    }
    Ok(flags)
}

/// Whether `args` name the flag --`name` (alone, or as --`name`=VALUE).
pub fn names_flag<S: AsRef<str>>(args: impl IntoIterator<Item = S>, name: &str) -> bool {
    let flag = format!("--{name}");
    args.into_iter().any(|a| a.as_ref() == flag || a.as_ref().strip_prefix(flag.as_str()).is_some_and(|rest| rest.starts_with('=')))
}

/// A value that a configuration file gave and the stages refused is the file's error, named
/// with its line; `given` tells whether the command line named the flag itself (then it is
/// the flag's), and a setting the file does not hold is a default's (the flag's too).
pub fn blame_file(e: Error, file: Option<&std::path::Path>, given: impl Fn(&str) -> bool) -> Error {
    match (e, file) {
        (Error::Param { name, msg }, Some(file)) if !given(name) => match config_file::line_of(file, name) {
            Some(line) => Error::Other(format!("{}:{line}: invalid setting {name}: {msg}", file.display())),
            None => Error::Param { name, msg },
        },
        (e, _) => e,
    }
}

/// The command line, with a `--config FILE` of `clv forward` expanded. Clap's own errors
/// (and --help, --version) exit here, as clap does, except that help or a version that
/// could not be written to a file or pipe is an error (clap would exit 0).
pub fn parse(raw: Vec<String>) -> Result<(Cli, ArgMatches)> {
    use std::io::IsTerminal;
    let matches = match Cli::command().try_get_matches_from(expand_config(raw)?) {
        Ok(matches) => matches,
        Err(e) if e.use_stderr() || std::io::stdout().is_terminal() => e.exit(),
        Err(e) => {
            emit(&e.render().to_string())?;
            std::process::exit(0)
        }
    };
    match Cli::from_arg_matches(&matches) {
        Ok(cli) => Ok((cli, matches)),
        Err(e) => e.exit(),
    }
}

/// Run the parsed subcommand.
pub fn execute(cli: &Cli, matches: &ArgMatches) -> Result<()> {
    let sub = |name| matches.subcommand_matches(name).expect("subcommand parsed");
    let result = match &cli.command {
        Command::Forward(args) => forward::forward(args, sub("forward")),
        Command::Backward(args) => backward::backward(args, sub("backward")),
        Command::Inspect(args) => inspect::inspect(args),
        Command::Analyze(args) => analyze::analyze(args),
        Command::Run(args) => run::run(args, sub("run")),
        Command::Combine(args) => clv::report::combine::combine(&args.runs).and_then(|c| if args.json { print_json(&c) } else { emit(&c.table()) }),
        Command::Bench(args) => bench::bench(args),
        Command::Config(args) => RunConfig::preset(&args.preset).and_then(|c| emit(&config_file::render(&args.preset, &c, &clv::store::run::StoreConfig::for_run(&c)))),
    };
    result.map_err(|e| e.on_full_disk(|| how_to_continue(&cli.command)))
}

/// What a person does to continue a command a full disk stopped, once there is space.
fn how_to_continue(command: &Command) -> String {
    match command {
        // An extension is continued by its own command (the new length is in no file yet
        // when the disk fills before its run.json is written).
        Command::Forward(args) if args.resume.is_some() && names_flag(std::env::args(), "steps") => {
            let window = [("clv-steps", args.clv_steps), ("transient", args.transient)].into_iter().filter_map(|(flag, v)| v.map(|v| format!(" --{flag} {v}"))).collect::<String>();
            format!("continue with `clv forward --resume {} --steps {}{window}`", args.resume.as_ref().map_or(String::new(), |r| r.display().to_string()), args.steps)
        }
        Command::Forward(args) => match args.resume.as_ref().or(args.out.as_ref()) {
            Some(run) => format!("continue with `clv forward --resume {}`", run.display()),
            None => "give the command again".into(),
        },
        // A stream's frames went to its reader: continued, it would carry only the rest.
        Command::Backward(args) if args.out.as_deref() == Some(std::path::Path::new("-")) => {
            format!("start the stream again (`clv backward {} --out - ...`, without --resume, for the whole window)", args.dir.display())
        }
        Command::Backward(args) => format!(
            "continue with `clv backward {} --resume` (without --resume if it says no sweep was recorded)",
            args.dir.display()
        ),
        Command::Analyze(_) => "give the command again with --overwrite, which replaces the unfinished report".into(),
        Command::Run(_) => "give the same `clv run` command again: it continues where it stopped".into(),
        _ => "give the command again".into(),
    }
}

/// Refuse `--out -` where a directory is written (`-` is standard output only for
/// `clv backward`'s frame stream); `what` names what goes there.
pub fn no_stdout_directory(out: &std::path::Path, what: &str) -> Result<()> {
    if out == std::path::Path::new("-") {
        return Err(Error::param("out", format!("- is standard output, where {what} cannot go: it is a directory of files; give a directory (only `clv backward --out -` streams)")));
    }
    Ok(())
}

/// `found` as one JSON object on standard output (every subcommand's --json).
pub fn print_json<T: serde::Serialize>(found: &T) -> Result<()> {
    emit(&(serde_json::to_string(found).map_err(|e| Error::Other(e.to_string()))? + "\n"))
}

/// `text` on standard output. A reader that has gone before it was all written is an error
/// that exits as a writer killed by SIGPIPE (141), as other tools do: a script must not
/// take a result that never arrived (`clv forward` without --out keeps nothing else) for
/// one that did.
pub fn emit(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(Error::OutputClosed { what: "the output was written whole".into(), then: "what it did not read is not shown".into() }),
        // Printed last, after the command's work: files it wrote are complete, and resuming
        // (what a full disk's message would say) has nothing to do.
        written => written.map_err(|e| {
            Error::Other(format!(
                "writing to standard output failed ({e}; a full disk or quota where it goes, such as a batch job's log?): what the command printed there is incomplete, the files it wrote are complete. \
                 Where the printed output was the result (a run without --out, `clv config > FILE`), give the command again once there is space"
            ))
        }),
    }
}
