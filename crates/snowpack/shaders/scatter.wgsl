// #import shared/objects

// Scatter pass (compute; the original drew a quad per pixel with a geometry
// shader into up to eight targets): every occlusion pixel that sees an object
// shares one pixel of snow among the atlas texels of its footprint rectangle,
// with integer atomics (HIT_UNIT per pixel) into one atlas for all objects,
// times a noise factor 1 + noise (2 hash - 1) that changes every frame.
// CPU twin: src/cpu/scatter.rs.

struct ScatterParams {
    resolution: u32,
    atlas_resolution: u32,
    frame: u32,
    noise: f32,
}

@group(0) @binding(0) var<uniform> params: ScatterParams;
@group(0) @binding(1) var footprint: texture_2d<u32>;
@group(0) @binding(2) var<storage, read_write> hits: array<atomic<u32>>;

fn hash(x: u32, y: u32, frame: u32) -> f32 {
    var h = x * 0x8da6b343u ^ y * 0xd8163841u ^ frame * 0xcb1ab31fu;
    h = (h ^ (h >> 16u)) * 0x7feb352du;
    h = (h ^ (h >> 15u)) * 0x846ca68bu;
    h = h ^ (h >> 16u);
    return f32(h >> 8u) / 16777216.0;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.resolution || gid.y >= params.resolution {
        return;
    }
    let r = textureLoad(footprint, vec2<u32>(gid.x, gid.y), 0);
    if r.x == 0xffffu {
        return;
    }
    let lo = r.xy;
    let hi = r.zw;
    let n = (hi.x - lo.x + 1u) * (hi.y - lo.y + 1u);
    let noise = 1.0 + params.noise * (2.0 * hash(gid.x, gid.y, params.frame) - 1.0);
    let w = u32(floor(HIT_UNIT * noise / f32(n) + 0.5));
    for (var y = lo.y; y <= hi.y; y++) {
        for (var x = lo.x; x <= hi.x; x++) {
            atomicAdd(&hits[y * params.atlas_resolution + x], w);
        }
    }
}
