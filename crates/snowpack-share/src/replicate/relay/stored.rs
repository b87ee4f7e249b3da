//! How the relay keeps its world and tiles in a [`TileStore`](crate::persist::TileStore): the state
//! names, a tile as the store holds it and back, and the store's "full".

use std::sync::Arc;

use crate::error::ShareError;
use crate::persist::{SnowClock, StoreError, TileData};
use crate::replicate::press::ground::HeightGrid;
use crate::replicate::tile::{NO_STAMP, ShareClock, SharedTile};
use crate::replicate::world::WorldIdentity;

/// The state name the relay's world is saved under in its store.
pub const WORLD_STATE: &str = "world";

/// The state name the world's heightmap is saved under, when its terrain
/// is one and the world was pinned holding it
/// ([`HeightGrid::to_bytes`](crate::replicate::press::ground::HeightGrid::to_bytes)):
/// a relay opened on the store then presses over it.
pub const GROUND_STATE: &str = "ground";

/// The state name the world's epoch (f64 Unix seconds, little-endian) is saved under ([`SnowRelay::world_epoch`](super::SnowRelay::world_epoch)).
pub const EPOCH_STATE: &str = "epoch";

/// Marks, in a stored tile's snow plane, a tile without a footprint plane
/// (bit 16 of every texel; the deficit takes bits 0..16). The store's
/// format always has a footprint plane, so this keeps "none" apart from
/// "all empty", which digest differently.
const NO_STAMP_PLANE: u32 = 1 << 16;

/// The heightmap a store keeps beside `world` ([`GROUND_STATE`]): it must
/// decode and be the terrain the world names.
pub(super) fn saved_ground(bytes: &[u8], world: &WorldIdentity) -> Result<Arc<HeightGrid>, ShareError> {
    let grid = HeightGrid::from_bytes(bytes).map_err(|e| ShareError::StoreWorld(format!("the saved heightmap does not decode: {e}")))?;
    if grid.terrain_identity() != world.settings.terrain {
        return Err(ShareError::StoreWorld(format!(
            "the saved heightmap is \"{}\", the saved world's terrain \"{}\"",
            grid.terrain_identity(),
            world.settings.terrain
        )));
    }
    Ok(Arc::new(grid))
}

/// Whether a store refused a write because its disk budget is spent.
pub(super) fn is_full(e: &StoreError) -> bool {
    matches!(e, StoreError::Io { source, .. } if source.kind() == std::io::ErrorKind::StorageFull)
}

/// A relay's tile as the tile store keeps it. The store's planes are
/// reused for deficits, not heights: `snow_xor_rest` holds the deficit
/// (bits 0..16), with bit 16 set in every texel when the tile has no
/// footprint plane (the store's format always has one; it is then all
/// [`NO_STAMP`]); the clock's `refill_m` holds the refill quanta (an
/// integer, exact below 2⁵³) and `fallen_m` the f32 widened. Reading back
/// ([`tile_from_data`]) gives the same tile bit for bit.
#[must_use]
pub fn tile_to_data(t: &SharedTile) -> TileData {
    let flag = if t.stamps.is_empty() { NO_STAMP_PLANE } else { 0 };
    TileData {
        key: t.key,
        side: t.side,
        clock: SnowClock {
            time_s: t.clock.time_s,
            refill_m: t.clock.refill_quanta as f64,
            fallen_m: f64::from(t.clock.fallen_m),
            stamp_quanta: t.clock.stamp_quanta,
        },
        snow_xor_rest: t.deficit.iter().map(|&d| u32::from(d) | flag).collect(),
        stamps: if t.stamps.is_empty() { vec![NO_STAMP; t.texels()] } else { t.stamps.clone() },
        fallen: t.fallen.clone(),
        packed: t.packed.clone(),
    }
}

/// Inverse of [`tile_to_data`]. Data that no relay wrote is
/// [`StoreError::Corrupt`] (naming no file) saying what does not fit.
pub fn tile_from_data(d: TileData) -> Result<SharedTile, StoreError> {
    let corrupt = |why: String| StoreError::Corrupt { path: std::path::PathBuf::new(), why };
    let q = d.clock.refill_m;
    if !((0.0..9_007_199_254_740_992.0).contains(&q) && q.fract() == 0.0) {
        return Err(corrupt(format!("refill {q} is not a whole number of quanta")));
    }
    let fallen_m = d.clock.fallen_m as f32;
    if f64::from(fallen_m).to_bits() != d.clock.fallen_m.to_bits() {
        return Err(corrupt(format!("snowfall so far {} is not an f32", d.clock.fallen_m)));
    }
    let flag = d.snow_xor_rest.first().map_or(0, |v| v & !0xffff);
    if flag != 0 && flag != NO_STAMP_PLANE {
        return Err(corrupt(format!("snow plane flags {flag:#x}")));
    }
    let mut deficit = Vec::with_capacity(d.snow_xor_rest.len());
    for &v in &d.snow_xor_rest {
        if v & !0xffff != flag {
            return Err(corrupt("snow plane flags differ between texels".to_owned()));
        }
        deficit.push((v & 0xffff) as u16);
    }
    let stamps = if flag == NO_STAMP_PLANE { Vec::new() } else { d.stamps };
    let tile = SharedTile {
        key: d.key,
        side: d.side,
        clock: ShareClock { time_s: d.clock.time_s, refill_quanta: q as u64, stamp_quanta: d.clock.stamp_quanta, fallen_m },
        deficit,
        stamps,
        fallen: d.fallen,
        packed: d.packed,
    };
    if tile.is_consistent() { Ok(tile) } else { Err(corrupt("planes of the wrong size".to_owned())) }
}
