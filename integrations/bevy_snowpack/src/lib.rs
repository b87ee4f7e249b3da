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
//! [`SnowFootstep`] messages; [`FeelsSnow`] entities get a
//! [`SnowResistance`] (how much the snow under them holds them back);
//! [`SnowpackDiagnosticsPlugin`] puts the snow's GPU time and memory into
//! Bevy's `DiagnosticsStore`. [`SnowReplicationPlugin`] shares the snow
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
//!     .add_plugins((DefaultPlugins, SnowpackPlugin::default().with_depth(0.4)))
//!     .add_systems(Startup, |mut commands: Commands| {
//!         commands.spawn((SnowDeformer::Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 0.6, 0.0)));
//!     })
//!     .run();
//! ```
//!
//! Cargo features (Bevy's guidelines: the plugin forces no windowing
//! backend or image format on a game; its examples turn theirs on):
//!
//! | feature | default | what |
//! |---|---|---|
//! | `render` | yes | the snow in the render world: [`SnowpackPlugin`], the ground, materials, passes, deformers, queries (snowpack, wgpu, Bevy's render, core-pipeline and PBR crates) |
//! | `gltf` | yes | Bevy's glTF loader and animations, for skinned characters from glTF |
//! | `multiplayer` | yes | shared snow over bevy_replicon, server and clients (implies `render` and `server`) |
//! | `server` | no | the relay alone: `SnowReplicationPlugin`'s server half on snowpack-share, without bevy_render, bevy_pbr, wgpu or winit |

#[cfg(feature = "render")]
mod coat;
#[cfg(feature = "render")]
mod control;
#[cfg(feature = "render")]
mod deformers;
#[cfg(feature = "render")]
mod diagnostics;
#[cfg(feature = "render")]
mod footsteps;
#[cfg(feature = "render")]
mod from_render;
#[cfg(feature = "render")]
mod ground;
#[cfg(feature = "render")]
mod ground_pass;
#[cfg(feature = "render")]
mod material_extension;
#[cfg(feature = "render")]
mod mesh_deformer;
#[cfg(feature = "render")]
mod query;
#[cfg(feature = "render")]
mod receive;
#[cfg(feature = "render")]
mod render;
#[cfg(feature = "render")]
mod render_state;
#[cfg(feature = "server")]
mod replication;
#[cfg(feature = "render")]
mod resistance;
#[cfg(feature = "render")]
mod settings;
#[cfg(feature = "render")]
mod sinkage;
#[cfg(feature = "render")]
mod systems;
#[cfg(feature = "render")]
mod terrain_asset;
#[cfg(feature = "render")]
mod world_switch;

#[cfg(feature = "render")]
use bevy::prelude::*;
#[cfg(feature = "render")]
use bevy::render::RenderApp;
#[cfg(feature = "render")]
use glam::DVec2;
#[cfg(feature = "render")]
use snowpack::{ObjectShape, SnowParams, StoreConfig, StreamerConfig, TerrainSource};

/// The library, for its types beyond the [`prelude`] (`bevy_snowpack::snowpack::ObjectStats`).
#[cfg(feature = "render")]
pub use snowpack;
/// Shared snow without a GPU (the relay, the peer's and relay's settings,
/// the tile store): what the `server` feature builds on.
pub use snowpack_share;

#[cfg(feature = "render")]
pub use coat::{COAT_READ_FRAMES, CoatLook, SnowCoat, SnowCoatExtension, SnowCoatLook, SnowCoatMaterial, SnowCoatSettings};
#[cfg(feature = "render")]
pub use control::{SnowControl, SnowObjectStats, SnowSaved};
#[cfg(feature = "render")]
pub use deformers::SnowWheel;
#[cfg(feature = "render")]
pub use diagnostics::SnowpackDiagnosticsPlugin;
#[cfg(feature = "render")]
pub use footsteps::{FootKind, SnowFoot, SnowFootstep};
#[cfg(feature = "render")]
pub use ground::{SnowGroundExtension, SnowGroundMaterial, snow_height_range};
#[cfg(feature = "render")]
pub use ground_pass::SnowGroundPass;
#[cfg(feature = "render")]
pub use material_extension::{SnowCoverBindings, SnowCoverExtension, SnowCoverMaterial, snow_cover_lift};
#[cfg(feature = "render")]
pub use query::{SnowAnswered, SnowAnswers, SnowQuery, SnowTicket};
#[cfg(feature = "render")]
pub use render_state::SnowRenderState;
#[cfg(feature = "multiplayer")]
pub use replication::SnowSharing;
#[cfg(feature = "server")]
pub use replication::{
    SnowDepthUnder, SnowOwnedBy, SnowRelayStore, SnowReplicationPlugin, SnowReplicationSettings, SnowReplicationSystems, SnowServer, SnowToClient, SnowToServer,
};
#[cfg(feature = "render")]
pub use resistance::{FeelsSnow, SnowResistance};
#[cfg(feature = "render")]
pub use systems::SnowSystems;
#[cfg(feature = "render")]
pub use terrain_asset::{SnowTerrainAsset, SnowTerrainStatus, TerrainAssetError, heightmap_from_image, triangles_from_mesh};

