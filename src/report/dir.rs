//! A report directory: index.html with every figure, caption and small table, summary.json,
//! and the CSV, PNG and SVG files of the analyses.
//!
//! It is written so that what is on disk never passes for what it is not
//! ([`begin_report`], [`write_report_file`]): when the first frame arrives, index.html is
//! replaced by a page that says the report is being written, and the earlier report's
//! summary.json and files go; summary.json, the mark of a finished report, is written last.
//! A report killed midway thus says so, and the command given again leaves exactly the
//! files of an uninterrupted one. Every file is written under a temporary name and renamed
//! into place (whole or absent when the process dies; a symbolic link in the way is
//! replaced, not written through), and only plain file names directly inside the report
//! directory are ever removed, whatever an edited summary.json lists. The files are not
//! fsynced: a report lost to a power cut is regenerated, not recovered. One writer at a
//! time: it holds a lock in the report directory from before its first look at it to its
//! end ([`lock_report`]), so that two processes never leave a mix of their reports.

use crate::config::RunConfig;
use crate::error::{Error, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What an analysis wrote: shown as one entry of index.html.
#[derive(Clone, Debug, Serialize)]
pub struct Produced {
    pub title: String,
    /// What was computed, how, and which figure of the paper it corresponds to.
    pub caption: String,
    /// Figure stems (stem.png and stem.svg exist).
    pub figures: Vec<String>,
    /// Table files (CSV, JSON).
    pub tables: Vec<String>,
}

/// Cells of one CSV line as the report writes them (RFC 4180: double-quoted cells may hold
/// commas, as modes.csv's "T(1,0)", and doubled quotes).
pub fn csv_cells(line: &str) -> Vec<String> {
    let (mut cells, mut cell, mut quoted) = (Vec::new(), String::new(), false);
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cell.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => cells.push(std::mem::take(&mut cell)),
            _ => cell.push(c),
        }
    }
    cells.push(cell);
    cells
}

/// A small CSV table (the paper's Tables I-III, the mode table) as HTML, numbers to six
/// significant digits; None for tables too large to read on a page (the CSV has them all).
fn html_table(csv: &str) -> Option<String> {
    const MAX_ROWS: usize = 24;
    const MAX_COLUMNS: usize = 18;
    let lines: Vec<&str> = csv.lines().collect();
    let cells = csv_cells;
    let header = cells(lines.first()?);
    if lines.len() < 2 || lines.len() > MAX_ROWS + 1 || header.len() > MAX_COLUMNS {
        return None;
    }
    let number = |c: &str| match c.parse::<f64>() {
        Ok(x) if c.contains(['e', '.']) && x.is_finite() => significant(x, 6),
        _ => escape(c),
    };
    let row = |cells: Vec<String>, tag: &str| format!("<tr>{}</tr>", cells.iter().map(|c| format!("<{tag}>{}</{tag}>", if tag == "th" { escape(c) } else { number(c) })).collect::<String>());
    let mut html = String::from("<table style=\"border-collapse:collapse;font-size:90%\" border=\"1\" cellpadding=\"3\">");
    html += &row(header, "th");
    for line in &lines[1..] {
        html += &row(cells(line), "td");
    }
    Some(html + "</table>\n")
}

