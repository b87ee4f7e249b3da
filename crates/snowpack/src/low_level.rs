//! Below the front door (feature `low_level`): the library's modules as they
//! are, for snowpack's own app, its scene loader, benchmarks, fuzz targets
//! and tests, and for a game that replaces a pass or drives one by hand.
//!
//! Nothing here is covered by the crate's stability promise: passes, their
//! parameter structs and their resources change with the implementation.
//! The root of the crate is the API a game builds on; reach in here only for
//! what it cannot do, and say why where you do. `docs/architecture.md` says
//! what each module owns and how one frame passes through them.

/// What the app, the tools and the tests read or do with the front door's
/// plain types beyond it (terrains, techniques, deformers, parameters,
/// snowfall, skinned meshes, coat settings, the game's ground, adapter
/// requests).
pub use crate::deform::params::SnowParamsExt;
/// The point queries' counters ([`SnowInspect::query_stats`]).
pub use crate::deform::query::{QueryStats, QueryStatsExt};
pub use crate::deform::shape::DeformerExt;
pub use crate::deform::technique::{RimStyleExt, TechniqueExt};
pub use crate::gpu::context::AdapterRequestExt;
/// What the app, the tools and the tests do with a [`crate::GpuContext`]
/// beyond the front door.
pub use crate::gpu::context::GpuContextExt;
/// What the app, the tools and the tests do with a [`crate::TileStreamer`]
/// beyond the front door.
pub use crate::persist::streamer::TileStreamerExt;
pub use crate::render::ground::{SnowGroundDescriptorExt, SnowGroundExt};
pub use crate::render::sampling::SnowWindowUniformExt;
/// The snow-sampling WGSL module in any bind group (the root has
/// [`crate::snow_sampling_wgsl_at`], which also takes the binding offset).
pub use crate::render::sampling::snow_sampling_wgsl;
pub use crate::skin::coat::CoatSettingsExt;
pub use crate::skin::skinning::SkinnedMeshExt;
/// What snowpack's own app, tools and tests read and drive of a
/// [`crate::SnowDeformation`] beyond the front door.
pub use crate::snow::inspect::{SnowInspect, WindowMass};
pub use crate::snowfall::SnowfallExt;
pub use crate::terrain::{HeightmapTerrainExt, TerrainMeshExt, TerrainSourceExt};
pub use snowpack_share::persist::TileStoreExt;
pub use snowpack_share::replicate::{SnowPeerExt, WorldIdentityExt, WorldSettings};

/// Snow settling on objects: the object atlas, its passes and state.
pub mod accumulate {
    pub use crate::accumulate::*;
}
/// The core deformation: the window's resources and passes.
pub mod deform {
    pub use crate::deform::*;
}
/// The library's error type.
pub mod error {
    pub use crate::error::*;
}
/// The per-frame recording context and window placement handed to plug-ins.
pub mod frame {
    pub use crate::frame::*;
}
/// Device, readback and timing plumbing.
pub mod gpu {
    pub use crate::gpu::*;
}
/// The capture and occlusion depth format.
pub mod height_depth {
    pub use crate::height_depth::*;
}
/// The one shape of a compute pass and the window's shared bindings.
pub mod pass {
    pub use crate::pass::*;
}
/// The tile store, its codec and disks, and the streamer.
pub mod persist {
    pub use crate::persist::*;
}
/// snowpack's own renderer (the demo's and the headless runner's), its
/// parameters, and the ground drawn into a game's pass.
pub mod render {
    pub use crate::render::*;
}
/// Shared snow: mergeable tiles, their clock, the world identity, the wire
/// messages, peers and relays, and the window's gather and merge passes.
pub mod replicate {
    pub use crate::replicate::*;
}
/// Every pass's composed WGSL, validated by naga at build time.
pub mod shaders {
    pub use crate::shaders::*;
}
/// Skeletons, clips, feet and GPU skinning of characters.
pub mod skin {
    pub use crate::skin::*;
}
/// [`crate::SnowDeformation`]'s modules: the orchestrator, its saved state
/// and sharing.
pub mod snow {
    pub use crate::snow::*;
}
/// The snowfall settings.
pub mod snowfall {
    pub use crate::snowfall::*;
}
/// Terrain sources and their evaluation.
pub mod terrain {
    pub use crate::terrain::*;
}
/// The resident tiles around the window and their passes.
pub mod tiles {
    pub use crate::tiles::*;
}
