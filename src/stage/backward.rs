//! The backward (Ginelli) pass: covariant Lyapunov vectors by reverse replay of a run.
//!
//! Ginelli et al. (paper section 3): with Gbar_n = G_n R_n from the forward pass,
//! C_{n-1} = R_n^{-1} C_n keeps V_n = G_n C_n covariant, V_n = J_{n-1} V_{n-1}; the columns of
//! C are renormalised every step and -ln |column| / tau are the local CLV exponents.
//!
//! Why it is built this way:
//! - Only checkpoints are on disk. Each segment between two checkpoints is recomputed from
//!   the older one with the forward code itself, and the recomputed state at the newer
//!   checkpoint must equal the stored one bit for bit: a run can never be silently replayed
//!   with other numbers (another build, another CPU, an altered file).
//! - Segments are recomputed on a second thread while the sweep consumes the previous one,
//!   and the run's threads are shared between the two ([`Cores`]): the recomputation is the
//!   larger part (a QR per step against two triangular products), so it takes every thread
//!   the sweep is not using. Two segments are in memory at most; past the `--memory`
//!   budget the Gram-Schmidt bases of a segment live in an unlinked scratch file (memmap2).
//! - C is iterated at every step (the local exponents need it), but V_n = G_n C_n, a quarter
//!   of a step's arithmetic, and the G_n it needs are kept only for the frames that will be
//!   read (`--vectors-every`): the analyses of vector statistics sample a few hundred frames.
//! - After each segment the frame file is synced and a progress record (C at the segment's
//!   older end, the accumulated exponents, frames written) is saved: `--resume` continues
//!   bit for bit from there.

use super::forward::Forward;
use crate::statistics::{block_len, Accumulator, Estimate};
use super::frame::{on_stride, Frame};
use crate::config::RunConfig;
use crate::error::{Error, Result};
use crate::store::checked_json;
use crate::linalg::{pack_upper, par, unpack_upper_into};
use crate::rng::Rng;
use crate::store::frames::{tmp_path, FrameFile, Flow, StreamInfo};
use crate::store::checkpoints::Checkpoints;
use crate::store::progress::{write_report, Progress};
use crate::store::run::{RunDir, RunMeta, StoreR};
use crate::store::scratch::Storage;
use faer::{Mat, MatMut, MatRef};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// C at t_omega, where the backward iteration starts: any upper-triangular C gives vectors
/// v_omega^j in S_omega^j = span{g^1..g^j} (paper Sec. 3, eq. initial_condition).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CInit {
    /// C = 1 at the end of the window (the paper's choice).
    Identity,
    /// A random upper-triangular C with positive diagonal (generic), from the run's seed.
    Random,
}

/// What the backward stage is asked to do (part of its progress record, so a resumed sweep
/// cannot silently change it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BackwardOptions {
    /// Backward steps discarded before frames are emitted.
    pub transient: u64,
    pub c_init: CInit,
    /// Put G_n into the frames too.
    pub with_gs: bool,
    /// Keep the frames of the steps that are multiples of m in the frame file (0: no file).
    pub save_every: u64,
    /// The frame file: relative to the run directory when inside it (so that a moved run
    /// still finds it), absolute otherwise ([`BackwardOptions::frames_file`]).
    pub frames_path: Option<PathBuf>,
    /// Form V_n = G_n C_n (and copy G_n) only for the frames whose step n is a multiple of m
    /// ([`on_stride`]); the others carry the phase point and the local exponents.
    /// V = G C is D k^2 flops a frame, a quarter of a backward step (k = D), and the analyses of
    /// vector statistics read only the frames of every m-th step anyway (`clv analyze --every`).
    #[serde(default = "one")]
    pub vectors_every: u64,
    /// The sweep sends its frames nowhere: no frame file and no stream, only the CLV
    /// spectrum (`clv backward --save-every 0` without --out; `frames_path` is then None, as
    /// for a stream). Absent from the records of earlier builds, which named the default
    /// frame file with --save-every 0 for such a sweep.
    #[serde(default, skip_serializing_if = "is_false")]
    pub no_frames: bool,
}

fn one() -> u64 {
    1
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl BackwardOptions {
    /// The frame file `file` as the options record it: relative to the run directory `run`
    /// when inside it, else absolute; never relative to the directory the command runs in,
    /// which a later --resume may not share.
    pub fn record_frames_path(run: &Path, file: &Path) -> Result<PathBuf> {
        let (run, file) = (canonical(run)?, canonical(file)?);
        Ok(file.strip_prefix(&run).map_or(file.clone(), Path::to_path_buf))
    }

    /// Where the frames go, as `frames_path`, `save_every` and `no_frames` say together (a
    /// record of an earlier build names a file with --save-every 0 for a sweep that wrote
    /// none).
    pub fn destination(&self) -> Destination<'_> {
        match (&self.frames_path, self.no_frames) {
            (Some(path), _) if self.save_every > 0 => Destination::File { path, every: self.save_every },
            (Some(_), _) | (None, true) => Destination::Nowhere,
            (None, false) => Destination::Stream,
        }
    }

    /// The frame file of a sweep of the run in `run`, if it writes one.
    pub fn frames_file(&self, run: &Path) -> Option<PathBuf> {
        match self.destination() {
            Destination::File { path, .. } => Some(run.join(path)),
            _ => None,
        }
    }

    /// The sweep sends its frames to a reader (`--out -`, or `clv run`'s analyses in the
    /// same process) rather than to a file or nowhere.
    pub fn streams(&self) -> bool {
        self.destination() == Destination::Stream
    }

    /// The options as the flags of `clv backward` that give them.
    pub fn as_flags(&self) -> String {
        let out = match &self.frames_path {
            Some(p) => format!("--out {} ", p.display()),
            None if self.no_frames => String::new(),
            None => "--out - ".into(),
        };
        let c_init = match self.c_init {
            CInit::Identity => "identity",
            CInit::Random => "random",
        };
        let gs = if self.with_gs { " --with-gs" } else { "" };
        format!("{out}--save-every {} --vectors-every {} --transient {} --c-init {c_init}{gs}", self.save_every, self.vectors_every, self.transient)
    }

    /// The options of the sweep that wrote a frame stream, from its metadata (None for a
    /// stream of a build before they were written into it).
    pub fn of_stream(info: &crate::store::frames::StreamInfo) -> Option<Self> {
        info.backward_json.as_deref().and_then(|s| serde_json::from_str(s).ok())
    }

    /// [`BackwardOptions::as_flags`] of the same sweep into `file` (its path as a user gives
    /// it, where the record holds it relative to the run directory).
    pub fn flags_into(&self, file: &Path) -> String {
        BackwardOptions { frames_path: Some(file.to_path_buf()), no_frames: false, ..self.clone() }.as_flags()
    }

    pub fn for_run(meta: &RunMeta) -> Self {
        BackwardOptions { transient: meta.store.transient, c_init: CInit::Identity, with_gs: false, save_every: 1, frames_path: None, vectors_every: 1, no_frames: false }
    }

    /// As a frame stream's metadata records them (`backward.json`).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }
}

