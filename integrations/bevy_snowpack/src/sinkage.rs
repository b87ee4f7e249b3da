//! The arithmetic of snow the game can feel that the library does not
//! have: the terrain coefficient of walking in snow ([`crate::resistance`]
//! has the sources). Sinkage, hardness and a wheel's compaction resistance
//! are the library's (`snowpack::mechanics`, `docs/mechanics.md`).

/// Standard gravity (m/s²).
pub(crate) use snowpack::mechanics::GRAVITY;

/// Richmond, Potter and Santee's terrain coefficient of snow at a sinkage
/// of `sinkage_m`, ramped from firm ground's 1 over the first 2 cm of snow
/// depth (their fit starts at packed snow's 1.26).
#[must_use]
pub(crate) fn terrain_coefficient(sinkage_m: f32, depth_m: f32) -> f32 {
    let z = 100.0 * sinkage_m.max(0.0);
    let snow = 0.0005 * z * z * z + 0.0001 * z * z + 0.1072 * z + 1.2604;
    1.0 + (snow - 1.0) * (depth_m / 0.02).clamp(0.0, 1.0)
}
