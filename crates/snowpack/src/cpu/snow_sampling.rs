//! CPU twin of `shaders/shared/snow_sampling.wgsl`: the same samples of the
//! displayed surface (height, normal, depth, compaction) from a blocking read
//! of it ([`crate::SnowDeformation::read_surface`]), same operations in the
//! same order.

use glam::{Vec2, Vec3};

use crate::TerrainSource;
use crate::render::sampling::SnowWindowUniform;

/// A read-back displayed surface and where it lies.
#[derive(Clone, Copy, Debug)]
pub struct SampledSurface<'a> {
    /// The window, as bound at binding 0.
    pub window: SnowWindowUniform,
    /// Displayed height per texel, window-local row-major.
    pub heights: &'a [f32],
    /// Unit normal per texel, window-local row-major.
    pub normals: &'a [[f32; 3]],
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
        i * self.window.resolution as usize + j
    }

    fn bilinear(k: &Taps, a: f32, b: f32, c: f32, d: f32) -> f32 {
        mix(mix(a, b, k.f.x), mix(c, d, k.f.x), k.f.y)
    }

    fn taps(&self, xz: Vec2) -> Taps {
        let r = self.window.resolution as usize;
        let last = (r - 1) as f32;
        let t = ((xz - Vec2::from(self.window.corner)) / self.window.texel_m - 0.5).clamp(Vec2::ZERO, Vec2::splat(last));
        let c0 = t.floor();
        let (j0, i0) = (c0.x as usize, c0.y as usize);
        Taps { i0, j0, i1: (i0 + 1).min(r - 1), j1: (j0 + 1).min(r - 1), f: t - c0 }
    }

    /// Terrain height under the snow at `xz`.
    #[must_use]
    pub fn ground_height(&self, xz: Vec2) -> f32 {
        let p = xz + Vec2::from(self.window.floating_origin);
        self.terrain.height_at(p.x, p.y)
    }

    /// Untouched snow: terrain plus the rest depth.
    #[must_use]
    pub fn rest_height(&self, xz: Vec2) -> f32 {
        self.ground_height(xz) + self.window.rest_depth_m
    }

    /// Whether `xz` is inside the placed window.
    #[must_use]
    pub fn inside(&self, xz: Vec2) -> bool {
        let extent = self.window.resolution as f32 * self.window.texel_m;
        let q = xz - Vec2::from(self.window.corner);
        self.window.placed != 0 && q.cmpge(Vec2::ZERO).all() && q.cmple(Vec2::splat(extent)).all()
    }

    /// `snow_height`.
    #[must_use]
    pub fn height(&self, xz: Vec2) -> f32 {
        if !self.inside(xz) {
            return self.rest_height(xz);
        }
        let k = self.taps(xz);
        let h = |i, j| self.heights[self.at(i, j)];
        Self::bilinear(&k, h(k.i0, k.j0), h(k.i0, k.j1), h(k.i1, k.j0), h(k.i1, k.j1))
    }

    /// `snow_normal`.
    #[must_use]
    pub fn normal(&self, xz: Vec2) -> Vec3 {
        if !self.inside(xz) {
            let e = self.window.texel_m;
            let dx = self.rest_height(xz + Vec2::new(e, 0.0)) - self.rest_height(xz - Vec2::new(e, 0.0));
            let dz = self.rest_height(xz + Vec2::new(0.0, e)) - self.rest_height(xz - Vec2::new(0.0, e));
            return Vec3::new(-dx, 2.0 * e, -dz).normalize();
        }
        let k = self.taps(xz);
        let n = |i, j| Vec3::from(self.normals[self.at(i, j)]);
        let (a, b, c, d) = (n(k.i0, k.j0), n(k.i0, k.j1), n(k.i1, k.j0), n(k.i1, k.j1));
        a.lerp(b, k.f.x).lerp(c.lerp(d, k.f.x), k.f.y).normalize()
    }

    /// `snow_depth`.
    #[must_use]
    pub fn depth(&self, xz: Vec2) -> f32 {
        (self.height(xz) - self.ground_height(xz)).max(0.0)
    }

    fn texel_ground(&self, i: usize, j: usize) -> f32 {
        let (gx, gz) = (self.window.origin_texel[0] + j as i32, self.window.origin_texel[1] + i as i32);
        self.terrain.height_at((gx as f32 + 0.5) * self.window.texel_m, (gz as f32 + 0.5) * self.window.texel_m)
    }

    /// `snow_compaction`.
    #[must_use]
    pub fn compaction(&self, xz: Vec2) -> f32 {
        if !self.inside(xz) {
            return 0.0;
        }
        let k = self.taps(xz);
        let ground =
            Self::bilinear(&k, self.texel_ground(k.i0, k.j0), self.texel_ground(k.i0, k.j1), self.texel_ground(k.i1, k.j0), self.texel_ground(k.i1, k.j1));
        let depth = self.window.rest_depth_m;
        ((ground + depth - self.height(xz)) / depth.max(1e-4)).clamp(0.0, 1.0)
    }
}
