//! The ground under the snow: flat, procedural noise, a heightmap or any triangle mesh.
//!
//! The same description is evaluated on the GPU (by the window pass, for newly
//! exposed texels; see `shaders/shared/terrain.wgsl`) and on the CPU (physics,
//! queries and the CPU twins). The two evaluations use the same `f32` operations
//! in the same order, so they agree to within rounding (tests use 1e-4 m).

use std::sync::Arc;

use glam::Vec3;

use crate::error::SnowError;

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

/// A grid of heights covering a rectangle of the world, sampled bilinearly
/// between pixel centres and clamped at its edges. Made by
/// [`HeightmapTerrain::new`], which checks it, so sampling never fails.
///
/// The grid is shared, not copied: a shared-snow world's identity holds it
/// too, so its peer presses over it as the GPU does
/// (`snowpack_share::replicate::press::ground::HeightGrid`, one sampling
/// for the window's twins and the presses).
#[derive(Clone, Debug, PartialEq)]
pub struct HeightmapTerrain {
    grid: Arc<HeightGrid>,
}

/// Where the terrain's height comes from.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
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
    /// A triangle mesh (for example a glTF terrain), drawn from above into a grid.
    Mesh(Arc<TerrainMesh>),
}

/// Largest side of a heightmap (pixels): 8192 is the default texture limit
/// of wgpu's adapters (the heightmap's own check is the shared grid's).
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the scene loader and the tools (`low_level`)"))]
pub const HEIGHTMAP_MAX_SIDE: u32 = snowpack_share::replicate::press::ground::HEIGHT_GRID_MAX_SIDE;

/// Largest side of the grid a terrain mesh is drawn into (texels). 2048 is
/// the texture limit every wgpu adapter has, GL ES included.
pub const MESH_GRID_MAX_SIDE: u32 = 2048;

/// Columns of the mesh grid are a multiple of this, so a row is a multiple of
/// 256 bytes and the GPU can copy the drawn texture into a tight buffer.
const MESH_GRID_COLUMN_ALIGN: u32 = 64;

/// Any terrain given as triangles: the blog's "draw the terrain mesh" route,
/// so cliffs, bridges' decks, roads and sculpted ground all work.
///
/// The mesh is drawn from above into a grid (the highest surface per texel
/// centre wins, as a depth test would choose): on the GPU by
/// `crate::deform::terrain_bake::TerrainBakePass` for the snow window, and on
/// the CPU by `draw_from_above` for physics and queries (the
/// tests hold the two to 0.1 mm plus slope × texel / 128 wherever a texel's
/// centre is not on a triangle's edge). Overhangs are invisible from above, which is
/// right for snow: it lies on the top surface. Its triangles and grid are
/// the tools' (`TerrainMeshExt` in `low_level`).
#[derive(Clone, PartialEq)]
pub struct TerrainMesh {
    /// World-space triangles, three corners each.
    pub(crate) triangles: Vec<[[f32; 3]; 3]>,
    /// The grid the mesh was drawn into on the CPU: its size, placement and heights.
    pub(crate) grid: HeightmapTerrain,
}

impl std::fmt::Debug for TerrainMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TerrainMesh")
            .field("triangles", &self.triangles.len())
            .field("grid", &(self.grid.width(), self.grid.height()))
            .field("center_m", &self.grid.center_m())
            .field("size_m", &self.grid.size_m())
            .finish()
    }
}

