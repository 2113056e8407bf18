//! `clv bench`: the speed and memory of the kernels and stages, measured side by side in one
//! run on this machine.
//!
//! Machines are noisy (the same kernel runs 2-6x slower under load), so everything is
//! reported as medians with their spread, and the targets are ratios of quantities measured
//! in the same run, never absolute times.

use crate::config::{RunConfig, SystemConfig};
use crate::error::{Error, Result};
use crate::linalg::par;
use crate::rng::Rng;
use crate::stage::backward::{self, BackwardOptions};
use crate::stage::forward::Forward;
use crate::stage::forward_run::{self, Feedback};
use crate::store::frames::Flow;
use crate::store::records::{encode_r, Checkpoint, Stats};
use crate::store::run::{BuildInfo, RunMeta, StoreConfig, FORMAT};
use crate::system::disks::{box_sides, HardDisks};
use crate::system::{DynamicalSystem, Tangent};
use faer::{Mat, MatRef};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Disks N of the benchmark system (D = 4N); the paper's 198 by default.
    pub n: usize,
    /// Tangent vectors (default D).
    pub k: Option<usize>,
    pub threads: usize,
    /// Repetitions of each kernel measurement.
    pub reps: usize,
    /// System sizes for the collision-rate measurement.
    pub collision_sizes: Vec<usize>,
    /// Measure peak RSS by running `exe` as child processes (None: skip).
    pub exe: Option<PathBuf>,
}

/// Median and spread of repeated measurements (milliseconds unless stated).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Stat {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Stat {
    pub fn of(mut xs: Vec<f64>) -> Stat {
        xs.retain(|x| x.is_finite());
        if xs.is_empty() {
            return Stat { median: f64::NAN, min: f64::NAN, max: f64::NAN };
        }
        let (min, max) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| (lo.min(x), hi.max(x)));
        Stat { median: crate::statistics::median(&xs), min, max }
    }
}

/// The peak RSS of a run length: the largest of `runs` child processes.
#[derive(Clone, Debug, Serialize)]
pub struct Rss {
    pub steps: u64,
    pub peak_mb: f64,
    pub runs: usize,
}

/// Collisions per second of one system size (k = 0).
#[derive(Clone, Debug, Serialize)]
pub struct CollisionRate {
    pub n: usize,
    pub per_second: Stat,
}

/// Child processes per run length, short and long. The forward peak moved from run to run
/// by up to 4 MB at D = k = 792 while zstd's worker threads compressed the segments (their
/// job buffers came and went); on the writer's thread alone it moves by 2 MB (35.6-38.1 MB
/// in four 20-step runs, 37.1-38.0 MB at 200 steps, 2026-11-27).
/// One long run against the largest of three short ones was not a fair comparison:
/// on 2026-11-26 the short runs' largest was 55.6 MB, the one long run 51.6 MB. Both
/// lengths now take the largest of three, so that growth with the run's length is what
/// their difference shows.
const RSS_RUNS: [usize; 2] = [3, 3];

