// Stamp pass (deferred point deformation): one workgroup per contact point
// writes the footprint h = foot + d^2 * scale over a range x range texel
// square around it into the toroidal stamp buffer with atomicMin, so the
// result does not depend on the order points run in. The update pass takes
// the lower of this and the persistent snow; the rim pass raises rims from
// the stored foot height. CPU twin: src/cpu/stamp.rs.

struct StampParams {
    origin: vec2<i32>,
    resolution: u32,
    range_texels: u32,
    texel_m: f32,
    low_m: f32,
    high_m: f32,
    count: u32,
}

@group(0) @binding(0) var<uniform> params: StampParams;
// Per point: window-local x (m), foot height (m), window-local z (m), scale (1/m).
@group(0) @binding(1) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> stamps: array<atomic<u32>>;

const SIDE: u32 = 8u;

@compute @workgroup_size(8, 8)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let k = wg.x + wg.y * 65535u;
    if k >= params.count {
        return;
    }
    let p = points[k];
    let res = i32(params.resolution);
    let range = i32(params.range_texels);
    // The square's first texel: range / 2 texels before the point's texel.
    let i0 = i32(floor(p.z / params.texel_m)) - range / 2;
    let j0 = i32(floor(p.x / params.texel_m)) - range / 2;
    let foot = stamp_quantise(p.y, params.low_m, params.high_m);
    for (var di = i32(lid.y); di < range; di += i32(SIDE)) {
        let i = i0 + di;
        if i < 0 || i >= res {
            continue;
        }
        let dz = (f32(i) + 0.5) * params.texel_m - p.z;
        for (var dj = i32(lid.x); dj < range; dj += i32(SIDE)) {
            let j = j0 + dj;
            if j < 0 || j >= res {
                continue;
            }
            let dx = (f32(j) + 0.5) * params.texel_m - p.x;
            let h = p.y + (dx * dx + dz * dz) * p.w;
            let packed = (stamp_quantise(h, params.low_m, params.high_m) << 16u) | foot;
            let s = storage_index(params.origin, params.resolution, u32(i), u32(j));
            atomicMin(&stamps[s], packed);
        }
    }
}
