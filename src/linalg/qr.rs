//! The QR step Gbar_n = G_n R_n (paper Sec. 3) with explicit G_n and a positive diagonal of R.
//!
//! A forward step spends nearly all its time here (8/3 D^3 flops for k = D), so this is our
//! own driver around faer's sequential kernels, built to use two cores well:
//! - the factorisation is right-looking blocked Householder on panels of 32 columns with
//!   one panel of lookahead: the trailing columns are dealt out to the workers in chunks of
//!   whole panels, and the owner of the next panel updates and factors it first, so that
//!   the others never wait long for it;
//! - Q is formed the way LAPACK's orgqr does (reflector blocks from last to first, each
//!   only on the part of Q it can change, a third fewer flops than on a full identity), but
//!   one column chunk at a time, taken from a shared counter: the chunks are independent
//!   and stay in cache.
//!
//! The workers are a [`Crew`] of our own threads, because they wait on each other. The
//! chunk grids do not depend on the number of threads, so neither do the bits of the result
//! (tested). faer's blocked QR with its own threading took 26-37 ms at D = 792 on two cores,
//! this driver 14.5-15.4 ms with subnormals flushed (examples/qr_blocks.rs, qr_realistic.rs). The sign fix (diag R > 0) makes G_n unique, so that ln R_ii
//! are the exponent increments and the Ginelli iteration C_{n-1} = R_n^{-1} C_n carries no
//! sign noise.

use super::crew::Crew;
use crate::system::Tangent;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::qr::no_pivoting::factor;
use faer::{Conj, Mat, MatMut, MatRef, Par};
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// Columns per chunk: a worker's unit of the trailing update and of the formation of Q.
const CHUNK: usize = 64;
/// Below this many matrix entries the work is not split between threads.
const PARALLEL_MIN: usize = 256 * 256;

/// Workspace for repeated QR factorisations of D x k tangent blocks.
pub struct Qr {
    /// The block in column-major order; after factoring, R above the diagonal and the
    /// Householder vectors below it.
    a: Mat<f64>,
    /// The triangular factor T of each panel's block reflector (panel p in columns p*nb..).
    t: Mat<f64>,
    nb: usize,
    crew: Crew,
    /// Workers used by the next factorisation (at most the crew's size).
    active: usize,
    scratch: Vec<Mutex<Scratch>>,
}

/// One worker's scratch: faer's workspace, a d x CHUNK block of Q and the signs of diag R.
struct Scratch {
    mem: MemBuffer,
    q: Mat<f64>,
    /// sign(R_ii): the sign fix of column i of Q and row i of R.
    sign: Vec<f64>,
}

/// The parallelism setting for `threads` worker threads (1 = sequential).
pub fn par(threads: usize) -> Par {
    if threads <= 1 { Par::Seq } else { Par::rayon(threads) }
}

impl Qr {
    /// The workspace for a D x k block on `threads` threads, with the panel width measured to
    /// be fastest at D = k = 792 (examples/qr_blocks.rs).
    pub fn new(d: usize, k: usize, threads: usize) -> Self {
        Self::with_panel(d, k, 32, threads)
    }

    /// A workspace with a chosen panel width `nb` (for tuning experiments).
    pub fn with_panel(d: usize, k: usize, nb: usize, threads: usize) -> Self {
        assert!(k <= d, "QR of a D x k block needs k <= D");
        let nb = nb.clamp(1, k.max(1));
        let workers = if d * k >= PARALLEL_MIN { threads.clamp(1, k.div_ceil(nb)) } else { 1 };
        let req = StackReq::any_of(&[
            factor::qr_in_place_scratch::<f64>(d, nb, nb, Par::Seq, Default::default()),
            householder::apply_block_householder_on_the_left_in_place_scratch::<f64>(d, nb, k),
        ]);
        // Without helper threads (none could be started) the crew is the calling thread.
        let crew = Crew::new(workers).or_else(|_| Crew::new(1)).expect("a crew of one starts no thread");
        let scratch = (0..crew.workers()).map(|_| Mutex::new(Scratch { mem: MemBuffer::new(req), q: Mat::zeros(d, CHUNK.min(k)), sign: vec![1.0; k] })).collect();
        let active = crew.workers();
        Qr { a: Mat::zeros(d, k), t: Mat::zeros(nb, k), nb, crew, active, scratch }
    }

