// #import shared/tiles
// #import shared/stamp
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/snow_word
// #import shared/pass_flags

// Tile restore pass: makes tiles resident in their slots as the window comes
// near them. A tile the store held (its heights XOR its rest height, so
// untouched snow is 0) is copied from the upload buffer and
// brought up to now: the snowfall, refill and footprint refill of the time it
// was away are applied at once (pass_time, as the update would have over
// those frames; nothing at all when no time counted, so a restore is then
// bit-exact). A tile never seen gets fresh snow with the snowfall so far, as
// the window pass gives new texels. Terrain is evaluated here with the same
// code as the window pass, so it matches it bit for bit.
// An entry may also carry a second saved tile to merge (`merge`): what the
// window made in a tile's place while the disk was late with it. Both are
// brought up to now, then folded texel by texel with shared snow's merge
// (TexelCopy::merge in src/replicate/tile.rs): the deeper deficit, the lower
// footprint, the deeper snowfall, the more packed snow; a texel one copy
// dominates keeps its bits. Saved planes in `upload`: snow, footprints,
// snowfall, packed snow (zeros where the tile had none). A `merge` of
// IN_SLOT folds the slot's own texels in instead, as they are now: a live
// merge, when the stored version of a tile the window stood in for with
// fresh snow arrives while the tile is resident (src/tiles/streaming/live_merge.rs).
// CPU twin: src/cpu/tile_restore.rs.

struct RestoreParams {
    side: u32,
    _pad0: u32,
    count: u32,
    flags: u32,          // 2: the world has snowfall
    texel_m: f32,
    depth_m: f32,
    fallen_m: f32,       // snowfall so far on open ground, for fresh tiles
    max_fallen_m: f32,
    low_m: f32,          // footprint quantisation range
    high_m: f32,
    planes: u32,         // planes per resident slot (shared/tiles.wgsl)
    _pad1: u32,
}

struct RestoreEntry {
    tile: vec2<i32>,
    slot: u32,
    upload: u32,         // first u32 of the saved planes in `upload`, or FRESH
    refill_m: f32,       // time away: refill (m)
    fall_m: f32,         // time away: snowfall on open ground (m)
    quanta: u32,         // time away: footprint refill (stamp quanta)
    elapsed: u32,        // 1 when any time counted
    merge: u32,          // first u32 of a second tile's planes to merge in, FRESH (none) or IN_SLOT (the slot as it is)
    merge_refill_m: f32, // its time away, as above
    merge_fall_m: f32,
    merge_quanta: u32,
}

const FRESH: u32 = 0xffffffffu;
const IN_SLOT: u32 = 0xfffffffeu;
const USE_FALLEN: u32 = 2u;
// The slots have a footprint plane (a plane left over in the params' planes,
// set by `TileRestorePass::record`: a flag, so no branch tests uniforms alone).
const STAMP_PLANE: u32 = 4u;

@group(0) @binding(0) var<uniform> params: RestoreParams;

@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(0) @binding(1) var<storage, read> entries: array<RestoreEntry>;
@group(0) @binding(2) var<storage, read> upload: array<u32>;
@group(0) @binding(3) var<storage, read_write> tiles: array<u32>;

// Texel `i` of the saved planes at `at` in `upload`, brought up to now.
fn saved_texel(at: u32, area: u32, i: u32, ground: f32, refill_m: f32, fall_m: f32, quanta: u32) -> TexelState {
    var t: TexelState;
    // Saved heights are XOR their rest height (0 where untouched): the
    // rest is recomputed here from the same terrain, so they come back exactly.
    t.stamp = upload[at + area + i];
    t.fallen = bitcast<f32>(upload[at + 2u * area + i]);
    t.packed = upload[at + 3u * area + i];
    t.snow = bitcast<f32>(upload[at + i] ^ bitcast<u32>(ground + (params.depth_m + t.fallen)));
    if refill_m > 0.0 || fall_m > 0.0 || quanta > 0u {
        t = pass_time(ground, params.depth_m, t, fall_m, params.max_fallen_m, refill_m, quanta, params.low_m, params.high_m, (pass_flags() & USE_FALLEN) != 0u);
    }
    return t;
}

