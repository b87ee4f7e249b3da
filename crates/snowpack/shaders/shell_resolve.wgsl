// The full-screen steps of the shell's depth peeling (Leshonkov & Frolov
// 2021, section 3.1, Figure 2), and the composite over the scene. Depth is
// reverse-Z: nearer is greater, 0 is the far plane, which no layer reaches,
// so 0 marks "no layer" in the peel depth and "done" in the cull depth.
//   Step 2 (`fs_layer_depth`): the layer found in step 1 into the depth
//     buffer, or 0 where there is none or it lies behind the scene.
//   Step 4 (`fs_extend`): the cull depth for the next pass's step 1: the
//     layer's depth, or 0 where no layer was shaded or where the opacity
//     accumulated so far passes the threshold (0.95).
//   `fs_composite`: the shell's premultiplied colour over the HDR scene; in
//     the debug view, the pixels one pass shaded in green (their Figure 3).

struct PeelParams {
    threshold: f32,       // opacity that ends a pixel's peeling
    debug_pass: u32,      // 0 off; k: tint the pixels pass k shaded
    width: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: PeelParams;
@group(0) @binding(1) var depth_a: texture_2d<f32>;   // step 2: the layer; step 4: the peel depth
@group(0) @binding(2) var depth_b: texture_2d<f32>;   // the scene
@group(0) @binding(3) var accumulated: texture_2d<f32>;
@group(0) @binding(4) var<storage, read> shaded: array<u32>;  // bit k-1: pass k shaded the pixel

@vertex
fn vs_full(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u)) * 2.0 - 1.0;
    return vec4<f32>(xy, 0.0, 1.0);
}

@fragment
fn fs_layer_depth(@builtin(position) pos: vec4<f32>) -> @builtin(frag_depth) f32 {
    let p = vec2<i32>(pos.xy);
    let layer = textureLoad(depth_a, p, 0).r;
    let scene = textureLoad(depth_b, p, 0).r;
    return select(0.0, layer, layer > scene);
}

@fragment
fn fs_extend(@builtin(position) pos: vec4<f32>) -> @builtin(frag_depth) f32 {
    let p = vec2<i32>(pos.xy);
    let peel = textureLoad(depth_a, p, 0).r;
    let alpha = textureLoad(accumulated, p, 0).a;
    return select(peel, 0.0, alpha >= params.threshold);
}

@fragment
fn fs_composite(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(pos.xy);
    let c = textureLoad(accumulated, p, 0);
    // A debug pass shows over the shaded result: green where that pass
    // shaded, dimmed elsewhere. Chosen by a select: with a branch on the
    // uniform alone, Mesa 22's lavapipe compiles this shader again at every
    // draw and keeps every copy (docs/deformation.md, "Branches on uniforms").
    let bit = (shaded[u32(p.y) * params.width + u32(p.x)] >> (params.debug_pass - 1u)) & 1u;
    let shown = select(vec4<f32>(0.0, 0.0, 0.0, 0.5), vec4<f32>(0.0, 0.6, 0.0, 0.6), bit == 1u);
    return select(c, shown, params.debug_pass > 0u);
}
