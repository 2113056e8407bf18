//! Experiment: spread of forward step times (MD+tangent, QR) over many steps, N = 198.
use clv::config::{RunConfig, SystemConfig};
use clv::stage::forward::Forward;

fn main() {
    let threads: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let config = RunConfig { system: SystemConfig::disks(198, 0.7, 2.0 / 11.0).unwrap(), tau: 0.6, relax_steps: 0, steps: 400, vectors: 792, seed: 1, threads, blocks: 2 };
    let mut f = Forward::new(&config).unwrap();
    for _ in 0..5 {
        f.step().unwrap();
    }
    let (mut md, mut qr) = (vec![], vec![]);
    let t = std::time::Instant::now();
    for _ in 0..200 {
        let (a, q) = f.step_timed().unwrap();
        md.push(a.as_secs_f64() * 1e3);
        qr.push(q.as_secs_f64() * 1e3);
    }
    let wall = t.elapsed().as_secs_f64() * 1e3 / 200.0;
    for (name, mut v) in [("md+tangent", md), ("qr", qr)] {
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        v.sort_by(f64::total_cmp);
        println!("{name}: mean {mean:.2} median {:.2} p90 {:.2} max {:.2}", v[v.len() / 2], v[v.len() * 9 / 10], v[v.len() - 1]);
    }
    println!("wall per step {wall:.2} ms");
}
