//! Configuration files: a small TOML subset whose keys are the command-line flags.
//!
//! Why flags: one vocabulary for the command line and files. A file is expanded into
//! `--key value` arguments placed before the command line's own, so flags given on the
//! command line override the file. Supported TOML: `[section]` headers (for readability
//! only, and only those `clv config` writes: [system], [run], [store]), `key = value` with
//! bare or quoted keys, numbers (with `_` between digits), "basic" and 'literal' strings
//! without escapes, booleans for switches, and `#` comments.

use clv::config::{RunConfig, SystemConfig};
use clv::error::{Error, Result};
use clv::store::run::StoreConfig;
use std::fmt::Write;
use std::path::Path;

/// The section headers a file may have; they do not change what a key means.
const SECTIONS: [&str; 3] = ["system", "run", "store"];

/// The arguments a configuration file stands for. `known` lists the accepted keys.
pub fn expand(path: &Path, known: &[String]) -> Result<Vec<String>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut args = Vec::new();
    let mut seen: Vec<(String, usize)> = Vec::new();
    for (no, raw) in text.lines().enumerate() {
        let line = strip_comment(raw).trim();
        let bad = |msg: String| Error::Other(format!("{}:{}: {msg}", path.display(), no + 1));
        if line.is_empty() {
            continue;
        }
        if let Some(section) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            // A misspelt or foreign section would otherwise pass silently with its keys.
            if !SECTIONS.contains(&section.trim()) {
                return Err(bad(format!("unknown section [{}]; sections only group the settings for reading, and are [system], [run] and [store]", section.trim())));
            }
            continue;
        }
        let (key, value) = line.split_once('=').ok_or_else(|| bad(format!("expected `key = value`, found {line:?}")))?;
        let key = unquoted(key.trim()).unwrap_or(key.trim()).replace('_', "-");
        if !known.contains(&key) {
            return Err(bad(format!("unknown setting {key:?}; valid settings: {}", known.join(", "))));
        }
        if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
            return Err(bad(format!("{key} is set again (first on line {first}); a setting may appear once")));
        }
        seen.push((key.clone(), no + 1));
        let value = value.trim();
        let value = match unquoted(value) {
            Some(s) if s.contains('\\') && value.starts_with('"') => return Err(bad(format!("the value of {key} has an escape sequence, which these files do not read; write it as a 'literal string'"))),
            Some(s) => s.to_string(),
            None if value == "true" || value == "false" => value.to_string(),
            None => number(value).ok_or_else(|| {
                let takes_fractions = ["aspect", "henon-a", "henon-b", "lorenz-sigma", "lorenz-rho", "lorenz-beta"].contains(&key.as_str());
                let fraction = if value.contains('/') && takes_fractions { format!(" (a fraction is written as a string: {key} = \"{value}\")") } else { String::new() };
                bad(format!("the value of {key} must be a number, a \"string\" or true/false, found {value:?}{fraction}"))
            })?,
        };
        match value.as_str() {
            "true" => args.push(format!("--{key}")),
            // Kept, not dropped: a setting that takes a value refuses it (it was silently
            // left at its default).
            "false" => args.push(format!("--{key}=false")),
            // One argument `--key=value`: a negative number is a value, not a flag.
            _ => args.push(format!("--{key}={value}")),
        }
    }
    Ok(args)
}

/// The line (1-based) of `path` that sets `key`, for an error about its value.
pub fn line_of(path: &Path, key: &str) -> Option<usize> {
    let text = std::fs::read_to_string(path).ok()?;
    text.lines().position(|raw| strip_comment(raw).split_once('=').is_some_and(|(k, _)| unquoted(k.trim()).unwrap_or(k.trim()).replace('_', "-") == key)).map(|i| i + 1)
}

fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    for (i, c) in line.char_indices() {
        match (c, quote) {
            ('"' | '\'', None) => quote = Some(c),
            (c, Some(q)) if c == q => quote = None,
            ('#', None) => return &line[..i],
            _ => {}
        }
    }
    line
}

