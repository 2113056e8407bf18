//! clv: Lyapunov spectra, Gram-Schmidt vectors and covariant Lyapunov vectors of chaotic
//! many-particle systems, after Bosetti & Posch, "Covariant Lyapunov Vectors for Rigid Disk
//! Systems".
//!
//! The folders follow the data flow: [`system`] (what evolves), [`stage`] (the forward
//! Gram-Schmidt pass, the backward Ginelli pass, the analyses and the pipeline of all three),
//! [`store`] (how runs and frames live on disk), [`linalg`] (the QR step and the Ginelli
//! step's kernels), [`report`] (what a person sees); [`statistics`] holds the time averages
//! and their errors all of them share, and [`machine`] says what memory there is.

// Index loops over the rows and columns of matrices and tangent blocks read as the formulas
// they implement do; clippy's iterator rewrite of them would not.
#![allow(clippy::needless_range_loop)]

pub mod bench;
pub mod config;
pub mod error;
pub mod linalg;
pub mod machine;
pub mod report;
pub mod rng;
pub mod stage;
pub mod statistics;
pub mod store;
pub mod system;

pub use error::{Error, Result};

/// `eprintln!` that never panics: a notice that cannot be written (standard error closed,
/// or its file on a full disk or at a file-size limit) is lost, not the run that gives it.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}
