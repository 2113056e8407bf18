//! Pure math kernels of the analyses of Bosetti & Posch, "Covariant Lyapunov Vectors for
//! Rigid Disk Systems" (GS vectors and CLVs of 2-d hard disks).
//!
//! Conventions shared by every file:
//! * N disks, phase-space dimension D = 4N; a tangent vector is a `&[f64]` of length D
//!   ordered (dq_x1, dq_y1, ..., dq_yN, dp_x1, ..., dp_yN), the phase point likewise
//!   (q_x1, ..., q_yN, p_x1, ..., p_yN) (paper eq. for Gamma in Sec. 5.4).
//! * A set of k vectors is column-major, length D k: vector j is `data[j*D..(j+1)*D]`.
//! * Indices are 0-based; the paper's Lyapunov index i (1-based) is our i - 1.
//! * Box sides lx, ly, periodic; sigma = m = 1.
//!
//! Nothing here does I/O or keeps state beyond small accumulators: frame consumers wrap these.

pub mod angles;
pub mod convergence;
pub mod local;
pub mod localization;
pub mod modes;
pub mod nullspace;
pub mod projections;
pub mod vecset;

#[cfg(test)]
mod testutil;