/// The description of the frame stream a backward stage with `opts` writes over the run in
/// `dir`: the run, its forward spectrum, and the options (file, pipe and in-process alike).
pub fn stream_info(dir: &RunDir, meta: &RunMeta, opts: &BackwardOptions) -> StreamInfo {
    StreamInfo {
        run_json: Some(RunDir::meta_json(meta)),
        spectrum_json: std::fs::read_to_string(dir.spectrum_path()).ok(),
        backward_json: Some(opts.to_json()),
    }
}

/// Statistics of a backward sweep.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct BackwardStats {
    pub frames: u64,
    pub first_frame_step: u64,
    pub last_frame_step: u64,
    pub segments: u64,
    pub recomputed_steps: u64,
    pub wall_seconds: f64,
    /// The consumer stopped the stream before the end (a closed pipe).
    pub stopped_early: bool,
}

/// The result of a backward sweep, as `clv backward --json` prints it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BackwardReport {
    /// The CLV spectrum: time averages of the local exponents over the emitted frames.
    pub exponents: Vec<f64>,
    #[serde(deserialize_with = "crate::statistics::errors_or_nan")]
    pub stderr: Vec<f64>,
    /// The forward Gram-Schmidt spectrum of the same run.
    pub gs_exponents: Vec<f64>,
    #[serde(deserialize_with = "crate::statistics::errors_or_nan")]
    pub gs_stderr: Vec<f64>,
    /// h_KS from the CLV and from the GS spectrum (absent from older reports).
    #[serde(default)]
    pub ks_entropy: Option<Estimate>,
    #[serde(default)]
    pub gs_ks_entropy: Option<Estimate>,
    /// The GS spectrum over the steps of the emitted frames only, like for like with the
    /// CLV spectrum: the whole run's GS spectrum differs from the CLV one by the window's
    /// own fluctuation, which the CLV errors measure (absent from older reports, and from a
    /// sweep resumed from an older progress record).
    #[serde(default)]
    pub gs_window: Option<WindowSpectrum>,
    pub options: BackwardOptions,
    pub statistics: BackwardStats,
    /// What the forward stage warned of, which holds for these exponents too (the same R
    /// matrices); absent when it warned of nothing.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// What the stage did that a person should know (not stored).
    #[serde(skip)]
    pub notes: Vec<String>,
    /// Read back from the sweep that finished earlier (`--resume`): its statistics are that
    /// sweep's, not work done now (not stored).
    #[serde(skip)]
    pub earlier: bool,
}

/// A spectrum over the frames' window, with its batch-means errors and h_KS.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct WindowSpectrum {
    pub exponents: Vec<f64>,
    #[serde(deserialize_with = "crate::statistics::errors_or_nan")]
    pub stderr: Vec<f64>,
    pub ks_entropy: Option<Estimate>,
}

fn progress_path(dir: &RunDir) -> PathBuf {
    dir.progress_path()
}

/// What a frame file that stands for the run in `dir` must hold: that run's frames (its
/// run.json) from its last backward sweep (`options`, as backward.json records them). A file
/// copied or restored over it from another run or sweep would otherwise be analysed under
/// the run's name.
pub struct SweepFile {
    pub dir: PathBuf,
    pub meta: RunMeta,
    pub options: Option<BackwardOptions>,
}

impl SweepFile {
    /// Why the frame stream described by `info` is not that sweep's, if it is not.
    pub fn check(&self, info: &crate::store::frames::StreamInfo) -> std::result::Result<(), String> {
        let run: Option<RunMeta> = info.run_json.as_deref().and_then(|s| serde_json::from_str(s).ok());
        if let Some(run) = run.filter(|r| !(r.config.same_but_threads(&self.meta.config) && r.store == self.meta.store)) {
            let differ = crate::store::run::differences((&self.meta.config, &self.meta.store, "in run.json"), (&run.config, &run.store, "in the file")).join(", ");
            return Err(format!("it holds another run's frames ({differ})"));
        }
        let sweep = BackwardOptions::of_stream(info);
        let unnamed = |o: &BackwardOptions| BackwardOptions { frames_path: None, ..o.clone() };
        match (&self.options, sweep) {
            (Some(want), Some(have)) if unnamed(want) != unnamed(&have) => Err(format!(
                "the run's last backward sweep ({}, recorded in {}) did not write it: another sweep did ({})",
                want.as_flags(),
                progress_path(&RunDir { path: self.dir.clone() }).display(),
                have.as_flags()
            )),
            _ => Ok(()),
        }
    }
}

/// How to write a frame file `file` anew, as a clause that follows "; ": move it aside and
/// give its sweep again, with the options recorded in it and its run directory where known;
/// for an interrupted sweep's FILE.tmp, continue that sweep instead.
pub fn rewrite_advice(file: &Path, options: Option<&BackwardOptions>, run: Option<&Path>) -> String {
    let run = run.map_or("RUN_DIR".to_string(), |d| d.display().to_string());
    // An interrupted sweep's FILE.tmp: the sweep that finishes it writes FILE.
    let whole = file.to_str().and_then(|f| f.strip_suffix(".tmp")).filter(|f| f.ends_with(".mcap")).map(PathBuf::from);
    let target = whole.as_deref().unwrap_or(file);
    let flags = match options {
        Some(o) => o.flags_into(target),
        None => format!("--out {}", target.display()),
    };
    match &whole {
        Some(f) => format!(
            "it is the unfinished file of an interrupted sweep into {}: continue that sweep with `clv backward {run} --resume`, or delete it and give the sweep again: `clv backward {run} {flags}`",
            f.display()
        ),
        None => format!("to write it whole, move {} aside and give its sweep again: `clv backward {run} {flags}`", file.display()),
    }
}

pub fn report_path(dir: &RunDir) -> PathBuf {
    dir.clv_spectrum_path()
}

/// The window of a run: frames at steps first..=last; first is the paper's t_0, and C starts
/// at the run's last step, the paper's t_omega, beyond last by the backward transient.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub first: u64,
    pub last: u64,
}

impl Window {
    /// The window a sweep with `opts` emits frames for: the steps the forward run kept for
    /// the backward stage, less the backward transient at the newer end. The run's last
    /// step is never a frame (its local exponents would need R of the step after it), so
    /// a transient of 0 ends the window one step before it.
    pub fn of(meta: &RunMeta, opts: &BackwardOptions) -> Result<Self> {
        let (config, store) = (&meta.config, &meta.store);
        let total = config.relax_steps + config.steps;
        let kept = store.clv_steps + store.transient;
        if store.clv_steps == 0 {
            return Err(Error::Other(
                "the forward run kept no CLV window (--clv-steps 0: the Gram-Schmidt spectrum only), so there is nothing for a backward sweep; \
                 to get covariant vectors, extend it with `clv forward --resume RUN_DIR --steps MORE --clv-steps N` (RUN_DIR the run's directory), which keeps what the backward stage needs \
                 for a window of the last N steps (with a transient of N/2 steps after it, or --transient T)"
                    .into(),
            ));
        }
        if opts.transient >= kept {
            return Err(Error::param("transient", format!("must be below the {kept} steps the run kept for the backward stage (--clv-steps + --transient of the forward run)")));
        }
        Ok(Window { first: total - kept, last: total - opts.transient.max(1) })
    }

