// Ambient occlusion of the displayed snow surface from its height field
// (exact for a height field: nothing hides under it). Per texel, the horizon
// in 8 directions is found by marching 2^k texels out; each direction's sky
// is cos^2 of the horizon elevation (cosine-weighted). CPU twin: `cpu/ao.rs`.

struct AoParams {
    resolution: u32,
    steps: u32,
    texel_m: f32,
    strength: f32,
}

@group(0) @binding(0) var<uniform> params: AoParams;
@group(0) @binding(1) var<storage, read> surface: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read_write> ao: array<f32>;

fn height(i: i32, j: i32) -> f32 {
    let last = i32(params.resolution) - 1;
    let ci = clamp(i, 0, last);
    let cj = clamp(j, 0, last);
    return bitcast<f32>(surface[u32(ci) * params.resolution + u32(cj)].x);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.resolution || id.y >= params.resolution {
        return;
    }
    let i = i32(id.y);
    let j = i32(id.x);
    let h0 = height(i, j);
    var dirs = array<vec2<i32>, 8>(
        vec2<i32>(1, 0), vec2<i32>(1, 1), vec2<i32>(0, 1), vec2<i32>(-1, 1),
        vec2<i32>(-1, 0), vec2<i32>(-1, -1), vec2<i32>(0, -1), vec2<i32>(1, -1),
    );
    var occluded = 0.0;
    for (var d = 0u; d < 8u; d++) {
        let dir = dirs[d];
        let unit = select(1.0, 1.41421356, dir.x != 0 && dir.y != 0) * params.texel_m;
        var slope = 0.0;
        for (var k = 0u; k < params.steps; k++) {
            let r = i32(1u << k);
            let rise = height(i + dir.y * r, j + dir.x * r) - h0;
            slope = max(slope, rise / (f32(r) * unit));
        }
        // sin^2 of the horizon elevation.
        occluded += slope * slope / (1.0 + slope * slope);
    }
    ao[id.y * params.resolution + id.x] = 1.0 - params.strength * occluded / 8.0;
}
