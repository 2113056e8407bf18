//! Event-driven molecular dynamics of hard disks over one interval tau.
//!
//! Why it is built this way:
//! - Cell lists (cells at least sigma wide) make the cost of a collision independent of N.
//!   Pairs are found through the 3 x 3 neighbouring cells, and the periodic image of a
//!   partner is fixed by the cell offset, not by a minimum-image guess; this also handles
//!   boxes with fewer than three cells in a direction, where a disk may meet two images.
//! - Each particle keeps only its earliest predicted event in a binary heap; per-particle
//!   counters invalidate stale events. A popped event whose partner has moved on is not
//!   lost: its owner is predicted again at that time.
//! - Positions and tangent rows are updated lazily, each particle at its own time, so an
//!   event touches two particles only.
//! - Every interval starts from scratch (times relative to the interval start, cells and
//!   events rebuilt from positions): event times keep full precision over arbitrarily long
//!   runs, and a state restored from a snapshot continues bit for bit.

use super::collision;
use crate::error::{Error, Result};
use crate::system::Tangent;
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::ops::Range;

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// Collision with partner j, whose image is shifted by (sx Lx, sy Ly).
    Collision { sx: i8, sy: i8 },
    /// Crossing into the neighbouring cell along `axis` (0 = x, 1 = y) in direction `dir`.
    Crossing { axis: u8, dir: i8 },
}

#[derive(Clone, Copy, Debug)]
struct Event {
    t: f64,
    i: u32,
    j: u32,
    ci: u32,
    cj: u32,
    kind: Kind,
}

impl PartialEq for Event {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Event {}
impl PartialOrd for Event {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Event {
    /// Reversed, so that `BinaryHeap` pops the earliest event; ties are broken by the
    /// particle indices, which keeps the order total and the run deterministic.
    fn cmp(&self, o: &Self) -> Ordering {
        o.t.total_cmp(&self.t).then(o.i.cmp(&self.i)).then(o.j.cmp(&self.j))
    }
}

/// Positions, velocities and box of the disks; what the engine moves.
pub struct Disks<'a> {
    pub lx: f64,
    pub ly: f64,
    pub pos: &'a mut [[f64; 2]],
    pub vel: &'a mut [[f64; 2]],
}

/// A collision as the tangent vectors see it: the free flights of both disks since their
/// last update, then the linearised collision map.
#[derive(Clone, Copy, Debug)]
struct TangentCollision {
    i: u32,
    j: u32,
    dt_i: f64,
    dt_j: f64,
    n: [f64; 2],
    v: [f64; 2],
    vn: f64,
}

/// Columns of the tangent block processed together when the collisions of an interval are
/// replayed: 4N rows of this many columns stay in the L2 cache (792 x 32 x 8 B = 200 kB)
/// instead of the whole block streaming through memory once per collision.
const COLUMN_BLOCK: usize = 32;

/// The tangent block shared by the replay workers, each of which owns a block of columns.
struct SharedBlock {
    ptr: *mut f64,
    len: usize,
    k: usize,
}

unsafe impl Sync for SharedBlock {}

impl SharedBlock {
    /// Columns `cols` of row `row`. Safety: no other live slice overlaps it.
    #[allow(clippy::mut_from_ref)]
    unsafe fn row(&self, row: usize, cols: &Range<usize>) -> &mut [f64] {
        assert!(cols.start <= cols.end && cols.end <= self.k && row * self.k + cols.end <= self.len);
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(row * self.k + cols.start), cols.len()) }
    }
}

/// Scratch space reused from interval to interval (no allocation per step).
#[derive(Clone, Debug, Default)]
pub struct Engine {
    /// Threads for the replay of the tangent block (0 or 1: the calling thread only).
    pub threads: usize,
    /// The interval's collisions, replayed on the tangent block column block by block.
    log: Vec<TangentCollision>,
    nc: [usize; 2],
    w: [f64; 2],
    cell: Vec<[u32; 2]>,
    members: Vec<Vec<u32>>,
    t_pos: Vec<f64>,
    t_tan: Vec<f64>,
    count: Vec<u32>,
    heap: BinaryHeap<Event>,
}