    /// The oldest and newest step of the frames a whole sweep with `opts` leaves: in its
    /// frame file the multiples of --save-every, on a stream every step.
    pub fn frame_steps(&self, opts: &BackwardOptions) -> Option<(u64, u64)> {
        let m = match opts.destination() {
            Destination::File { every, .. } => every,
            Destination::Stream => 1,
            Destination::Nowhere => return None,
        };
        let (oldest, newest) = (self.first.div_ceil(m) * m, self.last / m * m);
        (oldest <= newest).then_some((oldest, newest))
    }
}

/// One recomputed segment [s0, s1]: Gamma_n for n = s0..=s1, packed R_n for n = s0+1..=s1,
/// and G_n for the steps whose frames carry vectors, in flat buffers that are handed back
/// and reused (two exist at most), so the memory of the sweep never depends on the window
/// length. G_n of step s0 + i is in slot `g_slot[i]`; with `--vectors-every m` a segment of
/// C steps needs at most ceil((C + 1) / m) slots instead of C + 1.
struct Segment {
    s0: u64,
    s1: u64,
    g: Storage,
    g_slot: Vec<Option<usize>>,
    phase: Vec<f64>,
    r: Vec<f64>,
}

impl Segment {
    fn new(steps: usize, d: usize, k: usize, vectors_every: u64, out_of_core: Option<&Path>) -> Result<Self> {
        Ok(Segment {
            s0: 0,
            s1: 0,
            g: Storage::new(Self::g_slots(steps, vectors_every) * d * k, out_of_core)?,
            g_slot: vec![None; steps + 1],
            phase: vec![0.0; (steps + 1) * d],
            r: vec![0.0; steps * k * (k + 1) / 2],
        })
    }

    /// G_n slots a segment of `steps` steps needs: one per multiple of `vectors_every` among
    /// its steps + 1 step numbers.
    fn g_slots(steps: usize, vectors_every: u64) -> usize {
        (steps + 1).div_ceil(vectors_every.max(1) as usize)
    }

    /// G_n of step `n`, if the segment kept it.
    fn g(&self, n: u64, dk: usize) -> Option<&[f64]> {
        let slot = (*self.g_slot.get(n.checked_sub(self.s0)? as usize)?)?;
        Some(&self.g.slice()[slot * dk..(slot + 1) * dk])
    }
}

/// Threads the sweep (R^-1 C, V = G C) of a run on `threads` threads uses: see [`Cores`].
pub fn sweep_threads(threads: usize) -> usize {
    (threads / 3).max(1)
}

/// How the run's threads are shared between the recomputation and the sweep. The sweep
/// (R^-1 C and V = G C, 4/3 D^3 flops a step) gets a third of them, at least one; the
/// recomputation (8/3 D^3) the rest while the sweep works, and all of them while the sweep
/// waits for its next segment. Spinning QR workers must not share a core with the sweep,
/// so together the two use no more threads than the run has (two when it has one: the
/// recomputation beside the sweep).
struct Cores {
    threads: usize,
    sweeping: std::sync::atomic::AtomicBool,
}

impl Cores {
    fn new(threads: usize) -> Self {
        Cores { threads: threads.max(1), sweeping: false.into() }
    }

    fn sweep_threads(&self) -> usize {
        sweep_threads(self.threads)
    }

    fn recompute_threads(&self) -> usize {
        if self.sweeping.load(std::sync::atomic::Ordering::Relaxed) {
            (self.threads - self.sweep_threads()).max(1)
        } else {
            self.threads
        }
    }

    fn set_sweeping(&self, sweeping: bool) {
        self.sweeping.store(sweeping, std::sync::atomic::Ordering::Relaxed);
    }
}

/// Recompute segment [s0, s1] into `seg` from the older checkpoint and verify it against
/// the newer one: R_n for every step, G_n for the steps n where `reads_g(n)` (the frames
/// that carry vectors).
/// The pass `fwd` is made on the first segment and restored on the others.
#[allow(clippy::too_many_arguments)]
fn recompute(config: &RunConfig, store_r_all: bool, reads_g: &dyn Fn(u64) -> bool, cores: &Cores, cps: &mut Checkpoints, fwd: &mut Option<Forward>, s0: u64, s1: u64, seg: &mut Segment) -> Result<()> {
    // The newer end first: it is the older end of the segment before, still in `cps`.
    let want = cps.get(s1)?;
    let start = cps.get(s0)?;
    let fwd = match fwd {
        Some(f) => {
            f.restore(&start)?;
            f
        }
        None => fwd.insert(Forward::resume(config, &start)?),
    };
    let (d, k) = (fwd.system.dim(), config.vectors);
    let (dk, kk) = (d * k, k * (k + 1) / 2);
    seg.s0 = s0;
    seg.s1 = s1;
    let mut used = 0;
    for (i, slot) in seg.g_slot.iter_mut().enumerate() {
        *slot = (i as u64 <= s1 - s0 && reads_g(s0 + i as u64)).then(|| {
            used += 1;
            used - 1
        });
    }
    if used * dk > seg.g.slice().len() {
        return Err(Error::Other(format!("segment {s0}..{s1} needs {used} G_n slots, more than its buffer holds (a bug: please report it)")));
    }
    let g = seg.g.slice_mut();
    if let Some(slot) = seg.g_slot[0] {
        g[slot * dk..(slot + 1) * dk].copy_from_slice(&start.g);
    }
    seg.phase[..d].copy_from_slice(&start.system.phase);
    for n in s0 + 1..=s1 {
        fwd.set_threads(cores.recompute_threads());
        let i = (n - s0) as usize;
        let g_n = seg.g_slot[i].map(|slot| &mut g[slot * dk..(slot + 1) * dk]);
        fwd.step_with_copies(g_n, &mut seg.r[(i - 1) * kk..i * kk])?;
        seg.phase[i * d..(i + 1) * d].copy_from_slice(&fwd.system.snapshot().phase);
    }
    let got = fwd.state();
    if got != *want {
        let file = cps.segment_of(s1).map(|s| s.path.display().to_string()).unwrap_or_default();
        return Err(Error::Dynamics(format!(
            "recomputation from step {s0} does not reproduce the checkpoint at step {s1} stored in {file}: {}. \
             The run was made by another build or on a CPU with other features (see run.json), or the file was altered; \
             the backward stage refuses to continue with numbers it cannot verify",
            want.first_difference(&got)
        )));
    }
    // The R_n a `--store-r all` run keeps for readers outside clv are checked like the
    // checkpoints: what the sweep uses is the recomputed R_n, and a stored one that differs
    // says the file is not the run's.
    if store_r_all {
        for (n, packed) in cps.stored_r(s0, s1)? {
            let i = (n - s0) as usize;
            let recomputed = &seg.r[(i - 1) * kk..i * kk];
            if let Some(at) = recomputed.iter().zip(&packed).position(|(a, b)| a.to_bits() != b.to_bits()) {
                let file = cps.segment_of(n).map(|s| s.path.display().to_string()).unwrap_or_default();
                return Err(Error::Dynamics(format!(
                    "R_n at step {n} stored in {file} (--store-r all) is not the recomputed one: packed entry {at} is {:e}, recomputed {:e}. \
                     The file was altered or the run was made by another build; the backward stage refuses to continue with numbers it cannot verify",
                    packed.get(at).copied().unwrap_or(f64::NAN),
                    recomputed[at]
                )));
            }
        }
    }
    Ok(())
}

