//! Lyapunov modes (paper Sec. 5.5: Table III and Figs. 10, 11, 12; hard disks only).
//!
//! 1. The degenerate steps of the forward Gram-Schmidt spectrum next to the null space are
//!    found from the GS exponents and their standard errors carried by the frame stream
//!    ([`km::mode_steps`]; paper Fig. 8: two-fold steps are T candidates, four-fold steps LP
//!    candidates, twice or four times that where the box's symmetry makes several wave
//!    vectors degenerate, [`km::Candidates`]): neighbours equal within [`STEP_TOL`](super::mode_steps::STEP_TOL) combined
//!    standard errors, or, in the mode region bordering the null space, groups set apart
//!    from their neighbours by gaps ten times their own spread. The four exponents of an LP
//!    mode of a finite system are not exactly equal: in the paper's run they differ by ten
//!    standard errors, which the separation finds. Where neither test sees the whole group,
//!    a step whose vectors classify as L, P or LP at the first frame is widened to the block
//!    of the LP mode's size around it that its LP basis explains best. Next to the mode
//!    region found so far, a block of a mode's size that stands apart from its neighbours
//!    (its range below both gaps) is a step if its vectors are that mode at the first frame:
//!    a small system's LP exponents spread like the smooth spectrum's (N = 40). Both in
//!    [`resolve_steps`](super::mode_steps::resolve_steps), which every analysis that names
//!    steps reaches through [`Context::settle`] at the first sampled frame, so that all
//!    find the same steps. The table says which rule found each step.
//! 2. Every step is classified in every (sampled) frame by projecting the position part of
//!    its GS vectors (the paper classifies with GS vectors; CLVs when the frames carry no GS
//!    vectors) onto the orthonormalised Table III bases T, L, P, LP of every candidate wave
//!    vector k = 2 pi (n_x / L_x, n_y / L_y), |k| <= 2 pi [`MAX_N`](super::mode_steps::MAX_N) / max(L_x, L_y), and of
//!    those of equal |k| together. In the paper's box these are (n_x, 0), n_x = 1..=4. The
//!    table reports the majority class, its mean fraction for GS and CLV groups, and the
//!    share of frames that agree.
//!
//!    The steps themselves are fixed at the first frame, yet the rules that look at vectors
//!    can come out otherwise at another frame (N = 40, 1500 steps: 6 of 50 frames would add
//!    a pair at i = 70..71). So the steps are resolved again at every sampled frame, and the
//!    table says how many frames give the same steps and which other steps some frames give:
//!    the reader sees whether the first frame was typical.
//! 3. T modes of one wave vector (Fig. 10): the perturbations across k (dq_y and dp_y for
//!    (n_x, 0)) of one vector of the pair against the position along k (q_x) at one frame,
//!    GS and CLV, with the least-squares fit A cos(k x + phi); amplitudes and rms residuals
//!    of the fits of both vectors, averaged over frames, are tabulated.
//! 4. LP modes of one wave vector (Figs. 11, 12): the pure L and P vectors are reconstructed
//!    inside the four-dimensional GS and CLV groups at one frame from the position (Fig. 11,
//!    sine patterns) and the momentum perturbations (Fig. 12, cosine patterns); for P the
//!    disk momenta are divided out.
//! 5. Steps of several wave vectors (beyond the paper, whose thin box has none: T(1,0)+T(0,1)
//!    in a square box) get the figures of each of their wave vectors, its pure T, L and P
//!    vectors reconstructed inside the whole step.
//!
//! Small systems may have few or no modes: the table is then empty and says so.

use super::kernels::modes::{self as km, Candidates, Family, ModeKind, Part, SineFit, Step, Wave};
use super::kernels::vecset;
use super::mode_steps::{candidates, classify_step, excess, group, is_positive, matches_degeneracy, step_window, Found, MAX_N, MIN_FRACTION, STEP_TOL};
use super::{save_figure, write_csv, write_text_csv, Analysis, Context, Mean, Produced};
use crate::error::Result;
use crate::report::plot::{Figure, Marker};
use crate::stage::frame::Frame;
use serde::Serialize;
use std::path::Path;

/// Candidate kinds in the order of [`km::mode_fractions`].
const KINDS: [ModeKind; 4] = [ModeKind::T, ModeKind::L, ModeKind::P, ModeKind::LP];
/// Fit values per (source, vector, family): amplitude, residual, residual/amplitude for dq
/// and for dp across k.
const FIT_VALUES: usize = 6;

fn candidate(kind: ModeKind, family: usize) -> usize {
    family * KINDS.len() + KINDS.iter().position(|&k| k == kind).expect("kind")
}

fn candidate_of(c: usize) -> (ModeKind, usize) {
    (KINDS[c % KINDS.len()], c / KINDS.len())
}

struct StepAcc {
    step: Step,
    /// How [`resolve_steps`](super::mode_steps::resolve_steps) found it.
    found: Found,
    /// Mean fractions of every candidate (order of `candidate`) for the GS and CLV groups.
    gs: Mean,
    clv: Mean,
    /// Per-frame winners of the classification.
    votes: Vec<u64>,
    /// Two-fold steps: sine fits of every vector for every family of one wave vector,
    /// [source][vector][family][value] (NaN for families of several).
    fits: Option<Mean>,
}

pub struct Modes {
    ctx: Context,
    candidates: Candidates,
    /// The context's mode steps (from the first frame on) with their accumulators.
    steps: Vec<StepAcc>,
    /// The frame of the pattern figures (the first one consumed).
    shown: Option<Frame>,
    /// The steps resolved at each frame on its own, counted over the frames.
    resolved: Resolutions,
}

/// How the steps come out when each frame resolves them on its own
/// ([`super::mode_steps::resolve`]), against those fixed at the first frame.
#[derive(Default)]
struct Resolutions {
    /// Frames whose own resolution gives exactly the fixed steps.
    same: u64,
    /// Frames resolved (all of them, unless the stream cannot have mode steps).
    frames: u64,
    /// Each step (start, len) any frame resolved, with the number of frames that did.
    steps: std::collections::BTreeMap<(usize, usize), u64>,
}

impl Resolutions {
    fn add(&mut self, own: &[(Step, Found)], fixed: &[(Step, Found)]) {
        let key = |(s, _): &(Step, Found)| (s.start, s.len);
        let own: Vec<(usize, usize)> = own.iter().map(key).collect();
        self.frames += 1;
        if own == fixed.iter().map(key).collect::<Vec<_>>() {
            self.same += 1;
        }
        for step in own {
            *self.steps.entry(step).or_default() += 1;
        }
    }

    /// Frames that resolve the step (start, len) on their own.
    fn of(&self, step: &Step) -> u64 {
        self.steps.get(&(step.start, step.len)).copied().unwrap_or(0)
    }

    /// The steps some frames resolve that the first did not, as (start, len, frames).
    fn others<'a>(&'a self, fixed: &'a [StepAcc]) -> impl Iterator<Item = (usize, usize, u64)> + 'a {
        self.steps.iter().filter(|((start, len), _)| !fixed.iter().any(|a| a.step.start == *start && a.step.len == *len)).map(|(&(start, len), &n)| (start, len, n))
    }
}

/// See [`super::Missing`].
pub fn left_out(ctx: &Context, missing: super::Missing) -> Option<&'static str> {
    (missing == super::Missing::AllVectors && ctx.is_disks()).then_some("the mode steps of Table III and Figs. 10-12")
}

pub fn new(ctx: &Context) -> Option<Box<dyn Analysis>> {
    if !ctx.is_disks() {
        return None;
    }
    Some(Box::new(Modes { ctx: ctx.clone(), candidates: candidates(ctx), steps: Vec::new(), shown: None, resolved: Resolutions::default() }))
}

/// The row of the mode table (modes.csv, modes.json).
#[derive(Clone, Debug, Serialize)]
pub struct ModeRow {
    /// "+" below the null space (positive exponents), "-" above it.
    pub side: String,
    /// Paper (1-based) indices of the first and last exponent of the step.
    pub first: usize,
    pub last: usize,
    /// The number of exponents: 2 or 4 for a mode of one wave vector.
    pub degeneracy: usize,
    /// "degenerate" (equal exponents within the tolerance), "separated" (set apart from
    /// its neighbours, [`km::SEPARATION`]), "widened" (a shorter step classified L/P/LP,
    /// widened to its LP mode's size by [`resolve_steps`](super::mode_steps::resolve_steps)) or "vectors" (a block next to the
    /// mode region that stands apart and whose vectors are that mode, [`resolve_steps`](super::mode_steps::resolve_steps)).
    pub detection: String,
    /// Mean forward GS exponent of the step.
    pub lambda: f64,
    /// Largest minus smallest of its GS exponents: a step found by separation or by its
    /// vectors need not be degenerate (a small system's LP exponents differ by many errors).
    pub spread: f64,
    /// Majority class over the frames ("T", "L", "P", "LP"; "-" if unclassified).
    pub kind: String,
    /// The (first) wave vector of the majority candidate; none (empty cells, null) if
    /// unclassified.
    pub n_x: Option<i32>,
    pub n_y: Option<i32>,
    /// Its wave number |k| (NaN if unclassified).
    pub k: f64,
    /// "T(1,0)", "LP(2,0)", "T(1,0)+T(0,1)" (several wave vectors of one |k|), ...;
    /// "unclassified" where no candidate won a frame or the winner's fraction is below
    /// [`MIN_FRACTION`].
    pub name: String,
    /// The candidate that won most frames, even where it explains too little to count.
    pub best: String,
    /// The share of the vectors it explains beyond chance ([`excess`] of the GS fraction, or
    /// of the CLV one without GS vectors); below [`MIN_FRACTION`] the step is unclassified.
    pub beyond_chance: f64,
    /// Mean fraction (over frames) of the normalised position parts of the step's GS
    /// (resp. CLV) vectors in the span of the majority candidate's (`best`) basis.
    pub fraction_gs: Option<f64>,
    pub fraction_clv: Option<f64>,
    /// Share of frames whose own best candidate is the majority one.
    pub agreement: f64,
    /// Share of frames that find this step when they resolve the steps on their own (the
    /// table's steps are those of the first frame).
    pub resolved: f64,
    /// The class agrees with the degeneracy (T: 2 per wave vector; L, P, LP: 4).
    pub consistent: bool,
    pub frames: u64,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

fn fmt(x: f64) -> String {
    super::csv_number(x)
}

impl Analysis for Modes {
    fn name(&self) -> &'static str {
        "modes"
    }

