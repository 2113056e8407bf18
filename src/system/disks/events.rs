//! Event-driven molecular dynamics of hard disks over one interval tau.
//!
//! Why it is built this way:
//! - Cell lists (cells at least sigma wide) make the cost of a collision independent of N.
//!   Pairs are found through the 3 x 3 neighbouring cells, and the periodic image of a
//!   partner is fixed by the cell offset, not by a minimum-image guess; this also handles
//!   boxes with fewer than three cells in a direction, where a disk may meet two images.
//! - Each particle keeps only its earliest predicted event, queued by time in a bucket
//!   queue ([`super::queue`]); per-particle counters invalidate stale events. A popped event
//!   whose partner has moved on is not lost: its owner is predicted again at that time.
//! - Within an interval the disks are stored in cell order, one cache line each, and each
//!   cell lists its members in a fixed block of slots: the neighbours an event reads lie
//!   together in memory. With N = 19800 (beyond the L2 cache) this and the bucket queue
//!   made a collision 1.5-2x faster than a binary heap and the caller's order (measured with
//!   examples/collision_scaling.rs), with the same order of events, ties included, and the
//!   same bits (spectra of runs with N = 30, 198 and 1980, and N = 100 at tau = 20,
//!   compared).
//! - Positions and tangent rows are updated lazily, each particle at its own time, so an
//!   event touches two particles only.
//! - Every interval starts from scratch (times relative to the interval start, cells and
//!   events rebuilt from positions): event times keep full precision over arbitrarily long
//!   runs, and a state restored from a snapshot continues bit for bit.

use super::collision;
use super::queue::{EventQueue, Queued};
use crate::error::{Error, Result};
use crate::system::Tangent;
use std::ops::Range;

#[derive(Clone, Copy, Debug)]
enum Kind {
    /// Collision with partner j, whose image is shifted by (sx Lx, sy Ly).
    Collision { sx: i8, sy: i8 },
    /// Crossing into the neighbouring cell along `axis` (0 = x, 1 = y) in direction `dir`.
    Crossing { axis: u8, dir: i8 },
}

/// A disk's predicted event, kept with it: the queue holds only its time and owner.
#[derive(Clone, Copy, Debug)]
struct Pending {
    /// The partner's local index and its event counter when predicted.
    j: u32,
    cj: u32,
    kind: Kind,
}

impl Default for Pending {
    fn default() -> Self {
        Pending { j: u32::MAX, cj: 0, kind: Kind::Crossing { axis: 0, dir: 0 } }
    }
}

/// A disk as the engine moves it within an interval: all that an event of the disk reads
/// and writes, in one cache line.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Disk {
    /// Position at time `t_pos` (not wrapped between crossings).
    r: [f64; 2],
    v: [f64; 2],
    t_pos: f64,
    /// Event counter: predictions made before it last changed are stale.
    count: u32,
    cell: [u32; 2],
    pending: Pending,
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

/// Slots per cell at least (a cell has room for twice the most disks any cell starts with).
const MIN_CELL_SLOTS: usize = 8;

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
    /// The disks in cell order (local index), so that neighbours are near in memory.
    disks: Vec<Disk>,
    /// Time up to which local disk l's tangent rows have been advanced.
    t_tan: Vec<f64>,
    /// Caller's index of local disk l.
    id: Vec<u32>,
    /// The cell of the caller's disk i (row-major index), while sorting.
    cell_of_id: Vec<u32>,
    /// Members (local indices) of cell c: `slots[c * cap..][..fill[c]]`.
    slots: Vec<u32>,
    fill: Vec<u32>,
    cap: usize,
    /// The first local index of each cell at the interval's start.
    cell_start: Vec<u32>,
    queue: EventQueue,
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

/// The least normal speed, as a fraction of the relative speed, at which two disks count as
/// approaching. Below it the sign of r . v is rounding: a collision there changes the
/// velocities by less than their last digits, so the pair would approach again at once and
/// the event loop would repeat it at one instant for ever. With impact parameters uniform,
/// a collision this close to grazing has probability (1e-9)^2 / 2 = 5e-19.
const GRAZING: f64 = 1e-9;

