//! The terrain presses are pressed over, as a machine knows it: from the
//! world's identity (`"flat at H m"`, or the value noise `"noise seed S
//! base B m amplitude A m wavelength W m"`, which the identity names
//! whole), or from a heightmap the machine holds ([`HeightGrid`]) whose
//! digest the identity names (`"heightmap D"`). A machine without the
//! heightmap (a relay that knows the world from its store alone) cannot
//! press there, and says so (`docs/multiplayer.md`, "Presses"); a mesh's
//! grid is drawn on the GPU, which a CPU does not repeat bit for bit, so
//! mesh worlds share tiles.
//!
//! The noise and the heightmap's sampling are the ones
//! `shared/terrain.wgsl` evaluates under every texel (snowpack's `terrain`
//! module uses these functions; one copy for the window's CPU twins and
//! for the presses).

use std::sync::Arc;

pub use super::height_grid::{HEIGHT_GRID_MAX_SIDE, HeightGrid, HeightGridError};
use crate::replicate::world::{WorldIdentity, WorldSettings};

/// Number of octaves of the fractal noise; must match `shared/terrain.wgsl`.
const NOISE_OCTAVES: u32 = 4;
/// 1 / (1 + 1/2 + 1/4 + 1/8): the fractal sum is normalised by a multiply,
/// as the shader does (a GPU's division may round otherwise).
const NOISE_NORM: f32 = 0.533_333_36;

// The same operations in the same order as `shared/terrain.wgsl`, with no
// division (a GPU's may round otherwise). A GPU that fuses a multiply and an
// add may find a height an ulp apart; the presses do not depend on it
// where it matters: the deficit at the terrain comes from the rest column,
// not from the rest height less the terrain (`ground_quanta`).

/// The lattice hash shared with `shared/terrain.wgsl` (a murmur-style finaliser).
#[must_use]
pub fn lattice_hash(ix: i32, iz: i32, seed: u32) -> u32 {
    let mut h = (ix as u32).wrapping_mul(0x8da6_b343) ^ (iz as u32).wrapping_mul(0xd816_3841) ^ seed.wrapping_mul(0xcb1a_b31f);
    h = (h ^ (h >> 16)).wrapping_mul(0x7feb_352d);
    h = (h ^ (h >> 15)).wrapping_mul(0x846c_a68b);
    h ^ (h >> 16)
}

