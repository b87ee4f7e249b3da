// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/snow_word

// Surface unpack pass (the renderer's): the displayed height of every texel
// (terrain + the upper half of its `snow` word, shared/snow_word.wgsl), and
// its normal by central differences from a 18x18 workgroup-memory tile
// (16x16 plus a one-texel apron, clamped at the window's edges), packed
// window-local for the passes that march or draw the height field:
//   surface[t] = (bitcast<u32>(height), pack2x16snorm(normal.x, normal.z))
// with normal.y = sqrt(1 - x^2 - z^2). The deformation does not need it:
// games sample the snow words directly (snow_sampling.wgsl).
// CPU twin: src/cpu/surface_unpack.rs.

struct UnpackParams {
    origin: vec2<i32>,
    resolution: u32,
    texel_m: f32,
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution (storage_index_wrapped)
}

@group(0) @binding(0) var<uniform> params: UnpackParams;
@group(0) @binding(1) var<storage, read> snow: array<u32>;
@group(0) @binding(2) var<storage, read> heightmap: array<f32>;
@group(0) @binding(3) var<uniform> terrain_params: TerrainParams;
@group(0) @binding(4) var<storage, read_write> surface: array<vec2<u32>>;

const TILE: u32 = 16u;
const SPAN: u32 = 18u;

var<workgroup> tile: array<f32, 324>;

fn load(i: i32, j: i32) -> f32 {
    let r = i32(params.resolution) - 1;
    let ci = u32(clamp(i, 0, r));
    let cj = u32(clamp(j, 0, r));
    let ground = texel_ground(terrain_params, params.origin + vec2<i32>(i32(cj), i32(ci)), params.texel_m);
    return snow_word_shown(snow[storage_index_wrapped(params.storage_origin, params.resolution, ci, cj)], ground);
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>, @builtin(local_invocation_index) flat: u32) {
    let i0 = i32(wg.y * TILE) - 1;
    let j0 = i32(wg.x * TILE) - 1;
    for (var k = flat; k < SPAN * SPAN; k += TILE * TILE) {
        tile[k] = load(i0 + i32(k / SPAN), j0 + i32(k % SPAN));
    }
    workgroupBarrier();

    let i = wg.y * TILE + lid.y;
    let j = wg.x * TILE + lid.x;
    if i >= params.resolution || j >= params.resolution {
        return;
    }
    let t = (lid.y + 1u) * SPAN + lid.x + 1u;
    let dx = tile[t + 1u] - tile[t - 1u];
    let dz = tile[t + SPAN] - tile[t - SPAN];
    let n = normalize(vec3(-dx, 2.0 * params.texel_m, -dz));
    surface[i * params.resolution + j] = vec2<u32>(bitcast<u32>(tile[t]), pack2x16snorm(vec2(n.x, n.z)));
}
