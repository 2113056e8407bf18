//! Hard disks in a periodic rectangular box (paper section 5): N disks of diameter
//! sigma = 1 and mass m = 1, elastic collisions, straight flights in between.
//!
//! Internally the tangent rows of disk i are 4i..4i+4 = (dq_x, dq_y, dp_x, dp_y), so that a
//! collision touches two contiguous blocks; [`DynamicalSystem::internal_row`] maps the
//! paper's ordering (q_x1, q_y1, ..., q_yN ; p_x1, ..., p_yN) onto it.

pub mod collision;
pub mod events;
mod queue;

use super::{DynamicalSystem, Invariants, Snapshot, Tangent};
use crate::error::{Error, Result};
use crate::rng::Rng;
use events::{Disks, Engine};

#[derive(Clone, Debug)]
pub struct HardDisks {
    lx: f64,
    ly: f64,
    tau: f64,
    pos: Vec<[f64; 2]>,
    vel: Vec<[f64; 2]>,
    collisions: u64,
    engine: Engine,
}

/// Box sides (Lx, Ly) for N disks at density rho = N/(Lx Ly) and aspect ratio Ly/Lx.
pub fn box_sides(n: usize, density: f64, aspect: f64) -> (f64, f64) {
    let lx = (n as f64 / (density * aspect)).sqrt();
    (lx, aspect * lx)
}

impl HardDisks {
    /// N disks in an Lx x Ly box, started on a square-ish lattice (sites chosen at random
    /// when the lattice has more sites than disks) with random velocities, total momentum
    /// exactly zero and kinetic energy per disk K/N = 1.
    pub fn new(n: usize, lx: f64, ly: f64, tau: f64, seed: u64) -> Result<Self> {
        if n < 2 {
            return Err(Error::param("n", format!("need at least 2 disks, got {n}")));
        }
        check_box(lx, ly)?;
        if !(tau > 0.0 && tau.is_finite()) {
            return Err(Error::param("tau", format!("must be a positive number, got {tau}")));
        }
        let mut rng = Rng::new(seed);
        let pos = lattice(n, lx, ly, &mut rng)?;
        // Velocities in opposite pairs: the total momentum is exactly zero, summed in order.
        // An odd N ends with a triple v, w, -(v + w), so that no disk starts at rest.
        let mut vel = vec![[0.0; 2]; n];
        let pairs = if n % 2 == 1 && n >= 3 { (n - 3) / 2 } else { n / 2 };
        for p in 0..pairs {
            let g = [rng.normal(), rng.normal()];
            vel[2 * p] = g;
            vel[2 * p + 1] = [-g[0], -g[1]];
        }
        if n % 2 == 1 && n >= 3 {
            let (v, w) = ([rng.normal(), rng.normal()], [rng.normal(), rng.normal()]);
            vel[n - 3] = v;
            vel[n - 2] = w;
            vel[n - 1] = [-(v[0] + w[0]), -(v[1] + w[1])];
        }
        let k2: f64 = vel.iter().map(|v| v[0] * v[0] + v[1] * v[1]).sum();
        let scale = (2.0 * n as f64 / k2).sqrt();
        vel.iter_mut().for_each(|v| *v = [v[0] * scale, v[1] * scale]);
        if n % 2 == 1 && n >= 3 {
            // Scaled, -(v + w) is no longer exactly the negated sum: make it so again.
            vel[n - 1] = [-(vel[n - 3][0] + vel[n - 2][0]), -(vel[n - 3][1] + vel[n - 2][1])];
        }
        Ok(HardDisks { lx, ly, tau, pos, vel, collisions: 0, engine: Engine::default() })
    }

    /// Disks at given positions and velocities (any energy); validated for overlaps.
    pub fn from_state(lx: f64, ly: f64, tau: f64, pos: Vec<[f64; 2]>, vel: Vec<[f64; 2]>) -> Result<Self> {
        check_box(lx, ly)?;
        let n = pos.len();
        if vel.len() != n || n < 2 {
            return Err(Error::Other(format!("need at least 2 disks and as many velocities as positions ({} vs {})", n, vel.len())));
        }
        let mut s = HardDisks { lx, ly, tau, pos: vec![[0.0; 2]; n], vel: vec![[0.0; 2]; n], collisions: 0, engine: Engine::default() };
        let mut phase = vec![0.0; 4 * n];
        for i in 0..n {
            phase[2 * i..2 * i + 2].copy_from_slice(&pos[i]);
            phase[2 * n + 2 * i..2 * n + 2 * i + 2].copy_from_slice(&vel[i]);
        }
        s.restore(&Snapshot { phase, events: 0 })?;
        Ok(s)
    }

