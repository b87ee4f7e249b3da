//! CPU twin of the capture pass's wheels (`capture_wheel.wgsl`): the tyre's
//! lowest surface along a vertical line, tread included, as the shader's
//! fragments compute it ([`super::capture_sphere::capture_depths`] places
//! the wheels).

use glam::Vec3;

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
/// instance `w` ([`snowpack::low_level::deform::wheel::instance`]) along the vertical line
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
