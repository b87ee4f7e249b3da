// #import snow_sampling

// SnowGround: the snow surface drawn into a render pass a game owns.
// Its import is the snow sampling module (snow_sampling.wgsl, group 1), which
// this pass uses exactly as a game's shader would.
//
// A grid of (quads + 1)^2 quads, fixed in world space (its lines sit on
// multiples of the quad size, so moving the window does not make the geometry
// swim) and clamped to the window's extent, displaced by `snow_height` in the
// vertex shader. The fragment shader samples the normal, compaction and depth
// per pixel, so shading keeps the full texel resolution wherever the grid is
// coarser than the texels. Lighting: sun (Lambert plus a wrapped, tinted term
// for light scattered through the grains, as shared/lighting.wgsl's `shade`)
// and a hemispherical ambient (sky above, bounce below); output is linear
// radiance, not tone-mapped. `GroundCamera` and `GroundParams` in
// src/render/ground.rs.

struct GroundCamera {
    view_proj: mat4x4<f32>,
    position: vec4<f32>,        // eye xyz; w unused
}

struct GroundParams {
    sun_direction: vec4<f32>,   // unit vector toward the sun; w: wrap amount
    sun_color: vec4<f32>,       // rgb: what a white Lambertian surface facing the sun reflects; w unused
    sky_color: vec4<f32>,       // rgb: ambient on a white surface facing up
    bounce_color: vec4<f32>,    // rgb: ambient on a white surface facing down
    fresh_albedo: vec4<f32>,    // rgb: untouched snow
    packed_albedo: vec4<f32>,   // rgb: snow pressed to the ground
    bare_albedo: vec4<f32>,     // rgb: ground where the snow is gone
    scatter: vec4<f32>,         // rgb: tint of the wrapped (scattered) light
    grid: vec4<f32>,            // first line x, z (m), quad size (m), quads per side
    bounds: vec4<f32>,          // window's corner x, z and far corner x, z (m)
}

@group(0) @binding(0) var<uniform> camera: GroundCamera;
@group(0) @binding(1) var<uniform> ground: GroundParams;

struct GroundOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> GroundOut {
    let row = u32(ground.grid.w) + 1u;
    let k = vec2<f32>(f32(vi % row), f32(vi / row));
    let xz = clamp(ground.grid.xy + k * ground.grid.z, ground.bounds.xy, ground.bounds.zw);
    let world = vec3<f32>(xz.x, snow_height(xz), xz.y);
    var out: GroundOut;
    out.clip = camera.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    return out;
}

@fragment
fn fs_main(in: GroundOut) -> @location(0) vec4<f32> {
    let xz = in.world.xz;
    let n = snow_normal(xz);
    // Pressed snow is denser with larger grains: darker and bluer.
    let pressed = smoothstep(0.02, 0.35, snow_compaction(xz));
    let bare = 1.0 - smoothstep(0.005, 0.03, snow_depth(xz));
    let albedo = mix(mix(ground.fresh_albedo.rgb, ground.packed_albedo.rgb, pressed), ground.bare_albedo.rgb, bare);
    // Snow scatters; bare ground does not.
    let wrap = ground.sun_direction.w * (1.0 - bare);

    let n_l = dot(n, ground.sun_direction.xyz);
    let lambert = max(n_l, 0.0);
    let wrapped = max((n_l + wrap) / ((1.0 + wrap) * (1.0 + wrap)), 0.0);
    let sun = ground.sun_color.rgb * (lambert + ground.scatter.rgb * max(wrapped - lambert, 0.0));
    let ambient = mix(ground.bounce_color.rgb, ground.sky_color.rgb, n.y * 0.5 + 0.5);
    return vec4<f32>(albedo * (sun + ambient), 1.0);
}
