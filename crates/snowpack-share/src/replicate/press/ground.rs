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

/// Largest side of a [`HeightGrid`] (samples): wgpu's default texture limit.
pub const HEIGHT_GRID_MAX_SIDE: u32 = 8192;

/// A heightmap as every machine samples it: `width × height` heights
/// (row `r` at larger world z than row `r - 1`) covering `size_m` (x, z)
/// metres centred on `center_m`, sampled bilinearly between sample centres
/// and clamped at the edges ([`HeightGrid::height_at`], the twin of
/// `heightmap_at` in `shared/terrain.wgsl`). Checked when made, so
/// sampling never fails; its digest is computed once.
#[derive(Clone, PartialEq)]
pub struct HeightGrid {
    width: u32,
    height: u32,
    heights_m: Vec<f32>,
    center_m: [f32; 2],
    size_m: [f32; 2],
    /// `1 / size_m`, rounded once: the sampling multiplies by it, as the
    /// shader does (a GPU's division may round otherwise).
    per_size_m: [f32; 2],
    digest: u64,
}

impl std::fmt::Debug for HeightGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeightGrid")
            .field("samples", &(self.width, self.height))
            .field("center_m", &self.center_m)
            .field("size_m", &self.size_m)
            .field("digest", &format_args!("{:016x}", self.digest))
            .finish()
    }
}

/// A [`HeightGrid`] that cannot be made: which of its inputs (`heightmap`,
/// `heightmap size_m`, `heightmap center_m`) and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("invalid {field}: {why}")]
pub struct HeightGridError {
    /// The input at fault, as a scene names it.
    pub field: &'static str,
    /// Why it is refused.
    pub why: String,
}

impl HeightGrid {
    /// A grid of `width × height` samples, `heights_m` row-major. Refused,
    /// naming what is wrong: a zero side or one above
    /// [`HEIGHT_GRID_MAX_SIDE`], a sample count other than `width ×
    /// height`, a height that is not finite, a size that is not positive
    /// and finite (or whose inverse is not), a centre that is not finite.
    pub fn new(width: u32, height: u32, heights_m: Vec<f32>, center_m: [f32; 2], size_m: [f32; 2]) -> Result<Self, HeightGridError> {
        let bad = |field: &'static str, why: String| Err(HeightGridError { field, why });
        if width == 0 || height == 0 {
            return bad("heightmap", format!("{width}x{height} pixels: both sides must be at least 1"));
        }
        if width > HEIGHT_GRID_MAX_SIDE || height > HEIGHT_GRID_MAX_SIDE {
            return bad("heightmap", format!("{width}x{height} pixels: at most {HEIGHT_GRID_MAX_SIDE} on a side are supported"));
        }
        let count = u64::from(width) * u64::from(height);
        if heights_m.len() as u64 != count {
            return bad("heightmap", format!("{} heights for {width}x{height} pixels (needs {count})", heights_m.len()));
        }
        if let Some(k) = heights_m.iter().position(|h| !h.is_finite()) {
            return bad("heightmap", format!("height {} at pixel {k} is not a finite number of metres", heights_m[k]));
        }
        let per_size_m = size_m.map(|s| 1.0 / s);
        if !size_m.iter().chain(&per_size_m).all(|s| s.is_finite() && *s > 0.0) {
            return bad("heightmap size_m", format!("{size_m:?} must be two positive, finite sizes in metres"));
        }
        if !center_m.iter().all(|c| c.is_finite()) {
            return bad("heightmap center_m", format!("{center_m:?} must be finite"));
        }
        let digest = digest([width, height, center_m[0].to_bits(), center_m[1].to_bits(), size_m[0].to_bits(), size_m[1].to_bits()], &heights_m);
        Ok(Self { width, height, heights_m, center_m, size_m, per_size_m, digest })
    }

    /// Samples per row.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Heights (m), row-major, `width × height` of them.
    #[must_use]
    pub fn heights_m(&self) -> &[f32] {
        &self.heights_m
    }

