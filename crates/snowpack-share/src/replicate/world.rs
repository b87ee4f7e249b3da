//! A world's identity: the settings two machines must share for their snow
//! to merge. A peer of another world is refused, naming what differs.

use std::sync::Arc;

use crate::SNOW_QUANTUM_M;

use super::press::height_grid::HeightGrid;
use super::tile::ShareClock;

/// The settings that make a world: tiles from machines that agree on all of
/// them merge; anything else is refused (the relay names each difference).
///
/// Made by [`WorldIdentity::new`] (no GPU) or by snowpack's window
/// (`SnowDeformation::world_identity`); tools read and build one field by
/// field through [`WorldIdentityExt`] and [`WorldSettings`].
///
/// An identity found from a heightmap (a scene's, a window's) also holds
/// the heightmap, so this machine can press over it
/// ([`crate::replicate::press::PressGround::of_identity`]). The heightmap
/// is not sent and not compared: its digest in the settings is.
#[derive(Clone, Debug)]
pub struct WorldIdentity {
    pub(crate) settings: WorldSettings,
    /// The heightmap `settings.terrain` names, where this machine holds it
    /// (set only where the digest is checked or the name made from it:
    /// `holding`, `WorldTerrain::heightmap`).
    pub(crate) grid: Option<Arc<HeightGrid>>,
}

impl PartialEq for WorldIdentity {
    /// The same world: the same settings (the heightmap one side holds is
    /// named by its digest in them).
    fn eq(&self, other: &Self) -> bool {
        self.settings == other.settings
    }
}

/// A [`WorldIdentity`]'s settings as plain data, field by field: what the
/// relay's tools, the attack tests and the property tests read and build
/// ([`WorldIdentityExt::settings`], [`WorldIdentityExt::from_settings`]).
#[derive(Clone, Debug, PartialEq)]
pub struct WorldSettings {
    /// Side of a texel (m).
    pub texel_m: f32,
    /// Texels per tile side.
    pub tile_side: u32,
    /// The terrain, as `terrain_identity` describes it.
    pub terrain: String,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// Trail refill (m/s).
    pub refill_m_per_s: f32,
    /// Snowfall on open ground (m/s); 0 without snowfall.
    pub snowfall_m_per_s: f32,
    /// The most snowfall a texel keeps (m); 0 without snowfall.
    pub max_fallen_m: f32,
    /// Whether tiles carry the lying-snow plane: snowfall so far, and
    /// berms where presses displace snow.
    pub has_snowfall: bool,
    /// The footprint quantisation range (m): low and high.
    pub stamp_range_m: [f32; 2],
}

/// What the relay, the tools and the tests ask of a [`WorldIdentity`]
/// beyond a game's API (a named extension trait, so the identity has one
/// shape with or without `low_level`; `snowpack::low_level::WorldIdentityExt`
/// re-exports it).
pub trait WorldIdentityExt: Sized {
    /// The differences between `self` (here) and `other` (there), one
    /// phrase each ("tile side: 32 here, 64 there"); empty when they are
    /// the same world. Floats compare bit for bit.
    #[must_use]
    fn differences(&self, other: &Self) -> Vec<String>;

    /// The world clock at `time_s` seconds since the world began: the refill
    /// and snowfall every copy of the snow has had by then.
    #[must_use]
    fn clock_at(&self, time_s: f64) -> ShareClock;

    /// One footprint quantum (m): the range over 65535 steps.
    #[must_use]
    fn stamp_quantum_m(&self) -> f32;

    /// The identity's settings, field by field.
    #[must_use]
    fn settings(&self) -> &WorldSettings;

    /// An identity of `settings` as they are: a test's odd world, or a
    /// world another tool described field by field.
    #[must_use]
    fn from_settings(settings: WorldSettings) -> Self;

    /// The same world, holding `grid` when its terrain is the heightmap
    /// the settings name (by its digest); as it was otherwise. A window's
    /// identity holds its heightmap this way, so its peer presses over it.
    #[must_use]
    fn holding(self, grid: Arc<HeightGrid>) -> Self;
}

