//! What the `snowpack` binary's demo shares with the browser build
//! (`crates/snowpack-web`): the scene session (world, player, snow and
//! renderer), the camera rig, the egui panel, and the glue between a scene's
//! world and the snow that the headless runner uses too. The window, input and
//! command line stay in the binary; this part compiles for `wasm32` as well.
//! Without the `gpu` feature (the server-only binary) it is what the server
//! shares with the rest: [`BadInput`] and [`machine_fault`].

#[cfg(feature = "gpu")]
pub mod camera;
#[cfg(feature = "gpu")]
pub mod characters;
#[cfg(feature = "gpu")]
pub mod panel;
#[cfg(feature = "gpu")]
pub mod session;

/// A problem with what the user gave us: the binary exits with code 2.
#[derive(Debug)]
pub struct BadInput(pub String);

impl std::fmt::Display for BadInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadInput {}

/// Whether a store error is the machine's fault (the disk failed, hung, or
/// the worker died: exit 1) rather than the user's (a store of another
/// tile side or format, a damaged or mismatched save: exit 2).
#[must_use]
pub fn machine_fault(e: &snowpack_share::error::StoreError) -> bool {
    use snowpack_share::error::StoreError;
    matches!(e, StoreError::Io { .. } | StoreError::TimedOut { .. } | StoreError::WorkerGone)
}
