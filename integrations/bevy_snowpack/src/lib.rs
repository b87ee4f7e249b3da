//! bevy_snowpack: snowpack's deformable snow as a Bevy 0.20 plugin.
//!
//! [`SnowpackPlugin`] creates a [`snowpack::SnowDeformation`] on Bevy's own
//! `RenderDevice` and `RenderQueue` in the render world and records its frame
//! into the render graph before the cameras draw. Entities with a
//! [`SnowDeformer`] press the snow; the [`SnowWindowTarget`] entity carries
//! the deformation window along; [`SnowQuery`] asks the snow at points
//! (answers a frame or two late); a camera with [`SnowGroundPass`] draws
//! snowpack's own snow ground in its main pass, or [`SnowGroundMaterial`]
//! draws a ground mesh displaced by the snow in the main and the prepass
//! (depth, shadow) vertex shaders; [`SnowFoot`] entities raise
//! [`SnowFootstep`] messages.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_snowpack::{SnowDeformer, SnowpackPlugin, SnowpackSettings};
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, SnowpackPlugin::new(SnowpackSettings::default())))
//!     .add_systems(Startup, |mut commands: Commands| {
//!         commands.spawn((SnowDeformer::Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 0.6, 0.0)));
//!     })
//!     .run();
//! ```

mod footsteps;
mod ground;
mod ground_pass;
mod query;
mod render;

use bevy::prelude::*;
use bevy::render::RenderApp;
use glam::DVec2;
use snowpack::{SnowParams, TerrainSource};

pub use footsteps::{FootKind, SnowFoot, SnowFootstep};
pub use ground::{SnowGroundExtension, SnowGroundMaterial, snow_height_range};
pub use ground_pass::SnowGroundPass;
pub use query::{SnowAnswers, SnowQuery, SnowTicket};
pub use render::SnowRenderState;

/// What the plugin's deformation is made of.
#[derive(Resource, Clone, Debug)]
pub struct SnowpackSettings {
    /// The window: size and resolution, depth, technique, refill, snowfall,
    /// tile memory (see `snowpack::SnowParams`).
    pub params: SnowParams,
    /// The terrain under the snow.
    pub terrain: TerrainSource,
    /// Where the window starts (world x, z in m); [`SnowWindowTarget`] moves it.
    pub center: Vec2,
    /// Step the snow by this many seconds each frame instead of the frame's
    /// `Time` delta: deterministic replays and tests.
    pub fixed_dt_s: Option<f32>,
}

impl Default for SnowpackSettings {
    fn default() -> Self {
        Self {
            params: SnowParams { extent_m: 32.0, resolution: 512, depth_m: 0.4, ..SnowParams::default() },
            terrain: TerrainSource::Flat { height_m: 0.0 },
            center: Vec2::ZERO,
            fixed_dt_s: None,
        }
    }
}

/// Something that presses the snow, placed by the entity's `GlobalTransform`
/// (its translation and rotation; its scale scales the shape).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
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
}

impl SnowDeformer {
    /// The library's deformer for this shape placed at `transform`.
    #[must_use]
    pub fn placed(&self, transform: &GlobalTransform) -> snowpack::Deformer {
        let (scale, rotation, translation) = transform.to_scale_rotation_translation();
        match *self {
            Self::Sphere { radius } => snowpack::Deformer::Sphere { center: translation, radius: radius * scale.abs().max_element() },
            Self::Box { half_extents } => snowpack::Deformer::Box { center: translation, half_extents: half_extents * scale.abs(), rotation },
        }
    }
}

/// The deformation window follows this entity (its x, z); one per app.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct SnowWindowTarget;

/// Adds deformable snow to an app (see the crate docs). Needs Bevy's render
/// plugins (`DefaultPlugins`, or the render, core-pipeline and PBR plugins).
pub struct SnowpackPlugin {
    /// The deformation's settings.
    pub settings: SnowpackSettings,
}

impl SnowpackPlugin {
    /// The plugin with these settings.
    #[must_use]
    pub fn new(settings: SnowpackSettings) -> Self {
        Self { settings }
    }
}

impl Plugin for SnowpackPlugin {
    fn build(&self, app: &mut App) {
        let query = SnowQuery::default();
        app.insert_resource(self.settings.clone()).insert_resource(query.clone());
        footsteps::build(app);
        ground::build(app);
        ground_pass::build(app);
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app, self.settings.clone(), query);
        }
    }
}

/// The window's centre as the library takes it.
pub(crate) fn dvec2(v: Vec2) -> DVec2 {
    DVec2::new(f64::from(v.x), f64::from(v.y))
}
