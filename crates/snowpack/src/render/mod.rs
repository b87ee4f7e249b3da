//! The snow renderer: CDLOD terrain displaced by the deformation, physically
//! based snow (GGX, wrapped blue-tinted diffuse, sparkle, compaction, detail
//! normals), a fitted sun shadow map, height-field ambient occlusion,
//! prefiltered image-based sky light and a filmic tone map; headless or into
//! any colour target. `docs/rendering.md` describes the design.
//!
//! One frame, in order: `ao` (compute) → `shadow` (terrain, actors and posed
//! characters into the shadow map) → `sky` → `terrain` → `actors` (spheres,
//! boxes, characters) → `objects` → `shell` (when on: construction, depth
//! peeling, composite; [`shell`]) → `tonemap`.

// What a game's own pass needs (the ground, the sampling module and its
// bind layout) is always built; snowpack's own renderer only with the
// `renderer` feature (the demo, the headless runner, `low_level`).
pub mod ground;
pub mod pipeline;
pub mod sampling;

#[cfg(feature = "renderer")]
pub mod actors;
#[cfg(feature = "renderer")]
pub mod ao;
#[cfg(feature = "renderer")]
pub mod camera;
#[cfg(feature = "renderer")]
pub mod detail;
#[cfg(feature = "renderer")]
pub mod environment;
#[cfg(feature = "renderer")]
pub mod frame;
#[cfg(feature = "renderer")]
pub mod lod;
#[cfg(feature = "renderer")]
pub mod objects;
#[cfg(feature = "renderer")]
pub mod params;
#[cfg(feature = "renderer")]
mod renderer;
#[cfg(feature = "renderer")]
pub mod shadow;
#[cfg(feature = "renderer")]
pub mod shell;
#[cfg(feature = "renderer")]
pub mod skinned;
#[cfg(feature = "renderer")]
pub mod sky;
#[cfg(feature = "renderer")]
pub mod surface;
#[cfg(feature = "renderer")]
pub mod terrain;
#[cfg(feature = "renderer")]
pub mod tonemap;

pub use ground::{GroundCamera, SnowGround, SnowGroundDescriptor};
#[cfg(feature = "renderer")]
pub use renderer::*;
