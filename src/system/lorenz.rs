//! The Lorenz-63 flow x' = sigma (y - x), y' = x (rho - z) - y, z' = x y - beta z, with the
//! classic sigma = 10, rho = 28, beta = 8/3.
//!
//! Why a third system: it is a flow with no conservation law, so one exponent is zero
//! because of the flow direction alone (its CLV is parallel to the vector field), and the
//! divergence -(sigma + 1 + beta) is the same at every point, so the exponents sum to it
//! exactly. The state and the tangent vectors are integrated together with
//! fixed-step fourth-order Runge-Kutta, the Jacobian evaluated on the stages of the orbit:
//! the tangent map is then the exact derivative of the discrete flow map, and a replay from
//! a checkpoint repeats every bit.

use super::{DynamicalSystem, Invariants, Snapshot, Tangent};
use crate::error::{Error, Result};

/// Runge-Kutta steps per unit time at the classic parameters: h = 0.0025 keeps the
/// divergence of the discrete map within about 1e-6 of -(sigma + 1 + beta) per unit time
/// (the GS exponents sum to it to that), at about 3 us a step.
const STEPS_PER_UNIT: f64 = 400.0;
/// The most Runge-Kutta steps per unit time that other parameters may ask for (a field ten
/// thousand times as fast as the classic one).
pub const MAX_STEPS_PER_UNIT: f64 = 1e4 * STEPS_PER_UNIT;

#[derive(Clone, Debug)]
pub struct Lorenz {
    pub sigma: f64,
    pub rho: f64,
    pub beta: f64,
    tau: f64,
    x: [f64; 3],
    steps: u64,
}

impl Lorenz {
    pub const SIGMA: f64 = 10.0;
    pub const RHO: f64 = 28.0;
    pub const BETA: f64 = 8.0 / 3.0;

    pub fn new(sigma: f64, rho: f64, beta: f64, tau: f64, x: [f64; 3]) -> Self {
        Lorenz { sigma, rho, beta, tau, x, steps: 0 }
    }

    pub fn point(&self) -> [f64; 3] {
        self.x
    }

    /// The vector field at `x`.
    pub fn field(&self, x: [f64; 3]) -> [f64; 3] {
        [self.sigma * (x[1] - x[0]), x[0] * (self.rho - x[2]) - x[1], x[0] * x[1] - self.beta * x[2]]
    }

    /// The Jacobian of the field at `x`; its trace is -(sigma + 1 + beta) everywhere.
    pub fn jacobian(&self, x: [f64; 3]) -> [[f64; 3]; 3] {
        [[-self.sigma, self.sigma, 0.0], [self.rho - x[2], -1.0, -x[0]], [x[1], x[0], -self.beta]]
    }

    /// How fast the field turns near its attractor, up to a factor: the Jacobian's entries
    /// sigma, 1, beta and |x|, |y| ~ sqrt(beta |rho|), and the rotation rate sqrt(sigma |rho|).
    fn rate(sigma: f64, rho: f64, beta: f64) -> f64 {
        sigma + 1.0 + beta + (sigma * rho.abs()).sqrt() + (beta * rho.abs()).sqrt()
    }

    /// Runge-Kutta steps per unit time: [`STEPS_PER_UNIT`] at the classic parameters, and
    /// as many more as the field is faster, so that other parameters get the same accuracy
    /// per turn of the orbit.
    pub fn steps_per_unit(sigma: f64, rho: f64, beta: f64) -> f64 {
        STEPS_PER_UNIT * (Self::rate(sigma, rho, beta) / Self::rate(Self::SIGMA, Self::RHO, Self::BETA)).max(1.0)
    }

    /// The default time between QR steps: 0.1 at the classic parameters, shorter in
    /// proportion where the field is faster ([`Lorenz::steps_per_unit`]), so that the
    /// tangent vectors spread by about as much between two QR steps.
    pub fn default_tau(sigma: f64, rho: f64, beta: f64) -> f64 {
        0.1 * STEPS_PER_UNIT / Self::steps_per_unit(sigma, rho, beta)
    }

    /// Substeps of one tau and their length.
    fn substeps(&self) -> (usize, f64) {
        // Within 1e-9 of a whole number it is that number: the default tau times the steps
        // per unit time is 40 up to rounding.
        let n = (self.tau * Self::steps_per_unit(self.sigma, self.rho, self.beta) - 1e-9).ceil().max(1.0) as usize;
        (n, self.tau / n as f64)
    }

    /// Beyond this the orbit has left the attractor: far outside the ellipsoid that traps
    /// every orbit (its size grows like rho + sigma).
    fn escape_bound(&self) -> f64 {
        1e6f64.max(1e3 * (1.0 + self.rho.abs() + self.sigma + self.beta))
    }
}

fn axpy(x: [f64; 3], a: f64, d: [f64; 3]) -> [f64; 3] {
    [x[0] + a * d[0], x[1] + a * d[1], x[2] + a * d[2]]
}

fn mul(j: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| j[r][0] * v[0] + j[r][1] * v[1] + j[r][2] * v[2])
}

