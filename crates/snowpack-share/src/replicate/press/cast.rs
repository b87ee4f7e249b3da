//! The capture's ray casts on the CPU: the lowest surface of a sphere swept
//! to a capsule, a tyre with its tread, or a box, along the vertical line
//! through a texel's centre, with the operations `capture_shapes.wgsl`
//! (snowpack's compute capture) uses, in the same order, so a machine
//! without a GPU presses what the GPU pressed ([`super::press_tiles`])
//! and snowpack's CPU twin of the pass checks the GPU against it.

use glam::{Mat4, Vec3};

/// Lowest height where the vertical line through `p` (x, z) meets the sphere
/// at `c` of radius `r`.
fn sphere_bottom(p: [f32; 2], c: [f32; 3], r: f32) -> Option<f32> {
    let (dx, dz) = (p[0] - c[0], p[1] - c[2]);
    let d2 = dx * dx + dz * dz;
    (d2 <= r * r).then(|| c[1] - (r * r - d2).sqrt())
}

/// Lowest height where the vertical line through `p` (x, z) meets the
/// capsule of radius `r` around the segment `a`..`b` (a swept sphere), as
/// `capture_sphere.wgsl` computes it: the lower of the end spheres and the
/// lateral cylinder where its hit projects inside the segment.
#[must_use]
pub fn capsule_bottom(p: [f32; 2], a: [f32; 3], b: [f32; 3], r: f32) -> Option<f32> {
    let ends = [sphere_bottom(p, a, r), sphere_bottom(p, b, r)];
    let mut best = ends.into_iter().flatten().reduce(f32::min);
    let (a, b) = (Vec3::from(a), Vec3::from(b));
    let axis = b - a;
    let len2 = axis.length_squared();
    if len2 < 1e-12 {
        return best;
    }
    let u = axis / len2.sqrt();
    let w0 = Vec3::new(p[0] - a.x, 0.0, p[1] - a.z);
    let wu = w0.dot(u);
    let qa = 1.0 - u.y * u.y;
    if qa < 1e-6 {
        return best;
    }
    let qb = w0.y - wu * u.y;
    let qc = w0.length_squared() - wu * wu - r * r;
    let disc = qb * qb - qa * qc;
    if disc < 0.0 {
        return best;
    }
    let y = (-qb - disc.sqrt()) / qa;
    let t = (wu + y * u.y) / len2.sqrt();
    if (0.0..=1.0).contains(&t) {
        best = Some(best.map_or(a.y + y, |v| v.min(a.y + y)));
    }
    best
}

/// Height above the centre where the vertical line through `w` (relative to
/// the centre, `w.y = 0`) enters the cylinder of radius `r` and half width
/// `hw` around the unit axle `a` (`capture_wheel.wgsl`, `cylinder_entry`).
fn cylinder_entry(w: Vec3, a: Vec3, r: f32, hw: f32) -> Option<f32> {
    let wa = w.dot(a);
    let (mut lo, mut hi) = (f32::NEG_INFINITY, f32::INFINITY);
    if a.y.abs() < 1e-6 {
        if wa.abs() > hw {
            return None;
        }
    } else {
        let (t0, t1) = ((-hw - wa) / a.y, (hw - wa) / a.y);
        (lo, hi) = (t0.min(t1), t0.max(t1));
    }
    let qa = 1.0 - a.y * a.y;
    let qc = w.length_squared() - wa * wa - r * r;
    if qa < 1e-6 {
        if qc > 0.0 {
            return None;
        }
    } else {
        let qb = -wa * a.y;
        let disc = qb * qb - qa * qc;
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        lo = lo.max((-qb - s) / qa);
        hi = hi.min((-qb + s) / qa);
    }
    (lo <= hi).then_some(lo)
}

