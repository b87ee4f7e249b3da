//! One accumulation atlas for all objects: charts, their packing, the
//! UV-space bake of normals and texel areas, and the meshes drawn from it.
//!
//! Each box face is a rectangular chart and each sphere one octahedral chart
//! (no poles, and its seams lie on the lower hemisphere, where no snow lies).
//! Charts are packed on shelves at one texel density for every object (so
//! every object's snow has the same detail), the densest that fits, but no
//! finer than half an occlusion pixel: snow arrives one occlusion pixel at a
//! time, so finer texels would only show that pixel grid as a waffle (seen
//! in the first renders, at 10 texels a pixel). Each chart has a two-texel
//! gutter, so the 5x5 blur never reaches from one chart into another.

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};

use super::mesh::{ChartedMesh, barycentric};
use super::{ObjectShape, SnowObject};
use crate::error::SnowError;

/// Finest atlas texel whatever the occlusion (m): detail below half a centimetre is not worth texels.
pub const MIN_TEXEL_M: f32 = 0.005;

/// Atlas texels per occlusion pixel at most, along each axis.
pub const TEXELS_PER_PIXEL: f32 = 2.0;

/// Gutter around each chart (texels): the settle blur's radius.
pub const GUTTER: u32 = 2;

/// Owner value of texels that belong to no chart (gutters, unused space).
pub const NO_OWNER: u32 = u32::MAX;

/// How a chart maps its unit square onto an object's surface.
#[derive(Clone, Debug, PartialEq)]
enum ChartMap {
    /// A box face: centre `origin`, outward normal `n`, axes `u` and `v`
    /// (unit vectors) spanning `size` metres.
    Face { origin: Vec3, n: Vec3, u: Vec3, v: Vec3, size: Vec2 },
    /// A whole sphere, octahedral.
    Octahedral { radius: f32 },
    /// A triangle mesh through its UVs (its own, or one chart per triangle);
    /// baked by rasterising its triangles, not through [`ChartMap::point`].
    Mesh(std::sync::Arc<ChartedMesh>),
}

/// Octahedral square coordinate in [-1, 1]² to a unit direction.
fn octa_decode(q: Vec2) -> Vec3 {
    let y = 1.0 - q.x.abs() - q.y.abs();
    let (x, z) = if y >= 0.0 { (q.x, q.y) } else { ((1.0 - q.y.abs()) * q.x.signum(), (1.0 - q.x.abs()) * q.y.signum()) };
    Vec3::new(x, y, z).normalize()
}

impl ChartMap {
    /// Object-space position and outward normal at chart coordinate (s, t)
    /// in [0, 1]², for the analytic charts (`None` for a mesh).
    fn point(&self, s: f32, t: f32) -> Option<(Vec3, Vec3)> {
        match *self {
            Self::Face { origin, n, u, v, size } => Some((origin + u * (s - 0.5) * size.x + v * (t - 0.5) * size.y, n)),
            Self::Octahedral { radius } => {
                let d = octa_decode(Vec2::new(s * 2.0 - 1.0, t * 2.0 - 1.0));
                Some((d * radius, d))
            }
            Self::Mesh(_) => None,
        }
    }

    /// Surface size the chart stands for (m per side, for its texel count).
    fn extent_m(&self) -> Vec2 {
        match *self {
            Self::Face { size, .. } => size,
            // Same area as the sphere: side 2 r sqrt(pi).
            Self::Octahedral { radius } => Vec2::splat(2.0 * radius * std::f32::consts::PI.sqrt()),
            // The UV square holds the surface at the coverage of its triangles.
            Self::Mesh(ref m) => Vec2::splat((m.area / m.coverage.max(1e-6)).sqrt()),
        }
    }
}

/// One chart placed in the atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct Chart {
    /// Index of its object.
    pub object: u32,
    /// Interior texels: `[x0, y0, width, height]`.
    pub rect: [u32; 4],
    map: ChartMap,
}

impl Chart {
    /// Object-space position and normal at continuous texel coordinate (x, y)
    /// of a box face or sphere chart (`None` for a mesh's).
    #[must_use]
    pub fn point_at_texel(&self, x: f32, y: f32) -> Option<(Vec3, Vec3)> {
        let [x0, y0, w, h] = self.rect;
        self.map.point((x - x0 as f32) / w as f32, (y - y0 as f32) / h as f32)
    }

