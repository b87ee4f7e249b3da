// #import shared/capture_shapes

// Capture pass, analytic shapes, by compute: the lowest surface of every
// sphere swept over the frame (a capsule), tyre pose and box over each
// window texel's centre, as the capture depth's 16-bit code (depth linear in
// world height, 0 at low_m, 1 at high_m). No rasteriser and no depth target:
// each workgroup takes a 16x16-texel tile, keeps the shapes whose bounds
// reach it (read 128 at a time, each invocation testing one) in workgroup
// memory, and each invocation ray casts its two texels against that list.
// Texels are stored two a word (even column low), as 65535 minus the code,
// so 0 is "nothing captured" and untouched snow stays zero; update.wgsl
// reads them and takes the lower of them and the meshes' rasterised depth.
// CPU twin: src/cpu/capture_shapes.rs (capture_depths, shape_codes).

struct ShapeParams {
    texel_m: f32,
    low_m: f32,
    high_m: f32,
    resolution: u32,
    capsules: u32, // shapes [0, capsules) are capsules,
    wheels: u32,   // then this many tyre poses,
    boxes: u32,    // then this many boxes
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: ShapeParams;
// Per shape five vec4: its bounds (window-local x0, z0, x1, z1 in m), then
// a capsule's start (xyz, radius) and end, a tyre's 16-float instance
// (src/deform/wheel.rs, `instance`), or a box's inverse model matrix.
@group(0) @binding(1) var<storage, read> shapes: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> codes: array<u32>;

const SHAPE_VEC4S: u32 = 5u;
// Invocations per workgroup, and shapes tested per round.
const ROUND: u32 = 128u;
// A depth beyond the capture's range: nothing there.
const NONE: f32 = 2.0;

var<workgroup> listed: array<u32, 128>;
var<workgroup> listed_count: atomic<u32>;

// Shape k's capture depth over window-local point p (m), or NONE.
fn shape_depth(k: u32, p: vec2<f32>) -> f32 {
    let at = SHAPE_VEC4S * k + 1u;
    let range = params.high_m - params.low_m;
    if k < params.capsules {
        let a = shapes[at];
        let y = capsule_bottom(p, a.xyz, shapes[at + 1u].xyz, a.w);
        if y >= MISS {
            return NONE;
        }
        let d = (y - params.low_m) / range;
        if d <= 1.0 {
            return clamp(d, 0.0, 1.0);
        }
        return NONE;
    }
    if k < params.capsules + params.wheels {
        let center = shapes[at];
        let axle = shapes[at + 1u];
        let dx = p.x - center.x;
        let dz = p.y - center.z;
        let reach = sqrt(center.w * center.w + axle.w * axle.w);
        if abs(dx) > reach || abs(dz) > reach {
            return NONE;
        }
        let y = wheel_bottom(vec3(dx, 0.0, dz), axle.xyz, center.w, axle.w, shapes[at + 2u], shapes[at + 3u].x);
        if y >= MISS {
            return NONE;
        }
        let d = (center.y + y - params.low_m) / range;
        if d <= 1.0 {
            return clamp(d, 0.0, 1.0);
        }
        return NONE;
    }
    let inv = mat4x4<f32>(shapes[at], shapes[at + 1u], shapes[at + 2u], shapes[at + 3u]);
    let y = box_bottom(inv, p.x, p.y, params.low_m);
    if y >= MISS {
        return NONE;
    }
    let d = (y - params.low_m) / range;
    if d < 1.0 {
        return max(d, 0.0);
    }
    return NONE;
}

// A depth's stored half word: 65535 minus its 16-bit code (rounded to
// nearest; exact in f32 below 2^16), 0 for nothing.
fn stored(d: f32) -> u32 {
    if d >= 1.0 {
        return 0u;
    }
    return 65535u - u32(floor(d * 65535.0 + 0.5));
}

@compute @workgroup_size(8, 16)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>, @builtin(local_invocation_index) index: u32) {
    let half = params.resolution / 2u;
    let word = group.x * 8u + local.x;
    let row = group.y * 16u + local.y;
    let j = 2u * word;
    let t = params.texel_m;
    let z = (f32(row) + 0.5) * t;
    let p0 = vec2((f32(j) + 0.5) * t, z);
    let p1 = vec2((f32(j + 1u) + 0.5) * t, z);
    // The tile's texel centres, first and last.
    let lo = (vec2<f32>(group.xy * 16u) + 0.5) * t;
    let hi = (vec2<f32>(group.xy * 16u) + 15.5) * t;
    let inside = row < params.resolution && word < half;
    var best0 = 1.0;
    var best1 = 1.0;
    let total = params.capsules + params.wheels + params.boxes;
    for (var first = 0u; first < total; first += ROUND) {
        if index == 0u {
            atomicStore(&listed_count, 0u);
        }
        workgroupBarrier();
        let k = first + index;
        if k < total {
            let b = shapes[SHAPE_VEC4S * k];
            if b.z >= lo.x && b.x <= hi.x && b.w >= lo.y && b.y <= hi.y {
                listed[atomicAdd(&listed_count, 1u)] = k;
            }
        }
        // Every listing is in before any invocation reads the count.
        workgroupBarrier();
        let n = atomicLoad(&listed_count);
        if inside {
            for (var h = 0u; h < n; h++) {
                let s = listed[h];
                best0 = min(best0, shape_depth(s, p0));
                best1 = min(best1, shape_depth(s, p1));
            }
        }
        // Every invocation has read the list before the next round rewrites it.
        workgroupBarrier();
    }
    if inside {
        codes[row * half + word] = stored(best0) | (stored(best1) << 16u);
    }
}
