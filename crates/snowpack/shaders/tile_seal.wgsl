// #import shared/tiles
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/pass_flags

// Tile seal pass: turns the snow plane of the listed slots into what the
// store keeps, the snow height's bits XOR the bits of its rest height
// (ground + (depth + the texel's snowfall): the terrain plus the rest
// column, as every pass finds the rest height and tile_restore.wgsl undoes it), just before those slots are copied out.
// XOR is its own inverse: sealing a slot twice gives it back (a save seals
// the resident tiles, reads them, and seals them again). The ground is
// evaluated here from the terrain's source, with the very code the restore
// uses, so the round trip is bit-exact on any terrain; a CPU evaluation of
// the terrain matches it only to rounding. CPU twin: src/cpu/tile_seal.rs.

struct SealParams {
    side: u32,
    planes: u32,         // planes per resident slot (shared/tiles.wgsl)
    flags: u32,          // 2: the world has snowfall
    count: u32,          // entries listed
    texel_m: f32,
    depth_m: f32,
    _pad0: u32,
    _pad1: u32,
}

const USE_FALLEN: u32 = 2u;

@group(0) @binding(0) var<uniform> params: SealParams;

@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(0) @binding(1) var<storage, read> entries: array<vec4<i32>>; // (col, row, slot, 0)
@group(0) @binding(2) var<storage, read_write> tiles: array<u32>;

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let area = params.side * params.side;
    if gid.x >= area || gid.y >= params.count {
        return;
    }
    let e = entries[gid.y];
    let g = e.xy * i32(params.side) + vec2<i32>(i32(gid.x % params.side), i32(gid.x / params.side));
    let ground = texel_ground(terrain_params, g, params.texel_m);
    let base = u32(e.z) * params.planes * area + gid.x;
    var lying = 0.0;
    if (pass_flags() & USE_FALLEN) != 0u {
        lying = bitcast<f32>(tiles[base + PLANE_FALLEN * area]);
    }
    tiles[base + PLANE_SNOW * area] ^= bitcast<u32>(ground + (params.depth_m + lying));
}
