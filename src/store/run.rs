//! The run directory: its description (run.json) and its segment files.

use super::segment::{self, parse_final_name};
use crate::config::{RunConfig, SystemConfig};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::fs;
use std::path::{Path, PathBuf};

pub const FORMAT: &str = "clv-run/1";

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StoreR {
    /// R_n at checkpoints only; the backward stage recomputes the rest.
    Checkpoints,
    /// R_n at every step of the CLV window as well, for readers outside clv
    /// (scripts/read_run.py); the backward stage recomputes them all the same and refuses a
    /// run whose stored R_n differ from the recomputed ones.
    All,
}

/// The settings in which two runs differ, as the flags that set them, each side named by its
/// label: "--steps 10000 in the run, 5000 asked for" (the thread count is no setting of a run).
pub fn differences((run, run_store, here): (&RunConfig, &StoreConfig, &str), (asked, asked_store, there): (&RunConfig, &StoreConfig, &str)) -> Vec<String> {
    let (ours, theirs) = (flag_values(run, run_store), flag_values(asked, asked_store));
    let mut out: Vec<String> = theirs
        .iter()
        .filter_map(|(id, want)| {
            let flag = id.replace('_', "-");
            match ours.iter().find(|(o, _)| o == id) {
                Some((_, have)) if have == want => None,
                Some((_, have)) => Some(format!("--{flag} {have} {here}, {want} {there}")),
                None => Some(format!("--{flag} {want} {there}, none {here}")),
            }
        })
        .collect();
    // Another system's own flags on this side (--lorenz-rho against a Henon run).
    out.extend(ours.iter().filter(|(id, _)| !theirs.iter().any(|(t, _)| t == id)).map(|(id, have)| format!("--{} {have} {here}, none {there}", id.replace('_', "-"))));
    if out.is_empty() {
        out.push("settings that flags do not show".into());
    }
    out
}

/// [`differences`] for a message: the system's first (it makes most of the others), then
/// at most three more, with how many are left out.
pub fn differences_summary(mut differ: Vec<String>) -> String {
    differ.sort_by_key(|d| !d.starts_with("--system "));
    match differ.len() {
        0..=4 => differ.join(", "),
        more => format!("{}, and {} more", differ[..3].join(", "), more - 3),
    }
}

/// The values of the flags that define a run, as they would be given on the command line,
/// by the flags' ids (--relax-steps is relax_steps).
pub fn flag_values(c: &RunConfig, store: &StoreConfig) -> Vec<(&'static str, String)> {
    let mut v = vec![
        ("tau", c.tau.to_string()),
        ("relax_steps", c.relax_steps.to_string()),
        ("steps", c.steps.to_string()),
        ("vectors", c.vectors.to_string()),
        ("seed", c.seed.to_string()),
        ("blocks", c.blocks.to_string()),
        ("checkpoint_every", store.checkpoint_every.to_string()),
        ("segment_checkpoints", store.segment_checkpoints.to_string()),
        ("segment_mb", (store.segment_bytes >> 20).to_string()),
        ("store_r", match store.store_r {
            StoreR::Checkpoints => "checkpoints".into(),
            StoreR::All => "all".into(),
        }),
        ("clv_steps", store.clv_steps.to_string()),
        ("transient", store.transient.to_string()),
    ];
    match &c.system {
        SystemConfig::Henon { a, b } => v.extend([("system", "henon".into()), ("henon_a", a.to_string()), ("henon_b", b.to_string())]),
        SystemConfig::Lorenz { sigma, rho, beta } => v.extend([
            ("system", "lorenz".into()),
            ("lorenz_sigma", sigma.to_string()),
            ("lorenz_rho", rho.to_string()),
            ("lorenz_beta", beta.to_string()),
        ]),
        SystemConfig::Disks { n, lx, ly, density, aspect } => v.extend([
            ("system", "disks".into()),
            ("n", n.to_string()),
            ("lx", lx.to_string()),
            ("ly", ly.to_string()),
            ("density", density.to_string()),
            ("aspect", aspect.to_string()),
        ]),
    }
    v
}

/// How a run is laid out on disk and what is kept.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StoreConfig {
    /// Steps between checkpoints (the paper's 100 tau).
    pub checkpoint_every: u64,
    /// Checkpoints per segment file.
    pub segment_checkpoints: u64,
    /// A segment is also closed once it holds this many bytes of messages.
    pub segment_bytes: u64,
    pub store_r: StoreR,
    /// The length of the CLV window in steps: covariant vectors are wanted at its
    /// clv_steps + 1 steps, both ends included ([`crate::stage::backward::Window`]), which end
    /// `transient` steps before the run's last.
    pub clv_steps: u64,
    /// Steps of the backward sweep discarded as transient, before the CLV window.
    pub transient: u64,
    /// Segments kept before the window (for resuming), older ones are pruned.
    pub keep_segments: u64,
}

impl StoreConfig {
    /// The defaults for a run: checkpoints every 100 steps (a shorter run's only at its
    /// ends), 10 per segment, the CLV window
    /// a tenth of relax-steps + steps, at most 2/3 of steps (the paper's window is the last
    /// tenth of its run), a transient of half that.
    pub fn for_run(config: &RunConfig) -> Self {
        // The paper's window: the last tenth of the run (2.5e4 of 2.5e5 steps), inside the
        // accumulated steps.
        let clv_steps = ((config.relax_steps + config.steps) / 10).min(config.steps * 2 / 3).max(1);
        StoreConfig {
            checkpoint_every: config.relax_steps.saturating_add(config.steps).clamp(1, 100),
            segment_checkpoints: 10,
            segment_bytes: 1 << 30,
            store_r: StoreR::Checkpoints,
            clv_steps,
            transient: Self::transient_for(clv_steps),
            keep_segments: 2,
        }
    }

    /// The default backward transient of a CLV window of `clv_steps`: half as many steps again
    /// for C to converge (the paper's 2.5e4 window with its transient, of 2.5e5 steps).
    pub fn transient_for(clv_steps: u64) -> u64 {
        (clv_steps / 2).max(1)
    }