/// Where a sweep's frames go ([`BackwardOptions::destination`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Destination<'a> {
    /// A frame file (its path as recorded, relative to the run directory where inside it)
    /// that keeps the frames of the steps that are multiples of `every`.
    File { path: &'a Path, every: u64 },
    /// A reader of the stream (standard output, or `clv run`'s analyses): every frame.
    Stream,
    /// Nowhere: the sweep computes the CLV spectrum only.
    Nowhere,
}

/// About how many bytes the frame file of a sweep with `opts` over the run in `dir` takes
/// (nothing without one): a frame's phase point and two sets of local exponents, 8 (D + 2k),
/// and 8 D k more for V_n, and again for G_n, where they are formed; its keys, record and
/// index entry; and the file's copies of the run's descriptions (frames are not compressed).
pub fn frame_file_bytes(dir: &RunDir, meta: &RunMeta, opts: &BackwardOptions) -> u64 {
    let Ok(window) = Window::of(meta, opts) else { return 0 };
    if !matches!(opts.destination(), Destination::File { .. }) {
        return 0;
    }
    const PER_MESSAGE: u64 = 160;
    const PER_FILE: u64 = 4096;
    let (d, k) = (meta.config.system.dim() as u64, meta.config.vectors as u64);
    let vectors = 8 * d * k * (1 + u64::from(opts.with_gs));
    let frames: u64 = (window.first..=window.last)
        .filter(|&n| on_stride(n, opts.save_every))
        .map(|n| 8 * (d + 2 * k) + PER_MESSAGE + if on_stride(n, opts.vectors_every) { vectors } else { 0 })
        .sum();
    let descriptions: usize = stream_info(dir, meta, opts).metadata().values().map(String::len).sum();
    frames + descriptions as u64 + crate::store::schema::FRAME.text.len() as u64 + PER_FILE
}

/// The progress of the sweep `opts` describes when it is to be continued (`resume`), after
/// the checks that a new or continued sweep strands, mixes or overwrites nothing: another
/// interrupted sweep's frames, another sweep's record, an existing file.
fn prior_sweep(dir: &RunDir, meta: &RunMeta, opts: &BackwardOptions, resume: bool) -> Result<Option<Progress>> {
    let frames_path = opts.frames_file(&dir.path);
    let progress_file = progress_path(dir);
    let record = match std::fs::read_to_string(&progress_file) {
        Ok(text) if resume => Some(text),
        // A sweep writes its record before anything else: without one there is nothing of
        // it to continue, and its options are unknown (starting over with the defaults would
        // quietly drop e.g. --with-gs, and could take another sweep's frame file).
        Err(e) if resume && e.kind() == std::io::ErrorKind::NotFound => {
            return Err(Error::param("resume", format!(
                "there is no backward sweep of {} to continue ({} does not exist: none was started, or it stopped before it could record itself); \
                 give the command without --resume, with the options you want",
                dir.path.display(),
                progress_file.display()
            )));
        }
        Err(e) if resume => return Err(Error::io(&progress_file, e)),
        // A new sweep replaces the progress record: refuse where that would strand the
        // frames an interrupted sweep with other options left in its file.
        Ok(text) => {
            if let Ok(p) = Progress::read(&dir.path, &progress_file, text.as_bytes())
                && !p.done
                && p.options != *opts
                && let Some(stranded) = p.options.frames_file(&dir.path).map(|f| tmp_path(&f)).filter(|t| t.exists())
            {
                let file = p.options.frames_file(&dir.path).map(|f| f.display().to_string()).unwrap_or_default();
                let m = p.options.save_every.max(1);
                let kept = if p.stats.frames == 0 { 0 } else { (p.stats.last_frame_step / m + 1).saturating_sub(p.stats.first_frame_step.div_ceil(m)) };
                return Err(Error::Other(format!(
                    "{} holds the progress of an interrupted backward sweep into {file} (down to step {}: {} frames, {kept} of them kept in {}), which a new sweep would make impossible to resume; \
                     finish it first with `clv backward {} --out {file} --resume`, or delete {} to give it up",
                    progress_file.display(),
                    p.at,
                    p.stats.frames,
                    stranded.display(),
                    dir.path.display(),
                    stranded.display()
                )));
            }
            None
        }
        _ => None,
    };
    let prior: Option<Progress> = match record {
        Some(text) => {
            let p = Progress::read(&dir.path, &progress_file, text.as_bytes()).map_err(|e| {
                // The frames the sweep left would stop a new one: name them, where the damaged
                // record still says where they are, or else in the file this command names.
                let recorded = serde_json::from_str::<serde_json::Value>(&text).ok().and_then(|v| v["options"]["frames_path"].as_str().map(|f| tmp_path(&dir.path.join(f))));
                let left = recorded
                    .into_iter()
                    .chain(frames_path.as_deref().map(tmp_path))
                    .find(|t| t.exists())
                    .map_or(String::new(), |t| format!("delete {} (the frames it left) and ", t.display()));
                Error::Other(format!("{e}; the sweep cannot be continued from it: {left}give the command without --resume to start the sweep over (the forward run is not affected)"))
            })?;
            if p.options != *opts {
                let (record, was, given) = (progress_file.display(), p.options.as_flags(), opts.as_flags());
                return Err(Error::param("resume", if p.done {
                    format!("the sweep recorded in {record} ({was}) has finished, and no sweep with {given} recorded itself (one killed at its start has not yet): there is nothing to continue; give the command without --resume")
                } else {
                    format!(
                        "the interrupted sweep recorded in {record} was started with {was}, not {given}; continue it with `clv backward {} --resume` and no other flags, or run without --resume to start over",
                        dir.path.display()
                    )
                }));
            }
            Some(p)
        }
        None => {
            if let Some(f) = frames_path.as_ref()
                && tmp_path(f).exists() {
                    // This run's own sweep from before it was made longer: its record went with
                    // the shorter run's results, so it cannot be continued.
                    let theirs = crate::store::frames::metadata_of(&tmp_path(f)).ok().flatten().and_then(|m| serde_json::from_str::<RunMeta>(m.get("run.json")?).ok());
                    if let Some(shorter) = theirs.filter(|t| t.config.steps < meta.config.steps && RunConfig { steps: meta.config.steps, ..t.config.clone() }.same_but_threads(&meta.config)) {
                        return Err(Error::Other(format!(
                            "{} holds the frames of an interrupted backward sweep of this run as it was with {} steps, before it was made longer: \
                             that sweep cannot be continued (its record went with the shorter run's results); delete the file, or give this sweep another --out",
                            tmp_path(f).display(),
                            shorter.config.steps
                        )));
                    }
                    return Err(Error::Other(format!(
                        "{} holds the frames of an interrupted backward sweep (of this run, or of another whose --out names the same file): \
                         continue that sweep with `clv backward RUN --resume`, give this one another --out, or delete the file to give that sweep up",
                        tmp_path(f).display()
                    )));
                }
            None
        }
    };
    // Refused before the new sweep records itself: a refusal leaves nothing behind.
    if let (None, Some(f)) = (&prior, frames_path.as_ref())
        && f.exists()
    {
        return Err(Error::param("out", if f.is_dir() {
            format!("{} is a directory; --out names the frame file to write (FILE.mcap)", f.display())
        } else {
            format!("{} already exists; refusing to overwrite it: choose another --out (or delete it yourself, if it is a frame file you no longer need)", f.display())
        }));
    }
    Ok(prior)
}

