//! Experiment (not part of the tool): collisions per second with k = 0 against N, all sizes
//! measured in turn, round after round, to tell the scaling from the host's noise.
//!
//! cargo run --release --example collision_scaling [-- ROUNDS [N,N,... [TAU]]]
use clv::system::disks::{box_sides, HardDisks};
use clv::system::{DynamicalSystem, Tangent};
use std::time::Instant;

fn rate(size: usize, tau: f64) -> f64 {
    let (lx, ly) = box_sides(size, 0.7, 2.0 / 11.0);
    let mut s = HardDisks::new(size, lx, ly, tau, 3).expect("a valid system");
    let mut none = Tangent::zeros(4 * size, 0);
    s.advance(&mut none).expect("dynamics");
    let c0 = s.invariants().events;
    let t = Instant::now();
    while s.invariants().events - c0 < 300_000 {
        s.advance(&mut none).expect("dynamics");
    }
    (s.invariants().events - c0) as f64 / t.elapsed().as_secs_f64()
}

fn main() {
    let mut args = std::env::args().skip(1);
    let rounds: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(5);
    let sizes: Vec<usize> = args.next().map_or(vec![198, 1980, 19800], |s| s.split(',').filter_map(|x| x.parse().ok()).collect());
    let tau: f64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(0.6);
    for _ in 0..rounds {
        let r: Vec<String> = sizes.iter().map(|&n| format!("N = {n}: {:.3e}", rate(n, tau))).collect();
        println!("{}", r.join("  "));
    }
}
