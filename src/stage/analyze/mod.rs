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
//! The report directory they write into (index.html, files written whole, its lock) is
//! [`crate::report::dir`]'s; which frames a source names (a file, standard input, a run
//! directory) is `source`'s.

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
mod source;
#[cfg(test)]
mod testing;
pub mod transversality;

pub use source::analyze_source;

use super::backward::{BackwardOptions, Window};
use super::frame::{lcm, multiples_in, on_stride, Frame};
use crate::error::{Error, Result};
use crate::report::SpectrumSummary;
use crate::store::frames::{Flow, StreamInfo};
use crate::store::run::RunMeta;
// The report directory's writers, for the analyses.
pub use crate::report::dir::{csv_number, save_figure, write_csv, write_report_file, write_text_csv, Produced};
use crate::report::dir::{begin_report, write_index, Head};
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
    /// The run the frames come from (its configuration and store settings).
    pub run: RunMeta,
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
    /// The frames carry V_n at the steps that are multiples of this (the backward stage's
    /// `--vectors-every`).
    pub vectors_every: u64,
    /// The mode steps ([`mode_steps::resolve`]) or why there are none, from
    /// [`Context::settle`] on.
    pub modes: mode_steps::Resolved,
    /// `options.j` is the default, which [`Context::settle`] moves before the mode steps.
    pub j_default: bool,
}

/// Palette colours ([`crate::report::plot::Figure::color`]) of the two kinds of vector
/// wherever a figure shows both, the paper's blue for Gram-Schmidt and red for covariant
/// (Figs. 2, 8, 9, 10-12): one colour per kind across the report.
pub const GS_COLOR: usize = 0;
pub const CLV_COLOR: usize = 1;

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

/// The default of `--every`: clv_steps / 400 rounded down (400 to 800 frames of a window of
/// `clv_steps`; all of a shorter one), rounded up to a
/// multiple of `m`, the stride of the frames that carry V_n (`--vectors-every`, and a frame
/// file's `--save-every`).
pub fn default_every(clv_steps: u64, vectors_every: u64) -> u64 {
    let m = vectors_every.max(1);
    (clv_steps / 400).max(1).div_ceil(m) * m
}

