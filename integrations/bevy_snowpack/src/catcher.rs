//! [`SnowCatcher`]: an object the falling snow settles on, which the
//! render world's extraction turns into the library's `snowpack::SnowObject`.

use bevy::prelude::*;
use snowpack::ObjectShape;

/// An object snow settles on while it falls (`params.snowfall`): the
/// library's accumulation on its upward surfaces where the sky reaches them,
/// carried along as the entity moves and turns. Adding or removing one lays
/// the objects' atlas out anew (their snow so far is lost). Read the snow on
/// each through [`SnowControl::request_object_stats`](crate::SnowControl::request_object_stats). The library's own
/// `snowpack::SnowObject` is what this becomes in the render world.
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq)]
#[require(Transform)]
// Its reflected path stays where it was declared before it had a file of
// its own (the crate root), so saved scenes and reflected names still match.
#[type_path = "bevy_snowpack"]
pub struct SnowCatcher {
    /// Its shape (a box or a sphere around the entity's origin, or a mesh;
    /// the library's type, opaque to reflection).
    #[reflect(ignore, clone, default = "unit_cube")]
    pub shape: ObjectShape,
    /// Whether its snow is dilated across chart seams (off for thin, holey objects).
    pub dilate: bool,
}

impl SnowCatcher {
    /// A box of these side lengths (m).
    #[must_use]
    pub fn cuboid(size_m: Vec3) -> Self {
        Self { shape: ObjectShape::Box { size_m }, dilate: true }
    }

    /// A sphere of this radius (m).
    #[must_use]
    pub fn sphere(radius_m: f32) -> Self {
        Self { shape: ObjectShape::Sphere { radius_m }, dilate: true }
    }
}

/// The shape a reflected [`SnowCatcher`] without one gets: a 1 m cube.
fn unit_cube() -> ObjectShape {
    ObjectShape::Box { size_m: Vec3::ONE }
}