    fn consume(&mut self, frame: &Frame) -> Result<()> {
        let (d, families) = (frame.d, self.candidates.families.len());
        if self.shown.is_none() {
            self.shown = Some(frame.clone());
            self.ctx.settle(frame);
            let candidates = families * KINDS.len();
            self.steps = self
                .ctx
                .modes
                .iter()
                .flatten()
                .map(|&(step, found)| StepAcc {
                    step,
                    found,
                    gs: Mean::new(candidates),
                    clv: Mean::new(candidates),
                    votes: vec![0; candidates],
                    fits: (step.len == 2).then(|| Mean::new(2 * step.len * families * FIT_VALUES)),
                })
                .collect();
        }
        if let (Ok(fixed), Ok(own)) = (&self.ctx.modes, super::mode_steps::resolve(&self.ctx, frame)) {
            self.resolved.add(&own, fixed);
        }
        let cands = &self.candidates;
        let steps = &mut self.steps;
        let fractions = |set: &[f64]| km::mode_fractions(set, &frame.phase, cands, Part::Position).into_iter().map(|m| m.fraction).collect::<Vec<_>>();
        for acc in steps.iter_mut() {
            let clv = group(&frame.v, d, &acc.step);
            let gs = frame.g.as_deref().map(|g| group(g, d, &acc.step));
            if let Some(m) = classify_step(frame, &acc.step, cands) {
                acc.votes[candidate(m.kind, m.family)] += 1;
            }
            acc.clv.add(fractions(clv));
            if let Some(gs) = gs {
                acc.gs.add(fractions(gs));
            }
            if let Some(fits) = acc.fits.as_mut() {
                let mut row = Vec::with_capacity(2 * acc.step.len * families * FIT_VALUES);
                for set in [gs, Some(clv)] {
                    for j in 0..acc.step.len {
                        for family in &cands.families {
                            match (set, family.single()) {
                                (Some(set), Some(wave)) => {
                                    let (q, p) = km::fit_transverse(vecset::col(set, d, j), &frame.phase, wave, cands.lx, cands.ly);
                                    row.extend([q.amplitude, q.residual, q.residual / q.amplitude, p.amplitude, p.residual, p.residual / p.amplitude]);
                                }
                                _ => row.extend([f64::NAN; FIT_VALUES]),
                            }
                        }
                    }
                }
                fits.add(row);
            }
        }
        Ok(())
    }

    fn finish(self: Box<Self>, out: &Path, frames: u64) -> Result<Vec<Produced>> {
        let why = self.ctx.modes.as_ref().err().cloned();
        let source = if self.ctx.with_gs { "GS vectors" } else { "covariant vectors (the frames carry no GS vectors)" };
        let (rows, chosen): (Vec<ModeRow>, Vec<Chosen>) = self.steps.iter().map(|acc| self.mode_row(acc, frames)).unzip();
        self.write_table(out, &rows, source, frames, why.as_deref())?;

        let mut tables = vec!["modes.csv".to_string(), "modes.json".to_string()];
        let mut fit_rows = self.mean_fit_rows(&chosen);
        let (pattern_entries, transverse_rows, lp_rows) = self.pattern_figures(&chosen, out)?;
        fit_rows.extend(transverse_rows);
        if !fit_rows.is_empty() {
            let header = ["first", "last", "i", "source", "n_x", "n_y", "scope", "amp_dqt", "resid_dqt", "rel_resid_dqt", "amp_dpt", "resid_dpt", "rel_resid_dpt"];
            write_text_csv(&out.join("modes_fits.csv"), &header, &fit_rows)?;
            tables.push("modes_fits.csv".into());
        }
        if !lp_rows.is_empty() {
            let header = ["first", "last", "n_x", "n_y", "source", "figure", "pattern", "overlap", "amplitude", "phase", "residual"];
            write_text_csv(&out.join("modes_lp.csv"), &header, &lp_rows)?;
            tables.push("modes_lp.csv".into());
        }

        let caption = self.caption(&rows, why.as_deref(), frames, source);
        let mut produced = vec![Produced { title: "Lyapunov modes (Table III)".into(), caption, figures: vec![], tables }];
        produced.extend(pattern_entries);
        produced.extend(dispersion(&self.ctx, &rows, out)?);
        Ok(produced)
    }
}

/// The classification of a step that counts: the majority candidate's kind and family (index
/// into [`Candidates::families`]); none where the step is unclassified.
type Chosen = Option<(ModeKind, usize)>;

/// Rows of a text table (modes_fits.csv, modes_lp.csv).
type TextRows = Vec<Vec<String>>;

impl Modes {
    /// The mode table's row of one step, classified by the majority vote over the frames, and
    /// its [`Chosen`] classification: the winner where it explains at least [`MIN_FRACTION`]
    /// of the vectors beyond chance.
    fn mode_row(&self, acc: &StepAcc, frames: u64) -> (ModeRow, Chosen) {
        let (ctx, cands, d) = (&self.ctx, &self.candidates, self.ctx.d);
        let (gs, clv) = (acc.gs.mean(), acc.clv.mean());
        // majority vote; ties go to the candidate of lower |k|
        let best = (0..acc.votes.len()).filter(|&c| acc.votes[c] > 0).max_by_key(|&c| (acc.votes[c], std::cmp::Reverse(c)));
        let pick = |m: &Mean, v: &[f64]| best.filter(|_| m.n > 0).and_then(|c| finite(v[c]));
        let candidate = best.map(candidate_of).map(|(k, f)| (k, &cands.families[f]));
        // A candidate that explains little of the vectors is no classification, however
        // often it comes out on top.
        let fraction = pick(&acc.gs, &gs).or(pick(&acc.clv, &clv));
        let beyond_chance = fraction.zip(candidate).map_or(f64::NAN, |(f, (k, family))| excess(f, family.dim(k), d));
        let clear = beyond_chance >= MIN_FRACTION;
        let (kind, family) = candidate.filter(|_| clear).map_or((None, None), |(k, f)| (Some(k), Some(f)));
        let wave = family.map(|f| f.waves[0]);
        let (lambda, spread) = gs_exponents(ctx, &acc.step);
        let row = ModeRow {
            side: if is_positive(&acc.step, d) { "+".into() } else { "-".into() },
            first: acc.step.start + 1,
            last: acc.step.start + acc.step.len,
            degeneracy: acc.step.len,
            detection: detection(ctx, acc),
            lambda,
            spread,
            kind: kind.map_or("-".into(), |k| format!("{k:?}")),
            n_x: wave.map(|w| w.n_x),
            n_y: wave.map(|w| w.n_y),
            k: family.map_or(f64::NAN, |f| f.k),
            name: kind.zip(family).map_or("unclassified".into(), |(k, f)| f.name(k)),
            best: candidate.map_or("-".into(), |(k, f)| f.name(k)),
            beyond_chance,
            fraction_gs: pick(&acc.gs, &gs),
            fraction_clv: pick(&acc.clv, &clv),
            agreement: best.map_or(0.0, |c| acc.votes[c] as f64 / frames.max(1) as f64),
            resolved: self.resolved.of(&acc.step) as f64 / self.resolved.frames.max(1) as f64,
            consistent: kind.zip(family).is_some_and(|(k, f)| matches_degeneracy(&acc.step, k, f)),
            frames,
        };
        (row, kind.zip(best.map(|c| candidate_of(c).1)).filter(|_| clear))
    }

    /// The mode table: modes.csv, and modes.json with the rows, the rules' settings, the
    /// candidates and `why` there are no steps.
    fn write_table(&self, out: &Path, rows: &[ModeRow], source: &str, frames: u64, why: Option<&str>) -> Result<()> {
        let cands = &self.candidates;
        let header = ["side", "first", "last", "degeneracy", "detection", "lambda", "spread", "kind", "n_x", "n_y", "k", "name", "best", "beyond_chance", "fraction_gs", "fraction_clv", "agreement", "resolved", "consistent", "frames"];
        let text: Vec<Vec<String>> = rows.iter().map(ModeRow::cells).collect();
        write_text_csv(&out.join("modes.csv"), &header, &text)?;
        let json = serde_json::json!({
            "source": source,
            "frames": frames,
            "step_tolerance": STEP_TOL,
            "separation": km::SEPARATION,
            "window": step_window(self.ctx.d, cands),
            "max_n": MAX_N,
            "min_fraction": MIN_FRACTION,
            "candidates": cands.families.iter().map(|f| f.name(ModeKind::T).replace('T', "")).collect::<Vec<_>>(),
            "note": why,
            "modes": rows,
            "resolved_alike": self.resolved.same,
            "other_steps": self.resolved.others(&self.steps).map(|(start, len, n)| serde_json::json!({"first": start + 1, "last": start + len, "frames": n})).collect::<Vec<_>>(),
        });
        super::write_report_file(&out.join("modes.json"), &serde_json::to_vec_pretty(&json).unwrap_or_default())
    }

    /// The rows of modes_fits.csv of scope "mean": the sine fits A cos(k x + phi) of dq and dp
    /// across k, averaged over frames, of every vector (GS and CLV) of the two-fold steps
    /// classified T.
    fn mean_fit_rows(&self, chosen: &[Chosen]) -> TextRows {
        let cands = &self.candidates;
        let mut fit_rows = Vec::new();
        let families = cands.families.len();
        for (acc, c) in self.steps.iter().zip(chosen) {
            let (Some(fits), Some((ModeKind::T, f))) = (acc.fits.as_ref(), c) else { continue };
            let Some(wave) = cands.families[*f].single() else { continue };
            let mean = fits.mean();
            for (s, src) in ["GS", "CLV"].into_iter().enumerate() {
                for j in 0..acc.step.len {
                    let at = ((s * acc.step.len + j) * families + f) * FIT_VALUES;
                    let v = &mean[at..at + FIT_VALUES];
                    if v.iter().all(|x| x.is_nan()) {
                        continue;
                    }
                    let mut row = vec![(acc.step.start + 1).to_string(), (acc.step.start + acc.step.len).to_string(), (acc.step.start + j + 1).to_string(), src.into(), wave.n_x.to_string(), wave.n_y.to_string(), "mean".into()];
                    row.extend(v.iter().map(|&x| fmt(x)));
                    fit_rows.push(row);
                }
            }
        }
        fit_rows
    }

    /// The pattern figures at the first frame of the positive steps classified as a mode of one
    /// wave vector with that mode's degeneracy: Fig. 10 for T, Figs. 11 and 12 for LP. Their
    /// report entries, the T steps' rows of modes_fits.csv and the LP steps' rows of
    /// modes_lp.csv.
    fn pattern_figures(&self, chosen: &[Chosen], out: &Path) -> Result<(Vec<Produced>, TextRows, TextRows)> {
        let cands = &self.candidates;
        let shown = self.shown.as_ref();
        let (mut pattern_entries, mut fit_rows, mut lp_rows) = (Vec::new(), Vec::new(), Vec::new());
        for (acc, c) in self.steps.iter().zip(chosen) {
            let (Some(frame), Some((kind, f))) = (shown, *c) else { continue };
            let family = &cands.families[f];
            if !is_positive(&acc.step, self.ctx.d) || !matches_degeneracy(&acc.step, kind, family) {
                continue;
            }
            // A step of several wave vectors (T(1,0)+T(0,1) in a square box) gets the figures
            // of each, reconstructed inside the whole step.
            for &wave in &family.waves {
                // In the paper's order of figures: the T modes (Fig. 10), then the LP modes
                // (Figs. 11, 12), each by wave vector (by |n_x| + |n_y|, then (1,0) before (0,1)),
                // whatever the order of their steps.
                let order = (kind != ModeKind::T, wave.n_x.abs() + wave.n_y.abs(), wave.n_y.abs());
                if kind == ModeKind::T {
                    let (entry, rows) = transverse_figures(cands, frame, &acc.step, family, wave, out)?;
                    fit_rows.extend(rows);
                    pattern_entries.push((order, entry));
                } else {
                    let (entry, rows) = lp_figures(cands, frame, &acc.step, family, wave, out)?;
                    lp_rows.extend(rows);
                    pattern_entries.push((order, entry));
                }
            }
        }
        pattern_entries.sort_by_key(|(order, _)| *order);
        Ok((pattern_entries.into_iter().map(|(_, entry)| entry).collect(), fit_rows, lp_rows))
    }

