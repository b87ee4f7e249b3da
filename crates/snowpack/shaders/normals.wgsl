// Normals pass: central differences of the displayed height from a 18x18
// workgroup-memory tile (16x16 plus a one-texel apron, clamped at the window's
// edges), packed with the height for the renderer:
//   surface[t] = (bitcast<u32>(height), pack2x16snorm(normal.x, normal.z))
// The rim and blur passes leave the height in word 2t; this pass reads those
// words and writes only the normal words 2t + 1.
// with normal.y = sqrt(1 - x^2 - z^2). CPU twin: src/cpu/normals.rs.

struct NormalParams {
    resolution: u32,
    texel_m: f32,
    _pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> params: NormalParams;
@group(0) @binding(1) var<storage, read_write> surface: array<u32>;

const TILE: u32 = 16u;
const SPAN: u32 = 18u;

var<workgroup> tile: array<f32, 324>;

fn load(i: i32, j: i32) -> f32 {
    let r = i32(params.resolution) - 1;
    return bitcast<f32>(surface[2u * (u32(clamp(i, 0, r)) * params.resolution + u32(clamp(j, 0, r)))]);
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
    surface[2u * (i * params.resolution + j) + 1u] = pack2x16snorm(vec2(n.x, n.z));
}