impl TerrainMesh {
    /// Places a grid of about `texel_m` texels over the triangles' extent and
    /// draws them into it on the CPU. The texel grows when the mesh would need
    /// more than `MESH_GRID_MAX_SIDE` texels on a side.
    pub fn new(triangles: Vec<[[f32; 3]; 3]>, texel_m: f32) -> Result<Self, crate::SnowError> {
        let bad = |why: String| SnowError::InvalidParameter { field: "terrain mesh", why };
        if triangles.is_empty() {
            return Err(bad("the mesh has no triangles".into()).into());
        }
        if !(texel_m.is_finite() && texel_m > 0.0) {
            return Err(bad(format!("texel size must be a positive number of metres, got {texel_m}")).into());
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in triangles.iter().flatten() {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(bad(format!("a vertex is not finite: {p:?}")).into());
            }
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let extent = [hi[0] - lo[0], hi[2] - lo[2]];
        if !(extent[0].is_finite() && extent[1].is_finite() && (hi[1] - lo[1]).is_finite()) {
            return Err(bad(format!("the mesh spans {lo:?} to {hi:?} m, a size that is not a finite f32")).into());
        }
        if extent[0] <= 0.0 || extent[1] <= 0.0 {
            return Err(bad("the mesh has no extent seen from above (all triangles edge-on)".into()).into());
        }
        let max_side = (MESH_GRID_MAX_SIDE - MESH_GRID_COLUMN_ALIGN) as f32;
        let texel = texel_m.max(extent[0] / max_side).max(extent[1] / max_side);
        let cols = ((extent[0] / texel).ceil() as u32 + 1).next_multiple_of(MESH_GRID_COLUMN_ALIGN);
        let rows = (extent[1] / texel).ceil() as u32 + 1;
        let size_m = [cols as f32 * texel, rows as f32 * texel];
        let center_m = [(lo[0] + hi[0]) * 0.5, (lo[2] + hi[2]) * 0.5];
        let origin = [center_m[0] - size_m[0] * 0.5, center_m[1] - size_m[1] * 0.5];
        let heights_m = draw_from_above(&triangles, cols, rows, origin, size_m, lo[1]);
        let grid = HeightmapTerrain::new(cols, rows, heights_m, center_m, size_m)?;
        Ok(Self { triangles, grid })
    }
}

// The noise every machine evaluates alike (the presses too): one copy, in
// the share crate.
use snowpack_share::replicate::press::ground::HeightGrid;
#[cfg(test)]
use snowpack_share::replicate::press::ground::fbm;
pub(crate) use snowpack_share::replicate::press::ground::{lattice_hash, noise_height};

impl HeightmapTerrain {
    /// A heightmap of `width` x `height` pixels, `heights_m` row-major (row
    /// `r` at larger world z than row `r - 1`), covering `size_m` (x, z)
    /// metres centred on world `center_m`. Errors name what is wrong: a zero
    /// side or one above `HEIGHTMAP_MAX_SIDE`, a sample count other than `width * height`, a height that is
    /// not finite, a size that is not positive and finite, a centre that is
    /// not finite.
    pub fn new(width: u32, height: u32, heights_m: Vec<f32>, center_m: [f32; 2], size_m: [f32; 2]) -> Result<Self, crate::SnowError> {
        HeightGrid::new(width, height, heights_m, center_m, size_m)
            .map(|grid| Self { grid: Arc::new(grid) })
            .map_err(|e| SnowError::InvalidParameter { field: e.field, why: e.why }.into())
    }

    /// The grid, shared: what a world's identity holds
    /// (`WorldTerrain::heightmap`) so presses travel over it.
    pub(crate) fn shared_grid(&self) -> &Arc<HeightGrid> {
        &self.grid
    }

    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    /// The same grid with other heights (as many, finite): a mesh terrain's
    /// grid as the GPU baked it.
    pub(crate) fn with_heights(&self, heights_m: Vec<f32>) -> Result<Self, SnowError> {
        let g = &self.grid;
        Self::new(g.width(), g.height(), heights_m, g.center_m(), g.size_m()).map_err(Into::into)
    }
}

impl TerrainSource {
    /// Terrain height (m) at world (x, z).
    #[must_use]
    pub fn height_at(&self, x: f32, z: f32) -> f32 {
        match self {
            Self::Flat { height_m } => *height_m,
            Self::Noise(n) => noise_height(x, z, (n.seed, n.base_m, n.amplitude_m, n.wavelength_m)),
            Self::Heightmap(hm) => hm.height_at(x, z),
            Self::Mesh(m) => m.grid.height_at(x, z),
        }
    }

