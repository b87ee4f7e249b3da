//! The core deformation: the window's resources and the passes over them
//! (sliding window, capture, footprints, update, rims, blur, normals,
//! decals, point queries), one module (and one WGSL file) per pass. It knows
//! nothing of accumulation on objects, of the tiles kept for the world or of
//! skinning: the orchestrator ([`crate::snow::SnowDeformation`]) records
//! those beside these passes.

pub mod blur;
pub mod capture;
pub mod decal;
pub mod normals;
pub mod params;
pub mod query;
pub mod resources;
pub mod rim;
pub mod shape;
pub mod stamp;
pub mod technique;
pub mod terrain_bake;
pub mod traffic;
pub mod update;
pub mod window;

pub use query::{PointAnswers, PointSample, QueryStats, QueryTicket};
