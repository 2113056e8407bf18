//! The Henon map (paper section 4): x' = a - x^2 + b y, y' = x, with a = 1.4, b = 0.3.
//!
//! The cheapest complete test of the Lyapunov machinery: |det J| = b at every point, so
//! lambda_1 + lambda_2 = ln b exactly, and one iteration is one tau.

use super::{DynamicalSystem, Invariants, Snapshot, Tangent};
use crate::error::{Error, Result};

#[derive(Clone, Debug)]
pub struct Henon {
    pub a: f64,
    pub b: f64,
    x: f64,
    y: f64,
    iterations: u64,
}

impl Henon {
    pub const A: f64 = 1.4;
    pub const B: f64 = 0.3;

    pub fn new(a: f64, b: f64, x: f64, y: f64) -> Self {
        Henon { a, b, x, y, iterations: 0 }
    }

    pub fn point(&self) -> (f64, f64) {
        (self.x, self.y)
    }

    /// The inverse map, x = y', y = (x' - a + y'^2) / b: what draws the stable manifold,
    /// along which backward iteration stretches.
    pub fn inverse(a: f64, b: f64, [x, y]: [f64; 2]) -> [f64; 2] {
        [y, (x - a + y * y) / b]
    }

    /// The Jacobian [[-2x, b], [1, 0]] at (x, y).
    pub fn jacobian(&self) -> [[f64; 2]; 2] {
        [[-2.0 * self.x, self.b], [1.0, 0.0]]
    }
}

/// A parameter as typed (1.4), or in exponent form where that would run to many digits.
fn short(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) { format!("{x:e}") } else { x.to_string() }
}

impl DynamicalSystem for Henon {
    fn name(&self) -> &'static str {
        "henon"
    }
    fn dim(&self) -> usize {
        2
    }
    fn tau(&self) -> f64 {
        1.0
    }

    fn advance(&mut self, tangent: &mut Tangent) -> Result<()> {
        let k = tangent.count();
        let [[j00, j01], [j10, _]] = self.jacobian();
        let (dx, dy) = tangent.rows_mut().split_at_mut(k);
        for (u, v) in dx.iter_mut().zip(dy.iter_mut()) {
            let (a, b) = (*u, *v);
            *u = j00 * a + j01 * b;
            *v = j10 * a;
        }
        let x = self.a - self.x * self.x + self.b * self.y;
        self.y = self.x;
        self.x = x;
        self.iterations += 1;
        if !x.is_finite() || x.abs() > 1e6 {
            return Err(Error::Dynamics(format!(
                "the Henon orbit (a = {}, b = {}) escaped to infinity after {} iterations; start from another seed{}",
                short(self.a),
                short(self.b),
                self.iterations,
                if (self.a, self.b) == (Self::A, Self::B) { "" } else { ", or choose a and b with a bounded attractor (the classic a = 1.4, b = 0.3 has one)" }
            )));
        }
        Ok(())
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot { phase: vec![self.x, self.y], events: self.iterations }
    }

    fn restore(&mut self, s: &Snapshot) -> Result<()> {
        match s.phase[..] {
            [x, y] if x.is_finite() && y.is_finite() => {
                self.x = x;
                self.y = y;
                self.iterations = s.events;
                Ok(())
            }
            _ => Err(Error::Dynamics(format!(
                "a Henon state needs 2 finite numbers, got {:?}",
                s.phase
            ))),
        }
    }

    fn invariants(&self) -> Invariants {
        Invariants { energy: f64::NAN, momentum: [0.0; 2], events: self.iterations }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_undoes_the_map() {
        let mut h = Henon::new(Henon::A, Henon::B, 0.3, -0.2);
        for _ in 0..20 {
            let (x, y) = h.point();
            h.advance(&mut Tangent::zeros(2, 0)).unwrap();
            let (x1, y1) = h.point();
            let [bx, by] = Henon::inverse(Henon::A, Henon::B, [x1, y1]);
            assert!((bx - x).abs() < 1e-12 && (by - y).abs() < 1e-12, "({bx}, {by}) against ({x}, {y})");
        }
    }

    /// Finite differences: the tangent map equals (F(x + eps u) - F(x)) / eps up to O(eps).
    #[test]
    fn tangent_matches_finite_differences() {
        let base = Henon::new(Henon::A, Henon::B, 0.3, -0.2);
        let u = [0.6, -0.8];
        let mut errs = Vec::new();
        for eps in [1e-4, 1e-5, 1e-6] {
            let mut h = base.clone();
            let mut t = Tangent::zeros(2, 1);
            t.set_vector(&h, 0, &u);
            let mut p = base.clone();
            p.restore(&Snapshot { phase: vec![0.3 + eps * u[0], -0.2 + eps * u[1]], events: 0 }).unwrap();
            let mut none = Tangent::zeros(2, 0);
            for _ in 0..5 {
                h.advance(&mut t).unwrap();
                p.advance(&mut none).unwrap();
            }
            let (a, b) = (h.snapshot().phase, p.snapshot().phase);
            let err = (0..2).map(|i| ((b[i] - a[i]) / eps - t.get(i, 0)).abs()).fold(0.0, f64::max);
            errs.push(err);
        }
        for w in errs.windows(2) {
            let ratio = w[0] / w[1];
            assert!((7.0..14.0).contains(&ratio), "error should fall tenfold with eps: {errs:?}");
        }
    }
}