    /// Lowest and highest height the terrain can have anywhere (m).
    #[must_use]
    pub fn height_bounds(&self) -> (f32, f32) {
        match self {
            Self::Flat { height_m } => (*height_m, *height_m),
            Self::Noise(n) => (n.base_m - n.amplitude_m.abs(), n.base_m + n.amplitude_m.abs()),
            Self::Heightmap(hm) => hm.height_range(),
            Self::Mesh(m) => m.height_range(),
        }
    }
}

/// Terrain height at the centre of global texel `g` = (column, row): twin of
/// `texel_ground` in `shared/terrain_kind.wgsl`.
#[must_use]
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
pub fn texel_ground(terrain: &TerrainSource, g: [i32; 2], texel_m: f32) -> f32 {
    let x = (g[0] as f32 + 0.5) * texel_m;
    let z = (g[1] as f32 + 0.5) * texel_m;
    terrain.height_at(x, z)
}

/// Draws `triangles` (world positions, three per triangle) into a
/// `width x height` grid covering `[x0, x0 + size_x] x [z0, z0 + size_z]`;
/// row `r` lies at larger z than row `r - 1`. Texels no triangle covers keep
/// `floor_m`. Triangles seen edge-on from above (zero area in x, z) draw nothing.
#[must_use]
pub fn draw_from_above(triangles: &[[[f32; 3]; 3]], width: u32, height: u32, origin: [f32; 2], size: [f32; 2], floor_m: f32) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let mut out = vec![floor_m; w * h];
    let (tx, tz) = (size[0] / width as f32, size[1] / height as f32);
    for tri in triangles {
        let [a, b, c] = *tri;
        // Signed doubled area in (x, z); its sign tells the winding.
        let area = (b[0] - a[0]) * (c[2] - a[2]) - (c[0] - a[0]) * (b[2] - a[2]);
        if area.abs() < 1e-12 {
            continue;
        }
        let min_x = a[0].min(b[0]).min(c[0]);
        let max_x = a[0].max(b[0]).max(c[0]);
        let min_z = a[2].min(b[2]).min(c[2]);
        let max_z = a[2].max(b[2]).max(c[2]);
        // Texel centres inside the bounding box.
        let j0 = (((min_x - origin[0]) / tx - 0.5).ceil().max(0.0)) as usize;
        let j1 = (((max_x - origin[0]) / tx - 0.5).floor()).min(w as f32 - 1.0);
        let i0 = (((min_z - origin[1]) / tz - 0.5).ceil().max(0.0)) as usize;
        let i1 = (((max_z - origin[1]) / tz - 0.5).floor()).min(h as f32 - 1.0);
        if j1 < 0.0 || i1 < 0.0 {
            continue;
        }
        for i in i0..=i1 as usize {
            let z = origin[1] + (i as f32 + 0.5) * tz;
            for j in j0..=j1 as usize {
                let x = origin[0] + (j as f32 + 0.5) * tx;
                // Barycentric weights; inclusive edges (a shared edge gives the
                // same height from both sides, so double coverage is harmless).
                let wa = ((b[0] - x) * (c[2] - z) - (c[0] - x) * (b[2] - z)) / area;
                let wb = ((c[0] - x) * (a[2] - z) - (a[0] - x) * (c[2] - z)) / area;
                let wc = 1.0 - wa - wb;
                let eps = -1e-6;
                if wa < eps || wb < eps || wc < eps {
                    continue;
                }
                let y = wa * a[1] + wb * b[1] + wc * c[1];
                let slot = &mut out[i * w + j];
                if y > *slot {
                    *slot = y;
                }
            }
        }
    }
    out
}

/// What snowpack's own app, tools and tests read of a [`HeightmapTerrain`] beyond the front door: its samples, size and place, digest and height range.
/// A named item of `low_level` (an extension trait): [`HeightmapTerrain`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait HeightmapTerrainExt: Sized {
    /// An FNV-1a digest of the size, placement and heights (their bits): two
    /// machines with the same heightmap agree on it (the shared-snow world
    /// identity names terrains by it).
    #[must_use]
    fn digest(&self) -> u64;

    /// Pixels per row.
    #[must_use]
    fn width(&self) -> u32;

    /// Rows.
    #[must_use]
    fn height(&self) -> u32;

    /// Heights in metres, row-major, `width * height` values.
    #[must_use]
    fn heights_m(&self) -> &[f32];

    /// World (x, z) of the centre of the covered area (m).
    #[must_use]
    fn center_m(&self) -> [f32; 2];

    /// World size (x, z) of the covered area (m).
    #[must_use]
    fn size_m(&self) -> [f32; 2];

    /// Lowest and highest sample (m).
    #[must_use]
    fn height_range(&self) -> (f32, f32);

    /// Bilinear height at world (x, z), clamped to the edge pixels outside the covered area.
    #[must_use]
    fn height_at(&self, x: f32, z: f32) -> f32;
}

impl HeightmapTerrainExt for HeightmapTerrain {
    fn digest(&self) -> u64 {
        self.grid.digest()
    }

    fn width(&self) -> u32 {
        self.grid.width()
    }

    fn height(&self) -> u32 {
        self.grid.height()
    }

    fn heights_m(&self) -> &[f32] {
        self.grid.heights_m()
    }

    fn center_m(&self) -> [f32; 2] {
        self.grid.center_m()
    }

    fn size_m(&self) -> [f32; 2] {
        self.grid.size_m()
    }

    fn height_range(&self) -> (f32, f32) {
        self.grid.height_range()
    }

    fn height_at(&self, x: f32, z: f32) -> f32 {
        self.grid.height_at(x, z)
    }
}

/// What snowpack's own app, tools and tests read of a [`TerrainMesh`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`TerrainMesh`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait TerrainMeshExt: Sized {
    /// Lowest and highest vertex height (m).
    #[must_use]
    fn height_range(&self) -> (f32, f32);

    /// World-space triangles, three corners each.
    #[must_use]
    fn triangles(&self) -> &[[[f32; 3]; 3]];

    /// The grid the mesh was drawn into on the CPU: its size, placement and heights.
    #[must_use]
    fn grid(&self) -> &HeightmapTerrain;
}

impl TerrainMeshExt for TerrainMesh {
    fn triangles(&self) -> &[[[f32; 3]; 3]] {
        &self.triangles
    }

