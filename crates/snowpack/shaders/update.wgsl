// Update pass: the persistent snow height. Per texel,
//   snow = max(terrain, min(snow + refill * dt capped at rest, max(terrain, actor)))
// where rest = terrain + depth and actor is the captured lowest actor surface.
// In place: each texel reads and writes only itself. CPU twin: src/cpu/update.rs.

struct UpdateParams {
    origin: vec2<i32>,
    resolution: u32,
    depth_m: f32,
    refill_m: f32,   // refill_m_per_s * dt for this frame
    low_m: f32,
    high_m: f32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: UpdateParams;
// The depth target is bound as an unfilterable float texture: GLSL has no
// texelFetch for depth textures, and this binding works on every backend.
@group(0) @binding(1) var capture: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> terrain: array<f32>;
@group(0) @binding(3) var<storage, read_write> snow: array<f32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x;
    let i = gid.y;
    if i >= params.resolution || j >= params.resolution {
        return;
    }
    let s = storage_index(params.origin, params.resolution, i, j);
    let ground = terrain[s];
    let rest = ground + params.depth_m;
    var h = min(snow[s] + params.refill_m, rest);
    let d = textureLoad(capture, vec2<u32>(j, i), 0).x;
    if d < 1.0 {
        let actor = params.low_m + d * (params.high_m - params.low_m);
        h = min(h, max(ground, actor));
    }
    snow[s] = max(h, ground);
}