    /// Use at most `threads` of the crew from the next factorisation on (at least one, at
    /// most the number the workspace was made for). The result does not depend on it.
    pub fn set_threads(&mut self, threads: usize) {
        self.active = threads.clamp(1, self.crew.workers());
    }

    /// Factor the block in place (Gbar_n = G_n R_n): on return `g` holds G_n and `r` the
    /// k x k upper-triangular R_n with a positive diagonal (its lower part is zero).
    ///
    /// If a column is linearly dependent on the ones before it (or not finite), `g` is left
    /// as it was, `r` is zero but for R_ii = 0 (NaN if `g` is not finite), and an i such
    /// that the first i + 1 columns are dependent is returned, for the caller to report
    /// (faer's panel factorisation tells how many columns of a panel are independent, not
    /// which).
    pub fn factor(&mut self, g: &mut Tangent, r: &mut Mat<f64>) -> Option<usize> {
        self.factor_with_copies(g, r, Copies::default())
    }

    /// [`Qr::factor`], also writing the copies of G_n and R_n that `copies` asks for, with
    /// the same bits as [`Tangent::write_paper_columns`] and [`super::pack_upper`]: each
    /// worker writes its chunks while they are in cache, instead of a pass over the whole
    /// block afterwards (the backward stage's recomputation: 1.7 + 0.4 ms a step at D = 792,
    /// measured). Nothing is written there if a column is dependent.
    pub fn factor_with_copies(&mut self, g: &mut Tangent, r: &mut Mat<f64>, copies: Copies<'_>) -> Option<usize> {
        let (d, k) = (g.dim(), g.count());
        assert!(r.nrows() == k && r.ncols() == k && self.a.nrows() == d && self.a.ncols() == k);
        if k == 0 {
            return None;
        }
        let paper = copies.g_paper.map(|p| {
            assert!(p.internal_row.len() == d && p.out.len() == d * k, "paper columns need D rows and D x k values");
            SharedPaper { rows: p.internal_row, ptr: p.out.as_mut_ptr(), d }
        });
        let r_packed = copies.r_packed.map(|out| {
            assert_eq!(out.len(), k * (k + 1) / 2, "packed R needs k (k + 1) / 2 values");
            SharedPacked(out.as_mut_ptr())
        });
        let nb = self.nb;
        let rows = g.rows_mut();
        assert_eq!(rows.len(), d * k);
        let job = Job {
            a: Shared::new(self.a.as_mut()),
            t: Shared::new(self.t.as_mut()),
            panels: (0..k.div_ceil(nb)).map(|p| p * nb..((p + 1) * nb).min(k)).collect(),
            nb,
            per_chunk: (CHUNK / nb).max(1),
            workers: self.active,
            g_rows: SharedRows { ptr: rows.as_mut_ptr(), d, k },
            paper,
            r_out: Shared::new(r.as_mut()),
            r_packed,
            factored: AtomicUsize::new(0),
            deficient: AtomicUsize::new(usize::MAX),
            stop: AtomicBool::new(false),
            q_next: AtomicUsize::new(0),
        };
        let scratch = &self.scratch;
        self.crew.run_on(job.workers, &|me| {
            let _stop_others = StopOnPanic(&job.stop);
            let _flush = super::FlushSubnormals::new();
            let mut guard = scratch[me].lock().unwrap_or_else(|e| e.into_inner());
            if job.factor(me, &mut guard.mem) {
                job.form_q(&mut guard);
            }
        });

        let i = job.deficient.into_inner();
        if i == usize::MAX {
            return None;
        }
        r.fill(0.0);
        r[(i, i)] = if g.rows().iter().all(|x| x.is_finite()) { 0.0 } else { f64::NAN };
        // `g` still holds the input: Q is only written once every panel is factored.
        Some(i)
    }
}

