// Rim pass: the displayed height before blur, in window-local order.
// Hanák's cubic remap (eq. 4.1), f(x) = -3.4766x^3 + 6.508x^2 - 2.231x + 0.215,
// applied to the normalised snow depth x and blended in by `elevation`:
//   shown = terrain + depth * (x + elevation * (f(x) - x)).
// CPU twin: src/cpu/rim.rs.

struct RimParams {
    origin: vec2<i32>,
    resolution: u32,
    depth_m: f32,
    elevation: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: RimParams;
@group(0) @binding(1) var<storage, read> terrain: array<f32>;
@group(0) @binding(2) var<storage, read> snow: array<f32>;
@group(0) @binding(3) var<storage, read_write> shown: array<f32>;

fn hanak_cubic(x: f32) -> f32 {
    return ((-3.4766 * x + 6.508) * x - 2.231) * x + 0.215;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x;
    let i = gid.y;
    if i >= params.resolution || j >= params.resolution {
        return;
    }
    let s = storage_index(params.origin, params.resolution, i, j);
    let ground = terrain[s];
    let x = clamp((snow[s] - ground) / params.depth_m, 0.0, 1.0);
    let remapped = x + params.elevation * (hanak_cubic(x) - x);
    shown[i * params.resolution + j] = ground + params.depth_m * max(remapped, 0.0);
}
