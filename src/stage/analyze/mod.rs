//! The analyses: independent consumers of the CLV frame stream, each on its own thread.
//!
//! Why this shape: the backward stage produces frames one at a time and the paper's
//! analyses are time averages or histograms over them, so each analysis is a consumer that
//! folds frames into its own state and writes its numbers and figures at the end. The
//! [`Analyzer`] feeds every consumer over its own bounded channel (frames are shared through
//! `Arc`, never copied per consumer; a slow analysis slows the stream instead of growing a
//! queue). An analysis is one file with a `new` function listed in [`registry`]: adding one
//! touches no other.
//!
//! The pure numerics live in [`kernels`]; the files next to this one turn them into
//! consumers, tables (CSV, JSON) and figures (PNG, SVG).
//!
//! What limits a report as a whole is said once, at its head (index.html, summary.json): a
//! stream that covers less than the window its metadata describes, such as one continued
//! with `clv backward --resume`, would otherwise give a report that looks complete.
//!
//! A report directory is written so that what is on disk never passes for what it is not
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

pub mod convergence;
pub mod henon;
pub mod kernels;
pub mod local_exponents;
pub mod localization;
pub mod mode_steps;
pub mod modes;
pub mod nullspace;
pub mod overlaps;
pub mod projections;
pub mod spectrum;
#[cfg(test)]
mod testing;
pub mod transversality;

use super::backward::{BackwardOptions, Window};
use super::frame::{multiples_in, on_stride, Frame};
use crate::config::RunConfig;
use crate::error::{Error, Result};
use crate::report::SpectrumSummary;
use crate::store::frames::{Flow, StreamInfo};
use crate::store::run::RunMeta;
use crossbeam_channel::{bounded, Sender};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::thread::JoinHandle;

/// Choices common to all analyses; the defaults scale with the system size.
#[derive(Clone, Debug, Serialize)]
pub struct Options {
    /// Analyses of vector statistics use the frames of the steps that are multiples of m.
    pub every: u64,
    /// Selected Lyapunov indices (1-based, as in the paper) for the overlap figures.
    pub j: Vec<usize>,
    /// Window lengths Delta (steps) for finite-time exponents.
    pub deltas: Vec<u64>,
}

/// What every analysis knows about the run it analyses.
#[derive(Clone, Debug)]
pub struct Context {
    pub run: Option<RunMeta>,
    /// The forward (Gram-Schmidt) spectrum of the run, if known.
    pub gs: Option<SpectrumSummary>,
    /// "disks", "henon" or "lorenz".
    pub system: String,
    pub d: usize,
    pub k: usize,
    /// Number of disks (0 for maps).
    pub n: usize,
    pub lx: f64,
    pub ly: f64,
    pub tau: f64,
    /// Frames carry G_n as well as V_n.
    pub with_gs: bool,
    pub options: Options,
    /// Where the frames came from, for captions.
    pub source: String,
    /// The oldest and newest step of the frames a whole sweep leaves in this stream (when
    /// its metadata says), to report a stream that covers less.
    pub frame_steps: Option<(u64, u64)>,
    /// The stream holds the frames of the steps on this stride (a frame file's
    /// `--save-every`; 1 for a stream, which carries every step).
    pub saved_every: u64,
    /// The mode steps ([`mode_steps::resolve`]) or why there are none, from
    /// [`Context::settle`] on.
    pub modes: mode_steps::Resolved,
    /// `options.j` is the default, which [`Context::settle`] moves before the mode steps.
    pub j_default: bool,
}

/// How often the analyses that apply to this run read V_n, for the backward stage's
/// `vectors_every`: at every `--every`-th step by default, but at every frame of the Henon
/// map, whose picture follows the vectors along the orbit (and where V costs nothing).
pub fn vectors_every_for(meta: &RunMeta) -> u64 {
    match meta.config.system {
        crate::config::SystemConfig::Henon { .. } | crate::config::SystemConfig::Lorenz { .. } => 1,
        crate::config::SystemConfig::Disks { .. } => default_every(meta.store.clv_steps, 1),
    }
}