    /// The caption of the mode table: how steps are found and classified and what was found,
    /// or why there is no table, or that no step was found.
    fn caption(&self, rows: &[ModeRow], why: Option<&str>, frames: u64, source: &str) -> String {
        let (cands, d) = (&self.candidates, self.ctx.d);
        let found: Vec<String> = rows.iter().map(ModeRow::summary).collect();
        let mut lengths: Vec<String> = cands.step_lengths().iter().rev().map(|l| l.to_string()).collect();
        let last = lengths.pop().unwrap_or_default();
        let lengths = if lengths.is_empty() { last } else { format!("{} or {last}", lengths.join(", ")) };
        match (why, found.is_empty()) {
            (Some(why), _) => format!("No mode table: {why}."),
            (None, true) => format!(
                "No degenerate steps of {} exponents (neighbours equal within {STEP_TOL} combined standard errors, or set apart by gaps {:.0} times their spread) within {} indices of the null space in the forward GS spectrum, and no block next to the null space that stands apart from its neighbours with vectors of a mode: this system shows no Lyapunov modes at this precision. The table is empty.",
                lengths,
                1.0 / km::SEPARATION,
                step_window(d, cands)
            ),
            (None, false) => format!(
                "Degenerate steps of the forward GS spectrum within {} indices of the null space (neighbours equal within {STEP_TOL} combined standard errors, or, next to the null space, set apart by gaps {:.0} times their spread; a shorter step classified L/P/LP is widened to the block of its LP mode's size that the LP basis explains best; next to the mode region, a block of a mode's size set apart from its neighbours is a step where its vectors are that mode at the first frame: the table's detection column says which rule found each), classified in each of {frames} frames by projecting the position perturbations of their {source} onto the orthonormalised Table III bases T, L, P, LP of {}; majority class, mean fraction of the group in its span. Found: {}. {}",
                step_window(d, cands),
                1.0 / km::SEPARATION,
                candidates_text(cands),
                found.join("; "),
                self.resolution_text()
            ),
        }
    }

    /// How typical the first frame's steps are, for the caption: how many frames resolve the
    /// same steps on their own, and which other steps some frames find.
    fn resolution_text(&self) -> String {
        let r = &self.resolved;
        let others: Vec<String> = r.others(&self.steps).map(|(start, len, n)| format!("i = {}..{} in {n}", start + 1, start + len)).collect();
        let others = if others.is_empty() { "no frame finds another step".to_string() } else { format!("other steps found by some frames: {}", others.join(", ")) };
        let at = self.shown.as_ref().map_or(String::new(), |f| format!(" (step {}, the newest: the backward stream delivers it first)", f.step));
        format!(
            "The steps are those resolved at the first sampled frame read{at}; resolved at each frame on its own, {} of {} frames give the same steps ({others}; the resolved column).",
            r.same, r.frames
        )
    }
}

/// How the step was found, in the words of [`ModeRow::detection`].
fn detection(ctx: &Context, acc: &StepAcc) -> String {
    match (acc.found, ctx.gs.as_ref()) {
        (Found::Widened, _) => "widened".into(),
        (Found::Vectors, _) => "vectors".into(),
        (Found::Exponents, Some(g)) if !km::within_errors(&g.exponents, &g.stderr, STEP_TOL, &acc.step) => "separated".into(),
        _ => "degenerate".into(),
    }
}

/// The mean lambda of the step's forward GS exponents and their spread (largest minus
/// smallest); both NaN without the forward spectrum.
fn gs_exponents(ctx: &Context, step: &Step) -> (f64, f64) {
    let of_step = ctx.gs.as_ref().map_or(&[][..], |g| &g.exponents[step.start..step.start + step.len]);
    let lambda = if of_step.is_empty() { f64::NAN } else { of_step.iter().sum::<f64>() / step.len as f64 };
    let spread = of_step.iter().copied().fold(f64::NEG_INFINITY, f64::max) - of_step.iter().copied().fold(f64::INFINITY, f64::min);
    (lambda, if of_step.is_empty() { f64::NAN } else { spread })
}

impl ModeRow {
    /// The row's cells in modes.csv (empty n_x, n_y where unclassified).
    fn cells(&self) -> Vec<String> {
        let r = self;
        vec![
            r.side.clone(),
            r.first.to_string(),
            r.last.to_string(),
            r.degeneracy.to_string(),
            r.detection.clone(),
            fmt(r.lambda),
            fmt(r.spread),
            r.kind.clone(),
            r.n_x.map_or(String::new(), |n| n.to_string()),
            r.n_y.map_or(String::new(), |n| n.to_string()),
            fmt(r.k),
            r.name.clone(),
            r.best.clone(),
            fmt(r.beyond_chance),
            fmt(r.fraction_gs.unwrap_or(f64::NAN)),
            fmt(r.fraction_clv.unwrap_or(f64::NAN)),
            fmt(r.agreement),
            fmt(r.resolved),
            r.consistent.to_string(),
            r.frames.to_string(),
        ]
    }

    /// The step in words for the caption's list of what was found: its name, indices,
    /// degeneracy, detection, lambda, fraction and agreement.
    fn summary(&self) -> String {
        let r = self;
        let weak = if r.name != r.best { format!(" of the best candidate {}, {:.2} beyond chance, below {MIN_FRACTION}", r.best, r.beyond_chance) } else { String::new() };
        format!(
            "{} at i = {}..{} ({}-fold{}, λ = {:.4}{}, fraction {:.2}{weak}, {:.0}% of frames agree, {} of {} find the step on their own)",
            r.name,
            r.first,
            r.last,
            r.degeneracy,
            if r.detection == "degenerate" { String::new() } else { format!(", {}", r.detection) },
            r.lambda,
            if r.detection == "degenerate" { String::new() } else { format!(" with its exponents spread over {:.4}", r.spread) },
            r.fraction_gs.or(r.fraction_clv).unwrap_or(f64::NAN),
            100.0 * r.agreement,
            (r.resolved * r.frames as f64).round(),
            r.frames
        )
    }
}

/// The candidates in words, for captions: "the wave vectors k = 2π (n_x/L_x, n_y/L_y) with
/// |k| ≤ 0.637: (1,0), (2,0), ...".
fn candidates_text(cands: &Candidates) -> String {
    let k_max = std::f64::consts::TAU * MAX_N as f64 / cands.lx.max(cands.ly);
    let singles: Vec<String> = cands.families.iter().filter_map(|f| f.single()).map(|w| w.to_string()).collect();
    let together: Vec<String> = cands.families.iter().filter(|f| f.waves.len() > 1).map(|f| f.waves.iter().map(|w| w.to_string()).collect::<Vec<_>>().join("+")).collect();
    let together = if together.is_empty() {
        String::new()
    } else {
        format!(", each alone, and those of one |k| together, which the box's symmetry makes degenerate (steps of 2 exponents per wave vector for T, 4 for LP): {}", together.join(", "))
    };
    format!("the wave vectors k = 2π (n_x/L_x, n_y/L_y) with |k| ≤ 2π·{MAX_N}/max(L_x, L_y) = {k_max:.3}: {}{together}", singles.join(", "))
}

/// Least-squares line through the origin, y = c x: c and its standard error from the
/// residuals (NaN with fewer than two points).
fn fit_through_origin(x: &[f64], y: &[f64]) -> (f64, f64) {
    let sxx: f64 = x.iter().map(|x| x * x).sum();
    let c = x.iter().zip(y).map(|(x, y)| x * y).sum::<f64>() / sxx;
    let m = x.len();
    let se = if m < 2 { f64::NAN } else { (x.iter().zip(y).map(|(x, y)| (y - c * x).powi(2)).sum::<f64>() / (m - 1) as f64 / sxx).sqrt() };
    (c, se)
}

/// The dispersion relation of the modes (beyond the paper): the exponent of each positive,
/// consistently classified step against its wave number |k|, per kind, with a line through
/// the origin. The kinetic theory of Lyapunov modes (de Wijn & van Beijeren, Phys. Rev. E 70,
/// 016207 (2004)) gives lambda proportional to k at small k; how far lambda / k drifts with
/// k shows where that ends.
fn dispersion(ctx: &Context, rows: &[ModeRow], out: &Path) -> Result<Option<Produced>> {
    let mut modes: Vec<&ModeRow> = rows.iter().filter(|r| r.side == "+" && r.consistent && r.k.is_finite() && r.lambda.is_finite()).collect();
    modes.sort_by(|a, b| a.kind.cmp(&b.kind).then(a.k.total_cmp(&b.k)));
    if modes.is_empty() {
        return Ok(None);
    }
    let wave_number = |r: &ModeRow| r.k;
    let stderr = |r: &ModeRow| ctx.gs.as_ref().map_or(f64::NAN, |g| g.stderr[r.first - 1..r.last].iter().sum::<f64>() / r.degeneracy as f64);
    let number = |n: Option<i32>| n.map_or(String::new(), |n| n.to_string());
    let table: Vec<Vec<String>> = modes.iter().map(|r| vec![r.kind.clone(), r.name.clone(), number(r.n_x), number(r.n_y), fmt(wave_number(r)), fmt(r.lambda), fmt(stderr(r)), fmt(r.spread), fmt(r.lambda / wave_number(r))]).collect();
    write_text_csv(&out.join("modes_dispersion.csv"), &["kind", "name", "n_x", "n_y", "k", "lambda", "stderr", "spread", "lambda_over_k"], &table)?;
    let mut kinds: Vec<&str> = modes.iter().map(|r| r.kind.as_str()).collect();
    kinds.dedup();
    let mut fig = Figure::new("Dispersion of the Lyapunov modes").x_label("k = |k|, k = 2π (n_x/L_x, n_y/L_y)").y_label("λ");
    let mut fits = Vec::new();
    let mut lines = Vec::new();
    // The points first: the first series get the largest markers.
    for (colour, &kind) in kinds.iter().enumerate() {
        let of_kind: Vec<&&ModeRow> = modes.iter().filter(|r| r.kind == kind).collect();
        let k: Vec<f64> = of_kind.iter().map(|r| wave_number(r)).collect();
        let lambda: Vec<f64> = of_kind.iter().map(|r| r.lambda).collect();
        let (c, se) = fit_through_origin(&k, &lambda);
        fig.series(&format!("{kind} modes"), &k, &lambda, Marker::Points).color(colour);
        let k_max = k.iter().copied().fold(0.0, f64::max);
        lines.push((format!("{kind}: λ = {c:.4} k"), k_max, c, colour));
        let ratios: Vec<String> = of_kind.iter().map(|r| format!("{:.4}", r.lambda / wave_number(r))).collect();
        let error = if se.is_finite() { format!(" ± {se:.1e}") } else { String::new() };
        fits.push(format!("{kind}: c = {c:.4}{error} from {} step(s), λ/k = {} for {}", k.len(), ratios.join(", "), of_kind.iter().map(|r| r.name.as_str()).collect::<Vec<_>>().join(", ")));
    }
    // Each fit in the colour of its points.
    for (label, k_max, c, colour) in lines {
        fig.series(&label, &[0.0, k_max], &[0.0, c * k_max], Marker::Line).color(colour);
    }
    // The range of each step's exponents, around the mean the point is.
    let mut ranged = false;
    for (colour, &kind) in kinds.iter().enumerate() {
        for r in modes.iter().filter(|r| r.kind == kind) {
            let Some(range) = ctx.gs.as_ref().and_then(|g| g.exponents.get(r.first - 1..r.last)) else { continue };
            let (lo, hi) = range.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &l| (lo.min(l), hi.max(l)));
            if lo.is_finite() && hi > lo {
                fig.series("", &[r.k, r.k], &[lo, hi], Marker::Line).color(colour);
                ranged = true;
            }
        }
    }
    save_figure(&fig, out, "modes_dispersion")?;
    Ok(Some(Produced {
        title: "Dispersion of the Lyapunov modes (beyond the paper)".into(),
        caption: format!(
            "Exponent λ of each positive mode step of the table above against its wave number |k|, k = 2π (n_x/L_x, n_y/L_y) (L_x = {:.4}, L_y = {:.4}), with a least-squares line λ = c k through the origin for each kind{}: {}. \
             The kinetic theory of Lyapunov modes (de Wijn & van Beijeren 2004) gives λ proportional to k for small k; λ/k changing with k shows where that ends.{}",
            ctx.lx,
            ctx.ly,
            if ranged { " and, as vertical bars, the range of each step's exponents" } else { "" },
            fits.join("; "),
            {
                let split: Vec<String> = modes.iter().filter(|r| r.detection != "degenerate").map(|r| format!("{} ({:.4})", r.name, r.spread)).collect();
                if split.is_empty() {
                    String::new()
                } else {
                    format!(" λ is the mean of a step's exponents, and stderr the mean of their errors; the exponents of {} are not equal within those errors but spread over the ranges given (the spread column), which bound λ better than the errors do.", split.join(", "))
                }
            }
        ),
        figures: vec!["modes_dispersion".into()],
        tables: vec!["modes_dispersion.csv".into()],
    }))
}

