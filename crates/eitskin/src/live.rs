//! The frame path over time: the chain each frame goes through, the pipeline around it (reference,
//! noise, dropped channels), labelled frames, parallel work, scratch buffers and memory checks.

pub mod chain;
pub mod labelled;
pub mod memory;
pub mod parallel;
pub mod pipeline;
pub(crate) mod scratch;