/// Why a context has no mode steps before [`Context::settle`].
const UNSETTLED: &str = "no frame with covariant vectors was analysed";

/// The paper's index `j` of its N = 198 system, among 393 positive exponents, scaled to a
/// system with `positive` positive exponents.
pub fn paper_index(j: usize, positive: usize) -> usize {
    (j as f64 * positive as f64 / 393.0).round() as usize
}

/// The least common multiple of two strides: the steps on both.
fn lcm(a: u64, b: u64) -> u64 {
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let (a, b) = (a.max(1), b.max(1));
    a / gcd(a, b) * b
}

/// The default of `--every`: about 400 frames of a window of `clv_steps`, rounded up to a
/// multiple of `m`, the stride of the frames that carry V_n (`--vectors-every`, and a frame
/// file's `--save-every`).
pub fn default_every(clv_steps: u64, vectors_every: u64) -> u64 {
    let m = vectors_every.max(1);
    (clv_steps / 400).max(1).div_ceil(m) * m
}

impl Context {
    /// The context of a stream, from its description and its first frame.
    pub fn new(info: &StreamInfo, first: &Frame, source: &str, every: Option<u64>, j: Option<Vec<usize>>, deltas: Option<Vec<u64>>) -> Result<Self> {
        let run: Option<RunMeta> = info.run_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
        let gs: Option<SpectrumSummary> = info.spectrum_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
        let (system, n, lx, ly, tau, clv_steps) = match &run {
            Some(m) => {
                let (name, n, lx, ly) = match m.config.system {
                    crate::config::SystemConfig::Henon { .. } => ("henon", 0, 0.0, 0.0),
                    crate::config::SystemConfig::Lorenz { .. } => ("lorenz", 0, 0.0, 0.0),
                    crate::config::SystemConfig::Disks { n, lx, ly, .. } => ("disks", n, lx, ly),
                };
                (name.to_string(), n, lx, ly, m.config.tau, m.store.clv_steps)
            }
            None => return Err(Error::Other(format!("{source}: the frame stream carries no run description (clv.run metadata); was it written by clv backward?"))),
        };
        if let Some(bad) = j.iter().flatten().find(|&&j| j == 0 || j > first.k) {
            return Err(Error::param("j", format!("index {bad} is outside 1..={}", first.k)));
        }
        // Streams written before 2026-11-24 carry no backward options: V in every frame.
        let backward: Option<BackwardOptions> = info.backward_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
        let vectors_every = backward.as_ref().map_or(1, |o| o.vectors_every.max(1));
        let with_gs = backward.as_ref().map_or(first.g.is_some(), |o| o.with_gs);
        // A frame file keeps the frames of every --save-every-th step: the default stride lands
        // on those that carry V.
        let saved_every = backward.as_ref().map_or(1, |o| if o.frames_path.is_some() { o.save_every.max(1) } else { 1 });
        let every = every.unwrap_or_else(|| default_every(clv_steps, lcm(vectors_every, saved_every)));
        if every == 0 {
            return Err(Error::param("every", "must be at least 1"));
        }
        if !every.is_multiple_of(vectors_every) {
            return Err(Error::param("every", format!(
                "{source}: the backward stage formed the covariant vectors only at the steps that are multiples of {vectors_every} (--vectors-every {vectors_every}), \
                 so the vector statistics can sample every m-th step only for m a multiple of {vectors_every}, not {every}"
            )));
        }
        let given_deltas = deltas.is_some();
        let deltas = deltas.unwrap_or_else(|| [1u64, 2, 5, 10, 20, 50, 100, 200, 500].into_iter().filter(|&dl| dl * 4 <= clv_steps.max(4)).collect());
        if deltas.contains(&0) {
            return Err(Error::param("deltas", "window lengths must be at least 1 step"));
        }
        let frame_steps = run.as_ref().zip(backward.as_ref()).and_then(|(m, o)| Window::of(m, o).ok()?.frame_steps(o));
        // Windows of Delta consecutive frames (not computed for a file of every m-th step):
        // lengths of which none fits would give a table of NaN only.
        if let Some((oldest, newest)) = frame_steps.filter(|_| given_deltas && saved_every == 1) {
            let frames = newest - oldest + 1;
            if deltas.iter().all(|&dl| dl > frames) {
                return Err(Error::param(
                    "deltas",
                    format!("{source} holds the {frames} frames of steps {oldest}..{newest}, fewer than every window length given ({deltas:?}): no window would fit; give lengths up to {frames} steps"),
                ));
            }
        }
        if let Some((oldest, newest)) = frame_steps
            && newest / every * every < oldest
        {
            return Err(Error::param(
                "every",
                format!("{source} holds the frames of steps {oldest}..{newest}, and no step among them is a multiple of {every}: the vector statistics would have no frame; give a smaller m (by default about 400 frames are sampled)"),
            ));
        }
        let mut ctx = Context {
            gs,
            system,
            d: first.d,
            k: first.k,
            n,
            lx,
            ly,
            tau,
            with_gs,
            options: Options { every, j: Vec::new(), deltas },
            saved_every,
            source: source.to_string(),
            frame_steps,
            run,
            modes: Err(UNSETTLED.into()),
            j_default: j.is_none(),
        };
        ctx.options.j = j.unwrap_or_else(|| ctx.default_j());
        Ok(ctx)
    }

