//! The one shape of a compute pass ([`compute::ComputePass`]: its pipelines,
//! uniform and bindings, recorded by one call) and the window's buffers as
//! one bind group shared by every pass over the window
//! ([`window_bindings::WindowBindings`]).
#![cfg_attr(not(feature = "low_level"), allow(dead_code, unused_imports, reason = "what the tests use beyond the front door, reached through `low_level`"))]

pub mod compute;
pub mod window_bindings;
