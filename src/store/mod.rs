//! How data lives on disk: a run directory of chunked MCAP segment files.
//!
//! ```text
//! RUN_DIR/run.json                  configuration + store layout + build (also inside every segment)
//! RUN_DIR/seg-FIRST-LAST.mcap       finished segments: steps FIRST (its first message)..=LAST (its last checkpoint)
//! RUN_DIR/seg-FIRST.mcap.tmp        the segment being written (a leftover means a crash)
//! RUN_DIR/spectrum.json             the final forward spectrum, once the run is complete
//! RUN_DIR/.lock                     the write lock a stage holds while it writes the run (lock.rs)
//! RUN_DIR/backward.json             the backward stage's record of its last sweep (resume; progress.rs)
//! RUN_DIR/clv_spectrum.json         the CLV spectrum of the last sweep
//! RUN_DIR/clv_spectrum-N.json       those of earlier sweeps with other options, kept
//! RUN_DIR/frames.mcap[.tmp]         the default frame file of `clv backward` (frames.rs)
//! RUN_DIR/previous-S-steps/         the stages' results of the run as it was with S steps,
//!                                   moved aside when it was made longer
//! RUN_DIR/run.json.from-segments    the newest segment's copy of an edited or damaged run.json
//! RUN_DIR/*.corrupt, *.superseded   damaged or misnamed segments set aside, and those a repair replaced (repair.rs)
//! RUN_DIR/repair-unverified/        the steps a repair recomputes, until they meet the next segment (a leftover: a stopped repair)
//! ```
//!
//! Why this shape: the Ginelli backward pass needs, newest first, what the forward pass
//! computed, and for the paper's system that is far too much to keep in memory. Checkpoints
//! every `checkpoint_every` steps hold the exact state, so anything between two of them can be
//! recomputed; files are only ever created whole (tmp + fsync + rename), so a killed run loses
//! at most the segment in progress and resumes bit for bit.

pub mod cbor;
pub mod checked_json;
pub mod checkpoints;
pub mod fault;
pub mod frames;
pub mod lock;
pub mod progress;
pub mod records;
pub mod repair;
pub mod run;
pub mod schema;
pub mod scratch;
pub mod segment;
pub mod sink;
pub mod write_error;

pub use run::{RunDir, RunMeta, StoreConfig, StoreR};