    /// Completes the context at the first frame the vector statistics sample (on the stride
    /// `every`: the same frame in every analysis, and the same in a stream written with
    /// `--vectors-every`): the mode steps are resolved on it, and the default j's last index
    /// ends before them. Analyses that use the mode steps or j call it before anything else.
    pub fn settle(&mut self, frame: &Frame) {
        self.modes = mode_steps::resolve(self, frame);
        if self.j_default {
            self.options.j = self.default_j();
        }
    }

    /// The paper's selections of Figs. 4, 13 and 14 for N = 198, j = 1, 200 and 370 among
    /// its 2N - 3 = 393 positive exponents, scaled to this system's positive part; for hard
    /// disks the last is J of F^(J), the last unstable vector before the mode region
    /// ([`transversality::f_size`]), as 370 is in the paper's run.
    fn default_j(&self) -> Vec<usize> {
        let positive = if self.n > 1 { 2 * self.n - 3 } else { self.d };
        let last = if self.is_disks() && self.n > 1 { transversality::f_size(self.d, &mode_steps::positive(&self.modes, self.d)) } else { paper_index(370, positive) };
        let mut v: Vec<usize> = [1, paper_index(200, positive), last].iter().map(|&j| j.clamp(1, self.k.max(1))).collect();
        v.dedup();
        v
    }

    /// What a person must know about a stream that covers less than the whole window: its
    /// frames of steps `first..=last` against the window's.
    pub fn coverage_warning(&self, first: u64, last: u64) -> Option<String> {
        let (oldest, newest) = self.frame_steps?;
        let mut missing = Vec::new();
        if last < newest {
            missing.push(format!(
                "the frames of steps {}..{newest} are missing (a stream continued with `clv backward --resume` starts where the interrupted stream stopped; start it again without --resume for the whole window)",
                last + 1
            ));
        }
        if first > oldest {
            missing.push(format!("the frames of steps {oldest}..{} are missing (the stream stopped before the end of the window)", first - 1));
        }
        (!missing.is_empty()).then(|| format!("This stream covers steps {first}..{last} of the window {oldest}..{newest}, and every result here describes those steps only: {}.", missing.join("; ")))
    }

    /// Frames per block for standard errors by batch means: the run's `blocks` blocks over
    /// the frames an analysis reads, counted in the stream (every frame it holds, or with
    /// `sampled` those on the stride `every`), as the backward stage counts them for its own
    /// CLV spectrum; 20 blocks of 1000 frames without a run description.
    pub fn block_len(&self, sampled: bool) -> u64 {
        let stride = if sampled { lcm(self.options.every, self.saved_every) } else { self.saved_every };
        let frames = match self.frame_steps {
            Some((oldest, newest)) => multiples_in(oldest, newest, stride),
            None => self.run.as_ref().map_or(1000, |m| m.store.clv_steps) / stride.max(1),
        };
        crate::stage::forward::block_len(frames, self.run.as_ref().map_or(20, |m| m.config.blocks as u64))
    }