/// What a game uses: `use bevy_snowpack::prelude::*;`.
pub mod prelude {
    #[cfg(feature = "multiplayer")]
    pub use crate::SnowSharing;
    #[cfg(feature = "render")]
    pub use crate::{
        FeelsSnow, FootKind, SnowAnswered, SnowAnswers, SnowCatcher, SnowCoat, SnowCoatLook, SnowCoatMaterial, SnowCoatSettings, SnowControl, SnowDeformer,
        SnowFoot, SnowFootstep, SnowGroundExtension, SnowGroundMaterial, SnowGroundPass, SnowObjectStats, SnowQuery, SnowResistance, SnowSaved,
        SnowStoreSettings, SnowSystems, SnowTicket, SnowWheel, SnowWindowTarget, SnowpackDiagnosticsPlugin, SnowpackPlugin, SnowpackSettings,
    };
    #[cfg(feature = "render")]
    pub use crate::{SnowCoverExtension, SnowCoverMaterial, SnowTerrainAsset, SnowTerrainStatus};
    #[cfg(feature = "server")]
    pub use crate::{
        SnowDepthUnder, SnowOwnedBy, SnowRelayStore, SnowReplicationPlugin, SnowReplicationSettings, SnowReplicationSystems, SnowServer, SnowToClient,
        SnowToServer,
    };
    #[cfg(feature = "render")]
    pub use snowpack::{
        CoatSettings, HeightmapTerrain, NoiseTerrain, ObjectShape, ObjectStats, PointSample, RimStyle, SnowParams, Snowfall, Technique, TerrainSource,
    };
    #[cfg(feature = "server")]
    pub use snowpack_share::{PeerConfig, RelayConfig};
}

