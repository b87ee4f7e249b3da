//! Parameters of the snow surface, shared by every deformation pass.

use snowpack_share::mechanics::SnowMechanics;

use crate::error::SnowError;
use crate::snowfall::SnowfallExt;
use crate::{RimStyle, Technique};

/// How the deformation window is sized and how the snow behaves.
///
/// Field names follow the `[snow]` table of scene files (see `docs/scene.md`).
#[derive(Clone, Debug, PartialEq)]
pub struct SnowParams {
    /// Side of the square deformation window (m).
    pub extent_m: f32,
    /// Texels per side of the window.
    pub resolution: u32,
    /// Rest depth of fresh snow above the terrain (m), >= 0; 0 is bare
    /// ground (snow comes only from `snowfall`).
    pub depth_m: f32,
    /// Linear refill of trails while it snows (m/s).
    pub refill_m_per_s: f32,
    /// Rim strength in the displayed surface (Hanák's cubic remap); 0 = no rims.
    pub elevation: f32,
    /// Whether the displayed surface gets the 5x5 Gaussian blur.
    pub blur: bool,
    /// How actors deform the snow; switchable at runtime.
    pub technique: Technique,
    /// Side of one point's footprint square (texels), 32..=128 ("points", "combined").
    pub range_texels: u32,
    /// Rim formula of the points technique.
    pub rim: RimStyle,
    /// Penetration hardness of fresh snow (kPa): the pressure that sinks a
    /// 10 cm plate 10 cm into it. Packed snow is harder: it holds the load
    /// that packed it ([`SnowParams::mechanics`]). Fresh powder is a few
    /// kPa, settled snow tens.
    pub hardness_kpa: f32,
    /// Density of fresh snow: the initial cover, refill and snowfall
    /// (kg/m³; default 100). Presses pack it: the column's mass stays.
    pub density_kg_m3: f32,
    /// Density at which snow stops packing (kg/m³; default 500, CRREL's
    /// final density under a wheel); what a press squeezes beyond it is
    /// displaced.
    pub max_density_kg_m3: f32,
    /// The snow's angle of repose (degrees, in (0, 90)): walls a press left
    /// steeper than this slide into the trench beside them, a step of the
    /// erosion pass a frame (`docs/mechanics.md`, "Erosion"). `None` (the
    /// default): trails keep the walls their presses made. Not applied
    /// while the window shares its snow.
    pub repose_deg: Option<f32>,
    /// Whether snow a press squeezes beyond the final density moves aside
    /// into berms (`docs/mechanics.md`, "Displacement"): the displace pass
    /// puts it down on the texels beside the press, as snow lying on the
    /// rest surface, so a blade (a box scraping the ground,
    /// [`crate::Deformer::blade`]) pushes a windrow. `false` (the default):
    /// it is counted as displaced and leaves the window. Needs the depth or
    /// combined technique (the capture gives the direction); the window then
    /// keeps a lying-snow plane (4 bytes a texel) as with snowfall.
    pub displace: bool,
    /// Snowfall (the `[snowfall]` table): the ground gains depth where the sky
    /// reaches it and objects accumulate snow. `None`: no snow falls, and the
    /// ground's snowfall buffer is not allocated.
    pub snowfall: Option<crate::snowfall::Snowfall>,
    /// Memory budget (bytes) for the snow of tiles the window has left, so a
    /// trail is still there when the window comes back (the scene's
    /// `[store]` table). `Some`: kept in memory
    /// (`TileStreamer::in_memory`, tiles of
    /// `default_tile_texels`); beyond the budget the least recently left
    /// tiles are forgotten (fresh snow). `None`: texels leaving the window
    /// are forgotten and no tiles are resident on the GPU. Default
    /// `DEFAULT_TILE_MEMORY_BYTES`. A disk store attached with
    /// `StoredWindow::attach_store` (feature `store`) replaces the memory keeper.
    pub tile_memory_bytes: Option<usize>,
    /// Largest distance (m) a deformer may move between two frames and still
    /// be swept over its motion (see `crate::deform::sweep`); a larger
    /// jump is a teleport and presses only where it lands. 0 turns sweeping
    /// off (each deformer presses where it stands each frame). Default 4 m
    /// (a vehicle at 120 m/s at 30 frames a second).
    pub teleport_m: f32,
    /// Whether a window over noise hills keeps the terrain's height under
    /// each texel (4 bytes a texel: 4 MiB at 1024²) instead of evaluating
    /// the noise, four octaves of hashes, in every pass that visits each
    /// texel each frame (`docs/deformation.md`, "The window's ground"). The
    /// same snow either way; on lavapipe a 1024² frame over hills took half
    /// the time. `false` (the default) keeps the default window within its
    /// memory budget. Flat and heightmap terrain store nothing either way.
    pub store_ground: bool,
}

/// The default [`SnowParams::tile_memory_bytes`]: 64 MiB, the scene's
/// `[store] memory_mb` default. Untouched tiles are not kept, so without
/// snowfall it holds about 8,000 trodden tiles of 32² (8 KiB each): 33,000
/// m² of trails at the default 6.25 cm texel; with snowfall every tile is
/// kept (12 KiB), about five default windows' worth.
pub const DEFAULT_TILE_MEMORY_BYTES: usize = 64 << 20;

