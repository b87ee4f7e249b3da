//! GPU plumbing: adapter and device selection (or a game's device), readback rings, per-pass timing, render-pipeline builders; a compute pass's pipeline cache is `pass`'s.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

pub mod context;
pub mod layout;
pub mod readback;
pub mod render;
pub mod timing;

pub use context::{AdapterRequest, GpuContext};
pub use readback::{ReadbackRing, read_buffer};
pub use timing::{GpuTimer, PassTimings};
