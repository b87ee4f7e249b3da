//! The WGSL source of every pass, composed from `shaders/` and validated by
//! naga at build time (see `build.rs`).

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
