//! Triangle-mesh objects (glTF in scenes): their own UVs as the object's
//! chart when they are usable (inside the unit square, not overlapping), or
//! a chart per triangle that snowpack lays out itself.

use glam::{Vec2, Vec3};

use crate::error::SnowError;

/// A rigid triangle mesh in object space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjectMesh {
    /// Vertex positions (m).
    pub positions: Vec<Vec3>,
    /// Vertex normals (unit); empty to use face normals.
    pub normals: Vec<Vec3>,
    /// Texture coordinates (`TEXCOORD_0`), if the mesh has them.
    pub uvs: Option<Vec<Vec2>>,
    /// Triangle list.
    pub indices: Vec<u32>,
}

/// A mesh with UVs fit for the atlas, every triangle's corners its own or shared.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChartedMesh {
    /// Vertex positions (m).
    pub positions: Vec<Vec3>,
    /// Vertex normals (unit).
    pub normals: Vec<Vec3>,
    /// UVs in the unit square, not overlapping.
    pub uvs: Vec<Vec2>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Whether the UVs were generated (a chart per triangle) rather than the mesh's own.
    pub generated: bool,
    /// Fraction of the unit square the UV triangles cover.
    pub coverage: f32,
    /// Surface area (m²).
    pub area: f32,
}

/// Side of the raster that tests UVs for overlap.
const OVERLAP_GRID: usize = 256;

/// Gap between generated per-triangle charts (m): about two texels at the
/// usual atlas density, so the settle blur does not join them.
const TRIANGLE_GUTTER_M: f32 = 0.06;

fn tri_area(a: Vec3, b: Vec3, c: Vec3) -> f32 {
    0.5 * (b - a).cross(c - a).length()
}

fn uv_area(a: Vec2, b: Vec2, c: Vec2) -> f32 {
    0.5 * ((b - a).perp_dot(c - a)).abs()
}

/// Barycentric coordinates of `p` in the triangle (a, b, c), if it is not degenerate.
#[must_use]
pub fn barycentric(p: Vec2, a: Vec2, b: Vec2, c: Vec2) -> Option<Vec3> {
    let d = (b - a).perp_dot(c - a);
    if d.abs() < 1e-12 {
        return None;
    }
    let w1 = (p - a).perp_dot(c - a) / d;
    let w2 = (b - a).perp_dot(p - a) / d;
    Some(Vec3::new(1.0 - w1 - w2, w1, w2))
}

impl ObjectMesh {
    /// Checks sizes and indices; the error names what is wrong.
    pub fn validate(&self) -> Result<(), SnowError> {
        let bad = |why: String| Err(SnowError::InvalidParameter { field: "mesh", why });
        let n = self.positions.len();
        if self.indices.is_empty() || !self.indices.len().is_multiple_of(3) {
            return bad(format!("{} indices do not make whole triangles", self.indices.len()));
        }
        if let Some(k) = self.indices.iter().find(|&&k| k as usize >= n) {
            return bad(format!("index {k} is past the {n} vertices"));
        }
        if !self.normals.is_empty() && self.normals.len() != n {
            return bad(format!("{} normals for {n} vertices", self.normals.len()));
        }
        if self.uvs.as_ref().is_some_and(|u| u.len() != n) {
            return bad("the UVs do not match the vertices".into());
        }
        if self.positions.iter().any(|p| !p.is_finite()) {
            return bad("a position is not finite".into());
        }
        Ok(())
    }

    /// Surface area (m²).
    #[must_use]
    pub fn area(&self) -> f32 {
        self.indices.chunks_exact(3).map(|t| tri_area(self.positions[t[0] as usize], self.positions[t[1] as usize], self.positions[t[2] as usize])).sum()
    }

    /// Farthest vertex from the origin (m).
    #[must_use]
    pub fn radius(&self) -> f32 {
        self.positions.iter().map(|p| p.length()).fold(0.0, f32::max)
    }