/// `x` rounded to `digits` significant digits, written in its shortest form: plain between
/// 1e-3 and 1e6 (0.38, 1, 0.0454545), else in exponent form (3.69706e-4).
fn significant(x: f64, digits: usize) -> String {
    let rounded: f64 = format!("{x:.*e}", digits.max(1) - 1).parse().unwrap_or(x);
    if rounded == 0.0 || (1e-3..1e6).contains(&rounded.abs()) {
        format!("{rounded}")
    } else {
        format!("{rounded:e}")
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// The line of index.html that names the run a report is of (its configuration as JSON,
/// empty for a stream without one): what [`report_in`] reads back.
fn run_line(run: Option<&RunConfig>) -> String {
    let json = run.map(|c| serde_json::to_string(c).unwrap_or_default()).unwrap_or_default();
    format!("<p>Run: <code>{}</code></p>\n", escape(&json))
}

/// What the head of index.html says about the frames a report is of.
pub struct Head<'a> {
    /// Where the frames came from.
    pub source: &'a str,
    pub d: usize,
    pub k: usize,
    pub with_gs: bool,
    /// Which frames the vector statistics use, in words.
    pub sample: String,
    /// The configuration of the run the frames are of, if known.
    pub run: Option<&'a RunConfig>,
    /// Hard disks (the page states their units and vector ordering).
    pub disks: bool,
    /// The analyses' options, for summary.json.
    pub options: serde_json::Value,
    /// The stream was read to its end, undamaged: else the report, of the frames before the
    /// damage, stays unfinished (no summary.json), as where an analysis failed.
    pub whole: bool,
    /// What the frames cannot give (no GS vectors, k < D), and so this report leaves out.
    pub left_out: Vec<String>,
}

/// Write index.html (every entry of `produced` with its figures, caption and small tables)
/// and then summary.json, which marks the report finished.
/// `failed`: what the analyses that failed said; their sections are missing, and the report
/// stays unfinished (no summary.json, the page says so).
/// `frames`: how many were read, of steps `first..=last`.
#[allow(clippy::too_many_arguments)]
pub fn write_index(head: &Head, out: &Path, produced: &[Produced], warnings: &[String], failed: &[String], frames: u64, first: u64, last: u64) -> Result<()> {
    let finished = failed.is_empty() && head.whole;
    let title = if finished { "clv analyses" } else { "clv analyses: incomplete" };
    let mut html = String::from("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>") + title + "</title>\n<style>body{font-family:sans-serif;max-width:1000px;margin:auto;padding:1em} figure{margin:2em 0} img{max-width:100%} code{background:#eee}</style></head><body>\n";
    html += &format!(
        "<h1>Covariant Lyapunov vector analyses</h1>\n<p>Source: <code>{}</code>; {} frames (steps {}..{}), D = {}, k = {}{}; vector statistics use {}.</p>\n{}<p>Conventions: {}</p>\n",
        escape(head.source),
        frames,
        if frames > 0 { first } else { 0 },
        last,
        head.d,
        head.k,
        if head.with_gs { ", with Gram-Schmidt vectors" } else { "" },
        head.sample,
        run_line(head.run),
        if head.disks {
            "units σ = m = K/N = 1, exponents per unit time; step numbers count the relaxation steps too, and t = step × τ; indices i are 1-based as in the paper; vectors ordered (δq_x1, δq_y1, ..., δq_yN; δp_x1, ..., δp_yN); angles in radians, captions add degrees where the paper uses them."
        } else {
            "exponents per unit time (per iteration for a map); t = step × τ; indices i are 1-based."
        }
    );
    for w in warnings {
        html += &format!("<p style=\"border:2px solid #c00;padding:0.5em\"><strong>Warning.</strong> {}</p>\n", escape(w));
    }
    for l in &head.left_out {
        html += &format!("<p><strong>Not in this report.</strong> {}</p>\n", escape(l));
    }
    for f in failed {
        html += &format!("<p style=\"border:2px solid #c00;padding:0.5em\"><strong>Incomplete report.</strong> {}: its section is missing; give the command again with <code>--overwrite</code> once the cause is mended.</p>\n", escape(f));
    }
    let mut shown = std::collections::HashSet::new();
    for p in produced {
        html += &format!("<section><h2>{}</h2>\n", escape(&p.title));
        // The caption describes the entry's figures together: once, after them.
        for f in &p.figures {
            html += &format!("<figure><img src=\"{f}.png\" alt=\"{f}\"><figcaption>{f} (<a href=\"{f}.svg\">SVG</a>)</figcaption></figure>\n");
        }
        html += &format!("<p>{}</p>\n", escape(&p.caption));
        if !p.tables.is_empty() {
            let links: Vec<String> = p.tables.iter().map(|t| format!("<a href=\"{t}\">{t}</a>")).collect();
            html += &format!("<p>Numbers: {}</p>\n", links.join(", "));
        }
        for t in p.tables.iter().filter(|t| t.ends_with(".csv") && shown.insert(t.as_str())) {
            if let Some(table) = std::fs::read_to_string(out.join(t)).ok().and_then(|text| html_table(&text)) {
                html += &format!("<details open><summary>{t}</summary>\n{table}</details>\n");
            }
        }
        html += "</section>\n";
    }
    html += "<p>Everything above as JSON: <a href=\"summary.json\">summary.json</a>.</p>\n</body></html>\n";
    write_report_file(&out.join("index.html"), html.as_bytes())?;
    if !finished {
        return Ok(());
    }
    // Last: a report with a summary.json is finished.
    let summary = serde_json::json!({ "frames": frames, "first_step": first, "last_step": last, "options": head.options, "warnings": warnings, "left_out": head.left_out, "produced": produced });
    write_report_file(&out.join("summary.json"), &serde_json::to_vec_pretty(&summary).unwrap_or_default())?;
    let manifest = out.join(WRITING);
    std::fs::remove_file(&manifest).map_err(|e| Error::io(&manifest, e))
}

/// The suffix of the temporary names of [`write_report_file`] (after a leading dot).
const TMP_SUFFIX: &str = ".clv-tmp";
/// The names of the files a report being written has written so far, one a line; removed
/// once its summary.json is written.
const WRITING: &str = ".clv-writing";

/// Write one file of a report whole: under a temporary name beside it, renamed over `path`.
/// A killed process leaves the earlier file or the new one, never half of one, and a
/// symbolic link at `path` is replaced by the file instead of written through.
pub fn write_report_file(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write as _;
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    // Named in the manifest before it exists: a report killed before its summary.json
    // still tells the next one what to remove ([`begin_report`]).
    // One write of the whole line, under a lock: the analyses write their files from
    // threads of their own, and their names must not interleave.
    static MANIFEST: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let manifest = path.with_file_name(WRITING);
    {
        let _one_at_a_time = MANIFEST.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        std::fs::OpenOptions::new().create(true).append(true).open(&manifest).and_then(|mut f| f.write_all(format!("{name}\n").as_bytes())).map_err(|e| Error::io(&manifest, e))?;
    }
    let tmp = path.with_file_name(format!(".{name}{TMP_SUFFIX}"));
    // A leftover of a killed run: removed (a link itself, never its target), then created
    // anew, so that nothing already there is written through.
    let _ = std::fs::remove_file(&tmp);
    let written = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp).and_then(|mut f| f.write_all(bytes));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(&tmp, e));
    }
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
}

