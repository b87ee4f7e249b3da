//! CPU twin of `shaders/shell_tetrahedra.wgsl`: prisms split into tetrahedra
//! by the vertex-index rule, with their affine maps and drawing indices.

use glam::Vec3;

use snowpack::low_level::render::shell::tetrahedra::{CORNERS_PER_TETRA, MAX_SHAPE_RATIO, Tetra, TetraParams};
use snowpack::low_level::render::shell::vertices::ShellVertex;

/// Corner `c` of tetrahedron `t` of the prism over a face with vertex indices
/// `sorted` (ascending), as a vertex-data index (offset copies from `count`):
/// T0 = (a, b, c, c'), T1 = (a, b, b', c'), T2 = (a, a', b', c'). Each side
/// quad is split from its lower-indexed base vertex to its higher-indexed
/// offset vertex.
#[must_use]
pub fn prism_corner(sorted: [u32; 3], count: u32, t: u32, c: u32) -> u32 {
    let [a, b, cc] = sorted;
    let corners = [a, b, cc, count + cc, a, b, count + b, count + cc, a, count + a, count + b, count + cc];
    corners[(t * 4 + c) as usize]
}

/// Faces of a tetrahedron as (corner, corner, corner, opposite corner), as in
/// the shader: wound counter-clockwise seen from outside when det(e1, e2, e3) > 0.
const TETRA_FACES: [[usize; 4]; 4] = [[1, 2, 3, 0], [0, 3, 2, 1], [0, 1, 3, 2], [0, 2, 1, 3]];

fn corner_position(vertices: &[ShellVertex], count: u32, index: u32) -> Vec3 {
    let v = if index < count { vertices[index as usize].base } else { vertices[(index - count) as usize].top };
    Vec3::new(v[0], v[1], v[2])
}

fn corner_texture(vertices: &[ShellVertex], count: u32, index: u32) -> [f32; 4] {
    let k = if index < count { index } else { index - count };
    let v = vertices[k as usize];
    [v.base[3], v.top[3], if index < count { 0.0 } else { 1.0 }, 0.0]
}

/// The tetrahedra (three per face) and their corner indices (twelve each).
#[must_use]
pub fn shell_tetrahedra(params: &TetraParams, faces: &[u32], vertices: &[ShellVertex]) -> (Vec<Tetra>, Vec<u32>) {
    let n = params.faces as usize;
    let mut tetras = vec![Tetra::default(); n * 3];
    let mut corners = vec![0u32; n * 3 * CORNERS_PER_TETRA as usize];
    for f in 0..n {
        let (i0, i1, i2) = (faces[3 * f], faces[3 * f + 1], faces[3 * f + 2]);
        let lo = i0.min(i1).min(i2);
        let hi = i0.max(i1).max(i2);
        let sorted = [lo, i0 + i1 + i2 - lo - hi, hi];
        for t in 0..3u32 {
            let idx: [u32; 4] = std::array::from_fn(|c| prism_corner(sorted, params.count, t, c as u32));
            let p: [Vec3; 4] = idx.map(|i| corner_position(vertices, params.count, i));
            let mut tet = Tetra { tex: idx.map(|i| corner_texture(vertices, params.count, i)), ..Tetra::default() };
            let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
            let (c1, c2, c3) = (e2.cross(e3), e3.cross(e1), e1.cross(e2));
            let det = e1.dot(c1);
            let slot = 3 * f + t as usize;
            let out = &mut corners[slot * 12..slot * 12 + 12];
            // Too flat for an accurate map (shape ratio over MAX_SHAPE_RATIO,
            // det = 0 included): marked and collapsed, as in the shader.
            let longest = e1.length_squared().max(e2.length_squared()).max(e3.length_squared());
            let drawn = det.abs() * MAX_SHAPE_RATIO > longest * longest.sqrt();
            if !drawn {
                tet.origin = p[0].extend(0.0).to_array();
                tetras[slot] = tet;
                out.fill(idx[0]);
                continue;
            }
            tet.origin = p[0].extend(1.0).to_array();
            tet.bary = [c1, c2, c3].map(|c| (c / det).extend(0.0).to_array());
            tetras[slot] = tet;
            // Outward from the one sign of det, as in the shader.
            let flip = det < 0.0;
            for (face, q) in TETRA_FACES.iter().enumerate() {
                out[3 * face] = idx[q[0]];
                out[3 * face + 1] = if flip { idx[q[2]] } else { idx[q[1]] };
                out[3 * face + 2] = if flip { idx[q[1]] } else { idx[q[2]] };
            }
        }
    }
    (tetras, corners)
}
