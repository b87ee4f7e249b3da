// #import shared/objects

// Settle pass: the frame's increment blurred 5x5 (Dinh's Gaussian weights,
// renormalised over the texels of the same object), added to the
// accumulation, then Dinh's stability (eq. 4.3): a surface whose world normal
// n makes an angle with up beyond the angle of repose holds nothing (its snow
// slides off at once); of the new snow, a fraction t sticks, t ramping from 0
// at the angle of repose to 1 ten degrees inside it (so a dome's snow cap
// thins to its edge instead of ending in a cliff on the texel grid); a
// surface holds up to c = m * n.y and snow above that falls off gradually,
//   a <- a - (a - c) * f,   f = 1 - exp(-falloff * dt).
// CPU twin: src/cpu/settle.rs.

struct SettleParams {
    atlas_resolution: u32,
    max_m: f32,
    cos_repose: f32,
    falloff: f32,
    cos_full: f32,   // cosine of (repose - 10 degrees): full capacity from here up
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: SettleParams;
@group(0) @binding(1) var<storage, read> objects: array<ObjectGpu>;
@group(0) @binding(2) var<storage, read> normal_area: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> owner: array<u32>;
@group(0) @binding(4) var<storage, read> fresh: array<f32>;
@group(0) @binding(5) var<storage, read_write> acc: array<f32>;

const WEIGHTS = array<f32, 3>(0.2270270270, 0.1945945946, 0.1216216216);

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.atlas_resolution;
    if gid.x >= n || gid.y >= n {
        return;
    }
    let k = gid.y * n + gid.x;
    let own = owner[k];
    if own == NO_OWNER {
        acc[k] = 0.0;
        return;
    }
    var sum = 0.0;
    var weight = 0.0;
    for (var dy = -2; dy <= 2; dy++) {
        for (var dx = -2; dx <= 2; dx++) {
            let x = i32(gid.x) + dx;
            let y = i32(gid.y) + dy;
            if x < 0 || y < 0 || x >= i32(n) || y >= i32(n) {
                continue;
            }
            let m = u32(y) * n + u32(x);
            if owner[m] != own {
                continue;
            }
            let w = WEIGHTS[abs(dx)] * WEIGHTS[abs(dy)];
            sum += w * fresh[m];
            weight += w;
        }
    }
    let up = (objects[own].rotation * vec4<f32>(normal_area[k].xyz, 0.0)).y;
    var a = 0.0;
    if up >= params.cos_repose {
        let t = clamp((up - params.cos_repose) / max(params.cos_full - params.cos_repose, 1e-6), 0.0, 1.0);
        a = acc[k] + t * sum / weight;
        let cap = params.max_m * up;
        if a > cap {
            a -= (a - cap) * params.falloff;
        }
    }
    acc[k] = max(a, 0.0);
}
