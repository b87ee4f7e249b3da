//! CPU twin of `tile_merge.wgsl`.

use snowpack::low_level::deform::packed_snow;
use snowpack::low_level::deform::snow_word::column_press;
use snowpack::low_level::replicate::gather::PACKED_PLANES;
use snowpack::low_level::replicate::merge::TileMergeParams;

use super::exchange::WindowBuffers;
use super::stamp::{STAMP_EMPTY, height};
use super::window::{storage_index, texel_ground};

/// A tile's texel as it travels: deficit, packed snow, footprint, snowfall lying.
struct TexelInTransit {
    d: u32,
    q: u32,
    st: u32,
    l: f32,
}

/// Folds the packed `tiles` at `keys` (`[column, row, first frame of
/// history to replay, carries packed snow]`, the first `p.count`) into the
/// window's toroidal snow, footprints, snowfall and packed snow over its
/// terrain (`w`), replaying the frames of `history`
/// ([`snowpack::low_level::replicate::merge::FrameRecord::gpu`], the first `p.frames`)
/// from each tile's first frame on. A tile that carries packed snow merges
/// it by the larger; for one that does not, a deficit the merge raises
/// packs the column as a press would. Returns the snow quanta displaced
/// beyond the final density.
pub fn merge(p: &TileMergeParams, (keys, history): (&[[i32; 4]], &[[u32; 4]]), tiles: &[u32], w: &mut WindowBuffers<'_>) -> u64 {
    let WindowBuffers { terrain, snow, stamps, fallen, packed } = w;
    let mut displaced = 0u64;
    let side = p.side as usize;
    let area = side * side;
    let r = p.resolution as i32;
    let use_fallen = p.flags & TileMergeParams::USE_FALLEN != 0;
    for (t, key) in keys.iter().enumerate().take(p.count as usize) {
        for y in 0..side {
            for x in 0..side {
                let g = [key[0] * p.side as i32 + x as i32, key[1] * p.side as i32 + y as i32];
                let local = [g[0] - p.origin[0], g[1] - p.origin[1]];
                if !(0..r).contains(&local[0]) || !(0..r).contains(&local[1]) {
                    continue;
                }
                let s = storage_index(p.origin, p.resolution, local[1] as u32, local[0] as u32);
                let k = t * PACKED_PLANES * area + y * side + x;
                let ground = texel_ground(terrain, g, p.texel_m);
                let copy = TexelInTransit {
                    d: tiles[k] & 0xffff,
                    q: tiles[k] >> 16,
                    st: if p.flags & TileMergeParams::HAS_STAMPS != 0 { tiles[k + area] } else { STAMP_EMPTY },
                    l: if use_fallen { f32::from_bits(tiles[k + 2 * area]) } else { 0.0 },
                };
                let first = key[2].max(0) as usize;
                let c = replay(p, ground, copy, history.iter().take(p.frames as usize).skip(first));
                let mut lying = 0.0;
                if use_fallen {
                    lying = fallen[s].max(c.l);
                    fallen[s] = lying;
                }
                let column = p.depth_m + lying;
                let rest = ground + column;
                let word = snow[s];
                let at_ground = column_press(ground, column, ground);
                let deficit = (word & 0xffff).max(c.d).min(at_ground);
                snow[s] = (word & 0xffff_0000) | deficit;
                if key[3] != 0 {
                    let own = packed_snow::get(packed, s);
                    packed_snow::set(packed, s, own.max(c.q.min(65535)));
                } else {
                    displaced += super::update::pack_press(packed, s, (word & 0xffff, deficit), at_ground, p.pack_ratio);
                }
                if p.flags & TileMergeParams::HAS_STAMPS != 0 && c.st < stamps[s] {
                    stamps[s] = if height(c.st & 0xffff, p.low_m, p.high_m) >= rest { STAMP_EMPTY } else { c.st };
                }
            }
        }
    }
    displaced
}

/// The window's own frames replayed on a tile's texel over `ground`, as
/// the update ran them (the loop in `tile_merge.wgsl`'s `main`).
fn replay<'a>(p: &TileMergeParams, ground: f32, mut c: TexelInTransit, frames: impl Iterator<Item = &'a [u32; 4]>) -> TexelInTransit {
    let use_fallen = p.flags & TileMergeParams::USE_FALLEN != 0;
    for h in frames {
        if use_fallen {
            c.l = c.l.max((c.l + f32::from_bits(h[2])).min(p.max_fallen_m));
        }
        let column_f = p.depth_m + c.l;
        let rest_f = ground + column_f;
        c.d -= c.d.min(h[0]);
        if c.st != STAMP_EMPTY {
            if h[3] != 0 {
                let was = c.d;
                c.d = c.d.max(column_press(ground, column_f, height(c.st >> 16, p.low_m, p.high_m)));
                c.q = replay_pack(c.q, (was, c.d), column_press(ground, column_f, ground), p.pack_ratio);
            }
            if h[1] > 0 {
                let foot = (c.st & 0xffff) + h[1];
                c.st = if foot > 65535 || height(foot, p.low_m, p.high_m) >= rest_f { STAMP_EMPTY } else { (((c.st >> 16) + h[1]).min(65535) << 16) | foot };
            }
        }
        c.d = c.d.min(column_press(ground, column_f, ground));
    }
    c
}

/// `replay_pack` in `tile_merge.wgsl`: a replayed press from `was` to `now`
/// packs the copy's column as the update would, up to the final density.
fn replay_pack(q: u32, (was, now): (u32, u32), at_ground: u32, ratio: f32) -> u32 {
    if now <= was {
        return q;
    }
    (q + (now - was)).min(q.max(packed_snow::cap(at_ground - now.min(at_ground), ratio)))
}
