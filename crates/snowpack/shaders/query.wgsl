// Point queries: for each asked point (x, z in metres from the window's
// corner), the snow there, bilinear between texel centres: the persistent
// snow height, the displayed surface and its normal, the terrain and the rest
// surface (terrain + depth + snowfall so far). Points within half a texel of
// the window's edge, or outside it, are answered with inside = 0.
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

// 32 bytes: what `PointSample` unpacks on the CPU.
struct Sample {
    height_m: f32,
    surface_m: f32,
    terrain_m: f32,
    rest_m: f32,
    normal_x: f32,
    normal_y: f32,
    normal_z: f32,
    inside: f32,
}

@group(0) @binding(0) var<uniform> params: QueryParams;
@group(0) @binding(1) var<storage, read> points: array<vec2<f32>>;
// The terrain's source (shared/terrain.wgsl), evaluated at texel centres.
@group(0) @binding(2) var<storage, read> heightmap: array<f32>;
@group(0) @binding(3) var<storage, read> snow: array<f32>;
@group(0) @binding(4) var<storage, read> fallen: array<f32>;
@group(0) @binding(5) var<storage, read> surface: array<vec2<u32>>;
@group(0) @binding(6) var<storage, read_write> samples: array<Sample>;
@group(0) @binding(7) var<uniform> terrain_params: TerrainParams;

fn bilerp(a: f32, b: f32, c: f32, d: f32, f: vec2<f32>) -> f32 {
    let ab = a + (b - a) * f.x;
    let cd = c + (d - c) * f.x;
    return ab + (cd - ab) * f.y;
}

fn surface_normal(t: vec2<u32>) -> vec3<f32> {
    let n = unpack2x16snorm(t.y);
    return vec3(n.x, sqrt(max(1.0 - n.x * n.x - n.y * n.y, 0.0)), n.y);
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
    var out = Sample(0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
    if cell.x < 0.0 || cell.y < 0.0 || cell.x > f32(r - 2) || cell.y > f32(r - 2) {
        samples[k] = out;
        return;
    }
    let j = u32(cell.x);
    let i = u32(cell.y);
    let res = params.resolution;
    // Persistent state is toroidal; the displayed surface is window-local.
    let s00 = storage_index(params.origin, res, i, j);
    let s01 = storage_index(params.origin, res, i, j + 1u);
    let s10 = storage_index(params.origin, res, i + 1u, j);
    let s11 = storage_index(params.origin, res, i + 1u, j + 1u);
    out.height_m = bilerp(snow[s00], snow[s01], snow[s10], snow[s11], f);
    let g = params.origin + vec2<i32>(i32(j), i32(i));
    let t00 = texel_ground(terrain_params, g, params.texel_m);
    let t01 = texel_ground(terrain_params, g + vec2<i32>(1, 0), params.texel_m);
    let t10 = texel_ground(terrain_params, g + vec2<i32>(0, 1), params.texel_m);
    let t11 = texel_ground(terrain_params, g + vec2<i32>(1, 1), params.texel_m);
    out.terrain_m = bilerp(t00, t01, t10, t11, f);
    var fallen_m = 0.0;
    if params.use_fallen != 0u {
        fallen_m = bilerp(fallen[s00], fallen[s01], fallen[s10], fallen[s11], f);
    }
    out.rest_m = out.terrain_m + params.depth_m + fallen_m;
    let w00 = surface[i * res + j];
    let w01 = surface[i * res + j + 1u];
    let w10 = surface[(i + 1u) * res + j];
    let w11 = surface[(i + 1u) * res + j + 1u];
    out.surface_m = bilerp(bitcast<f32>(w00.x), bitcast<f32>(w01.x), bitcast<f32>(w10.x), bitcast<f32>(w11.x), f);
    let n00 = surface_normal(w00);
    let n01 = surface_normal(w01);
    let n10 = surface_normal(w10);
    let n11 = surface_normal(w11);
    let n = normalize(mix(mix(n00, n01, f.x), mix(n10, n11, f.x), f.y));
    out.normal_x = n.x;
    out.normal_y = n.y;
    out.normal_z = n.z;
    out.inside = 1.0;
    samples[k] = out;
}