    /// Atlas texel coordinate of UV `uv` in this chart.
    fn texel_of_uv(&self, uv: Vec2) -> Vec2 {
        let [x0, y0, w, h] = self.rect;
        Vec2::new(x0 as f32 + uv.x * w as f32, y0 as f32 + uv.y * h as f32)
    }

    /// Surface area of texel (x, y) of this chart (m²): the two triangles of its corners.
    fn texel_area(&self, x: u32, y: u32) -> f32 {
        match self.map {
            ChartMap::Face { size, .. } => size.x * size.y / (self.rect[2] * self.rect[3]) as f32,
            ChartMap::Octahedral { .. } | ChartMap::Mesh(_) => {
                let p = |dx: u32, dy: u32| self.point_at_texel((x + dx) as f32, (y + dy) as f32).map_or(Vec3::ZERO, |q| q.0);
                let (a, b, c, d) = (p(0, 0), p(1, 0), p(1, 1), p(0, 1));
                0.5 * ((b - a).cross(c - a).length() + (c - a).cross(d - a).length())
            }
        }
    }
}

/// Where every object's charts lie in the atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasLayout {
    /// Texels per side.
    pub resolution: u32,
    /// Atlas texels per metre of surface.
    pub texels_per_m: f32,
    /// Every chart.
    pub charts: Vec<Chart>,
    /// Objects laid out.
    pub object_count: u32,
}

/// The atlas baked in UV space (on the CPU: objects are rigid, so it never changes).
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasBake {
    /// Per texel: object-space normal xyz and surface area (m²); zero outside charts.
    pub normal_area: Vec<[f32; 4]>,
    /// Per texel: index of the object, or [`NO_OWNER`].
    pub owner: Vec<u32>,
    /// Per texel: object-space position of its centre (m).
    pub position: Vec<[f32; 3]>,
}

/// One vertex of an object's mesh (occlusion and drawing).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ObjectVertex {
    /// Object-space position (m).
    pub position: [f32; 3],
    /// Object-space outward normal.
    pub normal: [f32; 3],
    /// Object-space metres per atlas texel along the atlas x axis.
    pub tangent: [f32; 3],
    /// Object-space metres per atlas texel along the atlas y axis.
    pub bitangent: [f32; 3],
    /// Atlas texel coordinate (continuous; texel centres at +0.5).
    pub uv: [f32; 2],
    /// 0 on a box face's border (snow tapers to nothing at edges), 1 inside.
    pub taper: f32,
    /// Index of the object.
    pub object: u32,
    /// The chart's interior `[x0, y0, x1, y1]` (texels, exclusive end).
    pub chart: [f32; 4],
}

/// The six faces of a box of `size`: (normal axis, sign) with their u and v axes.
fn box_faces(size: Vec3) -> Vec<ChartMap> {
    let mut faces = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            let ua = (axis + 1) % 3;
            let mut u = Vec3::ZERO;
            u[ua] = 1.0;
            let v = n.cross(u);
            let va = (0..3).find(|&k| v[k] != 0.0).unwrap_or(0);
            faces.push(ChartMap::Face { origin: n * size[axis] * 0.5, n, u, v, size: Vec2::new(size[ua], size[va]) });
        }
    }
    faces
}

fn object_charts(shape: &ObjectShape) -> Vec<ChartMap> {
    match shape {
        ObjectShape::Box { size_m } => box_faces(*size_m),
        ObjectShape::Sphere { radius_m } => vec![ChartMap::Octahedral { radius: *radius_m }],
        ObjectShape::Mesh(mesh) => vec![ChartMap::Mesh(std::sync::Arc::new(mesh.charted()))],
    }
}

/// Shelf-packs rectangles of `sizes` (texels, gutter included) into a square of
/// side `res`; the lower-left corner of each, or `None` if they do not fit.
fn shelf_pack(sizes: &[[u32; 2]], res: u32) -> Option<Vec<[u32; 2]>> {
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse((sizes[k][1], sizes[k][0])));
    let mut at = vec![[0u32; 2]; sizes.len()];
    let (mut x, mut y, mut shelf) = (0u32, 0u32, 0u32);
    for k in order {
        let [w, h] = sizes[k];
        if w > res {
            return None;
        }
        if x + w > res {
            y += shelf;
            x = 0;
            shelf = 0;
        }
        if y + h > res {
            return None;
        }
        at[k] = [x, y];
        x += w;
        shelf = shelf.max(h);
    }
    Some(at)
}