/// How the pattern figures of one wave vector show it: the position along k on the x axis,
/// wrapped into the length over which the pattern repeats `periods` times, and the names of
/// the components along and across k (x and y for (n_x, 0), as in the paper's figures).
struct WaveAxes {
    wave: Wave,
    k: f64,
    along: [f64; 2],
    across: [f64; 2],
    span: f64,
    x_label: &'static str,
    along_name: &'static str,
    across_name: &'static str,
}

impl WaveAxes {
    fn new(cands: &Candidates, wave: Wave) -> Self {
        let (lx, ly) = (cands.lx, cands.ly);
        let (along, across) = wave.axes(lx, ly);
        let k = wave.norm(lx, ly);
        let (span, x_label, along_name, across_name) = match (wave.n_x, wave.n_y) {
            (_, 0) => (lx, "q_x", "x", "y"),
            (0, _) => (ly, "q_y", "y", "x"),
            _ => (std::f64::consts::TAU * wave.periods() as f64 / k, "e_k·q (along k)", "k", "t"),
        };
        WaveAxes { wave, k, along, across, span, x_label, along_name, across_name }
    }

    /// The position along k of every disk, wrapped into [0, span).
    fn positions(&self, phase: &[f64]) -> Vec<f64> {
        km::project(km::part_of(phase, Part::Position), self.along).into_iter().map(|x| x.rem_euclid(self.span)).collect()
    }

    /// "T1" for (1,0), "T1_m1" for (1,-1): file names.
    fn stem(&self, kind: ModeKind) -> String {
        let Wave { n_x, n_y } = self.wave;
        let signed = |n: i32| if n < 0 { format!("m{}", -n) } else { n.to_string() };
        if n_y == 0 { format!("{kind:?}{n_x}") } else { format!("{kind:?}{}_{}", signed(n_x), signed(n_y)) }
    }
}

/// The curve amplitude cos(k x + phase) on a fine grid over [0, span].
fn fit_curve(fit: &SineFit, k: f64, span: f64) -> (Vec<f64>, Vec<f64>) {
    let x: Vec<f64> = (0..=200).map(|i| span * i as f64 / 200.0).collect();
    let y = x.iter().map(|&x| fit.amplitude * (k * x + fit.phase).cos()).collect();
    (x, y)
}

/// Per-disk values of one source of vectors ("GS" or "CLV") in a pattern figure, in the
/// source's colour ([`source_color`]); a check, a pattern that vanishes for an ideal mode,
/// in open markers.
struct Scatter {
    label: String,
    src: String,
    y: Vec<f64>,
    check: bool,
}

/// The palette colour of the vectors of `src`, "GS" or "CLV", as in every figure that
/// shows both ([`super::GS_COLOR`]).
fn source_color(src: &str) -> usize {
    if src == "GS" { super::GS_COLOR } else { super::CLV_COLOR }
}

/// A scatter figure of per-disk values against the position along k with sine-fit curves
/// (label, source, fit), each in its source's colour: the values first, then the checks,
/// then the fits.
fn pattern_figure(title: &str, y_label: &str, axes: &WaveAxes, x: &[f64], points: &[Scatter], fits: &[(String, String, SineFit)]) -> Figure {
    let mut fig = Figure::new(title).x_label(axes.x_label).y_label(y_label).x_range(0.0, axes.span);
    for check in [false, true] {
        for p in points.iter().filter(|p| p.check == check) {
            fig.series(&p.label, x, &p.y, Marker::Points).color(source_color(&p.src)).open_markers(check);
        }
    }
    for (label, src, fit) in fits {
        if fit.amplitude.is_finite() {
            let (cx, cy) = fit_curve(fit, axes.k, axes.span);
            fig.series(label, &cx, &cy, Marker::Line).color(source_color(src));
        }
    }
    fig.hline(0.0);
    fig
}

