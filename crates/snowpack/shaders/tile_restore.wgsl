// #import shared/tiles
// #import shared/stamp
// #import shared/terrain
// #import shared/terrain_kind

// Tile restore pass: makes tiles resident in their slots as the window comes
// near them. A tile the store held (its heights XOR its rest height, so
// untouched snow is 0) is copied from the upload buffer and
// brought up to now: the snowfall, refill and footprint refill of the time it
// was away are applied at once (pass_time, as the update would have over
// those frames; nothing at all when no time counted, so a restore is then
// bit-exact). A tile never seen gets fresh snow with the snowfall so far, as
// the window pass gives new texels. Terrain is evaluated here with the same
// code as the window pass, so it matches it bit for bit.
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
}

const FRESH: u32 = 0xffffffffu;
const USE_FALLEN: u32 = 2u;

@group(0) @binding(0) var<uniform> params: RestoreParams;
@group(0) @binding(1) var<uniform> terrain_params: TerrainParams;
@group(0) @binding(2) var<storage, read> heightmap: array<f32>;
@group(0) @binding(3) var<storage, read> entries: array<RestoreEntry>;
@group(0) @binding(4) var<storage, read> upload: array<u32>;
@group(0) @binding(5) var<storage, read_write> tiles: array<u32>;

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
    let use_fallen = (params.flags & USE_FALLEN) != 0u;
    var t: TexelState;
    if e.upload == FRESH {
        t.fallen = select(0.0, params.fallen_m, use_fallen);
        t.snow = ground + params.depth_m + params.fallen_m;
        t.stamp = STAMP_EMPTY;
    } else {
        // Saved heights are XOR their rest height (0 where untouched): the
        // rest is recomputed here from the same terrain, so they come back exactly.
        t.stamp = upload[e.upload + area + gid.x];
        t.fallen = bitcast<f32>(upload[e.upload + 2u * area + gid.x]);
        t.snow = bitcast<f32>(upload[e.upload + gid.x] ^ bitcast<u32>(ground + params.depth_m + t.fallen));
        if e.elapsed != 0u {
            t = pass_time(ground, params.depth_m, t, e.fall_m, params.max_fallen_m, e.refill_m, e.quanta, params.low_m, params.high_m, use_fallen);
        }
    }
    let base = e.slot * params.planes * area + gid.x;
    tiles[base + PLANE_SNOW * area] = bitcast<u32>(t.snow);
    if has_stamp_plane(params.planes, use_fallen) {
        tiles[base + plane_stamps(params.planes) * area] = t.stamp;
    }
    if (params.flags & USE_FALLEN) != 0u {
        tiles[base + PLANE_FALLEN * area] = bitcast<u32>(t.fallen);
    }
}