    /// Which frames the vector statistics use, for captions.
    pub fn sample(&self) -> String {
        match self.options.every {
            1 => "every frame of the stream".into(),
            m => format!("the frames of the steps that are multiples of {m}"),
        }
    }

    pub fn is_disks(&self) -> bool {
        self.system == "disks"
    }

    /// Reduced index i/D of the 0-based index i (the paper's i/4N).
    pub fn reduced(&self, i: usize) -> f64 {
        (i + 1) as f64 / self.d as f64
    }

    /// 0-based range (inclusive) of the central, mode-carrying part of a full disk spectrum:
    /// the positive indices of the Fig. 8 plot, up to 2N-3, and their conjugates, which the
    /// enlargements of Figs. 3, 5, 6, 7, 9 and 14 show (the paper's right panels and insets).
    /// None for maps and partial spectra.
    pub fn central_range(&self) -> Option<(usize, usize)> {
        if !self.is_disks() || self.k != self.d || self.n < 2 {
            return None;
        }
        let last = 2 * self.n - 4;
        let first = last.saturating_sub((self.d / 6).max(8));
        Some((first, self.d - 1 - first))
    }
}

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

/// A consumer of frames.
pub trait Analysis: Send {
    /// Short name (used for threads and messages).
    fn name(&self) -> &'static str;
    /// Whether it wants only the sampled frames (`--every`, [`on_stride`]), or all of them.
    fn sampled(&self) -> bool {
        true
    }
    fn consume(&mut self, frame: &Frame) -> Result<()>;
    /// Write tables and figures into `out`; `frames` is how many frames it consumed.
    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>>;
}

type Maker = fn(&Context) -> Option<Box<dyn Analysis>>;

/// Every analysis that applies to this context (each decides for itself).
pub fn registry(ctx: &Context) -> Vec<Box<dyn Analysis>> {
    const MAKERS: &[Maker] = &[
        spectrum::new,
        convergence::new,
        localization::new,
        overlaps::new,
        projections::new,
        nullspace::new,
        local_exponents::new,
        modes::new,
        transversality::new,
        henon::new,
    ];
    MAKERS.iter().filter_map(|make| make(ctx)).collect()
}

/// The analyses of the registry whose names are in `only` (all if `only` is empty); an
/// unknown name is an error listing the known ones.
pub fn select(ctx: &Context, only: &[String]) -> Result<Vec<Box<dyn Analysis>>> {
    let all = registry(ctx);
    if only.is_empty() {
        return Ok(all);
    }
    let known: Vec<&str> = all.iter().map(|a| a.name()).collect();
    if let Some(bad) = only.iter().find(|o| !known.contains(&o.as_str())) {
        return Err(Error::param("only", format!("no analysis {bad:?} applies to this stream; available: {}", known.join(", "))));
    }
    Ok(all.into_iter().filter(|a| only.iter().any(|o| o == a.name())).collect())
}

struct Worker {
    name: &'static str,
    tx: Option<Sender<Arc<Frame>>>,
    handle: JoinHandle<Result<Vec<Produced>>>,
}

/// Runs analyses concurrently over a stream of frames.
pub struct Analyzer {
    ctx: Context,
    out: PathBuf,
    workers: Vec<Worker>,
    frames: u64,
    /// Frames on the stride `--every`: those the vector statistics read.
    sampled: u64,
    first_step: u64,
    last_step: u64,
}