/// One factorisation, shared by the crew's workers: the block and its copies, and what
/// the workers tell each other.
///
/// Safety of the shared views, for every method: a worker writes only the panels it owns
/// (p with `owner(p) == me`) until all panels are factored; a panel is read by others only
/// after it is factored (published through `factored`), and then never written. G is only
/// read until every panel is factored. After that, nothing writes `a` any more, and each
/// chunk of Q, and so of G, its paper copy and R, is taken by one worker alone (`q_next`).
struct Job<'a> {
    /// The block in column-major order; once factored, R above the diagonal and the
    /// Householder vectors below it.
    a: Shared,
    /// The triangular factor T of each panel's block reflector.
    t: Shared,
    panels: Vec<Range<usize>>,
    nb: usize,
    /// Panels per chunk: the trailing columns are updated in chunks of whole panels, about
    /// CHUNK wide, and the worker that updates a chunk also factors its panels.
    per_chunk: usize,
    workers: usize,
    g_rows: SharedRows,
    paper: Option<SharedPaper<'a>>,
    r_out: Shared,
    r_packed: Option<SharedPacked>,
    /// Panels factored so far.
    factored: AtomicUsize,
    /// The first dependent column found.
    deficient: AtomicUsize,
    /// Set to stop every worker.
    stop: AtomicBool,
    /// The next chunk of Q to form.
    q_next: AtomicUsize,
}

impl Job<'_> {
    fn chunk_of(&self, p: usize) -> usize {
        p / self.per_chunk
    }

    fn owner(&self, p: usize) -> usize {
        self.chunk_of(p) % self.workers
    }

    fn k(&self) -> usize {
        self.a.ncols
    }

    /// Factor panel p (owned by the caller, up to date) and publish it.
    unsafe fn factor_panel(&self, p: usize, mem: &mut MemBuffer) {
        let cols = self.panels[p].clone();
        let w = cols.len();
        let info = unsafe { factor::qr_in_place(self.a.view(cols.start.., cols.clone()), self.t.view(..w, cols.clone()), Par::Seq, MemStack::new(mem), Default::default()) };
        if info.rank < w {
            self.deficient.fetch_min(cols.start + info.rank, Ordering::Relaxed);
            self.stop.store(true, Ordering::Release);
        }
        self.factored.store(p + 1, Ordering::Release);
    }

    /// Reflector block p (factored) applied to columns `cols` (owned by the caller).
    unsafe fn update(&self, p: usize, cols: Range<usize>, mem: &mut MemBuffer) {
        let panel = self.panels[p].clone();
        unsafe {
            householder::apply_block_householder_transpose_on_the_left_in_place_with_conj(
                self.a.view(panel.start.., panel.clone()).as_ref(),
                self.t.view(..panel.len(), panel.clone()).as_ref(),
                Conj::Yes,
                self.a.view(panel.start.., cols),
                Par::Seq,
                MemStack::new(mem),
            );
        }
    }

    /// Worker `me`'s part of the factorisation: right-looking, one panel of lookahead. It
    /// applies reflector block p to its panels, the next one first, and factors that as soon
    /// as it is up to date. False if the factorisation stopped (a dependent column or a
    /// worker's panic).
    fn factor(&self, me: usize, mem: &mut MemBuffer) -> bool {
        let (np, k) = (self.panels.len(), self.k());
        let cw = self.per_chunk * self.nb;
        for p in (0..np).filter(|&p| self.owner(p) == me) {
            unsafe { self.g_rows.read_cols(self.a.view(.., self.panels[p].clone()), self.panels[p].start) };
        }
        if self.owner(0) == me {
            unsafe { self.factor_panel(0, mem) };
        }
        for p in 0..np - 1 {
            if !wait_for(&self.factored, p + 1, &self.stop) {
                return false;
            }
            // My chunks' columns right of panel p, on the fixed chunk grid (so that the gemm
            // calls, and the rounding, are the same for any number of workers).
            let first = self.chunk_of(p + 1);
            let chunk_cols = |c: usize| (c * cw).max(self.panels[p].end)..((c + 1) * cw).min(k);
            if self.owner(p + 1) == me {
                unsafe {
                    self.update(p, chunk_cols(first), mem);
                    self.factor_panel(p + 1, mem);
                }
            }
            for c in (first + 1..k.div_ceil(cw)).filter(|&c| c % self.workers == me) {
                unsafe { self.update(p, chunk_cols(c), mem) };
            }
        }
        wait_for(&self.factored, np, &self.stop)
    }

    /// Q one chunk of columns at a time (orgqr), the most expensive chunks first; each with
    /// its signs fixed, written to G (and its paper copy), and its columns of R.
    fn form_q(&self, scratch: &mut Scratch) {
        let Scratch { mem, q, sign } = scratch;
        let k = self.k();
        for (i, s) in sign.iter_mut().enumerate() {
            *s = if unsafe { self.a.read(i, i) } < 0.0 { -1.0 } else { 1.0 };
        }
        let q_chunks = k.div_ceil(CHUNK);
        loop {
            let i = self.q_next.fetch_add(1, Ordering::Relaxed);
            if i >= q_chunks {
                return;
            }
            let c = q_chunks - 1 - i;
            let cols = c * CHUNK..((c + 1) * CHUNK).min(k);
            let mut q = q.as_mut().get_mut(.., ..cols.len());
            q.fill(0.0);
            for (j, col) in cols.clone().enumerate() {
                q[(col, j)] = 1.0;
            }
            for panel in self.panels.iter().rev().filter(|p| p.start < cols.end) {
                let from = panel.start.max(cols.start);
                unsafe {
                    householder::apply_block_householder_on_the_left_in_place_with_conj(
                        self.a.view(panel.start.., panel.clone()).as_ref(),
                        self.t.view(..panel.len(), panel.clone()).as_ref(),
                        Conj::No,
                        q.as_mut().get_mut(panel.start.., from - cols.start..),
                        Par::Seq,
                        MemStack::new(mem),
                    );
                }
            }
            unsafe {
                self.g_rows.write_cols(q.as_ref(), cols.start, &sign[cols.clone()]);
                if let Some(paper) = &self.paper {
                    paper.write_cols(q.as_ref(), cols.start, &sign[cols.clone()]);
                }
                self.write_r(cols, sign);
            }
        }
    }

    /// Columns `cols` of R (and of its packed copy): the upper triangle of the factored
    /// block with the signs of `sign`, zero below.
    unsafe fn write_r(&self, cols: Range<usize>, sign: &[f64]) {
        let mut rc = unsafe { self.r_out.view(.., cols.clone()) };
        let fa = unsafe { self.a.view(.., cols.clone()) };
        for (jj, j) in cols.enumerate() {
            let src = fa.as_ref().col(jj).try_as_col_major().expect("column-major").as_slice();
            let dst = rc.as_mut().col_mut(jj).try_as_col_major_mut().expect("column-major").as_slice_mut();
            let (upper, lower) = dst.split_at_mut(j + 1);
            for ((x, y), s) in upper.iter_mut().zip(src).zip(sign) {
                *x = s * y;
            }
            lower.fill(0.0);
            if let Some(packed) = &self.r_packed {
                // Column j of the packed triangle starts at j (j + 1) / 2.
                unsafe { std::slice::from_raw_parts_mut(packed.0.add(j * (j + 1) / 2), j + 1).copy_from_slice(upper) };
            }
        }
    }
}