impl AtlasLayout {
    /// Lays out `objects` in an atlas of `resolution` texels per side, no finer
    /// than `TEXELS_PER_PIXEL` texels per occlusion pixel of `pixel_m`.
    pub fn new(objects: &[SnowObject], resolution: u32, pixel_m: f32) -> Result<Self, SnowError> {
        let maps: Vec<(u32, ChartMap)> =
            objects.iter().enumerate().flat_map(|(k, o)| object_charts(&o.shape).into_iter().map(move |m| (k as u32, m))).collect();
        for o in objects {
            let ok = match &o.shape {
                ObjectShape::Box { size_m } => size_m.is_finite() && size_m.min_element() > 0.0,
                ObjectShape::Sphere { radius_m } => radius_m.is_finite() && *radius_m > 0.0,
                ObjectShape::Mesh(mesh) => {
                    mesh.validate().map_err(|e| SnowError::InvalidParameter { field: "mesh", why: format!("object {:?}: {e}", o.name) })?;
                    mesh.area() > 0.0
                }
            };
            if !ok {
                return Err(SnowError::InvalidParameter { field: "size_m", why: format!("object {:?} has a non-positive size", o.name) });
            }
        }
        let texels = |density: f32| -> Vec<[u32; 2]> {
            maps.iter()
                .map(|(_, m)| {
                    // Saturating: a chart metres across by the billion (a finite but vast
                    // mesh) is wider than any atlas at this density, never a wrapped small
                    // one; the bisection below then finds a density at which it fits.
                    let e = m.extent_m() * density;
                    [(e.x.ceil().max(2.0) as u32).saturating_add(2 * GUTTER), (e.y.ceil().max(2.0) as u32).saturating_add(2 * GUTTER)]
                })
                .collect()
        };
        // The densest layout that fits: bisect on texels per metre.
        let (mut lo, mut hi) = (0.0f32, (TEXELS_PER_PIXEL / pixel_m).min(1.0 / MIN_TEXEL_M));
        if shelf_pack(&texels(hi), resolution).is_none() {
            if shelf_pack(&texels(lo), resolution).is_none() {
                return Err(SnowError::InvalidParameter {
                    field: "atlas_resolution",
                    why: format!("{} objects do not fit in a {resolution}² atlas", objects.len()),
                });
            }
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if shelf_pack(&texels(mid), resolution).is_some() {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            hi = lo;
        }
        let density = hi;
        let sizes = texels(density);
        let places = shelf_pack(&sizes, resolution).unwrap_or_default();
        let charts = maps
            .iter()
            .zip(sizes.iter().zip(&places))
            .map(|((object, map), (s, p))| Chart {
                object: *object,
                rect: [p[0] + GUTTER, p[1] + GUTTER, s[0] - 2 * GUTTER, s[1] - 2 * GUTTER],
                map: map.clone(),
            })
            .collect();
        Ok(Self { resolution, texels_per_m: density, charts, object_count: objects.len() as u32 })
    }

    /// Atlas rows in use: charts are shelf-packed from row 0, so every texel
    /// at or above this row is outside every chart and its gutter.
    #[must_use]
    pub fn used_rows(&self) -> u32 {
        self.charts.iter().map(|c| c.rect[1] + c.rect[3] + GUTTER).max().unwrap_or(0).min(self.resolution)
    }

    /// Bakes normals, areas, owners and positions per texel.
    #[must_use]
    pub fn bake(&self) -> AtlasBake {
        let n = self.resolution as usize * self.resolution as usize;
        let mut bake = AtlasBake { normal_area: vec![[0.0; 4]; n], owner: vec![NO_OWNER; n], position: vec![[0.0; 3]; n] };
        let n = self.resolution as usize;
        for c in &self.charts {
            if let ChartMap::Mesh(mesh) = &c.map {
                bake_mesh(c, mesh, n, &mut bake);
                continue;
            }
            let [x0, y0, w, h] = c.rect;
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    let k = y as usize * n + x as usize;
                    let Some((p, nrm)) = c.point_at_texel(x as f32 + 0.5, y as f32 + 0.5) else { continue };
                    bake.normal_area[k] = nrm.extend(c.texel_area(x, y)).to_array();
                    bake.owner[k] = c.object;
                    bake.position[k] = p.to_array();
                }
            }
        }
        bake
    }

    /// The atlas texel nearest to object-space point `p` on object `object`'s
    /// surface (by the baked positions); for tests and tools.
    #[must_use]
    pub fn nearest_texel(&self, bake: &AtlasBake, object: u32, p: Vec3) -> Option<usize> {
        (0..bake.owner.len()).filter(|&k| bake.owner[k] == object).min_by(|&a, &b| {
            let da = Vec3::from(bake.position[a]).distance_squared(p);
            let db = Vec3::from(bake.position[b]).distance_squared(p);
            da.total_cmp(&db)
        })
    }

    /// Every object's mesh: vertices, triangle indices, and per object its
    /// index range. `dense`: about 4 cm quads, for drawing displaced; else the
    /// fewest that follow the surface (one quad a box face, 16² on a sphere),
    /// for the occlusion.
    #[must_use]
    pub fn meshes(&self, dense: bool) -> (Vec<ObjectVertex>, Vec<u32>, Vec<std::ops::Range<u32>>) {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let mut ranges = vec![0..0; self.object_count as usize];
        for object in 0..self.object_count {
            let start = indices.len() as u32;
            for c in self.charts.iter().filter(|c| c.object == object) {
                if let ChartMap::Mesh(mesh) = &c.map {
                    // The mesh as it is, for drawing and for the occlusion alike.
                    mesh_vertices(c, mesh, &mut vertices, &mut indices);
                } else {
                    chart_grid(c, if dense { grid_quads(c) } else { coarse_quads(c) }, &mut vertices, &mut indices);
                }
            }
            ranges[object as usize] = start..indices.len() as u32;
        }
        (vertices, indices, ranges)
    }
}