impl Analyzer {
    pub fn start(ctx: Context, analyses: Vec<Box<dyn Analysis>>, out: &Path) -> Result<Self> {
        begin_report(out, &ctx.source, ctx.run.as_ref().map(|m| &m.config))?;
        let every = ctx.options.every;
        let mut workers = Vec::new();
        for mut analysis in analyses {
            let (tx, rx) = bounded::<Arc<Frame>>(8);
            let name = analysis.name();
            let dir = out.to_path_buf();
            let wants_sample = analysis.sampled();
            let handle = std::thread::Builder::new()
                .name(format!("clv-{name}"))
                .spawn(move || -> Result<Vec<Produced>> {
                    let mut used = 0u64;
                    for frame in rx {
                        if !wants_sample || on_stride(frame.step, every) {
                            analysis.consume(&frame)?;
                            used += 1;
                        }
                    }
                    analysis.finish(&dir, used)
                })
                .map_err(|e| Error::Other(format!("cannot start analysis {name}: {e}")))?;
            workers.push(Worker { name, tx: Some(tx), handle });
        }
        Ok(Analyzer { ctx, out: out.to_path_buf(), workers, frames: 0, sampled: 0, first_step: u64::MAX, last_step: 0 })
    }

    /// Hand a frame to every analysis. A failed analysis stops the stream with its error.
    pub fn feed(&mut self, frame: Arc<Frame>) -> Result<Flow> {
        if on_stride(frame.step, self.ctx.options.every) && frame.v.is_empty() {
            return Err(Error::corrupt(
                &self.ctx.source,
                format!(
                    "the frame of step {} carries no covariant vectors although the analyses sample it (every {}-th step); \
                     the stream was written with another --vectors-every than its metadata says",
                    frame.step, self.ctx.options.every
                ),
            ));
        }
        self.frames += 1;
        self.sampled += u64::from(on_stride(frame.step, self.ctx.options.every));
        self.first_step = self.first_step.min(frame.step);
        self.last_step = self.last_step.max(frame.step);
        for i in 0..self.workers.len() {
            let sent = self.workers[i].tx.as_ref().is_some_and(|tx| tx.send(frame.clone()).is_ok());
            if !sent {
                self.workers[i].tx = None;
                let w = self.workers.remove(i);
                let name = w.name;
                return Err(match w.handle.join() {
                    Ok(Err(e)) => Error::Other(format!("analysis {name}: {e}")),
                    _ => Error::Other(format!("analysis {name} stopped")),
                });
            }
        }
        Ok(Flow::Continue)
    }

    /// Join the analyses and write the index; `damage` (the stream ended early or broke) is
    /// put at the head of the index and of summary.json's warnings.
    pub fn finish(mut self, damage: Option<&str>) -> Result<Analysed> {
        let mut produced = Vec::new();
        let mut errors = Vec::new();
        for w in &mut self.workers {
            w.tx = None;
        }
        for w in self.workers.drain(..) {
            match w.handle.join() {
                Ok(Ok(p)) => produced.extend(p),
                Ok(Err(e)) => errors.push(format!("analysis {}: {e}", w.name)),
                Err(_) => errors.push(format!("analysis {} panicked", w.name)),
            }
        }
        let damaged = damage.map(|d| format!("The stream ends early or is damaged ({d}); every result here is from the {} complete frames before that point.", self.frames));
        let coverage = self.ctx.coverage_warning(self.first_step, self.last_step).filter(|_| self.frames > 0);
        let unsampled = (self.frames > 0 && self.sampled == 0).then(|| {
            format!(
                "No frame of this stream (steps {}..{}) is on the stride --every {}: the analyses of vector statistics had no frame to read, and their tables are empty; give a smaller --every.",
                self.first_step, self.last_step, self.ctx.options.every
            )
        });
        let warnings: Vec<String> = damaged.into_iter().chain(coverage).chain(unsampled).collect();
        write_index(&self.ctx, &self.out, &produced, &warnings, self.frames, self.first_step, self.last_step)?;
        if !errors.is_empty() {
            return Err(Error::Other(errors.join("; ")));
        }
        Ok(Analysed { produced, frames: self.frames, warnings })
    }
}

