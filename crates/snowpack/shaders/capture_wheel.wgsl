// Capture pass, wheels: an orthographic view from below the terrain looking
// up. Each instance is one pose of a tyre (a wheel swept over the frame is
// drawn once per sub-step): a cylinder of outer radius r and half width w
// around its axle, with a tread of raised lugs (surface at r) and grooves
// between them (at r - depth). A quad over the tyre's footprint writes the
// lowest surface along each texel centre's vertical line as depth, exactly:
// no tessellation. CPU twin: src/cpu/capture_wheel.rs (wheel_bottom); the tread
// coordinates are documented in src/deform/wheel.rs.

struct CaptureParams {
    extent_m: f32,
    texel_m: f32,
    low_m: f32,   // world height at depth 0
    high_m: f32,  // world height at depth 1
}

@group(0) @binding(0) var<uniform> params: CaptureParams;

const MISS: f32 = 3.0e38;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) center: vec4<f32>, // window-local centre, outer radius
    @location(1) @interpolate(flat) axle: vec4<f32>,   // unit axle, half width
    @location(2) @interpolate(flat) tread: vec4<f32>,  // roll (m), spacing (m), lug depth (m), pattern
    @location(3) @interpolate(flat) extra: vec4<f32>,  // lug fraction
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32, @location(0) center: vec4<f32>, @location(1) axle: vec4<f32>, @location(2) tread: vec4<f32>, @location(3) extra: vec4<f32>) -> VertexOut {
    var corners = array<vec2<f32>, 6>(
        vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(1.0, 1.0),
        vec2(-1.0, -1.0), vec2(1.0, 1.0), vec2(-1.0, 1.0),
    );
    // A square around the centre that holds the tyre in any orientation,
    // half a texel wider so every texel centre under it is covered.
    let half = sqrt(center.w * center.w + axle.w * axle.w) + 0.5 * params.texel_m;
    let local = center.xz + corners[vertex] * half;
    var out: VertexOut;
    out.position = vec4(local.x / params.extent_m * 2.0 - 1.0, 1.0 - local.y / params.extent_m * 2.0, 0.0, 1.0);
    out.center = center;
    out.axle = axle;
    out.tread = tread;
    out.extra = extra;
    return out;
}

// Height above the centre where the vertical line through w (relative to
// the centre, w.y = 0) enters the cylinder of radius r and half width hw
// around the unit axle a; MISS when it does not meet it. The cylinder is the
// intersection of a slab (|q.a| <= hw) and an infinite cylinder, both
// convex: the entry is the later of their entries.
fn cylinder_entry(w: vec3<f32>, a: vec3<f32>, r: f32, hw: f32) -> f32 {
    let wa = dot(w, a);
    var lo = -MISS;
    var hi = MISS;
    if abs(a.y) < 1e-6 {
        if abs(wa) > hw {
            return MISS;
        }
    } else {
        let t0 = (-hw - wa) / a.y;
        let t1 = (hw - wa) / a.y;
        lo = min(t0, t1);
        hi = max(t0, t1);
    }
    // |q|^2 - (q.a)^2 <= r^2 with q = w + y e_y.
    let qa = 1.0 - a.y * a.y;
    let qc = dot(w, w) - wa * wa - r * r;
    if qa < 1e-6 {
        if qc > 0.0 {
            return MISS;
        }
    } else {
        let qb = -wa * a.y;
        let disc = qb * qb - qa * qc;
        if disc < 0.0 {
            return MISS;
        }
        let s = sqrt(disc);
        lo = max(lo, (-qb - s) / qa);
        hi = min(hi, (-qb + s) / qa);
    }
    if lo > hi {
        return MISS;
    }
    return lo;
}

// Whether the tyre point q (relative to the centre) lies on a lug.
fn on_lug(q: vec3<f32>, a: vec3<f32>, r: f32, tread: vec4<f32>, fraction: f32) -> bool {
    let pattern = u32(tread.w + 0.5);
    if pattern == 0u {
        return true;
    }
    let fwd_raw = cross(a, vec3(0.0, 1.0, 0.0));
    if dot(fwd_raw, fwd_raw) < 1e-12 {
        return true; // a wheel lying flat: its tread faces sideways
    }
    let fwd = normalize(fwd_raw);
    let down = normalize(vec3(0.0, -1.0, 0.0) + a.y * a);
    let along = dot(q, a);
    let perp = q - along * a;
    // Arc coordinate: roll plus the arc from the lowest point to q.
    var s = tread.x + r * atan2(dot(perp, fwd), dot(perp, down));
    let spacing = tread.y;
    if pattern == 1u {
        // Blocks: two rows, staggered by half a spacing.
        if along < 0.0 {
            s = s + 0.5 * spacing;
        }
    } else {
        // Chevron: the lug's arc position shifts with the distance from the centre line.
        s = s + abs(along);
    }
    let phase = s / spacing;
    return phase - floor(phase) < fraction;
}

// Lowest height (relative to the centre) of the tyre along the vertical line through w.
fn wheel_bottom(w: vec3<f32>, a: vec3<f32>, r: f32, hw: f32, tread: vec4<f32>, fraction: f32) -> f32 {
    let outer = cylinder_entry(w, a, r, hw);
    if outer >= MISS {
        return MISS;
    }
    if on_lug(w + vec3(0.0, outer, 0.0), a, r, tread, fraction) {
        return outer;
    }
    return cylinder_entry(w, a, r - tread.z, hw);
}

struct FragmentOut {
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    // Framebuffer pixel (j + 0.5, i + 0.5) is the centre of window texel (i, j).
    let p = in.position.xy * params.texel_m;
    let w = vec3(p.x - in.center.x, 0.0, p.y - in.center.z);
    let y = wheel_bottom(w, in.axle.xyz, in.center.w, in.axle.w, in.tread, in.extra.x);
    if y >= MISS {
        discard;
    }
    let depth = (in.center.y + y - params.low_m) / (params.high_m - params.low_m);
    if depth > 1.0 {
        discard;
    }
    var out: FragmentOut;
    out.depth = clamp(depth, 0.0, 1.0);
    return out;
}