fn lattice_value(ix: i32, iz: i32, seed: u32) -> f32 {
    ((lattice_hash(ix, iz, seed) >> 8) as f32) * (2.0 / 16_777_216.0) - 1.0
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Single-octave value noise in `[-1, 1]` at lattice coordinates (x, z).
#[must_use]
pub fn value_noise(x: f32, z: f32, seed: u32) -> f32 {
    let fx = x.floor();
    let fz = z.floor();
    let ix = fx as i32;
    let iz = fz as i32;
    let tx = fade(x - fx);
    let tz = fade(z - fz);
    let a = lattice_value(ix, iz, seed);
    let b = lattice_value(ix + 1, iz, seed);
    let c = lattice_value(ix, iz + 1, seed);
    let d = lattice_value(ix + 1, iz + 1, seed);
    let ab = a + (b - a) * tx;
    let cd = c + (d - c) * tx;
    ab + (cd - ab) * tz
}

/// Four-octave fractal sum of [`value_noise`], normalised to `[-1, 1]`.
#[must_use]
pub fn fbm(x: f32, z: f32, seed: u32) -> f32 {
    let mut sum = 0.0_f32;
    let mut amp = 1.0_f32;
    let mut freq = 1.0_f32;
    for octave in 0..NOISE_OCTAVES {
        sum += amp * value_noise(x * freq, z * freq, seed.wrapping_add(octave));
        amp *= 0.5;
        freq *= 2.0;
    }
    sum * NOISE_NORM
}

/// Terrain height (m) at world (x, z) of the value noise: `base_m +
/// amplitude_m × fbm(x / wavelength_m, z / wavelength_m, seed)`, the
/// division a multiply by the reciprocal, as `shared/terrain.wgsl` does.
#[must_use]
pub fn noise_height(x: f32, z: f32, (seed, base_m, amplitude_m, wavelength_m): (u32, f32, f32, f32)) -> f32 {
    let per_wavelength = 1.0 / wavelength_m;
    base_m + amplitude_m * fbm(x * per_wavelength, z * per_wavelength, seed)
}

/// The terrain under the presses: one a world's identity names whole, or
/// a heightmap this machine holds.
#[derive(Clone, Debug, PartialEq)]
pub enum PressGround {
    /// A horizontal plane at this height (m).
    Flat(f32),
    /// Value noise: `base_m + amplitude_m × fbm(x / wavelength_m, z / wavelength_m, seed)`.
    Noise {
        /// The noise's seed.
        seed: u32,
        /// Height of the noise's middle (m).
        base_m: f32,
        /// Its amplitude (m).
        amplitude_m: f32,
        /// Its wavelength (m; positive).
        wavelength_m: f32,
    },
    /// A heightmap whose digest the world's identity names.
    Heightmap(Arc<HeightGrid>),
}

impl PressGround {
    /// The terrain of `world` as its identity names it (snowpack's
    /// `terrain_identity`): flat or value noise, with finite numbers;
    /// `None` for any other terrain.
    #[must_use]
    pub fn of_world(world: &WorldSettings) -> Option<Self> {
        let t = world.terrain.as_str();
        if let Some(h) = t.strip_prefix("flat at ").and_then(|r| r.strip_suffix(" m")) {
            return h.parse::<f32>().ok().filter(|h| h.is_finite()).map(Self::Flat);
        }
        let words: Vec<&str> = t.strip_prefix("noise seed ")?.split(' ').collect();
        let [seed, "base", base, "m", "amplitude", amplitude, "m", "wavelength", wavelength, "m"] = words.as_slice() else {
            return None;
        };
        let metres = |w: &str| w.parse::<f32>().ok().filter(|v| v.is_finite());
        let (base_m, amplitude_m, wavelength_m) = (metres(base)?, metres(amplitude)?, metres(wavelength).filter(|w| *w > 0.0)?);
        Some(Self::Noise { seed: seed.parse().ok()?, base_m, amplitude_m, wavelength_m })
    }

    /// The terrain of `world` as this machine can press over it: what its
    /// settings name whole ([`Self::of_world`]), or the heightmap it holds
    /// whose digest they name (a world found from a scene or a window;
    /// one decoded from the wire or a store holds none).
    #[must_use]
    pub fn of_identity(world: &WorldIdentity) -> Option<Self> {
        // An identity holds only the grid its terrain names (`holding`,
        // `WorldTerrain::heightmap`).
        Self::of_world(&world.settings).or_else(|| world.grid.as_ref().map(|grid| Self::Heightmap(Arc::clone(grid))))
    }

    /// Terrain height (m) at the centre of global texel `g` (column, row)
    /// of `texel_m` texels, as `texel_ground` in `shared/terrain_kind.wgsl`
    /// finds it (the window's texels are i32 there).
    #[must_use]
    pub fn at_texel(&self, g: [i64; 2], texel_m: f32) -> f32 {
        // The texel's centre, as `texel_ground` finds it.
        let x = (g[0] as i32 as f32 + 0.5) * texel_m;
        let z = (g[1] as i32 as f32 + 0.5) * texel_m;
        match *self {
            Self::Flat(h) => h,
            Self::Noise { seed, base_m, amplitude_m, wavelength_m } => noise_height(x, z, (seed, base_m, amplitude_m, wavelength_m)),
            Self::Heightmap(ref grid) => grid.height_at(x, z),
        }
    }
}