    pub fn validate(&self, config: &RunConfig) -> Result<()> {
        if self.checkpoint_every == 0 {
            return Err(Error::param("checkpoint-every", "must be at least 1"));
        }
        let total = config.relax_steps + config.steps;
        if self.checkpoint_every > total {
            return Err(Error::param("checkpoint-every", format!(
                "{} is longer than the whole run ({total} steps, relaxation included); choose at most {total}",
                self.checkpoint_every
            )));
        }
        if self.segment_checkpoints == 0 {
            return Err(Error::param("segment-checkpoints", "must be at least 1"));
        }
        let needed = self.clv_steps.saturating_add(self.transient);
        if needed > config.steps {
            // More steps only where a run can have that many (2^53 with the relaxation).
            let more = if needed <= (1u64 << 53).saturating_sub(config.relax_steps) { format!("give --steps {needed} or more, or ") } else { "give ".into() };
            return Err(Error::param("clv-steps", format!(
                "the CLV window ({}) plus the backward transient ({}) must fit in the accumulated --steps ({}); {more}a shorter --clv-steps and --transient \
                 (by default a tenth of the run and half that; --transient 0 discards none)",
                self.clv_steps, self.transient, config.steps
            )));
        }
        Ok(())
    }

    /// First step of the part of the run the backward stage needs (transient + window).
    pub fn window_start(&self, config: &RunConfig) -> u64 {
        let total = config.relax_steps + config.steps;
        total - self.clv_steps - self.transient
    }

    /// The checkpoint the backward stage recomputes its first segment from (at or before
    /// [`StoreConfig::window_start`]): segments that end before it are prunable.
    pub fn first_needed_checkpoint(&self, config: &RunConfig) -> u64 {
        let c = self.checkpoint_every.max(1);
        self.window_start(config) / c * c
    }

    /// Steps at which checkpoints are written: 0, C, 2C, ... and always the last step.
    pub fn is_checkpoint(&self, step: u64, total: u64) -> bool {
        step.is_multiple_of(self.checkpoint_every) || step == total
    }

    /// The last step before `step` at which the forward stage writes anything (a checkpoint,
    /// or an R_n of the window with `--store-r all`): where the segment before one beginning
    /// at `step` ends, at the latest.
    pub fn last_write_before(&self, step: u64, config: &RunConfig) -> u64 {
        let before = step.saturating_sub(1);
        if self.store_r == StoreR::All && before > self.window_start(config) {
            before
        } else {
            before / self.checkpoint_every.max(1) * self.checkpoint_every.max(1)
        }
    }

    /// Bytes a checkpoint (with its R and stats) takes before compression.
    pub fn checkpoint_bytes(&self, config: &RunConfig) -> u64 {
        // In f64: a system too large for any disk must still get a number (saturated), not a
        // wrapped one.
        let (d, k) = (config.system.dim() as f64, config.vectors as f64);
        // A run of fewer steps than --blocks has one block per step.
        let blocks = (config.blocks as u64).min(config.steps) as f64 + 1.0;
        (8.0 * (d * k + d + k * (3.0 + blocks)) + 4.0 * k * (k + 1.0) + 8.0 * 3.0 * k + 600.0) as u64
    }

    /// Estimated disk footprint of the finished run: pruning removes whole segments, so the
    /// segment holding the window's first step is kept whole, from the start of its span of
    /// `segment_checkpoints` checkpoints (up to that many - 1 more than the window needs),
    /// and `keep_segments` whole segments before it. Segments of a resumed run, or closed
    /// early by `segment_bytes`, start elsewhere: the estimate is then off by less than a
    /// segment.
    pub fn footprint(&self, config: &RunConfig) -> Footprint {
        let per_checkpoint = self.checkpoint_bytes(config);
        let window = self.clv_steps + self.transient;
        let total = config.relax_steps + config.steps;
        let span = self.checkpoint_every.saturating_mul(self.segment_checkpoints).max(1);
        let first_kept = total.saturating_sub(window) / span * span;
        let kept = (total - first_kept).div_ceil(self.checkpoint_every) + 1 + self.keep_segments * self.segment_checkpoints;
        let total_cps = total.div_ceil(self.checkpoint_every) + 1;
        let checkpoints = kept.min(total_cps);
        let k = config.vectors as u64;
        let r_all = if self.store_r == StoreR::All { window.saturating_mul(4 * k).saturating_mul(k + 1) } else { 0 };
        Footprint { bytes: checkpoints.saturating_mul(per_checkpoint).saturating_add(r_all), checkpoints, per_checkpoint, r_all, r_steps: window }
    }
}

/// What a finished run keeps on disk ([`StoreConfig::footprint`]); its Display explains it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    pub bytes: u64,
    /// Checkpoints kept, each of `per_checkpoint` bytes (with its R and statistics).
    pub checkpoints: u64,
    pub per_checkpoint: u64,
    /// Bytes of the R_n of `r_steps` steps (--store-r all; 0 otherwise).
    pub r_all: u64,
    pub r_steps: u64,
}

impl std::fmt::Display for Footprint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "about {} on disk: {} checkpoints of {} kept", human(self.bytes), self.checkpoints, human(self.per_checkpoint))?;
        if self.r_all > 0 {
            write!(f, " + {} of R matrices for {} steps (--store-r all)", human(self.r_all), self.r_steps)?;
        }
        Ok(())
    }
}

/// Bytes free for an unprivileged user on the file system that holds `path` (or would hold
/// it: its nearest existing ancestor); None where it cannot be found out.
pub fn free_bytes(path: &Path) -> Option<u64> {
    if let Some(fake) = super::fault::fake_free_bytes() {
        return Some(fake);
    }
    let existing = path.ancestors().find(|p| !p.as_os_str().is_empty() && p.exists()).unwrap_or(Path::new("."));
    statvfs_free(existing)
}

#[cfg(unix)]
fn statvfs_free(path: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).ok()?;
    let mut st = std::mem::MaybeUninit::<libc::statvfs>::uninit();
    // SAFETY: `c` is a NUL-terminated path and `st` is written by statvfs before it is read.
    let st = unsafe { (libc::statvfs(c.as_ptr(), st.as_mut_ptr()) == 0).then(|| st.assume_init())? };
    Some((st.f_bavail as u64).saturating_mul(st.f_frsize as u64))
}

#[cfg(not(unix))]
fn statvfs_free(_: &Path) -> Option<u64> {
    None
}

/// Less space free where a file is written than it will need: see [`short_of_space`].
#[derive(Clone, Debug, PartialEq)]
pub struct ShortOfSpace {
    pub path: PathBuf,
    pub needed: u64,
    pub free: u64,
}