/// Quads along each side of a chart's grid: about 4 cm each, 2 to 48 (16 to
/// 64 for spheres, whose octahedral diamond needs an even count).
fn grid_quads(c: &Chart) -> [u32; 2] {
    match c.map {
        ChartMap::Face { size, .. } => [size.x, size.y].map(|s| (s / 0.04).ceil().clamp(2.0, 48.0) as u32),
        ChartMap::Octahedral { radius } => [((radius * 2.0 / 0.04).ceil() as u32).clamp(16, 64).next_multiple_of(2); 2],
        ChartMap::Mesh(_) => [1, 1],
    }
}

/// Quads along each side of a chart's coarse grid (the occlusion's).
fn coarse_quads(c: &Chart) -> [u32; 2] {
    match c.map {
        ChartMap::Face { .. } | ChartMap::Mesh(_) => [1, 1],
        ChartMap::Octahedral { .. } => [16, 16],
    }
}

/// Appends a chart's grid of `qa` x `qb` quads.
fn chart_grid(c: &Chart, [qa, qb]: [u32; 2], vertices: &mut Vec<ObjectVertex>, indices: &mut Vec<u32>) {
    let [x0, y0, w, h] = c.rect;
    let chart = [x0 as f32, y0 as f32, (x0 + w) as f32, (y0 + h) as f32];
    let base = vertices.len() as u32;
    let face = matches!(c.map, ChartMap::Face { .. });
    for b in 0..=qb {
        for a in 0..=qa {
            let (s, t) = (a as f32 / qa as f32, b as f32 / qb as f32);
            let (x, y) = (x0 as f32 + s * w as f32, y0 as f32 + t * h as f32);
            let at = |x: f32, y: f32| c.point_at_texel(x, y).unwrap_or((Vec3::ZERO, Vec3::Y));
            let (p, n) = at(x, y);
            // Metres per texel along the atlas axes, by central differences.
            let e = 0.25;
            let tangent = (at(x + e, y).0 - at(x - e, y).0) / (2.0 * e);
            let bitangent = (at(x, y + e).0 - at(x, y - e).0) / (2.0 * e);
            let border = a == 0 || b == 0 || a == qa || b == qb;
            vertices.push(ObjectVertex {
                position: p.to_array(),
                normal: n.to_array(),
                tangent: tangent.to_array(),
                bitangent: bitangent.to_array(),
                uv: [x, y],
                taper: if face && border { 0.0 } else { 1.0 },
                object: c.object,
                chart,
            });
        }
    }
    let row = qa + 1;
    for b in 0..qb {
        for a in 0..qa {
            let i00 = base + b * row + a;
            let (i10, i01, i11) = (i00 + 1, i00 + row, i00 + row + 1);
            // On the octahedral chart, split along the diamond's edges so the
            // fold to the lower hemisphere runs along triangle edges.
            let along_main = match c.map {
                ChartMap::Octahedral { .. } => {
                    let (sa, sb) = (2 * a + 1 < qa, 2 * b + 1 < qb);
                    sa == sb
                }
                ChartMap::Face { .. } | ChartMap::Mesh(_) => true,
            };
            let (t1, t2) = if along_main { ([i00, i01, i10], [i10, i01, i11]) } else { ([i00, i01, i11], [i00, i11, i10]) };
            // Outward winding (counter-clockwise seen from outside).
            for t in [t1, t2] {
                let p = |k: u32| Vec3::from(vertices[k as usize].position);
                let nrm = Vec3::from(vertices[t[0] as usize].normal) + Vec3::from(vertices[t[1] as usize].normal) + Vec3::from(vertices[t[2] as usize].normal);
                let cross = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
                if cross.dot(nrm) >= 0.0 {
                    indices.extend_from_slice(&t);
                } else {
                    indices.extend_from_slice(&[t[0], t[2], t[1]]);
                }
            }
        }
    }
}

