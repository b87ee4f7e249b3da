//! snowpack: real-time deformable snow on wgpu.
//!
//! Actors press trails into a persistent snow height field that refills over
//! time; a chain of GPU passes turns it into the displayed surface (rims,
//! blur, normals); point queries answer gameplay's questions (snow depth under
//! a foot) a frame or two late without stalling; the snow is drawn into the
//! game's own render pass ([`SnowGround`]) or by the full `Renderer` (feature `renderer`).
//! Every compute pass has a CPU twin (`snowpack_testkit::cpu`, the test kit crate).
//!
//! A game with its own wgpu device:
//!
//! ```
//! use snowpack::{Deformer, GpuContext, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
//!
//! /// The game hands over its device and queue (cheap handles; it keeps its own).
//! fn snow_on(device: wgpu::Device, queue: wgpu::Queue) -> Result<(), snowpack::SnowError> {
//! let ctx = GpuContext::from_device(device, queue);
//! let mut snow = SnowDeformation::new(&ctx, SnowParams::default(), TerrainSource::Flat { height_m: 0.0 }, glam::DVec2::ZERO)?;
//! let ball = [Deformer::Sphere { center: glam::Vec3::new(0.0, 0.3, 0.0), radius: 0.4 }];
//! let mut encoder = ctx.device.create_command_encoder(&Default::default());
//! // The frame: what presses the snow, and where the game asks about it.
//! let frame = SnowFrame::new(1.0 / 60.0, &ball).with_queries(&[glam::Vec2::ZERO]);
//! snow.encode(&ctx, &mut encoder, &frame);
//! // ... the game's passes, with `ground.draw(..)` among their draws ...
//! ctx.queue.submit([encoder.finish()]); // nothing to call after it
//! // A frame or two later (each `encode` takes the answers that came back):
//! if let Some(sample) = snow.point_answers().and_then(|a| a.samples[0]) {
//!     println!("{:.2} m of snow, {:.0}% pressed", sample.depth_m(), 100.0 * sample.compaction());
//! }
//! Ok(())
//! }
//! ```
//!
//! Without a device of its own (tools, tests, a headless server), snowpack
//! picks an adapter itself; this runs as a test:
//!
//! ```
//! # fn main() -> Result<(), snowpack::SnowError> {
//! use glam::{DVec2, Vec2, Vec3};
//! use snowpack::{AdapterRequest, Deformer, GpuContext, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
//!
//! # if GpuContext::new_headless(&AdapterRequest::from_env()).is_err() && std::env::var("SNOWPACK_REQUIRE_GPU").map_or(true, |v| v.is_empty() || v == "0") { return Ok(()) }
//! let ctx = GpuContext::new_headless(&AdapterRequest::from_env())?;
//! let params = SnowParams { extent_m: 8.0, resolution: 128, depth_m: 0.5, ..SnowParams::default() };
//! let mut snow = SnowDeformation::new(&ctx, params, TerrainSource::Flat { height_m: 0.0 }, DVec2::ZERO)?;
//! // A ball whose bottom is 0.2 m above the ground presses 0.3 m of the 0.5 m of snow away.
//! let ball = Deformer::Sphere { center: Vec3::new(1.0, 0.6, 1.0), radius: 0.4 };
//! let points = [Vec2::new(1.0, 1.0), Vec2::new(-3.0, -3.0)];
//! // `step_frame`: encode, submit (a convenience for tools and tests).
//! let ticket = snow.step_frame(&ctx, &SnowFrame::new(1.0 / 60.0, &[ball]).with_queries(&points))?;
//! snow.finish(&ctx)?; // a test may wait; a game's frame never does
//! let answers = snow.point_answers().expect("answered");
//! assert_eq!(Some(answers.ticket), ticket);
//! let (under, away) = (answers.samples[0].unwrap(), answers.samples[1].unwrap());
//! assert!((under.depth_m() - 0.2).abs() < 0.01 && (under.compaction() - 0.6).abs() < 0.02);
//! assert!((away.depth_m() - 0.5).abs() < 1e-3 && away.compaction() < 1e-3);
//! # Ok(())
//! # }
//! ```
//!
//! `docs/integration.md` in the repository walks through adopting it.
//!
//! The crate root is the front door: the context ([`GpuContext`]), the snow
//! ([`SnowDeformation`], [`SnowParams`], [`SnowFrame`]), what presses it
//! ([`Deformer`], [`SkinnedMesh`], [`SkinnedPose`]), the terrain under it,
//! the ground drawn in a game's pass ([`SnowGround`]), point queries, objects
//! that gather snow ([`SnowObject`]) and errors. Trails stay in memory
//! while the window is away; keeping them on disk and sharing them between
//! machines are features.
//!
//! Features:
//! - `store`: trails kept on disk and whole-snow saves (`StoredWindow`,
//!   `SnowDeformation`'s `attach_store`, `preload`, `save`; `TileStore`,
//!   `TileStreamer`, their settings, `StoreError`).
//! - `share`: shared snow, a game's client side (`SharedWindow`,
//!   `SnowDeformation`'s `enable_sharing`, `world_identity`; `SnowPeer`, its
//!   settings and counters, `WorldIdentity`, `ShareError`).
//! - `renderer`: snowpack's own renderer (`Renderer`, `RenderParams`,
//!   `Camera`, `EnvironmentMap`, `ShellSettings`), as the demo and the
//!   headless runner draw the snow.
//! - `relay` (implies `share`): the relay of shared snow (`SnowRelay`,
//!   `RelayConfig`, `RelayStats`), for a game's server.
//! - `low_level` (implies all of the above): `snowpack::low_level`,
//!   named items below the front door (passes, their parameters, readbacks,
//!   the tile and wire formats) for snowpack's app, tools and tests.
//!
//! `docs/architecture.md` in the repository shows the layers, what each
//! module owns and one frame's path through them.

