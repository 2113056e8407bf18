//! The event queue of one interval: buckets over a window of time, a heap beyond it.
//!
//! Why not a binary heap alone: with N = 19800 disks the heap's lower levels miss the cache
//! on every pop and push (a quarter of the event loop's time, measured), and its depth grows
//! with log N. Here time is cut into buckets so that a bucket holds about two entries at a
//! time: an event goes into the bucket of its time (one access), and a pop takes the earliest
//! of the current bucket's few entries. The width comes from the disks' first predictions
//! (their mean time m: the entries lie about N / m to a unit of time), so it suits any N,
//! density and tau. The buckets, 8N of them, cover a window of sixteen times m (all of
//! tau = 0.6 in the paper's system); the rare events beyond it wait in a heap and move into
//! the buckets when the window moves on. So the memory stays O(N) however long tau is.
//!
//! No event is ever scheduled before the one being handled, so the current bucket only moves
//! forward, and the pop order is exactly the order of (t, owner, counter), the same as a
//! heap's: the run does not depend on the queue.

/// An entry: the owner's index `id` in the caller's numbering and `l` in the engine's, and
/// its event counter `ci` when predicted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Queued {
    pub t: f64,
    pub id: u32,
    pub l: u32,
    pub ci: u32,
}

impl Queued {
    /// Earlier first; ties are broken by the owner in the caller's numbering (so the order
    /// does not depend on where the engine keeps a disk), then by its counter: the order is
    /// total and the run deterministic.
    fn before(&self, o: &Queued) -> bool {
        self.t.total_cmp(&o.t).then(self.id.cmp(&o.id)).then(self.ci.cmp(&o.ci)).is_lt()
    }
}

const NONE: u32 = u32::MAX;

#[derive(Clone, Debug, Default)]
pub struct EventQueue {
    /// First entry of each bucket (an index into `entries`), or NONE.
    heads: Vec<u32>,
    entries: Vec<Queued>,
    /// Next entry in the same bucket, or in the free list.
    next: Vec<u32>,
    free: u32,
    /// The window: bucket b holds the times in [start + b / scale, start + (b + 1) / scale).
    start: f64,
    scale: f64,
    /// The end of the window (times from here on wait in `later`).
    end: f64,
    /// The bucket of the last pop: every entry is in it or after it.
    current: usize,
    later: std::collections::BinaryHeap<Later>,
    /// Entries pushed before the first pop, which sets the buckets' width from them.
    first: Vec<Queued>,
    calibrated: bool,
    /// Times the window moved on in this interval.
    pub moves: u64,
}

/// An entry beyond the window, earliest first out of the heap.
#[derive(Clone, Copy, Debug)]
struct Later(Queued);

impl PartialEq for Later {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == std::cmp::Ordering::Equal
    }
}
impl Eq for Later {}
impl PartialOrd for Later {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Later {
    /// Reversed, so that `BinaryHeap` gives the earliest first.
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        if self.0.before(&o.0) {
            std::cmp::Ordering::Greater
        } else if o.0.before(&self.0) {
            std::cmp::Ordering::Less
        } else {
            std::cmp::Ordering::Equal
        }
    }
}

impl EventQueue {
    /// Empty the queue for an interval of `n` disks starting at time 0; the first pushes
    /// should be each disk's first event.
    pub fn reset(&mut self, n: usize) {
        self.heads.clear();
        self.heads.resize((8 * n).max(16), NONE);
        self.entries.clear();
        self.next.clear();
        self.free = NONE;
        self.current = 0;
        self.later.clear();
        self.first.clear();
        self.calibrated = false;
        self.moves = 0;
    }

    /// The buckets' width, from the entries pushed so far (times from 0): two entries to a
    /// bucket where they lie len / mean time to a unit of time.
    fn calibrate(&mut self) {
        self.calibrated = true;
        let mean = self.first.iter().map(|e| e.t).sum::<f64>() / self.first.len().max(1) as f64;
        self.scale = if mean > 0.0 && mean.is_finite() { self.first.len() as f64 / (2.0 * mean) } else { 1.0 };
        self.start = 0.0;
        self.end = self.heads.len() as f64 / self.scale;
        let first = std::mem::take(&mut self.first);
        for &e in &first {
            self.push(e);
        }
        self.first = first;
        self.first.clear();
    }