impl Context {
    /// The context of a stream, from its description and its first frame.
    pub fn new(info: &StreamInfo, first: &Frame, source: &str, every: Option<u64>, j: Option<Vec<usize>>, deltas: Option<Vec<u64>>) -> Result<Self> {
        let run: RunMeta = match info.run_json.as_deref().map(serde_json::from_str) {
            Some(Ok(run)) => run,
            Some(Err(e)) => return Err(Error::Other(format!("{source}: the frame stream's run description (clv.run metadata) does not read: {e}; was it written by another version of clv?"))),
            None => return Err(Error::Other(format!("{source}: the frame stream carries no run description (clv.run metadata); was it written by clv backward?"))),
        };
        let gs: Option<SpectrumSummary> = info.spectrum_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
        let (name, n, lx, ly) = match run.config.system {
            crate::config::SystemConfig::Henon { .. } => ("henon", 0, 0.0, 0.0),
            crate::config::SystemConfig::Lorenz { .. } => ("lorenz", 0, 0.0, 0.0),
            crate::config::SystemConfig::Disks { n, lx, ly, .. } => ("disks", n, lx, ly),
        };
        let (system, tau, clv_steps) = (name.to_string(), run.config.tau, run.store.clv_steps);
        if let Some(bad) = j.iter().flatten().find(|&&j| j == 0 || j > first.k) {
            return Err(Error::param("j", format!("index {bad} is outside 1..={}", first.k)));
        }
        // Streams written before 2026-11-24 carry no backward options: V in every frame.
        let backward = BackwardOptions::of_stream(info);
        let vectors_every = backward.as_ref().map_or(1, |o| o.vectors_every.max(1));
        let with_gs = backward.as_ref().map_or(first.g.is_some(), |o| o.with_gs);
        // A frame file keeps the frames of every --save-every-th step: the default stride lands
        // on those that carry V.
        let saved_every = match backward.as_ref().map(BackwardOptions::destination) {
            Some(super::backward::Destination::File { every, .. }) => every,
            _ => 1,
        };
        let every_given = every.is_some();
        let with_v = lcm(vectors_every, saved_every);
        let every = every.unwrap_or_else(|| default_every(clv_steps, with_v));
        if every == 0 {
            return Err(Error::param("every", "must be at least 1"));
        }
        if !every.is_multiple_of(with_v) {
            let why = match (vectors_every, saved_every) {
                (1, s) => format!("the file holds the frames of the steps that are multiples of {s} only (--save-every {s})"),
                (v, 1) => format!("the backward stage formed the covariant vectors only at the steps that are multiples of {v} (--vectors-every {v})"),
                (v, s) => format!("the file holds the frames of the steps that are multiples of {s} (--save-every {s}), with covariant vectors at the multiples of {v} (--vectors-every {v})"),
            };
            return Err(Error::param("every", format!("{source}: {why}, so the vector statistics can sample every m-th step only for m a multiple of {with_v}, not {every}")));
        }
        let given_deltas = deltas.is_some();
        let mut deltas = deltas.unwrap_or_else(|| [1u64, 2, 5, 10, 20, 50, 100, 200, 500].into_iter().filter(|&dl| dl * 4 <= clv_steps.max(4)).collect());
        // Each length once, shortest first (a repeated one would write its rows twice).
        deltas.sort_unstable();
        deltas.dedup();
        if deltas.contains(&0) {
            return Err(Error::param("deltas", "window lengths must be at least 1 step"));
        }
        // A file of every m-th step has no windows of consecutive frames: none are measured,
        // and summary.json's options say so; lengths asked for are refused.
        if saved_every > 1 {
            if given_deltas {
                return Err(Error::param(
                    "deltas",
                    format!(
                        "{source} holds the frames of the steps that are multiples of {saved_every} only (--save-every {saved_every}), with no windows of consecutive frames for the finite-time analyses: \
                         leave --deltas out (the other analyses run), or analyse the whole stream (`clv backward RUN_DIR --out - | clv analyze -`)"
                    ),
                ));
            }
            deltas.clear();
        }
        let frame_steps = backward.as_ref().and_then(|o| Window::of(&run, o).ok()?.frame_steps(o));
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
        // Refused only where a smaller m would sample a frame; where none can, the analyses
        // go on without vector statistics and say so, as with the default m.
        let none_of = |m: u64, (oldest, newest): (u64, u64)| newest / m * m < oldest;
        if let Some(steps) = frame_steps.filter(|&steps| every_given && none_of(every, steps) && !none_of(with_v, steps)) {
            let (oldest, newest) = steps;
            let multiple = if with_v > 1 { format!(", a multiple of {with_v}") } else { String::new() };
            return Err(Error::param(
                "every",
                format!("{source} holds the frames of steps {oldest}..{newest}, and no step among them is a multiple of {every}: the vector statistics would have no frame; give a smaller m{multiple} (by default m is the window's steps / 400: 400 to 800 frames)"),
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
            vectors_every,
            source: source.to_string(),
            frame_steps,
            run,
            modes: Err(UNSETTLED.into()),
            j_default: j.is_none(),
        };
        // Each index once, in the order given (a repeated one would be drawn twice).
        ctx.options.j = j.map(|j| j.iter().enumerate().filter(|&(i, x)| !j[..i].contains(x)).map(|(_, &x)| x).collect()).unwrap_or_else(|| ctx.default_j());
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

    /// The paper's selection of Fig. 13 (Fig. 4 takes its last index) for N = 198, j = 1, 200 and 370 among
    /// its 2N - 3 = 393 positive exponents, scaled to this system's positive part; for hard
    /// disks the last is J of F^(J), the last unstable vector before the mode region
    /// ([`mode_steps::f_size`]), as 370 is in the paper's run.
    fn default_j(&self) -> Vec<usize> {
        let positive = if self.n > 1 { 2 * self.n - 3 } else { self.d };
        let last = if self.is_disks() && self.n > 1 { mode_steps::f_size(self.d, &mode_steps::positive(&self.modes, self.d)) } else { paper_index(370, positive) };
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
    /// CLV spectrum (the window of the run, where the stream does not say its steps).
    pub fn block_len(&self, sampled: bool) -> u64 {
        let stride = if sampled { lcm(self.options.every, self.saved_every) } else { self.saved_every };
        let frames = match self.frame_steps {
            Some((oldest, newest)) => multiples_in(oldest, newest, stride),
            None => self.run.store.clv_steps / stride.max(1),
        };
        crate::statistics::block_len(frames, self.run.config.blocks as u64)
    }

    /// Which frames the vector statistics use, for captions.
    pub fn sample(&self) -> String {
        match self.options.every {
            1 => "every frame of the stream".into(),
            m => format!("the frames of the steps that are multiples of {m}"),
        }
    }

    /// "averaged over N frames (which)", for the captions of tables of means with their
    /// spreads over frames (`_std` columns, NaN from one frame).
    pub fn averaged_over(&self, frames: u64) -> String {
        let one = if frames < 2 { "; the tables' _std columns, spreads over frames, are NaN from one frame" } else { "" };
        format!("averaged over {frames} frames ({}{one})", self.sample())
    }

    pub fn is_disks(&self) -> bool {
        self.system == "disks"
    }

    /// The 0-based indices of the six-dimensional null space of hard disks, 2N-3..2N+3
    /// ([`SystemConfig::neutral`](crate::config::SystemConfig::neutral)), where all of them
    /// are among the k vectors; None for other systems or N < 2. E^u is the indices below it
    /// and E^s those above.
    pub fn null_space(&self) -> Option<std::ops::Range<usize>> {
        let null = self.run.config.system.neutral();
        (self.is_disks() && self.n >= 2 && null.end <= self.k).then_some(null)
    }

    /// The 0-based range 2N..2N+3 of the last three null-space vectors (the paper's
    /// i = 2N+1..2N+3), where all of the null space is among the k vectors: their covariant
    /// vectors do not converge, since backward iteration turns e_(k+3) into e_(k+3) - s e_k
    /// after the backward time s (their exponents drift like ln s / s, Fig. 2; spectrum.csv's
    /// lambda_clv_null_shear).
    pub fn null_shear(&self) -> Option<std::ops::Range<usize>> {
        self.null_space().map(|null| null.start + 3..null.end)
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

/// Why part of an analysis's results is missing from a report: the frames do not have
/// what it needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Missing {
    /// The frames carry no Gram-Schmidt vectors (`clv backward` without --with-gs).
    GsVectors,
    /// The frames carry the k < D leading vectors only.
    AllVectors,
    /// The frames are those of every m-th step only (`--save-every m`), not consecutive.
    ConsecutiveFrames,
}

/// What an analysis leaves out of a report for want of `Missing` in the frames of `ctx`,
/// in a few words naming figures and tables ("Figs. 3 and 4"), said once at the report's
/// head rather than by figures gone missing.
type LeftOut = fn(&Context, Missing) -> Option<&'static str>;

/// Every analysis, with what it leaves out where the frames lack something.
const ANALYSES: &[(Maker, LeftOut)] = &[
    (spectrum::new, spectrum::left_out),
    (convergence::new, nothing_left_out),
    (localization::new, localization::left_out),
    (overlaps::new, overlaps::left_out),
    (projections::new, projections::left_out),
    (nullspace::new, nullspace::left_out),
    (local_exponents::new, local_exponents::left_out),
    (modes::new, modes::left_out),
    (transversality::new, transversality::left_out),
    (henon::new, henon::left_out),
];

fn nothing_left_out(_: &Context, _: Missing) -> Option<&'static str> {
    None
}

/// Every analysis that applies to this context (each decides for itself).
pub fn registry(ctx: &Context) -> Vec<Box<dyn Analysis>> {
    ANALYSES.iter().filter_map(|(make, _)| make(ctx)).collect()
}

/// What the analyses leave out for want of `missing`, in registry order.
fn left_out(ctx: &Context, missing: Missing) -> Vec<&'static str> {
    ANALYSES.iter().filter_map(|(_, left_out)| left_out(ctx, missing)).collect()
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
        begin_report(out, &ctx.source, Some(&ctx.run.config))?;
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
                    // With no sampled frame an analysis of them has nothing to show, and its
                    // captions would state results of no data: left out, as the report's head
                    // says ([`Analyzer::finish`]).
                    if wants_sample && used == 0 {
                        return Ok(Vec::new());
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
        if on_stride(frame.step, self.ctx.options.every) {
            // As every analysis settles its own context, for summary.json's options.
            if self.sampled == 0 {
                self.ctx.settle(&frame);
            }
            self.sampled += 1;
        }
        self.first_step = self.first_step.min(frame.step);
        self.last_step = self.last_step.max(frame.step);
        for i in 0..self.workers.len() {
            let sent = self.workers[i].tx.as_ref().is_some_and(|tx| tx.send(frame.clone()).is_ok());
            if !sent {
                self.workers[i].tx = None;
                let w = self.workers.remove(i);
                let name = w.name;
                return Err(match w.handle.join() {
                    Ok(Err(e)) if e.is_disk_full() => e,
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
        // A full disk is the command's error as it is, so that it says how to continue.
        let mut full_disk = None;
        for w in &mut self.workers {
            w.tx = None;
        }
        for w in self.workers.drain(..) {
            match w.handle.join() {
                Ok(Ok(p)) => produced.extend(p),
                Ok(Err(e)) => {
                    errors.push(format!("analysis {}: {e}", w.name));
                    if e.is_disk_full() {
                        full_disk.get_or_insert(e);
                    }
                }
                Err(_) => errors.push(format!("analysis {} panicked", w.name)),
            }
        }
        let damaged = damage.map(|d| format!("The stream ends early or is damaged ({d}); every result here is from the {} complete frames before that point.", self.frames));
        let coverage = self.ctx.coverage_warning(self.first_step, self.last_step).filter(|_| self.frames > 0);
        let unsampled = (self.frames > 0 && self.sampled == 0).then(|| {
            let with_v = lcm(self.ctx.vectors_every, self.ctx.saved_every);
            let remedy = if with_v > 1 && self.last_step / with_v * with_v < self.first_step {
                format!(
                    "the frames carry covariant vectors only at the steps that are multiples of {with_v} (--vectors-every {}, --save-every {}): write them again with smaller strides",
                    self.ctx.vectors_every, self.ctx.saved_every
                )
            } else {
                format!("give a smaller --every (a multiple of {with_v})")
            };
            format!(
                "No frame of this stream (steps {}..{}) is on the stride --every {}: the analyses of vector statistics had no frame to read and are left out; {remedy}.",
                self.first_step, self.last_step, self.ctx.options.every
            )
        });
        let forward = self.ctx.gs.iter().flat_map(|g| &g.warnings).map(|w| format!("The forward stage warned: {w}."));
        // What the frames cannot give, said once here rather than by figures gone missing.
        let listed = |missing| {
            let what = left_out(&self.ctx, missing);
            if what.is_empty() { String::new() } else { format!(" ({})", what.join("; ")) }
        };
        let without_gs = (!self.ctx.with_gs && self.frames > 0).then(|| {
            format!(
                "The frames carry no Gram-Schmidt vectors (written by `clv backward` without --with-gs): the comparisons of GS and covariant vectors{} and the GS columns of the tables are left out; write the frames again with --with-gs for them.",
                listed(Missing::GsVectors)
            )
        });
        let partial = (self.ctx.k < self.ctx.d && self.frames > 0).then(|| {
            format!("The frames carry the k = {} leading of D = {} vectors: what needs all of them{} is left out.", self.ctx.k, self.ctx.d, listed(Missing::AllVectors))
        });
        let strided = (self.ctx.saved_every > 1 && self.frames > 0).then(|| {
            format!(
                "The frame file holds the frames of the steps that are multiples of {} only (--save-every): what needs consecutive steps{} is left out; analyse the whole stream (`clv backward RUN_DIR --out - | clv analyze -`) for it.",
                self.ctx.saved_every,
                listed(Missing::ConsecutiveFrames)
            )
        });
        let warnings: Vec<String> = forward.chain(damaged).chain(coverage).chain(unsampled).collect();
        let ctx = &self.ctx;
        let head = Head {
            source: &ctx.source,
            d: ctx.d,
            k: ctx.k,
            with_gs: ctx.with_gs,
            sample: ctx.sample(),
            run: Some(&ctx.run.config),
            disks: ctx.is_disks(),
            options: serde_json::to_value(&ctx.options).unwrap_or_default(),
            whole: damage.is_none(),
            left_out: without_gs.into_iter().chain(partial).chain(strided).collect(),
        };
        write_index(&head, &self.out, &produced, &warnings, &errors, self.frames, self.first_step, self.last_step)?;
        if let Some(e) = full_disk {
            return Err(e);
        }
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

/// Running mean and standard deviation over frames of a set of quantities. The spread is
/// Welford's running sum of squared deviations: the sums of x and x^2 would cancel to
/// round-off of <x^2> (a constant 1 over 43 frames showed a spread of 1.8e-8, not 0).
#[derive(Clone, Debug)]
pub struct Mean {
    pub n: u64,
    sum: Vec<f64>,
    /// Welford's running mean and sum of squared deviations from it.
    running: Vec<f64>,
    m2: Vec<f64>,
}

impl Mean {
    pub fn new(len: usize) -> Self {
        Mean { n: 0, sum: vec![0.0; len], running: vec![0.0; len], m2: vec![0.0; len] }
    }
    pub fn add(&mut self, x: impl IntoIterator<Item = f64>) {
        self.n += 1;
        let n = self.n as f64;
        for (((s, mu), m2), x) in self.sum.iter_mut().zip(self.running.iter_mut()).zip(self.m2.iter_mut()).zip(x) {
            *s += x;
            let delta = x - *mu;
            *mu += delta / n;
            *m2 += delta * (x - *mu);
        }
    }
    pub fn mean(&self) -> Vec<f64> {
        self.sum.iter().map(|s| s / self.n as f64).collect()
    }
    /// Sample standard deviation over frames (frames are correlated: not an error of the
    /// mean). NaN with fewer than two frames: one frame shows no spread, it does not show
    /// that there is none.
    pub fn std(&self) -> Vec<f64> {
        if self.n < 2 {
            return vec![f64::NAN; self.sum.len()];
        }
        let n = self.n as f64;
        self.m2.iter().map(|m2| (m2 / (n - 1.0)).max(0.0).sqrt()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::Mean;

    #[test]
    fn mean_std_is_the_sample_deviation_and_unknown_from_one_frame() {
        let mut m = Mean::new(2);
        m.add([1.0, 5.0]);
        assert_eq!(m.mean(), vec![1.0, 5.0]);
        assert!(m.std().iter().all(|s| s.is_nan()), "one frame: {:?}", m.std());
        m.add([3.0, 5.0]);
        // Sample deviation of {1, 3}: sqrt(((1-2)^2 + (3-2)^2) / (2 - 1)) = sqrt(2).
        let s = m.std();
        assert!((s[0] - 2f64.sqrt()).abs() < 1e-15 && s[1] == 0.0, "{s:?}");
    }

    /// A constant shows no spread, and a small spread on a large value is not lost to
    /// cancellation (the sums of x and x^2 gave 1.8e-8 for a constant 1 over 43 frames).
    #[test]
    fn mean_std_does_not_cancel() {
        let mut m = Mean::new(2);
        let xs: Vec<f64> = (0..43).map(|i| 1e4 + 1e-3 * ((i * 7919) % 43) as f64 / 43.0).collect();
        for &x in &xs {
            m.add([0.1, x]);
        }
        let mean = xs.iter().sum::<f64>() / 43.0;
        let two_pass = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 42.0).sqrt();
        let s = m.std();
        assert_eq!(s[0], 0.0);
        assert!((s[1] - two_pass).abs() < 1e-9 * two_pass, "{} against {two_pass}", s[1]);
    }
}