// The modules are the crate's own: the front door is the root's re-exports
// below, and what the app, the Bevy plugin and the tests need beyond it is
// re-exported by `low_level` (feature `low_level`).
mod accumulate;
mod deform;
mod error;
mod frame;
mod gpu;
mod height_depth;
#[cfg(feature = "low_level")]
pub mod low_level;
mod pass;
mod persist;
mod render;
mod replicate;
#[cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, reason = "every shader is composed and validated in every configuration; the renderer's and `ALL` are used with features")
)]
mod shaders;
mod skin;
mod snow;
mod snowfall;
mod terrain;
mod tiles;

// The front door: what a game uses (docs/architecture.md lists it and says why each is here).
pub use accumulate::{ObjectShape, ObjectStats, SnowObject};
pub use deform::params::SnowParams;
pub use deform::shape::Deformer;
pub use deform::technique::{RimStyle, Technique};
pub use deform::{PointAnswers, PointSample, QueryTicket};
pub use error::front::{SnowError, SnowErrorKind};
pub use gpu::{AdapterRequest, GpuContext, PassTimings};
pub use render::ground::{GroundLighting, SNOW_SAMPLING_WGSL};
pub use render::sampling::{SNOW_SAMPLING_GROUP, SnowWindowUniform, sampling_buffers, sampling_layout_entries, snow_sampling_wgsl_at};
pub use render::{GroundCamera, SnowGround, SnowGroundDescriptor};
// Trails kept on disk and whole-snow saves (feature `store`).
#[cfg(feature = "store")]
pub use error::front::{StoreError, StoreErrorKind};
#[cfg(feature = "store")]
pub use persist::{StoreConfig, StreamerConfig, TileStore, TileStreamer, WhenFull};
#[cfg(feature = "store")]
pub use snow::stored_window::StoredWindow;
// Shared snow, a game's client side (feature `share`).
#[cfg(feature = "share")]
pub use error::front::{ShareError, ShareErrorKind};
#[cfg(feature = "share")]
pub use replicate::{PeerConfig, PeerStats, SnowPeer, WorldIdentity};
#[cfg(feature = "share")]
pub use snow::shared_window::SharedWindow;
// The relay a game's server runs between its players (feature `relay`).
#[cfg(feature = "relay")]
pub use replicate::{PeerId, RelayConfig, RelayStats, SnowRelay};
pub use skin::coat::CoatSettings;
pub use skin::skinning::SkinnedMesh;
pub use snow::{SkinnedId, SkinnedPose, SnowDeformation, SnowFrame};
pub use snowfall::Snowfall;
/// Snow with mass: density from compaction, hardness, Bekker's sinkage and a
/// wheel's resistance (`docs/mechanics.md`); [`SnowParams::mechanics`] gives
/// the window's, [`PointSample::density_kg_m3`] the snow at a point.
pub use snowpack_share::mechanics;
pub use terrain::{HeightmapTerrain, NoiseTerrain, TerrainMesh, TerrainSource};

// snowpack's own renderer, for tools and the demo (feature `renderer`).
#[cfg(feature = "renderer")]
pub use render::shell::ShellSettings;
#[cfg(feature = "renderer")]
pub use render::{Camera, DebugView, EnvironmentMap, IMAGE_FORMAT, LightParams, Material, MaterialPreset, RenderParams, Renderer};
