//! Every command of the README's shell blocks runs, in order, in one scratch directory, so
//! the README cannot rot. `clv` is the binary under test; `cargo` and `pip` lines are the
//! set-up itself and are skipped; `python3 scripts/...` lines run when python3 has the
//! packages.

mod common;
use std::path::Path;
use std::process::Command;

fn shell_commands(readme: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_sh = false;
    for line in readme.lines() {
        if line.starts_with("```") {
            in_sh = !in_sh && line.trim() == "```sh";
            continue;
        }
        if in_sh {
            let cmd = line.split(" # ").next().unwrap_or("").trim();
            if !cmd.is_empty() && !cmd.starts_with('#') {
                out.push(cmd.to_string());
            }
        }
    }
    out
}

#[test]
fn every_readme_command_runs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let commands = shell_commands(&readme);
    assert!(commands.len() >= 10, "README has {} commands", commands.len());
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_clv")).parent().unwrap().to_path_buf();
    let work = common::scratch("readme", "work");
    let python = common::python_has("mcap, cbor2, numpy");
    let mut ran = 0;
    for cmd in &commands {
        if cmd.starts_with("cargo ") || cmd.contains("pip install") || (cmd.starts_with("python3 ") && !python) {
            continue;
        }
        let cmd = cmd.replace("python3 scripts/", &format!("python3 {}/scripts/", root.display()));
        let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default());
        let out = Command::new("bash").args(["-o", "pipefail", "-c", &cmd]).current_dir(&work).env("PATH", path).output().unwrap();
        assert!(out.status.success(), "README command failed: {cmd}\n{}", String::from_utf8_lossy(&out.stderr));
        ran += 1;
    }
    assert!(ran >= 10, "only {ran} README commands ran");
    assert!(work.join("report40/index.html").exists() && work.join("report40-file/index.html").exists());
}
