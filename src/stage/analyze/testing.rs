//! Synthetic contexts, frames and table readers shared by the unit tests of the analyses.

use super::{Context, Options};
use crate::config::{RunConfig, SystemConfig};
use crate::store::run::{BuildInfo, RunMeta, StoreConfig, FORMAT};
use crate::report::SpectrumSummary;
use crate::stage::frame::Frame;
use std::path::PathBuf;

pub use crate::rng::Rng;

pub fn unit(mut v: Vec<f64>) -> Vec<f64> {
    let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    v.iter_mut().for_each(|x| *x /= n);
    v
}

/// Random disk positions in the box and momenta (paper ordering), 4N values.
pub fn phase(n: usize, lx: f64, ly: f64, rng: &mut Rng) -> Vec<f64> {
    let mut g: Vec<f64> = (0..n).flat_map(|_| [lx, ly]).map(|l| l * rng.uniform()).collect();
    g.extend((0..2 * n).map(|_| rng.normal()));
    g
}

/// Place `cols` (D each) into a full set (column-major) at 0-based index `at` onwards.
pub fn plant(set: &mut [f64], d: usize, at: usize, cols: &[Vec<f64>]) {
    for (j, c) in cols.iter().enumerate() {
        set[(at + j) * d..(at + j + 1) * d].copy_from_slice(c);
    }
}

/// dq = pattern (2N), dp = c dq; returns the unit vector and the factor 1/norm.
pub fn tangent(dq: &[f64], c: f64) -> (Vec<f64>, f64) {
    let mut v = dq.to_vec();
    v.extend(dq.iter().map(|x| c * x));
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    (unit(v), 1.0 / norm)
}

/// Unit tangent vectors of the `kind` mode of wave vector (n_x, 0) in an lx x ly box at
/// `phase`, columns `which` of its Table III basis, with dp = c dq.
pub fn mode_vectors(lx: f64, ly: f64, kind: super::kernels::modes::ModeKind, n_x: i32, phase: &[f64], c: f64, which: &[usize]) -> Vec<Vec<f64>> {
    use super::kernels::modes::{mode_patterns, Family, Wave};
    let w = Wave { n_x, n_y: 0 };
    let pat = mode_patterns(kind, &Family { waves: vec![w], k: w.norm(lx, ly) }, phase, lx, ly);
    let h = phase.len() / 2;
    which.iter().map(|&j| tangent(&pat[j * h..(j + 1) * h], c).0).collect()
}

/// A full set of d random unit vectors (column-major).
pub fn random_set(d: usize, rng: &mut Rng) -> Vec<f64> {
    (0..d).flat_map(|_| unit((0..d).map(|_| rng.normal()).collect())).collect()
}

/// Symmetric spectrum of 4N exponents with well separated values, six zeros in the null
/// space and, on both sides, a degenerate run of `len` exponents ending next to it.
pub fn spectrum(n: usize, len: usize) -> SpectrumSummary {
    let m = 2 * n - 3;
    let mut pos: Vec<f64> = (0..m).map(|i| 3.0 - 2.5 * i as f64 / m as f64).collect();
    for x in &mut pos[m - len..] {
        *x = 0.1;
    }
    let mut e = pos.clone();
    e.extend([0.0; 6]);
    e.extend(pos.iter().rev().map(|x| -x));
    SpectrumSummary { stderr: vec![1e-3; e.len()], exponents: e, ks_entropy: None, blocks: None, warnings: Vec::new() }
}

/// Set exponents `at`, `at + 1`, ... to `xs` and their conjugates to `-xs`, keeping the
/// spectrum symmetric.
pub fn plant_block(spec: &mut SpectrumSummary, at: usize, xs: &[f64]) {
    let d = spec.exponents.len();
    for (j, &x) in xs.iter().enumerate() {
        spec.exponents[at + j] = x;
        spec.exponents[d - 1 - at - j] = -x;
    }
}

/// The context of a stream of `system` ("disks", "henon" or "lorenz"; N disks in an lx x ly
/// box) with D = d, its run the preset of that system with k = d vectors and a backward
/// window of 1000 steps (20 blocks of 50 frames).
pub fn context(system: &str, n: usize, d: usize, lx: f64, ly: f64, gs: Option<SpectrumSummary>, with_gs: bool) -> Context {
    let mut config = RunConfig::preset(if system == "disks" { "default" } else { system }).unwrap();
    if system == "disks" {
        config.system = SystemConfig::disks_in_box(n, lx, ly);
    }
    config.vectors = d;
    let store = StoreConfig { clv_steps: 1000, ..StoreConfig::for_run(&config) };
    Context {
        run: RunMeta { format: FORMAT.into(), store, config, build: BuildInfo::current() },
        gs,
        system: system.into(),
        d,
        k: d,
        n,
        lx,
        ly,
        tau: if system == "henon" { 1.0 } else { 0.6 },
        with_gs,
        options: Options { every: 1, j: vec![1], deltas: vec![1] },
        source: "synthetic".into(),
        frame_steps: None,
        saved_every: 1,
        vectors_every: 1,
        modes: Err("not settled".into()),
        j_default: false,
    }
}

