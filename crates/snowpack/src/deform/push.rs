//! Which way a moving box pushes snow (displacement, `docs/mechanics.md`):
//! a blade or a crate's flat underside tells the capture nothing of its
//! travel, and a thin blade has open snow on both sides, so the update
//! sends what such a box takes along the face that leads its motion. The
//! CPU finds, for each box that moved this frame, its footprint (grown by
//! the motion) and that face's normal, window-local; the update reads them
//! from its uniform (`UpdateParams::pushers`).

use glam::{DVec2, Quat, Vec2, Vec3};

use super::shape::Deformer;

/// Boxes whose push the update knows in a frame; others push by the rise
/// of the capture alone.
pub const MOST_PUSHERS: usize = 8;

/// One pusher as the update reads it: `[centre x, centre z, axis x, axis z]`
/// and `[half extent along the axis, half extent across, push x, push z]`,
/// window-local metres, the footprint grown by the frame's motion and two
/// texels; an unused one has half extents of -1e9 (nothing is inside).
pub type Pusher = [[f32; 4]; 2];

/// No pusher.
pub const NO_PUSHER: Pusher = [[0.0; 4], [-1.0e9, -1.0e9, 0.0, 0.0]];

/// The pushers of this frame's `deformers` swept from `previous` (the
/// boxes that moved across the ground, at most `MOST_PUSHERS`), relative
/// to the window's corner (world x, z), with `texel_m` texels.
#[must_use]
pub fn pushers(deformers: &[Deformer], previous: &[Option<Deformer>], corner: DVec2, texel_m: f32) -> [Pusher; MOST_PUSHERS] {
    let mut out = [NO_PUSHER; MOST_PUSHERS];
    let found = deformers.iter().zip(previous).filter_map(|(now, before)| match (*now, *before) {
        (Deformer::Box { center, half_extents, rotation }, Some(Deformer::Box { center: was, .. })) => {
            pusher(center, half_extents, rotation, center - was, corner, texel_m)
        }
        _ => None,
    });
    for (slot, p) in out.iter_mut().zip(found) {
        *slot = p;
    }
    out
}

/// The pusher of a box at `center` that moved by `motion` this frame, or
/// `None` when it did not move across the ground. It pushes along the
/// normal of the vertical face that sweeps the most ground: the face's
/// width times how squarely it meets the motion.
fn pusher(center: Vec3, half: Vec3, rotation: Quat, motion: Vec3, corner: DVec2, texel_m: f32) -> Option<Pusher> {
    let m = Vec2::new(motion.x, motion.z);
    if m.length() < 1e-5 {
        return None;
    }
    let flat = |v: Vec3| Vec2::new(v.x, v.z);
    let (ax, az) = (flat(rotation * Vec3::X), flat(rotation * Vec3::Z));
    // Half extents of the footprint along the box's own horizontal axes (upright boxes: a blade, a crate).
    let (hx, hz) = (half.x * ax.length(), half.z * az.length());
    let (ax, az) = (ax.try_normalize()?, az.try_normalize()?);
    // The x faces are 2 hz wide and meet the motion by |ax . m|; the z faces 2 hx wide by |az . m|.
    let normal = if hz * ax.dot(m).abs() > hx * az.dot(m).abs() { ax } else { az };
    let push = normal * normal.dot(m).signum();
    let grow = m.length() + 2.0 * texel_m;
    let c = [(f64::from(center.x) - corner.x) as f32, (f64::from(center.z) - corner.y) as f32];
    Some([[c[0], c[1], ax.x, ax.y], [hx + grow, hz + grow, push.x, push.y]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_blade_pushes_along_its_face_and_a_still_box_not_at_all() {
        let blade = Deformer::blade(Vec3::new(3.0, 0.0, 2.0), Vec3::X, 30.0, (2.5, 0.8));
        let Deformer::Box { center, half_extents, rotation } = blade else { unreachable!() };
        let before = Deformer::Box { center: center - Vec3::new(0.05, 0.0, 0.0), half_extents, rotation };
        let p = pushers(&[blade, blade], &[Some(before), Some(blade)], DVec2::new(1.0, 1.0), 0.0625);
        let face = Quat::from_rotation_y(30f32.to_radians()) * Vec3::X;
        assert!((p[0][1][2] - face.x).abs() < 1e-5 && (p[0][1][3] - face.z).abs() < 1e-5, "{p:?}");
        assert!((p[0][0][0] - 2.0).abs() < 1e-5 && (p[0][0][1] - 1.0).abs() < 1e-5);
        // The second did not move: no pusher.
        assert_eq!(p[1], NO_PUSHER);
    }
}
