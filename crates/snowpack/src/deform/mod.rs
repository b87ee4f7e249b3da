//! The deformation pipeline: sliding window, capture, update, rims, blur,
//! normals and readback, one module (and one WGSL file) per pass.

pub mod capture;
pub mod decal;
pub mod display;
pub mod exchange;
pub mod params;
pub mod pipeline;
pub mod query;
pub mod resources;
pub mod saved;
pub mod shape;
pub mod snow_word;
pub mod stamp;
pub mod technique;
pub mod terrain_bake;
pub mod tile_restore;
pub mod tile_seal;
pub mod tile_weather;
pub mod tiles;
pub mod traffic;
pub mod update;
pub mod window;

pub use pipeline::{SkinnedId, SkinnedPose, SnowDeformation, SnowFrame};
pub use query::{PointAnswers, PointSample, QueryStats, QueryTicket};