pub fn frame(step: u64, phase: Vec<f64>, v: Vec<f64>, g: Option<Vec<f64>>) -> Frame {
    let d = phase.len();
    Frame { step, time: step as f64, d, k: v.len() / d, phase, local: vec![0.0; v.len() / d], gs_local: Vec::new(), v, g }
}

/// A fresh output directory for one test, removed with everything in it when dropped.
pub fn out_dir(name: &str) -> OutDir {
    let dir = std::env::temp_dir().join(format!("clv-analyses-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    OutDir(dir)
}

/// See [`out_dir`].
pub struct OutDir(PathBuf);

impl std::ops::Deref for OutDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

use crate::report::dir::csv_cells as split_csv;

/// Rows of a CSV file as maps from header to cell.
pub fn read_csv(path: &std::path::Path) -> Vec<std::collections::BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header = split_csv(lines.next().unwrap());
    lines.map(|l| header.iter().cloned().zip(split_csv(l)).collect()).collect()
}

pub fn is_png(path: &std::path::Path) -> bool {
    std::fs::read(path).is_ok_and(|b| b.starts_with(b"\x89PNG\r\n\x1a\n"))
}

/// A CSV of numbers: its header and rows.
pub fn read_table(path: &std::path::Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines.map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    (header, rows)
}

/// One column of a [`read_table`] result.
pub fn column(table: &(Vec<String>, Vec<Vec<f64>>), name: &str) -> Vec<f64> {
    let c = table.0.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name} in {:?}", table.0));
    table.1.iter().map(|r| r[c]).collect()
}

/// A planted mode scenario: its context (with the GS spectrum), a frame whose GS and
/// covariant vectors carry the mode, and the 0-based first index `at` of the block. The
/// mode table finds the block (tested in modes.rs); the analyses that take their steps from
/// it (transversality, overlaps) test against the same scenarios.
pub struct Planted {
    pub ctx: Context,
    pub spectrum: SpectrumSummary,
    pub frame: Frame,
    /// The same phase point with random vectors in place of the planted ones.
    pub random: Frame,
    pub at: usize,
}

/// The box of the planted scenarios: N = 30 disks in 14 x 3, narrow like the paper's.
pub const PLANTED_BOX: (usize, f64, f64) = (30, 14.0, 3.0);

fn planted(seed: u64, spectrum: SpectrumSummary, at: usize, n_x: i32, c: f64, mirror: bool) -> Planted {
    let (n, lx, ly) = PLANTED_BOX;
    let d = 4 * n;
    let mut rng = Rng::new(seed);
    let ctx = context("disks", n, d, lx, ly, Some(spectrum.clone()), true);
    let phase = phase(n, lx, ly, &mut rng);
    let cols = mode_vectors(lx, ly, super::kernels::modes::ModeKind::LP, n_x, &phase, c, &[0, 1, 2, 3]);
    let random = random_set(d, &mut rng);
    let mut g = random.clone();
    plant(&mut g, d, at, &cols);
    if mirror {
        plant(&mut g, d, d - at - 4, &cols);
    }
    Planted { ctx, spectrum, frame: frame(3, phase.clone(), g.clone(), Some(g)), random: frame(4, phase, random.clone(), Some(random)), at }
}

/// An LP(2,0) quadruplet whose outer exponents differ by many standard errors (as a finite
/// system's do): the exponents alone see its middle pair only, which the mode table widens
/// to the block and its conjugate.
pub fn split_lp_quadruplet() -> Planted {
    let n = PLANTED_BOX.0;
    let d = 4 * n;
    let mut spec = spectrum(n, 4);
    let at = 2 * n - 7;
    for (i, x) in [(at, 0.13), (at + 3, 0.07), (d - 1 - at, -0.13), (d - 1 - at - 3, -0.07)] {
        spec.exponents[i] = x;
    }
    planted(4, spec, at, 2, -0.4, false)
}

/// A small system's LP(1,0) block (N = 40 in the paper's box): its four exponents spread like
/// the smooth spectrum's, so no exponent test sees it, but it stands apart between wider
/// gaps, next to the T pair; its vectors (and its mirror's) are that mode.
pub fn lp_block_found_by_its_vectors() -> Planted {
    let n = PLANTED_BOX.0;
    let mut spec = spectrum(n, 2);
    let at = 2 * n - 9;
    plant_block(&mut spec, at, &[0.6, 0.55, 0.5, 0.45]);
    planted(9, spec, at, 1, 0.5, true)
}