    pub fn n(&self) -> usize {
        self.pos.len()
    }
    pub fn box_size(&self) -> (f64, f64) {
        (self.lx, self.ly)
    }
    pub fn positions(&self) -> &[[f64; 2]] {
        &self.pos
    }
    pub fn velocities(&self) -> &[[f64; 2]] {
        &self.vel
    }

    /// Smallest centre distance over all pairs (minimum image); >= 1 means no overlap.
    pub fn min_separation(&self) -> f64 {
        min_separation(&self.pos, self.lx, self.ly).0
    }

    /// Minimum-image difference a - b of two positions.
    pub fn separation(&self, a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
        let d = |x: f64, l: f64| x - l * (x / l).round();
        [d(a[0] - b[0], self.lx), d(a[1] - b[1], self.ly)]
    }
}

/// Largest box side: positions carry absolute rounding errors of L * 2^-53, which must stay
/// far below the disk diameter for contact times to mean anything.
pub const MAX_SIDE: f64 = 1e9;

fn check_box(lx: f64, ly: f64) -> Result<()> {
    for (name, l) in [("lx", lx), ("ly", ly)] {
        if !(l.is_finite() && l > 1.0) {
            return Err(Error::param(name, format!(
                "the box side must exceed the disk diameter 1 (else a disk overlaps its own image), got {l}; \
                 lower --density or bring --aspect closer to 1 (or, giving the sides, a larger --{name})"
            )));
        }
        if l > MAX_SIDE {
            return Err(Error::param(name, format!(
                "a box side of {l:e} disk diameters is beyond {MAX_SIDE:e}, where rounding in the positions approaches the contact distance; \
                 raise --density or bring --aspect closer to 1 (or, giving the sides, a smaller --{name})"
            )));
        }
    }
    Ok(())
}

/// Start positions: the nx x ny lattice, square or with every other row shifted by half a
/// spacing (a triangular-like packing, periodic when ny is even), whose closest pair is
/// farthest apart among those that hold n disks.
fn lattice(n: usize, lx: f64, ly: f64, rng: &mut Rng) -> Result<Vec<[f64; 2]>> {
    let mut best: Option<(f64, usize, usize, bool)> = None;
    for ny in 1..=n {
        let nx = n.div_ceil(ny);
        let (ax, ay) = (lx / nx as f64, ly / ny as f64);
        let mut options = vec![(ax.min(ay), false)];
        if ny % 2 == 0 {
            options.push((ax.min((0.25 * ax * ax + ay * ay).sqrt()).min(2.0 * ay), true));
        }
        for (spacing, staggered) in options {
            if best.is_none_or(|(s, ..)| spacing > s) {
                best = Some((spacing, nx, ny, staggered));
            }
        }
    }
    let (spacing, nx, ny, staggered) = best.ok_or_else(|| Error::param("n", "must be at least 1 disk"))?;
    if spacing < 1.0 + 1e-9
        && let Some(sites) = skewed_lattice(n, lx, ly)
    {
        return Ok(sites);
    }
    if spacing < 1.0 + 1e-9 {
        return Err(Error::param("density", format!(
            "cannot place {n} disks without overlap in a {lx:.4} x {ly:.4} box (the best start lattice, {nx} x {ny}, has a closest pair at {spacing:.10}, not above 1 + 1e-9); \
             lower --density or change --aspect"
        )));
    }
    let (ax, ay) = (lx / nx as f64, ly / ny as f64);
    let mut sites: Vec<[f64; 2]> = (0..ny)
        .flat_map(|iy| {
            let shift = if staggered && iy % 2 == 1 { 0.5 } else { 0.0 };
            (0..nx).map(move |ix| [(ix as f64 + 0.25 + shift) * ax, (iy as f64 + 0.5) * ay])
        })
        .collect();
    if sites.len() > n {
        rng.shuffle(&mut sites);
        sites.truncate(n);
    }
    Ok(sites)
}

