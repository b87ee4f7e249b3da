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
//! # if GpuContext::new_headless(&AdapterRequest::from_env()).is_err() && !snowpack::testing::gpu_required() { return Ok(()) }
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
//! The modules, core first (each uses only those above it, and the neutral
//! ones; `tests/layering.rs` keeps `deform` and `accumulate` apart):
//!
//! | module | what |
//! |---|---|
//! | [`gpu`], [`terrain`], [`error`] | device and readback plumbing, terrain sources, errors |
//! | [`frame`], [`height_depth`], [`snowfall`] | neutral: the per-frame recording context and window placement plug-ins get, the capture and occlusion depth format, the snowfall settings |
//! | [`deform`] | the core deformation: the window's resources and passes (window, capture, footprints, update, rims, blur, normals, decals, point queries) |
//! | [`accumulate`] | snow settling on objects (plugs in; knows nothing of `deform`) |
//! | [`persist`], [`tiles`] | the tile store and streamer; the resident tiles around the window and their passes (plug in) |
//! | [`skin`] | skeletons, clips and GPU skinning of characters (plugs in) |
//! | [`replicate`] | shared snow: mergeable tiles, their clock, the world identity, the wire messages, [`replicate::SnowPeer`] and [`replicate::SnowRelay`]; the window's changed-tile flags, gather and merge passes (plugs in) |
//! | [`snow`] | [`SnowDeformation`]: the core passes and the plug-ins recorded in order, save and load |
//! | [`render`] | snowpack's renderer and the ground drawn into a game's pass |

pub mod accumulate;
#[doc(hidden)]
pub mod cpu;
pub mod deform;
pub mod error;
pub mod frame;
pub mod gpu;
pub mod height_depth;
pub mod persist;
pub mod render;
pub mod replicate;
#[doc(hidden)]
pub mod shaders;
pub mod skin;
pub mod snow;
pub mod snowfall;
pub mod terrain;
#[doc(hidden)]
pub mod testing;
pub mod tiles;

// The types a game needs, at the root (docs/integration.md walks through them).
pub use accumulate::SnowObject;
pub use deform::params::SnowParams;
pub use deform::shape::Deformer;
pub use deform::technique::{RimStyle, Technique};
pub use deform::{PointAnswers, PointSample, QueryStats, QueryTicket};
pub use error::SnowError;
pub use gpu::{AdapterRequest, GpuContext};
pub use persist::{StoreConfig, StreamerConfig, TileStore, TileStreamer};
pub use render::ground::{GroundLighting, SNOW_SAMPLING_WGSL};
pub use render::shell::ShellSettings;
pub use render::{Camera, EnvironmentMap, GroundCamera, RenderParams, Renderer, SnowGround, SnowGroundDescriptor};
pub use snow::{SkinnedId, SkinnedPose, SnowDeformation, SnowFrame};
pub use snowfall::Snowfall;
pub use terrain::{HeightmapTerrain, NoiseTerrain, TerrainMesh, TerrainSource};