    /// Whether the mesh's own UVs can be its chart: every one inside the unit
    /// square, none degenerate, and no two triangles covering the same place
    /// (at most 1% of the covered cells of a 256² raster counted twice, for
    /// shared edges).
    #[must_use]
    pub fn uvs_usable(&self) -> bool {
        let Some(uvs) = &self.uvs else { return false };
        if uvs.iter().any(|u| !u.is_finite() || u.min_element() < 0.0 || u.max_element() > 1.0) {
            return false;
        }
        let g = OVERLAP_GRID;
        let mut count = vec![0u8; g * g];
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| uvs[t[k] as usize] * g as f32);
            // A triangle with no area in UV would get no texels, hence no snow.
            if uv_area(a, b, c) < 1e-6 {
                return false;
            }
            let lo = a.min(b).min(c).floor().max(Vec2::ZERO);
            let hi = a.max(b).max(c).ceil().min(Vec2::splat(g as f32));
            for y in lo.y as usize..hi.y as usize {
                for x in lo.x as usize..hi.x as usize {
                    let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    if barycentric(p, a, b, c).is_some_and(|w| w.min_element() > 0.0) {
                        count[y * g + x] = count[y * g + x].saturating_add(1);
                    }
                }
            }
        }
        let covered = count.iter().filter(|&&c| c > 0).count();
        let twice = count.iter().filter(|&&c| c > 1).count();
        covered > 0 && twice * 100 <= covered
    }

    /// The mesh with UVs fit for the atlas: its own when usable, otherwise a
    /// chart per triangle laid out on shelves (vertices no longer shared).
    #[must_use]
    pub fn charted(&self) -> ChartedMesh {
        let normals: Vec<Vec3> = if self.normals.len() == self.positions.len() {
            self.normals.iter().map(|n| n.normalize_or(Vec3::Y)).collect()
        } else {
            // Face normals, averaged at shared vertices.
            let mut acc = vec![Vec3::ZERO; self.positions.len()];
            for t in self.indices.chunks_exact(3) {
                let [a, b, c] = [0, 1, 2].map(|k| self.positions[t[k] as usize]);
                let n = (b - a).cross(c - a);
                for &k in t {
                    acc[k as usize] += n;
                }
            }
            acc.into_iter().map(|n| n.normalize_or(Vec3::Y)).collect()
        };
        let area = self.area();
        if self.uvs_usable() {
            let uvs = self.uvs.clone().unwrap_or_default();
            let coverage = self.indices.chunks_exact(3).map(|t| uv_area(uvs[t[0] as usize], uvs[t[1] as usize], uvs[t[2] as usize])).sum();
            return ChartedMesh { positions: self.positions.clone(), normals, uvs, indices: self.indices.clone(), generated: false, coverage, area };
        }
        // A chart per triangle: its corners in its own plane, shelf-packed in metres.
        let tris: Vec<[u32; 3]> = self.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let flat: Vec<([Vec2; 3], Vec2)> = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|k| self.positions[k as usize]);
                let u = (b - a).normalize_or(Vec3::X);
                let v = (b - a).cross(c - a).cross(u).normalize_or(Vec3::Z);
                let q = [Vec2::ZERO, Vec2::new((b - a).dot(u), (b - a).dot(v)), Vec2::new((c - a).dot(u), (c - a).dot(v))];
                let lo = q[0].min(q[1]).min(q[2]);
                let q = q.map(|p| p - lo);
                (q, q[0].max(q[1]).max(q[2]))
            })
            .collect();
        let total: f32 = flat.iter().map(|(_, s)| (s.x + TRIANGLE_GUTTER_M) * (s.y + TRIANGLE_GUTTER_M)).sum();
        let row_width = total.sqrt() * 1.1;
        let mut order: Vec<usize> = (0..flat.len()).collect();
        order.sort_by(|&a, &b| flat[b].1.y.total_cmp(&flat[a].1.y));
        let mut at = vec![Vec2::ZERO; flat.len()];
        let (mut x, mut y, mut shelf, mut width) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
        for k in order {
            let s = flat[k].1 + TRIANGLE_GUTTER_M;
            if x + s.x > row_width && x > 0.0 {
                y += shelf;
                x = 0.0;
                shelf = 0.0;
            }
            at[k] = Vec2::new(x, y) + 0.5 * TRIANGLE_GUTTER_M;
            x += s.x;
            width = width.max(x);
            shelf = shelf.max(s.y);
        }
        let side = width.max(y + shelf).max(1e-6);
        let mut out = ChartedMesh { generated: true, area, ..ChartedMesh::default() };
        for (t, ((q, _), origin)) in tris.iter().zip(flat.iter().zip(&at)) {
            for k in 0..3 {
                out.positions.push(self.positions[t[k] as usize]);
                out.normals.push(normals[t[k] as usize]);
                out.uvs.push((*origin + q[k]) / side);
                out.indices.push(out.indices.len() as u32);
            }
        }
        out.coverage = out.indices.chunks_exact(3).map(|t| uv_area(out.uvs[t[0] as usize], out.uvs[t[1] as usize], out.uvs[t[2] as usize])).sum();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square of two triangles in the xz plane, facing up, UV-mapped.
    fn quad(uvs: Option<Vec<Vec2>>) -> ObjectMesh {
        ObjectMesh {
            positions: vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 1.0)],
            normals: vec![Vec3::Y; 4],
            uvs,
            indices: vec![0, 2, 1, 0, 3, 2],
        }
    }

    #[test]
    fn own_uvs_are_used_when_they_do_not_overlap() {
        let m = quad(Some(vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)]));
        assert!(m.validate().is_ok());
        let c = m.charted();
        assert!(!c.generated);
        assert!((c.coverage - 1.0).abs() < 1e-5 && (c.area - 1.0).abs() < 1e-5);
    }

    #[test]
    fn overlapping_or_missing_uvs_get_a_chart_per_triangle() {
        // The second triangle folded over the first.
        let m = quad(Some(vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.9, 0.1)]));
        assert!(!m.uvs_usable());
        // One triangle with no area in UV.
        assert!(!quad(Some(vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 1.0)])).uvs_usable());
        for m in [m, quad(None)] {
            let c = m.charted();
            assert!(c.generated);
            assert_eq!(c.indices.len(), 6);
            assert!(c.uvs.iter().all(|u| u.min_element() >= 0.0 && u.max_element() <= 1.0));
            let generated = ObjectMesh { positions: c.positions.clone(), normals: c.normals.clone(), uvs: Some(c.uvs.clone()), indices: c.indices.clone() };
            assert!(generated.uvs_usable(), "generated charts do not overlap");
            // Each chart keeps its triangle's shape: UV area in proportion to surface area.
            let ratio: Vec<f32> = c.indices.chunks_exact(3).map(|t| uv_area(c.uvs[t[0] as usize], c.uvs[t[1] as usize], c.uvs[t[2] as usize])).collect();
            assert!((ratio[0] - ratio[1]).abs() < 1e-5);
        }
    }

    #[test]
    fn bad_meshes_are_errors() {
        let mut m = quad(None);
        m.indices.push(9);
        assert!(m.validate().is_err());
        let mut m = quad(None);
        m.indices = vec![0, 1, 2, 7, 0, 1];
        assert!(m.validate().is_err());
    }
}
