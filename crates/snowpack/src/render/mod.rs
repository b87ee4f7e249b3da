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

/// Declares the modules of snowpack's own renderer, compiled with its feature.
macro_rules! renderer_modules {
    ($($module:ident),* $(,)?) => {
        $(
            #[cfg(feature = "renderer")]
            pub mod $module;
        )*
    };
}

renderer_modules!(actors, ao, camera, detail, environment, frame, lod, objects, params, shadow, shell, skinned, sky, surface, terrain, tonemap);
#[cfg(feature = "renderer")]
mod renderer;

pub use ground::{GroundCamera, SnowGround, SnowGroundDescriptor};
#[cfg(feature = "renderer")]
pub use renderer::*;
