//! The stages of the pipeline: forward Gram-Schmidt pass (and, in later stages, the backward
//! Ginelli pass and the analyses that consume its frames).

pub mod backward;
pub mod forward;
pub mod analyze;
pub mod forward_run;
pub mod frame;
pub mod pipeline;
pub mod signals;