    /// Queue an event; its time must not be before the last one popped.
    pub fn push(&mut self, e: Queued) {
        if !self.calibrated {
            self.first.push(e);
            return;
        }
        if e.t >= self.end {
            self.later.push(Later(e));
            return;
        }
        // Rounding is monotone, so a later time never lands in an earlier bucket.
        let b = (((e.t - self.start) * self.scale) as usize).min(self.heads.len() - 1);
        debug_assert!(b >= self.current, "an event at {} is before the bucket of the last pop", e.t);
        let b = b.max(self.current);
        let slot = if self.free != NONE {
            let slot = self.free;
            self.free = self.next[slot as usize];
            self.entries[slot as usize] = e;
            self.next[slot as usize] = self.heads[b];
            slot
        } else {
            self.entries.push(e);
            self.next.push(self.heads[b]);
            (self.entries.len() - 1) as u32
        };
        self.heads[b] = slot;
    }

    /// The earliest event, removed from the queue.
    pub fn pop(&mut self) -> Option<Queued> {
        if !self.calibrated {
            self.calibrate();
        }
        loop {
            while self.heads.get(self.current).is_some_and(|&h| h == NONE) {
                self.current += 1;
            }
            if self.current < self.heads.len() {
                break;
            }
            // The window is empty: move it on to the earliest later event.
            let first = self.later.peek()?.0.t;
            self.moves += 1;
            self.start = first;
            self.end = first + self.heads.len() as f64 / self.scale;
            self.current = 0;
            while self.later.peek().is_some_and(|l| l.0.t < self.end) {
                let Later(e) = self.later.pop()?;
                self.push(e);
            }
        }
        let head = self.heads[self.current];
        // The earliest entry of the bucket and the link that points to it.
        let (mut best, mut best_link) = (head, None);
        let (mut prev, mut at) = (head, self.next[head as usize]);
        while at != NONE {
            if self.entries[at as usize].before(&self.entries[best as usize]) {
                (best, best_link) = (at, Some(prev));
            }
            (prev, at) = (at, self.next[at as usize]);
        }
        let after = self.next[best as usize];
        match best_link {
            None => self.heads[self.current] = after,
            Some(p) => self.next[p as usize] = after,
        }
        self.next[best as usize] = self.free;
        self.free = best;
        Some(self.entries[best as usize])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Events pushed while others are popped, each no earlier than the last pop (as the
    /// engine does), come out in the order of (t, owner, counter), ties included.
    #[test]
    fn pops_in_time_order_while_events_are_pushed() {
        let tau = 0.6;
        let mut rng = Rng::new(7);
        let mut q = EventQueue::default();
        for expected in [1usize, 10, 1000] {
            q.reset(expected.div_ceil(8));
            let mut reference: Vec<Queued> = Vec::new();
            let mut now = 0.0;
            let mut popped = Vec::new();
            let mut pushes = 0u32;
            let push = |q: &mut EventQueue, reference: &mut Vec<Queued>, now: f64, rng: &mut Rng, i: u32| {
                // Some events at exactly `now` or tau, and repeated times with other owners.
                let t = match i % 7 {
                    0 => now,
                    1 => tau,
                    2 => reference.last().map_or(now, |e| e.t),
                    _ => now + (tau - now) * rng.uniform(),
                };
                let e = Queued { t, id: i % 13, l: 0, ci: i % 5 };
                q.push(e);
                reference.push(e);
            };
            for _ in 0..3 * expected {
                push(&mut q, &mut reference, now, &mut rng, pushes);
                pushes += 1;
            }
            while let Some(e) = q.pop() {
                let first = (0..reference.len()).reduce(|a, b| if reference[b].before(&reference[a]) { b } else { a }).unwrap();
                assert_eq!(e, reference.swap_remove(first), "pop {} of {expected}", popped.len());
                now = e.t;
                popped.push(e);
                if pushes < 8 * expected as u32 && popped.len() % 3 != 0 {
                    push(&mut q, &mut reference, now, &mut rng, pushes);
                    pushes += 1;
                }
            }
            assert!(reference.is_empty());
            assert!(popped.windows(2).all(|w| w[0].t <= w[1].t));
        }
    }
}