/// Tile side (texels) of the default memory keeper for a window of
/// `resolution` texels: 32, or the largest power of two that divides the
/// resolution when that is smaller (16 for 16, 48, 80, ...). Small tiles
/// keep the GPU's resident ring close to the window (its side is the
/// resolution plus two tiles) and the memory keeper's trails narrow.
#[must_use]
pub fn default_tile_texels(resolution: u32) -> u32 {
    let largest = 1u32 << resolution.trailing_zeros().min(31);
    largest.min(32)
}

impl Default for SnowParams {
    fn default() -> Self {
        Self {
            extent_m: 64.0,
            resolution: 1024,
            depth_m: 0.5,
            refill_m_per_s: 0.0,
            elevation: 1.0,
            blur: true,
            technique: Technique::Depth,
            range_texels: 64,
            rim: RimStyle::Rounded,
            hardness_kpa: 10.0,
            density_kg_m3: 100.0,
            max_density_kg_m3: 500.0,
            repose_deg: None,
            displace: false,
            snowfall: None,
            tile_memory_bytes: Some(DEFAULT_TILE_MEMORY_BYTES),
            teleport_m: 4.0,
            store_ground: false,
        }
    }
}

/// Smallest and largest window resolution snowpack accepts.
pub const RESOLUTION_RANGE: std::ops::RangeInclusive<u32> = 16..=8192;

impl SnowParams {
    /// Whether the window keeps a plane of snow lying on the rest surface
    /// (`fallen`): snowfall so far, and berms when it displaces.
    #[must_use]
    pub(crate) fn keeps_lying_snow(&self) -> bool {
        self.snowfall.is_some() || self.displace
    }

    /// Size of one texel (m).
    #[must_use]
    pub fn texel_m(&self) -> f32 {
        self.extent_m / self.resolution as f32
    }

    /// The snow's mechanics: its densities and hardness on Wong's "Snow
    /// (U.S.)" pressure–sinkage curve (`docs/mechanics.md`): how dense the
    /// snow at a point is, how far a foot or a wheel sinks into it and
    /// what it costs a wheel.
    #[must_use]
    pub fn mechanics(&self) -> SnowMechanics {
        SnowMechanics {
            fresh_density_kg_m3: self.density_kg_m3,
            max_density_kg_m3: self.max_density_kg_m3,
            hardness_kpa: self.hardness_kpa,
            ..SnowMechanics::default()
        }
    }
}

/// Footprint sizes the points technique accepts (texels per side).
pub const RANGE_TEXELS: std::ops::RangeInclusive<u32> = 32..=128;

/// What snowpack's own app, tools and tests read of [`SnowParams`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`SnowParams`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait SnowParamsExt: Sized {
    /// Number of texels in the window.
    #[must_use]
    fn texel_count(&self) -> usize;

    /// Checks every value; the error names the offending field.
    fn validate(&self) -> Result<(), SnowError>;
}

impl SnowParamsExt for SnowParams {
    fn texel_count(&self) -> usize {
        self.resolution as usize * self.resolution as usize
    }

    fn validate(&self) -> Result<(), SnowError> {
        let bad = |field: &'static str, why: String| Err(SnowError::InvalidParameter { field, why });
        if !RESOLUTION_RANGE.contains(&self.resolution) || !self.resolution.is_multiple_of(16) {
            return bad("resolution", format!("{} is not a multiple of 16 in {}..={}", self.resolution, RESOLUTION_RANGE.start(), RESOLUTION_RANGE.end()));
        }
        if !(self.extent_m.is_finite() && self.extent_m > 0.0) {
            return bad("extent_m", format!("{} must be a positive number of metres", self.extent_m));
        }
        if !(self.depth_m.is_finite() && self.depth_m >= 0.0) {
            return bad("depth_m", format!("{} must be zero or a positive number of metres", self.depth_m));
        }
        if !(self.refill_m_per_s.is_finite() && self.refill_m_per_s >= 0.0) {
            return bad("refill_m_per_s", format!("{} must be zero or positive", self.refill_m_per_s));
        }
        if !(self.teleport_m.is_finite() && self.teleport_m >= 0.0) {
            return bad("teleport_m", format!("{} must be zero or a positive number of metres", self.teleport_m));
        }
        if !(self.elevation.is_finite() && self.elevation >= 0.0) {
            return bad("elevation", format!("{} must be zero or positive", self.elevation));
        }
        if !(self.hardness_kpa.is_finite() && self.hardness_kpa > 0.0) {
            return bad("hardness_kpa", format!("{} must be a positive number of kPa", self.hardness_kpa));
        }
        if let Err((field, why)) = self.mechanics().validate() {
            return bad(field, why);
        }
        if let Some(r) = self.repose_deg
            && !(r.is_finite() && r > 0.0 && r < 90.0)
        {
            return bad("repose_deg", format!("{r} must be an angle between 0 and 90 degrees"));
        }
        if let Some(s) = &self.snowfall {
            s.validate()?;
        }
        if !RANGE_TEXELS.contains(&self.range_texels) {
            return bad("range_texels", format!("{} is outside {}..={}", self.range_texels, RANGE_TEXELS.start(), RANGE_TEXELS.end()));
        }
        Ok(())
    }
}
