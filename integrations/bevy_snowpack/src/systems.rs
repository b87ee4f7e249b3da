//! The plugin's system sets, in the order a frame runs them. What the
//! render world sends back travels on `from_render.rs`'s channel and is
//! received in [`SnowSystems::Receive`] (`receive.rs`).

use bevy::prelude::*;

/// The plugin's systems, in the order a frame runs them; order a game's own
/// around them with `.before(SnowSystems::…)` / `.after(SnowSystems::…)`.
///
/// Main world:
/// - [`Self::Receive`] (`PreUpdate`): what the render world read back arrives
///   ([`crate::SnowQuery`] answers, [`crate::SnowControl`] results; what arrives during a
///   frame's extraction is handed over there). A system after it in the
///   same frame sees them.
/// - [`Self::Gather`] (`PostUpdate`, after transform propagation): the mesh
///   deformers' poses are gathered for this frame's extraction. A system that
///   moves a [`crate::SnowDeformer`] runs before `PostUpdate` (or before this set).
/// - [`Self::Footsteps`] (`PostUpdate`, after [`Self::Gather`]): the
///   [`crate::SnowFoot`] answers are read, [`crate::SnowFootstep`] messages
///   written, and the next questions asked. Read the messages after this set
///   (or in the next frame's `Update`).
/// - [`Self::Bounds`] (`PostUpdate`, after Bevy's bounds): the snow ground
///   meshes' bounds span the snow's heights.
///
/// Render world:
/// - [`Self::Extract`] (`ExtractSchedule`): the settings, deformers, objects,
///   meshes' poses, questions and requests are taken from the main world.
/// - [`Self::Encode`] (`RenderGraph`, before the cameras): changed settings are
///   applied and the snow's frame recorded; after the submit, the readbacks
///   are started and finished ones sent to the main world.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SnowSystems {
    /// Answers and results from the render world arrive (main world, `PreUpdate`).
    Receive,
    /// The mesh deformers' poses are gathered (main world, `PostUpdate`).
    Gather,
    /// Footsteps are detected and their questions asked (main world, `PostUpdate`).
    Footsteps,
    /// The snow ground meshes' bounds are grown (main world, `PostUpdate`).
    Bounds,
    /// The frame's snow is taken from the main world (render world, `ExtractSchedule`).
    Extract,
    /// Settings applied, the frame recorded, readbacks sent (render world, `RenderGraph`).
    Encode,
}

/// Inside [`SnowSystems::Receive`]: the system that puts what arrived where
/// the main world reads it. The plugin's systems that announce what arrived
/// (events for observers) run after it.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Delivered;