/// Cells per direction: as many as fit with a width of at least sigma (with a margin so
/// that rounding never makes a cell narrower than a contact distance).
fn cells_along(l: f64) -> usize {
    ((l / (1.0 + 1e-9)).floor() as usize).max(1)
}

/// Cells per direction for `n` disks: [`cells_along`] each side, unless that makes more than
/// four cells per disk (a dilute gas), where wider cells keep the number near that (clearing
/// and scanning empty cells would cost more than the collisions).
pub(super) fn cell_counts(lx: f64, ly: f64, n: usize) -> [usize; 2] {
    let fine = [cells_along(lx), cells_along(ly)];
    let most = 4 * n.max(4);
    if fine[0].saturating_mul(fine[1]) <= most {
        return fine;
    }
    let w = (lx * ly / most as f64).sqrt();
    [((lx / w) as usize).clamp(1, fine[0]), ((ly / w) as usize).clamp(1, fine[1])]
}

fn wrap_cell(c: i64, n: usize) -> (usize, i8) {
    if c < 0 {
        ((c + n as i64) as usize, -1)
    } else if c >= n as i64 {
        ((c - n as i64) as usize, 1)
    } else {
        (c as usize, 0)
    }
}

/// Wrap a coordinate into [0, l).
pub fn wrap(x: f64, l: f64) -> f64 {
    let mut x = x;
    if x < 0.0 {
        x += l;
    }
    if x >= l {
        x -= l;
    }
    x
}

/// Time until two disks at relative position r with relative velocity v touch
/// (sigma = 1), or None if they do not approach or miss. The root is taken in the form
/// c / (-b + sqrt(disc)), which stays accurate for grazing collisions; a pair that
/// overlaps by rounding and approaches collides at once.
pub fn contact_time(r: [f64; 2], v: [f64; 2]) -> Option<f64> {
    let b = r[0] * v[0] + r[1] * v[1];
    if b >= 0.0 {
        return None;
    }
    let v2 = v[0] * v[0] + v[1] * v[1];
    let c = r[0] * r[0] + r[1] * r[1] - 1.0;
    let disc = b * b - v2 * c;
    if disc <= 0.0 {
        return None;
    }
    Some((c / (-b + disc.sqrt())).max(0.0))
}

impl Engine {
    /// Advance the disks and the tangent block (rows 4i..4i+4 belong to disk i) over tau.
    /// Returns the number of collisions.
    pub fn run(&mut self, d: &mut Disks, tangent: &mut Tangent, tau: f64) -> Result<u64> {
        let n = d.pos.len();
        let k = tangent.count();
        self.rebuild(d);
        for i in 0..n {
            self.predict(d, i, 0.0, tau);
        }
        let mut collisions = 0u64;
        let mut events = 0u64;
        let limit = (100_000 * n as u64).saturating_mul((tau.ceil() as u64).max(1)).saturating_add(1_000_000);
        while let Some(ev) = self.heap.pop() {
            events += 1;
            if events > limit {
                return Err(Error::Dynamics(format!(
                    "the event loop stalled: more than {limit} events within one tau = {tau} \
                     at t = {} (inside the interval); the state is probably degenerate",
                    ev.t
                )));
            }
            let i = ev.i as usize;
            if ev.ci != self.count[i] {
                continue;
            }
            match ev.kind {
                Kind::Crossing { axis, dir } => self.cross(d, i, axis as usize, dir, ev.t, tau),
                Kind::Collision { sx, sy } => {
                    let j = ev.j as usize;
                    if ev.cj != self.count[j] {
                        self.predict(d, i, ev.t, tau);
                        continue;
                    }
                    if self.collide(d, k, i, j, [sx, sy], ev.t) {
                        collisions += 1;
                        self.predict(d, i, ev.t, tau);
                        self.predict(d, j, ev.t, tau);
                    } else {
                        self.predict(d, i, ev.t, tau);
                    }
                }
            }
        }
        for i in 0..n {
            let dt = tau - self.t_pos[i];
            for a in 0..2 {
                let l = if a == 0 { d.lx } else { d.ly };
                d.pos[i][a] = wrap(d.pos[i][a] + d.vel[i][a] * dt, l);
            }
        }
        if k > 0 {
            self.replay(tangent, tau);
        }
        Ok(collisions)
    }