impl std::fmt::Display for ShortOfSpace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "warning: this needs about {} on disk, and the file system of {} has {} free; when it fills, the stage stops cleanly, and once there is space it continues where it stopped (the message then says how)",
            human(self.needed),
            self.path.display(),
            human(self.free)
        )
    }
}

/// `Some` when `needed` bytes will not fit in the free space where `path` is written (None
/// also where the free space cannot be found out).
pub fn short_of_space(path: &Path, needed: u64) -> Option<ShortOfSpace> {
    let free = free_bytes(path)?;
    (free < needed).then(|| ShortOfSpace { path: path.to_path_buf(), needed, free })
}

/// Whether a finished segment reads whole with every CRC checked. Read only where a
/// segment's copy of run.json is about to be believed against run.json.
fn reads_whole(path: &Path) -> bool {
    segment::read_segment(path, segment::ReadMode::Strict, |_| Ok(())).is_ok()
}

pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e12 {
        format!("{:.2} TB", b / 1e12)
    } else if b >= 1e9 {
        format!("{:.2} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.1} MB", b / 1e6)
    } else {
        format!("{:.0} kB", (b / 1e3).ceil())
    }
}

/// Identifies the floating-point path of the dynamics and the QR step; changed whenever an
/// edit changes the bits a run produces (block sizes, operation order).
///
/// Flushing subnormal numbers to zero in the linear algebra (linalg::FlushSubnormals) kept
/// the identifier: forward and backward runs of the paper's system (N = 198, 220 steps, two
/// threads) gave the same bits with and without it, and where a true subnormal would make
/// them differ, the backward stage's bitwise check of every recomputed segment says so.
pub const NUMERICS: &str = "clv-numerics/3 (QR: blocked Householder in 32-column panels, 64-column chunks, any thread count; tangent replay in 32-column blocks)";

/// Facts about the build that determine the bits of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BuildInfo {
    pub clv_version: String,
    /// See [`NUMERICS`].
    #[serde(default)]
    pub numerics: String,
    pub arch: String,
    /// CPU features faer dispatches on (recorded for the reader; [`BuildInfo::simd_level`]
    /// is what must match for a run to continue).
    pub cpu_features: Vec<String>,
}

impl BuildInfo {
    pub fn current() -> Self {
        let mut cpu_features = Vec::new();
        #[cfg(target_arch = "x86_64")]
        {
            // Each named once (the std macro takes a literal token); AVX2, FMA and AVX-512
            // first, as earlier builds listed them, then the rest of the x86-64-v2 and -v3
            // sets, which decide faer's (pulp's) code paths ([`BuildInfo::simd_level`]).
            macro_rules! probe {
                ($($name:tt),*) => { $(if std::arch::is_x86_feature_detected!($name) { cpu_features.push($name.to_string()); })* };
            }
            probe!("avx2", "fma", "avx512f", "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "bmi1", "bmi2", "lzcnt");
        }
        BuildInfo { clv_version: env!("CARGO_PKG_VERSION").into(), numerics: NUMERICS.into(), arch: std::env::consts::ARCH.into(), cpu_features }
    }

    /// Refuse to continue a run whose bits this build and machine cannot reproduce: the
    /// continuation would not match the stored part, and the backward stage's bitwise check
    /// would reject the mixed run later.
    pub fn check_can_continue(&self, run: &Path) -> Result<()> {
        match self.differs_here() {
            None => Ok(()),
            Some(what) => Err(Error::Other(format!(
                "{}: the run was made by another build or on another kind of CPU ({what}); continuing it here would not reproduce its numbers bit for bit. \
                 Continue it with the build and kind of machine that started it, or start a new run",
                run.display()
            ))),
        }
    }

    /// How this build and machine differ from the ones that made the run, where that can change
    /// its bits: the numerics, the architecture, or [`BuildInfo::simd_level`].
    pub fn differs_here(&self) -> Option<String> {
        let here = BuildInfo::current();
        if self.numerics != here.numerics {
            Some(format!("its numerics are {:?}, this build's are {:?}", self.numerics, here.numerics))
        } else if self.arch != here.arch || self.simd_level() != here.simd_level() {
            Some(format!(
                "it ran on {} with {:?} ({}), this machine is {} with {:?} ({})",
                self.arch,
                self.cpu_features,
                self.simd_level(),
                here.arch,
                here.cpu_features,
                here.simd_level()
            ))
        } else {
            None
        }
    }

    /// The level of x86-64 instruction sets that decides the bits: faer's SIMD code (pulp)
    /// takes its x86-64-v3 paths (AVX2, FMA, BMI1/2, LZCNT and the v2 set), its v2 paths, or
    /// scalar ones, which add in other orders; so do glibc's ln and exp with and without FMA.
    /// AVX-512 is left out: in this build (faer without its `nightly` feature) only faer's
    /// matrix products dispatch on it, to kernels that give the AVX2 kernels' bits at twice
    /// their speed (`avx512_and_avx2_products_agree_bit_for_bit`), so a run continues on a
    /// node with or without it. Records of builds before the v2/v3 sets were listed name only
    /// AVX2 and FMA: there both stand for v3.
    pub fn simd_level(&self) -> &'static str {
        const V3: [&str; 6] = ["avx", "avx2", "bmi1", "bmi2", "fma", "lzcnt"];
        let has = |f: &str| self.cpu_features.iter().any(|g| g == f);
        if self.cpu_features.is_empty() {
            ""
        } else if self.is_earlier_record() {
            if has("avx2") && has("fma") { "x86-64-v3" } else { "below x86-64-v3 (not recorded further)" }
        } else if V2_FEATURES.iter().chain(&V3).all(|f| has(f)) {
            "x86-64-v3"
        } else if V2_FEATURES.iter().all(|f| has(f)) {
            "x86-64-v2"
        } else {
            "below x86-64-v2"
        }
    }

    /// Whether the CPU this record was made on had the features `here` has, as far as the
    /// record lists them (a record of an earlier build lists AVX2, FMA and AVX-512 only).
    pub fn same_cpu_features(&self, here: &BuildInfo) -> bool {
        let listed = |f: &&String| !self.is_earlier_record() || EARLIER_FEATURES.contains(&f.as_str());
        here.cpu_features.iter().filter(listed).eq(self.cpu_features.iter())
    }

    /// A record of a build before the x86-64-v2 set was listed ([`EARLIER_FEATURES`] only).
    fn is_earlier_record(&self) -> bool {
        !self.cpu_features.iter().any(|f| V2_FEATURES.contains(&f.as_str()))
    }
}

