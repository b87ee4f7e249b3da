// Rim pass: the displayed height before blur, in window-local order, into
// the height word of `surface` (even words; the normal words are left alone).
// Mode 0 (depth, decals): Hanák's cubic remap (eq. 4.1),
//   f(x) = -3.4766x^3 + 6.508x^2 - 2.231x + 0.215,
// applied to the normalised snow depth x and blended in by `elevation`:
//   shown = terrain + depth * (x + elevation * (f(x) - x)),
// depth being the rest depth plus the snowfall so far where it snows.
// Modes 1 (MS16) and 2 (Wasmut's rounded variant), for points and combined:
// the persistent snow as it is, plus a rim where a stored footprint rises
// above the rest height over undisturbed snow, from its foot height:
//   e = sqrt(h - foot) - sqrt(rest - foot), M = sqrt(rest - foot), r = e / M,
//   MS16: 1 - (0.5 - 2r)^2, rounded: 1 - (2r - 1)^2, clamped at 0,
// times elevation * RIM_PEAK * (rest - foot). CPU twin: src/cpu/rim.rs.

struct RimParams {
    origin: vec2<i32>,
    resolution: u32,
    depth_m: f32,
    elevation: f32,
    mode: u32,
    low_m: f32,
    high_m: f32,
    use_fallen: u32,  // 1: the rest depth includes `fallen` (snowfall so far)
    texel_m: f32,
}

@group(0) @binding(0) var<uniform> params: RimParams;
// The terrain's source (shared/terrain.wgsl), evaluated at texel centres.
@group(0) @binding(1) var<storage, read> heightmap: array<f32>;
@group(0) @binding(2) var<storage, read> snow: array<f32>;
// Viewed as f32 words: texel t's height is word 2t (see normals.wgsl).
@group(0) @binding(3) var<storage, read_write> surface: array<f32>;
@group(0) @binding(4) var<storage, read> stamps: array<u32>;
@group(0) @binding(5) var<storage, read> fallen: array<f32>;
@group(0) @binding(6) var<uniform> terrain_params: TerrainParams;

const RIM_PEAK: f32 = 0.25;
// Snow within this of the rest height counts as undisturbed (grows rims).
const UNDISTURBED_M: f32 = 0.001;

fn hanak_cubic(x: f32) -> f32 {
    return ((-3.4766 * x + 6.508) * x - 2.231) * x + 0.215;
}

fn point_rim(st: u32, rest: f32) -> f32 {
    if st == STAMP_EMPTY {
        return 0.0;
    }
    let h = stamp_height(st >> 16u, params.low_m, params.high_m);
    let foot = stamp_height(st & 0xffffu, params.low_m, params.high_m);
    if foot >= rest || h <= rest {
        return 0.0;
    }
    let m = sqrt(rest - foot);
    let r = (sqrt(h - foot) - m) / m;
    var t: f32;
    if params.mode == 1u {
        t = 0.5 - 2.0 * r;
    } else {
        t = 2.0 * r - 1.0;
    }
    return max(1.0 - t * t, 0.0) * params.elevation * RIM_PEAK * (rest - foot);
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x;
    let i = gid.y;
    if i >= params.resolution || j >= params.resolution {
        return;
    }
    let s = storage_index(params.origin, params.resolution, i, j);
    let ground = texel_ground(terrain_params, params.origin + vec2<i32>(i32(j), i32(i)), params.texel_m);
    var depth = params.depth_m;
    if params.use_fallen != 0u {
        depth += fallen[s];
    }
    var out: f32;
    if depth <= 0.0 {
        // Bare ground (depth_m 0, no snowfall yet): no snow to remap or to
        // push into rims.
        out = snow[s];
    } else if params.mode == 0u {
        let x = clamp((snow[s] - ground) / depth, 0.0, 1.0);
        let remapped = x + params.elevation * (hanak_cubic(x) - x);
        out = ground + depth * max(remapped, 0.0);
    } else {
        let rest = ground + depth;
        out = snow[s];
        if out >= rest - UNDISTURBED_M {
            out += point_rim(stamps[s], rest);
        }
    }
    surface[2u * (i * params.resolution + j)] = out;
}
