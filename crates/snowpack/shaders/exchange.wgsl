// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/snow_word
// #import shared/tiles
// #import shared/tile_table
// #import shared/pass_flags
// #import shared/packed_snow
// #import shared/mass_ledger

// Exchange pass: moves texels between the sliding window and the resident
// tiles when the window moves (with a tile store attached). `stash` copies
// the texels about to be overwritten (the old window's, at the storage the
// newly exposed texels take) into their tiles; `load` fills the newly
// exposed texels from theirs. Two dispatches, stash first. Texels whose
// tile has no slot (not in the key table) are left alone: a long move
// stashes and loads in batches of tiles (src/deform/tiles.rs). The window
// keeps its snow as a deficit below the rest height (shared/snow_word.wgsl),
// the tiles as the f32 height: stash and load convert, evaluating the
// terrain from its source. The packed snow goes with the texel both ways
// (its plane in the slot), so a column comes back with its mass. With
// COUNT, what a stash moves out is counted in the ledger as left and what
// a load moves in as entered (shared/mass_ledger.wgsl); a long move's
// batches count nothing and instead sweep the whole window once before
// (left) and once after (entered): SWEEP counts without moving.
// CPU twin: src/cpu/exchange.rs.

struct ExchangeParams {
    origin: vec2<i32>,      // the window's origin after the move
    old_origin: vec2<i32>,  // before it (stash only)
    resolution: u32,
    side: u32,              // tile side (texels)
    keys_per_side: u32,     // side of the toroidal key table (shared/tiles.wgsl)
    flags: u32,             // 1: stash (else load), 2: the world has snowfall (`fallen` in use), 4: the window has `stamps`, 8: count, 16: sweep
    rect_count: u32,
    texel_m: f32,           // where the terrain is evaluated
    planes: u32,            // planes per resident slot (shared/tiles.wgsl)
    depth_m: f32,           // rest depth: the window's snow words are deficits below terrain + depth + fallen
    rects: array<vec4<u32>, 2>, // exposed window-local (row0, col0, rows, cols)
}

const STASH: u32 = 1u;
const USE_FALLEN: u32 = 2u;
const HAS_STAMPS: u32 = 4u;
// Count what moves in the ledger: a stash's texels left, a load's entered.
const COUNT: u32 = 8u;
// Move nothing: only count the window's texels (with COUNT; as left with
// STASH, else as entered), for a long move's batches.
const SWEEP: u32 = 16u;

@group(0) @binding(0) var<uniform> params: ExchangeParams;

@group(0) @binding(1) var<storage, read_write> tiles: array<u32>;
// Tile key -> slot (shared/tiles.wgsl).
@group(0) @binding(2) var<storage, read> tile_table: array<u32>;
// Packed snow, two texels a word (shared/packed_snow.wgsl).
@group(0) @binding(3) var<storage, read_write> packed: array<atomic<u32>>;
@group(1) @binding(2) var<storage, read_write> snow: array<u32>; // shared/snow_word.wgsl
@group(1) @binding(3) var<storage, read_write> stamps: array<u32>;
@group(1) @binding(4) var<storage, read_write> fallen: array<f32>;
// The terrain's source (shared/terrain.wgsl): the rest height the snow words are below.
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;

const WORKGROUP: u32 = 256u;

// Window texel `s`'s snow as the ledger counts it.
fn texel_column(s: u32, use_fallen: bool) -> u32 {
    var lying = 0.0;
    if use_fallen {
        lying = fallen[s];
    }
    return ledger_column(snow[s], params.depth_m, lying, packed_get(atomicLoad(&packed[packed_index(s)]), s));
}

// Stashes the old window's texel at storage `s` into its tile (where it
// has a slot); returns its snow (0 where it stayed).
fn stash(s: u32, use_fallen: bool, has_stamps: bool) -> u32 {
    let n = params.keys_per_side;
    let side = params.side;
    let res = i32(params.resolution);
    // The old window's texel at this storage: congruent to it, inside the old window.
    let sj = i32(s % params.resolution);
    let si = i32(s / params.resolution);
    let o = params.old_origin;
    let g = vec2<i32>(o.x + wrap_index(sj - o.x, res), o.y + wrap_index(si - o.y, res));
    // Only tiles with a slot take texels (a long move stashes in batches).
    if !tile_resident(g, side, n) {
        return 0u;
    }
    let ground = texel_ground(terrain_params, g, params.texel_m);
    var column = params.depth_m;
    if use_fallen {
        column += fallen[s];
    }
    tiles[tile_index(g, side, n, params.planes, PLANE_SNOW)] = bitcast<u32>(snow_column_height(snow[s], ground, column));
    // The slots have a footprint plane exactly when the window has a footprint buffer.
    if has_stamps {
        tiles[tile_index(g, side, n, params.planes, plane_stamps(params.planes))] = stamps[s];
    }
    if use_fallen {
        tiles[tile_index(g, side, n, params.planes, PLANE_FALLEN)] = bitcast<u32>(fallen[s]);
    }
    tiles[tile_index(g, side, n, params.planes, plane_packed(use_fallen))] = packed_get(atomicLoad(&packed[packed_index(s)]), s);
    return texel_column(s, use_fallen);
}

// Loads window-local texel (i, j) at storage `s` from its tile (where it
// has a slot); returns its snow (0 where it stayed).
fn load(i: u32, j: u32, s: u32, use_fallen: bool, has_stamps: bool) -> u32 {
    let n = params.keys_per_side;
    let side = params.side;
    let g = params.origin + vec2<i32>(i32(j), i32(i));
    if !tile_resident(g, side, n) {
        return 0u;
    }
    let ground = texel_ground(terrain_params, g, params.texel_m);
    var column = params.depth_m;
    if has_stamps {
        stamps[s] = tiles[tile_index(g, side, n, params.planes, plane_stamps(params.planes))];
    }
    if use_fallen {
        let lying = bitcast<f32>(tiles[tile_index(g, side, n, params.planes, PLANE_FALLEN)]);
        fallen[s] = lying;
        column += lying;
    }
    let h = bitcast<f32>(tiles[tile_index(g, side, n, params.planes, PLANE_SNOW)]);
    snow[s] = snow_column_press(ground, column, h);
    // Its neighbour in the word may be another invocation's: and, then or.
    let q = min(tiles[tile_index(g, side, n, params.planes, plane_packed(use_fallen))], 0xffffu);
    atomicAnd(&packed[packed_index(s)], ~(0xffffu << packed_shift(s)));
    atomicOr(&packed[packed_index(s)], q << packed_shift(s));
    return texel_column(s, use_fallen);
}

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let texel = rect_texel(gid.x + gid.y * groups.x * WORKGROUP, params.rects, params.rect_count);
    let stashing = (pass_flags() & STASH) != 0u;
    if texel.z != 0u {
        let s = storage_index(params.origin, params.resolution, texel.x, texel.y);
        let use_fallen = (pass_flags() & USE_FALLEN) != 0u;
        var moved = 0u;
        if (pass_flags() & SWEEP) != 0u {
            moved = texel_column(s, use_fallen);
        } else if stashing {
            moved = stash(s, use_fallen, (pass_flags() & HAS_STAMPS) != 0u);
        } else {
            moved = load(texel.x, texel.y, s, use_fallen, (pass_flags() & HAS_STAMPS) != 0u);
        }
        if (pass_flags() & COUNT) != 0u {
            ledger_add(select(1u, 0u, stashing), moved);
        }
    }
    ledger_flush(li, LEDGER_LEFT, LEDGER_ENTERED);
}