/// What the analyses of a stream produced.
pub struct Analysed {
    pub produced: Vec<Produced>,
    pub frames: u64,
    /// What limits the results as a whole (also at the head of index.html and in summary.json).
    pub warnings: Vec<String>,
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

/// A small CSV table (the paper's Tables II-IV, the mode table) as HTML, numbers to six
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

fn write_index(ctx: &Context, out: &Path, produced: &[Produced], warnings: &[String], frames: u64, first: u64, last: u64) -> Result<()> {
    let mut html = String::from("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>clv analyses</title>\n<style>body{font-family:sans-serif;max-width:1000px;margin:auto;padding:1em} figure{margin:2em 0} img{max-width:100%} code{background:#eee}</style></head><body>\n");
    html += &format!(
        "<h1>Covariant Lyapunov vector analyses</h1>\n<p>Source: <code>{}</code>; {} frames (steps {}..{}), D = {}, k = {}{}; vector statistics use {}.</p>\n{}<p>Conventions: {}</p>\n",
        escape(&ctx.source),
        frames,
        if frames > 0 { first } else { 0 },
        last,
        ctx.d,
        ctx.k,
        if ctx.with_gs { ", with Gram-Schmidt vectors" } else { "" },
        ctx.sample(),
        run_line(ctx.run.as_ref().map(|m| &m.config)),
        if ctx.is_disks() {
            "units σ = m = K/N = 1, exponents per unit time; step numbers count the relaxation steps too, and t = step × τ; indices i are 1-based as in the paper; vectors ordered (δq_x1, δq_y1, ..., δq_yN; δp_x1, ..., δp_yN); angles in radians, captions add degrees where the paper uses them."
        } else {
            "exponents per unit time (per iteration for a map); t = step × τ; indices i are 1-based."
        }
    );
    for w in warnings {
        html += &format!("<p style=\"border:2px solid #c00;padding:0.5em\"><strong>Incomplete stream.</strong> {}</p>\n", escape(w));
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
    // Last: a report with a summary.json is finished.
    let summary = serde_json::json!({ "frames": frames, "first_step": first, "last_step": last, "options": ctx.options, "warnings": warnings, "produced": produced });
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
    let lock = crate::store::lock::take(&path, out, LOCKED_FOR, true, |e| Error::io(&path, e))?;
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
    let ours = |name: &str| name == WRITING || name == LOCK || (name.starts_with('.') && name.ends_with(TMP_SUFFIX));
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

/// Save a figure as SVG and PNG ([`write_report_file`]).
pub fn save_figure(fig: &crate::report::plot::Figure, out: &Path, stem: &str) -> Result<()> {
    write_report_file(&out.join(format!("{stem}.svg")), fig.to_svg().as_bytes())?;
    write_report_file(&out.join(format!("{stem}.png")), &fig.to_png())
}

/// Running mean and standard error (from the spread over frames) of a set of quantities.
#[derive(Clone, Debug)]
pub struct Mean {
    pub n: u64,
    sum: Vec<f64>,
    sum2: Vec<f64>,
}

impl Mean {
    pub fn new(len: usize) -> Self {
        Mean { n: 0, sum: vec![0.0; len], sum2: vec![0.0; len] }
    }
    pub fn add(&mut self, x: impl IntoIterator<Item = f64>) {
        for ((s, s2), x) in self.sum.iter_mut().zip(self.sum2.iter_mut()).zip(x) {
            *s += x;
            *s2 += x * x;
        }
        self.n += 1;
    }
    pub fn mean(&self) -> Vec<f64> {
        self.sum.iter().map(|s| s / self.n as f64).collect()
    }
    /// Standard deviation over frames (frames are correlated: not an error of the mean).
    pub fn std(&self) -> Vec<f64> {
        let n = self.n as f64;
        self.sum.iter().zip(&self.sum2).map(|(s, s2)| ((s2 / n - (s / n).powi(2)).max(0.0)).sqrt()).collect()
    }
}

/// A run directory stands for the frame file its last backward sweep wrote (its `--out`).
/// Where that sweep wrote none (a stream, `--save-every 0`), has not finished it, or its
/// file is gone, the run is refused, naming the sweep: a frames.mcap left by an earlier sweep
/// is not this one's frames. A run without a sweep record (or one of a build before them)
/// stands for the frames.mcap in it.
fn frame_source(source: &Path) -> Result<(PathBuf, Option<Expected>)> {
    if !source.is_dir() {
        return Ok((source.to_path_buf(), None));
    }
    let expect = |options: Option<BackwardOptions>| -> Result<Option<Expected>> {
        let (_, meta) = crate::store::RunDir::open(source)?;
        Ok(Some(Expected { dir: source.to_path_buf(), meta, options }))
    };
    let d = source.display();
    let frames = crate::store::RunDir { path: source.to_path_buf() }.frames_path();
    let record = source.join("backward.json");
    let last = crate::stage::backward::last_sweep(source).map_err(|e| {
        Error::Other(format!("{e}; the run's last backward sweep is unknown, so {d} cannot stand for its frames: name a frame file (`clv analyze FILE --out REPORT`), or write one with `clv backward {d} --out FILE.mcap`"))
    })?;
    let Some(last) = last else {
        if frames.exists() {
            return Ok((frames, expect(None)?));
        }
        return Err(Error::Other(format!(
            "{d} is a directory without a frame file ({}); analyse a run with `clv backward {d} --out - | clv analyze - --out REPORT`, or write {} with `clv backward {d}` first",
            frames.display(),
            frames.display()
        )));
    };
    let opts = &last.options;
    let file = opts.frames_file(source);
    if let Some(file) = file.as_ref().filter(|f| last.done && f.exists()) {
        return Ok((file.clone(), expect(Some(last.options.clone()))?));
    }
    let flags = format!("recorded in {}: {}", record.display(), opts.as_flags());
    if let Some(f) = file.as_ref().filter(|_| !last.done) {
        return Err(Error::Other(format!(
            "{d}: the run's last backward sweep ({flags}) has not finished writing {}; continue it with `clv backward {d} --resume`, then analyse the run again",
            f.display()
        )));
    }
    let what = match &file {
        Some(f) => format!("wrote {}, which is gone (deleted or moved)", f.display()),
        None if opts.streams() => "streamed its frames to a reader (`--out -`, or the analyses of `clv run`) and wrote no frame file".into(),
        None => "computed only the CLV spectrum (`--save-every 0`) and wrote no frame file".into(),
    };
    let other = if frames.exists() && file.as_ref() != Some(&frames) {
        format!("; {} is an earlier sweep's: analyse it by name if you want those frames (`clv analyze {} --out REPORT`)", frames.display(), frames.display())
    } else {
        String::new()
    };
    let write = if frames.exists() { format!("{d}/NAME.mcap") } else { frames.display().to_string() };
    Err(Error::Other(format!(
        "{d}: the run's last backward sweep ({flags}) {what}, so there are no frames of it to analyse; write a frame file with `clv backward {d} --out {write}` and analyse the run again{other}"
    )))
}

/// What the frame file that stands for a run directory must hold: the frames of that run
/// (run.json) from its last backward sweep (backward.json's options, where one is recorded).
/// A file copied or restored over it from another run or sweep would otherwise be
/// analysed under the run's name.
struct Expected {
    dir: PathBuf,
    meta: RunMeta,
    options: Option<BackwardOptions>,
}

impl Expected {
    fn check(&self, info: &StreamInfo, file: &Path) -> Result<()> {
        let (d, f) = (self.dir.display(), file.display());
        let fix = format!("analyse the file by name if you mean its frames (`clv analyze {f} --out REPORT`), or write this run's with `clv backward {d} --out FILE.mcap` and analyse that");
        let run: Option<RunMeta> = info.run_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
        if let Some(run) = run.filter(|r| !(r.config.same_but_threads(&self.meta.config) && r.store == self.meta.store)) {
            let differ = crate::stage::pipeline::differences((&self.meta.config, &self.meta.store, "in run.json"), (&run.config, &run.store, "in the file")).join(", ");
            return Err(Error::Other(format!("{f} stands for the frames of {d}, but it holds another run's frames ({differ}): {fix}")));
        }
        let sweep: Option<BackwardOptions> = info.backward_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
        let unnamed = |o: &BackwardOptions| BackwardOptions { frames_path: None, ..o.clone() };
        if let (Some(want), Some(have)) = (&self.options, sweep)
            && unnamed(want) != unnamed(&have)
        {
            return Err(Error::Other(format!(
                "{f} stands for the frames of {d}'s last backward sweep ({}, recorded in {}), but another sweep wrote it ({}): {fix}",
                want.as_flags(),
                self.dir.join("backward.json").display(),
                have.as_flags()
            )));
        }
        Ok(())
    }
}

/// Whether `path` holds the checkpoints of a run segment (read only to explain an error).
fn is_run_segment(path: &Path) -> bool {
    use crate::store::schema::CHECKPOINT;
    let mut found = false;
    let _ = crate::store::segment::read_segment(path, crate::store::segment::ReadMode::Salvage, |m| {
        found |= m.topic == CHECKPOINT.topic;
        Ok(())
    });
    found
}

/// Run every applicable analysis over the frames of `source` (a file, or "-" for standard
/// input) into `out`, calling `on_frame` with the count of frames read so far. Returns what
/// was produced and the number of frames read.
pub fn analyze_source(
    source: &Path,
    out: &Path,
    every: Option<u64>,
    j: Option<Vec<usize>>,
    deltas: Option<Vec<u64>>,
    only: &[String],
    on_frame: &mut dyn FnMut(u64),
) -> Result<Analysed> {
    let (source, expected) = frame_source(source)?;
    let source = &source;
    let info = std::cell::RefCell::new(StreamInfo::default());
    let mut analyzer: Option<Analyzer> = None;
    let name = if source == Path::new("-") { "<stdin>".to_string() } else { source.display().to_string() };
    let damage = crate::store::frames::read_frames_with(
        source,
        |i| {
            if let Some(expected) = &expected {
                expected.check(&i, source)?;
            }
            *info.borrow_mut() = i;
            Ok(())
        },
        |frame| {
            if analyzer.is_none() {
                let ctx = Context::new(&info.borrow(), &frame, &name, every, j.clone(), deltas.clone())?;
                let analyses = select(&ctx, only)?;
                analyzer = Some(Analyzer::start(ctx, analyses, out)?);
            }
            let analyzer = analyzer.as_mut().expect("started");
            let flow = analyzer.feed(Arc::new(frame))?;
            on_frame(analyzer.frames);
            Ok(flow)
        },
    )?;
    let Some(analyzer) = analyzer else {
        if is_run_segment(source) {
            return Err(Error::Other(format!(
                "{name} is a segment of a run directory (checkpoints and R matrices), not a frame stream; make the frames with `clv backward RUN_DIR --out - | clv analyze - --out REPORT`"
            )));
        }
        return Err(Error::Other(match damage {
            Some(d) => format!("{name}: no frames in the stream ({d})"),
            None => format!("{name}: no frames in the stream: its writer sent none. It failed before its first frame (its own error says why: a full disk, a signal), or it was `clv backward --resume` of a sweep that had finished, which sends none (start it without --resume)"),
        }));
    };
    let analysed = analyzer.finish(damage.as_deref())?;
    if let Some(d) = damage {
        let rewrite = if source == Path::new("-") {
            String::new()
        } else {
            let options: Option<BackwardOptions> = info.borrow().backward_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
            let run = expected.as_ref().map(|e| e.dir.clone()).or_else(|| options.as_ref()?.frames_path.as_deref().and_then(|r| crate::store::frames::run_dir_of(source, r)));
            format!("; {}", super::backward::rewrite_advice(source, options.as_ref(), run.as_deref()))
        };
        return Err(Error::corrupt(
            &name,
            format!("the stream ends early or is damaged ({d}); the {} complete frames before it were analysed into {}, but the results are incomplete{rewrite}", analysed.frames, out.display()),
        ));
    }
    Ok(analysed)
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
