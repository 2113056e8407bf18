//! Experiment (not part of the tool): covariant vectors of the steps between two V_n = G_n C_n
//! by the tangent map, V_{n+1} = J_n V_n with its columns normalised (the covariance that
//! defines the CLVs), instead of a triangular product per step. It would lower the
//! backward stage's work with V in every frame; this measures what it costs and how far the
//! propagated vectors are from the ones V = G C gives.
//!
//! A forward pass of the paper's system keeps G_n, R_n and the phase point of every step;
//! a backward pass from C = I, after a transient, forms V_n = G_n C_n for a few steps and
//! propagates it one and two steps on. The error of a column is the distance
//! min |v -+ w| between the propagated and the formed unit vector.
//!
//! Measured on 2026-11-26 (AMD EPYC, 2 cores, with another clv process running beside it),
//! N = 198, eight probed steps: one step of the tangent map puts the last vectors (j = 760
//! to 792, the most contracting) up to 2e-10 to 5e-10 from V = G C (median over the columns
//! 3e-14 to 1e-13); two steps up to 5e-7. The tangent map took 12.9-13.2 ms on one thread
//! (restore 0.6, into the tangent layout 2.2-3.1, MD and tangent 3.7-3.8, back into the
//! paper's layout and normalised 4.7-5.1) against 11.9-15.4 ms for V = G C. So it is neither
//! cheaper nor as accurate, and the backward stage forms every V_n as G_n C_n. Even at the
//! idle machine's costs (layouts 0.6 ms each, MD and tangent 2 ms, V = G C 7.6 ms) the sweep
//! would shrink from about 11.3 to 9.4 ms a step with V formed every other step: a bound of
//! about 1.28 instead of 1.35 forward steps, bought with the error above.
//!
//! cargo run --release --example propagated_vectors [-- N]
use clv::config::{RunConfig, SystemConfig};
use clv::linalg::{ginelli_step, mul_upper};
use clv::stage::forward::Forward;
use clv::system::Tangent;
use faer::{Mat, MatMut, MatRef, Par};
use std::time::Instant;

fn normalise_columns(v: &mut [f64], d: usize) {
    for col in v.chunks_exact_mut(d) {
        let norm = col.iter().map(|x| x * x).sum::<f64>().sqrt();
        col.iter_mut().for_each(|x| *x /= norm);
    }
}

