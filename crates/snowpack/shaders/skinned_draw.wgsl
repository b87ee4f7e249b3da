// #import shared/lighting

// Skinned characters in pose: the skinning pass's world positions drawn as
// they are, flat-shaded from screen-space derivatives (low-poly characters
// need no smooth normals), lit like the snow, casting and receiving shadows.
// The snow a character carries (the snow coat, one f32 a vertex in metres:
// snow_coat.wgsl) is blended over the fur as the objects' snow is
// (object_draw.wgsl: `frame.fresh` albedo and roughness, the snow's
// scattering), by `snow_coat_cover`: a game's own character material calls
// the same function with the same buffer bound as a vertex attribute.

// Fur: a fox's orange, rough.
const FUR_ALBEDO: vec3<f32> = vec3<f32>(0.55, 0.22, 0.07);
const FUR_ROUGHNESS: f32 = 0.85;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) coat: f32,
}

// How much of a surface the snow coat covers: none below a millimetre, all
// from 1.5 cm, with a few millimetres of value noise over 4 cm cells of the
// world so the edge breaks up instead of following the mesh's contour.
fn snow_coat_cover(coat_m: f32, world: vec3<f32>) -> f32 {
    let cell = floor(world / 0.04);
    let f = fract(world / 0.04);
    let u = f * f * (3.0 - 2.0 * f);
    let c = vec3<i32>(cell);
    let a = mix(mix(hash3(c).x, hash3(c + vec3<i32>(1, 0, 0)).x, u.x), mix(hash3(c + vec3<i32>(0, 1, 0)).x, hash3(c + vec3<i32>(1, 1, 0)).x, u.x), u.y);
    let b = mix(mix(hash3(c + vec3<i32>(0, 0, 1)).x, hash3(c + vec3<i32>(1, 0, 1)).x, u.x), mix(hash3(c + vec3<i32>(0, 1, 1)).x, hash3(c + vec3<i32>(1, 1, 1)).x, u.x), u.y);
    let noise = mix(a, b, u.z) - 0.5;
    return smoothstep(0.001, 0.015, coat_m + noise * 0.006);
}

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) coat: f32) -> VsOut {
    var out: VsOut;
    out.clip = frame.view_proj * vec4<f32>(position, 1.0);
    out.world = position;
    out.coat = coat;
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
    let cover = snow_coat_cover(in.coat, in.world);
    let albedo = mix(FUR_ALBEDO, frame.fresh.rgb, cover);
    let roughness = mix(FUR_ROUGHNESS, frame.fresh.a, cover);
    let scatter = mix(vec3<f32>(1.0, 0.6, 0.4), frame.scatter.rgb, cover);
    let s = Surface(in.world, n, albedo, roughness, 1.0, scatter, mix(0.2, frame.scatter.a, cover), frame.detail.x * cover);
    return vec4<f32>(actor_debug_colour(shade(s), n), 1.0);
}
