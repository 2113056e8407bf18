//! `clv bench`: kernels and stages measured side by side on this machine.

use super::{emit, print_json};
use clap::Args;
use clv::Result;

#[derive(Args)]
pub struct BenchArgs {
    /// Disks N of the benchmark system (D = 4N).
    #[arg(long, default_value_t = clv::bench::PAPER_N, allow_negative_numbers = true)]
    pub n: usize,
    /// Tangent vectors (default D).
    #[arg(long, allow_negative_numbers = true)]
    pub vectors: Option<usize>,
    /// Threads for the linear algebra.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub threads: usize,
    /// Repetitions of each measurement.
    #[arg(long, default_value_t = 5, allow_negative_numbers = true)]
    pub reps: usize,
    /// System sizes N for the collision-rate measurement (k = 0).
    #[arg(long, value_delimiter = ',', default_value = "198,1980,19800", allow_negative_numbers = true)]
    pub collision_sizes: Vec<usize>,
    /// Skip the peak-memory measurement (child processes).
    #[arg(long)]
    pub no_rss: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

pub fn bench(args: &BenchArgs) -> Result<()> {
    let opts = clv::bench::BenchOptions {
        n: args.n,
        k: args.vectors,
        threads: args.threads,
        reps: args.reps,
        collision_sizes: args.collision_sizes.clone(),
        exe: if args.no_rss { None } else { std::env::current_exe().ok() },
    };
    let report = clv::bench::run(&opts, &mut |what| clv::note!("clv bench: {what}"))?;
    if args.json { print_json(&report) } else { emit(&report.table()) }
}