/// `path` with `.`, `..` and symbolic links resolved, as far as it exists (a file still to
/// be written keeps its name under its resolved directory).
fn canonical(path: &Path) -> Result<PathBuf> {
    let absolute = std::path::absolute(path).map_err(|e| Error::io(path, e))?;
    if let Ok(resolved) = absolute.canonicalize() {
        return Ok(resolved);
    }
    match (absolute.parent(), absolute.file_name()) {
        (Some(parent), Some(name)) => Ok(canonical(parent)?.join(name)),
        _ => Ok(absolute),
    }
}

/// Progress hooks: called with (steps recomputed, frames emitted) as the sweep advances.
pub type OnProgress<'a> = &'a mut dyn FnMut(u64, u64);

/// Run the backward pass over the run in `path`, handing every frame to `consumer`
/// (newest first). Frames are also saved to the frame file if the options ask for one.
pub fn run(
    path: &Path,
    opts: &BackwardOptions,
    resume: bool,
    memory_bytes: u64,
    threads: Option<usize>,
    consumer: &mut dyn FnMut(Arc<Frame>) -> Result<Flow>,
    on_progress: OnProgress,
) -> Result<BackwardReport> {
    let started = Instant::now();
    let (dir, mut meta) = RunDir::open(path)?;
    meta.config.set_threads(threads);
    let _lock = dir.lock("backward pass")?;
    meta.build.check_can_continue(path)?;
    dir.check_meta(&meta)?;
    let (config, store) = (&meta.config, &meta.store);
    let gs = forward_spectrum(&dir)?;
    let window = checked_window(&meta, opts)?;
    let progress_file = progress_path(&dir);
    // Before anything looks at the frame file or writes: another run's sweep may be writing
    // the same --out.
    let frames_path = opts.frames_file(&dir.path);
    let _frames_lock = match &frames_path {
        Some(f) => Some(crate::store::frames::lock(f)?),
        None => None,
    };
    let prior = prior_sweep(&dir, &meta, opts, resume)?;
    if prior.as_ref().is_some_and(|p| p.done) {
        return finished_earlier(&dir, opts);
    }
    let mut notes: Vec<String> = prior.as_ref().and_then(|p| frames_sent_before(p, opts, window)).into_iter().collect();

    let cores = Arc::new(Cores::new(config.threads));
    let mut sweep = Sweep::start(opts, window, config, prior.as_ref(), &progress_file, par(cores.sweep_threads()), started)?;
    let c_every = store.checkpoint_every;
    let total = config.relax_steps + config.steps;
    let resume_at = prior.as_ref().map(|p| p.at).unwrap_or(total);
    let mut bounds: Vec<u64> = (window.first / c_every * c_every..total).step_by(c_every as usize).collect();
    bounds.push(total);
    let todo: Vec<(u64, u64)> = bounds.windows(2).rev().map(|w| (w[0], w[1])).filter(|&(_, s1)| s1 <= resume_at).collect();
    if prior.is_none() {
        // A new sweep owns the progress record from its start, before its frame file exists:
        // interrupted before its first segment, it is the one --resume continues (an earlier
        // record left in place would point --resume at another sweep, and strand this one's
        // frames).
        sweep.record(resume_at, false).save(&progress_file)?;
    }
    let mut frame_file = match &frames_path {
        Some(f) => Some(open_frame_file(f, &dir, &meta, opts, window, prior.as_ref())?),
        None => None,
    };

    let (d, k) = (config.system.dim(), config.vectors);
    let segment_bytes = 8 * (Segment::g_slots(c_every as usize, opts.vectors_every) * d * k) as u64;
    // Two segment buffers, and a third share as headroom for what the sweep and the
    // consumers of its frames hold besides (C, the frames being formed and queued): a budget
    // that only just holds two segments goes out of core.
    // The budget is --memory, or less where the machine or the job's memory limit (its
    // control group) offers less: past it the OOM killer ends the stage without a word.
    let offered = crate::machine::available_memory();
    let budget = offered.map_or(memory_bytes, |m| m.min(memory_bytes));
    let out_of_core = (3 * segment_bytes > budget).then(|| dir.path.clone());
    if out_of_core.is_some() && budget < memory_bytes {
        notes.push(format!(
            "this machine (or the job's memory limit) offered {} MB, less than --memory's {} MB and less than three segments' Gram-Schmidt bases ({} MB each: two in use, a third's worth for the rest): they were kept in a scratch file in {}",
            budget >> 20,
            memory_bytes >> 20,
            segment_bytes >> 20,
            dir.path.display()
        ));
    }
    let planned = todo.len() as u64;
    let recomputation = Recomputation {
        config: config.clone(),
        store_r_all: store.store_r == StoreR::All,
        window,
        vectors_every: opts.vectors_every,
        segment_steps: c_every as usize,
        out_of_core,
        cores: cores.clone(),
    };
    let segments = recomputation.spawn(dir.segments()?, todo)?;
    let flow = sweep.all_segments(segments, planned, &cores, frame_file.as_mut(), &progress_file, &dir.path, consumer, on_progress)?;

    let stopped = flow == Flow::Stop;
    sweep.clock();
    let Sweep { acc, acc_gs, mut stats, .. } = sweep;
    stats.stopped_early = stopped;
    let mut report = BackwardReport {
        exponents: acc.exponents(1.0),
        stderr: acc.stderr(1.0),
        ks_entropy: acc.ks_entropy(1.0, config.system.neutral()),
        warnings: gs.warnings,
        gs_exponents: gs.exponents,
        gs_stderr: gs.stderr,
        gs_ks_entropy: gs.ks_entropy,
        gs_window: acc_gs.as_ref().map(|a| WindowSpectrum { exponents: a.exponents(config.tau), stderr: a.stderr(config.tau), ks_entropy: a.ks_entropy(config.tau, config.system.neutral()) }),
        options: opts.clone(),
        statistics: stats.clone(),
        notes,
        earlier: false,
    };
    if stopped {
        return Ok(report);
    }
    if let Some(file) = frame_file {
        file.finish()?;
    }
    write_report(&dir, &mut report)?;
    let done = Progress { options: opts.clone(), at: window.first, c: Vec::new(), acc, acc_gs, stats, done: true };
    done.save(&progress_file)?;
    Ok(report)
}

