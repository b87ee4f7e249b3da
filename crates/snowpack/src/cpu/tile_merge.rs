//! CPU twin of `tile_merge.wgsl`.

use crate::deform::snow_word::press_quanta;
use crate::replicate::gather::PACKED_PLANES;
use crate::replicate::merge::TileMergeParams;

use super::exchange::WindowBuffers;
use super::stamp::{STAMP_EMPTY, height};
use super::window::{storage_index, texel_ground};

/// Folds the packed `tiles` at `keys` (`[column, row, first frame of
/// history to replay, 0]`, the first `p.count`) into the window's toroidal
/// snow, footprints, snowfall and packed snow over its terrain (`w`),
/// replaying the frames of `history`
/// ([`crate::replicate::merge::FrameRecord::gpu`], the first `p.frames`)
/// from each tile's first frame on. A deficit the merge raises packs the
/// column as a press would; returns the snow quanta displaced beyond the
/// final density.
pub fn merge(p: &TileMergeParams, (keys, history): (&[[i32; 4]], &[[u32; 4]]), tiles: &[u32], w: &mut WindowBuffers<'_>) -> u64 {
    let WindowBuffers { terrain, snow, stamps, fallen, packed } = w;
    let mut displaced = 0u64;
    let side = p.side as usize;
    let area = side * side;
    let r = p.resolution as i32;
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
                let use_fallen = p.flags & TileMergeParams::USE_FALLEN != 0;
                let mut d = tiles[k];
                let mut st = if p.flags & TileMergeParams::HAS_STAMPS != 0 { tiles[k + area] } else { STAMP_EMPTY };
                let mut l = if use_fallen { f32::from_bits(tiles[k + 2 * area]) } else { 0.0 };
                let first = key[2].max(0) as usize;
                for h in history.iter().take(p.frames as usize).skip(first) {
                    if use_fallen {
                        l = l.max((l + f32::from_bits(h[2])).min(p.max_fallen_m));
                    }
                    let rest_f = ground + p.depth_m + l;
                    d -= d.min(h[0]);
                    if st != STAMP_EMPTY {
                        if h[3] != 0 {
                            d = d.max(press_quanta(rest_f, ground, height(st >> 16, p.low_m, p.high_m)));
                        }
                        if h[1] > 0 {
                            let foot = (st & 0xffff) + h[1];
                            st = if foot > 65535 || height(foot, p.low_m, p.high_m) >= rest_f {
                                STAMP_EMPTY
                            } else {
                                (((st >> 16) + h[1]).min(65535) << 16) | foot
                            };
                        }
                    }
                    d = d.min(press_quanta(rest_f, ground, ground));
                }
                let mut lying = 0.0;
                if use_fallen {
                    lying = fallen[s].max(l);
                    fallen[s] = lying;
                }
                let rest = ground + p.depth_m + lying;
                let word = snow[s];
                let at_ground = press_quanta(rest, ground, ground);
                let deficit = (word & 0xffff).max(d).min(at_ground);
                snow[s] = (word & 0xffff_0000) | deficit;
                displaced += super::update::pack_press(packed, s, (word & 0xffff, deficit), at_ground, p.pack_ratio);
                if p.flags & TileMergeParams::HAS_STAMPS != 0 {
                    let incoming = st;
                    if incoming < stamps[s] {
                        stamps[s] = if height(incoming & 0xffff, p.low_m, p.high_m) >= rest { STAMP_EMPTY } else { incoming };
                    }
                }
            }
        }
    }
    displaced
}
