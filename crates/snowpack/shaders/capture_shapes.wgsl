// #import shared/capture_shapes

// Capture pass, analytic shapes, by compute: the lowest surface of every
// sphere swept over the frame (a capsule), tyre pose and box over each
// window texel's centre, as the capture depth's 16-bit code (depth linear in
// world height, 0 at low_m, 1 at high_m). No rasteriser and no depth target.
// The CPU bins the shapes into the window's 16x16-texel tiles (by their
// bounds, half a texel wider than the shape); the capture buffer is cleared
// to "nothing" (0) first, and one workgroup runs per tile that holds a
// shape, each invocation ray casting its two texels against that tile's
// list only. Texels are stored two a word (even column low), as 65535 minus
// the code, so 0 is "nothing captured"; update.wgsl reads them and takes the
// lower of them and the meshes' rasterised depth.
// CPU twin: src/cpu/capture_shapes.rs (capture_depths, shape_codes).

struct ShapeParams {
    texel_m: f32,
    low_m: f32,
    high_m: f32,
    resolution: u32,
    capsules: u32, // shapes [0, capsules) are capsules,
    wheels: u32,   // then this many tyre poses, then boxes
    row: u32,      // workgroups per row of the dispatch
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: ShapeParams;
// One upload a frame: a header (the tiles holding a shape, where the bins
// start, in words; two more words), the shapes, the bins. Per shape its
// bounds (window-local x0, z0, x1, z1 in m: where it can capture anything),
// then a capsule's start (xyz, radius) and end (three vec4 in all), a tyre's
// 16-float instance (src/deform/wheel.rs, `instance`) or a box's inverse
// model matrix (five): `shape_at`. The bins: per tile holding a shape, four
// words (its column and row in tiles, its first entry and its count,
// entries counted from the bins' start), then the entries, each a shape's
// index.
@group(0) @binding(1) var<storage, read> list: array<u32>;
// The same buffer as vec4s: the shapes' data, read a vec4 at a time.
@group(0) @binding(2) var<storage, read> list_vec4: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> codes: array<u32>;

// The i-th vec4 of shape data (after the header).
fn shape_vec(i: u32) -> vec4<f32> {
    return list_vec4[1u + i];
}

// A depth beyond the capture's range: nothing there.
const NONE: f32 = 2.0;

// Where shape k starts in `shapes`: capsules take three vec4, the others five.
fn shape_at(k: u32) -> u32 {
    if k < params.capsules {
        return 3u * k;
    }
    return 3u * params.capsules + 5u * (k - params.capsules);
}

// Shape k's capture depth over window-local point p (m), or NONE.
fn shape_depth(k: u32, p: vec2<f32>) -> f32 {
    let first = shape_at(k);
    let b = shape_vec(first);
    if p.x < b.x || p.y < b.y || p.x > b.z || p.y > b.w {
        return NONE;
    }
    let at = first + 1u;
    let range = params.high_m - params.low_m;
    if k < params.capsules {
        let a = shape_vec(at);
        let y = capsule_bottom(p, a.xyz, shape_vec(at + 1u).xyz, a.w);
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
        let center = shape_vec(at);
        let axle = shape_vec(at + 1u);
        let dx = p.x - center.x;
        let dz = p.y - center.z;
        let reach = sqrt(center.w * center.w + axle.w * axle.w);
        if abs(dx) > reach || abs(dz) > reach {
            return NONE;
        }
        let y = wheel_bottom(vec3(dx, 0.0, dz), axle.xyz, center.w, axle.w, shape_vec(at + 2u), shape_vec(at + 3u).x);
        if y >= MISS {
            return NONE;
        }
        let d = (center.y + y - params.low_m) / range;
        if d <= 1.0 {
            return clamp(d, 0.0, 1.0);
        }
        return NONE;
    }
    let inv = mat4x4<f32>(shape_vec(at), shape_vec(at + 1u), shape_vec(at + 2u), shape_vec(at + 3u));
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
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>) {
    let tile = group.y * params.row + group.x;
    if tile >= list[0] {
        return;
    }
    let bins = list[1];
    let record = bins + 4u * tile;
    let word = list[record] * 8u + local.x;
    let row = list[record + 1u] * 16u + local.y;
    let first = bins + list[record + 2u];
    let count = list[record + 3u];
    let j = 2u * word;
    let t = params.texel_m;
    let z = (f32(row) + 0.5) * t;
    let p0 = vec2((f32(j) + 0.5) * t, z);
    let p1 = vec2((f32(j + 1u) + 0.5) * t, z);
    var best0 = 1.0;
    var best1 = 1.0;
    for (var h = 0u; h < count; h++) {
        let s = list[first + h];
        best0 = min(best0, shape_depth(s, p0));
        best1 = min(best1, shape_depth(s, p1));
    }
    codes[row * (params.resolution / 2u) + word] = stored(best0) | (stored(best1) << 16u);
}
