//! The ground under the snow: flat, procedural noise or a heightmap.
//!
//! The same description is evaluated on the GPU (by the window pass, for newly
//! exposed texels; see `shaders/shared/terrain.wgsl`) and on the CPU (physics,
//! queries and the CPU twins). The two evaluations use the same `f32` operations
//! in the same order, so they agree to within rounding (tests use 1e-4 m).

use glam::Vec3;

/// Value-noise terrain: `base_m + amplitude_m * fbm(x / wavelength_m, z / wavelength_m)`,
/// with a four-octave fractal sum normalised to `[-1, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseTerrain {
    /// Seed of the lattice hash; different seeds give unrelated terrains.
    pub seed: u32,
    /// Height of the terrain where the noise is zero (m).
    pub base_m: f32,
    /// Largest deviation from `base_m` (m).
    pub amplitude_m: f32,
    /// Horizontal size of the largest features (m).
    pub wavelength_m: f32,
}

/// A grid of heights covering a square of the world, sampled bilinearly between
/// pixel centres and clamped at its edges.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightmapTerrain {
    /// Pixels per row.
    pub width: u32,
    /// Rows; row `r` lies at larger world z than row `r - 1`.
    pub height: u32,
    /// Heights in metres, row-major, `width * height` values.
    pub heights_m: Vec<f32>,
    /// World (x, z) of the centre of the covered area (m).
    pub center_m: [f32; 2],
    /// World size (x, z) of the covered area (m).
    pub size_m: [f32; 2],
}

/// Where the terrain's height comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum TerrainSource {
    /// A horizontal plane at this height (m).
    Flat {
        /// World height of the plane (m).
        height_m: f32,
    },
    /// Procedural value noise.
    Noise(NoiseTerrain),
    /// A sampled heightmap (for example a 16-bit PNG).
    Heightmap(HeightmapTerrain),
}

/// Number of octaves of the fractal noise; must match `shared/terrain.wgsl`.
pub const NOISE_OCTAVES: u32 = 4;

/// The lattice hash shared with `shared/terrain.wgsl` (a murmur-style finaliser).
#[must_use]
pub fn lattice_hash(ix: i32, iz: i32, seed: u32) -> u32 {
    let mut h = (ix as u32).wrapping_mul(0x8da6_b343)
        ^ (iz as u32).wrapping_mul(0xd816_3841)
        ^ seed.wrapping_mul(0xcb1a_b31f);
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
    let mut norm = 0.0_f32;
    for octave in 0..NOISE_OCTAVES {
        sum += amp * value_noise(x * freq, z * freq, seed.wrapping_add(octave));
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

impl HeightmapTerrain {
    /// Bilinear height at world (x, z), clamped to the edge pixels outside the covered area.
    #[must_use]
    pub fn height_at(&self, x: f32, z: f32) -> f32 {
        let (w, h) = (self.width as i32, self.height as i32);
        // Continuous pixel coordinates with pixel centres at integer + 0.5.
        let u = ((x - self.center_m[0]) / self.size_m[0] + 0.5) * self.width as f32 - 0.5;
        let v = ((z - self.center_m[1]) / self.size_m[1] + 0.5) * self.height as f32 - 0.5;
        let u = u.clamp(0.0, (w - 1) as f32);
        let v = v.clamp(0.0, (h - 1) as f32);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let (i0, j0) = (v0 as i32, u0 as i32);
        let (i1, j1) = ((i0 + 1).min(h - 1), (j0 + 1).min(w - 1));
        let at = |i: i32, j: i32| self.heights_m[(i * w + j) as usize];
        let a = at(i0, j0);
        let b = at(i0, j1);
        let c = at(i1, j0);
        let d = at(i1, j1);
        let ab = a + (b - a) * fu;
        let cd = c + (d - c) * fu;
        ab + (cd - ab) * fv
    }
}

impl TerrainSource {
    /// Terrain height (m) at world (x, z).
    #[must_use]
    pub fn height_at(&self, x: f32, z: f32) -> f32 {
        match self {
            Self::Flat { height_m } => *height_m,
            Self::Noise(n) => {
                n.base_m + n.amplitude_m * fbm(x / n.wavelength_m, z / n.wavelength_m, n.seed)
            }
            Self::Heightmap(hm) => hm.height_at(x, z),
        }
    }

    /// Unit surface normal at world (x, z), by central differences over `eps_m`.
    #[must_use]
    pub fn normal_at(&self, x: f32, z: f32, eps_m: f32) -> Vec3 {
        let dx = self.height_at(x + eps_m, z) - self.height_at(x - eps_m, z);
        let dz = self.height_at(x, z + eps_m) - self.height_at(x, z - eps_m);
        Vec3::new(-dx, 2.0 * eps_m, -dz).normalize()
    }

    /// Lowest and highest height the terrain can have anywhere (m).
    #[must_use]
    pub fn height_bounds(&self) -> (f32, f32) {
        match self {
            Self::Flat { height_m } => (*height_m, *height_m),
            Self::Noise(n) => (n.base_m - n.amplitude_m.abs(), n.base_m + n.amplitude_m.abs()),
            Self::Heightmap(hm) => hm
                .heights_m
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| (lo.min(h), hi.max(h))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fbm_stays_in_range_and_varies() {
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for i in 0..200 {
            for j in 0..200 {
                let v = fbm(i as f32 * 0.173 - 17.0, j as f32 * 0.091 - 9.0, 3);
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        assert!(lo >= -1.0 && hi <= 1.0, "fbm out of range: {lo}..{hi}");
        assert!(hi - lo > 0.8, "fbm nearly constant: {lo}..{hi}");
    }

    #[test]
    fn heightmap_interpolates_between_pixel_centres() {
        let hm = HeightmapTerrain {
            width: 2,
            height: 1,
            heights_m: vec![0.0, 2.0],
            center_m: [0.0, 0.0],
            size_m: [2.0, 2.0],
        };
        // Pixel centres at x = -0.5 and x = 0.5.
        assert!((hm.height_at(-0.5, 0.0) - 0.0).abs() < 1e-6);
        assert!((hm.height_at(0.0, 0.0) - 1.0).abs() < 1e-6);
        assert!((hm.height_at(0.5, 0.0) - 2.0).abs() < 1e-6);
        assert!((hm.height_at(5.0, 0.0) - 2.0).abs() < 1e-6);
    }
}
