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

pub mod atlas;
pub mod increment;
pub mod mesh;
pub mod occlusion;
pub mod scatter;
pub mod settle;
pub mod state;
pub mod surface;

use glam::{Quat, Vec3};

use crate::error::SnowError;

pub use atlas::{AtlasBake, AtlasLayout, ObjectVertex};
pub use increment::{IncrementParams, IncrementPass};
pub use mesh::{ChartedMesh, ObjectMesh};
pub use occlusion::{OcclusionParams, OcclusionPass};
pub use scatter::{ScatterParams, ScatterPass};
pub use settle::{SettleParams, SettlePass};
pub use state::{ObjectStats, SnowAccumulation};
pub use surface::{AtlasSurfacePass, SurfaceParams};

/// How snow falls: the `[snowfall]` table of scene files.
#[derive(Clone, Debug, PartialEq)]
pub struct Snowfall {
    /// Direction the flakes travel (unit vector, pointing down).
    pub direction: Vec3,
    /// Depth open flat ground gains per second (m/s).
    pub rate_m_per_s: f32,
    /// Random per-frame tilt of the direction, up to this angle (degrees).
    pub flutter_deg: f32,
    /// Amplitude of the per-pixel noise on the amount that lands (0..1).
    pub noise: f32,
    /// Angle of repose: surfaces steeper than this hold no snow, and those within
    /// 10 degrees of it keep only part of what lands (degrees).
    pub repose_deg: f32,
    /// How fast snow beyond a surface's capacity slides off (1/s; Dinh's
    /// per-frame falloff `f` is `1 - exp(-falloff_per_s * dt)`).
    pub falloff_per_s: f32,
    /// Most snow a flat surface holds (Dinh's `m`), and the most that falls on
    /// the ground above its rest depth (m).
    pub max_m: f32,
    /// Texels per side of the objects' accumulation atlas.
    pub atlas_resolution: u32,
}

impl Default for Snowfall {
    fn default() -> Self {
        Self {
            direction: Vec3::NEG_Y,
            rate_m_per_s: 0.001,
            flutter_deg: 5.0,
            noise: 0.25,
            repose_deg: 40.0,
            falloff_per_s: 2.0,
            max_m: 1.0,
            atlas_resolution: 1024,
        }
    }
}

/// Steepest fall direction snowpack accepts: flakes must travel downward by at
/// least this much of their speed (the occlusion is a projection onto the ground).
pub const MIN_DOWNWARD: f32 = 0.1;

impl Snowfall {
    /// Checks every value; the error names the offending field.
    pub fn validate(&self) -> Result<(), SnowError> {
        let bad = |field: &'static str, why: String| Err(SnowError::InvalidParameter { field, why });
        let d = self.direction;
        if !d.is_finite() || d.length() < 1e-6 || d.normalize().y > -MIN_DOWNWARD {
            return bad("direction", format!("{d} must point downward (y below -{MIN_DOWNWARD} once normalised)"));
        }
        if !(self.rate_m_per_s.is_finite() && self.rate_m_per_s >= 0.0) {
            return bad("rate_m_per_s", format!("{} must be zero or positive", self.rate_m_per_s));
        }
        if !(self.flutter_deg.is_finite() && (0.0..=45.0).contains(&self.flutter_deg)) {
            return bad("flutter_deg", format!("{} is outside 0..=45 degrees", self.flutter_deg));
        }
        if !(self.noise.is_finite() && (0.0..=1.0).contains(&self.noise)) {
            return bad("noise", format!("{} is outside 0..=1", self.noise));
        }
        if !(self.repose_deg.is_finite() && (0.0..=90.0).contains(&self.repose_deg)) {
            return bad("repose_deg", format!("{} is outside 0..=90 degrees", self.repose_deg));
        }
        if !(self.falloff_per_s.is_finite() && self.falloff_per_s >= 0.0) {
            return bad("falloff_per_s", format!("{} must be zero or positive", self.falloff_per_s));
        }
        if !(self.max_m.is_finite() && self.max_m > 0.0) {
            return bad("max_m", format!("{} must be a positive number of metres", self.max_m));
        }
        if !(16..=8192).contains(&self.atlas_resolution) {
            return bad("atlas_resolution", format!("{} is outside 16..=8192", self.atlas_resolution));
        }
        Ok(())
    }
}

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
