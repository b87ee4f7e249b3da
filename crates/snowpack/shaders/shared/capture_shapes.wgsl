// The analytic shapes the capture ray casts from below (capture_shapes.wgsl):
// where the vertical line through a texel centre first meets a sphere swept
// over the frame (a capsule), a tyre with its tread, or a box. Each returns
// a height, MISS when the line misses. CPU twin: the same functions in
// snowpack-testkit's cpu/capture_shapes.rs, operation for operation.

const MISS: f32 = 3.0e38;

// Lowest height where the vertical line through `p` (x, z) meets the sphere
// at `c` of radius r; MISS when it misses.
fn sphere_bottom(p: vec2<f32>, c: vec3<f32>, r: f32) -> f32 {
    let d = p - c.xz;
    let d2 = dot(d, d);
    if d2 > r * r {
        return MISS;
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
    let t = (wu + y * u.y) / sqrt(len2); // projection onto the segment, 0..1 inside
    if t >= 0.0 && t <= 1.0 {
        best = min(best, a.y + y);
    }
    return best;
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

// Lowest height where the vertical line through (x, z) meets the unit cube
// under the inverse model matrix `inv` (a box, window-local): the slab test
// along the line's direction in cube space, from the capture's low height.
fn box_bottom(inv: mat4x4<f32>, x: f32, z: f32, low: f32) -> f32 {
    // In glam's order (Mat4::transform_point3), so the twin rounds alike.
    let o = ((inv[0].xyz * x + inv[1].xyz * low) + inv[2].xyz * z) + inv[3].xyz;
    let d = inv[1].xyz;
    var t0 = -MISS;
    var t1 = MISS;
    for (var axis = 0u; axis < 3u; axis++) {
        let oa = o[axis];
        let da = d[axis];
        if abs(da) < 1e-12 {
            if abs(oa) > 1.0 {
                return MISS;
            }
            continue;
        }
        let a = (-1.0 - oa) / da;
        let b = (1.0 - oa) / da;
        t0 = max(t0, min(a, b));
        t1 = min(t1, max(a, b));
    }
    if t0 <= t1 && t1 >= 0.0 {
        return low + t0;
    }
    return MISS;
}