#[cfg(feature = "render")]
/// What the plugin's deformation is made of: a resource; change it at any
/// time and the change reaches the snow at the next frame's extraction.
///
/// Applied live: `params.technique`, `params.refill_m_per_s`,
/// `params.snowfall` (only on a window created with snowfall),
/// `params.blur`, `params.elevation`, `params.range_texels` and
/// `params.rim`, `center` (when no [`SnowWindowTarget`] moves the window)
/// and `fixed_dt_s`. What sizes the snow makes a new snow world instead:
/// the window's `extent_m`, `resolution` and `depth_m`, `hardness_kpa`, `density_kg_m3`, `max_density_kg_m3`, `repose_deg`, `displace`,
/// `tile_memory_bytes`, `teleport_m`, the `terrain` and the `store`. The
/// old world's snow is saved to its store first (when it has one of its
/// own), the new one loads its store's save, and the materials bind the new
/// world; going back to a world's settings brings its trails back. Queries
/// in flight across the change are not answered.
///
/// Reflected (inspectors, scenes): `center`, `fixed_dt_s` and the store's
/// folder and tile side; `params` and `terrain` are the library's types,
/// which do not implement `Reflect` (snowpack does not depend on Bevy), so
/// reflection carries them opaquely: `reflect_clone` copies them, a
/// dynamic value or a serialized one leaves them out.
#[derive(Resource, Reflect, Clone, Debug)]
#[reflect(Resource, Clone, Debug, Default)]
pub struct SnowpackSettings {
    /// The window: size and resolution, depth, technique, refill, snowfall,
    /// tile memory (see `snowpack::SnowParams`).
    #[reflect(ignore, clone)]
    pub params: SnowParams,
    /// The terrain under the snow.
    #[reflect(ignore, clone, default = "flat_terrain")]
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

#[cfg(feature = "render")]
/// A disk store for the snow that leaves the window: the library's tile
/// store (`docs/persistence.md`). A save in `dir` ([`SnowControl::request_save`])
/// is loaded when the app starts again with the same window settings.
#[derive(Reflect, Clone, Debug)]
#[reflect(Clone, Debug)]
pub struct SnowStoreSettings {
    /// The store's folder (created when missing; one app at a time).
    pub dir: std::path::PathBuf,
    /// Side of a stored tile (texels; the window's resolution need not be a multiple).
    pub tile_texels: u32,
    /// Disk budget (least recently used tiles go beyond it; the library's type, opaque to reflection).
    #[reflect(ignore, clone)]
    pub disk: StoreConfig,
    /// Memory the streamer keeps tiles in before and after the disk (the library's type, opaque to reflection).
    #[reflect(ignore, clone)]
    pub memory: StreamerConfig,
}

/// The terrain a reflected value without one gets: flat ground at 0 m.
#[cfg(feature = "render")]
fn flat_terrain() -> TerrainSource {
    TerrainSource::Flat { height_m: 0.0 }
}

#[cfg(feature = "render")]
impl SnowStoreSettings {
    /// A store in `dir` with tiles of 64 texels, no disk budget and 128 MiB of memory.
    #[must_use]
    pub fn new(dir: impl Into<std::path::PathBuf>) -> Self {
        Self { dir: dir.into(), tile_texels: 64, disk: StoreConfig::default(), memory: StreamerConfig::default() }
    }
}

#[cfg(feature = "render")]
impl Default for SnowpackSettings {
    fn default() -> Self {
        Self {
            params: SnowParams { extent_m: 32.0, resolution: 512, depth_m: 0.4, ..SnowParams::default() },
            terrain: flat_terrain(),
            center: Vec2::ZERO,
            fixed_dt_s: None,
            store: None,
        }
    }
}

#[cfg(feature = "render")]
/// Something that presses the snow, placed by the entity's `GlobalTransform`
/// (its translation and rotation; its scale scales the shape). Every kind
/// the library presses with is here: an analytic sphere or box, a capsule
/// and any mesh (pressed by their triangles, skinned meshes in pose), a
/// contact point of the points technique, and a wheel ([`SnowWheel`] keeps
/// one rolling with its load).
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq)]
#[require(Transform)]
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

#[cfg(feature = "render")]
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
                deformers::placed_wheel(rotation, translation, radius * largest, half_width * largest, roll_m, lowest_m)
            }
            Self::Blade { width, height, angle_deg } => {
                Some(snowpack::Deformer::blade(translation, rotation * Vec3::NEG_Z, angle_deg, (width * scale.x.abs(), height * scale.y.abs())))
            }
            Self::Capsule { .. } | Self::Mesh => None,
        }
    }
}

#[cfg(feature = "render")]
/// An object snow settles on while it falls (`params.snowfall`): the
/// library's accumulation on its upward surfaces where the sky reaches them,
/// carried along as the entity moves and turns. Adding or removing one lays
/// the objects' atlas out anew (their snow so far is lost). Read the snow on
/// each through [`SnowControl::request_object_stats`]. The library's own
/// `snowpack::SnowObject` is what this becomes in the render world.
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Clone, Debug, PartialEq)]
#[require(Transform)]
pub struct SnowCatcher {
    /// Its shape (a box or a sphere around the entity's origin, or a mesh;
    /// the library's type, opaque to reflection).
    #[reflect(ignore, clone, default = "unit_cube")]
    pub shape: ObjectShape,
    /// Whether its snow is dilated across chart seams (off for thin, holey objects).
    pub dilate: bool,
}

#[cfg(feature = "render")]
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
#[cfg(feature = "render")]
fn unit_cube() -> ObjectShape {
    ObjectShape::Box { size_m: Vec3::ONE }
}

#[cfg(feature = "render")]
/// The deformation window follows this entity (its x, z); one per app.
#[derive(Component, Reflect, Clone, Copy, Debug, Default)]
#[reflect(Component, Clone, Debug, Default)]
#[require(Transform)]
pub struct SnowWindowTarget;

#[cfg(feature = "render")]
/// Adds deformable snow to an app (see the crate docs). Needs Bevy's render
/// plugins (`DefaultPlugins`, or the render, core-pipeline and PBR plugins).
///
/// `SnowpackPlugin::default()` is a 32 m window of 512 texels in 0.4 m of
/// snow on flat ground at 0 m; the builders change what a game needs:
///
/// ```no_run
/// # use bevy::prelude::*;
/// # use bevy_snowpack::prelude::*;
/// let snow = SnowpackPlugin::default()
///     .with_window(24.0, 512)
///     .with_depth(0.2)
///     .with_terrain(TerrainSource::Noise(NoiseTerrain { seed: 11, base_m: 0.0, amplitude_m: 1.2, wavelength_m: 20.0 }));
/// App::new().add_plugins((DefaultPlugins, snow));
/// ```
#[derive(Default)]
pub struct SnowpackPlugin {
    /// The deformation's settings (the [`SnowpackSettings`] resource it inserts).
    pub settings: SnowpackSettings,
}