/// Whether the tyre point `q` (relative to the centre) of wheel instance `w`
/// lies on a lug (`capture_wheel.wgsl`, `on_lug`).
fn on_lug(q: Vec3, w: &[f32; 16]) -> bool {
    let a = Vec3::new(w[4], w[5], w[6]);
    let (r, roll, spacing, pattern, fraction) = (w[3], w[8], w[9], (w[11] + 0.5) as u32, w[12]);
    if pattern == 0 {
        return true;
    }
    let fwd_raw = a.cross(Vec3::Y);
    if fwd_raw.length_squared() < 1e-12 {
        return true;
    }
    let fwd = fwd_raw.normalize();
    let down = (Vec3::NEG_Y + a.y * a).normalize();
    let along = q.dot(a);
    let perp = q - along * a;
    let mut s = roll + r * perp.dot(fwd).atan2(perp.dot(down));
    if pattern == 1 {
        if along < 0.0 {
            s += 0.5 * spacing;
        }
    } else {
        s += along.abs();
    }
    let phase = s / spacing;
    phase - phase.floor() < fraction
}

/// Lowest height, relative to the wheel's centre, of the tyre of wheel
/// instance `w` ([`super::wheel::instance`]) along the vertical line
/// through `rel` (relative to the centre, `rel.y = 0`), tread included, as
/// `capture_wheel.wgsl` computes it: the outer cylinder where it is hit on a
/// lug, else the groove floor `depth` further in.
#[must_use]
pub fn wheel_bottom(rel: Vec3, w: &[f32; 16]) -> Option<f32> {
    let a = Vec3::new(w[4], w[5], w[6]);
    let outer = cylinder_entry(rel, a, w[3], w[7])?;
    if on_lug(rel + Vec3::new(0.0, outer, 0.0), w) {
        return Some(outer);
    }
    cylinder_entry(rel, a, w[3] - w[10], w[7])
}

/// Lowest world height where the vertical line through (x, z) meets the unit
/// cube mapped by the inverse model matrix `inv`.
pub fn lowest_box_hit(inv: &Mat4, x: f32, z: f32, low: f32) -> Option<f32> {
    let o = inv.transform_point3(Vec3::new(x, low, z));
    let d = inv.transform_vector3(Vec3::Y);
    let (mut t0, mut t1) = (f32::NEG_INFINITY, f32::INFINITY);
    for axis in 0..3 {
        let (oa, da) = (o[axis], d[axis]);
        if da.abs() < 1e-12 {
            if oa.abs() > 1.0 {
                return None;
            }
            continue;
        }
        let (a, b) = ((-1.0 - oa) / da, (1.0 - oa) / da);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1 && t1 >= 0.0).then_some(low + t0)
}

/// The capture depth (0..1; 1 where nothing is) at window-local point `p`
/// (x, z) of the lowest of the shapes: capsules `[ax, ay, az, r, bx, by,
/// bz, 0]`, tyre poses ([`super::wheel::instance`]) and boxes (inverse
/// model matrices), for a capture whose depth 0 is at `low` and 1 at
/// `low + range` (m): a shape's depth is clamped to 0..1, and one above
/// the range misses.
#[must_use]
pub fn lowest_depth(
    (capsules, wheels, boxes): (impl Iterator<Item = [f32; 8]>, impl Iterator<Item = [f32; 16]>, impl Iterator<Item = Mat4>),
    p: [f32; 2],
    low: f32,
    range: f32,
) -> f32 {
    let [x, z] = p;
    let mut best = 1.0_f32;
    for c in capsules {
        let Some(y) = capsule_bottom([x, z], [c[0], c[1], c[2]], [c[4], c[5], c[6]], c[3]) else { continue };
        let d = (y - low) / range;
        if d <= 1.0 {
            best = best.min(d.clamp(0.0, 1.0));
        }
    }
    for w in wheels {
        let (dx, dz) = (x - w[0], z - w[2]);
        let reach = w[3].hypot(w[7]);
        if dx.abs() > reach || dz.abs() > reach {
            continue;
        }
        let Some(y) = wheel_bottom(Vec3::new(dx, 0.0, dz), &w) else { continue };
        let d = (w[1] + y - low) / range;
        if d <= 1.0 {
            best = best.min(d.clamp(0.0, 1.0));
        }
    }
    for inv in boxes {
        if let Some(y) = lowest_box_hit(&inv, x, z, low) {
            let d = (y - low) / range;
            if d < 1.0 {
                best = best.min(d.max(0.0));
            }
        }
    }
    best
}
