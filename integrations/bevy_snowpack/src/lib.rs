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
mod catcher;
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
mod snowpack_settings;
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
use snowpack::{SnowParams, TerrainSource};

/// The library, for its types beyond the [`prelude`] (`bevy_snowpack::snowpack::ObjectStats`).
#[cfg(feature = "render")]
pub use snowpack;
/// Shared snow without a GPU (the relay, the peer's and relay's settings,
/// the tile store): what the `server` feature builds on.
pub use snowpack_share;

#[cfg(feature = "render")]
pub use catcher::SnowCatcher;
#[cfg(feature = "render")]
pub use coat::{COAT_READ_FRAMES, CoatLook, SnowCoat, SnowCoatExtension, SnowCoatLook, SnowCoatMaterial, SnowCoatSettings};
#[cfg(feature = "render")]
pub use control::{SnowControl, SnowObjectStats, SnowSaved};
#[cfg(feature = "render")]
pub use deformers::{SnowDeformer, SnowWheel};
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
pub use snowpack_settings::{SnowStoreSettings, SnowWindowTarget, SnowpackSettings};
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
    /// `SnowDeformation::world_identity_for`: the world a server checks its clients against.
    #[cfg(feature = "multiplayer")]
    pub use snowpack::SharedWindow;
    #[cfg(feature = "render")]
    pub use snowpack::{
        CoatSettings, HeightmapTerrain, NoiseTerrain, ObjectShape, ObjectStats, PointSample, RimStyle, SnowParams, Snowfall, Technique, TerrainSource,
    };
    #[cfg(feature = "server")]
    pub use snowpack_share::{PeerConfig, RelayConfig};
}

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