/// Largest and median over the columns of min |v -+ w|.
fn column_errors(v: &[f64], w: &[f64], d: usize) -> (f64, f64, usize) {
    let mut e: Vec<(f64, usize)> = v
        .chunks_exact(d)
        .zip(w.chunks_exact(d))
        .enumerate()
        .map(|(j, (a, b))| {
            let minus = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
            let plus = a.iter().zip(b).map(|(x, y)| (x + y).powi(2)).sum::<f64>().sqrt();
            (minus.min(plus), j + 1)
        })
        .collect();
    e.sort_by(|a, b| a.0.total_cmp(&b.0));
    (e[e.len() - 1].0, e[e.len() / 2].0, e[e.len() - 1].1)
}

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(198);
    let d = 4 * n;
    let (relax, steps, transient, probes): (u64, usize, usize, usize) = (60, 70, 40, 8);
    let config = RunConfig { system: SystemConfig::disks(n, 0.7, 2.0 / 11.0).unwrap(), tau: 0.6, relax_steps: 0, steps: relax + steps as u64, vectors: d, seed: 1, threads: 2, blocks: 2 };
    let mut f = Forward::new(&config).unwrap();
    for _ in 0..relax {
        f.step().unwrap();
    }
    let (mut snaps, mut gs, mut rs) = (vec![f.system.snapshot()], vec![f.g.to_paper_columns(f.system.as_ref())], vec![]);
    for _ in 0..steps {
        f.step().unwrap();
        snaps.push(f.system.snapshot());
        gs.push(f.g.to_paper_columns(f.system.as_ref()));
        rs.push(f.r.clone());
    }
    // C_n for n = steps down to 0 (C_{n-1} = R_n^-1 C_n), kept for the probed steps.
    let mut c = Mat::<f64>::identity(d, d);
    let mut norms = vec![0.0; d];
    let mut cs = vec![None; steps + 1];
    let mut solve_ms = vec![];
    for m in (1..=steps).rev() {
        let t = Instant::now();
        ginelli_step(rs[m - 1].as_ref(), c.as_mut(), &mut norms, Par::Seq);
        solve_ms.push(t.elapsed().as_secs_f64() * 1e3);
        if m - 1 <= probes + 2 && steps - (m - 1) >= transient {
            cs[m - 1] = Some(c.clone());
        }
    }
    let formed = |m: usize, ms: &mut Vec<f64>| {
        let mut v = vec![0.0; d * d];
        let t = Instant::now();
        mul_upper(MatMut::from_column_major_slice_mut(&mut v, d, d), MatRef::from_column_major_slice(&gs[m], d, d), cs[m].as_ref().unwrap().as_ref(), Par::Seq);
        ms.push(t.elapsed().as_secs_f64() * 1e3);
        v
    };
    let mut system = Forward::new(&config).unwrap().system;
    system.set_threads(1);
    let mut tangent = Tangent::zeros(d, d);
    let mut parts = [vec![], vec![], vec![], vec![]];
    let mut propagate = |m: usize, v: &[f64], ms: &mut Vec<f64>| {
        let t = Instant::now();
        system.restore(&snaps[m]).unwrap();
        let t1 = Instant::now();
        tangent.read_paper_columns(system.as_ref(), v);
        let t2 = Instant::now();
        system.advance(&mut tangent).unwrap();
        let t3 = Instant::now();
        let mut w = vec![0.0; d * d];
        tangent.write_paper_columns(system.as_ref(), &mut w);
        normalise_columns(&mut w, d);
        let t4 = Instant::now();
        ms.push((t4 - t).as_secs_f64() * 1e3);
        for (p, (a, b)) in parts.iter_mut().zip([(t, t1), (t1, t2), (t2, t3), (t3, t4)]) {
            p.push((b - a).as_secs_f64() * 1e3);
        }
        w
    };
    let (mut vgc_ms, mut prop_ms) = (vec![], vec![]);
    println!("N = {n}, D = {d}: V_n = G_n C_n against the tangent map applied to V_(n-1) (one step) and V_(n-2) (two steps)");
    for m in 0..probes {
        let v0 = formed(m, &mut vgc_ms);
        let v1 = formed(m + 1, &mut vgc_ms);
        let v2 = formed(m + 2, &mut vgc_ms);
        let p1 = propagate(m, &v0, &mut prop_ms);
        let p2 = propagate(m + 1, &p1, &mut vec![]);
        let (max1, med1, j1) = column_errors(&p1, &v1, d);
        let (max2, med2, j2) = column_errors(&p2, &v2, d);
        println!("step {m}: one step: largest {max1:.2e} (j = {j1}), median {med1:.2e}; two steps: largest {max2:.2e} (j = {j2}), median {med2:.2e}");
    }
    let median = |mut x: Vec<f64>| {
        x.sort_by(f64::total_cmp);
        x[x.len() / 2]
    };
    let (solve, vgc, prop) = (median(solve_ms), median(vgc_ms), median(prop_ms));
    let [restore, read, advance, write] = parts.map(median);
    println!("the tangent map's parts, medians: restore {restore:.2} ms, into the tangent layout {read:.2}, advance (MD and tangent) {advance:.2}, back and normalised {write:.2}");
    println!("one thread, medians: R^-1 C {solve:.2} ms, V = G C {vgc:.2} ms, V by the tangent map (restore, layout both ways, advance, normalise) {prop:.2} ms");
    for p in [2.0, 3.0] {
        println!("  V = G C every {p} steps, the tangent map between: sweep {:.2} ms a step against {:.2}", solve + (vgc + (p - 1.0) * prop) / p, solve + vgc);
    }
}
