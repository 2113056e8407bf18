//! `clv bench` runs and reports every quantity the performance targets are stated in.
//! (No timing is asserted: machines are noisy; the numbers go to the README and notes.)

#[test]
fn bench_reports_every_quantity_as_json() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_clv"))
        .args(["bench", "--n", "6", "--reps", "2", "--collision-sizes", "8,80", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in ["gemm_gflops", "qr_ms", "forward_step_ms", "md_tangent_ms", "store_ms", "backward_step_ms", "backward_solve_ms", "backward_vgc_ms", "leading_k16_step_ms"] {
        let m = v[key]["median"].as_f64().unwrap_or(f64::NAN);
        assert!(m.is_finite() && m > 0.0, "{key}: {}", v[key]);
    }
    for key in ["floor_ms", "forward_step_over_qr", "qr_over_floor", "backward_over_forward"] {
        assert!(v[key].as_f64().is_some_and(|x| x.is_finite() && x > 0.0), "{key}: {}", v[key]);
    }
    // N = 6 says nothing about the paper's run: no projection of it.
    assert!(["paper_forward_hours", "paper_backward_hours", "paper_backward_sampled_hours"].iter().all(|key| v[*key].is_null()), "{v}");
    let rates = v["collisions_per_second"].as_array().unwrap();
    assert_eq!(rates.iter().map(|r| r["n"].as_u64()).collect::<Vec<_>>(), [Some(8), Some(80)]);
    assert!(rates.iter().all(|r| r["per_second"]["min"].as_f64().unwrap() > 0.0), "{rates:?}");
    // The spread is of rates measured side by side in each round, not of the medians.
    assert!(v["collision_rate_spread"].as_f64().is_some_and(|x| x >= 1.0 && x.is_finite()), "{}", v["collision_rate_spread"]);
    let rss = v["forward_peak_rss"].as_array().unwrap();
    assert_eq!(rss.len(), 2);
    assert!(rss.iter().all(|r| r["peak_mb"].as_f64().unwrap() > 1.0));
    assert_eq!((rss[0]["runs"].as_u64(), rss[1]["runs"].as_u64()), (Some(3), Some(3)), "each length is the largest of three runs");
    assert_eq!(v["backward_peak_rss"].as_array().unwrap().len(), 2);
    // The work bound of a backward step is one of several cores.
    assert!(v["backward_work_bound_ms"].is_null() && v["backward_work_bound_over_forward"].is_null());
}

/// On two threads the bench also gives the least a backward step can take from its work
/// measured on one thread, and that over the forward step.
#[test]
fn bench_on_two_threads_bounds_the_backward_step() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_clv"))
        .args(["bench", "--n", "6", "--reps", "2", "--threads", "2", "--collision-sizes", "8", "--no-rss", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let (bound, forward) = (v["backward_work_bound_ms"].as_f64().unwrap(), v["forward_step_ms"]["median"].as_f64().unwrap());
    assert!(bound > 0.0 && bound.is_finite());
    assert!((v["backward_work_bound_over_forward"].as_f64().unwrap() - bound / forward).abs() < 1e-12);
    // The table projects the paper's run only from steps of the paper's system.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_clv")).args(["bench", "--n", "6", "--reps", "1", "--collision-sizes", "8", "--no-rss"]).output().unwrap();
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("paper run projection: none (it needs N = 198 with all 792 vectors; this bench ran N = 6, k = 24)"), "{table}");
}

/// Options that would measure nothing (or never end) are refused, naming the flag.
#[test]
fn bench_refuses_options_that_measure_nothing() {
    for (args, flag) in [
        (&["--threads", "0"][..], "--threads"),
        (&["--reps", "0"], "--reps"),
        (&["--n", "0"], "--n"),
        (&["--vectors", "5000"], "--vectors"),
        (&["--collision-sizes", "8,1"], "--collision-sizes"),
        // too few disks for the bench's box, and more than any memory holds
        (&["--n", "3"], "--n"),
        (&["--n", "8", "--collision-sizes", "3"], "--collision-sizes"),
        (&["--n", "8", "--collision-sizes", "200000000000"], "--collision-sizes"),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_clv")).arg("bench").args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(&format!("invalid {flag}")), "{args:?}: {err}");
    }
}