/// Sets `stop` if the worker holding it unwinds, so that no other worker waits for it.
struct StopOnPanic<'a>(&'a AtomicBool);

impl Drop for StopOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Ordering::Release);
        }
    }
}

/// Wait until `counter >= n`; false if told to stop instead.
fn wait_for(counter: &AtomicUsize, n: usize, stop: &AtomicBool) -> bool {
    let mut spins = 0u32;
    loop {
        if counter.load(Ordering::Acquire) >= n {
            // A panel that lost rank sets `stop` before it is counted.
            return !stop.load(Ordering::Acquire);
        }
        if stop.load(Ordering::Acquire) {
            return false;
        }
        spins += 1;
        if spins < 2000 {
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }
}

/// A column-major matrix shared by workers that use disjoint columns of it.
#[derive(Clone, Copy)]
struct Shared {
    ptr: *mut f64,
    nrows: usize,
    ncols: usize,
    col_stride: isize,
}

unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Shared {
    fn new(m: MatMut<'_, f64>) -> Self {
        assert_eq!(m.row_stride(), 1, "shared matrices are column-major");
        Shared { ptr: m.as_ptr_mut(), nrows: m.nrows(), ncols: m.ncols(), col_stride: m.col_stride() }
    }

    /// Safety: no worker writes (i, j) at the same time.
    unsafe fn read(&self, i: usize, j: usize) -> f64 {
        assert!(i < self.nrows && j < self.ncols);
        unsafe { *self.ptr.offset(i as isize + j as isize * self.col_stride) }
    }

    /// Safety: the caller makes sure that views used at the same time do not overlap, unless
    /// all of them only read.
    #[allow(clippy::mut_from_ref)]
    unsafe fn view(&self, rows: impl std::ops::RangeBounds<usize>, cols: Range<usize>) -> MatMut<'_, f64> {
        let rows = range(rows, self.nrows);
        assert!(rows.end <= self.nrows && cols.end <= self.ncols && rows.start <= rows.end && cols.start <= cols.end);
        unsafe {
            MatMut::from_raw_parts_mut(
                self.ptr.offset(rows.start as isize + cols.start as isize * self.col_stride),
                rows.len(),
                cols.len(),
                1,
                self.col_stride,
            )
        }
    }
}

