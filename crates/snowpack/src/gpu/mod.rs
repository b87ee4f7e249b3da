//! GPU plumbing: adapter and device selection (or a game's device), readback rings, per-pass timing, render-pipeline builders, pipelines specialised on a constant.

pub mod context;
pub mod layout;
pub mod readback;
pub mod render;
pub mod specialised;
pub mod timing;

pub use context::{AdapterRequest, AdapterSummary, GpuContext};
pub use readback::{ReadbackRing, read_buffer};
pub use timing::{GpuTimer, PassTimings};
