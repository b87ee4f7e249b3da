//! CPU twin of `tile_restore.wgsl`.

use snowpack::TerrainSource;
use snowpack::low_level::deform::snow_word::{column_height, column_press};
use snowpack::low_level::replicate::tile::TexelCopy;
use snowpack::low_level::tiles::restore::{RestoreEntry, RestoreParams};

use super::stamp::STAMP_EMPTY;
use super::tile_weather::{SlotLayout, SnowConstants, TexelState, TimePassed, pass_time, read_texel, write_packed, write_texel};
use snowpack::low_level::tiles::streaming::plane_packed;

/// Writes each entry's tile into its slot: the saved planes in `upload`
/// brought up to now, or fresh snow over `terrain`; with a second tile to
/// merge, both up to now and folded by [`merge_texels`]; a merge of
/// [`RestoreEntry::IN_SLOT`] folds in the slot's texels as they are.
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
            let saved = |at: u32, time: TimePassed| {
                let u = at as usize;
                let fallen = f32::from_bits(upload[u + 2 * area + k]);
                let rest = ground + (p.depth_m + fallen);
                let saved =
                    TexelState { snow: f32::from_bits(upload[u + k] ^ rest.to_bits()), stamp: upload[u + area + k], fallen, packed: upload[u + 3 * area + k] };
                if time.refill_m > 0.0 || time.fall_m > 0.0 || time.quanta > 0 { pass_time(ground, &c, saved, &time) } else { saved }
            };
            let mut t = if e.upload == RestoreEntry::FRESH {
                TexelState { snow: ground + (p.depth_m + p.fallen_m), stamp: STAMP_EMPTY, fallen: if use_fallen { p.fallen_m } else { 0.0 }, packed: 0 }
            } else {
                saved(e.upload, TimePassed { fall_m: e.fall_m, refill_m: e.refill_m, quanta: e.quanta })
            };
            let planes = p.planes as usize;
            let layout = SlotLayout { area, planes, use_fallen };
            if e.merge == RestoreEntry::IN_SLOT {
                let here = TexelState { packed: tiles[(slot * planes + plane_packed(use_fallen)) * area + k], ..read_texel(tiles, slot, layout, k) };
                t = merge_texels(ground, p.depth_m, t, here);
            } else if e.merge != RestoreEntry::FRESH {
                let other = saved(e.merge, TimePassed { fall_m: e.merge_fall_m, refill_m: e.merge_refill_m, quanta: e.merge_quanta });
                t = merge_texels(ground, p.depth_m, t, other);
            }
            write_texel(tiles, slot, layout, k, t);
            write_packed(tiles, slot, layout, k, t.packed);
        }
    }
}

/// Two copies of a texel brought to one clock, merged by shared snow's rule
/// ([`TexelCopy::merge`]: the deeper deficit below each one's rest height, the
/// lower footprint, the deeper snowfall, the more packed snow); a copy that wins on every plane
/// keeps its bits. `merge_texels` in `tile_restore.wgsl`.
#[must_use]
pub fn merge_texels(ground: f32, depth_m: f32, a: TexelState, b: TexelState) -> TexelState {
    let copy = |t: TexelState| TexelCopy { deficit: column_press(ground, depth_m + t.fallen, t.snow), stamp: t.stamp, fallen_m: t.fallen, packed: t.packed };
    let (ca, cb) = (copy(a), copy(b));
    let m = ca.merge(cb);
    let snow = if m.deficit == ca.deficit && m.fallen_m.to_bits() == a.fallen.to_bits() {
        a.snow
    } else if m.deficit == cb.deficit && m.fallen_m.to_bits() == b.fallen.to_bits() {
        b.snow
    } else {
        column_height(m.deficit, ground, depth_m + m.fallen_m)
    };
    TexelState { snow, stamp: m.stamp, fallen: m.fallen_m, packed: m.packed }
}
