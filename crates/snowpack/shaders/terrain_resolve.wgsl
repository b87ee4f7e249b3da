// Terrain resolve: the bake's depth grid back into world heights (m), row-major
// into the heightmap buffer the window pass samples. Depth 0 (the cleared
// value) means no triangle covers the texel: it gets the mesh's lowest height.
// CPU twin: src/cpu/terrain_bake.rs (the whole bake).

struct ResolveParams {
    width: u32,
    height: u32,
    low_m: f32,
    high_m: f32,
    floor_m: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: ResolveParams;
// Unfilterable float binding of the depth target: works on every backend, GL included.
@group(0) @binding(1) var depth: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> heights: array<f32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x;
    let i = gid.y;
    if i >= params.height || j >= params.width {
        return;
    }
    let d = textureLoad(depth, vec2<u32>(j, i), 0).x;
    var h = params.floor_m;
    if d > 0.0 {
        h = params.low_m + d * (params.high_m - params.low_m);
    }
    heights[i * params.width + j] = h;
}