#[cfg(feature = "render")]
impl SnowpackPlugin {
    /// The plugin with these settings.
    #[must_use]
    pub fn new(settings: SnowpackSettings) -> Self {
        Self { settings }
    }

    /// All the settings at once.
    #[must_use]
    pub fn with_settings(mut self, settings: SnowpackSettings) -> Self {
        self.settings = settings;
        self
    }

    /// The library's parameters whole (window, depth, technique, refill, snowfall...).
    #[must_use]
    pub fn with_params(mut self, params: SnowParams) -> Self {
        self.settings.params = params;
        self
    }

    /// A window of `extent_m` metres a side and `resolution` texels a side.
    #[must_use]
    pub fn with_window(mut self, extent_m: f32, resolution: u32) -> Self {
        (self.settings.params.extent_m, self.settings.params.resolution) = (extent_m, resolution);
        self
    }

    /// Untouched snow this deep (m).
    #[must_use]
    pub fn with_depth(mut self, depth_m: f32) -> Self {
        self.settings.params.depth_m = depth_m;
        self
    }

    /// Trails fill in at this rate (m/s); 0 keeps them.
    #[must_use]
    pub fn with_refill(mut self, refill_m_per_s: f32) -> Self {
        self.settings.params.refill_m_per_s = refill_m_per_s;
        self
    }

    /// The terrain under the snow.
    #[must_use]
    pub fn with_terrain(mut self, terrain: TerrainSource) -> Self {
        self.settings.terrain = terrain;
        self
    }

    /// Where the window starts (world x, z in m).
    #[must_use]
    pub fn with_center(mut self, center: Vec2) -> Self {
        self.settings.center = center;
        self
    }

    /// Steps the snow by `dt_s` each frame (deterministic replays and tests).
    #[must_use]
    pub fn with_fixed_dt(mut self, dt_s: f32) -> Self {
        self.settings.fixed_dt_s = Some(dt_s);
        self
    }

    /// Keeps the trails that leave the window on disk.
    #[must_use]
    pub fn with_store(mut self, store: SnowStoreSettings) -> Self {
        self.settings.store = Some(store);
        self
    }
}

#[cfg(feature = "render")]
impl Plugin for SnowpackPlugin {
    fn build(&self, app: &mut App) {
        let (to_main, from_render) = std::sync::mpsc::channel();
        app.insert_resource(self.settings.clone())
            .init_resource::<SnowQuery>()
            .init_resource::<SnowControl>()
            .insert_resource(from_render::FromRenderWorld::new(from_render));
        register_types(app);
        receive::build(app);
        settings::build(app);
        footsteps::build(app);
        ground::build(app);
        ground_pass::build(app);
        mesh_deformer::build(app);
        coat::build(app);
        control::build(app);
        query::build(app);
        deformers::build(app);
        resistance::build(app);
        material_extension::build(app);
        terrain_asset::build(app);
        world_switch::build(app);
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app, self.settings.clone(), from_render::ToMainWorld(to_main));
        }
    }
}

/// The public components and resources of the plugin's core in Bevy's type
/// registry (Bevy is built without `reflect_auto_register`), for inspectors
/// and scenes; the coat's and the ground pass's register with their modules.
#[cfg(feature = "render")]
fn register_types(app: &mut App) {
    app.register_type::<SnowpackSettings>()
        .register_type::<SnowStoreSettings>()
        .register_type::<SnowDeformer>()
        .register_type::<SnowWheel>()
        .register_type::<SnowCatcher>()
        .register_type::<SnowWindowTarget>()
        .register_type::<FeelsSnow>()
        .register_type::<SnowResistance>()
        .register_type::<SnowFoot>()
        .register_type::<FootKind>()
        .register_type::<SnowQuery>()
        .register_type::<SnowTicket>()
        .register_type::<SnowControl>();
}

#[cfg(feature = "render")]
/// The window's centre as the library takes it.
pub(crate) fn dvec2(v: Vec2) -> DVec2 {
    DVec2::new(f64::from(v.x), f64::from(v.y))
}