/// Where no row lattice fits (few disks in a small box: 5 at density 0.7 in a square), the
/// skewed lattice k -> (k Lx/n, (k s mod n) Ly/n), k < n, with the shear s that keeps its
/// closest pair farthest apart, if that pair is more than a diameter apart. A lattice on the
/// torus, so its closest pair is that of site 0: O(n) a shear.
fn skewed_lattice(n: usize, lx: f64, ly: f64) -> Option<Vec<[f64; 2]>> {
    if !(2..=20_000).contains(&n) {
        return None;
    }
    let wrap = |x: f64, l: f64| x - l * (x / l).round();
    let closest = |s: usize| {
        (1..n)
            .map(|k| wrap(k as f64 * lx / n as f64, lx).hypot(wrap(((k * s) % n) as f64 * ly / n as f64, ly)))
            .fold(f64::INFINITY, f64::min)
    };
    let (s, spacing) = (1..n).map(|s| (s, closest(s))).max_by(|a, b| a.1.total_cmp(&b.1))?;
    (spacing > 1.0 + 1e-9).then(|| (0..n).map(|k| [(k as f64 + 0.25) * lx / n as f64, (((k * s) % n) as f64 + 0.5) * ly / n as f64]).collect())
}

/// (distance, i, j) of the closest pair, minimum image.
fn min_separation(pos: &[[f64; 2]], lx: f64, ly: f64) -> (f64, usize, usize) {
    let mut best = (f64::INFINITY, 0, 0);
    let d = |x: f64, l: f64| x - l * (x / l).round();
    for i in 0..pos.len() {
        for j in i + 1..pos.len() {
            let dx = d(pos[i][0] - pos[j][0], lx);
            let dy = d(pos[i][1] - pos[j][1], ly);
            let r = (dx * dx + dy * dy).sqrt();
            if r < best.0 {
                best = (r, i, j);
            }
        }
    }
    best
}

impl DynamicalSystem for HardDisks {
    fn name(&self) -> &'static str {
        "disks"
    }
    fn dim(&self) -> usize {
        4 * self.pos.len()
    }
    fn tau(&self) -> f64 {
        self.tau
    }

    fn advance(&mut self, tangent: &mut Tangent) -> Result<()> {
        debug_assert_eq!(tangent.dim(), self.dim());
        let mut d = Disks { lx: self.lx, ly: self.ly, pos: &mut self.pos, vel: &mut self.vel };
        self.collisions += self.engine.run(&mut d, tangent, self.tau)?;
        Ok(())
    }

    fn set_threads(&mut self, threads: usize) {
        self.engine.threads = threads;
    }

    fn snapshot(&self) -> Snapshot {
        let n = self.pos.len();
        let mut phase = vec![0.0; 4 * n];
        for i in 0..n {
            phase[2 * i..2 * i + 2].copy_from_slice(&self.pos[i]);
            phase[2 * n + 2 * i..2 * n + 2 * i + 2].copy_from_slice(&self.vel[i]);
        }
        Snapshot { phase, events: self.collisions }
    }

    fn restore(&mut self, s: &Snapshot) -> Result<()> {
        let n = self.pos.len();
        if s.phase.len() != 4 * n {
            return Err(Error::Dynamics(format!("a state of {n} disks needs {} numbers, got {}", 4 * n, s.phase.len())));
        }
        if let Some(i) = s.phase.iter().position(|x| !x.is_finite()) {
            return Err(Error::Dynamics(format!("phase component {i} is not finite ({})", s.phase[i])));
        }
        let mut pos: Vec<[f64; 2]> = (0..n).map(|i| [s.phase[2 * i], s.phase[2 * i + 1]]).collect();
        for p in &mut pos {
            *p = [events::wrap(p[0], self.lx), events::wrap(p[1], self.ly)];
        }
        let (r, i, j) = min_separation(&pos, self.lx, self.ly);
        if r < 1.0 - 1e-6 {
            return Err(Error::Dynamics(format!("disks {i} and {j} overlap (centre distance {r} < 1)")));
        }
        self.pos = pos;
        self.vel = (0..n).map(|i| [s.phase[2 * n + 2 * i], s.phase[2 * n + 2 * i + 1]]).collect();
        self.collisions = s.events;
        Ok(())
    }

    fn internal_row(&self, i: usize) -> usize {
        let two_n = 2 * self.pos.len();
        let (half, c) = if i < two_n { (0, i) } else { (2, i - two_n) };
        4 * (c / 2) + half + c % 2
    }

    fn invariants(&self) -> Invariants {
        let mut inv = Invariants { events: self.collisions, ..Default::default() };
        for v in &self.vel {
            inv.energy += 0.5 * (v[0] * v[0] + v[1] * v[1]);
            inv.momentum[0] += v[0];
            inv.momentum[1] += v[1];
        }
        inv
    }
}

#[cfg(test)]
mod tests;