/// The text inside "..." or '...', if `s` is quoted.
fn unquoted(s: &str) -> Option<&str> {
    ['"', '\''].into_iter().find_map(|q| s.strip_prefix(q)?.strip_suffix(q))
}

/// A TOML number as the command line takes it: underscores between digits dropped.
fn number(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let between_digits = |i: usize| i > 0 && i + 1 < b.len() && b[i - 1].is_ascii_digit() && b[i + 1].is_ascii_digit();
    if (0..b.len()).any(|i| b[i] == b'_' && !between_digits(i)) {
        return None;
    }
    let plain = s.replace('_', "");
    plain.parse::<f64>().is_ok().then_some(plain)
}

/// A configuration file for a run (what `clv config --preset NAME` prints).
pub fn render(name: &str, config: &RunConfig, store: &StoreConfig) -> String {
    let mut s = format!("# clv configuration: preset {name:?}. Keys are the flags of `clv forward`;\n# use with `clv forward --config FILE --out DIR` or `clv run --config FILE`.\n\n[system]\n");
    match &config.system {
        SystemConfig::Henon { a, b } => {
            let _ = writeln!(s, "system = \"henon\"\nhenon-a = {a}\nhenon-b = {b}    # x' = a - x^2 + b y, y' = x");
        }
        SystemConfig::Lorenz { sigma, rho, beta } => {
            let _ = writeln!(s, "system = \"lorenz\"\nlorenz-sigma = {sigma}\nlorenz-rho = {rho}\nlorenz-beta = {beta}    # x' = sigma (y - x), y' = x (rho - z) - y, z' = x y - beta z");
        }
        SystemConfig::Disks { n, density, aspect, .. } => {
            let _ = writeln!(s, "system = \"disks\"\nn = {n}\ndensity = {density}\naspect = {aspect}    # Ly/Lx");
        }
    }
    // Settings at their defaults are written as comments, so that they keep following the
    // settings they derive from when those are edited (k = D follows n; the CLV window
    // follows steps).
    let at_default = |default: bool| if default { "# " } else { "" };
    let derived = StoreConfig::for_run(config);
    let _ = writeln!(
        s,
        "\n[run]\n{}tau = {}    # default: the system's (0.6 for disks, 1 for Henon, 0.1 for the classic Lorenz flow)\nrelax-steps = {}\nsteps = {}\n{}vectors = {}    # default: all, k = D\nseed = {}\nthreads = {}\nblocks = {}",
        at_default(config.tau == config.system.default_tau()),
        config.tau,
        config.relax_steps,
        config.steps,
        at_default(config.vectors == config.system.dim()),
        config.vectors,
        config.seed,
        config.threads,
        config.blocks
    );
    let _ = writeln!(
        s,
        "\n[store]\n{}checkpoint-every = {}    # default: 100, or the whole run where it is shorter\nsegment-checkpoints = {}\n{}clv-steps = {}    # default: a tenth of relax-steps + steps, at most 2/3 of steps\n{}transient = {}    # default: half of clv-steps",
        at_default(store.checkpoint_every == derived.checkpoint_every),
        store.checkpoint_every,
        store.segment_checkpoints,
        at_default(store.clv_steps == derived.clv_steps),
        store.clv_steps,
        at_default(store.transient == derived.transient && store.clv_steps == derived.clv_steps),
        store.transient
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_render_to_files_that_expand_to_flags() {
        let dir = std::env::temp_dir().join(format!("clv-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let config = RunConfig::preset("paper").unwrap();
        let text = render("paper", &config, &StoreConfig::for_run(&config));
        let path = dir.join("paper.toml");
        std::fs::write(&path, &text).unwrap();
        let known: Vec<String> = ["system", "n", "density", "aspect", "tau", "relax-steps", "steps", "vectors", "seed", "threads", "blocks", "checkpoint-every", "segment-checkpoints", "clv-steps", "transient"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let args = expand(&path, &known).unwrap();
        let joined = args.join(" ");
        assert!(joined.contains("--n=198") && joined.contains("--steps=240000") && joined.contains("--system=disks"), "{joined}");
        // Defaults are comments: k = D and the CLV window follow n and steps when edited.
        assert!(text.contains("# vectors = 792") && text.contains("# clv-steps = 25000") && text.contains("# transient = 12500") && text.contains("# tau = 0.6"), "{text}");
        assert!(render("paper", &RunConfig { tau: 0.5, ..config.clone() }, &StoreConfig::for_run(&config)).contains("\ntau = 0.5"), "a tau of its own is written");
        assert!(!joined.contains("--vectors") && !joined.contains("--clv-steps") && !joined.contains("--transient"), "{joined}");
        let mut store = StoreConfig::for_run(&config);
        store.clv_steps = 1000;
        let args = {
            std::fs::write(&path, render("paper", &config, &store)).unwrap();
            expand(&path, &known).unwrap().join(" ")
        };
        assert!(args.contains("--clv-steps=1000") && args.contains("--transient=12500"), "a window of its own is written: {args}");
        std::fs::write(&path, "[run]\nsteps = 10 # comment\nbogus = 3\n").unwrap();
        let err = expand(&path, &known).unwrap_err().to_string();
        assert!(err.contains("paper.toml:3") && err.contains("bogus") && err.contains("steps"), "{err}");
        std::fs::write(&path, "name = \"a # b\"\n").unwrap();
        assert!(expand(&path, &["name".to_string()]).unwrap() == ["--name=a # b"]);
        // A negative number is the value, not a flag of its own.
        std::fs::write(&path, "n = -8\n").unwrap();
        assert_eq!(expand(&path, &known).unwrap(), ["--n=-8"]);
        // Quoted keys, literal strings and underscores between digits are TOML too.
        std::fs::write(&path, "\"n\" = 1_000\n'system' = 'disks' # a comment\ntau = 0.6\n").unwrap();
        assert_eq!(expand(&path, &known).unwrap(), ["--n=1000", "--system=disks", "--tau=0.6"]);
        for bad in ["n = 1__0\n", "n = _10\n", "n = 10_\n", "system = \"dis\\\"ks\"\n"] {
            std::fs::write(&path, bad).unwrap();
            assert!(expand(&path, &known).is_err(), "{bad:?}");
        }
        std::fs::write(&path, "steps = ten\n").unwrap();
        assert!(expand(&path, &known).unwrap_err().to_string().contains("must be a number"));
        // A fraction, which the flags take, is a string in TOML.
        std::fs::write(&path, "aspect = 2/11\n").unwrap();
        assert!(expand(&path, &known).unwrap_err().to_string().contains("(a fraction is written as a string: aspect = \"2/11\")"));
        std::fs::write(&path, "tau = 1/10\n").unwrap();
        assert!(!expand(&path, &known).unwrap_err().to_string().contains("a fraction"), "--tau takes no fraction");
        std::fs::write(&path, "aspect = \"2/11\"\n").unwrap();
        assert_eq!(expand(&path, &known).unwrap(), ["--aspect=2/11"]);
        // A setting given twice is refused (TOML forbids it; which one wins would be a guess).
        std::fs::write(&path, "steps = 10\n[store]\nsteps = 20\n").unwrap();
        let err = expand(&path, &known).unwrap_err().to_string();
        assert!(err.contains("paper.toml:3") && err.contains("first on line 1"), "{err}");
        // A misspelt section is refused, not read as a group of the known ones.
        std::fs::write(&path, "[ run ]\nsteps = 10\n[sytem]\nn = 8\n").unwrap();
        let err = expand(&path, &known).unwrap_err().to_string();
        assert!(err.contains("paper.toml:3") && err.contains("[sytem]") && err.contains("[store]"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