/// Whether `name` can be a file of a report: a plain name directly inside the report
/// directory (no directory part, not absolute, not hidden, not `..`).
fn is_report_name(name: &str) -> bool {
    let mut parts = Path::new(name).components();
    !name.starts_with('.') && !name.contains(['/', '\\']) && matches!((parts.next(), parts.next()), (Some(std::path::Component::Normal(n)), None) if n == name)
}

/// Remove the report file `name` from `out`: a regular file, or a symbolic link (the link,
/// never its target). A name that is not a report's ([`is_report_name`]), a directory, or a
/// missing file is left alone.
fn remove_report_file(out: &Path, name: &str) -> Result<()> {
    if !is_report_name(name) {
        return Ok(());
    }
    let path = out.join(name);
    match std::fs::symlink_metadata(&path) {
        Ok(m) if m.is_file() || m.is_symlink() => std::fs::remove_file(&path).map_err(|e| Error::io(&path, e)),
        _ => Ok(()),
    }
}

/// The page index.html shows while a report is written, and after a write that did not end.
fn unfinished_page(out: &Path, source: &str, run: Option<&RunConfig>) -> String {
    format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>clv analyses: incomplete</title></head><body>\n\
         <h1>Incomplete report</h1>\n<p>clv is writing this report (from <code>{}</code>), or was stopped before it finished \
         (a signal, an error, a full disk): the files here may be missing or partial, and there is no summary.json.</p>\n{}\
         <p>To write it again, give the command that wrote it once more with <code>--overwrite</code>: \
         <code>clv analyze SOURCE --out {} --overwrite</code> with the same options, or for the report of <code>clv run</code> the same <code>clv run</code> command.</p>\n</body></html>\n",
        escape(source),
        run_line(run),
        escape(&out.display().to_string())
    )
}

/// The lock file of a report directory ([`lock_report`]).
pub const LOCK: &str = ".clv-lock";

/// Exclusive right to write the report in a directory, held for a whole analysis: two
/// processes writing one report would leave a mix of both. Released, with its lock file,
/// when dropped; a directory it made and nothing was written into goes too.
pub struct ReportLock {
    lock: Option<crate::store::lock::WriteLock>,
    dir: PathBuf,
    made: bool,
}

impl Drop for ReportLock {
    fn drop(&mut self) {
        drop(self.lock.take());
        if self.made {
            // Only if empty: a refused or failed analysis leaves no directory behind.
            let _ = std::fs::remove_dir(&self.dir);
        }
    }
}

