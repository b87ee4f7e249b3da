//! What presses the snow: [`SnowDeformer`], every shape the library presses
//! with, placed by its entity's transform.
//!
//! Wheels: [`SnowWheel`] keeps a [`SnowDeformer::Wheel`] rolling with its
//! entity and sitting on the snow as deep as its load presses it.
//!
//! Each frame (main world, [`SnowSystems::Gather`]) the wheel's tread turns
//! by the distance its entity moved along its rolling direction times
//! `1 + slip` (the library's `roll_m`, so a rolling tyre prints its tread in
//! place and a slipping one smears it), and its lowest point is set where
//! its load holds it on the snow under it ([`crate::resistance`]'s sinkage,
//! from the snow asked about at the wheel: the untouched snow's height
//! minus the sinkage, never below the terrain). A wheel the game places
//! lower (on the terrain, say) presses only to that height; one above the
//! snow presses nothing.

use bevy::prelude::*;
use snowpack::mechanics::{SnowColumn, SnowMechanics, WheelContact};

use crate::{SnowSystems, SnowpackSettings};

/// Something that presses the snow, placed by the entity's `GlobalTransform`
/// (its translation and rotation; its scale scales the shape). Every kind
/// the library presses with is here: an analytic sphere or box, a capsule
/// and any mesh (pressed by their triangles, skinned meshes in pose), a
/// contact point of the points technique, and a wheel ([`SnowWheel`] keeps
/// one rolling with its load).
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq)]
#[require(Transform)]
// Its reflected path stays where it was declared before it had a file of
// its own (the crate root), so saved scenes and reflected names still match.
#[type_path = "bevy_snowpack"]
pub enum SnowDeformer {
    /// A sphere around the entity's origin.
    Sphere {
        /// Radius (m) before scaling (the largest scale axis applies).
        radius: f32,
    },
    /// A box centred on the entity's origin, turned with it.
    Box {
        /// Half the box's size along the entity's axes (m) before scaling.
        half_extents: Vec3,
    },
    /// A capsule along the entity's local y axis, centred on its origin
    /// (Bevy's `Capsule3d`): pressed by its triangles, like [`Self::Mesh`],
    /// so a lying, rolling or tumbling capsule presses what it covers.
    Capsule {
        /// Radius of its hemispheres and cylinder (m) before scaling.
        radius: f32,
        /// Half the length of its cylinder (m) before scaling.
        half_length: f32,
    },
    /// A contact point of the points technique (`Technique::Points` or
    /// `Combined`; the depth technique ignores it): the footprint
    /// `h = origin.y + d² · scale_per_m` around the entity's origin, the
    /// foot's lowest point.
    Point {
        /// Curvature of the footprint (1/m): `1 / 2r` matches a sphere of radius r.
        scale_per_m: f32,
    },
    /// A tyre with the library's default tread (blocks 12 cm apart, 2 cm
    /// deep) rolling about the entity's local x axis (kept horizontal),
    /// centred on its origin. [`SnowWheel`] writes this each frame from its
    /// motion and load; a game may also drive it by hand.
    Wheel {
        /// Outer radius (m) before scaling.
        radius: f32,
        /// Half the tyre's width (m) before scaling.
        half_width: f32,
        /// How far the tread has turned, as arc length (m): the distance
        /// rolled, times `1 + slip`.
        roll_m: f32,
        /// The lowest the tyre's bottom goes (world y, m): where the load
        /// holds it on the snow. The wheel presses from its transform or from
        /// this, whichever is higher; `f32::NEG_INFINITY`: from its
        /// transform; not finite and positive: it does not press (its load
        /// is not known yet).
        lowest_m: f32,
    },
    /// A plough's blade or a crate's face (`snowpack::Deformer::blade`):
    /// its lower edge's middle at the entity's origin, travelling along the
    /// entity's forward (-z) and turned `angle_deg` from square to it about
    /// the vertical. Scraping the ground with the snow's `params.displace`
    /// on, it pushes its cut aside into a windrow.
    Blade {
        /// Width along the edge (m) before scaling (the entity's x scale).
        width: f32,
        /// Height (m) before scaling (the entity's y scale).
        height: f32,
        /// Turn from square to the travel (degrees): the pushed snow slides
        /// off the trailing end.
        angle_deg: f32,
    },
    /// The entity's own mesh (`Mesh3d`) in its current pose, or, on an
    /// entity without one (a glTF scene's root), every mesh below it.
    /// Skinned meshes press in pose (the library skins them on the GPU from
    /// the joints' transforms); the mesh asset must keep its data in the
    /// main world (`RenderAssetUsages::MAIN_WORLD`, the glTF default).
    Mesh,
}

