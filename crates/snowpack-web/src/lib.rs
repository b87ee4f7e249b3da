//! The snowpack demo in a browser page: the scene, panel, camera modes,
//! player fox, techniques and snowfall of the native demo (the session, rig
//! and panel come from `snowpack-app`'s library), drawn with WebGPU through
//! wgpu, the panel and input through eframe's web runner.
//!
//! `web/build.sh` builds it for `wasm32-unknown-unknown` and runs
//! wasm-bindgen; `web/test.sh` opens the page in headless Chromium. Natively
//! this crate is only [`report`], the page test's checks, so `cargo test`
//! covers them.

pub mod report;

#[cfg(target_arch = "wasm32")]
mod app;

#[cfg(target_arch = "wasm32")]
pub use app::start;