/// Lock the report directory `out` (made if missing) for the analyses, before anything in
/// it is written or removed: an OS file lock on `out/.clv-lock` ([`crate::store::lock`]),
/// which is not a report file ([`is_report_name`]), so that no report lists or removes it.
pub fn lock_report(out: &Path) -> Result<ReportLock> {
    let made = !out.exists();
    let path = out.join(LOCK);
    let unwritable = |e: std::io::Error| match e.raw_os_error() {
        Some(libc::EROFS | libc::EACCES | libc::EPERM) => Error::Other(format!("{}: {e}; a report cannot be written there: give --out a directory you can write", path.display())),
        _ => Error::io(&path, e),
    };
    let lock = crate::store::lock::take(&path, out, LOCKED_FOR, true, unwritable)?;
    Ok(ReportLock { lock: Some(lock), dir: out.to_path_buf(), made })
}

/// Refuse as [`lock_report`] would if another process is writing the report in `out` now:
/// for a check made before the lock that would otherwise give another reason (files in
/// `out`, which that process is writing).
pub fn refuse_if_being_written(out: &Path) -> Result<()> {
    crate::store::lock::refuse_if_held(&out.join(LOCK), out, LOCKED_FOR)
}

const LOCKED_FOR: &str = "analyses (or give this report another --out)";

/// Start writing a report into `out` (made if missing): index.html becomes a page that says
/// the report is incomplete, then the earlier report's summary.json and the files it lists
/// are removed, and temporary files a killed writer left. Files a report does not write
/// (notes of the user's own) stay. `run` is the configuration of the run the frames are
/// of, named in the page as in a finished report's.
pub fn begin_report(out: &Path, source: &str, run: Option<&RunConfig>) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let mut earlier = report_files(out).unwrap_or_default();
    // The files of a report that was killed before its summary.json listed them.
    let manifest = out.join(WRITING);
    if let Ok(text) = std::fs::read_to_string(&manifest) {
        earlier.extend(text.lines().filter(|n| is_report_name(n)).map(String::from));
    }
    // Still listed while they go: a kill in the middle of the removal leaves them named.
    let listed: String = earlier.iter().map(|n| format!("{n}\n")).collect();
    crate::store::run::write_atomic(&manifest, listed.as_bytes())?;
    write_report_file(&out.join("index.html"), unfinished_page(out, source, run).as_bytes())?;
    remove_report_file(out, "summary.json")?;
    for name in earlier.iter().filter(|n| *n != "index.html") {
        remove_report_file(out, name)?;
    }
    for entry in std::fs::read_dir(out).map_err(|e| Error::io(out, e))?.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.ends_with(TMP_SUFFIX) {
            let path = entry.path();
            if entry.file_type().is_ok_and(|t| t.is_file() || t.is_symlink()) {
                std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
            }
        }
    }
    Ok(())
}

/// Write a CSV table: a header line and rows of numbers (full precision).
pub fn write_csv(path: &Path, header: &[&str], rows: impl IntoIterator<Item = Vec<f64>>) -> Result<()> {
    use std::fmt::Write as _;
    let mut s = header.join(",");
    s.push('\n');
    for row in rows {
        let cells: Vec<String> = row.iter().map(|&x| csv_number(x)).collect();
        let _ = writeln!(s, "{}", cells.join(","));
    }
    write_report_file(path, s.as_bytes())
}

/// Write a CSV whose cells are already formatted (text columns such as mode names); cells
/// with commas or quotes are quoted (RFC 4180).
pub fn write_text_csv(path: &Path, header: &[&str], rows: &[Vec<String>]) -> Result<()> {
    let quote = |c: &str| if c.contains([',', '"', '\n']) { format!("\"{}\"", c.replace('"', "\"\"")) } else { c.to_string() };
    let line = |cells: Vec<String>| cells.join(",") + "\n";
    let mut s = line(header.iter().map(|c| quote(c)).collect());
    for row in rows {
        s += &line(row.iter().map(|c| quote(c)).collect());
    }
    write_report_file(path, s.as_bytes())
}

/// A CSV cell: whole numbers (indices, steps, counts, flags) as integers, `78` rather than
/// `7.8e1`, so that they read as such (grep, pandas); everything else in the shortest
/// exponent form that reads back to the same bits.
pub fn csv_number(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else {
        format!("{x:e}")
    }
}