    /// Apply the interval's collisions and the final free flights to the tangent block,
    /// one block of columns at a time. The column blocks are independent, so `threads`
    /// workers each take a contiguous run of them (runs rather than alternate blocks, so
    /// that two workers never share the cache lines at a block boundary for long). The
    /// operations per column are the same, so the result does not depend on the number of
    /// threads.
    fn replay(&self, tangent: &mut Tangent, tau: f64) {
        let k = tangent.count();
        let blocks = k.div_ceil(COLUMN_BLOCK);
        let rows = tangent.rows_mut();
        let g = SharedBlock { ptr: rows.as_mut_ptr(), len: rows.len(), k };
        let workers = self.threads.clamp(1, blocks.max(1));
        let work = |w: usize| {
            for b in blocks * w / workers..blocks * (w + 1) / workers {
                // Safety: block b belongs to worker w alone.
                unsafe { self.replay_block(&g, b * COLUMN_BLOCK..((b + 1) * COLUMN_BLOCK).min(k), tau) };
            }
        };
        if workers == 1 {
            work(0);
        } else {
            rayon::scope(|s| {
                for w in 1..workers {
                    s.spawn(move |_| work(w));
                }
                work(0);
            });
        }
    }

    /// [`Engine::replay`] on the columns `cols`. Safety: no other thread touches them.
    unsafe fn replay_block(&self, g: &SharedBlock, cols: Range<usize>, tau: f64) {
        // Safety (all rows below): the rows of disks i != j are distinct.
        let disk = |i: usize| unsafe { [0, 1, 2, 3].map(|r| g.row(4 * i + r, &cols)) };
        for e in &self.log {
            let [qxi, qyi, pxi, pyi] = disk(e.i as usize);
            let [qxj, qyj, pxj, pyj] = disk(e.j as usize);
            collision::fly_rows([&mut *qxi, &mut *qyi], [pxi, pyi], e.dt_i);
            collision::fly_rows([&mut *qxj, &mut *qyj], [pxj, pyj], e.dt_j);
            collision::collide_rows([qxi, qyi, pxi, pyi, qxj, qyj, pxj, pyj], e.n, e.v, e.vn);
        }
        for (i, t) in self.t_tan.iter().enumerate() {
            let [qx, qy, px, py] = disk(i);
            collision::fly_rows([qx, qy], [px, py], tau - t);
        }
    }

    fn rebuild(&mut self, d: &mut Disks) {
        let n = d.pos.len();
        self.nc = cell_counts(d.lx, d.ly, n);
        self.w = [d.lx / self.nc[0] as f64, d.ly / self.nc[1] as f64];
        self.members.resize_with(self.nc[0] * self.nc[1], Vec::new);
        self.members.truncate(self.nc[0] * self.nc[1]);
        self.members.iter_mut().for_each(Vec::clear);
        self.cell.resize(n, [0, 0]);
        self.t_pos.clear();
        self.t_pos.resize(n, 0.0);
        self.t_tan.clear();
        self.t_tan.resize(n, 0.0);
        self.log.clear();
        self.count.clear();
        self.count.resize(n, 0);
        self.heap.clear();
        for i in 0..n {
            let mut c = [0u32; 2];
            for a in 0..2 {
                let l = if a == 0 { d.lx } else { d.ly };
                d.pos[i][a] = wrap(d.pos[i][a], l);
                c[a] = ((d.pos[i][a] / self.w[a]) as usize).min(self.nc[a] - 1) as u32;
            }
            self.cell[i] = c;
            self.members[c[1] as usize * self.nc[0] + c[0] as usize].push(i as u32);
        }
    }

    fn position(&self, d: &Disks, i: usize, t: f64) -> [f64; 2] {
        let dt = t - self.t_pos[i];
        [d.pos[i][0] + d.vel[i][0] * dt, d.pos[i][1] + d.vel[i][1] * dt]
    }