/// The forward run's GS spectrum (spectrum.json), which the backward report carries beside
/// the CLV spectrum: a run without it is not finished.
fn forward_spectrum(dir: &RunDir) -> Result<crate::report::SpectrumSummary> {
    let (file, run) = (dir.spectrum_path(), dir.path.display());
    crate::report::SpectrumSummary::read(&file).map_err(|e| match file.exists() {
        false => Error::Other(format!("the forward run in {run} is not complete (no spectrum.json); finish it with `clv forward --resume {run}`")),
        true => Error::Other(format!("{e}; `clv forward --resume {run}` rewrites it from the run's last checkpoint")),
    })
}

/// The CLV window of `opts`, refused where the options cannot give a frame.
fn checked_window(meta: &RunMeta, opts: &BackwardOptions) -> Result<Window> {
    if opts.vectors_every == 0 {
        return Err(Error::param("vectors-every", "must be at least 1 (1: every frame carries V_n)"));
    }
    let window = Window::of(meta, opts)?;
    if matches!(opts.destination(), Destination::File { every, .. } if window.last / every * every < window.first) {
        return Err(Error::param(
            "save-every",
            format!(
                "no step of the CLV window {}..{} is a multiple of {}: the frame file would hold no frame; give a --save-every of at most {}",
                window.first,
                window.last,
                opts.save_every,
                window.last - window.first + 1
            ),
        ));
    }
    Ok(window)
}

/// What a resumed stream says about the frames its interrupted predecessor already sent.
fn frames_sent_before(prior: &Progress, opts: &BackwardOptions, window: Window) -> Option<String> {
    if !opts.streams() || prior.stats.frames == 0 {
        return None;
    }
    let sent = window.last + 1 - prior.stats.frames;
    Some(format!(
        "the frames of steps {sent}..{} went to the reader of the interrupted stream and are not sent again: this stream carries steps {}..{}, \
         and analyses of it describe those steps only; for the whole window, start the stream again without --resume",
        window.last,
        window.first,
        sent - 1
    ))
}

/// The sweep's frame file: a new one, or, resuming, the interrupted one with the frames the
/// progress record counts (those of the steps that are multiples of --save-every among the
/// ones the sweep had emitted, window.last down).
fn open_frame_file(file: &Path, dir: &RunDir, meta: &RunMeta, opts: &BackwardOptions, window: Window, prior: Option<&Progress>) -> Result<FrameFile> {
    let metadata = stream_info(dir, meta, opts).metadata();
    match prior {
        Some(p) => {
            let kept: Vec<u64> = ((window.last + 1).saturating_sub(p.stats.frames)..=window.last).rev().filter(|&m| on_stride(m, opts.save_every)).collect();
            FrameFile::salvage(file, &metadata, &kept, &format!("clv backward {} {}", dir.path.display(), opts.flags_into(file)))
        }
        None => FrameFile::create(file, &metadata),
    }
}

/// The recomputation of the run's segments, newest first, on a thread of its own beside the
/// sweep: G_n (for V_n = G_n C_n) and R_n of every step of a segment from its checkpoint.
struct Recomputation {
    config: RunConfig,
    store_r_all: bool,
    window: Window,
    vectors_every: u64,
    /// Steps per segment (the run's checkpoint interval).
    segment_steps: usize,
    /// Where segment buffers go when they do not fit in memory.
    out_of_core: Option<PathBuf>,
    cores: Arc<Cores>,
}

type Segments = (crossbeam_channel::Receiver<Result<Segment>>, crossbeam_channel::Sender<Segment>, std::thread::JoinHandle<()>);

impl Recomputation {
    /// Start recomputing the segments `todo` ((s0, s1) steps, newest first) of the run's
    /// `segments`: each is sent when done (one at a time), into one of two buffers the sweep
    /// hands back over the second channel when it has swept them. The first error is sent
    /// and ends it.
    fn spawn(self, segments: Vec<crate::store::run::SegmentFile>, todo: Vec<(u64, u64)>) -> Result<Segments> {
        let (tx, rx) = crossbeam_channel::bounded::<Result<Segment>>(0);
        let (free_tx, free_rx) = crossbeam_channel::bounded::<Segment>(2);
        let (d, k) = (self.config.system.dim(), self.config.vectors);
        let handle = std::thread::Builder::new()
            .name("clv-recompute".into())
            .spawn(move || {
                let Recomputation { config, store_r_all, window, vectors_every, segment_steps, out_of_core, cores } = self;
                let reads_g = move |n: u64| n >= window.first && n <= window.last && on_stride(n, vectors_every);
                let mut cps = Checkpoints::new(segments);
                let mut fwd = None;
                let mut allocated = 0;
                for (s0, s1) in todo {
                    let buffer = match free_rx.try_recv() {
                        Ok(b) => Ok(b),
                        Err(_) if allocated < 2 => {
                            allocated += 1;
                            Segment::new(segment_steps, d, k, vectors_every, out_of_core.as_deref())
                        }
                        Err(_) => free_rx.recv().map_err(|_| Error::Other("the sweep stopped".into())),
                    };
                    let seg = buffer.and_then(|mut b| recompute(&config, store_r_all, &reads_g, &cores, &mut cps, &mut fwd, s0, s1, &mut b).map(|_| b));
                    let failed = seg.is_err();
                    if tx.send(seg).is_err() || failed {
                        break;
                    }
                }
            })
            .map_err(|e| Error::Other(format!("cannot start the recomputation thread: {e}")))?;
        Ok((rx, free_tx, handle))
    }
}

/// `--resume` of a sweep that finished: its report is the answer, and nothing is recomputed.
fn finished_earlier(dir: &RunDir, opts: &BackwardOptions) -> Result<BackwardReport> {
    let path = report_path(dir);
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let (mut report, _): (BackwardReport, _) = checked_json::from_slice(&path, text.as_bytes()).map_err(|e| Error::Other(format!("{e}; `clv inspect {}` says how to compute it again", dir.path.display())))?;
    let run = dir.path.display();
    report.earlier = true;
    report.notes = vec![if opts.streams() {
        format!("the backward sweep of {run} finished earlier and its frames went to the reader of that stream: this stream carries none; start it again without --resume for the frames")
    } else {
        let frames = match opts.frames_file(&dir.path) {
            Some(f) if f.exists() => format!("its frames are in {}; to write them again (a damaged file), move it aside and give the command without --resume", f.display()),
            Some(f) => format!("its frame file {} is gone (moved or deleted); give the command without --resume to write it again", f.display()),
            None => "it wrote no frame file".into(),
        };
        format!("the backward sweep of {run} finished earlier: nothing was recomputed, and this is its CLV spectrum; {frames}")
    }];
    Ok(report)
}

