//! Which steps of the spectrum are Lyapunov modes, and what they are: shared by the mode
//! table (paper Sec. 5.5, [`super::modes`]) and every analysis that names steps by their mode
//! (the transversality of the mode subspaces, Figs. 15-17), so that both find the same steps
//! and call them the same. The projections themselves are [`km`]'s; this adds the rules
//! that turn them into decisions (which exponents form a step, when a step counts as
//! classified, when a short step is half of an LP mode).

use super::kernels::modes::{self as km, Candidates, Family, ModeKind, ModeMatch, Part, Step};
use super::Context;
use crate::stage::frame::Frame;

/// Candidate wave vectors have |k| up to 2 pi MAX_N / max(L_x, L_y): (n_x, 0) up to
/// n_x = 4 in the paper's box.
pub const MAX_N: usize = 4;
/// The least share of a step's vectors beyond chance ([`excess`]) in its majority
/// candidate's span that counts as a classification. Modes have 0.56-0.97 (the paper's run,
/// ours of N = 40 and 100, a square of N = 100); a step that is no mode 0.05 (our N = 40
/// system in the paper's box turned by 90 degrees, before modes along y were candidates:
/// "LP(3,0)" at a fraction of 0.10 against the chance 4/80 won 56 % of the frames; an
/// 8-dimensional family of N = 8 disks: 0.53 against the chance 0.5).
pub const MIN_FRACTION: f64 = 0.3;
/// Neighbouring exponents within this many combined standard errors form a step.
pub const STEP_TOL: f64 = 3.0;
/// How many indices on either side of the null space are searched for mode steps: the
/// paper's N = 198 system has 18 mode indices per side (T and LP for n_x = 1, 2, 3). At
/// least the T and LP steps of the smallest |k| fit (12 in a square box).
pub fn step_window(d: usize, candidates: &Candidates) -> usize {
    let k_min = candidates.families.first().map_or(0.0, |f| f.k);
    let first = candidates.families.iter().filter(|f| f.k == k_min).map(|f| f.dim(ModeKind::T) + f.dim(ModeKind::LP)).max().unwrap_or(0);
    (d / 16).max(8).max(first)
}

/// The candidate modes of the run's box.
pub fn candidates(ctx: &Context) -> Candidates {
    Candidates::new(ctx.lx, ctx.ly, MAX_N)
}

/// The steps of the forward GS spectrum next to the null space (both sides) that the
/// candidates' modes could make, or why there are none to look for.
pub fn detect_steps(ctx: &Context) -> std::result::Result<Vec<Step>, String> {
    if ctx.k != ctx.d || ctx.d < 8 {
        return Err(format!("mode detection needs all D = {} vectors and exponents; the frames carry {}", ctx.d, ctx.k));
    }
    let Some(gs) = &ctx.gs else {
        return Err("the frame stream carries no forward GS spectrum to find the degenerate steps in".into());
    };
    if gs.exponents.len() != ctx.d || gs.stderr.len() != ctx.d {
        return Err(format!("the GS spectrum has {} exponents, expected D = {}", gs.exponents.len(), ctx.d));
    }
    Ok(km::mode_steps(&gs.exponents, &gs.stderr, STEP_TOL, step_window(ctx.d, &candidates(ctx)), &candidates(ctx).step_lengths()))
}

/// The resolved mode steps with how each was found, or why there are none.
pub type Resolved = std::result::Result<Vec<(Step, Found)>, String>;

/// The mode steps of a stream, both sides of the null space, resolved once at `frame` (the
/// first sampled frame, [`super::Context::settle`]) from the steps of the
/// exponents ([`detect_steps`], [`resolve_steps`]); or why there are none. Every analysis
/// that names steps takes them from its context, so that all find the same ones.
pub fn resolve(ctx: &Context, frame: &Frame) -> Resolved {
    let detected = detect_steps(ctx)?;
    if frame.v.len() != frame.d * frame.k || frame.k != ctx.d {
        return Err("the stream has no frame with all covariant vectors to classify the steps by".into());
    }
    let exponents = ctx.gs.as_ref().map(|g| g.exponents.as_slice()).unwrap_or_default();
    Ok(resolve_steps(&detected, frame, &candidates(ctx), exponents))
}

