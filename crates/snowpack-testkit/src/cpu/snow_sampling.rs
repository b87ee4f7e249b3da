//! CPU twin of `shaders/snow_sampling.wgsl`: the same samples of the
//! displayed surface (height, normal, depth, compaction) from a blocking read
//! of the snow words ([`snowpack::low_level::snow::inspect::SnowInspect::read_snow_words`]), same
//! operations in the same order.

use glam::{Vec2, Vec3};

use snowpack::SnowWindowUniform;
use snowpack::TerrainSource;
use snowpack::low_level::SnowWindowUniformExt;

/// A read-back displayed surface and where it lies.
#[derive(Clone, Copy, Debug)]
pub struct SampledSurface<'a> {
    /// The window, as bound at binding 0.
    pub window: SnowWindowUniform,
    /// Displayed height above the terrain per texel, window-local row-major
    /// ([`above_ground`]).
    pub above: &'a [f32],
    /// The terrain under the snow.
    pub terrain: &'a TerrainSource,
}

struct Taps {
    i0: usize,
    j0: usize,
    i1: usize,
    j1: usize,
    f: Vec2,
}

fn mix(a: f32, b: f32, t: f32) -> f32 {
    // WGSL's mix: a * (1 - t) + b * t.
    a * (1.0 - t) + b * t
}

impl SampledSurface<'_> {
    fn at(&self, i: usize, j: usize) -> usize {
        i * self.window.resolution() as usize + j
    }

    fn bilinear(k: &Taps, a: f32, b: f32, c: f32, d: f32) -> f32 {
        mix(mix(a, b, k.f.x), mix(c, d, k.f.x), k.f.y)
    }

    fn taps(&self, xz: Vec2) -> Taps {
        let r = self.window.resolution() as usize;
        let last = (r - 1) as f32;
        let t = ((xz - Vec2::from(self.window.corner())) / self.window.texel_m() - 0.5).clamp(Vec2::ZERO, Vec2::splat(last));
        let c0 = t.floor();
        let (j0, i0) = (c0.x as usize, c0.y as usize);
        Taps { i0, j0, i1: (i0 + 1).min(r - 1), j1: (j0 + 1).min(r - 1), f: t - c0 }
    }

    /// Terrain height under the snow at `xz`.
    #[must_use]
    pub fn ground_height(&self, xz: Vec2) -> f32 {
        let p = xz + Vec2::from(self.window.floating_origin());
        self.terrain.height_at(p.x, p.y)
    }

    /// Untouched snow: terrain plus the rest depth.
    #[must_use]
    pub fn rest_height(&self, xz: Vec2) -> f32 {
        self.ground_height(xz) + self.window.rest_depth_m()
    }

    /// Whether `xz` is inside the placed window.
    #[must_use]
    pub fn inside(&self, xz: Vec2) -> bool {
        let extent = self.window.resolution() as f32 * self.window.texel_m();
        let q = xz - Vec2::from(self.window.corner());
        self.window.placed() && q.cmpge(Vec2::ZERO).all() && q.cmple(Vec2::splat(extent)).all()
    }

    fn above_at(&self, i: i32, j: i32) -> f32 {
        let last = self.window.resolution() as i32 - 1;
        self.above[self.at(i.clamp(0, last) as usize, j.clamp(0, last) as usize)]
    }

    fn above_bilinear(&self, k: &Taps) -> f32 {
        let a = |i: usize, j: usize| self.above[self.at(i, j)];
        Self::bilinear(k, a(k.i0, k.j0), a(k.i0, k.j1), a(k.i1, k.j0), a(k.i1, k.j1))
    }

    /// `snow_height`.
    #[must_use]
    pub fn height(&self, xz: Vec2) -> f32 {
        if !self.inside(xz) {
            return self.rest_height(xz);
        }
        let k = self.taps(xz);
        let g = |i, j| self.texel_ground(i, j);
        Self::bilinear(&k, g(k.i0, k.j0), g(k.i0, k.j1), g(k.i1, k.j0), g(k.i1, k.j1)) + self.above_bilinear(&k)
    }

    /// `snow_normal`.
    #[must_use]
    pub fn normal(&self, xz: Vec2) -> Vec3 {
        let e = self.window.texel_m();
        let mut dx = self.ground_height(xz + Vec2::new(e, 0.0)) - self.ground_height(xz - Vec2::new(e, 0.0));
        let mut dz = self.ground_height(xz + Vec2::new(0.0, e)) - self.ground_height(xz - Vec2::new(0.0, e));
        if self.inside(xz) {
            let k = self.taps(xz);
            let (i0, j0, i1, j1) = (k.i0 as i32, k.j0 as i32, k.i1 as i32, k.j1 as i32);
            let ddx = |i, j| self.above_at(i, j + 1) - self.above_at(i, j - 1);
            let ddz = |i, j| self.above_at(i + 1, j) - self.above_at(i - 1, j);
            dx += Self::bilinear(&k, ddx(i0, j0), ddx(i0, j1), ddx(i1, j0), ddx(i1, j1));
            dz += Self::bilinear(&k, ddz(i0, j0), ddz(i0, j1), ddz(i1, j0), ddz(i1, j1));
        }
        Vec3::new(-dx, 2.0 * e, -dz).normalize()
    }

    /// `snow_depth`.
    #[must_use]
    pub fn depth(&self, xz: Vec2) -> f32 {
        (self.height(xz) - self.ground_height(xz)).max(0.0)
    }

    fn texel_ground(&self, i: usize, j: usize) -> f32 {
        let (gx, gz) = (self.window.origin_texel()[0] + j as i32, self.window.origin_texel()[1] + i as i32);
        self.terrain.height_at((gx as f32 + 0.5) * self.window.texel_m(), (gz as f32 + 0.5) * self.window.texel_m())
    }

    /// `snow_compaction`.
    #[must_use]
    pub fn compaction(&self, xz: Vec2) -> f32 {
        if !self.inside(xz) {
            return 0.0;
        }
        let depth = self.window.rest_depth_m();
        ((depth - self.above_bilinear(&self.taps(xz))) / depth.max(1e-4)).clamp(0.0, 1.0)
    }
}

/// The displayed height above the terrain per texel from snow words in
/// window-local order ([`snowpack::low_level::snow::inspect::SnowInspect::read_snow_words`]).
#[must_use]
pub fn above_ground(words: &[u32]) -> Vec<f32> {
    words.iter().map(|w| snowpack::low_level::deform::snow_word::f16_to_f32(w >> 16)).collect()
}