impl WorldIdentityExt for WorldIdentity {
    fn differences(&self, other: &Self) -> Vec<String> {
        let (here, there) = (&self.settings, &other.settings);
        let mut out = Vec::new();
        let mut f = |name: &str, a: f32, b: f32| {
            if a.to_bits() != b.to_bits() {
                out.push(format!("{name}: {a} here, {b} there"));
            }
        };
        f("texel size (m)", here.texel_m, there.texel_m);
        f("snow depth (m)", here.depth_m, there.depth_m);
        f("refill (m/s)", here.refill_m_per_s, there.refill_m_per_s);
        f("snowfall rate (m/s)", here.snowfall_m_per_s, there.snowfall_m_per_s);
        f("most snowfall kept (m)", here.max_fallen_m, there.max_fallen_m);
        f("footprint range low (m)", here.stamp_range_m[0], there.stamp_range_m[0]);
        f("footprint range high (m)", here.stamp_range_m[1], there.stamp_range_m[1]);
        if here.tile_side != there.tile_side {
            out.push(format!("tile side: {} here, {} there", here.tile_side, there.tile_side));
        }
        if here.has_snowfall != there.has_snowfall {
            out.push(format!("lying snow (snowfall or berms): {} here, {} there", on_off(here.has_snowfall), on_off(there.has_snowfall)));
        }
        if here.terrain != there.terrain {
            out.push(format!("terrain: {} here, {} there", here.terrain, there.terrain));
        }
        out
    }

    fn clock_at(&self, time_s: f64) -> ShareClock {
        let here = &self.settings;
        let t = time_s.max(0.0);
        let refill_m = f64::from(here.refill_m_per_s.max(0.0)) * t;
        let quantum = f64::from(self.stamp_quantum_m());
        ShareClock {
            time_s: t,
            refill_quanta: (refill_m / f64::from(SNOW_QUANTUM_M)).floor() as u64,
            stamp_quanta: if quantum > 0.0 { (refill_m / quantum).floor() as u64 } else { 0 },
            fallen_m: if here.has_snowfall { (f64::from(here.snowfall_m_per_s.max(0.0)) * t).min(f64::from(here.max_fallen_m)) as f32 } else { 0.0 },
        }
    }

    fn stamp_quantum_m(&self) -> f32 {
        let [low, high] = self.settings.stamp_range_m;
        (high - low) / 65_535.0
    }

    fn settings(&self) -> &WorldSettings {
        &self.settings
    }

    fn from_settings(settings: WorldSettings) -> Self {
        Self { settings, grid: None }
    }

    fn holding(self, grid: Arc<HeightGrid>) -> Self {
        if self.settings.terrain == grid.terrain_identity() { Self { grid: Some(grid), ..self } } else { self }
    }
}

/// Margin of the footprint (capture) height range beyond the terrain and the snow (m).
const FOOTPRINT_MARGIN_M: f32 = 1.0;

/// The footprint quantisation range (low, high) in m over terrain whose
/// heights span `tmin..=tmax`, under snow at most `deepest_m` deep (the rest
/// depth plus the most snowfall kept): the window's capture range and a
/// world's [`WorldIdentity`] alike, so that a world found without a window
/// is the window's.
///
/// The top is above the snow by the margin, and high enough that a stored
/// footprint's rim has fallen to zero below it: the rounded rim ends where
/// `h = foot + 4 (rest - foot)`, at most `4 rest - 3 low`. A footprint
/// clipped at a lower top would keep a non-zero rim out to the edge of its
/// range and leave a ridge there.
#[must_use]
pub fn footprint_range_m(deepest_m: f32, (tmin, tmax): (f32, f32)) -> (f32, f32) {
    let low = tmin - FOOTPRINT_MARGIN_M;
    let rest = tmax + deepest_m;
    (low, (rest + FOOTPRINT_MARGIN_M).max(4.0 * rest - 3.0 * low))
}