    /// Schedule the earliest event of disk i after time `now` (if it falls within tau).
    fn predict(&mut self, d: &Disks, i: usize, now: f64, tau: f64) {
        let ri = self.position(d, i, now);
        let vi = d.vel[i];
        let ci = self.cell[i];
        let mut best = Event { t: f64::INFINITY, i: i as u32, j: u32::MAX, ci: self.count[i], cj: 0, kind: Kind::Crossing { axis: 0, dir: 0 } };
        for a in 0..2 {
            let (lo, hi) = (ci[a] as f64 * self.w[a], (ci[a] + 1) as f64 * self.w[a]);
            let (dt, dir) = if vi[a] > 0.0 {
                ((hi - ri[a]) / vi[a], 1)
            } else if vi[a] < 0.0 {
                ((lo - ri[a]) / vi[a], -1)
            } else {
                continue;
            };
            let t = now + dt.max(0.0);
            if t < best.t {
                best.t = t;
                best.kind = Kind::Crossing { axis: a as u8, dir };
            }
        }
        let shift = [d.lx, d.ly];
        for oy in -1..=1i64 {
            let (cy, sy) = wrap_cell(ci[1] as i64 + oy, self.nc[1]);
            for ox in -1..=1i64 {
                let (cx, sx) = wrap_cell(ci[0] as i64 + ox, self.nc[0]);
                for &j in &self.members[cy * self.nc[0] + cx] {
                    let j = j as usize;
                    if j == i {
                        continue;
                    }
                    let rj = self.position(d, j, now);
                    let r = [ri[0] - rj[0] - sx as f64 * shift[0], ri[1] - rj[1] - sy as f64 * shift[1]];
                    let v = [vi[0] - d.vel[j][0], vi[1] - d.vel[j][1]];
                    if let Some(dt) = contact_time(r, v) {
                        let t = now + dt;
                        if t < best.t {
                            best = Event { t, i: i as u32, j: j as u32, ci: self.count[i], cj: self.count[j], kind: Kind::Collision { sx, sy } };
                        }
                    }
                }
            }
        }
        if best.t <= tau {
            self.heap.push(best);
        }
    }

    fn cross(&mut self, d: &mut Disks, i: usize, axis: usize, dir: i8, t: f64, tau: f64) {
        d.pos[i] = self.position(d, i, t);
        self.t_pos[i] = t;
        let old = self.cell[i];
        let (c, s) = wrap_cell(old[axis] as i64 + dir as i64, self.nc[axis]);
        let l = if axis == 0 { d.lx } else { d.ly };
        d.pos[i][axis] -= s as f64 * l;
        let mut new = old;
        new[axis] = c as u32;
        let from = &mut self.members[old[1] as usize * self.nc[0] + old[0] as usize];
        if let Some(at) = from.iter().position(|&m| m as usize == i) {
            from.swap_remove(at);
        }
        self.members[new[1] as usize * self.nc[0] + new[0] as usize].push(i as u32);
        self.cell[i] = new;
        self.count[i] = self.count[i].wrapping_add(1);
        self.predict(d, i, t, tau);
    }

    /// Carry out the collision of i with the image `shift` of j at time t, for the phase
    /// point and the tangent vectors. Returns false (and changes nothing) if rounding has
    /// left the pair not approaching.
    #[allow(clippy::too_many_arguments)]
    fn collide(&mut self, d: &mut Disks, k: usize, i: usize, j: usize, shift: [i8; 2], t: f64) -> bool {
        let ri = self.position(d, i, t);
        let rj = self.position(d, j, t);
        let r = [ri[0] - rj[0] - shift[0] as f64 * d.lx, ri[1] - rj[1] - shift[1] as f64 * d.ly];
        let dist = (r[0] * r[0] + r[1] * r[1]).sqrt();
        let n = [r[0] / dist, r[1] / dist];
        let v = [d.vel[i][0] - d.vel[j][0], d.vel[i][1] - d.vel[j][1]];
        let vn = v[0] * n[0] + v[1] * n[1];
        if vn >= 0.0 {
            return false;
        }
        d.pos[i] = ri;
        d.pos[j] = rj;
        self.t_pos[i] = t;
        self.t_pos[j] = t;
        if k > 0 {
            self.log.push(TangentCollision { i: i as u32, j: j as u32, dt_i: t - self.t_tan[i], dt_j: t - self.t_tan[j], n, v, vn });
            self.t_tan[i] = t;
            self.t_tan[j] = t;
        }
        for a in 0..2 {
            d.vel[i][a] -= vn * n[a];
            d.vel[j][a] += vn * n[a];
        }
        self.count[i] = self.count[i].wrapping_add(1);
        self.count[j] = self.count[j].wrapping_add(1);
        true
    }
}
