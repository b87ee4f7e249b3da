// Per-frame values every render pass reads; `FrameUniforms` in `src/render/frame.rs`.

struct Frame {
    view_proj: mat4x4<f32>,
    inv_view_proj: mat4x4<f32>,
    light_view_proj: mat4x4<f32>,
    camera: vec4<f32>,          // eye xyz; w: vertical term of the LOD distance (m)
    sun: vec4<f32>,             // unit vector toward the sun; w: sun intensity
    sun_color: vec4<f32>,       // rgb; w: sky (environment) intensity
    window: vec4<f32>,          // corner x, corner z, extent (m), texel (m)
    window_info: vec4<u32>,     // resolution, placed (0/1), debug view, decals on (0/1)
    lod: vec4<f32>,             // detail bonus (m), bonus fade margin (m), unused, view distance (m)
    snow: vec4<f32>,            // rest depth (m), shadow distance (m), shadow texel (m), exposure multiplier
    fresh: vec4<f32>,           // fresh albedo rgb, fresh roughness
    packed: vec4<f32>,          // compacted albedo rgb, compacted roughness
    ground: vec4<f32>,          // bare ground albedo rgb, its roughness
    scatter: vec4<f32>,         // subsurface tint rgb, wrap amount
    detail: vec4<f32>,          // sparkle, detail normal strength, detail frequency (1/m), macro variation
    background: vec4<f32>,      // solid background rgb; w: 1 draws it instead of the sky
    env_info: vec4<u32>,        // full environment width, height; unused, unused
    compaction: vec4<f32>,      // pressed fraction of the full compacted look, detail kept, sparkle kept, ground show-through
}

// Debug views (`DebugView` in `src/render/params.rs`).
const VIEW_LIT: u32 = 0u;
const VIEW_NORMALS: u32 = 1u;
const VIEW_AO: u32 = 2u;
const VIEW_LOD: u32 = 3u;
const VIEW_WIREFRAME: u32 = 4u;
const VIEW_DEFORMATION: u32 = 5u;

const PI: f32 = 3.14159265358979;

// Equirectangular mapping shared with `src/render/environment.rs`:
// u runs with azimuth from -z through +x, v from the zenith (0) to the nadir (1).
fn equirect_dir(u: f32, v: f32) -> vec3<f32> {
    let phi = (u - 0.5) * 2.0 * PI;
    let theta = v * PI;
    return vec3<f32>(sin(theta) * sin(phi), cos(theta), -sin(theta) * cos(phi));
}

fn dir_equirect(d: vec3<f32>) -> vec2<f32> {
    let u = atan2(d.x, -d.z) / (2.0 * PI) + 0.5;
    let v = acos(clamp(d.y, -1.0, 1.0)) / PI;
    return vec2<f32>(u, v);
}

// Bilinear sample of a w x h equirect map stored row-major from `base` in a
// storage array; wraps in u, clamps in v. Takes the four texels (storage
// pointers cannot be passed to functions), so callers fetch them.
struct Bilinear {
    i00: u32,
    i01: u32,
    i10: u32,
    i11: u32,
    f: vec2<f32>,
}

fn equirect_taps(uv: vec2<f32>, w: u32, h: u32, base: u32) -> Bilinear {
    let x = uv.x * f32(w) - 0.5;
    let y = clamp(uv.y * f32(h) - 0.5, 0.0, f32(h - 1u));
    let x0f = floor(x);
    let y0f = floor(y);
    let f = vec2<f32>(x - x0f, y - y0f);
    let x0 = u32((i32(x0f) + i32(w)) % i32(w));
    let x1 = (x0 + 1u) % w;
    let y0 = u32(y0f);
    let y1 = min(y0 + 1u, h - 1u);
    return Bilinear(base + y0 * w + x0, base + y0 * w + x1, base + y1 * w + x0, base + y1 * w + x1, f);
}

fn bilinear_mix(b: Bilinear, a00: vec3<f32>, a01: vec3<f32>, a10: vec3<f32>, a11: vec3<f32>) -> vec3<f32> {
    return mix(mix(a00, a01, b.f.x), mix(a10, a11, b.f.x), b.f.y);
}
