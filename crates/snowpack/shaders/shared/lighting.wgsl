// #import shared/frame

// Bindings and shading shared by the lit passes (terrain and actors):
// sun with a PCF shadow map, image-based sky light from the prefiltered
// environment, GGX specular, a wrapped, tinted diffuse for snow's scattering.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var shadow_map: texture_depth_2d;
@group(0) @binding(2) var shadow_sampler: sampler_comparison;
// Level 0: irradiance / pi; levels 1..=ENV_SPECULAR_LEVELS: GGX-prefiltered
// radiance for roughness level / ENV_SPECULAR_LEVELS; each ENV_W x ENV_H.
@group(0) @binding(3) var<storage, read> env_light: array<vec4<f32>>;
@group(0) @binding(4) var detail_map: texture_2d<f32>;
@group(0) @binding(5) var detail_sampler: sampler;

const ENV_W: u32 = 32u;
const ENV_H: u32 = 16u;
const ENV_SPECULAR_LEVELS: u32 = 5u;

fn env_level(level: u32, d: vec3<f32>) -> vec3<f32> {
    let b = equirect_taps(dir_equirect(d), ENV_W, ENV_H, level * ENV_W * ENV_H);
    return bilinear_mix(b, env_light[b.i00].rgb, env_light[b.i01].rgb, env_light[b.i10].rgb, env_light[b.i11].rgb);
}

fn env_irradiance(n: vec3<f32>) -> vec3<f32> {
    return env_level(0u, n) * frame.sun_color.w;
}

fn env_specular(r: vec3<f32>, roughness: f32) -> vec3<f32> {
    let x = clamp(roughness, 0.2, 1.0) * f32(ENV_SPECULAR_LEVELS);
    let l0 = u32(floor(x));
    let l1 = min(l0 + 1u, ENV_SPECULAR_LEVELS);
    return mix(env_level(l0, r), env_level(l1, r), x - floor(x)) * frame.sun_color.w;
}

// Fraction of the sun reaching `p` (normal `n`): 4 hardware-filtered PCF taps,
// faded out toward the shadow distance.
fn sun_visibility(p: vec3<f32>, n: vec3<f32>) -> f32 {
    let offset_p = p + n * frame.snow.z * 1.5;
    let c = frame.light_view_proj * vec4<f32>(offset_p, 1.0);
    let ndc = c.xyz / c.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    let texel = 1.0 / vec2<f32>(textureDimensions(shadow_map));
    var lit = 0.0;
    lit += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(-0.5, -0.5) * texel, ndc.z);
    lit += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(0.5, -0.5) * texel, ndc.z);
    lit += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(-0.5, 0.5) * texel, ndc.z);
    lit += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(0.5, 0.5) * texel, ndc.z);
    lit *= 0.25;
    let inside = all(uv > vec2<f32>(0.0)) && all(uv < vec2<f32>(1.0)) && ndc.z < 1.0;
    let dist = length(p - frame.camera.xyz);
    let fade = clamp((dist - 0.85 * frame.snow.y) / (0.15 * frame.snow.y), 0.0, 1.0);
    return select(1.0, mix(lit, 1.0, fade), inside);
}

fn ggx_d(n_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let d = n_h * n_h * (a2 - 1.0) + 1.0;
    return a2 / (PI * d * d);
}

fn smith_g1(n_x: f32, alpha: f32) -> f32 {
    let k = alpha * 0.5;
    return n_x / (n_x * (1.0 - k) + k);
}

fn fresnel_schlick(f0: f32, v_h: f32) -> f32 {
    return f0 + (1.0 - f0) * pow(1.0 - v_h, 5.0);
}

struct Surface {
    p: vec3<f32>,
    n: vec3<f32>,
    albedo: vec3<f32>,
    roughness: f32,
    ao: f32,
    // Subsurface tint and wrap: light bleeding past the terminator, bluish in snow.
    scatter: vec3<f32>,
    wrap: f32,
    sparkle: f32,
}

fn hash3(p: vec3<i32>) -> vec3<f32> {
    var h = vec3<u32>(bitcast<vec3<u32>>(p)) * vec3<u32>(0x8da6b343u, 0xd8163841u, 0xcb1ab31fu);
    h = (h ^ (h.yzx >> vec3<u32>(16u))) * 0x7feb352du;
    h = (h ^ (h.zxy >> vec3<u32>(15u))) * 0x846ca68bu;
    h = h ^ (h >> vec3<u32>(16u));
    return vec3<f32>(h >> vec3<u32>(8u)) / 16777216.0;
}

// Lit radiance leaving `s` toward the eye.
fn shade(s: Surface) -> vec3<f32> {
    let v = normalize(frame.camera.xyz - s.p);
    let l = frame.sun.xyz;
    let n = s.n;
    let n_l = dot(n, l);
    let n_v = max(dot(n, v), 1e-3);
    let h = normalize(l + v);
    let sun = frame.sun_color.rgb * frame.sun.w * sun_visibility(s.p, n);
    let alpha = max(s.roughness * s.roughness, 0.02);
    let f0 = 0.02;
    // Derivatives before any branch (uniform control flow).
    let cell_pos = s.p * 60.0;
    let footprint = length(fwidth(cell_pos));

    // Diffuse: Lambert plus a wrapped term whose excess over Lambert is tinted
    // by the scatter colour (light diffusing through the grains).
    let lambert = max(n_l, 0.0);
    let wrapped = max((n_l + s.wrap) / ((1.0 + s.wrap) * (1.0 + s.wrap)), 0.0);
    let diffuse = s.albedo * (lambert + s.scatter * max(wrapped - lambert, 0.0));

    var specular = 0.0;
    if n_l > 0.0 {
        let n_h = max(dot(n, h), 0.0);
        let spec = ggx_d(n_h, alpha) * smith_g1(n_l, alpha) * smith_g1(n_v, alpha) / (4.0 * n_v);
        specular = spec * fresnel_schlick(f0, max(dot(v, h), 0.0));
    }

    // Sparkle: a few grains per cell act as mirrors with random facets; they
    // flash when their facet bisects sun and eye. Faded where cells fall below a pixel.
    var glint = 0.0;
    if s.sparkle > 0.0 && n_l > 0.0 {
        let r = hash3(vec3<i32>(floor(cell_pos)));
        if r.z > 0.92 {
            let facet = normalize(n + (r - 0.5) * vec3<f32>(0.9, 0.0, 0.9));
            glint = pow(max(dot(facet, h), 0.0), 600.0) * 40.0 * s.sparkle * clamp(2.0 - footprint, 0.0, 1.0);
        }
    }

    let ambient_diffuse = s.albedo * env_irradiance(n);
    let r = reflect(-v, n);
    let env_f = fresnel_schlick(f0, n_v) * (1.0 - s.roughness * 0.5);
    let ambient_specular = env_specular(r, s.roughness) * env_f;
    return sun * (diffuse + vec3<f32>(specular + glint) * lambert) + (ambient_diffuse + ambient_specular) * s.ao;
}

// What an actor (sphere, box, character) shows in the debug views: its
// normal, or a neutral grey where the view is about the snow.
// No branch here tests uniforms alone: Mesa 22's lavapipe compiles such a
// shader again at every draw, uniforms inlined, and keeps every copy
// (docs/deformation.md, "Branches on uniforms"); a select chooses instead.
fn actor_debug_colour(lit: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let view = frame.window_info.z;
    let grey = select(lit, vec3<f32>(0.5), (view == VIEW_AO) | (view == VIEW_DEFORMATION));
    return select(grey, n * 0.5 + 0.5, view == VIEW_NORMALS);
}
