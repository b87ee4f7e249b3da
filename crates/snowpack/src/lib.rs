//! snowpack: real-time deformable snow on wgpu.
//!
//! Actors press trails into a persistent snow height field that refills over time;
//! a chain of GPU passes turns it into the displayed surface (rims, blur, normals)
//! and a readback ring answers CPU queries of snow depth a few frames late.
//! Every compute pass has a CPU twin in [`cpu`].

pub mod accumulate;
pub mod cpu;
pub mod deform;
pub mod error;
pub mod gpu;
pub mod persist;
pub mod render;
pub mod shaders;
pub mod skin;
pub mod terrain;
pub mod testing;

pub use deform::params::SnowParams;
pub use deform::shape::Deformer;
pub use deform::technique::{RimStyle, Technique};
pub use deform::{PointAnswers, PointSample, QueryStats, QueryTicket, SkinnedId, SkinnedPose, SnowDeformation, SnowFrame};
pub use error::SnowError;
pub use gpu::{AdapterRequest, GpuContext};
pub use render::{Camera, EnvironmentMap, RenderParams, Renderer};
pub use terrain::{HeightmapTerrain, NoiseTerrain, TerrainMesh, TerrainSource};