fn range(r: impl std::ops::RangeBounds<usize>, len: usize) -> Range<usize> {
    use std::ops::Bound::*;
    let start = match r.start_bound() {
        Included(&s) => s,
        Excluded(&s) => s + 1,
        Unbounded => 0,
    };
    let end = match r.end_bound() {
        Included(&e) => e + 1,
        Excluded(&e) => e,
        Unbounded => len,
    };
    start..end
}

/// The row-major D x k block G, shared by workers: all read it, then each writes the
/// columns it owns.
struct SharedRows {
    ptr: *mut f64,
    d: usize,
    k: usize,
}

unsafe impl Send for SharedRows {}
unsafe impl Sync for SharedRows {}

impl SharedRows {
    /// Columns `first..first + q.ncols()` of G from `q`, times `sign` (+-1 per column).
    /// Safety: no other worker writes these columns at the same time.
    unsafe fn write_cols(&self, q: MatRef<'_, f64>, first: usize, sign: &[f64]) {
        let (d, w) = q.shape();
        assert!(sign.len() == w && first + w <= self.k && d == self.d && q.row_stride() == 1);
        for i0 in (0..d).step_by(TILE) {
            let i1 = (i0 + TILE).min(d);
            for (j, s) in sign.iter().enumerate() {
                let col = &q.col(j).try_as_col_major().expect("column-major").as_slice()[i0..i1];
                for (i, x) in (i0..i1).zip(col) {
                    unsafe { *self.ptr.add(i * self.k + first + j) = s * x };
                }
            }
        }
    }
}

/// Copies of a factorisation's result in other layouts ([`Qr::factor_with_copies`]).
#[derive(Default)]
pub struct Copies<'a> {
    pub g_paper: Option<PaperColumns<'a>>,
    /// R_n, upper triangle packed column by column ([`super::pack_upper`]).
    pub r_packed: Option<&'a mut [f64]>,
}

/// G_n in the paper's layout: column-major D x k, row i taken from internal row
/// `internal_row[i]` ([`crate::system::DynamicalSystem::internal_row`]).
pub struct PaperColumns<'a> {
    pub internal_row: &'a [usize],
    pub out: &'a mut [f64],
}

/// A packed triangle written by workers that own disjoint columns.
struct SharedPacked(*mut f64);

unsafe impl Send for SharedPacked {}
unsafe impl Sync for SharedPacked {}

/// [`PaperColumns`] shared by workers that write disjoint columns.
struct SharedPaper<'a> {
    rows: &'a [usize],
    ptr: *mut f64,
    d: usize,
}

unsafe impl Send for SharedPaper<'_> {}
unsafe impl Sync for SharedPaper<'_> {}

impl SharedPaper<'_> {
    /// Columns `first..first + q.ncols()` of G, times `sign`, permuted to the paper's rows.
    /// Safety: no other worker writes these columns at the same time.
    unsafe fn write_cols(&self, q: MatRef<'_, f64>, first: usize, sign: &[f64]) {
        for (j, s) in sign.iter().enumerate() {
            let col = q.col(j).try_as_col_major().expect("column-major").as_slice();
            // Safety: column first + j lies inside the D x k buffer checked on entry.
            let out = unsafe { std::slice::from_raw_parts_mut(self.ptr.add((first + j) * self.d), self.d) };
            for (o, &r) in out.iter_mut().zip(self.rows) {
                *o = s * col[r];
            }
        }
    }
}

/// Rows per tile of the transpositions between G (row-major) and the column-major work.
const TILE: usize = 32;

