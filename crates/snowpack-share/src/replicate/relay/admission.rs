//! What a relay admits: a world it can use, and a peer's tile that fits
//! the world and is believable (the checks that need no peer's history;
//! where a peer may write is `PeerState::may_write`).

use super::stats::RelayRejections;
use crate::SNOW_QUANTUM_M;
use crate::persist::TileKey;
use crate::replicate::message::{MAX_TILE_SIDE, MIN_TILE_SIDE};
use crate::replicate::tile::{NO_STAMP, ShareClock, SharedTile};
use crate::replicate::world::WorldIdentity;

/// What makes a world unusable by a relay (a tile side off the wire's
/// range, a texel size or depth that is not a positive number).
pub(super) fn world_problems(w: &WorldIdentity) -> Vec<String> {
    let mut out = Vec::new();
    if !(MIN_TILE_SIDE..=MAX_TILE_SIDE).contains(&w.settings.tile_side) {
        out.push(format!("tile side: {} here, {MIN_TILE_SIDE}..={MAX_TILE_SIDE} there", w.settings.tile_side));
    }
    if !(w.settings.texel_m.is_finite() && w.settings.texel_m > 0.0) {
        out.push(format!("texel size (m): {} here, a positive number there", w.settings.texel_m));
    }
    if !(w.settings.depth_m.is_finite() && w.settings.depth_m >= 0.0) {
        out.push(format!("snow depth (m): {} here, a number at least 0 there", w.settings.depth_m));
    }
    if !(w.settings.max_fallen_m.is_finite() && w.settings.max_fallen_m >= 0.0) {
        out.push(format!("most snowfall kept (m): {} here, a number at least 0 there", w.settings.max_fallen_m));
    }
    out
}

/// Whether tile `t` fits the world: its side and planes are the world's,
/// it lies inside the world ([`in_bounds`]) and its footprints are ones a
/// deformer makes. A refusal is counted in `rejected`.
pub(super) fn fits_the_world(t: &SharedTile, world: &WorldIdentity, bounds_m: Option<[f64; 4]>, rejected: &mut RelayRejections) -> bool {
    if t.side != world.settings.tile_side || !t.is_consistent() || (!world.settings.has_snowfall && !t.fallen.is_empty()) {
        rejected.bad_tile += 1;
        return false;
    }
    if !in_bounds(t.key, world, bounds_m) {
        rejected.out_of_bounds += 1;
        return false;
    }
    // A packed footprint is (top << 16) | foot, its foot never above its top.
    if t.stamps.iter().any(|&s| s != NO_STAMP && (s & 0xffff) > (s >> 16)) {
        rejected.bad_footprint += 1;
        return false;
    }
    true
}

/// Whether tile `t` is believable: its clock not ahead of `limit`, no more
/// snowfall than has fallen by `limit` or `so_far`, no deficit deeper than
/// the snow. A refusal is counted in `rejected`.
pub(super) fn is_believable(t: &SharedTile, world: &WorldIdentity, limit: &ShareClock, so_far: &ShareClock, rejected: &mut RelayRejections) -> bool {
    if !t.clock.time_s.is_finite() || t.clock.time_s > limit.time_s || !limit.covers(&t.clock) {
        rejected.clock_ahead += 1;
        return false;
    }
    let most_fallen = limit.fallen_m.max(so_far.fallen_m);
    if t.fallen.iter().any(|f| !f.is_finite() || *f < 0.0 || *f > most_fallen) {
        rejected.too_much_snowfall += 1;
        return false;
    }
    let too_deep = t.deficit.iter().enumerate().any(|(k, &d)| {
        let lying = t.fallen.get(k).copied().unwrap_or(0.0);
        f32::from(d) * SNOW_QUANTUM_M > world.settings.depth_m + lying + SNOW_QUANTUM_M
    });
    if too_deep {
        rejected.too_deep += 1;
        return false;
    }
    true
}

/// Whether tile `key` lies where a window can be (its texels fit in i32,
/// as every window's do) and, with `bounds_m`, overlaps those bounds.
fn in_bounds(key: TileKey, world: &WorldIdentity, bounds_m: Option<[f64; 4]>) -> bool {
    let side = i64::from(world.settings.tile_side);
    let first = key.first_texel(world.settings.tile_side);
    let fits = |v: i64| v >= i64::from(i32::MIN) && v.saturating_add(side) <= i64::from(i32::MAX);
    if !(fits(first[0]) && fits(first[1])) {
        return false;
    }
    let Some([x0, z0, x1, z1]) = bounds_m else {
        return true;
    };
    let texel = f64::from(world.settings.texel_m);
    let (a, b) = ([first[0] as f64 * texel, first[1] as f64 * texel], [(first[0] + side) as f64 * texel, (first[1] + side) as f64 * texel]);
    a[0] < x1 && b[0] > x0 && a[1] < z1 && b[1] > z0
}