/// The files of the report in `out`, as its summary.json lists them (index.html and
/// summary.json included), but only names that can be a report's ([`is_report_name`]: an
/// edited summary.json cannot name a file elsewhere); None without a readable summary.
pub fn report_files(out: &Path) -> Option<std::collections::BTreeSet<String>> {
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).ok()?).ok()?;
    let mut files: std::collections::BTreeSet<String> = ["index.html".to_string(), "summary.json".to_string()].into();
    for p in summary["produced"].as_array()? {
        let names = |key: &str| p[key].as_array().into_iter().flatten().filter_map(|v| v.as_str().map(String::from)).collect::<Vec<_>>();
        files.extend(names("figures").into_iter().flat_map(|stem| [format!("{stem}.png"), format!("{stem}.svg")]));
        files.extend(names("tables"));
    }
    files.retain(|name| is_report_name(name));
    Some(files)
}

/// What a directory holds where a report is to be written ([`report_in`]).
#[derive(Debug, PartialEq)]
pub enum ReportDir {
    /// No report and no other file: missing, empty, or only what a report's writer leaves
    /// before its first file (its manifest, temporary files).
    Empty,
    /// A report of clv, finished or not, with the configuration of the run its frames were
    /// of (None for a stream without one, and for an incomplete report of a build before
    /// incomplete reports named their run).
    Report { run: Option<RunConfig>, finished: bool },
    /// Files, but no index.html of a clv report.
    Other,
}

/// What the directory `out` holds: a report (of which run), nothing, or other files.
pub fn report_in(out: &Path) -> ReportDir {
    let Ok(entries) = std::fs::read_dir(out) else { return ReportDir::Empty };
    // The manifest is written whole by `write_atomic`, through WRITING.tmp.
    let ours = |name: &str| name == WRITING || name.strip_prefix(WRITING) == Some(".tmp") || name == LOCK || (name.starts_with('.') && name.ends_with(TMP_SUFFIX));
    if entries.flatten().all(|e| ours(&e.file_name().to_string_lossy())) {
        return ReportDir::Empty;
    }
    let Ok(html) = std::fs::read_to_string(out.join("index.html")) else { return ReportDir::Other };
    if !html.contains("<title>clv analyses") {
        return ReportDir::Other;
    }
    let unescape = |s: &str| s.replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&");
    let run = html
        .split_once("<p>Run: <code>")
        .and_then(|(_, rest)| rest.split_once("</code>"))
        .and_then(|(json, _)| serde_json::from_str(&unescape(json)).ok());
    let finished = out.join("summary.json").is_file() && !html.contains("<title>clv analyses: incomplete");
    ReportDir::Report { run, finished }
}

