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
//! [`SnowFootstep`] messages. [`SnowReplicationPlugin`] shares the snow
//! between a game's server and clients over its bevy_replicon connection.
//!
//! Everything a game uses is in the [`prelude`]; the plugin's systems are
//! in [`SnowSystems`] for ordering a game's own around them; changes to
//! [`SnowpackSettings`] reach the snow the next frame (those that can change
//! live: see its docs).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_snowpack::prelude::*;
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, SnowpackPlugin::new(SnowpackSettings::default())))
//!     .add_systems(Startup, |mut commands: Commands| {
//!         commands.spawn((SnowDeformer::Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 0.6, 0.0)));
//!     })
//!     .run();
//! ```

mod coat;
mod control;
mod footsteps;
mod ground;
mod ground_pass;
mod mesh_deformer;
mod query;
mod render;
mod replication;
mod settings;
mod systems;

use bevy::prelude::*;
use bevy::render::RenderApp;
use glam::DVec2;
use snowpack::{ObjectShape, SnowParams, StoreConfig, StreamerConfig, TerrainSource};

/// The library, for its types beyond the [`prelude`] (`bevy_snowpack::snowpack::ObjectStats`).
pub use snowpack;

pub use coat::{COAT_READ_FRAMES, CoatLook, SnowCoat, SnowCoatExtension, SnowCoatLook, SnowCoatMaterial, SnowCoatSettings};
pub use control::SnowControl;
pub use footsteps::{FootKind, SnowFoot, SnowFootstep};
pub use ground::{SnowGroundExtension, SnowGroundMaterial, snow_height_range};
pub use ground_pass::SnowGroundPass;
pub use query::{SnowAnswers, SnowQuery, SnowTicket};
pub use render::SnowRenderState;
pub use replication::{
    SnowDepthUnder, SnowOwnedBy, SnowRelayStore, SnowReplicationPlugin, SnowReplicationSettings, SnowReplicationSystems, SnowServer, SnowSharing, SnowToClient,
    SnowToServer,
};
pub use systems::SnowSystems;

/// What a game uses: `use bevy_snowpack::prelude::*;`.
pub mod prelude {
    pub use crate::{
        FootKind, SnowAnswers, SnowCatcher, SnowCoat, SnowCoatLook, SnowCoatMaterial, SnowCoatSettings, SnowControl, SnowDeformer, SnowFoot, SnowFootstep,
        SnowGroundExtension, SnowGroundMaterial, SnowGroundPass, SnowQuery, SnowStoreSettings, SnowSystems, SnowTicket, SnowWindowTarget, SnowpackPlugin,
        SnowpackSettings,
    };
    pub use crate::{
        SnowDepthUnder, SnowOwnedBy, SnowRelayStore, SnowReplicationPlugin, SnowReplicationSettings, SnowReplicationSystems, SnowServer, SnowSharing,
        SnowToClient, SnowToServer,
    };
    pub use snowpack::{
        CoatSettings, HeightmapTerrain, NoiseTerrain, ObjectShape, ObjectStats, PointSample, RimStyle, SnowParams, Snowfall, Technique, TerrainSource,
    };
    pub use snowpack::{PeerConfig, RelayConfig};
}

/// What the plugin's deformation is made of: a resource; change it at any
/// time and the change reaches the snow at the next frame's extraction.
///
/// Applied live: `params.technique`, `params.refill_m_per_s`,
/// `params.snowfall` (only on a window created with snowfall),
/// `params.blur`, `params.elevation`, `params.range_texels` and
/// `params.rim`, `center` (when no [`SnowWindowTarget`] moves the window)
/// and `fixed_dt_s`. Fixed at start: the window's `extent_m`, `resolution`
/// and `depth_m`, `hardness_kpa`, `tile_memory_bytes`, `teleport_m`, the
/// `terrain` and the `store`; changing one of these logs a warning and
/// leaves the snow as it is (build a new app, or restart, to change them).
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
    /// Keep trails that leave the window on disk (and load a save found
    /// there); `None` keeps them in memory (`params.tile_memory_bytes`).
    pub store: Option<SnowStoreSettings>,
}