/// The sweep between segments: C, the accumulated local exponents and the statistics (what
/// the progress record keeps), and the buffers every step reuses.
struct Sweep<'a> {
    opts: &'a BackwardOptions,
    window: Window,
    d: usize,
    k: usize,
    tau: f64,
    par: faer::Par,
    c: Mat<f64>,
    acc: Accumulator,
    acc_gs: Option<Accumulator>,
    stats: BackwardStats,
    r: Mat<f64>,
    norms: Vec<f64>,
    /// The last frame handed out with V: once every consumer has dropped it, its buffers take
    /// the next such frame's V and G (no allocation per frame).
    spare: Option<Arc<Frame>>,
    /// Wall time of the sweep before this process continued it, and this process's start.
    wall_before: f64,
    started: Instant,
}

impl<'a> Sweep<'a> {
    /// The sweep at the run's last step (t_omega, beyond the window by the backward
    /// transient): C from `--c-init`, or where the interrupted sweep of the progress record
    /// `prior` (read from `progress_file`) left it; its wall time counts from `started`.
    fn start(opts: &'a BackwardOptions, window: Window, config: &RunConfig, prior: Option<&Progress>, progress_file: &Path, par: faer::Par, started: Instant) -> Result<Self> {
        let (d, k) = (config.system.dim(), config.vectors);
        let c = match prior {
            Some(p) => p.c_matrix(k).ok_or_else(|| {
                Error::corrupt(progress_file, format!("C holds {} numbers, not those of a {k} x {k} upper-triangular matrix; run without --resume to start over", p.c.len()))
            })?,
            None => initial_c(k, opts.c_init, config.seed),
        };
        let n_frames = window.last - window.first + 1;
        let acc = prior.map(|p| p.acc.clone()).unwrap_or_else(|| Accumulator::new(k, block_len(n_frames, config.blocks as u64)));
        let acc_gs = match prior {
            Some(p) => p.acc_gs.clone(),
            None => Some(Accumulator::new(k, acc.block_len)),
        };
        Ok(Sweep {
            opts,
            window,
            d,
            k,
            tau: config.tau,
            par,
            c,
            acc,
            acc_gs,
            stats: prior.map(|p| p.stats.clone()).unwrap_or_default(),
            r: Mat::zeros(k, k),
            norms: vec![0.0; k],
            spare: None,
            wall_before: prior.map_or(0.0, |p| p.stats.wall_seconds),
            started,
        })
    }

    /// Sweep down the `planned` segments the recomputation sends, syncing the frame file and
    /// saving the progress record after each. [`Flow::Stop`] when the consumer stopped the
    /// stream; an error when the recomputation failed or ended before its last segment.
    #[allow(clippy::too_many_arguments)]
    fn all_segments(
        &mut self,
        (rx, free_tx, producer): Segments,
        planned: u64,
        cores: &Cores,
        mut frame_file: Option<&mut FrameFile>,
        progress_file: &Path,
        run: &Path,
        consumer: &mut dyn FnMut(Arc<Frame>) -> Result<Flow>,
        on_progress: OnProgress,
    ) -> Result<Flow> {
        let swept_before = self.stats.segments;
        let mut flow = Flow::Continue;
        let mut failure = None;
        for segment in rx.iter() {
            cores.set_sweeping(true);
            let swept = segment.and_then(|seg| self.segment(&seg, frame_file.as_deref_mut(), consumer).map(|f| (seg, f)));
            let seg = match swept {
                Ok((_, Flow::Stop)) => {
                    flow = Flow::Stop;
                    break;
                }
                Ok((seg, Flow::Continue)) => seg,
                Err(e) => {
                    failure = Some(e);
                    break;
                }
            };
            on_progress(self.stats.recomputed_steps, self.stats.frames);
            if let Some(Err(e)) = frame_file.as_deref_mut().map(FrameFile::sync) {
                failure = Some(e);
                break;
            }
            self.clock();
            let at = seg.s0;
            let _ = free_tx.try_send(seg);
            if let Err(e) = self.record(at, false).save(progress_file) {
                failure = Some(e);
                break;
            }
            // The recomputation gets every thread only now: the record above is written on
            // this thread, and a spinning QR worker must not share its core.
            cores.set_sweeping(false);
        }
        // Both channels closed, so that a recomputation waiting to send a segment, or for a
        // buffer to recompute into, ends.
        drop((rx, free_tx));
        let joined = producer.join();
        if let Some(e) = failure {
            return Err(e);
        }
        // The recomputation ends early only with an error it sends, or by a bug: never take
        // its silence for the end of the window.
        let swept = self.stats.segments - swept_before;
        if flow == Flow::Continue && (joined.is_err() || swept < planned) {
            let why = match joined {
                Err(panic) => panic.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| panic.downcast_ref::<String>().cloned()).unwrap_or_default(),
                Ok(()) => "it stopped without an error".into(),
            };
            return Err(Error::Other(format!(
                "the recomputation of the run's segments failed after {swept} of {planned} segments ({why}); nothing was marked finished. \
                 Check the run with `clv inspect {}` (a damaged segment is recomputed by `clv forward --resume`), then give this command again with --resume",
                run.display()
            )));
        }
        Ok(flow)
    }

    /// Bring the sweep's wall time up to now.
    fn clock(&mut self) {
        self.stats.wall_seconds = self.wall_before + self.started.elapsed().as_secs_f64();
    }

    /// Sweep down one recomputed segment, newest step first: C_{n-1} = R_n^{-1} C_n at every
    /// step, and for each step in the window a frame (V_n = G_n C_n where it carries vectors),
    /// saved to `file` and handed to `consumer`. Stop when the consumer stops the stream.
    fn segment(&mut self, seg: &Segment, mut file: Option<&mut FrameFile>, consumer: &mut dyn FnMut(Arc<Frame>) -> Result<Flow>) -> Result<Flow> {
        let (d, k, tau) = (self.d, self.k, self.tau);
        let kk = k * (k + 1) / 2;
        self.stats.segments += 1;
        self.stats.recomputed_steps += seg.s1 - seg.s0;
        for n in (seg.s0 + 1..=seg.s1).rev() {
            let i = (n - seg.s0) as usize;
            unpack_upper_into(&seg.r[(i - 1) * kk..i * kk], &mut self.r);
            crate::linalg::ginelli_step(self.r.as_ref(), self.c.as_mut(), &mut self.norms, self.par);
            let m = n - 1;
            if m < self.window.first || m > self.window.last {
                continue;
            }
            let vectors = on_stride(m, self.opts.vectors_every);
            let (v, g) = if vectors {
                let g = seg
                    .g(m, d * k)
                    .ok_or_else(|| Error::Other(format!("the recomputed segment {}..{} lacks G_n of step {m} (a bug: please report it)", seg.s0, seg.s1)))?;
                let (mut v, recycled_g) = match self.spare.take().map(Arc::try_unwrap) {
                    Some(Ok(old)) => (old.v, old.g),
                    _ => (vec![0.0; d * k], None),
                };
                crate::linalg::mul_upper(MatMut::from_column_major_slice_mut(&mut v, d, k), MatRef::from_column_major_slice(g, d, k), self.c.as_ref(), self.par);
                let g = self.opts.with_gs.then(|| {
                    let mut buffer = recycled_g.unwrap_or_default();
                    buffer.clear();
                    buffer.extend_from_slice(g);
                    buffer
                });
                (v, g)
            } else {
                (Vec::new(), None)
            };
            // local CLV exponents, -ln |R_n^-1 c_j| / tau
            let local: Vec<f64> = self.norms.iter().map(|n| -n.ln() / tau).collect();
            // The CLV spectrum is the mean of the frames' local exponents (accumulated with
            // tau = 1), exactly as an analysis of the frame stream computes it.
            self.acc.add_logs(local.iter().copied());
            let ln_r: Vec<f64> = (0..k).map(|i| self.r[(i, i)].abs().ln()).collect();
            if let Some(acc_gs) = self.acc_gs.as_mut() {
                acc_gs.add_logs(ln_r.iter().copied());
            }
            let frame = Arc::new(Frame {
                step: m,
                time: m as f64 * tau,
                d,
                k,
                phase: seg.phase[(m - seg.s0) as usize * d..(m - seg.s0 + 1) as usize * d].to_vec(),
                v,
                local,
                gs_local: ln_r.iter().map(|l| l / tau).collect(),
                g,
            });
            if self.stats.frames == 0 {
                self.stats.last_frame_step = m;
            }
            self.stats.first_frame_step = m;
            if let Some(file) = file.as_mut()
                && on_stride(m, self.opts.save_every) {
                    file.write(&frame)?;
                }
            self.stats.frames += 1;
            if vectors {
                self.spare = Some(frame.clone());
            }
            if consumer(frame)? == Flow::Stop {
                return Ok(Flow::Stop);
            }
        }
        Ok(Flow::Continue)
    }

    /// The progress record of the sweep with C at step `at` (older end of the last segment).
    fn record(&self, at: u64, done: bool) -> Progress {
        Progress { options: self.opts.clone(), at, c: pack_upper(self.c.as_ref()), acc: self.acc.clone(), acc_gs: self.acc_gs.clone(), stats: self.stats.clone(), done }
    }
}