#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub n: usize,
    pub d: usize,
    pub k: usize,
    pub threads: usize,
    pub cores: usize,
    pub reps: usize,
    pub gemm_gflops: Stat,
    /// 8/3 D k^2 flops (D = k: 8/3 D^3) at the measured gemm rate.
    pub floor_ms: f64,
    pub qr_ms: Stat,
    /// Wall time per step of a stored forward run (everything, on all threads), in the
    /// steady state: from its first checkpoint after the start to its last.
    pub forward_step_ms: Stat,
    pub md_tangent_ms: Stat,
    /// Encoding checkpoint, R and statistics, amortised per step (on the simulation thread).
    pub store_ms: Stat,
    /// Wall time per step of the backward stage in the steady state (from the end of the
    /// third segment to the end of the last but one, recomputation overlapping the sweep),
    /// frames consumed in-process.
    pub backward_step_ms: Stat,
    pub backward_solve_ms: Stat,
    pub backward_vgc_ms: Stat,
    /// The median over the forward runs of the pairs (below) of the ratio of their
    /// steady-state step time to the median of ten QR steps timed just before each.
    pub forward_step_over_qr: f64,
    /// The median over the kernel repetitions of each QR's time over the floor at the gemm
    /// rate measured just before it.
    pub qr_over_floor: f64,
    /// The median over pairs of runs (a forward run, then the backward stage over it) of
    /// the ratio of their steady-state step times.
    pub backward_over_forward: f64,
    /// The backward stage over the same runs forming V_n only for every m-th step
    /// (`--vectors-every m`), m the analyses' sampling for the paper's 25000 CLV steps.
    pub sampled_every: u64,
    pub backward_sampled_step_ms: Stat,
    pub backward_sampled_over_forward: f64,
    /// The least a backward step with V in every frame can take on `threads` cores, from
    /// the work measured on one thread: (one-thread forward step + one-thread R^-1 C and
    /// V = G C) / threads (no schedule does a thread's work faster than one thread alone;
    /// the copies into the segment are left out, so it is lower still). None on one thread.
    pub backward_work_bound_ms: Option<f64>,
    /// That bound over the median forward step (the least `backward_over_forward` can be).
    pub backward_work_bound_over_forward: Option<f64>,
    /// The same forward step with k = 16 vectors (leading-k runs).
    pub leading_k16_step_ms: Stat,
    pub leading_k16_md_tangent_ms: Stat,
    pub leading_k16_qr_ms: Stat,
    /// Collisions per second with k = 0, each system size measured `reps` times, the sizes
    /// in turn (so that the host's slow spells fall on all of them).
    pub collisions_per_second: Vec<CollisionRate>,
    /// The median over those rounds of the fastest size's rate over the slowest's (the
    /// target: within 2x across N = 198 .. 19800).
    pub collision_rate_spread: f64,
    pub forward_peak_rss: Vec<Rss>,
    pub backward_peak_rss: Vec<Rss>,
    /// Projected hours for the paper's run (2.5e5 forward steps, 2.5e4 backward steps with
    /// frames and 1.25e4 before them); null unless the bench ran the paper's system (steps
    /// of another size say nothing about it).
    pub paper_forward_hours: Option<f64>,
    pub paper_backward_hours: Option<f64>,
    /// The same with V_n every `sampled_every` steps, as the paper's pipeline runs.
    pub paper_backward_sampled_hours: Option<f64>,
}

/// CLV steps of the paper's run (section 5: the last 2.5e4 steps).
const PAPER_CLV_STEPS: u64 = 25_000;

fn ms(t: std::time::Duration) -> f64 {
    t.as_secs_f64() * 1e3
}

fn random_mat(d: usize, k: usize, rng: &mut Rng) -> Mat<f64> {
    Mat::from_fn(d, k, |_, _| rng.normal())
}

fn disk_config(n: usize, k: usize, threads: usize, relax: u64, steps: u64) -> Result<RunConfig> {
    Ok(RunConfig { system: SystemConfig::disks(n, 0.7, 2.0 / 11.0)?, tau: 0.6, relax_steps: relax, steps, vectors: k, seed: 1, threads, blocks: 4 })
}

/// Peak resident set size of this process (Linux; None elsewhere).
pub fn peak_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn child_peak_rss_mb(exe: &Path, args: &[String]) -> Result<f64> {
    let out = std::process::Command::new(exe)
        .args(args)
        .env("CLV_REPORT_PEAK_RSS", "1")
        .output()
        .map_err(|e| Error::io(exe, e))?;
    let err = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        return Err(Error::Other(format!("benchmark child {args:?} failed: {err}")));
    }
    let kb: f64 = err.lines().find_map(|l| l.strip_prefix("clv-peak-rss-kb: ")).and_then(|v| v.trim().parse().ok()).unwrap_or(f64::NAN);
    Ok(kb / 1024.0)
}

/// The largest peak RSS of `runs` runs of `args`; `fresh` (a run directory the command
/// creates) is removed before each.
fn peak_of_runs(exe: &Path, args: &[String], steps: u64, runs: usize, fresh: Option<&Path>) -> Result<Rss> {
    let mut peak_mb = f64::NAN;
    for _ in 0..runs {
        if let Some(dir) = fresh {
            let _ = std::fs::remove_dir_all(dir);
        }
        peak_mb = child_peak_rss_mb(exe, args)?.max(peak_mb);
    }
    Ok(Rss { steps, peak_mb, runs })
}