/// The CPU features earlier builds recorded.
const EARLIER_FEATURES: [&str; 3] = ["avx2", "fma", "avx512f"];
/// The x86-64-v2 set beyond the baseline.
const V2_FEATURES: [&str; 5] = ["sse3", "ssse3", "sse4.1", "sse4.2", "popcnt"];

/// Everything that says how a run was made (run.json).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunMeta {
    pub format: String,
    pub config: RunConfig,
    pub store: StoreConfig,
    pub build: BuildInfo,
}

impl RunMeta {
    /// Whether `other` describes the same trajectory: everything but the run's length, its
    /// CLV window and the threads, which extending a run or moving it to another machine
    /// changes.
    pub fn same_trajectory(&self, other: &RunMeta) -> bool {
        let fixed = |m: &RunMeta| (m.format.clone(), RunConfig { steps: 0, threads: 1, ..m.config.clone() }, m.store.checkpoint_every);
        fixed(self) == fixed(other)
    }
}

/// A finished segment file.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentFile {
    pub path: PathBuf,
    pub first: u64,
    pub last: u64,
    pub bytes: u64,
}

impl SegmentFile {
    /// What is wrong with a segment whose steps are not those its name says, or None when
    /// they are. `held`: the steps of its first message and of its last checkpoint (which the
    /// writer names it by), None for a file without a checkpoint. Readers go by the names
    /// ([`super::checkpoints`], the gaps a repair looks for), so a file renamed, or copied in
    /// under another name, would send them to the wrong steps: it counts as damaged.
    pub fn misnamed(&self, held: Option<(u64, u64)>) -> Option<String> {
        let holds = match held {
            Some(steps) if steps == (self.first, self.last) => return None,
            Some((a, b)) => format!("holds steps {a}..{b}"),
            None => "holds no checkpoint".into(),
        };
        Some(format!("{}: it {holds}, not steps {}..{} as its name says (renamed, or copied in under another name)", self.path.display(), self.first, self.last))
    }

    /// With `--store-r all`, the step after which the run that wrote this segment stored
    /// every step's R_n (its window's start), from the run.json the segment carries; None
    /// for a run that stores R_n at checkpoints only, or where the copy cannot be read. A run
    /// made longer moves its window: the segments written before keep the old one.
    pub fn r_every_step_from(&self) -> Option<u64> {
        let meta = serde_json::from_str::<RunMeta>(&super::segment::embedded_run_json(&self.path)?).ok()?;
        (meta.store.store_r == StoreR::All).then(|| meta.store.window_start(&meta.config))
    }
}

/// The step after which both of two consecutive segments' runs stored every step's R_n
/// (see [`gap_between`]), None where either did not.
pub fn r_every_step_between(a: &SegmentFile, b: &SegmentFile) -> Option<u64> {
    Some(a.r_every_step_from()?.max(b.r_every_step_from()?))
}

/// Whether steps are missing between a segment that ends at `last` and the next one, which
/// begins at `first`. It must begin at the next step the run wrote: the checkpoint after
/// `last`, or with `--store-r all` the step after it once `last` is at or past `r_from`, the
/// window's start after which every step's R_n is stored (before it, the step after the start) ([`SegmentFile::r_every_step_from`]);
/// or earlier, at the checkpoint of its own that a stop on a signal wrote (off the grid of
/// every `checkpoint_every` steps) before the next one was due. One that begins at or
/// before `last` overlaps it, which leaves nothing missing.
pub fn gap_between(last: u64, first: u64, checkpoint_every: u64, r_from: Option<u64>) -> bool {
    first > next_write_after(last, checkpoint_every, r_from)
}

/// The first step after `last` at which the run writes anything (see [`gap_between`]).
pub fn next_write_after(last: u64, checkpoint_every: u64, r_from: Option<u64>) -> u64 {
    let c = checkpoint_every.max(1);
    let next = (last / c + 1) * c;
    match r_from {
        // The first R_n of the window is that of the step after its start.
        Some(window) => next.min(last.max(window) + 1),
        None => next,
    }
}

pub struct RunDir {
    pub path: PathBuf,
}

/// Exclusive right to write a run directory, held while a stage writes it: an OS file lock
/// on RUN_DIR/.lock ([`super::lock`]), which stays in place.
pub type RunLock = super::lock::WriteLock;

impl RunDir {
    /// Where an extension keeps the results of the run as it was with `steps` steps.
    pub fn previous_results(&self, steps: u64) -> PathBuf {
        self.path.join(format!("previous-{steps}-steps"))
    }

    /// Whether an extension of the run as it is with `steps` steps was cut off after it
    /// began to move the run's results aside ([`RunDir::archive_results`] moves
    /// spectrum.json first) and before its new run.json was in place.
    pub fn extension_interrupted(&self, steps: u64) -> bool {
        !self.spectrum_path().exists() && self.previous_results(steps).join("spectrum.json").exists()
    }

    /// Whether `name`, a file name in the run directory, is one of [`RunDir::previous_results`].
    pub fn is_previous_results(name: &std::ffi::OsStr) -> bool {
        name.to_string_lossy().starts_with("previous-")
    }

    /// Move what the stages wrote about the run as it was (its spectrum, and the backward
    /// stage's files) and `also` into `to`; `to`, if it holds anything. A move cut short is
    /// finished by the next call (each file is renamed whole); a file that would replace one
    /// already there stops it.
    pub fn archive_results(&self, to: &Path, also: &[&Path]) -> Result<Option<PathBuf>> {
        let frames = self.frames_path();
        let names = [self.clv_spectrum_path(), self.progress_path(), super::frames::tmp_path(&frames), frames];
        // spectrum.json first: once it is gone, the run is known to be in the middle of an
        // extension ([`RunDir::extension_interrupted`]), and is not finished at its old length.
        // Then `also`: the frame files a record names go before the record (backward.json),
        // so that a move cut short still finds them the next time. The CLV spectra of earlier
        // sweeps with other options describe the shorter run too.
        let mut present: Vec<PathBuf> = Vec::new();
        for p in std::iter::once(self.spectrum_path()).chain(also.iter().map(|p| p.to_path_buf())).chain(names).chain(self.earlier_clv_spectra()) {
            if p.exists() && !present.contains(&p) {
                present.push(p);
            }
        }
        if !present.is_empty() {
            std::fs::create_dir_all(to).map_err(|e| Error::io(to, e))?;
        }
        for from in present {
            let dest = to.join(from.file_name().unwrap_or_default());
            if dest.exists() {
                return Err(Error::Other(format!(
                    "{} and {} both exist; move one of them out of the way, then extend the run again",
                    from.display(),
                    dest.display()
                )));
            }
            std::fs::rename(&from, &dest).map_err(|e| Error::io(&from, e))?;
            super::fault::crash_point("result-moved");
        }
        if to.exists() {
            super::segment::sync_dir(to)?;
        }
        super::segment::sync_dir(&self.path)?;
        Ok(to.exists().then(|| to.to_path_buf()))
    }