impl SharedRows {
    /// Columns `first..first + a.ncols()` of G into the column-major `a`.
    /// Safety: no worker writes G at the same time.
    unsafe fn read_cols(&self, mut a: MatMut<'_, f64>, first: usize) {
        let (d, w) = a.shape();
        assert!(first + w <= self.k && d == self.d);
        for i0 in (0..d).step_by(TILE) {
            let i1 = (i0 + TILE).min(d);
            for j in 0..w {
                let col = &mut a.as_mut().col_mut(j).try_as_col_major_mut().expect("column-major").as_slice_mut()[i0..i1];
                for (i, x) in (i0..i1).zip(col) {
                    *x = unsafe { *self.ptr.add(i * self.k + first + j) };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random_block(d: usize, k: usize, seed: u64) -> Tangent {
        let mut rng = Rng::new(seed);
        let mut t = Tangent::zeros(d, k);
        t.rows_mut().iter_mut().for_each(|x| *x = rng.normal());
        t
    }

    /// A block like a tangent block after one tau: columns stretched and shrunk by up to
    /// e^{+-3} (condition number near e^6) and mixed.
    fn tangent_like(d: usize, k: usize, seed: u64) -> Tangent {
        let mut rng = Rng::new(seed);
        let mix = random_block(d, k, seed);
        let mut t = Tangent::zeros(d, k);
        let scale: Vec<f64> = (0..k).map(|j| (3.0 - 6.0 * j as f64 / k.max(2) as f64 + 0.1 * rng.normal()).exp()).collect();
        for i in 0..d {
            for j in 0..k {
                let x: f64 = (0..=j.min(3)).map(|l| mix.get(i, j - l) * scale[j - l]).sum();
                t.rows_mut()[i * k + j] = x;
            }
        }
        t
    }

    fn factor(a: &Tangent, nb: usize, threads: usize) -> (Tangent, Mat<f64>) {
        let (d, k) = (a.dim(), a.count());
        let mut g = a.clone();
        let mut r = Mat::zeros(k, k);
        Qr::with_panel(d, k, nb, threads).factor(&mut g, &mut r);
        (g, r)
    }

    /// G^T G = I to 1e-12, G R = A, R upper triangular with a positive diagonal and equal to
    /// faer's reference QR (signs fixed); for shapes around the panel and chunk boundaries,
    /// 1 to 3 threads.
    #[test]
    fn qr_is_orthonormal_and_matches_a_reference() {
        let shapes = [(2, 2, 32, 1), (2, 1, 32, 1), (7, 3, 32, 1), (40, 40, 32, 1), (100, 37, 16, 1), (130, 129, 16, 1), (130, 129, 7, 1), (300, 300, 32, 2), (400, 333, 24, 3), (520, 520, 32, 2), (300, 290, 7, 2), (300, 200, 100, 2)];
        for (n, &(d, k, nb, threads)) in shapes.iter().enumerate() {
            let a = if n % 2 == 0 { random_block(d, k, (d * 1000 + k) as u64) } else { tangent_like(d, k, n as u64) };
            let (g, r) = factor(&a, nb, threads);
            let am = Mat::from_fn(d, k, |i, j| a.get(i, j));
            let gm = Mat::from_fn(d, k, |i, j| g.get(i, j));
            let orth = (gm.transpose() * &gm - Mat::<f64>::identity(k, k)).norm_max();
            assert!(orth < 1e-12, "{d}x{k}: |G^T G - I| = {orth:e}");
            let recon = (&gm * &r - &am).norm_max() / am.norm_max();
            assert!(recon < 1e-13, "{d}x{k}: |GR - A| / |A| = {recon:e}");
            let reference = am.qr().R().to_owned();
            let mut worst: f64 = 0.0;
            for i in 0..k {
                assert!(r[(i, i)] > 0.0, "{d}x{k}: R_{i}{i} = {}", r[(i, i)]);
                let s = reference[(i, i)].signum();
                for j in 0..k {
                    if i > j {
                        assert_eq!(r[(i, j)], 0.0);
                    } else {
                        worst = worst.max((r[(i, j)] - s * reference[(i, j)]).abs() / am.col(j).norm_l2());
                    }
                }
            }
            // Two backward-stable QRs differ in R by up to about eps * cond(A) (a few hundred
            // for these blocks) relative to the column norms.
            assert!(worst < 1e-11, "{d}x{k}: R differs from faer's QR by {worst:e}");
        }
    }

    /// The chunk grid is fixed, so the result does not depend on the number of threads.
    #[test]
    fn result_is_bit_identical_for_any_thread_count() {
        let a = tangent_like(600, 520, 3);
        let (g1, r1) = factor(&a, 32, 1);
        for threads in [2, 3] {
            let (g, r) = factor(&a, 32, threads);
            assert!(g.rows() == g1.rows(), "G on {threads} threads differs from 1 thread");
            assert!(r == r1, "R on {threads} threads differs from 1 thread");
        }
        // And the same workspace used again, with the threads it may use changed between
        // calls (as the backward stage does), gives the same numbers.
        let mut qr = Qr::new(600, 520, 3);
        let mut r = Mat::zeros(520, 520);
        for threads in [3, 1, 2, 0, 9] {
            qr.set_threads(threads);
            let mut g = a.clone();
            qr.factor(&mut g, &mut r);
            assert!(g.rows() == g1.rows() && r == r1, "reused workspace on set_threads({threads})");
        }
    }

    /// G_n in the paper's layout, written from the chunks of Q, has the bits of the row-major
    /// result permuted, and packed R those of R, on one thread or two.
    #[test]
    fn paper_columns_are_the_permuted_result() {
        let (d, k) = (300, 260);
        let a = tangent_like(d, k, 8);
        // A permutation with no structure: the reversed order, then adjacent pairs swapped.
        let rows: Vec<usize> = (0..d).map(|i| (d - 1 - i) ^ 1).collect();
        for threads in [1, 2] {
            let (mut g, mut r) = (a.clone(), Mat::zeros(k, k));
            let mut out = vec![f64::NAN; d * k];
            let mut packed = vec![f64::NAN; k * (k + 1) / 2];
            Qr::new(d, k, threads).factor_with_copies(&mut g, &mut r, Copies { g_paper: Some(PaperColumns { internal_row: &rows, out: &mut out }), r_packed: Some(&mut packed) });
            assert!(packed.iter().zip(&crate::linalg::pack_upper(r.as_ref())).all(|(x, y)| x.to_bits() == y.to_bits()), "packed R, {threads} thread(s)");
            let (want, _) = factor(&a, 32, threads);
            assert!(g.rows() == want.rows());
            for j in 0..k {
                for (i, &row) in rows.iter().enumerate() {
                    assert_eq!(out[j * d + i].to_bits(), g.get(row, j).to_bits(), "paper row {i}, column {j}, {threads} thread(s)");
                }
            }
        }
    }

    /// A dependent column (or a NaN) leaves G alone and shows as R_ii = 0 (or NaN) at the
    /// first such column, on one thread or several.
    #[test]
    fn dependent_columns_are_reported_through_r() {
        for threads in [1, 2] {
            let (d, k) = (300, 300);
            let mut a = random_block(d, k, 5);
            for i in 0..d {
                let x = 2.0 * a.get(i, 10) - a.get(i, 3);
                a.rows_mut()[i * k + 150] = x;
            }
            // Dependent up to round-off: R_ii is at round-off level (either way).
            let (_, r) = factor(&a, 32, threads);
            assert!(r[(150, 150)].abs() < 1e-13 * r[(10, 10)], "R_ii = {:e}", r[(150, 150)]);
            // Exactly dependent: reported.
            for i in 0..d {
                a.rows_mut()[i * k + 150] = 0.0;
            }
            let (g, r) = factor(&a, 32, threads);
            assert!(g.rows() == a.rows(), "G must be left as it was");
            assert_eq!(r[(150, 150)], 0.0);
            assert!((0..k).all(|i| (0..k).all(|j| r[(i, j)] == 0.0)));
            let mut b = random_block(d, k, 6);
            b.rows_mut()[7 * k + 200] = f64::NAN;
            let (_, r) = factor(&b, 32, threads);
            assert!(r.diagonal().column_vector().iter().any(|x| x.is_nan()), "a NaN must show in diag R");
        }
    }

    #[test]
    fn an_empty_block_is_a_no_op() {
        let mut g = Tangent::zeros(8, 0);
        let mut r = Mat::zeros(0, 0);
        Qr::new(8, 0, 2).factor(&mut g, &mut r);
        assert_eq!((g.rows_mut().len(), r.nrows(), r.ncols()), (0, 0, 0));
    }
}