// Texel `i` of the slot at `base` (its first word), as it is now.
fn slot_texel(base: u32, area: u32, use_fallen: bool) -> TexelState {
    var t: TexelState;
    t.snow = bitcast<f32>(tiles[base + PLANE_SNOW * area]);
    t.packed = tiles[base + plane_packed(use_fallen) * area];
    t.stamp = STAMP_EMPTY;
    if (pass_flags() & STAMP_PLANE) != 0u {
        t.stamp = tiles[base + plane_stamps(params.planes) * area];
    }
    t.fallen = 0.0;
    if use_fallen {
        t.fallen = bitcast<f32>(tiles[base + PLANE_FALLEN * area]);
    }
    return t;
}

// Two copies of a texel at one clock, merged by the deficit below each one's
// rest height (TexelCopy::merge); a copy that wins on every plane keeps its bits.
fn merge_texels(ground: f32, a: TexelState, b: TexelState) -> TexelState {
    let da = snow_column_press(ground, params.depth_m + a.fallen, a.snow);
    let db = snow_column_press(ground, params.depth_m + b.fallen, b.snow);
    var out: TexelState;
    out.fallen = a.fallen;
    if bitcast<u32>(b.fallen) > bitcast<u32>(a.fallen) && b.fallen >= 0.0 {
        out.fallen = b.fallen;
    }
    out.stamp = min(a.stamp, b.stamp);
    out.packed = max(a.packed, b.packed);
    let d = max(da, db);
    if d == da && bitcast<u32>(out.fallen) == bitcast<u32>(a.fallen) {
        out.snow = a.snow;
    } else if d == db && bitcast<u32>(out.fallen) == bitcast<u32>(b.fallen) {
        out.snow = b.snow;
    } else {
        out.snow = snow_column_height(d, ground, params.depth_m + out.fallen);
    }
    return out;
}

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let area = params.side * params.side;
    if gid.x >= area || gid.y >= params.count {
        return;
    }
    let e = entries[gid.y];
    let local = vec2<i32>(i32(gid.x % params.side), i32(gid.x / params.side));
    let g = e.tile * i32(params.side) + local;
    let ground = texel_ground(terrain_params, g, params.texel_m);
    let use_fallen = (pass_flags() & USE_FALLEN) != 0u;
    var t: TexelState;
    if e.upload == FRESH {
        t.fallen = select(0.0, params.fallen_m, use_fallen);
        t.snow = ground + (params.depth_m + params.fallen_m);
        t.stamp = STAMP_EMPTY;
        t.packed = 0u;
    } else {
        t = saved_texel(e.upload, area, gid.x, ground, e.refill_m, e.fall_m, e.quanta);
    }
    let base = e.slot * params.planes * area + gid.x;
    if e.merge == IN_SLOT {
        // Read before this invocation writes the texel; no other touches it.
        t = merge_texels(ground, t, slot_texel(base, area, use_fallen));
    } else if e.merge != FRESH {
        t = merge_texels(ground, t, saved_texel(e.merge, area, gid.x, ground, e.merge_refill_m, e.merge_fall_m, e.merge_quanta));
    }
    tiles[base + PLANE_SNOW * area] = bitcast<u32>(t.snow);
    tiles[base + plane_packed(use_fallen) * area] = t.packed;
    if (pass_flags() & STAMP_PLANE) != 0u {
        tiles[base + plane_stamps(params.planes) * area] = t.stamp;
    }
    if (pass_flags() & USE_FALLEN) != 0u {
        tiles[base + PLANE_FALLEN * area] = bitcast<u32>(t.fallen);
    }
}