    pub fn meta_path(&self) -> PathBuf {
        self.path.join("run.json")
    }
    /// Where `clv backward` writes its frames unless told otherwise.
    pub fn frames_path(&self) -> PathBuf {
        self.path.join("frames.mcap")
    }
    pub fn spectrum_path(&self) -> PathBuf {
        self.path.join("spectrum.json")
    }
    /// The backward stage's record of its last sweep: options, progress, C to resume from.
    pub fn progress_path(&self) -> PathBuf {
        self.path.join("backward.json")
    }
    /// The CLV spectrum of the last backward sweep.
    pub fn clv_spectrum_path(&self) -> PathBuf {
        self.path.join("clv_spectrum.json")
    }
    /// The CLV spectrum of the `i`-th earlier sweep with other options, kept beside it.
    pub fn earlier_clv_spectrum_path(&self, i: usize) -> PathBuf {
        self.path.join(format!("clv_spectrum-{i}.json"))
    }
    /// Those of [`RunDir::earlier_clv_spectrum_path`] that exist.
    pub fn earlier_clv_spectra(&self) -> Vec<PathBuf> {
        let mut found: Vec<PathBuf> = fs::read_dir(&self.path)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.strip_prefix("clv_spectrum-").and_then(|n| n.strip_suffix(".json")).is_some_and(|i| i.parse::<usize>().is_ok())))
            .collect();
        found.sort();
        found
    }

    /// Create a new run directory (it must not exist, or be empty) and lock it for the
    /// `what`: the lock is taken before run.json is written, so that of two processes
    /// creating the same directory at once, one is refused before it writes anything.
    pub fn create(path: &Path, meta: &RunMeta, what: &str) -> Result<(Self, RunLock)> {
        // Asked first too, so that a refusal writes nothing (not even the lock file) into a
        // directory that holds something else; asked again under the lock, where it is sure.
        Self::check_empty(path, what)?;
        fs::create_dir_all(path).map_err(|e| Error::io(path, e))?;
        let dir = RunDir { path: path.to_path_buf() };
        let lock = dir.lock(what)?;
        Self::check_empty(path, what)?;
        write_atomic(&dir.meta_path(), &super::checked_json::to_vec(meta)?)?;
        Ok((dir, lock))
    }

    /// Refuse a directory that holds anything but what a creation cut short before run.json
    /// was in place leaves: its lock file and run.json's temporary file. Not empty because
    /// another process is creating the run there now, it is refused as a second writer.
    pub fn check_empty(path: &Path, what: &str) -> Result<()> {
        if !path.exists() {
            return Ok(());
        }
        let leftover = [path.join("run.tmp"), path.join(".lock")];
        let mut entries = fs::read_dir(path).map_err(|e| Error::io(path, e))?.filter(|e| !e.as_ref().is_ok_and(|e| leftover.contains(&e.path())));
        if entries.next().is_some() {
            super::lock::refuse_if_held(&path.join(".lock"), path, what)?;
            let what_is_there = if path.join("run.json").exists() {
                format!("it holds a run: continue it with `clv forward --resume {}`", path.display())
            } else {
                "it holds files of something other than a run".to_string()
            };
            return Err(Error::Other(format!("{} already exists and is not empty ({what_is_there}); choose another --out, or an empty or new directory", path.display())));
        }
        Ok(())
    }

    /// Complete a creation cut short between writing run.json's temporary file and renaming
    /// it into place: true if run.json was missing and its temporary file was whole (and is
    /// now run.json), false if there was nothing to complete. A partial temporary file means
    /// nothing of the run was computed; the error says to start it again.
    pub fn complete_creation(path: &Path) -> Result<bool> {
        let dir = RunDir { path: path.to_path_buf() };
        let (meta_path, tmp) = (dir.meta_path(), path.join("run.tmp"));
        if meta_path.exists() || !tmp.exists() {
            return Ok(false);
        }
        // Not while a process creating the run is between writing run.tmp and renaming it.
        let _lock = dir.lock("forward pass")?;
        if meta_path.exists() || !tmp.exists() {
            return Ok(false);
        }
        let bytes = fs::read(&tmp).map_err(|e| Error::io(&tmp, e))?;
        if super::checked_json::from_slice::<RunMeta>(&tmp, &bytes).is_err() {
            return Err(Error::Other(format!(
                "the run in {} was interrupted while it was being created ({} is incomplete) and holds no results; start it again with `clv forward --out {} ...`",
                path.display(),
                tmp.display(),
                path.display()
            )));
        }
        fs::rename(&tmp, &meta_path).map_err(|e| Error::io(&meta_path, e))?;
        segment::sync_dir(path)?;
        Ok(true)
    }

    /// Whether a process holds the run's write lock now (a forward or backward pass). Asks
    /// without taking it; false where the file system cannot lock.
    pub fn is_being_written(&self) -> bool {
        super::lock::is_held(&self.path.join(".lock"))
    }

    /// Take the run's write lock, or explain who holds it ([`super::lock`]).
    pub fn lock(&self, what: &str) -> Result<RunLock> {
        let path = self.path.join(".lock");
        super::lock::take(&path, &self.path, what, false, |e| match e.kind() {
            std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::ReadOnlyFilesystem => Error::Other(format!(
                "{} is not writable ({e}), and the {what} writes into it (its lock, progress record and results); copy the run to a place you can write (`cp -r`) and run it there",
                self.path.display()
            )),
            _ => Error::io(&path, e),
        })
    }

    pub fn open(path: &Path) -> Result<(Self, RunMeta)> {
        if path.is_file() {
            return Err(Error::Other(format!(
                "{} is a file, but a run directory (written by `clv forward --out DIR`) is expected here",
                path.display()
            )));
        }
        let dir = RunDir { path: path.to_path_buf() };
        let meta_path = dir.meta_path();
        let bytes = match fs::read(&meta_path) {
            Ok(bytes) => bytes,
            // Deleted by hand: the segments still hold copies of it.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && dir.segments().is_ok_and(|s| !s.is_empty()) => {
                return Err(dir.unreadable_meta(format!("it is missing ({e}), though the directory holds run segments")));
            }
            // Killed while it was created, between writing run.tmp and renaming it.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && path.join("run.tmp").exists() => {
                return Err(Error::Other(format!(
                    "{}: {e}: the run was interrupted while it was being created (its run.tmp is there); `clv forward --resume {}` completes it",
                    meta_path.display(),
                    path.display()
                )));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && !path.exists() => {
                return Err(Error::Other(format!("{} does not exist; give a run directory written by `clv forward --out`", path.display())));
            }
            Err(e) => return Err(Error::Other(format!("{}: {e}; is {} a run directory written by `clv forward --out`?", meta_path.display(), path.display()))),
        };
        // Damaged or edited (its checksum), a run.json can no longer be trusted with any
        // field: the build it names as much as the trajectory.
        let meta: RunMeta = match super::checked_json::from_slice(&meta_path, &bytes) {
            Ok((meta, super::checked_json::Seal::Checked)) => meta,
            // Without its checksum (an earlier build's, or the field removed by an edit), it
            // must at least say what the newest segment's copy says.
            Ok((meta, super::checked_json::Seal::Absent)) => match dir.newest_segment_meta() {
                Some(theirs) if !(theirs.config.same_but_threads(&meta.config) && theirs.store == meta.store) => {
                    return Err(dir.unreadable_meta("it carries no checksum (crc32), and it differs from the copy in the newest segment: the field was removed by an edit".into()));
                }
                _ => meta,
            },
            Err(Error::Corrupt { msg, .. }) => return Err(dir.unreadable_meta(msg)),
            Err(e) => return Err(dir.unreadable_meta(e.to_string())),
        };
        if meta.format != FORMAT {
            return Err(Error::corrupt(&meta_path, format!("format {:?}, this clv reads {FORMAT:?}", meta.format)));
        }
        // A run.json of an earlier build (without a checksum) is checked like a new run's
        // settings: the stages' arithmetic assumes them (a window inside the run, say).
        if let Err(e) = meta.config.validate().and_then(|()| meta.store.validate(&meta.config)) {
            return Err(Error::corrupt(&meta_path, format!("its settings are not those of a run clv writes ({e}): it was edited or damaged")));
        }
        Ok((dir, meta))
    }

    /// The run.json the newest intact segment with a readable copy was written with.
    fn newest_segment_meta(&self) -> Option<RunMeta> {
        self.segments().ok()?.iter().rev().find_map(|s| {
            let theirs = serde_json::from_str::<RunMeta>(&segment::embedded_run_json(&s.path)?).ok()?;
            reads_whole(&s.path).then_some(theirs)
        })
    }

    /// A run.json that does not parse (cut short, damaged): the newest segment's copy is put
    /// beside it, to restore it from, where there is one.
    fn unreadable_meta(&self, why: String) -> Error {
        let copy = self.path.join("run.json.from-segments");
        let restored = self.newest_segment_meta().and_then(|theirs| write_atomic(&copy, &super::checked_json::to_vec(&theirs).ok()?).ok());
        let way_out = match restored {
            Some(()) => format!("every segment holds a copy of it, and the newest one's is now in {}: move it over run.json to continue this run", copy.display()),
            None => "no segment holds a readable copy of it (the run wrote none yet): start the run again".into(),
        };
        Error::corrupt(self.meta_path(), format!("{why}; {way_out}"))
    }

    pub fn meta_json(meta: &RunMeta) -> String {
        serde_json::to_string(meta).unwrap_or_default()
    }

    /// Refuse a run.json that no longer describes the run its segments hold (edited by
    /// hand, or damaged): every finished segment carries the run.json it was written with.
    /// The copy of the newest one that disagrees is put beside it, to restore it from.
    ///
    /// Where other segments agree with run.json, the ones that disagree are the odd ones
    /// out (copied in from another run), and they are named instead. A segment that
    /// disagrees is evidence only if it reads whole: a flipped bit in its copy fails its
    /// CRC, and it is then a damaged segment, which `clv forward --resume` recomputes.
    pub fn check_meta(&self, meta: &RunMeta) -> Result<()> {
        let mut agreeing = 0;
        let mut foreign = Vec::new();
        for seg in self.segments()?.iter().rev() {
            let Some(json) = segment::embedded_run_json(&seg.path) else { continue };
            let Ok(theirs) = serde_json::from_str::<RunMeta>(&json) else { continue };
            if meta.same_trajectory(&theirs) {
                agreeing += 1;
            } else if reads_whole(&seg.path) {
                foreign.push((seg.clone(), theirs));
            }
        }
        if agreeing > 0 && !foreign.is_empty() {
            let names: Vec<String> = foreign.iter().map(|(s, _)| s.path.display().to_string()).collect();
            return Err(Error::Other(format!(
                "{} {} written for another run than run.json and the other {agreeing} segments describe ({}): {} not this run's; move {} out of {} (`clv forward --resume` then recomputes what is missing)",
                if names.len() == 1 { "segment" } else { "segments" },
                names.join(", "),
                serde_json::to_string(&foreign[0].1.config).unwrap_or_default(),
                if names.len() == 1 { "it is" } else { "they are" },
                if names.len() == 1 { "it" } else { "them" },
                self.path.display()
            )));
        }
        if let Some((seg, theirs)) = foreign.into_iter().next() {
            let seg = &seg;
            let copy = self.path.join("run.json.from-segments");
            write_atomic(&copy, &super::checked_json::to_vec(&theirs)?)?;
            let show = |m: &RunMeta| serde_json::to_string(&m.config).unwrap_or_default();
            return Err(Error::corrupt(
                self.meta_path(),
                format!(
                    "it describes another run ({}) than the one {} was written for ({}); run.json was edited or damaged. \
                     The segment's copy is in {}: move it over run.json to continue this run",
                    show(meta),
                    seg.path.display(),
                    show(&theirs),
                    copy.display()
                ),
            ));
        }
        Ok(())
    }

    /// Finished segments, oldest first.
    pub fn segments(&self) -> Result<Vec<SegmentFile>> {
        let mut out = Vec::new();
        for entry in fs::read_dir(&self.path).map_err(|e| Error::io(&self.path, e))? {
            let entry = entry.map_err(|e| Error::io(&self.path, e))?;
            let name = entry.file_name().to_string_lossy().to_string();
            if let Some((first, last)) = parse_final_name(&name) {
                let bytes = entry.metadata().map(|m| m.len()).unwrap_or(0);
                out.push(SegmentFile { path: entry.path(), first, last, bytes });
            }
        }
        out.sort_by_key(|s| s.first);
        Ok(out)
    }

    /// Leftover `.tmp` segments (interrupted writes).
    pub fn partial_segments(&self) -> Result<Vec<PathBuf>> {
        let mut out = Vec::new();
        for entry in fs::read_dir(&self.path).map_err(|e| Error::io(&self.path, e))? {
            let entry = entry.map_err(|e| Error::io(&self.path, e))?;
            let name = entry.file_name().to_string_lossy().to_string();
            if name.starts_with("seg-") && name.ends_with(".mcap.tmp") {
                out.push(entry.path());
            }
        }
        out.sort();
        Ok(out)
    }
}

