// Blur pass: one axis of the separable 5x5 Gaussian (1 4 6 4 1)/16 on the
// displayed height, window-local order, clamped at the window's edges. A
// 16x16 tile and its 2-texel apron along the axis are loaded into workgroup
// memory once; every tap then reads workgroup memory. CPU twin: src/cpu/blur.rs.
// Works in place in `surface`, viewed as two f32 words per texel: x reads the
// height words (2t) and writes the normal words (2t + 1) as scratch, z reads
// them back into the height words; the normals pass then overwrites the
// normal words. A dispatch reads one word of each texel and writes the
// other, so no word is both read and written in one dispatch.

struct BlurParams {
    resolution: u32,
    axis: u32,       // 0: along rows (x), 1: along columns (z)
    src_word: u32,   // word of a texel read: 0 height, 1 normal (scratch)
    dst_word: u32,   // word of a texel written
}

@group(0) @binding(0) var<uniform> params: BlurParams;
@group(0) @binding(1) var<storage, read_write> surface: array<f32>;

const TILE: u32 = 16u;
const RADIUS: u32 = 2u;
const SPAN: u32 = 20u; // TILE + 2 * RADIUS

// Indexed [across * SPAN + along].
var<workgroup> tile: array<f32, 320>;

fn texel(along: i32, across: u32) -> f32 {
    let r = i32(params.resolution);
    let a = u32(clamp(along, 0, r - 1));
    if params.axis == 0u {
        return surface[2u * (across * params.resolution + a) + params.src_word];
    }
    return surface[2u * (a * params.resolution + across) + params.src_word];
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
    surface[2u * out_index + params.dst_word] = sum * (1.0 / 16.0);
}
