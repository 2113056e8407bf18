//! Experiment (not part of the tool): CholeskyQR2 against the Householder QR the forward
//! stage uses, at D = 792 on a realistic tangent block, 1 and 2 threads.
use clv::config::{RunConfig, SystemConfig};
use clv::linalg::Qr;
use clv::stage::forward::Forward;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Accum, Mat, Par, Side};

fn cholqr_pass(a: &mut Mat<f64>, par: Par) -> Mat<f64> {
    let k = a.ncols();
    let mut gram = Mat::zeros(k, k);
    matmul(gram.as_mut(), Accum::Replace, a.transpose(), a.as_ref(), 1.0, par);
    let l = gram.llt(Side::Lower).expect("positive definite").L().to_owned();
    // A R^-1 with R = L^T: solve L X^T = A^T.
    solve_lower_triangular_in_place(l.as_ref(), a.as_mut().transpose_mut(), par);
    l.transpose().to_owned()
}

fn main() {
    let config = RunConfig { system: SystemConfig::disks(198, 0.7, 2.0 / 11.0).unwrap(), tau: 0.6, relax_steps: 0, steps: 10, vectors: 792, seed: 1, threads: 1, blocks: 2 };
    let mut f = Forward::new(&config).unwrap();
    for _ in 0..5 {
        f.step().unwrap();
    }
    // A realistic block: one tau of tangent dynamics applied to the current G.
    let mut t = f.g.clone();
    f.system.advance(&mut t).unwrap();
    let (d, k) = (792, 792);
    let a0 = Mat::from_fn(d, k, |i, j| t.get(i, j));
    for threads in [1usize, 2] {
        let par = if threads == 1 { Par::Seq } else { Par::rayon(threads) };
        let (mut hh, mut cq) = (vec![], vec![]);
        let mut r = Mat::zeros(k, k);
        let mut qr = Qr::new(d, k, threads);
        for _ in 0..5 {
            let mut g = t.clone();
            let s = std::time::Instant::now();
            qr.factor(&mut g, &mut r);
            hh.push(s.elapsed().as_secs_f64() * 1e3);
            let mut a = a0.clone();
            let s = std::time::Instant::now();
            let r1 = cholqr_pass(&mut a, par);
            let r2 = cholqr_pass(&mut a, par);
            let _r = &r2 * &r1;
            cq.push(s.elapsed().as_secs_f64() * 1e3);
            // Orthogonality of the CholeskyQR2 Q.
            let err = (a.transpose() * &a - Mat::<f64>::identity(k, k)).norm_max();
            assert!(err < 1e-12, "orthogonality {err}");
        }
        hh.sort_by(f64::total_cmp);
        cq.sort_by(f64::total_cmp);
        println!("{threads} thread(s): Householder (forward stage) {:.1} ms, CholeskyQR2 {:.1} ms (medians of 5)", hh[2], cq[2]);
    }
}
