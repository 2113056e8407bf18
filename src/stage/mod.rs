//! The stages of the pipeline: the forward Gram-Schmidt pass, the backward Ginelli pass over
//! the run it stored, and the analyses that consume the backward pass's frames.

pub mod backward;
pub mod forward;
pub mod analyze;
pub mod forward_run;
pub mod frame;
pub mod pipeline;
pub mod signals;
