//! The plugin's settings, below every system that reads them:
//! [`SnowpackSettings`] (the deformation's resource), [`SnowStoreSettings`]
//! (its disk store), [`SnowWindowTarget`] (the entity the window follows
//! instead of `center`) and the centre as the library takes it.

use bevy::prelude::*;
use glam::DVec2;
use snowpack::{SnowParams, StoreConfig, StreamerConfig, TerrainSource};

/// What the plugin's deformation is made of: a resource; change it at any
/// time and the change reaches the snow at the next frame's extraction.
///
/// Applied live: `params.technique`, `params.refill_m_per_s`,
/// `params.snowfall` (only on a window created with snowfall),
/// `params.blur`, `params.elevation`, `params.range_texels` and
/// `params.rim`, `center` (when no [`SnowWindowTarget`] moves the window)
/// and `fixed_dt_s`. What sizes the snow makes a new snow world instead:
/// the window's `extent_m`, `resolution` and `depth_m`, `hardness_kpa`, `density_kg_m3`, `max_density_kg_m3`, `repose_deg`, `displace`,
/// `tile_memory_bytes`, `teleport_m`, `store_ground`, the `terrain` and the `store`. The
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
// Its reflected path stays where it was declared before it had a file of
// its own (the crate root), so saved scenes and reflected names still match.
#[type_path = "bevy_snowpack"]
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

/// A disk store for the snow that leaves the window: the library's tile
/// store (`docs/persistence.md`). A save in `dir` ([`SnowControl::request_save`](crate::SnowControl::request_save))
/// is loaded when the app starts again with the same window settings.
#[derive(Reflect, Clone, Debug)]
#[reflect(Clone, Debug)]
// Its reflected path stays where it was declared before it had a file of
// its own (the crate root), so saved scenes and reflected names still match.
#[type_path = "bevy_snowpack"]
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
fn flat_terrain() -> TerrainSource {
    TerrainSource::Flat { height_m: 0.0 }
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
            terrain: flat_terrain(),
            center: Vec2::ZERO,
            fixed_dt_s: None,
            store: None,
        }
    }
}

/// The deformation window follows this entity (its x, z); one per app.
#[derive(Component, Reflect, Clone, Copy, Debug, Default)]
#[reflect(Component, Clone, Debug, Default)]
#[require(Transform)]
// Its reflected path stays where it was declared before it had a file of
// its own (the crate root), so saved scenes and reflected names still match.
#[type_path = "bevy_snowpack"]
pub struct SnowWindowTarget;

/// The window's centre as the library takes it.
pub(crate) fn dvec2(v: Vec2) -> DVec2 {
    DVec2::new(f64::from(v.x), f64::from(v.y))
}