/// A y range that shows the bulk of `values`: the 5th to 95th percentile widened by its own
/// width on both sides, with the number of values beyond it, if there are any; None if all
/// fit.
fn robust_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64, usize)> {
    let mut v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    if v.len() < 20 {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let (p5, p95) = (v[v.len() / 20], v[v.len() - 1 - v.len() / 20]);
    let (lo, hi) = (p5 - (p95 - p5), p95 + (p95 - p5));
    let off = v.iter().filter(|&&x| x < lo || x > hi).count();
    (off > 0).then_some((lo, hi, off))
}

/// Columns of per-disk values (the first is q_x), written as one CSV.
struct Columns(Vec<(String, Vec<f64>)>);

impl Columns {
    fn push(&mut self, name: String, y: &[f64]) {
        self.0.push((name, y.to_vec()));
    }
    fn write(&self, path: &Path) -> Result<()> {
        let header: Vec<&str> = self.0.iter().map(|(c, _)| c.as_str()).collect();
        let n = self.0.first().map_or(0, |c| c.1.len());
        write_csv(path, &header, (0..n).map(|r| self.0.iter().map(|(_, c)| c[r]).collect()))
    }
}

fn fit_cells(fit: &[SineFit; 2]) -> Vec<String> {
    fit.iter().flat_map(|f| [f.amplitude, f.residual, f.residual / f.amplitude]).map(fmt).collect()
}

/// Fig. 10 for one wave vector of a T step: its perturbations across k (dq_y and dp_y for
/// (n_x, 0)) against the position along k (q_x), GS and CLV, with fits. A pair of one wave
/// vector shows its last vector (the one nearest the null space, as the paper's i = 393 for
/// T(1,0)), the CLV's sign matched to the GS vector; a step of several wave vectors shows,
/// for each, the vector of the step's span whose dq best matches that wave's cos pattern
/// (reconstructed as Figs. 11 and 12 reconstruct L and P), with dq along k, which vanishes
/// for an ideal T pattern, as a check.
fn transverse_figures(cands: &Candidates, frame: &Frame, step: &Step, family: &Family, wave: Wave, out: &Path) -> Result<(Produced, Vec<Vec<String>>)> {
    let axes = WaveAxes::new(cands, wave);
    let d = frame.d;
    let i = step.start + step.len - 1;
    let x = axes.positions(&frame.phase);
    // The wave vector's own family (the step's may hold several).
    let own = Family { waves: vec![wave], k: axes.k };
    let name = own.name(ModeKind::T);
    let several = family.single().is_none();
    // (source, vector, |cos| of its dq with the pattern where reconstructed)
    let mut sources: Vec<(&str, Vec<f64>, Option<f64>)> = Vec::new();
    if several {
        let pattern = km::mode_patterns(ModeKind::T, &own, &frame.phase, cands.lx, cands.ly);
        let cos = &pattern[..d / 2];
        if let Some(g) = frame.g.as_deref() {
            let r = km::reconstruct(group(g, d, step), d, cos, Part::Position);
            sources.push(("GS", r.vector, Some(r.overlap)));
        }
        let r = km::reconstruct(group(&frame.v, d, step), d, cos, Part::Position);
        sources.push(("CLV", r.vector, Some(r.overlap)));
    } else {
        let gs = frame.g(i);
        // the sign of a vector is arbitrary: show the CLV with the sign that best matches g^i
        let sign = gs.map_or(1.0, |g| if vecset::dot(g, frame.v(i)) < 0.0 { -1.0 } else { 1.0 });
        if let Some(g) = gs {
            sources.push(("GS", g.to_vec(), None));
        }
        sources.push(("CLV", frame.v(i).iter().map(|x| sign * x).collect(), None));
    }
    let stem = format!("fig10_{}_i{}", axes.stem(ModeKind::T), i + 1);
    let mut rows = Vec::new();
    let mut columns = Columns(vec![(axes.x_label.split(' ').next().unwrap_or("x").into(), x.clone())]);
    let mut figs = Vec::new();
    let (a, t) = (axes.along_name, axes.across_name);
    let shown = if several { format!("{name} in {}, i = {}..{}", family.name(ModeKind::T), step.start + 1, i + 1) } else { format!("{name}, i = {}", i + 1) };
    for (part, comp, label) in [(Part::Position, format!("dq{t}"), format!("δq_{t}")), (Part::Momentum, format!("dp{t}"), format!("δp_{t}"))] {
        let mut points = Vec::new();
        let mut fits = Vec::new();
        for (src, v, _) in &sources {
            let y = km::project(km::part_of(v, part), axes.across);
            let fit = km::fit_sine(&x, &y, axes.k);
            fits.push((format!("{src} fit: A = {:.3}, rms residual {:.3}", fit.amplitude, fit.residual), src.to_string(), fit));
            columns.push(format!("{comp}_{}", src.to_lowercase()), &y);
            points.push(Scatter { label: src.to_string(), src: src.to_string(), y, check: false });
        }
        if several && part == Part::Position {
            for (src, v, _) in &sources {
                let y = km::project(km::part_of(v, part), axes.along);
                columns.push(format!("dq{a}_{}", src.to_lowercase()), &y);
                points.push(Scatter { label: format!("{src} δq_{a} (0 for an ideal T)"), src: src.to_string(), y, check: true });
            }
        }
        let title = format!("{shown}: {label} against {} (step {})", axes.x_label, frame.step);
        let fstem = format!("{stem}_{comp}");
        save_figure(&pattern_figure(&title, &label, &axes, &x, &points, &fits), out, &fstem)?;
        figs.push(fstem);
    }
    // The averaged fits of modes_fits.csv are those of the pair's own vectors.
    if !several {
        for (src, v, _) in &sources {
            let (q, p) = km::fit_transverse(v, &frame.phase, wave, cands.lx, cands.ly);
            let mut row = vec![(step.start + 1).to_string(), (step.start + step.len).to_string(), (i + 1).to_string(), src.to_string(), wave.n_x.to_string(), wave.n_y.to_string(), format!("step {}", frame.step)];
            row.extend(fit_cells(&[q, p]));
            rows.push(row);
        }
    }
    columns.write(&out.join(format!("{stem}.csv")))?;
    let across = if t == "t" { " across k" } else { "" };
    let colours = |one: &str, both: &str| if frame.g.is_some() { both.to_string() } else { one.to_string() };
    let caption = if several {
        let overlaps: Vec<String> = sources.iter().map(|(src, _, o)| format!("{src} {:.3}", o.unwrap_or(f64::NAN))).collect();
        format!(
            "Position (δq_{t}) and momentum (δp_{t}) perturbations{across} of the pure {name} vector, reconstructed at step {} inside the {}-dimensional {} of the {} step (i = {}..{}) by least squares against the cos pattern of δq_{t} (Table III), against s = {}, with least-squares fits A cos(k s + φ) in the same colours, k = {:.4}. |cos| between the reconstructed δq and the pattern (1 where the pattern lies in the span): {}. δq_{a}, which vanishes for an ideal T pattern, as a check in open markers. Every value is in {stem}.csv.",
            frame.step,
            step.len,
            colours("covariant subspace (vermillion)", "GS (blue) and covariant (vermillion) subspaces"),
            family.name(ModeKind::T),
            step.start + 1,
            step.start + step.len,
            axes.x_label,
            axes.k,
            overlaps.join(", ")
        )
    } else {
        format!(
            "Position (δq_{t}) and momentum (δp_{t}) perturbations{across} of vector i = {} of the {name} pair (i = {}..{}) against s = {} at step {}, for the {}, with least-squares fits A cos(k s + φ) in the same colours, k = {:.4}. Fits of both vectors of the pair averaged over the frames are in modes_fits.csv (columns dqt, dpt: across k).",
            i + 1,
            step.start + 1,
            step.start + step.len,
            axes.x_label,
            frame.step,
            colours("covariant vector (vermillion)", "GS vector (blue) and the covariant vector (vermillion, sign matched to the GS vector)"),
            axes.k
        )
    };
    let (title, tables) = if several {
        (format!("Transverse mode {name} of {} (Fig. 10)", family.name(ModeKind::T)), vec![format!("{stem}.csv")])
    } else {
        (format!("Transverse mode {name} (Fig. 10)"), vec![format!("{stem}.csv"), "modes_fits.csv".into()])
    };
    Ok((Produced { title, caption, figures: figs, tables }, rows))
}

/// Figs. 11 and 12 for one wave vector of an LP step: pure L and P vectors reconstructed
/// inside the GS and the CLV group (the whole step, also where it holds several wave
/// vectors) from the position (sine patterns) and the momentum (cosine patterns) parts.
fn lp_figures(cands: &Candidates, frame: &Frame, step: &Step, family: &Family, wave: Wave, out: &Path) -> Result<(Produced, Vec<Vec<String>>)> {
    let d = frame.d;
    let axes = WaveAxes::new(cands, wave);
    let x = axes.positions(&frame.phase);
    let mut sources: Vec<(&str, &[f64])> = Vec::new();
    if let Some(g) = frame.g.as_deref() {
        sources.push(("GS", group(g, d, step)));
    }
    sources.push(("CLV", group(&frame.v, d, step)));
    let name = Family { waves: vec![wave], k: axes.k }.name(ModeKind::LP);
    let stem = format!("{}_i{}", axes.stem(ModeKind::LP), step.start + 1);
    let mut rows = Vec::new();
    let mut columns = Columns(vec![(axes.x_label.split(' ').next().unwrap_or("x").into(), x.clone())]);
    let (a, t) = (axes.along_name, axes.across_name);
    let mut figs = Vec::new();
    // rms of δq across over rms of δq along, per source: 0 for an ideal L pattern.
    let mut across = Vec::new();
    // Fig. 11 from the position part (sine patterns), Fig. 12 from the momentum part (cosine).
    let mut off_scale = Vec::new();
    for (fig_no, part, c, pattern) in [(11, Part::Position, 'q', "sin"), (12, Part::Momentum, 'p', "cos")] {
        let (mut l_points, mut p_points, mut l_fits, mut p_fits) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for &(src, set) in &sources {
            let rec = km::reconstruct_lp(set, &frame.phase, wave, cands.lx, cands.ly, part);
            let (l, p) = if part == Part::Position { (rec.l_sin, rec.p_sin) } else { (rec.l_cos, rec.p_cos) };
            let l_x = km::project(km::part_of(&l.vector, part), axes.along);
            let l_y = km::project(km::part_of(&l.vector, part), axes.across);
            let p_f = km::divide_out_momenta(km::part_of(&p.vector, part), &frame.phase);
            let (lfit, pfit) = (km::fit_sine(&x, &l_x, axes.k), km::fit_sine(&x, &p_f, axes.k));
            for (which, overlap, fit) in [("L", l.overlap, lfit), ("P", p.overlap, pfit)] {
                rows.push(vec![
                    (step.start + 1).to_string(),
                    (step.start + step.len).to_string(),
                    wave.n_x.to_string(),
                    wave.n_y.to_string(),
                    src.into(),
                    fig_no.to_string(),
                    format!("{which}_{pattern}"),
                    fmt(overlap),
                    fmt(fit.amplitude),
                    fmt(fit.phase),
                    fmt(fit.residual),
                ]);
            }
            let s = src.to_lowercase();
            columns.push(format!("fig{fig_no}_L_d{c}{a}_{s}"), &l_x);
            columns.push(format!("fig{fig_no}_L_d{c}{t}_{s}"), &l_y);
            columns.push(format!("fig{fig_no}_P_d{c}_over_p_{s}"), &p_f);
            if part == Part::Position {
                let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
                across.push(format!("{src} {:.2}", rms(&l_y) / rms(&l_x)));
            }
            l_points.push(Scatter { label: format!("{src} δ{c}_{a}"), src: src.into(), y: l_x, check: false });
            l_points.push(Scatter { label: format!("{src} δ{c}_{t} (0 for an ideal L)"), src: src.into(), y: l_y, check: true });
            p_points.push(Scatter { label: format!("{src} (δ{c}·p)/p²"), src: src.into(), y: p_f, check: false });
            l_fits.push((format!("{src} fit: A = {:.3}", lfit.amplitude), src.to_string(), lfit));
            p_fits.push((format!("{src} fit: A = {:.3}", pfit.amplitude), src.to_string(), pfit));
        }
        let what = if part == Part::Position { "position" } else { "momentum" };
        for (which, points, fits, y_label) in [("L", &l_points, &l_fits, format!("δ{c}")), ("P", &p_points, &p_fits, format!("(δ{c}·p)/p²"))] {
            // dividing by p^2 blows up the nearly resting disks: they would flatten the sinusoid
            let range = robust_range(points.iter().flat_map(|p| p.y.iter().copied()));
            let title = format!("{name}: pure {which} ({pattern} pattern) from the {what} perturbations, step {}{}", frame.step, range.map(|(_, _, off)| format!(" ({off} {} off scale)", if off == 1 { "point" } else { "points" })).unwrap_or_default());
            let fstem = format!("fig{fig_no}_{stem}_{which}");
            let mut fig = pattern_figure(&title, &y_label, &axes, &x, points, fits);
            if let Some((lo, hi, off)) = range {
                fig = fig.y_range(lo, hi);
                let total = points.iter().flat_map(|p| p.y.iter()).filter(|y| y.is_finite()).count();
                let why = if which == "P" { ", divided by p² of nearly resting disks" } else { "" };
                off_scale.push(format!("Fig. {fig_no} {which}: {off} of {total} points beyond {lo:.3}..{hi:.3}{why}"));
            }
            save_figure(&fig, out, &fstem)?;
            figs.push(fstem);
        }
    }
    columns.write(&out.join(format!("{stem}.csv")))?;
    Ok((
        Produced {
            title: if family.single().is_some() { format!("Longitudinal-momentum mode {name} (Figs. 11, 12)") } else { format!("Longitudinal-momentum mode {name} of {} (Figs. 11, 12)", family.name(ModeKind::LP)) },
            caption: format!(
                "Pure L and P vectors{} reconstructed at step {} inside the {}-dimensional {} of {} (i = {}..{}) by least squares against the Table III patterns, against {}: Fig. 11 from the position perturbations (sine patterns: δq_{a} of L, with δq_{t}, which vanishes for an ideal L pattern, as a check, here rms δq_{t} / rms δq_{a} = {}, and (δq·p)/p² of P, the momenta divided out), Fig. 12 likewise from the momentum perturbations (cosine patterns). GS values in blue, CLV values in vermillion (as in Fig. 10), each with its sine fit in its colour; the checks of L, δq_{t} and δp_{t}, in open markers. Overlaps and sine fits are in modes_lp.csv.{}",
                if family.single().is_some() { String::new() } else { format!(" of {name}") },
                frame.step,
                if step.len == 4 { "four".to_string() } else { step.len.to_string() },
                if frame.g.is_some() { "GS and covariant subspaces" } else { "covariant subspace" },
                if family.single().is_some() { name.clone() } else { format!("the {} step", family.name(ModeKind::LP)) },
                step.start + 1,
                step.start + step.len,
                axes.x_label,
                across.join(", "),
                if off_scale.is_empty() {
                    String::new()
                } else {
                    format!(" Off scale, so that the sinusoid is seen: {} (every value is in {stem}.csv, and the fits use them all).", off_scale.join("; "))
                }
            ),
            figures: figs,
            tables: vec![format!("{stem}.csv"), "modes_lp.csv".into()],
        },
        rows,
    ))
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;

    const N: usize = 30;
    const LX: f64 = 14.0;
    const LY: f64 = 3.0;

    fn single(n_x: i32, n_y: i32) -> Family {
        let w = Wave { n_x, n_y };
        Family { waves: vec![w], k: w.norm(LX, LY) }
    }

    /// The shared [`super::super::testing::mode_vectors`] in this box.
    fn mode_vectors(kind: ModeKind, n_x: i32, phase: &[f64], c: f64, which: &[usize]) -> Vec<Vec<f64>> {
        super::super::testing::mode_vectors(LX, LY, kind, n_x, phase, c, which)
    }

    fn run(ctx: &Context, frames: &[Frame], name: &str) -> (OutDir, Vec<Produced>) {
        let out = out_dir(name);
        let mut a = new(ctx).expect("disks");
        for f in frames {
            a.consume(f).unwrap();
        }
        let produced = a.finish(&out, frames.len() as u64).unwrap();
        (out, produced)
    }

    #[test]
    fn planted_transverse_pair_is_t2_with_the_right_amplitude() {
        let d = 4 * N;
        let mut rng = Rng::new(1);
        let ctx = context("disks", N, d, LX, LY, Some(spectrum(N, 2)), true);
        let k = std::f64::consts::TAU * 2.0 / LX;
        let (amp, phi) = (0.8, [0.3, 1.9]);
        let mut frames = Vec::new();
        let mut expected = Vec::new(); // per frame: amplitude of dq_y of the two vectors
        for f in 0..3 {
            let phase = phase(N, LX, LY, &mut rng);
            let mut g = random_set(d, &mut rng);
            let mut amps = Vec::new();
            let cols: Vec<Vec<f64>> = phi
                .iter()
                .map(|&ph| {
                    let mut dq = vec![0.0; 2 * N];
                    for i in 0..N {
                        dq[2 * i + 1] = amp * (k * phase[2 * i] + ph).cos();
                    }
                    let (v, scale) = tangent(&dq, 0.6);
                    amps.push(amp * scale);
                    v
                })
                .collect();
            plant(&mut g, d, 2 * N - 5, &cols);
            expected.push(amps);
            let v = g.clone();
            frames.push(frame(100 - f, phase, v, Some(g)));
        }
        let (out, produced) = run(&ctx, &frames, "t2");
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("modes.json")).unwrap()).unwrap();
        let modes = json["modes"].as_array().unwrap();
        assert_eq!(modes.len(), 2, "{json}"); // the pair and its conjugate
        let t = modes.iter().find(|m| m["side"] == "+").unwrap();
        assert_eq!((t["first"].as_u64(), t["last"].as_u64()), (Some(2 * N as u64 - 4), Some(2 * N as u64 - 3)));
        assert_eq!((t["kind"].as_str(), t["n_x"].as_u64(), t["consistent"].as_bool()), (Some("T"), Some(2), Some(true)));
        assert!(t["fraction_gs"].as_f64().unwrap() > 0.999 && t["agreement"].as_f64() == Some(1.0), "{t}");
        // averaged fits of both vectors: the planted amplitude, zero residual
        let fits = read_csv(&out.join("modes_fits.csv"));
        for (j, want) in (0..2).map(|j| (j, expected.iter().map(|a| a[j]).sum::<f64>() / 3.0)) {
            let i = (2 * N - 4 + j).to_string();
            let row = fits.iter().find(|r| r["i"] == i && r["source"] == "GS" && r["scope"] == "mean").unwrap();
            let got: f64 = row["amp_dqt"].parse().unwrap();
            assert!((got - want).abs() < 1e-12, "vector {i}: amplitude {got}, planted {want}");
            assert!(row["resid_dqt"].parse::<f64>().unwrap() < 1e-12);
            assert!((row["amp_dpt"].parse::<f64>().unwrap() - 0.6 * want).abs() < 1e-12);
        }
        // the Fig. 10 panels of the plotted frame
        let stem = format!("fig10_T2_i{}", 2 * N - 3);
        for f in ["dqy", "dpy"] {
            assert!(is_png(&out.join(format!("{stem}_{f}.png"))));
            // GS and covariant vectors, each with its fit, in the GS and CLV colours (blue,
            // vermillion) and no other, as in Figs. 11 and 12
            let svg = std::fs::read_to_string(out.join(format!("{stem}_{f}.svg"))).unwrap();
            let data: Vec<&str> = svg.lines().filter(|l| l.starts_with("<g ") || l.starts_with("<path")).collect();
            let count = |c: &str| data.iter().filter(|l| l.contains(c)).count();
            assert!(count("#0072b2") == 3 && count("#d55e00") == 3 && data.len() == 6, "{data:?}");
        }
        let plotted = fits.iter().find(|r| r["scope"] == "step 100" && r["source"] == "CLV").unwrap();
        assert!((plotted["amp_dqt"].parse::<f64>().unwrap() - expected[0][1]).abs() < 1e-12);
        assert!(produced.iter().any(|p| p.figures.contains(&format!("{stem}_dqy"))));
        assert!(produced[0].caption.contains("T(2,0)"), "{}", produced[0].caption);
        // the dispersion point: the positive pair's exponent at k = 2 pi 2 / L_x
        let dispersion = read_csv(&out.join("modes_dispersion.csv"));
        assert_eq!(dispersion.len(), 1, "only the positive side: {dispersion:?}");
        let lambda = ctx.gs.as_ref().unwrap().exponents[2 * N - 5..2 * N - 3].iter().sum::<f64>() / 2.0;
        let row = &dispersion[0];
        assert_eq!((row["kind"].as_str(), row["n_x"].as_str()), ("T", "2"));
        assert!((row["k"].parse::<f64>().unwrap() - k).abs() < 1e-15 && (row["lambda"].parse::<f64>().unwrap() - lambda).abs() < 1e-15, "{row:?}");
        assert!(produced.iter().any(|p| p.figures == ["modes_dispersion"] && p.caption.contains(&format!("c = {:.4}", lambda / k))));
    }

    /// A few huge values (disks nearly at rest, divided by p^2) do not set the scale; a clean
    /// sinusoid keeps its own.
    #[test]
    fn outliers_leave_the_pattern_on_scale() {
        let sine: Vec<f64> = (0..100).map(|i| (i as f64 * 0.1).sin()).collect();
        assert_eq!(robust_range(sine.iter().copied()), None);
        let spiked: Vec<f64> = sine.iter().copied().chain([40.0, -25.0]).collect();
        let (lo, hi, off) = robust_range(spiked.into_iter()).unwrap();
        assert!(lo < -0.99 && lo > -3.0 && hi > 0.99 && hi < 3.0, "{lo} {hi}");
        assert_eq!(off, 2, "the two spikes are counted off scale");
    }

    #[test]
    fn line_through_the_origin() {
        let (c, se) = fit_through_origin(&[1.0, 2.0, 3.0], &[0.5, 1.0, 1.5]);
        assert!((c - 0.5).abs() < 1e-15 && se.abs() < 1e-15);
        // y = x + (1, -1, 1) e: c = 1 + (1 - 2 + 3) e / 14, residuals give the error
        let e = 0.01;
        let (c, se) = fit_through_origin(&[1.0, 2.0, 3.0], &[1.0 + e, 2.0 - e, 3.0 + e]);
        assert!((c - (1.0 + 2.0 * e / 14.0)).abs() < 1e-15);
        let resid: f64 = [(1.0, 1.0 + e), (2.0, 2.0 - e), (3.0, 3.0 + e)].iter().map(|(x, y)| (y - c * x).powi(2)).sum();
        assert!((se - (resid / 2.0 / 14.0).sqrt()).abs() < 1e-15);
        assert!(fit_through_origin(&[2.0], &[1.0]).1.is_nan(), "one point: no error");
    }

    #[test]
    fn planted_lp_quadruplet_is_reconstructed() {
        let d = 4 * N;
        let mut rng = Rng::new(2);
        let ctx = context("disks", N, d, LX, LY, Some(spectrum(N, 4)), false);
        let phase = phase(N, LX, LY, &mut rng);
        let pat = km::mode_patterns(ModeKind::LP, &single(1, 0), &phase, LX, LY);
        let h = 2 * N;
        // four random mixtures of the pure L, P patterns (dp = 0.7 dq)
        let pure: Vec<Vec<f64>> = (0..4).map(|j| tangent(&pat[j * h..(j + 1) * h], 0.7).0).collect();
        let cols: Vec<Vec<f64>> = (0..4)
            .map(|_| {
                let c: Vec<f64> = (0..4).map(|_| rng.normal()).collect();
                unit((0..d).map(|r| (0..4).map(|j| c[j] * pure[j][r]).sum()).collect())
            })
            .collect();
        let mut v = random_set(d, &mut rng);
        plant(&mut v, d, 2 * N - 7, &cols);
        let (out, produced) = run(&ctx, &[frame(7, phase, v, None)], "lp");
        let rows = read_csv(&out.join("modes.csv"));
        let lp = rows.iter().find(|r| r["side"] == "+").unwrap();
        assert_eq!((lp["kind"].as_str(), lp["n_x"].as_str(), lp["degeneracy"].as_str()), ("LP", "1", "4"));
        assert_eq!(lp["fraction_gs"], "NaN"); // classified with CLVs: no GS vectors
        assert!(lp["fraction_clv"].parse::<f64>().unwrap() > 0.999);
        let rec = read_csv(&out.join("modes_lp.csv"));
        assert_eq!(rec.len(), 4); // CLV only: L and P for Figs. 11 and 12
        assert!(rec.iter().all(|r| r["overlap"].parse::<f64>().unwrap() > 0.999999), "{rec:?}");
        for fig in ["fig11", "fig12"] {
            for m in ["L", "P"] {
                assert!(is_png(&out.join(format!("{fig}_LP1_i{}_{m}.png", 2 * N - 6))));
                // Values and fits in the CLV colour of Fig. 10 (vermillion) and no other; the
                // check of L (its component across k) in open markers.
                let svg = std::fs::read_to_string(out.join(format!("{fig}_LP1_i{}_{m}.svg", 2 * N - 6))).unwrap();
                let data: Vec<&str> = svg.lines().filter(|l| l.starts_with("<g ") || l.starts_with("<path")).collect();
                assert!(data.iter().all(|l| l.contains("#d55e00")), "{fig} {m}: {data:?}");
                assert_eq!(data.iter().any(|l| l.starts_with("<g fill=\"none\" stroke=\"#d55e00\"")), m == "L", "{fig} {m}: {data:?}");
            }
        }
        assert!(produced.iter().any(|p| p.title.contains("LP(1,0)")));
        assert_eq!(lp["name"], "LP(1,0)");
        assert!(std::fs::read_to_string(out.join("modes.csv")).unwrap().contains(",\"LP(1,0)\","));
    }

    /// Finite-N LP exponents are not exactly degenerate: only the middle pair of the planted
    /// quadruplet passes the statistical test; the pair classifies as LP and is widened to the
    /// planted block (transversality.rs tests that its analysis takes the widened block).
    #[test]
    fn split_lp_quadruplet_is_widened() {
        let d = 4 * N;
        let Planted { ctx, spectrum: spec, frame: f, at, .. } = split_lp_quadruplet();
        let detected = km::mode_steps(&spec.exponents, &spec.stderr, STEP_TOL, step_window(d, &Candidates::new(LX, LY, MAX_N)), &[4, 2]);
        assert_eq!(detected.iter().map(|s| (s.start, s.len)).collect::<Vec<_>>(), [(at + 1, 2), (d - at - 3, 2)]);
        let (out, _) = run(&ctx, std::slice::from_ref(&f), "widened");
        let rows = read_csv(&out.join("modes.csv"));
        let lp = rows.iter().find(|r| r["side"] == "+").unwrap();
        assert_eq!((lp["first"].as_str(), lp["last"].as_str()), ((at + 1).to_string().as_str(), (at + 4).to_string().as_str()));
        assert_eq!((lp["detection"].as_str(), lp["name"].as_str(), lp["consistent"].as_str()), ("widened", "LP(2,0)", "true"));
        assert!(lp["fraction_gs"].parse::<f64>().unwrap() > 0.999);
        assert!((lp["lambda"].parse::<f64>().unwrap() - 0.1).abs() < 1e-12);
        // the conjugate pair is widened to the mirror block (conjugate pairing)
        let minus = rows.iter().find(|r| r["side"] == "-").unwrap();
        assert_eq!((minus["first"].as_str(), minus["last"].as_str(), minus["detection"].as_str()), ((d - at - 3).to_string().as_str(), (d - at).to_string().as_str(), "widened"));
    }

    /// A quadruplet split by many standard errors but set apart from its neighbours (as in
    /// the paper's run) is found whole, and the table says how.
    #[test]
    fn separated_lp_quadruplet_is_found_whole() {
        let d = 4 * N;
        let mut rng = Rng::new(5);
        let mut spec = spectrum(N, 4);
        let at = 2 * N - 7;
        plant_block(&mut spec, at, &[0.1003, 0.1001, 0.0999, 0.0997]);
        spec.stderr.iter_mut().for_each(|e| *e = 1e-5);
        let ctx = context("disks", N, d, LX, LY, Some(spec), true);
        let phase = phase(N, LX, LY, &mut rng);
        let cols = mode_vectors(ModeKind::LP, 1, &phase, 0.5, &[0, 1, 2, 3]);
        let mut g = random_set(d, &mut rng);
        plant(&mut g, d, at, &cols);
        let (out, produced) = run(&ctx, &[frame(3, phase, g.clone(), Some(g))], "separated");
        let rows = read_csv(&out.join("modes.csv"));
        let lp = rows.iter().find(|r| r["side"] == "+").unwrap();
        assert_eq!((lp["first"].as_str(), lp["last"].as_str()), ((at + 1).to_string().as_str(), (at + 4).to_string().as_str()));
        assert_eq!((lp["detection"].as_str(), lp["name"].as_str(), lp["consistent"].as_str()), ("separated", "LP(1,0)", "true"));
        assert!(produced[0].caption.contains("LP(1,0) at i = 54..57 (4-fold, separated, λ = 0.1000 with its exponents spread over 0.0006,"), "{}", produced[0].caption);
        assert!((lp["spread"].parse::<f64>().unwrap() - 0.0006).abs() < 1e-12, "{lp:?}");
        let dispersion = produced.iter().find(|p| p.title.starts_with("Dispersion")).unwrap();
        assert!(dispersion.caption.contains("the exponents of LP(1,0) (0.0006) are not equal within those errors"), "{}", dispersion.caption);
    }

    /// In a square box the modes of (1,0) and (0,1) are degenerate by symmetry: a T step of
    /// 4 exponents and an LP step of 8, found, named and tabulated as such (their mixtures
    /// are random inside the steps, as in a real run), with the pattern figures of each wave
    /// vector, its pure vectors reconstructed inside the whole step.
    #[test]
    fn square_box_modes_of_two_wave_vectors() {
        const L: f64 = 8.0;
        let d = 4 * N;
        let mut rng = Rng::new(6);
        let mut spec = spectrum(N, 4);
        let lp_at = 2 * N - 3 - 12; // 0-based: LP 45..=52, T 53..=56
        for j in 0..8 {
            spec.exponents[lp_at + j] = 0.2;
            spec.exponents[d - 1 - lp_at - j] = -0.2;
        }
        let ctx = context("disks", N, d, L, L, Some(spec), true);
        let cands = candidates(&ctx);
        assert_eq!(step_window(d, &cands), 12);
        let both = cands.families.iter().find(|f| f.waves.len() == 2 && f.waves[0] == Wave { n_x: 1, n_y: 0 }).expect("(1,0)+(0,1)");
        assert_eq!((both.name(ModeKind::T), both.dim(ModeKind::T), both.dim(ModeKind::LP)), ("T(1,0)+T(0,1)".to_string(), 4, 8));
        let phase = phase(N, L, L, &mut rng);
        let mix = |kind: ModeKind, c: f64, rng: &mut Rng| -> Vec<Vec<f64>> {
            let pat = km::mode_patterns(kind, both, &phase, L, L);
            let m = pat.len() / (2 * N);
            let pure: Vec<Vec<f64>> = (0..m).map(|j| tangent(&pat[j * 2 * N..(j + 1) * 2 * N], c).0).collect();
            (0..m).map(|_| {
                let w: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
                unit((0..d).map(|r| (0..m).map(|j| w[j] * pure[j][r]).sum()).collect())
            }).collect()
        };
        let mut g = random_set(d, &mut rng);
        let lp = mix(ModeKind::LP, 0.5, &mut rng);
        let t = mix(ModeKind::T, 0.7, &mut rng);
        plant(&mut g, d, lp_at, &lp);
        plant(&mut g, d, lp_at + 8, &t);
        let (out, produced) = run(&ctx, &[frame(3, phase, g.clone(), Some(g))], "square");
        let rows = read_csv(&out.join("modes.csv"));
        let plus: Vec<_> = rows.iter().filter(|r| r["side"] == "+").collect();
        let got: Vec<(&str, &str, &str, &str, &str)> = plus.iter().map(|r| (r["first"].as_str(), r["last"].as_str(), r["degeneracy"].as_str(), r["name"].as_str(), r["consistent"].as_str())).collect();
        assert_eq!(got, [("46", "53", "8", "LP(1,0)+LP(0,1)", "true"), ("54", "57", "4", "T(1,0)+T(0,1)", "true")], "{rows:?}");
        assert!(plus.iter().all(|r| r["fraction_gs"].parse::<f64>().unwrap() > 0.999));
        // Fig. 10 of each wave vector: the reconstructed pure T vector is the pattern (dq
        // across k a cosine of q along k, residual 0; dq along k 0) in both sources, and
        // its dp is 0.7 of its dq, as planted.
        for (stem, across, along) in [("T1", "y", "x"), ("T0_1", "x", "y")] {
            let csv = out.join(format!("fig10_{stem}_i57.csv"));
            let table = read_table(&csv);
            let s = column(&table, &format!("q_{along}"));
            for src in ["gs", "clv"] {
                let dq = column(&table, &format!("dq{across}_{src}"));
                let dp = column(&table, &format!("dp{across}_{src}"));
                let fit = km::fit_sine(&s, &dq, std::f64::consts::TAU / L);
                assert!(fit.amplitude > 0.1 && fit.residual < 1e-12, "{stem} {src}: {fit:?}");
                assert!(column(&table, &format!("dq{along}_{src}")).iter().all(|x| x.abs() < 1e-12), "{stem} {src}");
                assert!(dq.iter().zip(&dp).all(|(q, p)| (0.7 * q - p).abs() < 1e-12), "{stem} {src}");
            }
            for comp in ["dq", "dp"] {
                assert!(is_png(&out.join(format!("fig10_{stem}_i57_{comp}{across}.png"))));
            }
        }
        let t_entries: Vec<&Produced> = produced.iter().filter(|p| p.title.contains("(Fig. 10)")).collect();
        assert_eq!(t_entries.iter().map(|p| p.title.as_str()).collect::<Vec<_>>(), ["Transverse mode T(1,0) of T(1,0)+T(0,1) (Fig. 10)", "Transverse mode T(0,1) of T(1,0)+T(0,1) (Fig. 10)"]);
        assert!(t_entries[0].caption.contains("4-dimensional GS (blue) and covariant (vermillion) subspaces of the T(1,0)+T(0,1) step (i = 54..57)") && t_entries[0].caption.contains("GS 1.000, CLV 1.000"), "{}", t_entries[0].caption);
        // The averaged fits are those of a pair's own vectors: none for a step of two waves.
        assert!(!out.join("modes_fits.csv").exists());
        // Figs. 11 and 12 of each wave vector: pure L and P in the span of the 8-fold step.
        let rec = read_csv(&out.join("modes_lp.csv"));
        assert_eq!(rec.len(), 16, "2 waves x GS, CLV x Figs. 11, 12 x L, P: {rec:?}");
        assert!(rec.iter().all(|r| r["first"] == "46" && r["last"] == "53" && r["overlap"].parse::<f64>().unwrap() > 0.999999), "{rec:?}");
        for stem in ["LP1", "LP0_1"] {
            for fig in ["fig11", "fig12"] {
                for m in ["L", "P"] {
                    assert!(is_png(&out.join(format!("{fig}_{stem}_i46_{m}.png"))), "{fig}_{stem}_i46_{m}");
                }
            }
        }
        let lp_entry = produced.iter().find(|p| p.title == "Longitudinal-momentum mode LP(1,0) of LP(1,0)+LP(0,1) (Figs. 11, 12)").expect("Figs. 11, 12 of (1,0)");
        assert!(lp_entry.caption.starts_with("Pure L and P vectors of LP(1,0) reconstructed at step 3 inside the 8-dimensional GS and covariant subspaces of the LP(1,0)+LP(0,1) step (i = 46..53)"), "{}", lp_entry.caption);
        assert!(produced[0].caption.contains("together") && produced[0].caption.contains("(1,0)+(0,1)"), "{}", produced[0].caption);
        let dispersion = read_csv(&out.join("modes_dispersion.csv"));
        assert_eq!(dispersion.len(), 2);
        assert!(dispersion.iter().all(|r| (r["k"].parse::<f64>().unwrap() - std::f64::consts::TAU / L).abs() < 1e-15));
    }

    /// A degenerate pair whose vectors are no sinusoid (random) is found as a step but not
    /// classified: its best candidate explains about the chance fraction 2/2N, below
    /// MIN_FRACTION; the table names that candidate and draws nothing for the step.
    #[test]
    fn a_step_of_random_vectors_is_unclassified() {
        let d = 4 * N;
        let mut rng = Rng::new(7);
        let ctx = context("disks", N, d, LX, LY, Some(spectrum(N, 2)), true);
        let g = random_set(d, &mut rng);
        let (out, produced) = run(&ctx, &[frame(3, phase(N, LX, LY, &mut rng), g.clone(), Some(g))], "random-step");
        let rows = read_csv(&out.join("modes.csv"));
        assert_eq!(rows.len(), 2, "{rows:?}");
        for r in &rows {
            assert_eq!((r["name"].as_str(), r["kind"].as_str(), r["consistent"].as_str(), r["n_x"].as_str()), ("unclassified", "-", "false", ""), "{r:?}");
            assert!(r["best"] != "-" && r["fraction_gs"].parse::<f64>().unwrap() < MIN_FRACTION, "{r:?}");
        }
        assert!(produced[0].caption.contains("of the best candidate") && !out.join("modes_dispersion.csv").exists(), "{}", produced[0].caption);
    }

    /// A small system's LP mode (N = 40 in the paper's box): its four exponents spread like
    /// the smooth spectrum's, so neither exponent test sees a step, but the block stands
    /// apart between gaps several times wider, next to the T pair. Its vectors find it, with
    /// its mirror (transversality.rs and overlaps.rs test that their F^(J) and Fig. 14 take
    /// it); random vectors in the same place find nothing.
    #[test]
    fn an_lp_block_split_like_the_smooth_spectrum_is_found_by_its_vectors() {
        let d = 4 * N;
        let Planted { ctx, spectrum: spec, frame: f, random: plain, at } = lp_block_found_by_its_vectors();
        let detected = km::mode_steps(&spec.exponents, &spec.stderr, STEP_TOL, step_window(d, &Candidates::new(LX, LY, MAX_N)), &[4, 2]);
        assert_eq!(detected.iter().map(|s| (s.start, s.len)).collect::<Vec<_>>(), [(at + 4, 2), (d - at - 6, 2)], "the exponents alone see the T pair only");
        let (out, _) = run(&ctx, std::slice::from_ref(&f), "lp-by-vectors");
        let rows = read_csv(&out.join("modes.csv"));
        let found: Vec<(&str, &str, &str, &str)> = rows.iter().map(|r| (r["first"].as_str(), r["last"].as_str(), r["detection"].as_str(), r["name"].as_str())).collect();
        let (a, b) = ((at + 1).to_string(), (at + 4).to_string());
        let (ma, mb) = ((d - at - 3).to_string(), (d - at).to_string());
        assert!(found.contains(&(a.as_str(), b.as_str(), "vectors", "LP(1,0)")), "{found:?}");
        assert!(found.contains(&(ma.as_str(), mb.as_str(), "vectors", "LP(1,0)")), "{found:?}");
        assert_eq!(found.len(), 4, "{found:?}");
        // The same exponents with random vectors: no block is added.
        let (out, _) = run(&ctx, std::slice::from_ref(&plain), "lp-by-vectors-random");
        let rows = read_csv(&out.join("modes.csv"));
        assert!(rows.iter().all(|r| r["detection"] != "vectors") && rows.len() == 2, "{rows:?}");
        // Two frames that resolve the steps differently: the table has the first frame's
        // steps and says how many frames find each, and which steps only the others find.
        let (out, produced) = run(&ctx, &[f.clone(), plain.clone()], "lp-by-vectors-first");
        let resolved: Vec<(String, f64)> = read_csv(&out.join("modes.csv")).iter().map(|r| (r["first"].clone(), r["resolved"].parse().unwrap())).collect();
        assert!(resolved.contains(&(a.clone(), 0.5)) && resolved.contains(&(ma.clone(), 0.5)) && resolved.contains(&((at + 5).to_string(), 1.0)), "{resolved:?}");
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("modes.json")).unwrap()).unwrap();
        assert!(json["resolved_alike"] == 1 && json["other_steps"].as_array().is_some_and(|o| o.is_empty()), "{json}");
        assert!(produced[0].caption.contains("1 of 2 frames give the same steps (no frame finds another step"), "{}", produced[0].caption);
        let (out, produced) = run(&ctx, &[plain, f], "lp-by-vectors-second");
        assert_eq!(read_csv(&out.join("modes.csv")).len(), 2);
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("modes.json")).unwrap()).unwrap();
        let others: Vec<(u64, u64, u64)> = json["other_steps"].as_array().unwrap().iter().map(|o| (o["first"].as_u64().unwrap(), o["last"].as_u64().unwrap(), o["frames"].as_u64().unwrap())).collect();
        assert_eq!(others, [(at as u64 + 1, at as u64 + 4, 1), ((d - at - 3) as u64, (d - at) as u64, 1)], "{json}");
        assert!(produced[0].caption.contains(&format!("other steps found by some frames: i = {a}..{b} in 1, i = {ma}..{mb} in 1")), "{}", produced[0].caption);
    }

    /// Two modes whose exponents lie closer together than to their neighbours (N = 120 in
    /// the paper's box: T(3,0) and LP(2,0)) stand apart only as a block of six: split where
    /// each part is its mode, both are found by their vectors, with their mirrors; random
    /// vectors in the same place find neither.
    #[test]
    fn two_modes_that_stand_apart_only_together_are_found_by_their_vectors() {
        let d = 4 * N;
        let mut rng = Rng::new(11);
        let mut spec = spectrum(N, 2);
        let at = 2 * N - 11; // 0-based first index of the block of six, just above the T pair
        plant_block(&mut spec, at, &[0.70, 0.68, 0.66, 0.64, 0.62, 0.60]);
        let detected = km::mode_steps(&spec.exponents, &spec.stderr, STEP_TOL, step_window(d, &Candidates::new(LX, LY, MAX_N)), &[4, 2]);
        assert_eq!(detected.iter().map(|s| (s.start, s.len)).collect::<Vec<_>>(), [(at + 6, 2), (d - at - 8, 2)], "the exponents alone see the T pair only");
        let ctx = context("disks", N, d, LX, LY, Some(spec), true);
        let phase = phase(N, LX, LY, &mut rng);
        let t2 = mode_vectors(ModeKind::T, 2, &phase, 0.5, &[0, 1]);
        let lp1 = mode_vectors(ModeKind::LP, 1, &phase, 0.5, &[0, 1, 2, 3]);
        let random = random_set(d, &mut rng);
        let mut g = random.clone();
        plant(&mut g, d, at, &t2);
        plant(&mut g, d, at + 2, &lp1);
        plant(&mut g, d, d - at - 6, &lp1);
        plant(&mut g, d, d - at - 2, &t2);
        let (out, _) = run(&ctx, &[frame(3, phase.clone(), g.clone(), Some(g))], "pair-by-vectors");
        let rows = read_csv(&out.join("modes.csv"));
        let found: Vec<(String, String, String, String)> = rows.iter().map(|r| (r["first"].clone(), r["last"].clone(), r["detection"].clone(), r["name"].clone())).collect();
        let row = |first: usize, last: usize, name: &str| (first.to_string(), last.to_string(), "vectors".to_string(), name.to_string());
        for want in [row(at + 1, at + 2, "T(2,0)"), row(at + 3, at + 6, "LP(1,0)"), row(d - at - 5, d - at - 2, "LP(1,0)"), row(d - at - 1, d - at, "T(2,0)")] {
            assert!(found.contains(&want), "{want:?} not in {found:?}");
        }
        assert_eq!(found.len(), 6, "{found:?}");
        let f = frame(3, phase, random.clone(), Some(random));
        let (out, _) = run(&ctx, std::slice::from_ref(&f), "pair-by-vectors-random");
        let rows = read_csv(&out.join("modes.csv"));
        assert!(rows.iter().all(|r| r["detection"] != "vectors") && rows.len() == 2, "{rows:?}");
    }

    /// Two exponents equal within their errors in the smooth part, apart from the mode region
    /// at the null space, are a step only if their vectors are a mode: chance equality in a
    /// short run is no step (kept with planted T(2,0) vectors, dropped with random ones).
    #[test]
    fn a_chance_pair_apart_from_the_mode_region_needs_mode_vectors() {
        let d = 4 * N;
        let mut rng = Rng::new(11);
        let mut spec = spectrum(N, 2);
        let at = 2 * N - 11; // 0-based, four indices above the T pair at 2N-5..2N-4, in the search window
        let mean = (spec.exponents[at] + spec.exponents[at + 1]) / 2.0;
        for i in [at, at + 1] {
            spec.exponents[i] = mean;
            spec.exponents[d - 1 - i] = -mean;
        }
        let detected = km::mode_steps(&spec.exponents, &spec.stderr, STEP_TOL, step_window(d, &Candidates::new(LX, LY, MAX_N)), &[4, 2]);
        assert!(detected.iter().any(|s| (s.start, s.len) == (at, 2)), "the exponents alone take the pair: {detected:?}");
        let ctx = context("disks", N, d, LX, LY, Some(spec), true);
        let phase = phase(N, LX, LY, &mut rng);
        let cols = mode_vectors(ModeKind::T, 2, &phase, 0.5, &[0, 1]);
        let random = random_set(d, &mut rng);
        let mut g = random.clone();
        plant(&mut g, d, at, &cols);
        // Half of an LP quadruplet that the smooth spectrum around it does not let widen: no
        // step either (a chance pair classified "LP" in the first frame, N = 8).
        let mut half_lp = random.clone();
        plant(&mut half_lp, d, at, &mode_vectors(ModeKind::LP, 1, &phase, 0.5, &[0, 2]));
        for (set, name, kept) in [(g, "chance-pair-mode", true), (random, "chance-pair-random", false), (half_lp, "chance-pair-half-lp", false)] {
            let (out, _) = run(&ctx, &[frame(3, phase.clone(), set.clone(), Some(set))], name);
            let rows = read_csv(&out.join("modes.csv"));
            let pair = rows.iter().find(|r| r["first"] == (at + 1).to_string());
            assert_eq!(pair.is_some(), kept, "{name}: {rows:?}");
            if let Some(r) = pair {
                assert_eq!((r["name"].as_str(), r["detection"].as_str()), ("T(2,0)", "degenerate"), "{r:?}");
            }
            assert!(rows.iter().any(|r| r["first"] == (2 * N - 4).to_string()), "the pair at the null space stays, unclassified or not: {rows:?}");
        }
    }

    /// A pair of LP-like vectors next to the smooth part of the spectrum is not widened: the
    /// four-fold blocks around it do not stand apart from their neighbours.
    #[test]
    fn a_pair_in_the_smooth_spectrum_is_not_widened() {
        let d = 4 * N;
        let mut rng = Rng::new(8);
        let ctx = context("disks", N, d, LX, LY, Some(spectrum(N, 2)), true);
        let phase = phase(N, LX, LY, &mut rng);
        let cols = mode_vectors(ModeKind::LP, 1, &phase, 0.5, &[0, 2]);
        let mut g = random_set(d, &mut rng);
        plant(&mut g, d, 2 * N - 5, &cols);
        let (out, _) = run(&ctx, &[frame(3, phase, g.clone(), Some(g))], "smooth-pair");
        let rows = read_csv(&out.join("modes.csv"));
        let plus = rows.iter().find(|r| r["side"] == "+").unwrap();
        assert_eq!((plus["first"].as_str(), plus["last"].as_str(), plus["detection"].as_str()), ((2 * N - 4).to_string().as_str(), (2 * N - 3).to_string().as_str(), "degenerate"), "{rows:?}");
    }

    /// The excess over chance: 0 for a random vector's expected fraction, 1 for a pure mode;
    /// a family spanning half the positions (8 of 2N = 16) at 0.53 is barely above chance.
    #[test]
    fn excess_over_chance() {
        assert_eq!((excess(0.05, 4, 160), excess(1.0, 4, 160)), (0.0, 1.0));
        assert!(excess(0.53, 8, 32) < 0.1 && excess(0.81, 2, 160) > 0.8);
        assert!(excess(0.9, 16, 32).is_nan());
    }

    #[test]
    fn no_modes_gives_an_empty_table_that_says_so() {
        let d = 4 * N;
        let mut rng = Rng::new(3);
        let f = frame(0, phase(N, LX, LY, &mut rng), random_set(d, &mut rng), None);
        for (gs, name, says) in [(Some(spectrum(N, 1)), "none", "No degenerate steps of 2 or 4 exponents"), (None, "nogs", "no forward GS spectrum")] {
            let ctx = context("disks", N, d, LX, LY, gs, false);
            let (out, produced) = run(&ctx, std::slice::from_ref(&f), name);
            assert_eq!(std::fs::read_to_string(out.join("modes.csv")).unwrap().lines().count(), 1);
            let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("modes.json")).unwrap()).unwrap();
            assert_eq!(json["modes"].as_array().map(|a| a.len()), Some(0));
            assert_eq!(produced.len(), 1);
            assert!(produced[0].caption.contains(says), "{}", produced[0].caption);
        }
        assert!(new(&context("henon", 0, 2, 0.0, 0.0, None, false)).is_none());
    }
}
