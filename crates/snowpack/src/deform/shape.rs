//! Shapes that press into the snow (the "deformers" drawn by the capture pass).

use glam::{Mat4, Quat, Vec3};

/// One object that deforms the snow this frame, in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Deformer {
    /// A sphere; captured exactly (its analytic lower surface is ray cast at each texel centre).
    Sphere {
        /// Centre in world space (m).
        center: Vec3,
        /// Radius (m).
        radius: f32,
    },
    /// An oriented box; captured exactly (ray cast against its faces at each texel centre).
    Box {
        /// Centre in world space (m).
        center: Vec3,
        /// Half the box's size along its local axes (m).
        half_extents: Vec3,
        /// Orientation of the box's local axes.
        rotation: Quat,
    },
    /// A contact point of the points technique (a foot, a paw): its footprint
    /// is `h = position.y + d^2 * scale_per_m`. The depth technique ignores it.
    Point {
        /// The foot's lowest point in world space (m).
        position: Vec3,
        /// Curvature of the footprint (1/m): `1 / 2r` matches a sphere of radius r.
        scale_per_m: f32,
    },
    /// A wheel: a cylinder with a tread, rolling about its axle (see
    /// `super::wheel`). Captured exactly (the lower surface of the tyre,
    /// lugs included, is ray cast at each texel centre); swept in sub-steps with its roll,
    /// so a rolling wheel prints its tread in place and a slipping one
    /// smears it.
    Wheel {
        /// Centre of the wheel (on its axle, midway across its width) in world space (m).
        center: Vec3,
        /// Unit direction of the axle. The wheel rolls forward along
        /// `axle x up` (`super::wheel::forward`) as `roll_m` grows.
        axle: Vec3,
        /// Outer radius, lugs included (m).
        radius: f32,
        /// Half the tyre's width along the axle (m).
        half_width: f32,
        /// The tread pattern on the tyre.
        tread: super::wheel::Tread,
        /// How far the tread has turned, as arc length at the outer radius
        /// (m): the distance rolled, times `1 + slip`.
        roll_m: f32,
    },
}

/// Thickness of a [`Deformer::blade`] (m): thin, and still two texels at
/// the default 6.25 cm so its sweep leaves no gap.
pub(crate) const BLADE_THICKNESS_M: f32 = 0.12;

impl Deformer {
    /// A blade: a plough's blade or the face of a crate, a thin box standing
    /// on its lower edge, centred at `edge_center`, `width_m` wide and
    /// `height_m` tall. It travels along `travel` (its horizontal part;
    /// none: along +x) and is turned `angle_deg` from square to it, so the
    /// snow it pushes slides along it and off its trailing end. Scraping the
    /// ground (its edge at or below the terrain), it packs nothing: with
    /// [`crate::SnowParams::displace`] every bit of snow it takes moves
    /// ahead of it and aside into a windrow (`docs/mechanics.md`).
    #[must_use]
    pub fn blade(edge_center: Vec3, travel: Vec3, angle_deg: f32, (width_m, height_m): (f32, f32)) -> Self {
        let flat = Vec3::new(travel.x, 0.0, travel.z).try_normalize().unwrap_or(Vec3::X);
        let normal = Quat::from_rotation_y(angle_deg.to_radians()) * flat;
        Self::Box {
            center: edge_center + Vec3::Y * (height_m * 0.5),
            half_extents: Vec3::new(width_m * 0.5, height_m * 0.5, BLADE_THICKNESS_M * 0.5),
            rotation: Quat::from_rotation_y(normal.x.atan2(normal.z)),
        }
    }

    /// The pose of a wheel (centre, axle, roll); `None` for other shapes.
    /// Here rather than in `wheel.rs`, which knows wheels but not the
    /// deformer kinds (a circle of files otherwise).
    #[must_use]
    pub(crate) fn wheel_pose(&self) -> Option<super::wheel::WheelPose> {
        match *self {
            Self::Wheel { center, axle, roll_m, .. } => Some((center, axle, roll_m)),
            _ => None,
        }
    }
}

/// What snowpack's own passes, tools and tests read of a [`Deformer`] beyond the front door: its box transform and lowest point.
/// A named item of `low_level` (an extension trait): [`Deformer`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait DeformerExt: Sized {
    /// World-space model matrix of a box (unit cube from -1 to 1 scaled by the half extents).
    #[must_use]
    fn box_matrix(center: Vec3, half_extents: Vec3, rotation: Quat) -> Mat4;

    /// Lowest world height of the shape (m).
    #[must_use]
    fn lowest_point(&self) -> f32;
}

impl DeformerExt for Deformer {
    fn box_matrix(center: Vec3, half_extents: Vec3, rotation: Quat) -> Mat4 {
        Mat4::from_scale_rotation_translation(half_extents, rotation, center)
    }

    fn lowest_point(&self) -> f32 {
        match *self {
            Self::Sphere { center, radius } => center.y - radius,
            Self::Box { center, half_extents, rotation } => {
                let m = glam::Mat3::from_quat(rotation);
                // Support function of the box in the -Y direction.
                let extent = (m.x_axis.y.abs() * half_extents.x) + (m.y_axis.y.abs() * half_extents.y) + (m.z_axis.y.abs() * half_extents.z);
                center.y - extent
            }
            Self::Point { position, .. } => position.y,
            Self::Wheel { center, axle, radius, half_width, .. } => center.y - super::wheel::extent_below(axle, radius, half_width),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_blade_stands_on_its_edge_turned_from_its_travel() {
        let edge = Vec3::new(1.0, -0.2, 3.0);
        let blade = Deformer::blade(edge, Vec3::new(0.0, 0.3, 2.0), 30.0, (2.5, 0.8));
        let Deformer::Box { center, half_extents, rotation } = blade else { panic!("a blade is a box") };
        assert!((blade.lowest_point() - edge.y).abs() < 1e-6);
        assert!((center - edge - Vec3::Y * 0.4).length() < 1e-6);
        assert_eq!(half_extents, Vec3::new(1.25, 0.4, BLADE_THICKNESS_M * 0.5));
        // Its face is turned 30 degrees from the travel (+z), about the vertical.
        let face = rotation * Vec3::Z;
        assert!((face.dot(Vec3::Z) - 30f32.to_radians().cos()).abs() < 1e-5 && face.y.abs() < 1e-6);
        // Standing still, it faces +x turned by the angle.
        let Deformer::Box { rotation, .. } = Deformer::blade(edge, Vec3::ZERO, 0.0, (1.0, 1.0)) else { unreachable!() };
        assert!((rotation * Vec3::Z - Vec3::X).length() < 1e-6);
    }
}