impl SnowDeformer {
    /// The library's deformer for this shape placed at `transform`; `None`
    /// for [`Self::Mesh`] and [`Self::Capsule`], which press as posed meshes
    /// instead, and for a wheel whose load is not known yet.
    #[must_use]
    pub fn placed(&self, transform: &GlobalTransform) -> Option<snowpack::Deformer> {
        let (scale, rotation, translation) = transform.to_scale_rotation_translation();
        let largest = scale.abs().max_element();
        match *self {
            Self::Sphere { radius } => Some(snowpack::Deformer::Sphere { center: translation, radius: radius * largest }),
            Self::Box { half_extents } => Some(snowpack::Deformer::Box { center: translation, half_extents: half_extents * scale.abs(), rotation }),
            Self::Point { scale_per_m } => Some(snowpack::Deformer::Point { position: translation, scale_per_m }),
            Self::Wheel { radius, half_width, roll_m, lowest_m } => {
                placed_wheel(rotation, translation, radius * largest, half_width * largest, roll_m, lowest_m)
            }
            Self::Blade { width, height, angle_deg } => {
                Some(snowpack::Deformer::blade(translation, rotation * Vec3::NEG_Z, angle_deg, (width * scale.x.abs(), height * scale.y.abs())))
            }
            Self::Capsule { .. } | Self::Mesh => None,
        }
    }
}

/// A wheel pressing the snow with its load: put it on the wheel's entity
/// (its local x axis is the axle, its origin the wheel's centre); the plugin
/// keeps the entity's [`SnowDeformer::Wheel`] up to date. With
/// [`crate::FeelsSnow`] on the same entity, [`crate::SnowResistance`]
/// gives its rolling resistance.
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_snowpack::prelude::*;
/// fn spawn_car_wheels(mut commands: Commands) {
///     for (x, z) in [(-0.8, 1.3), (0.8, 1.3), (-0.8, -1.3), (0.8, -1.3)] {
///         // A quarter of a 1500 kg car on each.
///         commands.spawn((SnowWheel::new(0.32, 0.2, 375.0), FeelsSnow::default(), Transform::from_xyz(x, 0.32, z)));
///     }
/// }
/// ```
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq, Default)]
#[require(Transform)]
pub struct SnowWheel {
    /// Outer radius of the tyre (m).
    pub radius_m: f32,
    /// Width of the tyre (m).
    pub width_m: f32,
    /// Mass resting on this wheel (kg): a vehicle's mass over its wheels.
    pub load_kg: f32,
    /// Wheel slip: the tread turns `1 + slip` times as fast as the wheel
    /// rolls (0 rolls, -1 a locked wheel sliding, > 0 spinning).
    pub slip: f32,
    /// How far the tread has turned (m of arc).
    roll_m: f32,
    /// Where the wheel was last frame.
    last: Option<Vec3>,
    /// The snow under it as last answered: the terrain's height and the
    /// untouched snow's (m).
    #[reflect(ignore)]
    pub(crate) snow_under: Option<(f32, f32)>,
}

impl Default for SnowWheel {
    /// A car's wheel: 0.32 m radius, 0.2 m wide, a quarter of 1500 kg.
    fn default() -> Self {
        Self::new(0.32, 0.2, 375.0)
    }
}

impl SnowWheel {
    /// A wheel of this radius and width (m) carrying `load_kg`, rolling without slip.
    #[must_use]
    pub fn new(radius_m: f32, width_m: f32, load_kg: f32) -> Self {
        Self { radius_m, width_m, load_kg, slip: 0.0, roll_m: 0.0, last: None, snow_under: None }
    }

    /// The same wheel with this slip.
    #[must_use]
    pub fn with_slip(mut self, slip: f32) -> Self {
        self.slip = slip;
        self
    }

    /// How far the tread has turned so far (m of arc).
    #[must_use]
    pub fn roll_m(&self) -> f32 {
        self.roll_m
    }

    /// The wheel as the snow's mechanics see it.
    #[must_use]
    pub fn contact(&self) -> WheelContact {
        WheelContact { load_kg: self.load_kg, radius_m: self.radius_m, width_m: self.width_m }
    }

