//! [`GroundAfter`]: what the window's steps leave for the characters' snow,
//! in a file below both (the steps record the coats; the coats read it).

use crate::accumulate::OcclusionParams;
use crate::frame::WindowFrame;

/// What the window's steps leave for the characters' snow
/// ([`super::coat`]): where the window is, this frame's snowfall and the
/// occlusion's projection.
#[derive(Clone, Copy, Debug)]
pub(super) struct GroundAfter {
    /// The window's placement this frame.
    pub window: WindowFrame,
    /// This frame's snowfall on open ground (m).
    pub fall_m: f32,
    /// The occlusion's projection, when objects shelter the ground.
    pub sky: Option<OcclusionParams>,
}