/// The steps of `modes` on the positive side (unstable modes), in index order.
pub fn positive(modes: &Resolved, d: usize) -> Vec<Step> {
    modes.as_ref().map(|m| m.iter().map(|(s, _)| *s).filter(|s| is_positive(s, d)).collect()).unwrap_or_default()
}

/// How a step of [`resolve_steps`] was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Found {
    /// By the exponents alone ([`detect_steps`]).
    Exponents,
    /// A shorter step of the exponents, widened to its LP mode's size.
    Widened,
    /// By its vectors: a block next to the mode region that stands apart from its neighbours
    /// but is split too widely for the exponents' tests (a small system's LP modes).
    Vectors,
}

/// The steps to analyse, fixed at the first frame, in index order:
/// - `detected` (from [`detect_steps`]), with every step whose vectors classify clearly
///   ([`classify_clearly`]) as L, P or LP and that is shorter than that LP mode (half of an
///   LP quadruplet split by the statistical test) widened to the block of the LP mode's size
///   containing it, on the same side of the null space and overlapping no other step, whose
///   vectors have the largest fraction in the LP span, if that block stands apart from its
///   neighbours (its spread below both gaps to them: the smooth part of a spectrum is no
///   step);
/// - walking outwards from the null space on the positive side, past the steps found so
///   far, each next block of a candidate step length that stands apart and whose vectors
///   classify clearly as the mode of that size (the exponents of a small system's LP mode
///   spread like the smooth spectrum's, yet the block sits between gaps several times
///   wider: N = 40 in the paper's box), or, where none does, a block of two such sizes that
///   stands apart as a whole and whose two parts are each their mode;
/// - a step of the exponents apart from the mode region that borders the null space stays
///   only if its vectors classify clearly: in a short run, two neighbours in a smooth
///   stretch of the spectrum can be equal within their errors by chance (N = 100, 2500
///   steps: i = 176..177, 0.05 beyond chance, 14 indices from the modes);
/// - a step that mirrors a positive one (conjugate pairing) takes the mirror of its
///   resolution, and a positive step found by its vectors brings its mirror along.
///
/// Exponent means are recomputed from `exponents` (the GS spectrum).
pub fn resolve_steps(detected: &[Step], frame: &Frame, candidates: &Candidates, exponents: &[f64]) -> Vec<(Step, Found)> {
    let d = frame.d;
    let (null_lo, null_hi) = (d / 2 - 3, d / 2 + 3);
    let set = frame.g.as_deref().unwrap_or(&frame.v);
    let at = |start: usize, len: usize| Step { start, len, mean: exponents[start..start + len].iter().sum::<f64>() / len as f64 };
    let mirror = |s: &Step| (d - s.start - s.len, s.len);
    let stands_apart = |c: &Step| {
        let spread = (exponents[c.start] - exponents[c.start + c.len - 1]).abs();
        let gap = |i: usize, j: usize| (exponents[i] - exponents[j]).abs();
        c.start > 0 && c.start + c.len < d && spread < gap(c.start - 1, c.start) && spread < gap(c.start + c.len - 1, c.start + c.len)
    };
    let mut out: Vec<(Step, Found)> = Vec::new();
    for (i, step) in detected.iter().enumerate() {
        let conjugate = detected.iter().position(|o| is_positive(o, d) && !is_positive(step, d) && mirror(o) == (step.start, step.len));
        if let Some(j) = conjugate.filter(|&j| j < out.len()) {
            let (start, len) = mirror(&out[j].0);
            out.push((at(start, len), out[j].1));
            continue;
        }
        let widened = match classify_clearly(frame, step, candidates) {
            Some(m) if m.kind != ModeKind::T && step.len < candidates.families[m.family].dim(ModeKind::LP) => {
                let len = candidates.families[m.family].dim(ModeKind::LP);
                let free = |c: &Step| {
                    let side = c.start + c.len <= null_lo || c.start >= null_hi;
                    let clear = detected.iter().enumerate().all(|(j, o)| j == i || o.start >= c.start + c.len || c.start >= o.start + o.len);
                    side && clear
                };
                let lp_family = Candidates { families: vec![candidates.families[m.family].clone()], ..*candidates };
                ((step.start + step.len).saturating_sub(len)..=step.start)
                    .filter(|&start| start + len <= exponents.len())
                    .map(|start| at(start, len))
                    .filter(|c| free(c) && stands_apart(c))
                    .map(|c| {
                        let lp = km::mode_fractions(group(set, d, &c), &frame.phase, &lp_family, Part::Position)
                            .into_iter()
                            .find(|f| f.kind == ModeKind::LP)
                            .map_or(f64::NAN, |f| f.fraction);
                        (c, lp)
                    })
                    .filter(|(_, lp)| lp.is_finite())
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(c, _)| c)
            }
            _ => None,
        };
        out.push(match widened {
            Some(c) => (c, Found::Widened),
            None => (*step, Found::Exponents),
        });
    }
    // Away from the mode region that borders the null space, two or four exponents equal
    // within their errors may be chance in a smooth stretch of a short run's spectrum: such a
    // step stays only if its vectors are a mode. The region is the step at the null space
    // (whatever its vectors) and the steps beyond it, each next to the last, as long as they
    // are modes: a chance pair next to it is no more a mode than one further out (N = 8:
    // an unclassified pair at i = 9..10, 0.07 beyond chance, next to the T pair, had cut
    // F^(J) to J = 8).
    // Half of an LP mode that could not be widened to its quadruplet (above) is no step: a
    // chance pair (N = 8, 800 steps: i = 9..10 as "LP" at 0.38 beyond chance in the first
    // frame, unclassified over the frames, had cut F^(J) to J = 8).
    let is_mode = |(s, found): &(Step, Found)| {
        *found != Found::Exponents
            || classify_clearly(frame, s, candidates).is_some_and(|m| m.kind == ModeKind::T || s.len >= candidates.families[m.family].dim(ModeKind::LP))
    };
    let bordering = |out: &[(Step, Found)]| {
        let (mut lo, mut hi) = (null_lo, null_hi);
        let mut keep = vec![false; out.len()];
        while let Some(i) = out.iter().position(|(s, _)| s.start + s.len == lo).filter(|&i| lo == null_lo || is_mode(&out[i])) {
            keep[i] = true;
            lo = out[i].0.start;
        }
        while let Some(i) = out.iter().position(|(s, _)| s.start == hi).filter(|&i| hi == null_hi || is_mode(&out[i])) {
            keep[i] = true;
            hi = out[i].0.start + out[i].0.len;
        }
        keep
    };
    let keep = bordering(&out);
    let mut kept = keep.iter();
    out.retain(|step| kept.next().is_some_and(|&k| k) || is_mode(step));
    // Outwards from the null space: the edge is the first index of the mode region so far.
    let mut edge = null_lo;
    loop {
        if let Some((s, _)) = out.iter().find(|(s, _)| s.start + s.len == edge && is_positive(s, d)) {
            edge = s.start;
            continue;
        }
        let clear = |c: &Step| out.iter().all(|(o, _)| o.start >= c.start + c.len || c.start >= o.start + o.len);
        let is_that_mode = |c: &Step| classify_clearly(frame, c, candidates).is_some_and(|m| matches_degeneracy(c, m.kind, &candidates.families[m.family]));
        let lengths: Vec<usize> = candidates.step_lengths().into_iter().filter(|&len| len >= 2).collect();
        let single = lengths.iter().filter(|&&len| len < edge).map(|&len| at(edge - len, len)).find(|c| clear(c) && stands_apart(c) && is_that_mode(c));
        // Two modes whose exponents lie closer together than to their neighbours stand apart
        // only together (N = 120, density 0.7, the paper's box: i = 224..229, likely T(3,0)
        // and LP(2,0), spread over 0.18 between gaps of 0.22 and 0.40): the block of both
        // sizes, split where each part is its mode.
        let pair = || {
            lengths.iter().flat_map(|&a| lengths.iter().map(move |&b| (a, b))).filter(|&(a, b)| a + b < edge).find_map(|(a, b)| {
                let (whole, inner, outer) = (at(edge - a - b, a + b), at(edge - a, a), at(edge - a - b, b));
                (clear(&whole) && stands_apart(&whole) && is_that_mode(&inner) && is_that_mode(&outer)).then(|| vec![inner, outer])
            })
        };
        let Some(parts) = single.map(|c| vec![c]).or_else(pair) else { break };
        for c in parts {
            out.push((c, Found::Vectors));
            let (start, len) = mirror(&c);
            if out.iter().all(|(o, _)| o.start >= start + len || start >= o.start + o.len) {
                out.push((at(start, len), Found::Vectors));
            }
            edge = c.start;
        }
    }
    out.sort_by_key(|(s, _)| s.start);
    out
}

