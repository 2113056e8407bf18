//! The analyses: independent consumers of the CLV frame stream, each on its own thread.
pub mod kernels;