/// Bakes a mesh chart by rasterising its UV triangles: each texel whose
/// centre lies in a triangle gets that triangle's interpolated position and
/// normal, and the triangle's surface area over its texel count as area.
fn bake_mesh(c: &Chart, m: &ChartedMesh, n: usize, bake: &mut AtlasBake) {
    for t in m.indices.chunks_exact(3) {
        let [ia, ib, ic] = [0, 1, 2].map(|k| t[k] as usize);
        let [a, b, cc] = [ia, ib, ic].map(|k| c.texel_of_uv(m.uvs[k]));
        let texels = 0.5 * (b - a).perp_dot(cc - a).abs();
        if texels <= 0.0 {
            continue;
        }
        let area = 0.5 * (m.positions[ib] - m.positions[ia]).cross(m.positions[ic] - m.positions[ia]).length();
        let lo = a.min(b).min(cc).floor().max(Vec2::ZERO);
        let hi = a.max(b).max(cc).ceil().min(Vec2::splat(n as f32));
        // The triangle's area over the texel centres it covers, so areas sum to the surface.
        let mut inside = Vec::new();
        for y in lo.y as usize..hi.y as usize {
            for x in lo.x as usize..hi.x as usize {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                if let Some(w) = barycentric(p, a, b, cc).filter(|w| w.min_element() >= 0.0) {
                    inside.push((y * n + x, w));
                }
            }
        }
        let per = area / inside.len().max(1) as f32;
        for (k, w) in inside {
            let pos = m.positions[ia] * w.x + m.positions[ib] * w.y + m.positions[ic] * w.z;
            let nrm = (m.normals[ia] * w.x + m.normals[ib] * w.y + m.normals[ic] * w.z).normalize_or(Vec3::Y);
            bake.normal_area[k] = nrm.extend(per).to_array();
            bake.owner[k] = c.object;
            bake.position[k] = pos.to_array();
        }
    }
}