/// J of F^(J): the paper's 370 of 2N - 3 = 393 positive exponents scaled to this system's
/// 2N - 3 = D/2 - 3, ending before the first positive mode step.
pub fn f_size(d: usize, steps: &[Step]) -> usize {
    let m = (d / 2).saturating_sub(3);
    let scaled = super::paper_index(370, m);
    let before_modes = steps.iter().filter(|s| is_positive(s, d)).map(|s| s.start).min().unwrap_or(m);
    scaled.min(m).min(before_modes)
}

/// True for a step on the positive side of the null space (an unstable mode).
pub fn is_positive(step: &Step, d: usize) -> bool {
    step.start + step.len <= d / 2 - 3
}

/// The step's vectors (column-major D x len) out of a full set.
pub fn group<'a>(set: &'a [f64], d: usize, step: &Step) -> &'a [f64] {
    &set[step.start * d..(step.start + step.len) * d]
}

/// Best Table III match of a step in one frame, by its GS vectors if the frame has them, else
/// by its CLVs (paper Sec. 5.5: GS-based classification of the position perturbations).
pub fn classify_step(frame: &Frame, step: &Step, candidates: &Candidates) -> Option<ModeMatch> {
    let set = frame.g.as_deref().unwrap_or(&frame.v);
    km::classify_mode(group(set, frame.d, step), &frame.phase, candidates, Part::Position)
}

