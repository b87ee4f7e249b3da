// #import shared/frame

// Exposure and a filmic tone map (ACES, Narkowicz's fit) from the HDR target
// to the output, which stores sRGB. Debug views pass through unmapped.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var hdr: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u)) * 2.0 - 1.0;
    return vec4<f32>(xy, 0.0, 1.0);
}

fn aces(x: vec3<f32>) -> vec3<f32> {
    let a = 2.51;
    let b = 0.03;
    let c = 2.43;
    let d = 0.59;
    let e = 0.14;
    return clamp((x * (a * x + b)) / (x * (c * x + d) + e), vec3<f32>(0.0), vec3<f32>(1.0));
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let c = textureLoad(hdr, vec2<i32>(pos.xy), 0).rgb;
    // Debug views other than the wireframe show their colours as they are.
    // No branch here tests uniforms alone: Mesa 22's lavapipe compiles such a
// shader again at every draw, uniforms inlined, and keeps every copy
// (docs/deformation.md, "Branches on uniforms"); a select chooses instead.
    let debug = (frame.window_info.z != VIEW_LIT) & (frame.window_info.z != VIEW_WIREFRAME);
    return vec4<f32>(select(aces(c * frame.snow.w), clamp(c, vec3<f32>(0.0), vec3<f32>(1.0)), debug), 1.0);
}
