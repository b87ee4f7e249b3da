//! How snow falls: the settings the ground's update and the objects'
//! accumulation both follow (the `[snowfall]` table of scene files).

use glam::Vec3;

use crate::error::SnowError;

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

impl Snowfall {}

/// What snowpack's own app, tools and tests do with a [`Snowfall`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`Snowfall`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait SnowfallExt: Sized {
    /// Checks every value; the error names the offending field.
    fn validate(&self) -> Result<(), SnowError>;
}

impl SnowfallExt for Snowfall {
    fn validate(&self) -> Result<(), SnowError> {
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