/// (step, wall seconds) of every checkpoint's statistics in a run directory.
fn checkpoint_walls(dir: &Path) -> Result<Vec<(u64, f64)>> {
    let (run, _) = crate::store::run::RunDir::open(dir)?;
    let mut walls = Vec::new();
    for seg in run.segments()? {
        crate::store::segment::read_segment(&seg.path, crate::store::segment::ReadMode::Strict, |m| {
            if m.topic == crate::store::schema::STATS.topic {
                let s = Stats::decode(m.data).map_err(|e| Error::corrupt(&seg.path, e))?;
                walls.push((s.step, s.wall_seconds));
            }
            Ok(())
        })?;
    }
    Ok(walls)
}

/// A relaxed forward pass of the benchmark system (its tangent block is realistic).
fn relaxed_forward(config: &RunConfig) -> Result<Forward> {
    let mut f = Forward::new(config)?;
    for _ in 0..config.relax_steps {
        f.step()?;
    }
    Ok(f)
}

/// Refuse a system size the bench cannot build: it puts N disks in the paper's box (density
/// 0.7, Ly/Lx = 2/11), whose short side must exceed a diameter, and it must fit in memory
/// (a kilobyte a disk is allowed; 10^6 disks without tangent vectors took 0.18 kB each).
fn check_size(flag: &'static str, size: usize) -> Result<()> {
    let (_, ly) = box_sides(size, 0.7, 2.0 / 11.0);
    if ly <= 1.0 {
        return Err(Error::param(flag, format!("{size} disks: the bench's box (the paper's shape, Ly/Lx = 2/11, at density 0.7) would be {ly:.2} disk diameters high, too narrow for a disk; give more disks")));
    }
    let need = 1024.0 * size as f64;
    if let Some(have) = crate::machine::available_memory()
        && need > have as f64
    {
        return Err(Error::param(flag, format!("{size} disks need about {:.1} GB, more than the {:.1} GB this machine has available; give fewer", need / 1e9, have as f64 / 1e9)));
    }
    Ok(())
}

