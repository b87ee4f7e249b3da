// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/stamp
// #import shared/snow_word
// #import shared/pass_flags
// #import shared/packed_snow
// #import shared/pack_press

// Tile merge pass (shared snow): folds tiles from other machines into the
// window's toroidal buffers (src/replicate/merge.rs). Tiles are packed as
// the gather pass writes them (deficit with the packed snow in its high
// half, footprint, snowfall bits: three planes of side*side). A tile is first brought to this window's clock:
// either on the CPU (SharedTile::catch_up, all the time passed in one step)
// or here, replaying this window's own frames since the tile's clock
// (`history`, from the tile's first frame on) as the update pass ran them:
// refill, the stored footprint pressing again, footprint refill and its
// rest test, the clamp at the terrain, snowfall; a replayed footprint
// press packs the tile's column as the update would. Replayed, a tile gathered
// on a machine with the same frames is exactly what that machine has now;
// in one step, a footprint's presses in between are missed (a quantum or
// two under footprints). Sky occlusion is not replayed: every texel counts
// as open, as in the catch-up.
// Then per texel inside the window:
//   fallen    = max(own, incoming)
//   deficit   = max(own, incoming), then never below the terrain under the
//               merged rest height (terrain + depth + fallen)
//   packed    = max(own, incoming) for a tile that carries packed snow (its
//               key's w = 1); for one that does not, what the deficit rose
//               by is packed into the column as a press would (shared/pack_press.wgsl)
//   footprint = min(own, incoming); where the incoming one wins, it is gone
//               if its foot is at or above the rest height (the rest test the
//               update applies as footprints refill, which the CPU catch-up
//               cannot: it has no terrain)
// Texels outside the window are left alone. It flags no tiles: a merge is
// not a change to send on. The displayed half of the words is kept; this
// frame's display pass redoes rims and blur. Tiles of one dispatch are
// distinct, so each texel is written by one invocation.
// CPU twin: src/cpu/tile_merge.rs.

struct TileMergeParams {
    origin: vec2<i32>,
    resolution: u32,
    side: u32,
    count: u32,
    flags: u32,        // 1: the window has footprints, 2: it has snowfall
    blocks: u32,       // 8x8 blocks per tile side
    depth_m: f32,      // rest depth (m)
    texel_m: f32,      // where the terrain is evaluated
    low_m: f32,        // footprint quantisation range (m)
    high_m: f32,
    frames: u32,       // frames in `history`
    max_fallen_m: f32, // most snowfall a texel keeps
    pack_ratio: f32,   // rho_max / rho_fresh - 1 (shared/pack_press.wgsl)
}

const MERGE_HAS_STAMPS: u32 = 1u;
const MERGE_USE_FALLEN: u32 = 2u;

@group(0) @binding(0) var<uniform> params: TileMergeParams;

// Per tile: (column, row, first frame of `history` to replay, 1 where the
// tile carries packed snow).
@group(0) @binding(1) var<storage, read> keys: array<vec4<i32>>;
@group(0) @binding(2) var<storage, read> tiles: array<u32>;
@group(1) @binding(2) var<storage, read_write> snow: array<u32>;
// Packed snow and, in its last two words, the displaced count (shared/pack_press.wgsl).
@group(0) @binding(4) var<storage, read_write> packed: array<atomic<u32>>;
@group(1) @binding(3) var<storage, read_write> stamps: array<u32>;
@group(1) @binding(4) var<storage, read_write> fallen: array<f32>;
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;
// This window's last frames, oldest first: (snow refill quanta, footprint
// refill quanta, snowfall (m) bits, 1 where the footprints pressed).
@group(0) @binding(3) var<storage, read> history: array<vec4<u32>>;

// The packed snow `q` of a replayed copy whose deficit a footprint raised
// from `was` to `now` (its column `at_ground` quanta at rest): as the
// update packs it, up to the final density (what passes it was displaced).
fn replay_pack(q: u32, was: u32, now: u32, at_ground: u32) -> u32 {
    if now <= was {
        return q;
    }
    return min(q + (now - was), max(q, packed_cap(at_ground - min(now, at_ground), params.pack_ratio)));
}

@compute @workgroup_size(8, 8)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let t = wg.y;
    let x = (wg.x % params.blocks) * 8u + lid.x;
    let y = (wg.x / params.blocks) * 8u + lid.y;
    if t >= params.count || x >= params.side || y >= params.side {
        return;
    }
    let key = keys[t];
    let g = key.xy * i32(params.side) + vec2<i32>(i32(x), i32(y));
    let local = g - params.origin;
    let r = i32(params.resolution);
    if local.x < 0 || local.y < 0 || local.x >= r || local.y >= r {
        return;
    }
    let s = storage_index(params.origin, params.resolution, u32(local.y), u32(local.x));
    let area = params.side * params.side;
    let k = t * 3u * area + y * params.side + x;
    let ground = texel_ground(terrain_params, g, params.texel_m);
    let use_fallen = (pass_flags() & MERGE_USE_FALLEN) != 0u;
    var d = tiles[k] & 0xffffu;
    var q = tiles[k] >> 16u;
    var st = STAMP_EMPTY;
    if (pass_flags() & MERGE_HAS_STAMPS) != 0u {
        st = tiles[k + area];
    }
    var l = 0.0;
    if use_fallen {
        l = bitcast<f32>(tiles[k + 2u * area]);
    }
    // The update pass's steps, frame by frame (update.wgsl).
    for (var f = u32(max(key.z, 0)); f < params.frames; f++) {
        let h = history[f];
        if use_fallen {
            l = max(l, min(l + bitcast<f32>(h.z), params.max_fallen_m));
        }
        let column_f = params.depth_m + l;
        let rest_f = ground + column_f;
        d -= min(d, h.x);
        if st != STAMP_EMPTY {
            if h.w != 0u {
                let was = d;
                d = max(d, snow_column_press(ground, column_f, stamp_height(st >> 16u, params.low_m, params.high_m)));
                q = replay_pack(q, was, d, snow_column_press(ground, column_f, ground));
            }
            if h.y > 0u {
                let foot = (st & 0xffffu) + h.y;
                if foot > 65535u || stamp_height(foot, params.low_m, params.high_m) >= rest_f {
                    st = STAMP_EMPTY;
                } else {
                    st = (min((st >> 16u) + h.y, 65535u) << 16u) | foot;
                }
            }
        }
        d = min(d, snow_column_press(ground, column_f, ground));
    }
    var lying = 0.0;
    if use_fallen {
        lying = max(fallen[s], l);
        fallen[s] = lying;
    }
    let column = params.depth_m + lying;
    let rest = ground + column;
    let word = snow[s];
    let at_ground = snow_column_press(ground, column, ground);
    let deficit = min(max(word & 0xffffu, d), at_ground);
    snow[s] = (word & 0xffff0000u) | deficit;
    if key.w != 0 {
        let own = packed_get(atomicLoad(&packed[packed_index(s)]), s);
        packed_set(s, own, max(own, min(q, 65535u)));
    } else {
        pack_press(s, word & 0xffffu, deficit, at_ground, params.pack_ratio);
    }
    if (pass_flags() & MERGE_HAS_STAMPS) != 0u {
        let incoming = st;
        if incoming < stamps[s] {
            if stamp_height(incoming & 0xffffu, params.low_m, params.high_m) >= rest {
                stamps[s] = STAMP_EMPTY;
            } else {
                stamps[s] = incoming;
            }
        }
    }
}
