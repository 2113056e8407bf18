//! clv: Lyapunov spectra, Gram-Schmidt vectors and covariant Lyapunov vectors of chaotic
//! many-particle systems, after Bosetti & Posch, "Covariant Lyapunov Vectors for Rigid Disk
//! Systems".
//!
//! The folders follow the data flow: [`system`] (what evolves), [`stage`] (forward Gram-Schmidt
//! pass, and later the backward Ginelli pass and the analyses), [`linalg`] (the QR step),
//! [`report`] (what a person sees).

pub mod bench;
pub mod config;
pub mod error;
pub mod linalg;
pub mod report;
pub mod rng;
pub mod stage;
pub mod store;
pub mod system;

pub use error::{Error, Result};
