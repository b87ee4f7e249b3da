// Capture pass, meshes: world-space triangle meshes (skinned characters in
// pose, caller meshes) drawn with an orthographic projection from below;
// depth is linear in world height, so the depth test keeps the lowest
// surface per texel. The analytic shapes (spheres, tyres, boxes) are not
// drawn here: capture_shapes.wgsl ray casts them by compute, and the update
// takes the lower of the two.

struct CaptureParams {
    extent_m: f32,
    texel_m: f32,
    low_m: f32,
    high_m: f32,
}

@group(0) @binding(0) var<uniform> params: CaptureParams;

// Swept over the frame: drawn once per sub-step, each vertex at
// lerp(previous, current, t). The instance gives the window's corner (world
// x, z of local 0, 0) and t; a mesh that is not swept is drawn once with t = 1.
@vertex
fn vs_swept(@location(0) current: vec3<f32>, @location(5) previous: vec3<f32>, @location(1) step: vec4<f32>) -> @builtin(position) vec4<f32> {
    let p = mix(previous, current, step.z) - vec3(step.x, 0.0, step.y);
    let depth = (p.y - params.low_m) / (params.high_m - params.low_m);
    return vec4(p.x / params.extent_m * 2.0 - 1.0, 1.0 - p.z / params.extent_m * 2.0, depth, 1.0);
}
