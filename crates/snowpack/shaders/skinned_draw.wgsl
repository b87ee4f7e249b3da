// #import shared/lighting

// Skinned characters in pose: the skinning pass's world positions drawn as
// they are, flat-shaded from screen-space derivatives (low-poly characters
// need no smooth normals), lit like the snow, casting and receiving shadows.

// Fur: a fox's orange, rough.
const FUR_ALBEDO: vec3<f32> = vec3<f32>(0.55, 0.22, 0.07);
const FUR_ROUGHNESS: f32 = 0.85;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
}

@vertex
fn vs_main(@location(0) position: vec3<f32>) -> VsOut {
    var out: VsOut;
    out.clip = frame.view_proj * vec4<f32>(position, 1.0);
    out.world = position;
    return out;
}

@vertex
fn vs_shadow(@location(0) position: vec3<f32>) -> @builtin(position) vec4<f32> {
    return frame.light_view_proj * vec4<f32>(position, 1.0);
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    var n = normalize(cross(dpdx(in.world), dpdy(in.world)));
    // Either winding: face the eye.
    if dot(n, frame.camera.xyz - in.world) < 0.0 {
        n = -n;
    }
    let s = Surface(in.world, n, FUR_ALBEDO, FUR_ROUGHNESS, 1.0, vec3<f32>(1.0, 0.6, 0.4), 0.2, 0.0);
    return vec4<f32>(actor_debug_colour(shade(s), n), 1.0);
}
