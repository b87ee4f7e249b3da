// Blur pass: one axis of the separable 5x5 Gaussian (1 4 6 4 1)/16 on the
// displayed height, window-local order, clamped at the window's edges. A
// 16x16 tile and its 2-texel apron along the axis are loaded into workgroup
// memory once; every tap then reads workgroup memory. CPU twin: src/cpu/blur.rs.

struct BlurParams {
    resolution: u32,
    axis: u32,       // 0: along rows (x), 1: along columns (z)
    _pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> params: BlurParams;
@group(0) @binding(1) var<storage, read> src: array<f32>;
@group(0) @binding(2) var<storage, read_write> dst: array<f32>;

const TILE: u32 = 16u;
const RADIUS: u32 = 2u;
const SPAN: u32 = 20u; // TILE + 2 * RADIUS

// Indexed [across * SPAN + along].
var<workgroup> tile: array<f32, 320>;

fn texel(along: i32, across: u32) -> f32 {
    let r = i32(params.resolution);
    let a = u32(clamp(along, 0, r - 1));
    if params.axis == 0u {
        return src[across * params.resolution + a];
    }
    return src[a * params.resolution + across];
}

@compute @workgroup_size(16, 16)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    // lid.x runs along the blur axis, lid.y across it.
    var base_along = wg.x * TILE;
    var base_across = wg.y * TILE;
    if params.axis == 1u {
        base_along = wg.y * TILE;
        base_across = wg.x * TILE;
    }
    let across = min(base_across + lid.y, params.resolution - 1u);
    let start = i32(base_along) - i32(RADIUS);
    tile[lid.y * SPAN + lid.x] = texel(start + i32(lid.x), across);
    if lid.x < 2u * RADIUS {
        tile[lid.y * SPAN + lid.x + TILE] = texel(start + i32(lid.x + TILE), across);
    }
    workgroupBarrier();

    let along = base_along + lid.x;
    if along >= params.resolution || base_across + lid.y >= params.resolution {
        return;
    }
    let t = lid.y * SPAN + lid.x;
    let sum = tile[t] + 4.0 * tile[t + 1u] + 6.0 * tile[t + 2u] + 4.0 * tile[t + 3u] + tile[t + 4u];
    var out_index = across * params.resolution + along;
    if params.axis == 1u {
        out_index = along * params.resolution + across;
    }
    dst[out_index] = sum * (1.0 / 16.0);
}
