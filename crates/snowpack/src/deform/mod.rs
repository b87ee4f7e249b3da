//! The core deformation: the window's resources and the passes over them
//! (sliding window, capture, footprints, update, the display: rims and blur,
//! decals, point queries), one module (and one WGSL file) per pass. It knows
//! nothing of accumulation on objects, of the tiles kept for the world or of
//! skinning: the orchestrator ([`crate::snow::SnowDeformation`]) records
//! those beside these passes.

pub mod capture;
pub mod capture_draw;
pub mod capture_instances;
pub mod capture_shapes;
pub mod decal;
pub mod displace;
pub mod display;
pub mod erosion;
pub mod packed_snow;
pub mod params;
pub mod push;
pub mod query;
pub mod resources;
pub mod shape;
pub mod snow_word;
pub mod stamp;
pub mod sweep;
pub mod technique;
pub mod terrain_bake;
pub mod traffic;
pub mod update;
pub mod wheel;
pub mod window;
pub mod window_ground;

pub use query::{PointAnswers, PointSample, QueryTicket};