/// Appends a mesh chart's own vertices and triangles, with atlas UVs and the
/// metres per texel along the atlas axes (per triangle, averaged at vertices).
fn mesh_vertices(c: &Chart, m: &ChartedMesh, vertices: &mut Vec<ObjectVertex>, indices: &mut Vec<u32>) {
    let base = vertices.len() as u32;
    let [x0, y0, w, h] = c.rect;
    let chart = [x0 as f32, y0 as f32, (x0 + w) as f32, (y0 + h) as f32];
    let mut tangents = vec![(Vec3::ZERO, Vec3::ZERO, 0u32); m.positions.len()];
    for t in m.indices.chunks_exact(3) {
        let [ia, ib, ic] = [0, 1, 2].map(|k| t[k] as usize);
        let (e1, e2) = (m.positions[ib] - m.positions[ia], m.positions[ic] - m.positions[ia]);
        let (d1, d2) = (c.texel_of_uv(m.uvs[ib]) - c.texel_of_uv(m.uvs[ia]), c.texel_of_uv(m.uvs[ic]) - c.texel_of_uv(m.uvs[ia]));
        let det = d1.perp_dot(d2);
        if det.abs() < 1e-12 {
            continue;
        }
        let tx = (e1 * d2.y - e2 * d1.y) / det;
        let ty = (e2 * d1.x - e1 * d2.x) / det;
        for k in [ia, ib, ic] {
            tangents[k].0 += tx;
            tangents[k].1 += ty;
            tangents[k].2 += 1;
        }
    }
    for (k, p) in m.positions.iter().enumerate() {
        let count = tangents[k].2.max(1) as f32;
        vertices.push(ObjectVertex {
            position: p.to_array(),
            normal: m.normals[k].to_array(),
            tangent: (tangents[k].0 / count).to_array(),
            bitangent: (tangents[k].1 / count).to_array(),
            uv: c.texel_of_uv(m.uvs[k]).to_array(),
            taper: 1.0,
            object: c.object,
            chart,
        });
    }
    indices.extend(m.indices.iter().map(|i| base + i));
}

#[cfg(test)]
mod tests {
    use glam::Quat;

    use super::*;

    fn objects() -> Vec<SnowObject> {
        vec![
            SnowObject {
                name: "table".into(),
                shape: ObjectShape::Box { size_m: Vec3::new(2.0, 0.1, 1.0) },
                position: Vec3::ZERO,
                rotation: Quat::IDENTITY,
                dilate: true,
            },
            SnowObject { name: "ball".into(), shape: ObjectShape::Sphere { radius_m: 0.5 }, position: Vec3::ZERO, rotation: Quat::IDENTITY, dilate: true },
        ]
    }

    #[test]
    fn charts_do_not_overlap_and_areas_sum_to_each_surface() {
        let layout = AtlasLayout::new(&objects(), 256, 0.001).expect("fits");
        let bake = layout.bake();
        let mut seen = vec![false; 256 * 256];
        for c in &layout.charts {
            let [x0, y0, w, h] = c.rect;
            assert!(x0 >= GUTTER && y0 >= GUTTER && x0 + w + GUTTER <= 256 && y0 + h + GUTTER <= 256, "chart {:?} within the atlas with its gutter", c.rect);
            for y in y0..y0 + h {
                for x in x0..x0 + w {
                    let k = (y * 256 + x) as usize;
                    assert!(!seen[k], "texel ({x}, {y}) in two charts");
                    seen[k] = true;
                }
            }
        }
        for (object, want) in [(0u32, 2.0 * (2.0 * 0.1 + 2.0 * 1.0 + 0.1 * 1.0)), (1, 4.0 * std::f32::consts::PI * 0.25)] {
            let area: f32 = (0..bake.owner.len()).filter(|&k| bake.owner[k] == object).map(|k| bake.normal_area[k][3]).sum();
            assert!((area - want).abs() < 0.02 * want, "object {object}: baked area {area} m², surface {want} m²");
        }
    }

    #[test]
    fn octahedral_chart_is_the_unit_sphere_and_meshes_face_outward() {
        let layout = AtlasLayout::new(&objects(), 256, 0.001).expect("fits");
        let (v, idx, ranges) = layout.meshes(true);
        assert_eq!(ranges.len(), 2);
        for t in idx.chunks(3) {
            let p = |k: usize| Vec3::from(v[t[k] as usize].position);
            let n = (p(1) - p(0)).cross(p(2) - p(0));
            if n.length() < 1e-9 {
                continue;
            }
            let nrm = Vec3::from(v[t[0] as usize].normal);
            assert!(n.dot(nrm) > 0.0, "triangle {t:?} faces inward");
        }
        for vert in v.iter().filter(|x| x.object == 1) {
            let p = Vec3::from(vert.position);
            assert!((p.length() - 0.5).abs() < 1e-4);
            assert!(Vec3::from(vert.normal).dot(p.normalize()) > 0.9999);
        }
    }

