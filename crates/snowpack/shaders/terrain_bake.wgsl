// Terrain bake: the terrain mesh drawn from above into a depth-only grid.
// Depth is linear in world height with the test `greater`, so each texel keeps
// the highest surface; terrain_resolve.wgsl turns depth back into metres.
// (Depth only: R32Float is not renderable on GL ES adapters.)

struct TerrainBakeParams {
    origin_m: vec2<f32>,
    size_m: vec2<f32>,
    low_m: f32,
    high_m: f32,
    _pad: vec2<f32>,
}

@group(0) @binding(0) var<uniform> params: TerrainBakeParams;

@vertex
fn vs_main(@location(0) position: vec3<f32>) -> @builtin(position) vec4<f32> {
    let u = (position.x - params.origin_m.x) / params.size_m.x;
    let v = (position.z - params.origin_m.y) / params.size_m.y;
    let depth = (position.y - params.low_m) / (params.high_m - params.low_m);
    // Row 0 of the target (the top of clip space) is the smallest z.
    return vec4(u * 2.0 - 1.0, 1.0 - v * 2.0, depth, 1.0);
}
