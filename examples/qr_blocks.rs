//! Experiment (not part of the tool): the Householder block size and parallelism of the QR
//! step at D = 792, on a random block (same flops as a tangent block).
use clv::linalg::Qr;
use clv::rng::Rng;
use clv::system::Tangent;
use faer::{Mat, Par};

fn main() {
    let d = 792;
    let mut rng = Rng::new(1);
    let mut a = Tangent::zeros(d, d);
    a.rows_mut().iter_mut().for_each(|x| *x = rng.normal());
    let mut r = Mat::zeros(d, d);
    for bs in [16, 32, 48, 64, 96, 128] {
        let mut line = format!("block {bs:>3}:");
        for (name, pf, pq) in [("1/1", Par::Seq, Par::Seq), ("1/2", Par::Seq, Par::rayon(2)), ("2/2", Par::rayon(2), Par::rayon(2))] {
            let mut qr = Qr::with_block(d, d, bs, pf, pq);
            let mut t: Vec<f64> = (0..5)
                .map(|_| {
                    let mut g = a.clone();
                    let s = std::time::Instant::now();
                    qr.factor(&mut g, &mut r);
                    s.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            t.sort_by(f64::total_cmp);
            line += &format!("  {name} threads (factor/Q) {:6.1} ms", t[2]);
        }
        println!("{line}");
    }
}