impl DynamicalSystem for Lorenz {
    fn name(&self) -> &'static str {
        "lorenz"
    }
    fn dim(&self) -> usize {
        3
    }
    fn tau(&self) -> f64 {
        self.tau
    }

    fn advance(&mut self, tangent: &mut Tangent) -> Result<()> {
        let k = tangent.count();
        let (n, h) = self.substeps();
        let rows = tangent.rows_mut();
        for _ in 0..n {
            // The orbit's stages, then every tangent vector with the Jacobians at them.
            let x = self.x;
            let k1 = self.field(x);
            let x2 = axpy(x, h / 2.0, k1);
            let k2 = self.field(x2);
            let x3 = axpy(x, h / 2.0, k2);
            let k3 = self.field(x3);
            let x4 = axpy(x, h, k3);
            let k4 = self.field(x4);
            let (j1, j2, j3, j4) = (self.jacobian(x), self.jacobian(x2), self.jacobian(x3), self.jacobian(x4));
            for c in 0..k {
                let v = [rows[c], rows[k + c], rows[2 * k + c]];
                let l1 = mul(&j1, v);
                let l2 = mul(&j2, axpy(v, h / 2.0, l1));
                let l3 = mul(&j3, axpy(v, h / 2.0, l2));
                let l4 = mul(&j4, axpy(v, h, l3));
                for r in 0..3 {
                    rows[r * k + c] = v[r] + h / 6.0 * (l1[r] + 2.0 * l2[r] + 2.0 * l3[r] + l4[r]);
                }
            }
            self.x = [0, 1, 2].map(|r| x[r] + h / 6.0 * (k1[r] + 2.0 * k2[r] + 2.0 * k3[r] + k4[r]));
        }
        self.steps += 1;
        if self.x.iter().any(|v| !v.is_finite() || v.abs() > self.escape_bound()) {
            return Err(Error::Dynamics(format!(
                "the Lorenz orbit (sigma = {}, rho = {}, beta = {}) left every bounded region after {} steps: the Runge-Kutta step h = {h:e} was too long for the field there; report this with the run's configuration",
                self.sigma, self.rho, self.beta, self.steps
            )));
        }
        Ok(())
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot { phase: self.x.to_vec(), events: self.steps }
    }

    fn restore(&mut self, s: &Snapshot) -> Result<()> {
        match s.phase[..] {
            [x, y, z] if [x, y, z].iter().all(|v| v.is_finite()) => {
                self.x = [x, y, z];
                self.steps = s.events;
                Ok(())
            }
            _ => Err(Error::Dynamics(format!("a Lorenz state needs 3 finite numbers, got {:?}", s.phase))),
        }
    }

    fn invariants(&self) -> Invariants {
        Invariants { energy: f64::NAN, momentum: [0.0; 2], events: self.steps }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lorenz() -> Lorenz {
        Lorenz::new(Lorenz::SIGMA, Lorenz::RHO, Lorenz::BETA, 0.1, [1.0, 1.0, 20.0])
    }

    /// The tangent map is the derivative of the flow map: central differences of the orbit
    /// over one tau agree with the propagated unit vectors.
    #[test]
    fn tangent_map_is_the_derivative_of_the_flow() {
        let mut base = lorenz();
        let mut t = Tangent::zeros(3, 0);
        for _ in 0..30 {
            base.advance(&mut t).unwrap();
        }
        let mut j = Tangent::identity(&base, 3);
        let mut a = base.clone();
        a.advance(&mut j).unwrap();
        let eps = 1e-6;
        for c in 0..3 {
            let (mut p, mut m) = (base.clone(), base.clone());
            p.x[c] += eps;
            m.x[c] -= eps;
            p.advance(&mut t).unwrap();
            m.advance(&mut t).unwrap();
            for r in 0..3 {
                let fd = (p.x[r] - m.x[r]) / (2.0 * eps);
                assert!((fd - j.get(r, c)).abs() < 1e-5 * (1.0 + fd.abs()), "d x_{r} / d x_{c}: {fd} against {}", j.get(r, c));
            }
        }
    }

    /// Liouville: the volume of the tangent block changes by exp(-(sigma + 1 + beta) tau)
    /// per step at every point (RK4 to its truncation error: up to 1.1e-7 a step of 0.1 at h = 0.0025, ten times that at h = 0.005).
    #[test]
    fn phase_volume_contracts_at_the_divergence() {
        let mut s = lorenz();
        for _ in 0..20 {
            let mut j = Tangent::identity(&s, 3);
            s.advance(&mut j).unwrap();
            let m = |r: usize, c: usize| j.get(r, c);
            let det = m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1)) - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0)) + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0));
            let want = -(Lorenz::SIGMA + 1.0 + Lorenz::BETA) * 0.1;
            assert!((det.ln() - want).abs() < 3e-7, "ln det = {} against {want}", det.ln());
        }
    }

    /// Other parameters get as many more Runge-Kutta steps as their field is faster, so that
    /// the volume still contracts at the divergence to the classic accuracy; the classic
    /// parameters keep their 400 steps per unit time (and their runs' bits).
    #[test]
    fn faster_fields_get_shorter_steps() {
        assert_eq!(Lorenz::steps_per_unit(Lorenz::SIGMA, Lorenz::RHO, Lorenz::BETA), STEPS_PER_UNIT);
        assert_eq!(Lorenz::steps_per_unit(10.0, 0.5, 8.0 / 3.0), STEPS_PER_UNIT, "slower fields keep the classic step");
        let (sigma, rho, beta) = (16.0, 1500.0, 4.0);
        let mut s = Lorenz::new(sigma, rho, beta, 0.1, [1.0, 1.0, rho]);
        assert!(s.substeps().0 > 200, "{:?}", s.substeps());
        let mut t = Tangent::zeros(3, 0);
        for _ in 0..50 {
            s.advance(&mut t).unwrap();
        }
        for _ in 0..20 {
            let mut j = Tangent::identity(&s, 3);
            s.advance(&mut j).unwrap();
            let m = |r: usize, c: usize| j.get(r, c);
            let det = m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1)) - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0)) + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0));
            let want = -(sigma + 1.0 + beta) * 0.1;
            assert!((det.ln() - want).abs() < 3e-7, "ln det = {} against {want}", det.ln());
        }
    }
}
