// After step 2 of each peeling pass: which pixels this pass will shade (a
// layer in the peel depth) — counted, and marked in a per-pixel bit mask for
// the debug view. CPU twin: `src/cpu/peel_count.rs`.

struct CountParams {
    pass_index: u32,
    width: u32,
    height: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: CountParams;
@group(0) @binding(1) var peel_depth: texture_2d<f32>;
@group(0) @binding(2) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read_write> shaded: array<u32>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let i = id.y * params.width + id.x;
    let bit = 1u << params.pass_index;
    // The first pass starts the mask afresh: a select, not a branch on a
    // uniform alone (Mesa 22's lavapipe compiles such a shader again at
    // every dispatch and keeps every copy; docs/deformation.md).
    var mask = select(shaded[i], 0u, params.pass_index == 0u);
    if textureLoad(peel_depth, vec2<i32>(id.xy), 0).r > 0.0 {
        atomicAdd(&counts[params.pass_index], 1u);
        mask |= bit;
    }
    shaded[i] = mask;
}
