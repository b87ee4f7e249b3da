// #import shared/tiles
// #import shared/stamp
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/pass_flags

// Tile weather pass: time passes on the resident tiles outside the window.
// Each frame with refill or snowfall, every texel of a resident tile that the
// window does not cover gets what the update gives open, untouched ground
// (pass_time), so a tile is always current when the window comes back over
// it or when it goes to the store. Only the slots listed in `slots` run:
// the CPU leaves out those wholly inside the window (most of them).
// CPU twin: src/cpu/tile_weather.rs.

struct WeatherParams {
    origin: vec2<i32>,   // the window's origin; its texels are the update's
    resolution: u32,
    side: u32,
    texel_m: f32,        // where a slot texel's ground is evaluated
    flags: u32,          // 2: the world has snowfall
    depth_m: f32,
    refill_m: f32,       // this frame's refill (m)
    fall_m: f32,         // this frame's snowfall on open ground (m)
    max_fallen_m: f32,
    quanta: u32,         // this frame's footprint refill (stamp quanta)
    low_m: f32,
    high_m: f32,
    count: u32,          // slots listed in `slots`
    planes: u32,         // planes per resident slot (shared/tiles.wgsl)
    _pad1: u32,
}

const USE_FALLEN: u32 = 2u;
// The slots have a footprint plane (a plane left over in the params' planes,
// set by `TileWeatherPass::record`: a flag, so no branch tests uniforms alone).
const STAMP_PLANE: u32 = 4u;

@group(0) @binding(0) var<uniform> params: WeatherParams;

@group(0) @binding(1) var<storage, read> owners: array<vec4<i32>>; // (col, row, resident, 0) per slot
@group(0) @binding(2) var<storage, read_write> tiles: array<u32>;
@group(0) @binding(3) var<storage, read> slots: array<u32>;
// The terrain's source (shared/terrain.wgsl): the ground under a slot texel.
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let area = params.side * params.side;
    if gid.x >= area || gid.y >= params.count {
        return;
    }
    let slot = slots[gid.y];
    let owner = owners[slot];
    if owner.z == 0 {
        return;
    }
    let g = owner.xy * i32(params.side) + vec2<i32>(i32(gid.x % params.side), i32(gid.x / params.side));
    let d = g - params.origin;
    let res = i32(params.resolution);
    if d.x >= 0 && d.y >= 0 && d.x < res && d.y < res {
        return;
    }
    let base = slot * params.planes * area + gid.x;
    let use_fallen = (pass_flags() & USE_FALLEN) != 0u;
    var t: TexelState;
    t.snow = bitcast<f32>(tiles[base + PLANE_SNOW * area]);
    let stamp_plane = (pass_flags() & STAMP_PLANE) != 0u;
    t.stamp = STAMP_EMPTY;
    if stamp_plane {
        t.stamp = tiles[base + plane_stamps(params.planes) * area];
    }
    t.fallen = 0.0;
    if use_fallen {
        t.fallen = bitcast<f32>(tiles[base + PLANE_FALLEN * area]);
    }
    let ground = texel_ground(terrain_params, g, params.texel_m);
    t = pass_time(ground, params.depth_m, t, params.fall_m, params.max_fallen_m, params.refill_m, params.quanta, params.low_m, params.high_m, use_fallen);
    tiles[base + PLANE_SNOW * area] = bitcast<u32>(t.snow);
    if stamp_plane {
        tiles[base + plane_stamps(params.planes) * area] = t.stamp;
    }
    if use_fallen {
        tiles[base + PLANE_FALLEN * area] = bitcast<u32>(t.fallen);
    }
}