    fn grid(&self) -> &HeightmapTerrain {
        &self.grid
    }

    fn height_range(&self) -> (f32, f32) {
        self.triangles.iter().flatten().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])))
    }
}

/// What snowpack's own app, tools and tests read of a [`TerrainSource`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`TerrainSource`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait TerrainSourceExt: Sized {
    /// Unit surface normal at world (x, z), by central differences over `eps_m`.
    #[must_use]
    fn normal_at(&self, x: f32, z: f32, eps_m: f32) -> Vec3;
}

impl TerrainSourceExt for TerrainSource {
    fn normal_at(&self, x: f32, z: f32, eps_m: f32) -> Vec3 {
        let dx = self.height_at(x + eps_m, z) - self.height_at(x - eps_m, z);
        let dz = self.height_at(x, z + eps_m) - self.height_at(x, z - eps_m);
        Vec3::new(-dx, 2.0 * eps_m, -dz).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_heightmap_is_checked_when_made() {
        let ok = |w, h, n: usize| HeightmapTerrain::new(w, h, vec![1.0; n], [0.0, 0.0], [4.0, 4.0]);
        assert!(ok(2, 3, 6).is_ok());
        let why = |r: Result<HeightmapTerrain, crate::SnowError>| r.expect_err("must be refused").to_string();
        assert!(why(ok(0, 3, 0)).contains("at least 1"));
        assert!(why(ok(2, 3, 5)).contains("5 heights for 2x3"));
        assert!(why(HeightmapTerrain::new(1, 2, vec![1.0, f32::NAN], [0.0, 0.0], [1.0, 1.0])).contains("pixel 1"));
        assert!(why(HeightmapTerrain::new(1, 1, vec![1.0], [0.0, 0.0], [0.0, 1.0])).contains("size_m"));
        assert!(why(HeightmapTerrain::new(1, 1, vec![1.0], [f32::INFINITY, 0.0], [1.0, 1.0])).contains("center_m"));
        // A checked heightmap samples anywhere without panicking, one pixel included.
        let one = HeightmapTerrain::new(1, 1, vec![2.5], [0.0, 0.0], [1.0, 1.0]).expect("valid");
        assert_eq!(one.height_at(-1e9, 1e9), 2.5);
    }

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
        let hm = HeightmapTerrain::new(2, 1, vec![0.0, 2.0], [0.0, 0.0], [2.0, 2.0]).expect("valid");
        // Pixel centres at x = -0.5 and x = 0.5.
        assert!((hm.height_at(-0.5, 0.0) - 0.0).abs() < 1e-6);
        assert!((hm.height_at(0.0, 0.0) - 1.0).abs() < 1e-6);
        assert!((hm.height_at(0.5, 0.0) - 2.0).abs() < 1e-6);
        assert!((hm.height_at(5.0, 0.0) - 2.0).abs() < 1e-6);
    }

    #[test]
    fn mesh_grid_holds_the_top_surface() {
        // A tilted square (y = 0.5 x + 0.25 z) with a flat "table" at y = 3
        // over part of it: the grid holds the plane outside the table, the
        // table inside it, and the plane's floor nowhere else.
        let p = |x: f32, z: f32| [x, 0.5 * x + 0.25 * z, z];
        let mut tris = vec![[p(-4.0, -4.0), p(4.0, -4.0), p(4.0, 4.0)], [p(-4.0, -4.0), p(4.0, 4.0), p(-4.0, 4.0)]];
        let t = |x: f32, z: f32| [x, 3.0, z];
        tris.push([t(0.0, 0.0), t(2.0, 0.0), t(2.0, 2.0)]);
        tris.push([t(0.0, 0.0), t(2.0, 2.0), t(0.0, 2.0)]);
        let mesh = TerrainMesh::new(tris, 0.1).unwrap();
        assert_eq!(mesh.grid.width() % 64, 0);
        let terrain = TerrainSource::Mesh(Arc::new(mesh));
        for &(x, z) in &[(-3.0, -3.0), (3.1, -2.0), (-1.0, 3.5), (2.6, 2.6)] {
            let want = 0.5 * x + 0.25 * z;
            assert!((terrain.height_at(x, z) - want).abs() < 1e-3, "plane at ({x}, {z})");
        }
        assert!((terrain.height_at(1.0, 1.0) - 3.0).abs() < 1e-4, "table");
        assert_eq!(terrain.height_bounds(), (-3.0, 3.0));
    }

    #[test]
    fn mesh_without_area_is_rejected() {
        let wall = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(TerrainMesh::new(vec![wall], 0.1).is_err());
        assert!(TerrainMesh::new(vec![], 0.1).is_err());
        let nan = [[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 1.0]];
        assert!(TerrainMesh::new(vec![nan], 0.1).is_err());
    }
}