    /// World (x, z) of the covered area's centre (m).
    #[must_use]
    pub fn center_m(&self) -> [f32; 2] {
        self.center_m
    }

    /// World size (x, z) of the covered area (m).
    #[must_use]
    pub fn size_m(&self) -> [f32; 2] {
        self.size_m
    }

    /// `1 / size_m`, as the sampling and the shader's uniforms use it.
    #[must_use]
    pub fn per_size_m(&self) -> [f32; 2] {
        self.per_size_m
    }

    /// An FNV-1a digest of the size, placement and heights (their bits):
    /// two machines with the same heightmap agree on it, and the world's
    /// identity names the terrain by it ([`Self::terrain_identity`]).
    #[must_use]
    pub fn digest(&self) -> u64 {
        self.digest
    }

    /// The terrain as a world's identity names it: `"heightmap D"`, the
    /// digest in 16 hex digits.
    #[must_use]
    pub fn terrain_identity(&self) -> String {
        format!("heightmap {:016x}", self.digest)
    }

    /// Lowest and highest sample (m).
    #[must_use]
    pub fn height_range(&self) -> (f32, f32) {
        self.heights_m.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| (lo.min(h), hi.max(h)))
    }

    /// Bilinear height (m) at world (x, z), clamped to the edge samples
    /// outside the covered area: `heightmap_at` in `shared/terrain.wgsl`,
    /// the same operations in the same order, with no division.
    #[must_use]
    pub fn height_at(&self, x: f32, z: f32) -> f32 {
        let (w, h) = (self.width as i32, self.height as i32);
        // Continuous sample coordinates with sample centres at integer + 0.5.
        let u = ((x - self.center_m[0]) * self.per_size_m[0] + 0.5) * self.width as f32 - 0.5;
        let v = ((z - self.center_m[1]) * self.per_size_m[1] + 0.5) * self.height as f32 - 0.5;
        let u = u.clamp(0.0, (w - 1) as f32);
        let v = v.clamp(0.0, (h - 1) as f32);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let (i0, j0) = (v0 as i32, u0 as i32);
        let (i1, j1) = ((i0 + 1).min(h - 1), (j0 + 1).min(w - 1));
        let at = |i: i32, j: i32| self.heights_m[(i * w + j) as usize];
        let (a, b, c, d) = (at(i0, j0), at(i0, j1), at(i1, j0), at(i1, j1));
        let ab = a + (b - a) * fu;
        let cd = c + (d - c) * fu;
        ab + (cd - ab) * fv
    }
}

/// FNV-1a over `header`'s words and then `heights`' bits, each little-endian.
fn digest(header: [u32; 6], heights: &[f32]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for w in header.into_iter().chain(heights.iter().map(|v| v.to_bits())) {
        for b in w.to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
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
        Self::of_world(&world.settings).or_else(|| {
            let grid = world.grid.as_ref()?;
            (world.settings.terrain == grid.terrain_identity()).then(|| Self::Heightmap(Arc::clone(grid)))
        })
    }

    /// Terrain height (m) at the centre of global texel `g` (column, row)
    /// of `texel_m` texels, as `texel_ground` in `shared/terrain_kind.wgsl`
    /// finds it (the window's texels are i32 there).
    #[must_use]
    pub fn at_texel(&self, g: [i64; 2], texel_m: f32) -> f32 {
        match *self {
            Self::Flat(h) => h,
            Self::Noise { seed, base_m, amplitude_m, wavelength_m } => {
                let x = (g[0] as i32 as f32 + 0.5) * texel_m;
                let z = (g[1] as i32 as f32 + 0.5) * texel_m;
                noise_height(x, z, (seed, base_m, amplitude_m, wavelength_m))
            }
            Self::Heightmap(ref grid) => {
                let x = (g[0] as i32 as f32 + 0.5) * texel_m;
                let z = (g[1] as i32 as f32 + 0.5) * texel_m;
                grid.height_at(x, z)
            }
        }
    }
}