    /// How far this wheel sinks (m) into `column` of snow of `mechanics`
    /// (`SnowpackSettings::params.mechanics()`; see [`crate::SnowResistance`]):
    /// Bekker's curve under its contact patch, less what the column is packed.
    #[must_use]
    pub fn sinkage_m(&self, mechanics: &SnowMechanics, column: SnowColumn) -> f32 {
        mechanics.wheel_sinkage_m(&self.contact(), column)
    }
}

pub(crate) fn build(app: &mut App) {
    app.add_systems(PostUpdate, drive_wheels.in_set(SnowSystems::Gather));
}

/// The axle of a wheel turned by `rotation`: its local x, kept horizontal.
fn horizontal_axle(rotation: Quat) -> Vec3 {
    let a = rotation * Vec3::X;
    Vec3::new(a.x, 0.0, a.z).try_normalize().unwrap_or(Vec3::X)
}

/// The library's wheel for [`SnowDeformer::Wheel`] at this pose (sizes already scaled).
pub(crate) fn placed_wheel(rotation: Quat, translation: Vec3, radius: f32, half_width: f32, roll_m: f32, lowest_m: f32) -> Option<snowpack::Deformer> {
    if lowest_m.is_nan() || lowest_m == f32::INFINITY {
        return None;
    }
    let center = Vec3::new(translation.x, translation.y.max(lowest_m + radius), translation.z);
    // The library's default tread: the front door builds it by inference.
    Some(snowpack::Deformer::Wheel { center, axle: horizontal_axle(rotation), radius, half_width, tread: Default::default(), roll_m })
}

/// Rolls each wheel by its motion and sets where its load holds it.
fn drive_wheels(
    mut commands: Commands,
    settings: Res<SnowpackSettings>,
    mut wheels: Query<(Entity, &mut SnowWheel, &GlobalTransform, Option<&mut SnowDeformer>)>,
) {
    for (entity, mut wheel, transform, deformer) in &mut wheels {
        let (_, rotation, translation) = transform.to_scale_rotation_translation();
        // The library's wheel rolls forward along `axle x up`.
        let ahead = horizontal_axle(rotation).cross(Vec3::Y);
        if let Some(last) = wheel.last {
            let turned = (translation - last).dot(ahead) * (1.0 + wheel.slip);
            wheel.roll_m += turned;
        }
        wheel.last = Some(translation);
        let lowest_m = match wheel.snow_under {
            Some((terrain_m, rest_m)) => (rest_m - wheel.sinkage_m(&settings.params.mechanics(), SnowColumn::fresh(rest_m - terrain_m))).max(terrain_m),
            None => f32::INFINITY,
        };
        let pressing = SnowDeformer::Wheel { radius: wheel.radius_m, half_width: 0.5 * wheel.width_m, roll_m: wheel.roll_m, lowest_m };
        match deformer {
            Some(mut d) => {
                if *d != pressing {
                    *d = pressing;
                }
            }
            None => {
                commands.entity(entity).insert(pressing);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wheel_sits_where_its_load_holds_it_and_rolls_along_its_motion() {
        // Not known yet: it does not press.
        assert!(placed_wheel(Quat::IDENTITY, Vec3::ZERO, 0.3, 0.1, 0.0, f32::INFINITY).is_none());
        // Placed on the terrain at 0.3 m, held at 0.25 m by its load: it presses from 0.25 m.
        let Some(snowpack::Deformer::Wheel { center, axle, roll_m, .. }) =
            placed_wheel(Quat::from_rotation_y(0.5), Vec3::new(1.0, 0.3, 2.0), 0.3, 0.1, 1.5, 0.25)
        else {
            panic!("a wheel")
        };
        assert!((center.y - 0.55).abs() < 1e-6 && center.x == 1.0 && center.z == 2.0);
        assert!(axle.y.abs() < 1e-6 && (axle.length() - 1.0).abs() < 1e-6);
        assert_eq!(roll_m, 1.5);
        // Above the snow: where its transform puts it.
        let Some(snowpack::Deformer::Wheel { center, .. }) = placed_wheel(Quat::IDENTITY, Vec3::new(0.0, 2.0, 0.0), 0.3, 0.1, 0.0, 0.25) else {
            panic!("a wheel")
        };
        assert_eq!(center.y, 2.0);
    }
}
