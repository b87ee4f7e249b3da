// Capture pass, spheres swept over the frame: an orthographic view from below
// the terrain looking up. Each sphere moved from `a` (last frame) to `b` (this
// frame), so what it pressed is the capsule of radius r around the segment ab
// (a sphere that did not move, or was not swept, has a == b). Each capsule is
// a quad over its footprint (the stadium of the segment's shadow, widened by
// r) whose fragments write the capsule's analytic lower surface as depth, so
// the captured height is exact: no tessellation and no sub-steps.
// CPU twin: src/cpu/capture_sphere.rs (capsule_bottom).

struct CaptureParams {
    extent_m: f32,
    texel_m: f32,
    low_m: f32,   // world height at depth 0
    high_m: f32,  // world height at depth 1
}

@group(0) @binding(0) var<uniform> params: CaptureParams;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) a: vec4<f32>, // window-local start xyz, radius
    @location(1) @interpolate(flat) b: vec4<f32>, // window-local end xyz
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32, @location(0) a: vec4<f32>, @location(1) b: vec4<f32>) -> VertexOut {
    // Two triangles over the square [-1, 1]^2, stretched along the motion.
    var corners = array<vec2<f32>, 6>(
        vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
        vec2(-1.0, -1.0), vec2(1.0, 1.0), vec2(-1.0, 1.0),
    );
    let c = corners[vertex];
    let r = a.w;
    let travel = b.xz - a.xz;
    let len = length(travel);
    var along = vec2(1.0, 0.0);
    if len > 1e-6 {
        along = travel / len;
    }
    let across = vec2(-along.y, along.x);
    let mid = 0.5 * (a.xz + b.xz);
    // Half a texel more on every side: the quad must cover every texel
    // centre inside the footprint whatever the rasteriser's rounding.
    let pad = 0.5 * params.texel_m;
    let local = mid + along * c.x * (0.5 * len + r + pad) + across * c.y * (r + pad);
    var out: VertexOut;
    out.position = vec4(local.x / params.extent_m * 2.0 - 1.0, 1.0 - local.y / params.extent_m * 2.0, 0.0, 1.0);
    out.a = a;
    out.b = b;
    return out;
}

// Lowest height where the vertical line through `p` (x, z) meets the sphere
// at `c` of radius r; a large value when it misses.
fn sphere_bottom(p: vec2<f32>, c: vec3<f32>, r: f32) -> f32 {
    let d = p - c.xz;
    let d2 = dot(d, d);
    if d2 > r * r {
        return 3.0e38;
    }
    return c.y - sqrt(r * r - d2);
}

// Lowest height where the vertical line through `p` meets the capsule of
// radius r around the segment a..b: the lower of the end spheres and the
// lateral cylinder where its hit projects inside the segment (a convex
// union: the first entry is the lowest entry into any part).
fn capsule_bottom(p: vec2<f32>, a: vec3<f32>, b: vec3<f32>, r: f32) -> f32 {
    var best = min(sphere_bottom(p, a, r), sphere_bottom(p, b, r));
    let axis = b - a;
    let len2 = dot(axis, axis);
    if len2 < 1e-12 {
        return best;
    }
    let u = axis / sqrt(len2);
    // Points a + w0 + y e_y at distance r from the axis line:
    // y^2 (1 - uy^2) + 2 y (w0y - (w0.u) uy) + |w0|^2 - (w0.u)^2 - r^2 = 0.
    let w0 = vec3(p.x - a.x, 0.0, p.y - a.z);
    let wu = dot(w0, u);
    let qa = 1.0 - u.y * u.y;
    if qa < 1e-6 {
        return best; // a vertical axis: the line enters through an end sphere
    }
    let qb = w0.y - wu * u.y;
    let qc = dot(w0, w0) - wu * wu - r * r;
    let disc = qb * qb - qa * qc;
    if disc < 0.0 {
        return best;
    }
    let y = (-qb - sqrt(disc)) / qa; // height above a.y
    let t = (wu + y * u.y) * inverseSqrt(len2); // projection onto the segment, 0..1 inside
    if t >= 0.0 && t <= 1.0 {
        best = min(best, a.y + y);
    }
    return best;
}

struct FragmentOut {
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    // Framebuffer pixel (j + 0.5, i + 0.5) is the centre of window texel (i, j).
    let p = in.position.xy * params.texel_m;
    let bottom = capsule_bottom(p, in.a.xyz, in.b.xyz, in.a.w);
    if bottom > 1.0e38 {
        discard;
    }
    let depth = (bottom - params.low_m) / (params.high_m - params.low_m);
    if depth > 1.0 {
        discard;
    }
    var out: FragmentOut;
    out.depth = clamp(depth, 0.0, 1.0);
    return out;
}
