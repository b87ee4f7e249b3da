//! The layout of a resident tile slot (`shared/tiles.wgsl`): its planes and
//! the key table's empty mark, shared by the streaming and the tile passes
//! (restore, weather, seal, exchange), which sit below it.

/// The key table's "no slot" (`NO_SLOT` in `shared/tiles.wgsl`).
pub const NO_SLOT: u32 = u32::MAX;

/// Most planes per resident tile: snow, fallen, packed snow, stamps
/// (`shared/tiles.wgsl`); a slot has the snowfall plane only in a world
/// with snowfall and the footprint plane only while the window has a
/// footprint buffer ([`planes`]). No terrain plane: the passes evaluate the
/// ground under a slot texel from the terrain's source.
pub const PLANES: usize = 4;
/// Plane of the snow height (f32 bits; height XOR rest height while sealed
/// for a copy-out, `tile_seal.wgsl`).
pub const PLANE_SNOW: usize = 0;
/// Plane of the snowfall so far (f32 bits); only in a world with snowfall.
pub const PLANE_FALLEN: usize = 1;

/// Planes per resident tile: snow, the snowfall so far where the world has
/// snowfall, the packed snow (snow quanta, one a u32), the packed
/// footprints where the window has a footprint buffer (points or combined
/// used).
#[must_use]
pub const fn planes(use_fallen: bool, has_stamps: bool) -> usize {
    2 + use_fallen as usize + has_stamps as usize
}

/// Plane of the packed snow: after the snowfall's where the world has
/// snowfall.
#[must_use]
pub const fn plane_packed(use_fallen: bool) -> usize {
    1 + use_fallen as usize
}

/// A tile pass's `flags` with its footprint-plane bit set where a slot of
/// `planes` planes has one (a plane left over after the snow, the packed
/// snow and, with `use_fallen` set in `flags`, the snowfall): the shader's choice as a
/// flag, so that no branch tests uniforms alone (docs/deformation.md).
/// `(use_fallen, stamp_plane)` are the pass's bits.
#[must_use]
pub(crate) const fn with_stamp_plane_flag(flags: u32, planes: u32, (use_fallen, stamp_plane): (u32, u32)) -> u32 {
    let has_plane = planes > 2 + (flags & use_fallen != 0) as u32;
    (flags & !stamp_plane) | if has_plane { stamp_plane } else { 0 }
}

/// Plane of the packed footprints in a slot of `planes` planes: the last
/// (only where the window has a footprint buffer).
#[must_use]
pub const fn plane_stamps(planes: usize) -> usize {
    planes - 1
}