pub fn run(o: &BenchOptions, say: &mut dyn FnMut(&str)) -> Result<BenchReport> {
    check_options(o)?;
    let (n, threads, reps) = (o.n, o.threads, o.reps);
    let d = 4 * n;
    let k = o.k.unwrap_or(d);

    say("gemm and forward steps (MD, tangent, QR), alternately");
    let config = disk_config(n, k, threads, 3, 100)?;
    let mut fwd = relaxed_forward(&config)?;
    let kernels = Kernels::measure(&mut fwd, threads, reps)?;

    say("store encoding");
    let store = StoreConfig::for_run(&config);
    let ck = Checkpoint { state: fwd.state(), time: fwd.time(), system: "disks".into(), d, k };
    let stats = Stats { step: 0, time: 0.0, exponents: vec![0.0; k], stderr: vec![0.0; k], energy: 0.0, energy_initial: 0.0, momentum: [0.0; 2], collisions: 0, wall_seconds: 0.0 };
    let store_ms = Stat::of((0..reps).map(|_| {
        let t = Instant::now();
        let bytes = ck.encode().len() + encode_r(1, &fwd.r).len() + stats.encode().len();
        std::hint::black_box(bytes);
        ms(t.elapsed()) / store.checkpoint_every as f64
    }).collect());

    say("backward kernels (R^-1 C, V = G C)");
    // On the threads the backward stage gives its sweep (the recomputation has the rest).
    let p = par(backward::sweep_threads(threads));
    let mut sweep = SweepKernels::of(&fwd);
    let backward_solve_ms = Stat::of((0..reps).map(|_| sweep.solve(p)).collect());
    let backward_vgc_ms = Stat::of((0..reps).map(|_| sweep.form_v(p)).collect());
    // The work of a backward step measured on one thread, for its bound on `threads` cores.
    let one_thread_work_ms = if threads >= 2 {
        say("one-thread forward steps and backward kernels (the work bound)");
        fwd.set_threads(1);
        let steps = (0..reps).map(|_| fwd.step_timed().map(|(a, q)| ms(a + q))).collect::<Result<Vec<_>>>()?;
        fwd.set_threads(threads);
        let sweeps = (0..reps).map(|_| sweep.solve(faer::Par::Seq) + sweep.form_v(faer::Par::Seq)).collect();
        Some(Stat::of(steps).median + Stat::of(sweeps).median)
    } else {
        None
    };

    say("stored forward run and backward stage over it, in pairs");
    let tmp = std::env::temp_dir().join(format!("clv-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let stages = Stages::measure(&mut fwd, n, k, threads, reps, &tmp)?;
    let backward_work_bound_ms = one_thread_work_ms.map(|w| w / threads as f64);

    say("leading k = 16");
    let lk = 16.min(d);
    let mut f16 = relaxed_forward(&disk_config(n, lk, threads, 3, 10)?)?;
    let (mut a16, mut q16, mut s16) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..reps.max(5) {
        let (a, q) = f16.step_timed()?;
        a16.push(ms(a));
        q16.push(ms(q));
        s16.push(ms(a + q));
    }

    say("collision rates (k = 0)");
    let (collisions_per_second, collision_rate_spread) = collision_rates(&o.collision_sizes, reps)?;

    let (forward_peak_rss, backward_peak_rss) = match &o.exe {
        Some(exe) => {
            say("peak memory (child processes, 10x longer runs)");
            peak_memory(exe, n, k, threads, &tmp)?
        }
        None => (Vec::new(), Vec::new()),
    };
    let _ = std::fs::remove_dir_all(&tmp);

    let Stages { forward_step_ms, backward_step_ms, backward_over_forward, sampled_every, backward_sampled_step_ms, backward_sampled_over_forward, forward_step_over_qr } = stages;
    let paper = n == PAPER_N && k == 4 * PAPER_N;
    Ok(BenchReport {
        n,
        d,
        k,
        threads,
        cores: std::thread::available_parallelism().map_or(1, |c| c.get()),
        reps,
        floor_ms: qr_floor_ms(d, k, kernels.gemm_gflops.median),
        gemm_gflops: kernels.gemm_gflops,
        qr_ms: kernels.qr_ms,
        forward_step_ms,
        md_tangent_ms: kernels.md_tangent_ms,
        store_ms,
        backward_step_ms,
        backward_solve_ms,
        backward_vgc_ms,
        forward_step_over_qr,
        qr_over_floor: kernels.qr_over_floor,
        backward_over_forward,
        sampled_every,
        backward_sampled_step_ms,
        backward_sampled_over_forward,
        backward_work_bound_ms,
        backward_work_bound_over_forward: backward_work_bound_ms.map(|b| b / forward_step_ms.median),
        leading_k16_step_ms: Stat::of(s16),
        leading_k16_md_tangent_ms: Stat::of(a16),
        leading_k16_qr_ms: Stat::of(q16),
        collisions_per_second,
        collision_rate_spread,
        forward_peak_rss,
        backward_peak_rss,
        paper_forward_hours: paper.then(|| 250_000.0 * forward_step_ms.median / 3.6e6),
        // The 12500 transient steps emit no frames, so they form no V either.
        paper_backward_hours: paper.then(|| (25_000.0 * backward_step_ms.median + 12_500.0 * backward_sampled_step_ms.median) / 3.6e6),
        paper_backward_sampled_hours: paper.then(|| 37_500.0 * backward_sampled_step_ms.median / 3.6e6),
    })
}

/// Refuse options the bench cannot measure with, naming the flag.
fn check_options(o: &BenchOptions) -> Result<()> {
    for (name, value) in [("threads", o.threads), ("reps", o.reps), ("n", o.n)] {
        if value == 0 {
            return Err(Error::param(name, "must be at least 1"));
        }
    }
    crate::config::check_threads(o.threads)?;
    let d = 4 * o.n;
    if o.k.is_some_and(|k| k == 0 || k > d) {
        return Err(Error::param("vectors", format!("must be between 1 and D = {d}")));
    }
    if let Some(&bad) = o.collision_sizes.iter().find(|&&size| size < 2) {
        return Err(Error::param("collision-sizes", format!("{bad} disks cannot collide with each other; give sizes of at least 2")));
    }
    check_size("n", o.n)?;
    for &size in &o.collision_sizes {
        check_size("collision-sizes", size)?;
    }
    Ok(())
}

/// The gemm rate and the forward step's kernels, measured alternately.
struct Kernels {
    gemm_gflops: Stat,
    qr_ms: Stat,
    md_tangent_ms: Stat,
    /// Median of each QR over the floor at the gemm rate measured just before it.
    qr_over_floor: f64,
}

impl Kernels {
    /// One gemm, then one step, so that each QR is compared with the gemm rate of its moment
    /// (the rate of a shared machine moves by 20 % within an hour).
    fn measure(fwd: &mut Forward, threads: usize, reps: usize) -> Result<Self> {
        let (d, k) = (fwd.system.dim(), fwd.g.count());
        let p = par(threads);
        let mut rng = Rng::new(7);
        let (a, b) = (random_mat(d, d, &mut rng), random_mat(d, d, &mut rng));
        let mut c = Mat::<f64>::zeros(d, d);
        let mut gemm_once = || {
            let t = Instant::now();
            faer::linalg::matmul::matmul(c.as_mut(), faer::Accum::Replace, a.as_ref(), b.as_ref(), 1.0, p);
            2.0 * (d as f64).powi(3) / t.elapsed().as_secs_f64() / 1e9
        };
        gemm_once(); // warm-up
        let (mut rates, mut md, mut qr, mut over_floor) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for _ in 0..reps.max(20) {
            let rate = gemm_once();
            let (a, q) = fwd.step_timed()?;
            rates.push(rate);
            md.push(ms(a));
            qr.push(ms(q));
            over_floor.push(ms(q) / qr_floor_ms(d, k, rate));
        }
        Ok(Kernels { gemm_gflops: Stat::of(rates), qr_ms: Stat::of(qr), md_tangent_ms: Stat::of(md), qr_over_floor: Stat::of(over_floor).median })
    }
}

/// The floor of one QR with explicit Q of a D x k block at `gflops`, in ms: Householder
/// factorisation and forming Q take 2 D k^2 - 2/3 k^3 flops each, 8/3 D^3 together at k = D.
fn qr_floor_ms(d: usize, k: usize, gflops: f64) -> f64 {
    let (d, k) = (d as f64, k as f64);
    (4.0 * d * k * k - 4.0 / 3.0 * k.powi(3)) / (gflops * 1e9) * 1e3
}

/// The backward sweep's two kernels on a realistic R and G: C_{n-1} = R_n^{-1} C_n (with the
/// renormalisation of its columns) and V_n = G_n C_n.
struct SweepKernels {
    r: Mat<f64>,
    c: Mat<f64>,
    norms: Vec<f64>,
    g: Vec<f64>,
    v: Vec<f64>,
}

impl SweepKernels {
    fn of(fwd: &Forward) -> Self {
        let (d, k) = (fwd.system.dim(), fwd.g.count());
        SweepKernels { r: fwd.r.clone(), c: Mat::identity(k, k), norms: vec![0.0; k], g: fwd.g.to_paper_columns(fwd.system.as_ref()), v: vec![0.0; d * k] }
    }

    /// One R^-1 C, in ms.
    fn solve(&mut self, p: faer::Par) -> f64 {
        let t = Instant::now();
        crate::linalg::ginelli_step(self.r.as_ref(), self.c.as_mut(), &mut self.norms, p);
        ms(t.elapsed())
    }

    /// One V = G C, in ms.
    fn form_v(&mut self, p: faer::Par) -> f64 {
        let (d, k) = (self.g.len() / self.c.nrows(), self.c.nrows());
        let t = Instant::now();
        crate::linalg::mul_upper(faer::MatMut::from_column_major_slice_mut(&mut self.v, d, k), MatRef::from_column_major_slice(&self.g, d, k), self.c.as_ref(), p);
        ms(t.elapsed())
    }
}

/// The stages themselves: stored forward runs and the backward stage over each.
struct Stages {
    forward_step_ms: Stat,
    backward_step_ms: Stat,
    backward_over_forward: f64,
    sampled_every: u64,
    backward_sampled_step_ms: Stat,
    backward_sampled_over_forward: f64,
    forward_step_over_qr: f64,
}

impl Stages {
    /// Each pair is one stored forward run (store defaults: a checkpoint every 100 steps) and
    /// the backward stage over it, one right after the other, so that their ratio is taken
    /// under the same load of a shared machine; the ratio reported is the median of the
    /// pairs'. Ten QR steps of `fwd` just before each forward run give its
    /// forward_step_over_qr the same way.
    fn measure(fwd: &mut Forward, n: usize, k: usize, threads: usize, reps: usize, tmp: &Path) -> Result<Self> {
        let (mut fsteps, mut bsteps, mut ratios, mut qr_ratios) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut sampled_steps, mut sampled_ratios) = (Vec::new(), Vec::new());
        // The paper's pipeline forms V only for the frames its analyses sample (every 62nd of
        // 25000 CLV steps: scripts/reproduce_paper.sh, `clv run`).
        let sampled_every = crate::stage::analyze::default_every(PAPER_CLV_STEPS, 1);
        for rep in 0..reps.clamp(2, 3) {
            let mut qr_now = Vec::new();
            for _ in 0..10 {
                qr_now.push(ms(fwd.step_timed()?.1));
            }
            let qr_now = Stat::of(qr_now).median;
            let dir = tmp.join(format!("pair{rep}"));
            // 630 steps: long enough for a steady state both ways, short enough for the default
            // bench to stay under 5 minutes where a step takes 23 ms (1030 steps took it to 5.2).
            let cfg = disk_config(n, k, threads, 0, 630)?;
            let mut st = StoreConfig::for_run(&cfg);
            st.clv_steps = 500;
            st.transient = 100;
            let meta = RunMeta { format: FORMAT.into(), config: cfg.clone(), store: st.clone(), build: BuildInfo::current() };
            forward_run::create(&dir, &meta, &mut Feedback::default())?;
            // The wall times the statistics record at the checkpoints give the steady-state
            // cost of a forward step (checkpoints, fsyncs and all) after the first interval,
            // without the start-up that a long run amortises.
            let walls = checkpoint_walls(&dir)?;
            let at = |step: u64| walls.iter().find(|w| w.0 == step).map(|w| w.1);
            let forward = match (at(100), at(600)) {
                (Some(a), Some(b)) => (b - a) * 1e3 / 500.0,
                _ => f64::NAN,
            };
            let backward = backward_step_ms(&dir, &meta, 1)?;
            fsteps.push(forward);
            bsteps.push(backward);
            ratios.push(backward / forward);
            // In two of the pairs only, to keep the default bench under 5 minutes on one thread.
            if rep < 2 {
                let sampled = backward_step_ms(&dir, &meta, sampled_every)?;
                sampled_steps.push(sampled);
                sampled_ratios.push(sampled / forward);
            }
            qr_ratios.push(forward / qr_now);
            let _ = std::fs::remove_dir_all(&dir);
        }
        Ok(Stages {
            forward_step_ms: Stat::of(fsteps),
            backward_step_ms: Stat::of(bsteps),
            backward_over_forward: Stat::of(ratios).median,
            sampled_every,
            backward_sampled_step_ms: Stat::of(sampled_steps),
            backward_sampled_over_forward: Stat::of(sampled_ratios).median,
            forward_step_over_qr: Stat::of(qr_ratios).median,
        })
    }
}

/// The steady-state time of a backward step over the stored run in `dir`, V formed every
/// `vectors_every` steps.
fn backward_step_ms(dir: &Path, meta: &RunMeta, vectors_every: u64) -> Result<f64> {
    let mut opts = BackwardOptions::for_run(meta);
    opts.save_every = 0;
    opts.vectors_every = vectors_every;
    let mut marks: Vec<(Instant, u64)> = Vec::new();
    backward::run(dir, &opts, false, u64::MAX, None, &mut |_| Ok(Flow::Continue), &mut |steps, _| marks.push((Instant::now(), steps)))?;
    // Seven segments (six of 100 steps) in the bench's pairs; the time per step is taken from
    // the end of the third segment's sweep to the end of the last but one (three segments):
    // the period of the overlapped pipeline, once both segment buffers have been written
    // whole (their first writes fault the pages in). The last sweep runs alone after the last recomputation,
    // once per run.
    Ok(match (marks.get(2), marks.len().checked_sub(2).and_then(|i| marks.get(i))) {
        (Some(first), Some(last)) if last.1 > first.1 => ms(last.0 - first.0) / (last.1 - first.1) as f64,
        _ => f64::NAN,
    })
}

/// Collisions per second of each size in `sizes` without tangent vectors, over 300000
/// collisions, `reps` rounds of all sizes in turn; and the median over the rounds of the
/// largest rate over the smallest.
fn collision_rates(sizes: &[usize], reps: usize) -> Result<(Vec<CollisionRate>, f64)> {
    let mut systems = sizes
        .iter()
        .map(|&size| {
            let (lx, ly) = box_sides(size, 0.7, 2.0 / 11.0);
            let mut s = HardDisks::new(size, lx, ly, 0.6, 3)?;
            s.advance(&mut Tangent::zeros(4 * size, 0))?; // melt the lattice
            Ok(s)
        })
        .collect::<Result<Vec<_>>>()?;
    let mut rates = vec![Vec::new(); sizes.len()];
    let mut spreads = Vec::new();
    for _ in 0..reps {
        for (s, rates) in systems.iter_mut().zip(&mut rates) {
            let mut none = Tangent::zeros(s.dim(), 0);
            let c0 = s.invariants().events;
            let t = Instant::now();
            while s.invariants().events - c0 < 300_000 {
                s.advance(&mut none)?;
            }
            rates.push((s.invariants().events - c0) as f64 / t.elapsed().as_secs_f64());
        }
        let round = rates.iter().filter_map(|r| r.last().copied());
        let (lo, hi) = round.fold((f64::INFINITY, 0.0f64), |(lo, hi), r| (lo.min(r), hi.max(r)));
        spreads.push(hi / lo);
    }
    let per_size = sizes.iter().zip(rates).map(|(&n, r)| CollisionRate { n, per_second: Stat::of(r) }).collect();
    Ok((per_size, Stat::of(spreads).median))
}

/// Peak RSS of forward and backward runs of two lengths 10x apart, as child processes of
/// `exe`. Checkpoints every 5 steps (in run segments of 2): both run lengths write, rotate
/// and prune segments, and both backward windows span the 4 or more segments that fill the
/// backward pipeline (with checkpoints every 10 steps, a 20-step window and its transient
/// were 3 segments and peaked at 212 MB, every window of 4 or more at 225 MB), so the
/// comparison is of steady states.
fn peak_memory(exe: &Path, n: usize, k: usize, threads: usize, tmp: &Path) -> Result<(Vec<Rss>, Vec<Rss>)> {
    let (mut forward, mut backward) = (Vec::new(), Vec::new());
    let base = 20u64;
    let owned = |args: &[&str]| args.iter().map(|s| s.to_string()).collect::<Vec<String>>();
    let (n, k, threads) = (n.to_string(), k.to_string(), threads.to_string());
    for scale in [1, 10] {
        let dir = tmp.join(format!("rss-f{scale}"));
        let steps = base * scale;
        let args = owned(&["forward", "--quiet", "--n", &n, "--vectors", &k, "--threads", &threads, "--relax-steps", "0", "--steps", &steps.to_string(), "--checkpoint-every", "5", "--segment-checkpoints", "2", "--clv-steps", "10", "--transient", "5", "--out", dir.to_str().unwrap_or_default()]);
        forward.push(peak_of_runs(exe, &args, steps, RSS_RUNS[usize::from(scale > 1)], Some(&dir))?);
    }
    for scale in [1, 10] {
        let dir = tmp.join(format!("rss-b{scale}"));
        let window = base * scale;
        let args = owned(&["forward", "--quiet", "--n", &n, "--vectors", &k, "--threads", &threads, "--relax-steps", "0", "--steps", &(window + 10).to_string(), "--checkpoint-every", "5", "--clv-steps", &window.to_string(), "--transient", "10", "--out", dir.to_str().unwrap_or_default()]);
        child_peak_rss_mb(exe, &args)?;
        let args = owned(&["backward", dir.to_str().unwrap_or_default(), "--quiet", "--save-every", "0"]);
        backward.push(peak_of_runs(exe, &args, window, RSS_RUNS[usize::from(scale > 1)], None)?);
    }
    Ok((forward, backward))
}

/// Disks of the paper's system (D = 4N = 792), the one the projection is for.
pub const PAPER_N: usize = 198;

impl BenchReport {
    pub fn table(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let st = |x: &Stat| format!("{:>9.3}  ({:.3} .. {:.3})", x.median, x.min, x.max);
        let _ = writeln!(s, "clv bench: N = {}, D = {}, k = {}, {} thread(s) on {} cores, {} repetitions (median (min .. max))", self.n, self.d, self.k, self.threads, self.cores, self.reps);
        let _ = writeln!(s, "  gemm_gflops            {}", st(&self.gemm_gflops));
        let _ = writeln!(s, "  floor_ms               {:>9.3}", self.floor_ms);
        let _ = writeln!(s, "  qr_ms                  {}", st(&self.qr_ms));
        let _ = writeln!(s, "  forward_step_ms        {}", st(&self.forward_step_ms));
        let _ = writeln!(s, "    md_tangent_ms        {}", st(&self.md_tangent_ms));
        let _ = writeln!(s, "    store_ms             {}", st(&self.store_ms));
        let _ = writeln!(s, "  backward_step_ms       {}", st(&self.backward_step_ms));
        let _ = writeln!(s, "    solve_ms (R^-1 C)    {}", st(&self.backward_solve_ms));
        let _ = writeln!(s, "    vgc_ms (V = G C)     {}", st(&self.backward_vgc_ms));
        let _ = writeln!(s, "  forward_step_over_qr   {:>9.3}   (target <= 1.15)", self.forward_step_over_qr);
        let _ = writeln!(s, "  qr_over_floor          {:>9.3}   (target <= 1.4 on 2 threads)", self.qr_over_floor);
        let _ = writeln!(s, "  backward_over_forward  {:>9.3}   (target <= 1.3)", self.backward_over_forward);
        if let (Some(ms), Some(ratio)) = (self.backward_work_bound_ms, self.backward_work_bound_over_forward) {
            let _ = writeln!(s, "    bound from the work on {} cores: {ms:.3} ms, over forward {ratio:.3} (one-thread step + sweep, over {})", self.threads, self.threads);
        }
        let _ = writeln!(s, "  with V every {:>3} steps: backward_step_ms {}, over forward {:.3}", self.sampled_every, st(&self.backward_sampled_step_ms), self.backward_sampled_over_forward);
        let _ = writeln!(s, "  k = 16: step {}  md+tangent {}  qr {}", st(&self.leading_k16_step_ms), st(&self.leading_k16_md_tangent_ms), st(&self.leading_k16_qr_ms));
        for r in &self.collisions_per_second {
            let p = &r.per_second;
            let _ = writeln!(s, "  collisions/s, k = 0, N = {:>6}: {:.3e}  ({:.3e} .. {:.3e})", r.n, p.median, p.min, p.max);
        }
        if self.collisions_per_second.len() > 1 {
            let _ = writeln!(s, "  collision_rate_spread   {:>9.3}   (fastest size over slowest, target <= 2)", self.collision_rate_spread);
        }
        for r in &self.forward_peak_rss {
            let _ = writeln!(s, "  forward peak RSS, {:>5} steps: {:.1} MB (largest of {} runs)", r.steps, r.peak_mb, r.runs);
        }
        for r in &self.backward_peak_rss {
            let _ = writeln!(s, "  backward peak RSS, window {:>5}: {:.1} MB (largest of {} runs)", r.steps, r.peak_mb, r.runs);
        }
        if let (Some(fwd), Some(bwd), Some(sampled)) = (self.paper_forward_hours, self.paper_backward_hours, self.paper_backward_sampled_hours) {
            let _ = writeln!(
                s,
                "  paper run projection: forward {fwd:.2} h + backward {bwd:.2} h = {:.2} h (V every {} steps: backward {sampled:.2} h, {:.2} h in all)",
                fwd + bwd,
                self.sampled_every,
                fwd + sampled
            );
        } else {
            let _ = writeln!(s, "  paper run projection: none (it needs N = {PAPER_N} with all {} vectors; this bench ran N = {}, k = {})", 4 * PAPER_N, self.n, self.k);
        }
        s
    }
}