/// C at the end of the window: the identity, or a random upper-triangular matrix with
/// positive diagonal and unit columns.
fn initial_c(k: usize, init: CInit, seed: u64) -> Mat<f64> {
    match init {
        CInit::Identity => Mat::identity(k, k),
        CInit::Random => {
            let mut rng = Rng::new(seed ^ 0x0067_696e_656c_6c69);
            let mut c = Mat::zeros(k, k);
            for j in 0..k {
                for i in 0..=j {
                    c[(i, j)] = if i == j { 1.0 + rng.uniform() } else { rng.normal() };
                }
                let norm = c.col(j).norm_l2();
                c.col_mut(j).iter_mut().for_each(|x| *x /= norm);
            }
            c
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::progress::tests::record;

    /// The three kinds of sweep by their options: into a file, to a reader, and without
    /// frames (whose record names no file, and reads as such where an earlier build named
    /// the default file with --save-every 0); records without the field still read.
    #[test]
    fn a_sweep_without_frames_names_no_file_and_is_no_stream() {
        let run = Path::new("/runs/r");
        let file = BackwardOptions { frames_path: Some("frames.mcap".into()), ..record(Vec::new()).options };
        let stream = BackwardOptions { save_every: 0, ..record(Vec::new()).options };
        let none = BackwardOptions { no_frames: true, ..stream.clone() };
        let legacy = BackwardOptions { save_every: 0, ..file.clone() };
        assert_eq!(file.frames_file(run), Some(run.join("frames.mcap")));
        for (o, streams) in [(&stream, true), (&none, false), (&legacy, false)] {
            assert_eq!((o.frames_file(run), o.streams()), (None, streams), "{o:?}");
        }
        assert!(file.as_flags().starts_with("--out frames.mcap --save-every 1") && stream.as_flags().starts_with("--out - --save-every 0"));
        assert!(none.as_flags().starts_with("--save-every 0"), "{}", none.as_flags());
        let window = Window { first: 10, last: 20 };
        assert_eq!((window.frame_steps(&stream), window.frame_steps(&none), window.frame_steps(&legacy)), (Some((10, 20)), None, None));
        // Written only where set: the records of files and streams are as before.
        assert!(!stream.to_json().contains("no_frames") && none.to_json().contains("\"no_frames\":true"));
        let back: BackwardOptions = serde_json::from_str(&stream.to_json()).unwrap();
        assert_eq!(back, stream);
    }

    /// The frame file inside the run is recorded relative to it however both are spelled
    /// (`..`, a symbolic link to the run, a file not yet written), outside it absolute.
    #[test]
    fn frame_files_inside_the_run_are_recorded_relative_to_it() {
        let base = std::env::temp_dir().join(format!("clv-record-path-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let run = base.join("B");
        std::fs::create_dir_all(run.join("sub")).unwrap();
        std::os::unix::fs::symlink(&run, base.join("L")).unwrap();
        let rel = |r: &Path, f: &Path| BackwardOptions::record_frames_path(r, f).unwrap();
        for (r, f) in [
            (run.clone(), run.join("frames.mcap")),
            (base.join("L"), base.join("L/frames.mcap")),
            (run.clone(), base.join("L/frames.mcap")),
            (base.join("L"), run.join("sub/../frames.mcap")),
            (run.join("sub/.."), run.join("frames.mcap")),
        ] {
            assert_eq!(rel(&r, &f), Path::new("frames.mcap"), "{} in {}", f.display(), r.display());
        }
        assert!(rel(&run, &base.join("elsewhere.mcap")).is_absolute());
        std::fs::remove_dir_all(&base).unwrap();
    }

    /// A random C_0 is upper triangular with unit columns and a positive diagonal, like
    /// every C the iteration makes; the identity is one; the seed decides it.
    #[test]
    fn the_initial_c_is_a_normalised_upper_triangle() {
        let k = 7;
        let c = initial_c(k, CInit::Random, 3);
        for j in 0..k {
            let norm: f64 = (0..k).map(|i| c[(i, j)] * c[(i, j)]).sum::<f64>().sqrt();
            assert!((norm - 1.0).abs() < 1e-15 && c[(j, j)] > 0.0, "column {j}: norm {norm}");
            assert!((j + 1..k).all(|i| c[(i, j)] == 0.0), "column {j} below the diagonal");
            assert!(j == 0 || (0..j).any(|i| c[(i, j)] != 0.0), "column {j} is not the identity's");
        }
        assert_eq!(initial_c(k, CInit::Random, 3), c);
        assert_ne!(initial_c(k, CInit::Random, 4), c);
        assert_eq!(initial_c(k, CInit::Identity, 3), Mat::<f64>::identity(k, k));
    }
}
