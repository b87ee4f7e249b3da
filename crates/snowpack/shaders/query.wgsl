// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/snow_word
// #import shared/packed_snow

// Point queries: for each asked point (x, z in metres from the window's
// corner), the snow there, bilinear between texel centres: the persistent
// snow height, the displayed surface and its normal, the terrain and the rest
// surface (terrain + depth + snowfall so far). Points within half a texel of
// the window's edge, or outside it, are answered with inside = 0.
// The snow words hold both the persistent snow (a deficit below rest) and
// the displayed height (above the terrain, shared/snow_word.wgsl); a
// texel's normal is the central difference of the displayed heights around
// it, clamped at the window's edges, as the renderer computes it. The
// packed snow (shared/packed_snow.wgsl) is bilinear too, in metres of fresh
// snow: with the height above the terrain it gives the column's density.
// One thread per point; a few thousand points cost one small dispatch.
// CPU twin: src/cpu/query.rs.

struct QueryParams {
    origin: vec2<i32>,
    resolution: u32,
    count: u32,
    texel_m: f32,
    depth_m: f32,
    use_fallen: u32,
    _pad: u32,
}

// 36 bytes: what `PointSample` unpacks on the CPU.
struct Sample {
    height_m: f32,
    surface_m: f32,
    terrain_m: f32,
    rest_m: f32,
    normal_x: f32,
    normal_y: f32,
    normal_z: f32,
    inside: f32,
    packed_m: f32,
}

@group(0) @binding(0) var<uniform> params: QueryParams;

// Whether the rest height includes snowfall, as this pipeline is built
// (`QueryPass` builds one per value in use, pass/compute.rs); the default
// reads `params.use_fallen`.
// Built in, no branch tests a uniform alone: Mesa 22's lavapipe compiles
// such a shader again at every dispatch, uniforms inlined, and keeps every
// copy (docs/deformation.md, "Branches on uniforms").
override QUERY_USE_FALLEN: u32 = 0xffffffffu;

fn query_uses_fallen() -> bool {
    if QUERY_USE_FALLEN != 0xffffffffu {
        return QUERY_USE_FALLEN != 0u;
    }
    return params.use_fallen != 0u;
}
@group(0) @binding(1) var<storage, read> points: array<vec2<f32>>;
// The terrain's source (shared/terrain.wgsl), evaluated at texel centres.
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(2) var<storage, read> snow: array<u32>;
@group(1) @binding(4) var<storage, read> fallen: array<f32>;
// Packed snow, two texels a word (shared/packed_snow.wgsl).
@group(0) @binding(3) var<storage, read> packed: array<u32>;

fn packed_m(s: u32) -> f32 {
    return f32(packed_get(packed[packed_index(s)], s)) * SNOW_QUANTUM_M;
}
@group(0) @binding(2) var<storage, read_write> samples: array<Sample>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;

fn bilerp(a: f32, b: f32, c: f32, d: f32, f: vec2<f32>) -> f32 {
    let ab = a + (b - a) * f.x;
    let cd = c + (d - c) * f.x;
    return ab + (cd - ab) * f.y;
}

// Displayed height of window-local texel (i, j), clamped into the window.
fn shown_at(i: i32, j: i32) -> f32 {
    let last = i32(params.resolution) - 1;
    let ci = u32(clamp(i, 0, last));
    let cj = u32(clamp(j, 0, last));
    let ground = texel_ground(terrain_params, params.origin + vec2<i32>(i32(cj), i32(ci)), params.texel_m);
    return snow_word_shown(snow[storage_index(params.origin, params.resolution, ci, cj)], ground);
}

fn texel_normal(i: i32, j: i32) -> vec3<f32> {
    let dx = shown_at(i, j + 1) - shown_at(i, j - 1);
    let dz = shown_at(i + 1, j) - shown_at(i - 1, j);
    return normalize(vec3(-dx, 2.0 * params.texel_m, -dz));
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= params.count {
        return;
    }
    let uv = points[k] / params.texel_m - vec2(0.5);
    let cell = floor(uv);
    let f = uv - cell;
    let r = i32(params.resolution);
    var out = Sample(0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0);
    if cell.x < 0.0 || cell.y < 0.0 || cell.x > f32(r - 2) || cell.y > f32(r - 2) {
        samples[k] = out;
        return;
    }
    let j = u32(cell.x);
    let i = u32(cell.y);
    let res = params.resolution;
    let s00 = storage_index(params.origin, res, i, j);
    let s01 = storage_index(params.origin, res, i, j + 1u);
    let s10 = storage_index(params.origin, res, i + 1u, j);
    let s11 = storage_index(params.origin, res, i + 1u, j + 1u);
    let g = params.origin + vec2<i32>(i32(j), i32(i));
    let t00 = texel_ground(terrain_params, g, params.texel_m);
    let t01 = texel_ground(terrain_params, g + vec2<i32>(1, 0), params.texel_m);
    let t10 = texel_ground(terrain_params, g + vec2<i32>(0, 1), params.texel_m);
    let t11 = texel_ground(terrain_params, g + vec2<i32>(1, 1), params.texel_m);
    out.terrain_m = bilerp(t00, t01, t10, t11, f);
    var l00 = 0.0;
    var l01 = 0.0;
    var l10 = 0.0;
    var l11 = 0.0;
    if query_uses_fallen() {
        l00 = fallen[s00];
        l01 = fallen[s01];
        l10 = fallen[s10];
        l11 = fallen[s11];
    }
    out.rest_m = out.terrain_m + params.depth_m + bilerp(l00, l01, l10, l11, f);
    let d = params.depth_m;
    out.height_m = bilerp(
        snow_column_height(snow[s00], t00, d + l00),
        snow_column_height(snow[s01], t01, d + l01),
        snow_column_height(snow[s10], t10, d + l10),
        snow_column_height(snow[s11], t11, d + l11),
        f,
    );
    out.packed_m = bilerp(packed_m(s00), packed_m(s01), packed_m(s10), packed_m(s11), f);
    out.surface_m = bilerp(snow_word_shown(snow[s00], t00), snow_word_shown(snow[s01], t01), snow_word_shown(snow[s10], t10), snow_word_shown(snow[s11], t11), f);
    let ii = i32(i);
    let jj = i32(j);
    let n = normalize(mix(mix(texel_normal(ii, jj), texel_normal(ii, jj + 1), f.x), mix(texel_normal(ii + 1, jj), texel_normal(ii + 1, jj + 1), f.x), f.y));
    out.normal_x = n.x;
    out.normal_y = n.y;
    out.normal_z = n.z;
    out.inside = 1.0;
    samples[k] = out;
}