/// Save a figure or panels of figures as SVG and PNG ([`write_report_file`]).
pub fn save_figure(fig: &impl crate::report::plot::Image, out: &Path, stem: &str) -> Result<()> {
    write_report_file(&out.join(format!("{stem}.svg")), fig.svg().as_bytes())?;
    write_report_file(&out.join(format!("{stem}.png")), &fig.png())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A report names its run in index.html, finished or still being written, and
    /// [`report_in`] reads it back; a directory without a report's index is not a report,
    /// and one with only a killed writer's manifest and lock file is empty.
    #[test]
    fn a_report_names_its_run() {
        let out = std::env::temp_dir().join(format!("clv-report-run-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        assert_eq!(report_in(&out), ReportDir::Empty);
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(out.join(WRITING), "spectrum.csv\n").unwrap();
        std::fs::write(out.join(LOCK), "").unwrap();
        assert_eq!(report_in(&out), ReportDir::Empty, "a killed writer's manifest and lock file are no report");
        let config = RunConfig::preset("default").unwrap();
        begin_report(&out, "test", Some(&config)).unwrap();
        assert_eq!(report_in(&out), ReportDir::Report { run: Some(config.clone()), finished: false });
        begin_report(&out, "test", None).unwrap();
        assert_eq!(report_in(&out), ReportDir::Report { run: None, finished: false });
        let index = format!("<!DOCTYPE html>\n<html><head><title>clv analyses</title></head><body>\n{}</body></html>\n", run_line(Some(&config)));
        std::fs::write(out.join("index.html"), index).unwrap();
        std::fs::write(out.join("summary.json"), "{}").unwrap();
        assert_eq!(report_in(&out), ReportDir::Report { run: Some(config), finished: true });
        std::fs::write(out.join("index.html"), "<html>my own page</html>").unwrap();
        assert_eq!(report_in(&out), ReportDir::Other);
        std::fs::remove_dir_all(&out).unwrap();
    }

    #[test]
    fn csv_numbers_read_back_exactly_and_whole_numbers_as_integers() {
        for x in [78.0, -3.0, 0.0, 1e14, 0.1, 1.0 / 3.0, -2.5e-17, 1e15, 6.02e23, f64::NAN] {
            let cell = csv_number(x);
            let back: f64 = cell.parse().unwrap();
            assert!(back == x || (x.is_nan() && back.is_nan()), "{x} -> {cell}");
        }
        assert_eq!((csv_number(78.0).as_str(), csv_number(10450.0).as_str(), csv_number(0.5).as_str()), ("78", "10450", "5e-1"));
    }

    #[test]
    fn small_tables_appear_in_the_page_to_six_digits() {
        assert_eq!((significant(0.123456789, 6).as_str(), significant(-12345.678, 6).as_str(), significant(2.0e-15, 6).as_str()), ("0.123457", "-12345.7", "2e-15"));
        assert_eq!((significant(0.99999999, 6).as_str(), significant(0.38, 6).as_str(), significant(3.697061e-4, 6).as_str()), ("1", "0.38", "3.69706e-4"));
        let table = html_table("side,first,name,lambda\n+,76,\"T(1,0)\",8.847895660242466e-1\n").unwrap();
        assert!(table.contains("<th>name</th>") && table.contains("<td>T(1,0)</td>") && table.contains("<td>0.88479</td>") && table.contains("<td>76</td>"), "{table}");
        let long: String = std::iter::once("i,x\n".to_string()).chain((0..100).map(|i| format!("{i},1e0\n"))).collect();
        assert!(html_table(&long).is_none());
    }

    #[test]
    fn only_plain_names_inside_the_report_are_report_files() {
        for name in ["spectrum.csv", "fig2_spectrum.png", "a..b.csv"] {
            assert!(is_report_name(name), "{name}");
        }
        for name in ["", ".", "..", "../victim.txt", "/etc/passwd", "sub/x.csv", "a\\b.csv", ".hidden", ".x.clv-tmp"] {
            assert!(!is_report_name(name), "{name}");
        }
    }

    #[test]
    fn report_files_replace_links_and_removal_spares_their_targets() {
        let dir = std::env::temp_dir().join(format!("clv-report-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let out = dir.join("report");
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(dir.join("target.txt"), "theirs").unwrap();
        std::os::unix::fs::symlink("../target.txt", out.join("a.csv")).unwrap();
        write_report_file(&out.join("a.csv"), b"ours").unwrap();
        assert_eq!(std::fs::read_to_string(dir.join("target.txt")).unwrap(), "theirs");
        assert!(std::fs::symlink_metadata(out.join("a.csv")).unwrap().is_file());
        std::os::unix::fs::symlink("../target.txt", out.join("b.csv")).unwrap();
        std::fs::create_dir(out.join("c.csv")).unwrap();
        for name in ["b.csv", "c.csv", "../target.txt", "missing.csv"] {
            remove_report_file(&out, name).unwrap();
        }
        assert!(std::fs::symlink_metadata(out.join("b.csv")).is_err() && out.join("c.csv").is_dir());
        assert_eq!(std::fs::read_to_string(dir.join("target.txt")).unwrap(), "theirs");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Report files written from many threads at once are each named whole on their own
    /// line of the manifest, and a report begun over an earlier one keeps the earlier
    /// files named there until they are gone (a kill midway leaves them listed).
    #[test]
    fn the_manifest_names_every_file_whole() {
        let out = std::env::temp_dir().join(format!("clv-manifest-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir_all(&out).unwrap();
        let names: Vec<String> = (0..64).map(|i| format!("table_with_a_long_name_{i:03}.csv")).collect();
        std::thread::scope(|s| {
            for chunk in names.chunks(8) {
                let out = &out;
                s.spawn(move || chunk.iter().for_each(|n| write_report_file(&out.join(n), b"x").unwrap()));
            }
        });
        let listed: std::collections::BTreeSet<String> = std::fs::read_to_string(out.join(WRITING)).unwrap().lines().map(String::from).collect();
        assert_eq!(listed, names.iter().cloned().collect());
        begin_report(&out, "test", None).unwrap();
        let listed = std::fs::read_to_string(out.join(WRITING)).unwrap();
        assert!(names.iter().all(|n| listed.lines().any(|l| l == n) && !out.join(n).exists()), "{listed}");
        std::fs::remove_dir_all(&out).unwrap();
    }
}