    #[test]
    fn density_is_uniform_and_fills_the_atlas() {
        let layout = AtlasLayout::new(&objects(), 512, 0.001).expect("fits");
        let used: u32 = layout.charts.iter().map(|c| (c.rect[2] + 2 * GUTTER) * (c.rect[3] + 2 * GUTTER)).sum();
        assert!(used as f32 > 0.4 * 512.0 * 512.0, "the densest packing uses a good part of the atlas ({used} texels)");
        let tiny = vec![SnowObject {
            name: "pebble".into(),
            shape: ObjectShape::Sphere { radius_m: 0.01 },
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            dilate: false,
        }];
        let layout = AtlasLayout::new(&tiny, 512, 0.001).expect("fits");
        assert!((layout.texels_per_m - 1.0 / MIN_TEXEL_M).abs() < 1e-3, "a small object stops at the finest texel");
        let layout = AtlasLayout::new(&tiny, 512, 0.1).expect("fits");
        assert!((layout.texels_per_m - TEXELS_PER_PIXEL / 0.1).abs() < 1e-3, "and at two texels per occlusion pixel");
    }

    #[test]
    fn a_mesh_bakes_its_area_with_its_own_uvs_or_a_chart_per_triangle() {
        use crate::accumulate::ObjectMesh;
        // A tent: two 2 x 1 m slopes meeting at a ridge, UV-mapped side by side.
        let p = [
            Vec3::new(-1.0, 0.0, -0.5),
            Vec3::new(1.0, 0.0, -0.5),
            Vec3::new(-1.0, 0.5, 0.0),
            Vec3::new(1.0, 0.5, 0.0),
            Vec3::new(-1.0, 0.0, 0.5),
            Vec3::new(1.0, 0.0, 0.5),
        ];
        let uv = [Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.5), Vec2::new(1.0, 0.5), Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0)];
        let indices = vec![0, 2, 1, 1, 2, 3, 2, 4, 3, 3, 4, 5];
        let area = 2.0 * 2.0 * (0.5f32 * 0.5 + 0.5 * 0.5).sqrt();
        for uvs in [Some(uv.to_vec()), None] {
            let mesh = ObjectMesh { positions: p.to_vec(), normals: vec![], uvs: uvs.clone(), indices: indices.clone() };
            let object = SnowObject {
                name: "tent".into(),
                shape: ObjectShape::Mesh(std::sync::Arc::new(mesh)),
                position: Vec3::ZERO,
                rotation: Quat::IDENTITY,
                dilate: true,
            };
            let layout = AtlasLayout::new(&[object], 128, 0.01).expect("fits");
            let bake = layout.bake();
            let baked: f32 = bake.normal_area.iter().zip(&bake.owner).filter(|(_, o)| **o == 0).map(|(n, _)| n[3]).sum();
            assert!((baked - area).abs() < 0.01 * area, "own UVs {}: baked {baked} m², surface {area} m²", uvs.is_some());
            // Normals are the faces' (45 degrees from up) averaged at the shared
            // ridge (straight up), interpolated between.
            for (n, _) in bake.normal_area.iter().zip(&bake.owner).filter(|(_, o)| **o == 0) {
                assert!(n[1] > std::f32::consts::FRAC_1_SQRT_2 - 0.01 && n[0].abs() < 1e-4, "normal {n:?}");
            }
            let (v, idx, _) = layout.meshes(true);
            assert_eq!(idx.len(), 12);
            assert!(v.iter().all(|x| x.uv[0] >= x.chart[0] && x.uv[0] <= x.chart[2] && x.uv[1] >= x.chart[1] && x.uv[1] <= x.chart[3]));
        }
    }

    #[test]
    fn rows_above_the_used_ones_belong_to_no_chart() {
        let layout = AtlasLayout::new(&objects(), 512, 0.05).expect("fits");
        let rows = layout.used_rows();
        assert!(rows < 512, "a coarse layout leaves rows free ({rows})");
        let bake = layout.bake();
        assert!(bake.owner[(rows as usize - GUTTER as usize - 1) * 512..].iter().any(|&o| o != NO_OWNER));
        assert!(bake.owner[rows as usize * 512..].iter().all(|&o| o == NO_OWNER));
    }

    #[test]
    fn too_many_objects_is_an_error() {
        let many: Vec<SnowObject> = (0..200).map(|k| SnowObject { name: format!("b{k}"), ..objects()[0].clone() }).collect();
        assert!(AtlasLayout::new(&many, 16, 0.001).is_err());
    }
}