/// How much of a step's vectors a candidate of dimension `dim` explains beyond chance:
/// (fraction - c) / (1 - c), with c = dim / 2N the fraction of a random vector (0 for
/// chance, 1 for a pure mode); NaN where the span is the whole space of positions.
pub fn excess(fraction: f64, dim: usize, d: usize) -> f64 {
    let chance = dim as f64 / (d / 2) as f64;
    if chance >= 1.0 { f64::NAN } else { (fraction - chance) / (1.0 - chance) }
}

/// [`classify_step`], if its match explains at least [`MIN_FRACTION`] of the vectors beyond
/// chance ([`excess`]): what the mode table counts as classified, and what the other
/// analyses name steps by.
pub fn classify_clearly(frame: &Frame, step: &Step, candidates: &Candidates) -> Option<ModeMatch> {
    classify_step(frame, step, candidates).filter(|m| excess(m.fraction, candidates.families[m.family].dim(m.kind), frame.d) >= MIN_FRACTION)
}

/// The mode a step is, by name ("LP(1,0)"), where [`classify_clearly`] finds one that also
/// has the step's degeneracy: what Figs. 14 and 15 call a step.
pub fn clear_name(frame: &Frame, step: &Step, candidates: &Candidates) -> Option<String> {
    let m = classify_clearly(frame, step, candidates)?;
    let family = &candidates.families[m.family];
    matches_degeneracy(step, m.kind, family).then(|| family.name(m.kind))
}

/// Whether a class is what the step's degeneracy suggests: the size of the T mode's step for
/// T, of the LP mode's for L, P or LP (a pure L or P vector group is half of an LP step).
pub fn matches_degeneracy(step: &Step, kind: ModeKind, family: &Family) -> bool {
    let kind = if kind == ModeKind::T { kind } else { ModeKind::LP };
    step.len == family.dim(kind)
}