/// The snow of a world as [`WorldIdentity::new`] takes it: the settings
/// every machine of the world agrees on, without the GPU library's types
/// (a dedicated server knows its world from these; snowpack's
/// `SnowDeformation::world_identity_for` gives the same identity from a
/// `SnowParams`).
#[derive(Clone, Debug, PartialEq)]
pub struct WorldSnow {
    /// Side of a texel (m): the window's extent over its resolution.
    pub texel_m: f32,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// Trail refill (m/s).
    pub refill_m_per_s: f32,
    /// Snowfall on open ground; `None` without it.
    pub snowfall: Option<WorldSnowfall>,
    /// Whether presses displace snow into berms (snow lying on the rest
    /// surface, shared in the tiles' snowfall plane like snowfall).
    pub displace: bool,
}

/// Snowfall in a [`WorldSnow`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldSnowfall {
    /// Rate on open ground (m/s).
    pub rate_m_per_s: f32,
    /// The most snowfall a texel keeps (m).
    pub max_m: f32,
}

/// The ground under a world's snow, as two machines agree on it: a
/// description (the kind and its parameters, or a digest of sampled
/// heights) and the span of its heights.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldTerrain {
    description: String,
    heights_m: (f32, f32),
    grid: Option<Arc<HeightGrid>>,
}

impl WorldTerrain {
    /// Flat ground at `height_m`.
    #[must_use]
    pub fn flat(height_m: f32) -> Self {
        Self { description: format!("flat at {height_m} m"), heights_m: (height_m, height_m), grid: None }
    }

    /// snowpack's value-noise terrain (`NoiseTerrain`) of these parameters.
    #[must_use]
    pub fn noise(seed: u32, base_m: f32, amplitude_m: f32, wavelength_m: f32) -> Self {
        Self {
            description: format!("noise seed {seed} base {base_m} m amplitude {amplitude_m} m wavelength {wavelength_m} m"),
            heights_m: (base_m - amplitude_m.abs(), base_m + amplitude_m.abs()),
            grid: None,
        }
    }

    /// A heightmap, named by its digest ([`HeightGrid::terrain_identity`]);
    /// the identity made of it holds the grid, so presses travel over it
    /// where the relay holds it too.
    #[must_use]
    pub fn heightmap(grid: Arc<HeightGrid>) -> Self {
        Self { description: grid.terrain_identity(), heights_m: grid.height_range(), grid: Some(grid) }
    }

    /// Any other ground: `description` is what machines compare (snowpack's
    /// `terrain_identity`, a digest of a heightmap's or a mesh's heights),
    /// `heights_m` the lowest and highest height (m).
    #[must_use]
    pub fn described(description: String, heights_m: (f32, f32)) -> Self {
        Self { description, heights_m, grid: None }
    }
}

impl WorldIdentity {
    /// The world of `snow` over `terrain`, shared in tiles of `tile_side`
    /// texels. No GPU and no window: what a dedicated server pins
    /// ([`crate::SnowRelay::pin_world`]).
    #[must_use]
    pub fn new(snow: &WorldSnow, terrain: &WorldTerrain, tile_side: u32) -> Self {
        let fall = snow.snowfall;
        let deepest = snow.depth_m + fall.map_or(0.0, |f| f.max_m);
        let (low, high) = footprint_range_m(deepest, terrain.heights_m);
        let settings = WorldSettings {
            texel_m: snow.texel_m,
            tile_side,
            terrain: terrain.description.clone(),
            depth_m: snow.depth_m,
            refill_m_per_s: snow.refill_m_per_s,
            snowfall_m_per_s: fall.map_or(0.0, |f| f.rate_m_per_s),
            max_fallen_m: fall.map_or(0.0, |f| f.max_m),
            has_snowfall: fall.is_some() || snow.displace,
            stamp_range_m: [low, high],
        };
        Self { settings, grid: terrain.grid.clone() }
    }
}

fn on_off(b: bool) -> &'static str {
    if b { "on" } else { "off" }
}