/// Write a small file whole or not at all: tmp, fsync, rename, fsync the directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let tmp = path.with_extension("tmp");
    let mut f = super::fault::Output(fs::File::create(&tmp).map_err(|e| Error::io(&tmp, e))?);
    f.write_all(bytes).and_then(|_| f.0.sync_all()).map_err(|e| Error::io(&tmp, e))?;
    super::fault::crash_point("atomic-synced");
    fs::rename(&tmp, path).map_err(|e| Error::io(path, e))?;
    super::fault::crash_point("atomic-renamed");
    if let Some(dir) = path.parent() {
        segment::sync_dir(if dir.as_os_str().is_empty() { Path::new(".") } else { dir })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{differences, differences_summary, free_bytes, gap_between, short_of_space, BuildInfo, StoreConfig};

    /// A run made with or without AVX-512 continues on either kind of node; one made on a
    /// CPU of another x86-64 level (a v3 feature such as BMI2 missing, as virtual machines
    /// may hide it) does not, nor one of other numerics. Records that list only AVX2, FMA
    /// and AVX-512 (earlier builds) count as v3 where they have both of the first two.
    #[test]
    fn a_run_continues_with_or_without_avx512_only() {
        let here = BuildInfo::current();
        let with = |features: &[&str]| BuildInfo { cpu_features: features.iter().map(|f| f.to_string()).collect(), ..here.clone() };
        let v3 = ["avx2", "fma", "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "bmi1", "bmi2", "lzcnt"];
        let mut v3_avx512 = v3.to_vec();
        v3_avx512.push("avx512f");
        assert_eq!(with(&v3).simd_level(), "x86-64-v3");
        assert_eq!(with(&v3_avx512).simd_level(), "x86-64-v3");
        assert_eq!(with(&["avx2", "fma", "avx512f"]).simd_level(), "x86-64-v3", "an earlier build's record");
        assert_eq!(with(&["avx2", "avx512f"]).simd_level(), "below x86-64-v3 (not recorded further)");
        assert_eq!(with(&v3.iter().copied().filter(|f| *f != "bmi2").collect::<Vec<_>>()).simd_level(), "x86-64-v2");
        assert_eq!(with(&["sse3", "popcnt"]).simd_level(), "below x86-64-v2");
        if here.simd_level() == "x86-64-v3" {
            assert!(with(&v3).differs_here().is_none() && with(&v3_avx512).differs_here().is_none() && with(&["avx2", "fma"]).differs_here().is_none());
            let no_bmi2 = with(&v3.iter().copied().filter(|f| *f != "bmi2").collect::<Vec<_>>());
            assert!(no_bmi2.differs_here().is_some_and(|why| why.contains("(x86-64-v2), this machine is") && why.contains("(x86-64-v3)")));
        }
        let numerics = BuildInfo { numerics: "clv-numerics/0".into(), ..here.clone() };
        assert!(numerics.differs_here().is_some_and(|why| why.contains("clv-numerics/0")));
    }

    /// What [`BuildInfo::simd_level`] rests on: faer's matrix products (private-gemm-x86)
    /// give the same bits with their AVX-512 and their AVX2 kernels, for full and triangular
    /// products, replacing or adding, with several alphas, column- and row-major operands,
    /// on one to three threads. (Without AVX-512 here, nothing can be compared.) The
    /// kernels differ (the AVX-512 ones are about twice as fast) and are not the naive sums.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_and_avx2_products_agree_bit_for_bit() {
        use private_gemm_x86::{gemm, Accum, DType, DstKind, IType, InstrSet};
        if !std::arch::is_x86_feature_detected!("avx512f") || !std::arch::is_x86_feature_detected!("fma") {
            eprintln!("no AVX-512 (or no FMA) here: the two kinds of kernels cannot be compared on this machine");
            return;
        }
        let mut rng = crate::rng::Rng::new(7);
        // Layouts: A, B and C column- or row-major (C only when full).
        #[derive(Clone, Copy, Debug)]
        struct Case {
            kind: DstKind,
            beta: Accum,
            alpha: f64,
            rows: [bool; 3],
            threads: usize,
        }
        let product = |instr, (m, n, k): (usize, usize, usize), a: &[f64], b: &[f64], c: &[f64], case: Case| {
            let mut c = c.to_vec();
            let strides = |row_major: bool, r: usize, cols: usize| if row_major { (cols as isize, 1) } else { (1, r as isize) };
            let ((ars, acs), (brs, bcs), (crs, ccs)) = (strides(case.rows[0], m, k), strides(case.rows[1], k, n), strides(case.rows[2], m, n));
            // SAFETY: every pointer and stride describes a buffer of the stated shape.
            unsafe {
                gemm(DType::F64, IType::U64, instr, m, n, k, c.as_mut_ptr().cast(), crs, ccs, std::ptr::null(), std::ptr::null(), case.kind, case.beta,
                    a.as_ptr().cast(), ars, acs, false, std::ptr::null(), 0, b.as_ptr().cast(), brs, bcs, false, (&raw const case.alpha).cast(), case.threads);
            }
            c
        };
        let mut rng2 = crate::rng::Rng::new(11);
        let mut size = |hi: usize| 1 + (rng2.uniform() * hi as f64) as usize % hi;
        // The QR's shapes, a square one, and random ones, a third with depths past the
        // kernels' k blocks (512).
        let mut shapes: Vec<(usize, usize, usize)> = vec![(792, 64, 32), (32, 64, 792), (792, 792, 792)];
        shapes.extend((0..120).map(|i| (size(500), size(200), if i % 3 == 0 { 512 + size(700) } else { size(500) })));
        for (i, &(m, n, k)) in shapes.iter().enumerate() {
            let kind = [DstKind::Full, DstKind::Upper, DstKind::Lower][i % 3];
            let case = Case {
                kind,
                beta: if i % 2 == 0 { Accum::Add } else { Accum::Replace },
                alpha: [-0.75, 1.0, -1.0, 2.0, 0.0][i % 5],
                rows: [i % 4 == 1, i % 6 == 2, kind == DstKind::Full && i % 9 == 3],
                threads: [1, 2, 1, 3][i % 4],
            };
            let shape = if kind == DstKind::Full { (m, n, k) } else { (m, m, k) };
            let fill = |len: usize, rng: &mut crate::rng::Rng| (0..len).map(|_| rng.normal()).collect::<Vec<f64>>();
            let (a, b, c) = (fill(shape.0 * shape.2, &mut rng), fill(shape.2 * shape.1, &mut rng), fill(shape.0 * shape.1, &mut rng));
            let avx2 = product(InstrSet::Avx256, shape, &a, &b, &c, case);
            let avx512 = product(InstrSet::Avx512, shape, &a, &b, &c, case);
            let differ = avx2.iter().zip(&avx512).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
            assert_eq!(differ, 0, "{shape:?} {case:?}: {differ} entries differ");
        }
        // Not the naive sums, which add in one order only: the test could not fail otherwise.
        let n = 300;
        let fill = |rng: &mut crate::rng::Rng| (0..n * n).map(|_| rng.normal()).collect::<Vec<f64>>();
        let (a, b, c) = (fill(&mut rng), fill(&mut rng), vec![0.0; n * n]);
        let plain = Case { kind: DstKind::Full, beta: Accum::Replace, alpha: -0.75, rows: [false; 3], threads: 1 };
        let kernel = product(InstrSet::Avx256, (n, n, n), &a, &b, &c, plain);
        let naive = (0..n * n).filter(|&ij| (-0.75 * (0..n).map(|l| a[ij % n + l * n] * b[l + ij / n * n]).sum::<f64>()).to_bits() != kernel[ij].to_bits()).count();
        assert!(naive > n * n / 2, "{naive} of {} differ from the naive sums", n * n);
    }

    /// A gap is a step the run wrote that no segment holds; the one after a stop's own
    /// checkpoint may begin anywhere up to the next write.
    #[test]
    fn a_gap_is_a_written_step_that_no_segment_holds() {
        // Checkpoints every 20 steps only.
        assert!(!gap_between(40, 60, 20, None) && !gap_between(40, 47, 20, None) && gap_between(40, 61, 20, None));
        assert!(!gap_between(40, 30, 20, None), "an overlap leaves nothing missing");
        // --store-r all, window from step 45: its first R_n is step 46's.
        assert!(!gap_between(40, 46, 20, Some(45)) && gap_between(40, 47, 20, Some(45)) && gap_between(40, 60, 20, Some(45)));
        assert!(!gap_between(45, 46, 20, Some(45)) && gap_between(45, 47, 20, Some(45)));
        assert!(!gap_between(50, 51, 20, Some(45)) && gap_between(50, 52, 20, Some(45)));
        // A window starting after the next checkpoint does not matter yet.
        assert!(!gap_between(0, 20, 20, Some(45)) && gap_between(0, 21, 20, Some(45)));
    }
    use crate::config::{RunConfig, SystemConfig};

    /// Runs that differ are told apart by the flags that set them: --lorenz-rho, not the
    /// configuration's field rho; --system, not its tag; --segment-mb in MB.
    #[test]
    fn differences_name_the_flags() {
        let lorenz = RunConfig::preset("lorenz").unwrap();
        let store = StoreConfig::for_run(&lorenz);
        let mut other = lorenz.clone();
        other.system = SystemConfig::lorenz_with(10.0, 21.0, 8.0 / 3.0).unwrap();
        assert_eq!(differences((&lorenz, &store, "in the run"), (&other, &store, "asked for")), ["--lorenz-rho 28 in the run, 21 asked for"]);
        let henon = RunConfig::preset("henon").unwrap();
        let d = differences((&lorenz, &store, "here"), (&henon, &store, "there")).join("; ");
        assert!(d.contains("--system lorenz here, henon there") && d.contains("--henon-a 1.4 there, none here") && d.contains("--tau 0.1 here, 1 there"), "{d}");
        assert!(d.contains("--lorenz-rho 28 here, none there"), "{d}");
        let mut bigger = store.clone();
        bigger.segment_bytes = 2 << 30;
        assert_eq!(differences((&lorenz, &store, "a"), (&lorenz, &bigger, "b")), ["--segment-mb 1024 a, 2048 b"]);
        let mut kept = store.clone();
        kept.keep_segments = 5;
        assert_eq!(differences((&lorenz, &store, "a"), (&lorenz, &kept, "b")), ["settings that flags do not show"]);
        // For a message: the system first, then three more and a count.
        let henon = RunConfig::preset("henon").unwrap();
        let summary = differences_summary(differences((&lorenz, &store, "a"), (&henon, &StoreConfig::for_run(&henon), "b")));
        assert!(summary.starts_with("--system lorenz a, henon b, ") && summary.ends_with(" more"), "{summary}");
        assert_eq!(differences_summary(vec!["x".into(), "--system a".into()]), "--system a, x");
    }

    #[test]
    fn free_space_is_found_for_a_directory_not_made_yet() {
        let path = std::env::temp_dir().join("clv-no-such-dir").join("run");
        assert!(free_bytes(&path).is_some_and(|b| b > 0));
    }

    /// Short of space only past the free bytes, and then saying where, how much and what
    /// happens when the disk fills.
    #[test]
    fn short_of_space_compares_with_the_free_bytes_and_names_the_file_system() {
        let path = std::env::temp_dir().join("clv-no-such-dir").join("run");
        let free = free_bytes(&path).unwrap();
        assert_eq!(short_of_space(&path, free / 2), None);
        let short = short_of_space(&path, free.saturating_mul(2).max(1 << 40)).unwrap();
        assert_eq!((short.path.as_path(), short.free <= free * 2), (path.as_path(), true));
        let text = short.to_string();
        assert!(text.contains(&path.display().to_string()) && text.contains("needs about") && text.contains("stops cleanly"), "{text}");
    }
}
