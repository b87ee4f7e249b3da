//! What the `snowpack` binary's demo shares with the browser build
//! (`crates/snowpack-web`): the scene session (world, player, snow and
//! renderer), the camera rig, the egui panel, and the glue between a scene's
//! world and the snow that the headless runner uses too. The window, input and
//! command line stay in the binary; this part compiles for `wasm32` as well.

pub mod camera;
pub mod characters;
pub mod panel;
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
