//! CPU twin of `tile_restore.wgsl`.

use crate::TerrainSource;
use crate::tiles::restore::{RestoreEntry, RestoreParams};

use super::stamp::STAMP_EMPTY;
use super::tile_weather::{SlotLayout, SnowConstants, TexelState, TimePassed, pass_time, write_texel};

/// Writes each entry's tile into its slot: the saved planes in `upload`
/// brought up to now, or fresh snow over `terrain`.
pub fn restore(p: &RestoreParams, entries: &[RestoreEntry], upload: &[u32], terrain: &TerrainSource, tiles: &mut [u32]) {
    let side = p.side as i32;
    let area = (p.side * p.side) as usize;
    let use_fallen = p.flags & RestoreParams::USE_FALLEN != 0;
    let c = SnowConstants { depth_m: p.depth_m, max_fallen_m: p.max_fallen_m, low_m: p.low_m, high_m: p.high_m, use_fallen };
    for e in entries.iter().take(p.count as usize) {
        let slot = e.slot as usize;
        for k in 0..area {
            let g = [e.tile[0] * side + (k as i32 % side), e.tile[1] * side + (k as i32 / side)];
            let ground = super::window::texel_ground(terrain, g, p.texel_m);
            let t = if e.upload == RestoreEntry::FRESH {
                TexelState { snow: ground + p.depth_m + p.fallen_m, stamp: STAMP_EMPTY, fallen: if use_fallen { p.fallen_m } else { 0.0 } }
            } else {
                let u = e.upload as usize;
                let fallen = f32::from_bits(upload[u + 2 * area + k]);
                let rest = ground + p.depth_m + fallen;
                let saved = TexelState { snow: f32::from_bits(upload[u + k] ^ rest.to_bits()), stamp: upload[u + area + k], fallen };
                if e.elapsed != 0 { pass_time(ground, &c, saved, &TimePassed { fall_m: e.fall_m, refill_m: e.refill_m, quanta: e.quanta }) } else { saved }
            };
            let planes = p.planes as usize;
            write_texel(tiles, slot, SlotLayout { area, planes, use_fallen }, k, t);
        }
    }
}
