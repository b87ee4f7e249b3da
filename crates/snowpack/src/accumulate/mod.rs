//! Occlusion-based snow accumulation (Reynolds, Laycock and Day; Dinh 2021,
//! chapters 4 and 5), on objects and on the ground.
//!
//! Per frame, while it snows:
//! 1. [`OcclusionPass`]: the objects drawn from the snowfall direction
//!    (jittered for flutter) with a sheared orthographic projection onto the
//!    deformation window: per pixel the height of the surface the sky sees
//!    (depth) and the rectangle of atlas texels its footprint covers.
//! 2. [`ScatterPass`] (compute, replacing the original's geometry shader):
//!    each pixel adds its share of one pixel's snow volume to the texels of its
//!    rectangle, with integer atomics into one atlas for all objects.
//! 3. [`IncrementPass`]: hits to a depth increment (volume over the texel's
//!    area), clearing the hits.
//! 4. [`SettlePass`]: the increment blurred 5x5 within its object, added, and
//!    the stability of eq. 4.3 (capacity by slope, angle of repose).
//! 5. [`AtlasSurfacePass`]: dilation (per object) and Scharr slopes, what the
//!    renderer draws.
//!
//! The ground uses the same occlusion depth: the update pass of the
//! deformation adds the snowfall only to texels the sky reaches (their rest
//! height rises), and refills trails only there (see `shaders/update.wgsl`).
//!
//! Accumulation lives in object space (the atlas), so objects that move or
//! turn carry their snow with them.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

pub mod atlas;
pub mod increment;
pub mod mesh;
pub mod occlusion;
pub mod scatter;
pub mod settle;
pub mod state;
pub mod surface;

use glam::{Quat, Vec3};

pub use atlas::{AtlasLayout, ObjectVertex};
pub use increment::{IncrementParams, IncrementPass};
pub use mesh::ObjectMesh;
pub use occlusion::OcclusionParams;
pub use scatter::{ScatterParams, ScatterPass};
pub use settle::{SettleParams, SettlePass};
pub use state::{ObjectStats, SnowAccumulation};
pub use surface::{AtlasSurfacePass, SurfaceParams};

/// The snowfall settings the accumulation passes take (defined beside the
/// ground's use of them, in `crate::snowfall`).
pub use crate::snowfall::Snowfall;

/// The shape of an accumulation object.
#[derive(Clone, Debug, PartialEq)]
pub enum ObjectShape {
    /// A box of these side lengths (m), centred on the object's position.
    Box {
        /// Side lengths along the object's x, y and z (m).
        size_m: Vec3,
    },
    /// A sphere of this radius (m).
    Sphere {
        /// Radius (m).
        radius_m: f32,
    },
    /// A triangle mesh (glTF in scenes), charted by its own UVs when they do
    /// not overlap, else a chart per triangle.
    Mesh(std::sync::Arc<ObjectMesh>),
}

/// An object snow settles on: the `[[object]]` table of scene files.
#[derive(Clone, Debug, PartialEq)]
pub struct SnowObject {
    /// Unique name (reported in `meta.json`).
    pub name: String,
    /// Shape and size (fixed once the atlas is laid out).
    pub shape: ObjectShape,
    /// Centre (m); may change every frame.
    pub position: Vec3,
    /// Orientation; may change every frame.
    pub rotation: Quat,
    /// Whether its accumulation is dilated (Dinh: fills chart margins; off for
    /// thin, holey objects like fences).
    pub dilate: bool,
}
