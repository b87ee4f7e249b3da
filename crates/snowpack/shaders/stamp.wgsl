// #import shared/window
// #import shared/stamp
// #import shared/share_flags

// Stamp pass (deferred point deformation): one workgroup per contact point
// writes the footprint h = foot + d^2 * scale over a range x range texel
// square around it into the toroidal stamp buffer with atomicMin, so the
// result does not depend on the order points run in. A point swept over the
// frame moved from p0 to p1 (foot heights included): its footprint is the
// lowest of the paraboloids along the segment, per texel at the t that
// minimises foot(t) + |q - p(t)|^2 scale (a quadratic in t, solved exactly),
// over the squares around both ends and between them. The update pass takes
// the lower of this and the persistent snow; the rim pass raises rims from
// the stored foot height. With shared snow (share_side > 0) a texel whose
// footprint this lowers flags its tile (shared/share_flags.wgsl): footprints
// are shared state, and a rim-only footprint changes no deficit, so the
// update pass cannot see it. CPU twin: src/cpu/stamp.rs.

struct StampParams {
    origin: vec2<i32>,
    resolution: u32,
    range_texels: u32,
    texel_m: f32,
    low_m: f32,
    high_m: f32,
    count: u32,
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution (storage_index_wrapped)
    share_side: u32, // changed-tile flags' tile side; 0: no flags
    share_keys: u32, // slots per side of the flags (shared/share_flags.wgsl)
}

@group(0) @binding(0) var<uniform> params: StampParams;
// Per point, two vec4: (window-local x (m), foot height (m), window-local z
// (m), scale (1/m)) where it ended this frame, then (x, foot, z, 0) where it
// started (the same for a point that is not swept).
@group(0) @binding(1) var<storage, read> points: array<vec4<f32>>;
@group(1) @binding(3) var<storage, read_write> stamps: array<atomic<u32>>;
@group(0) @binding(2) var<storage, read_write> share_flags: array<atomic<u32>>;

const SIDE: u32 = 8u;

@compute @workgroup_size(8, 8)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let k = wg.x + wg.y * 65535u;
    if k >= params.count {
        return;
    }
    let p1 = points[2u * k];
    let p0 = points[2u * k + 1u];
    let scale = p1.w;
    let res = i32(params.resolution);
    let range = i32(params.range_texels);
    // The squares' first texels: range / 2 texels before either end's texel.
    let i0 = i32(floor(min(p0.z, p1.z) / params.texel_m)) - range / 2;
    let j0 = i32(floor(min(p0.x, p1.x) / params.texel_m)) - range / 2;
    let rows = i32(floor(max(p0.z, p1.z) / params.texel_m)) - range / 2 + range - i0;
    let cols = i32(floor(max(p0.x, p1.x) / params.texel_m)) - range / 2 + range - j0;
    let travel = p1.xz - p0.xz;
    let climb = p1.y - p0.y;
    let qa = scale * dot(travel, travel);
    for (var di = i32(lid.y); di < rows; di += i32(SIDE)) {
        let i = i0 + di;
        if i < 0 || i >= res {
            continue;
        }
        for (var dj = i32(lid.x); dj < cols; dj += i32(SIDE)) {
            let j = j0 + dj;
            if j < 0 || j >= res {
                continue;
            }
            let q = (vec2(f32(j), f32(i)) + 0.5) * params.texel_m;
            // foot(t) + |q - p(t)|^2 scale = c + qb t + qa t^2, lowest at t.
            let qb = climb - 2.0 * scale * dot(q - p0.xz, travel);
            var t = 1.0;
            if qa > 1e-12 {
                t = clamp(-qb / (2.0 * qa), 0.0, 1.0);
            } else if qb > 0.0 {
                t = 0.0;
            }
            let at = p0.xz + t * travel;
            let foot_h = p0.y + t * climb;
            let dx = q.x - at.x;
            let dz = q.y - at.y;
            let h = foot_h + (dx * dx + dz * dz) * scale;
            let packed = (stamp_quantise(h, params.low_m, params.high_m) << 16u) | stamp_quantise(foot_h, params.low_m, params.high_m);
            let s = storage_index_wrapped(params.storage_origin, params.resolution, u32(i), u32(j));
            let old = atomicMin(&stamps[s], packed);
            // The texel's test first (a branch on a uniform alone has Mesa
            // 22's lavapipe compile this shader again at every dispatch).
            if packed < old && params.share_side != 0u {
                atomicStore(&share_flags[share_slot(params.origin + vec2<i32>(j, i), params.share_side, params.share_keys)], 1u);
            }
        }
    }
}
