// Capture pass, meshes: world-space triangle meshes (skinned characters in
// pose, caller meshes; `vs_swept`) and, with the capture's
// `ShapeCapture::Raster`, boxes as instanced unit cubes (`vs_main`), drawn
// with an orthographic projection from below; depth is linear in world
// height, so the depth test keeps the lowest surface per texel. By compute,
// capture_shapes.wgsl ray casts boxes instead, exactly.

struct CaptureParams {
    extent_m: f32,
    texel_m: f32,
    low_m: f32,
    high_m: f32,
}

@group(0) @binding(0) var<uniform> params: CaptureParams;

struct InstanceIn {
    @location(1) c0: vec4<f32>,
    @location(2) c1: vec4<f32>,
    @location(3) c2: vec4<f32>,
    @location(4) c3: vec4<f32>,
}

@vertex
fn vs_main(@location(0) position: vec3<f32>, inst: InstanceIn) -> @builtin(position) vec4<f32> {
    // Model matrix maps mesh space to window-local space (x, y = world height, z).
    let model = mat4x4<f32>(inst.c0, inst.c1, inst.c2, inst.c3);
    let p = model * vec4(position, 1.0);
    let depth = (p.y - params.low_m) / (params.high_m - params.low_m);
    return vec4(p.x / params.extent_m * 2.0 - 1.0, 1.0 - p.z / params.extent_m * 2.0, depth, 1.0);
}

// World-space meshes (skinned characters in pose, caller meshes), swept over
// the frame: drawn once per sub-step, each vertex at lerp(previous, current,
// t). The instance gives the window's corner (world x, z of local 0, 0) and t;
// a mesh that is not swept is drawn once with t = 1.
@vertex
fn vs_swept(@location(0) current: vec3<f32>, @location(5) previous: vec3<f32>, @location(1) step: vec4<f32>) -> @builtin(position) vec4<f32> {
    let p = mix(previous, current, step.z) - vec3(step.x, 0.0, step.y);
    let depth = (p.y - params.low_m) / (params.high_m - params.low_m);
    return vec4(p.x / params.extent_m * 2.0 - 1.0, 1.0 - p.z / params.extent_m * 2.0, depth, 1.0);
}
