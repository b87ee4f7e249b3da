//! CPU queries of snow height and depth, answered from the readback ring a few
//! frames late (never stalling the GPU).

use crate::TerrainSource;

/// A copy of the persistent snow height as it was at one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SnowSnapshot {
    /// Global texel index `[column, row]` of the window's local (0, 0) at that frame.
    pub origin: [i64; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Texel size (m).
    pub texel_m: f64,
    /// The frame the data belongs to (counting from 0).
    pub frame: u64,
    /// Heights in toroidal storage order.
    pub heights: Vec<f32>,
}

impl SnowSnapshot {
    /// Snow height of the global texel (column, row), if it was inside the window.
    #[must_use]
    pub fn texel(&self, col: i64, row: i64) -> Option<f32> {
        let r = i64::from(self.resolution);
        let (lc, lr) = (col - self.origin[0], row - self.origin[1]);
        if !(0..r).contains(&lc) || !(0..r).contains(&lr) {
            return None;
        }
        let (sc, sr) = (col.rem_euclid(r), row.rem_euclid(r));
        self.heights.get((sr * r + sc) as usize).copied()
    }

    /// Snow surface height (m) at world (x, z), bilinear between texel centres;
    /// `None` outside the window (or within half a texel of its edge).
    #[must_use]
    pub fn height_at(&self, x: f64, z: f64) -> Option<f32> {
        let u = x / self.texel_m - 0.5;
        let v = z / self.texel_m - 0.5;
        let (c0, r0) = (u.floor(), v.floor());
        let (fu, fv) = ((u - c0) as f32, (v - r0) as f32);
        let (c0, r0) = (c0 as i64, r0 as i64);
        let a = self.texel(c0, r0)?;
        let b = self.texel(c0 + 1, r0)?;
        let c = self.texel(c0, r0 + 1)?;
        let d = self.texel(c0 + 1, r0 + 1)?;
        let ab = a + (b - a) * fu;
        let cd = c + (d - c) * fu;
        Some(ab + (cd - ab) * fv)
    }

    /// Snow depth (m) above the terrain at world (x, z).
    #[must_use]
    pub fn depth_at(&self, terrain: &TerrainSource, x: f64, z: f64) -> Option<f32> {
        self.height_at(x, z).map(|h| (h - terrain.height_at(x as f32, z as f32)).max(0.0))
    }
}