/// A disk store for the snow that leaves the window: the library's tile
/// store (`docs/persistence.md`). A save in `dir` ([`SnowControl::request_save`])
/// is loaded when the app starts again with the same window settings.
#[derive(Clone, Debug)]
pub struct SnowStoreSettings {
    /// The store's folder (created when missing; one app at a time).
    pub dir: std::path::PathBuf,
    /// Side of a stored tile (texels; the window's resolution need not be a multiple).
    pub tile_texels: u32,
    /// Disk budget (least recently used tiles go beyond it).
    pub disk: StoreConfig,
    /// Memory the streamer keeps tiles in before and after the disk.
    pub memory: StreamerConfig,
}

impl SnowStoreSettings {
    /// A store in `dir` with tiles of 64 texels, no disk budget and 128 MiB of memory.
    #[must_use]
    pub fn new(dir: impl Into<std::path::PathBuf>) -> Self {
        Self { dir: dir.into(), tile_texels: 64, disk: StoreConfig::default(), memory: StreamerConfig::default() }
    }
}

impl Default for SnowpackSettings {
    fn default() -> Self {
        Self {
            params: SnowParams { extent_m: 32.0, resolution: 512, depth_m: 0.4, ..SnowParams::default() },
            terrain: TerrainSource::Flat { height_m: 0.0 },
            center: Vec2::ZERO,
            fixed_dt_s: None,
            store: None,
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
    /// The entity's own mesh (`Mesh3d`) in its current pose, or, on an
    /// entity without one (a glTF scene's root), every mesh below it.
    /// Skinned meshes press in pose (the library skins them on the GPU from
    /// the joints' transforms); the mesh asset must keep its data in the
    /// main world (`RenderAssetUsages::MAIN_WORLD`, the glTF default).
    Mesh,
}

impl SnowDeformer {
    /// The library's deformer for this shape placed at `transform`; `None`
    /// for [`Self::Mesh`], which presses as a posed mesh instead.
    #[must_use]
    pub fn placed(&self, transform: &GlobalTransform) -> Option<snowpack::Deformer> {
        let (scale, rotation, translation) = transform.to_scale_rotation_translation();
        match *self {
            Self::Sphere { radius } => Some(snowpack::Deformer::Sphere { center: translation, radius: radius * scale.abs().max_element() }),
            Self::Box { half_extents } => Some(snowpack::Deformer::Box { center: translation, half_extents: half_extents * scale.abs(), rotation }),
            Self::Mesh => None,
        }
    }
}

/// An object snow settles on while it falls (`params.snowfall`): the
/// library's accumulation on its upward surfaces where the sky reaches them,
/// carried along as the entity moves and turns. Adding or removing one lays
/// the objects' atlas out anew (their snow so far is lost). Read the snow on
/// each through [`SnowControl::request_object_stats`]. The library's own
/// `snowpack::SnowObject` is what this becomes in the render world.
#[derive(Component, Clone, Debug, PartialEq)]
pub struct SnowCatcher {
    /// Its shape (a box or a sphere around the entity's origin, or a mesh).
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
        let (to_main, from_render) = std::sync::mpsc::channel();
        app.insert_resource(self.settings.clone())
            .init_resource::<SnowQuery>()
            .init_resource::<SnowControl>()
            .insert_resource(systems::FromRenderWorld::new(from_render));
        systems::build(app);
        settings::build(app);
        footsteps::build(app);
        ground::build(app);
        ground_pass::build(app);
        mesh_deformer::build(app);
        coat::build(app);
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app, self.settings.clone(), systems::ToMainWorld(to_main));
        }
    }
}

/// The window's centre as the library takes it.
pub(crate) fn dvec2(v: Vec2) -> DVec2 {
    DVec2::new(f64::from(v.x), f64::from(v.y))
}
