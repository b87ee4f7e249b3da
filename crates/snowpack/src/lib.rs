//! snowpack: real-time deformable snow on wgpu.
//!
//! Actors press trails into a persistent snow height field that refills over
//! time; a chain of GPU passes turns it into the displayed surface (rims,
//! blur, normals); point queries answer gameplay's questions (snow depth under
//! a foot) a frame or two late without stalling; the snow is drawn into the
//! game's own render pass ([`SnowGround`]) or by the full [`Renderer`].
//! Every compute pass has a CPU twin (the hidden `cpu` module, for tests).
//!
//! A game with its own wgpu device:
//!
//! ```no_run
//! # fn main() -> Result<(), snowpack::SnowError> {
//! # let (device, queue): (wgpu::Device, wgpu::Queue) = unimplemented!();
//! use snowpack::{Deformer, GpuContext, SnowDeformation, SnowFrame, SnowParams, TerrainSource};
//!
//! let ctx = GpuContext::from_device(device, queue);
//! let mut snow = SnowDeformation::new(&ctx, SnowParams::default(), TerrainSource::Flat { height_m: 0.0 }, glam::DVec2::ZERO)?;
//! let ball = [Deformer::Sphere { center: glam::Vec3::new(0.0, 0.3, 0.0), radius: 0.4 }];
//! snow.query_points(&[glam::Vec2::ZERO]);
//! let mut encoder = ctx.device.create_command_encoder(&Default::default());
//! snow.encode(&ctx, &mut encoder, &SnowFrame::new(1.0 / 60.0, &ball));
//! ctx.queue.submit([encoder.finish()]);
//! snow.after_submit(&ctx);
//! // A frame or two later:
//! if let Some(sample) = snow.point_answers().and_then(|a| a.samples[0]) {
//!     println!("{:.2} m of snow, {:.0}% pressed", sample.depth_m(), 100.0 * sample.compaction());
//! }
//! # Ok(())
//! # }
//! ```
//!
//! `docs/integration.md` in the repository walks through adopting it.

pub mod accumulate;
#[doc(hidden)]
pub mod cpu;
pub mod deform;
pub mod error;
pub mod gpu;
pub mod persist;
pub mod render;
#[doc(hidden)]
pub mod shaders;
pub mod skin;
pub mod terrain;
#[doc(hidden)]
pub mod testing;

// The types a game needs, at the root (docs/integration.md walks through them).
pub use accumulate::{SnowObject, Snowfall};
pub use deform::params::SnowParams;
pub use deform::shape::Deformer;
pub use deform::technique::{RimStyle, Technique};
pub use deform::{PointAnswers, PointSample, QueryStats, QueryTicket, SkinnedId, SkinnedPose, SnowDeformation, SnowFrame};
pub use error::SnowError;
pub use gpu::{AdapterRequest, GpuContext};
pub use persist::{StoreConfig, StreamerConfig, TileStore, TileStreamer};
pub use render::ground::{GroundLighting, SNOW_SAMPLING_WGSL};
pub use render::shell::ShellSettings;
pub use render::{Camera, EnvironmentMap, GroundCamera, RenderParams, Renderer, SnowGround, SnowGroundDescriptor};
pub use terrain::{HeightmapTerrain, NoiseTerrain, TerrainMesh, TerrainSource};