/// Events per disk and unit time beyond which a run is refused as too close to close
/// packing to finish: gaps of about 1e-7 diameters (a start lattice may pass the packing
/// check with gaps of 1e-9). Near close packing a valid state has millions (8 disks 1e-6
/// short of a crystal: 2.4e6 collisions per disk and unit time; packing fraction 0.9, gaps
/// of 0.4 %, some hundreds); the stall test alone let 36 disks at number density
/// 1.1547 run 4 minutes for one step of tau = 0.6, to end in a tangent blow-up.
const MAX_EVENT_RATE: f64 = 1e7;

/// Whether two disks at relative position r (squared length `r2`) with relative velocity v
/// (squared length `v2`) approach, b = r . v: the one test of [`contact_time`] and
/// [`Engine::collide`], so that a pair the collision refuses is never predicted again.
fn approaching(b: f64, r2: f64, v2: f64) -> bool {
    b < 0.0 && b * b > GRAZING * GRAZING * r2 * v2
}

/// Time until two disks at relative position r with relative velocity v touch
/// (sigma = 1), or None if they do not approach ([`approaching`]) or miss. The root is
/// taken in the form c / (-b + sqrt(disc)), which stays accurate for grazing collisions; a
/// pair that overlaps by rounding and approaches collides at once.
pub fn contact_time(r: [f64; 2], v: [f64; 2]) -> Option<f64> {
    let b = r[0] * v[0] + r[1] * v[1];
    // Receding, the common case, decided before anything else is computed.
    if b >= 0.0 {
        return None;
    }
    let r2 = r[0] * r[0] + r[1] * r[1];
    let v2 = v[0] * v[0] + v[1] * v[1];
    if !approaching(b, r2, v2) {
        return None;
    }
    let c = r2 - 1.0;
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
        let sides = [d.lx, d.ly];
        self.rebuild(d);
        self.queue.reset(n);
        for i in 0..n {
            self.predict(i, 0.0, tau, sides);
        }
        let mut collisions = 0u64;
        // A stall is time standing still, not a high rate: near close packing a valid state
        // has millions of collisions per disk and unit time.
        let stall = 1000 + 100 * n as u64;
        let (mut now, mut at_now, mut events) = (f64::NEG_INFINITY, 0u64, 0u64);
        while let Some(ev) = self.queue.pop() {
            if ev.t > now {
                (now, at_now) = (ev.t, 0);
            }
            at_now += 1;
            if at_now > stall {
                return Err(Error::Dynamics(format!(
                    "the event loop stalled: more than {stall} events at one instant, t = {now} \
                     within the interval of tau = {tau}, without time moving on; the state is \
                     degenerate (disks in contact that cannot separate)"
                )));
            }
            events += 1;
            if events.is_multiple_of(1 << 20) && now > 0.0 {
                let rate = events as f64 / (n as f64 * now);
                if rate > MAX_EVENT_RATE {
                    return Err(Error::Dynamics(format!(
                        "{rate:.1e} events per disk and unit time (at t = {now:.3e} within the interval of tau = {tau}): \
                         the disks are packed so close that their gaps are about {:.0e} diameters, and every unit of time \
                         takes {:.1e} events, some of them grazing enough to blow up the tangent vectors; lower --density",
                        1.0 / rate,
                        rate * n as f64
                    )));
                }
            }
            let i = ev.l as usize;
            if ev.ci != self.disks[i].count {
                continue;
            }
            let p = self.disks[i].pending;
            match p.kind {
                Kind::Crossing { axis, dir } => self.cross(i, axis as usize, dir, ev.t, tau, sides),
                Kind::Collision { sx, sy } => {
                    let j = p.j as usize;
                    if p.cj != self.disks[j].count {
                        self.predict(i, ev.t, tau, sides);
                        continue;
                    }
                    if self.collide(k, i, j, [sx, sy], ev.t, sides) {
                        collisions += 1;
                        self.predict(i, ev.t, tau, sides);
                        self.predict(j, ev.t, tau, sides);
                    } else {
                        self.predict(i, ev.t, tau, sides);
                    }
                }
            }
        }
        for (l, disk) in self.disks.iter().enumerate() {
            let i = self.id[l] as usize;
            let dt = tau - disk.t_pos;
            for a in 0..2 {
                d.pos[i][a] = wrap(disk.r[a] + disk.v[a] * dt, sides[a]);
            }
            d.vel[i] = disk.v;
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
        for (&i, t) in self.id.iter().zip(&self.t_tan) {
            let [qx, qy, px, py] = disk(i as usize);
            collision::fly_rows([qx, qy], [px, py], tau - t);
        }
    }

    /// Start an interval: the caller's disks sorted into cells (a stable counting sort, so
    /// that each cell lists its disks in the caller's order), positions wrapped into the box.
    fn rebuild(&mut self, d: &Disks) {
        let n = d.pos.len();
        let sides = [d.lx, d.ly];
        self.nc = cell_counts(d.lx, d.ly, n);
        self.w = [d.lx / self.nc[0] as f64, d.ly / self.nc[1] as f64];
        let cells = self.nc[0] * self.nc[1];
        self.fill.clear();
        self.fill.resize(cells, 0);
        self.cell_of_id.resize(n, 0);
        for (i, p) in d.pos.iter().enumerate() {
            let c = self.cell_of([wrap(p[0], sides[0]), wrap(p[1], sides[1])]);
            let c = c[1] as usize * self.nc[0] + c[0] as usize;
            self.cell_of_id[i] = c as u32;
            self.fill[c] += 1;
        }
        // The first local index of each cell, then each disk's own.
        let mut next = 0u32;
        self.cell_start.clear();
        self.cell_start.extend(self.fill.iter().map(|&f| {
            next += f;
            next - f
        }));
        self.cap = (2 * self.fill.iter().max().copied().unwrap_or(0) as usize).max(MIN_CELL_SLOTS);
        // Slots past a cell's fill are never read: only the length matters.
        self.slots.resize(cells * self.cap, 0);
        self.fill.iter_mut().for_each(|f| *f = 0);
        self.id.resize(n, 0);
        self.disks.resize(n, Disk::default());
        self.t_tan.clear();
        self.t_tan.resize(n, 0.0);
        for i in 0..n {
            let c = self.cell_of_id[i] as usize;
            let l = self.cell_start[c] as usize + self.fill[c] as usize;
            self.slots[c * self.cap + self.fill[c] as usize] = l as u32;
            self.fill[c] += 1;
            self.id[l] = i as u32;
            let r = [wrap(d.pos[i][0], sides[0]), wrap(d.pos[i][1], sides[1])];
            let cell = [(c % self.nc[0]) as u32, (c / self.nc[0]) as u32];
            self.disks[l] = Disk { r, v: d.vel[i], t_pos: 0.0, count: 0, cell, pending: Pending::default() };
        }
        self.log.clear();
    }

    /// Slots per cell in the interval just run (tests: whether they grew).
    #[cfg(test)]
    pub(super) fn slots_per_cell(&self) -> usize {
        self.cap
    }

    /// Times the event queue's window moved on in the interval just run.
    #[cfg(test)]
    pub(super) fn queue_window_moves(&self) -> u64 {
        self.queue.moves
    }

    fn cell_of(&self, r: [f64; 2]) -> [u32; 2] {
        [0, 1].map(|a| ((r[a] / self.w[a]) as usize).min(self.nc[a] - 1) as u32)
    }

    /// The members of cell `c` (row-major index), as local indices.
    fn members(&self, c: usize) -> &[u32] {
        &self.slots[c * self.cap..c * self.cap + self.fill[c] as usize]
    }

    /// Add local disk l to cell `c`, after its members; the slots of every cell double when
    /// one is full (rare: a cell narrower than 2 holds at most 9 disks; only dilute gases get
    /// wider cells).
    fn enter(&mut self, c: usize, l: u32) {
        if self.fill[c] as usize == self.cap {
            let cap = 2 * self.cap;
            let mut slots = vec![0; self.fill.len() * cap];
            for (cell, &f) in self.fill.iter().enumerate() {
                slots[cell * cap..cell * cap + f as usize].copy_from_slice(&self.slots[cell * self.cap..cell * self.cap + f as usize]);
            }
            self.slots = slots;
            self.cap = cap;
        }
        self.slots[c * self.cap + self.fill[c] as usize] = l;
        self.fill[c] += 1;
    }

    /// Remove local disk l from cell `c`, the last member taking its place.
    fn leave(&mut self, c: usize, l: u32) {
        let f = self.fill[c] as usize;
        let members = &mut self.slots[c * self.cap..c * self.cap + f];
        if let Some(at) = members.iter().position(|&m| m == l) {
            members[at] = members[f - 1];
            self.fill[c] -= 1;
        }
    }

    /// Schedule the earliest event of local disk i after time `now` (if it falls within
    /// tau).
    fn predict(&mut self, i: usize, now: f64, tau: f64, sides: [f64; 2]) {
        let me = self.disks[i];
        let ri = me.position(now);
        let vi = me.v;
        let ci = me.cell;
        let mut best_t = f64::INFINITY;
        let mut best = Pending::default();
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
            if t < best_t {
                best_t = t;
                best.kind = Kind::Crossing { axis: a as u8, dir };
            }
        }
        for oy in -1..=1i64 {
            let (cy, sy) = wrap_cell(ci[1] as i64 + oy, self.nc[1]);
            for ox in -1..=1i64 {
                let (cx, sx) = wrap_cell(ci[0] as i64 + ox, self.nc[0]);
                for &j in self.members(cy * self.nc[0] + cx) {
                    if j as usize == i {
                        continue;
                    }
                    let other = &self.disks[j as usize];
                    let rj = other.position(now);
                    let r = [ri[0] - rj[0] - sx as f64 * sides[0], ri[1] - rj[1] - sy as f64 * sides[1]];
                    let v = [vi[0] - other.v[0], vi[1] - other.v[1]];
                    if let Some(dt) = contact_time(r, v) {
                        let t = now + dt;
                        if t < best_t {
                            best_t = t;
                            best = Pending { j, cj: other.count, kind: Kind::Collision { sx, sy } };
                        }
                    }
                }
            }
        }
        if best_t <= tau {
            self.disks[i].pending = best;
            self.queue.push(Queued { t: best_t, id: self.id[i], l: i as u32, ci: me.count });
        }
    }

    fn cross(&mut self, i: usize, axis: usize, dir: i8, t: f64, tau: f64, sides: [f64; 2]) {
        let disk = &mut self.disks[i];
        disk.r = disk.position(t);
        disk.t_pos = t;
        let old = disk.cell;
        let (c, s) = wrap_cell(old[axis] as i64 + dir as i64, self.nc[axis]);
        disk.r[axis] -= s as f64 * sides[axis];
        let mut new = old;
        new[axis] = c as u32;
        disk.cell = new;
        disk.count = disk.count.wrapping_add(1);
        let nx = self.nc[0];
        self.leave(old[1] as usize * nx + old[0] as usize, i as u32);
        self.enter(new[1] as usize * nx + new[0] as usize, i as u32);
        self.predict(i, t, tau, sides);
    }

    /// Carry out the collision of local disks i and j (the image `shift` of j) at time t,
    /// for the phase point and the tangent vectors. Returns false (and changes nothing) if
    /// rounding has left the pair not approaching: then [`contact_time`], computed from the
    /// same r and v, does not predict it again.
    fn collide(&mut self, k: usize, i: usize, j: usize, shift: [i8; 2], t: f64, sides: [f64; 2]) -> bool {
        let (a, b) = (self.disks[i], self.disks[j]);
        let ri = a.position(t);
        let rj = b.position(t);
        let r = [ri[0] - rj[0] - shift[0] as f64 * sides[0], ri[1] - rj[1] - shift[1] as f64 * sides[1]];
        let v = [a.v[0] - b.v[0], a.v[1] - b.v[1]];
        let r2 = r[0] * r[0] + r[1] * r[1];
        let rv = r[0] * v[0] + r[1] * v[1];
        if !approaching(rv, r2, v[0] * v[0] + v[1] * v[1]) {
            return false;
        }
        let dist = r2.sqrt();
        let n = [r[0] / dist, r[1] / dist];
        // Beyond GRAZING, v . n has the sign of r . v whatever the rounding.
        let vn = v[0] * n[0] + v[1] * n[1];
        if k > 0 {
            self.log.push(TangentCollision { i: self.id[i], j: self.id[j], dt_i: t - self.t_tan[i], dt_j: t - self.t_tan[j], n, v, vn });
            self.t_tan[i] = t;
            self.t_tan[j] = t;
        }
        for (l, r, sign) in [(i, ri, -1.0), (j, rj, 1.0)] {
            let disk = &mut self.disks[l];
            disk.r = r;
            disk.t_pos = t;
            for a in 0..2 {
                disk.v[a] += sign * vn * n[a];
            }
            disk.count = disk.count.wrapping_add(1);
        }
        true
    }
}

impl Disk {
    fn position(&self, t: f64) -> [f64; 2] {
        let dt = t - self.t_pos;
        [self.r[0] + self.v[0] * dt, self.r[1] + self.v[1] * dt]
    }
}
