// #import shared/shell

// Shell construction, step 2 of 2 (Figure 4): per face of the base mesh, its
// prism between S_t and S'_t split into three tetrahedra by the vertex-index
// rule (`prism_corner`), each with its world -> barycentric map and its
// corners' texture coordinates, and the twelve vertex-data indices of its
// four faces, wound counter-clockwise seen from outside, for drawing; one
// too flat for an accurate map in f32 is marked and drawn as nothing. Data
// independent: one invocation per face. CPU twin: `src/cpu/shell_tetrahedra.rs`.

struct TetraParams {
    faces: u32,
    count: u32,    // vertices of the base mesh
    _pad: vec2<u32>,
}

@group(0) @binding(0) var<uniform> params: TetraParams;
@group(0) @binding(1) var<storage, read> faces: array<u32>;
@group(0) @binding(2) var<storage, read> vertices: array<ShellVertex>;
@group(0) @binding(3) var<storage, read_write> tetras: array<Tetra>;
@group(0) @binding(4) var<storage, read_write> corners: array<u32>;

fn corner_position(index: u32) -> vec3<f32> {
    if index < params.count {
        return vertices[index].base.xyz;
    }
    return vertices[index - params.count].top.xyz;
}

fn corner_texture(index: u32) -> vec4<f32> {
    let k = select(index - params.count, index, index < params.count);
    let v = vertices[k];
    return vec4<f32>(v.base.w, v.top.w, select(1.0, 0.0, index < params.count), 0.0);
}

// Largest shape ratio (longest edge from corner 0, cubed, over 6 x the
// volume) of a tetrahedron that is drawn: `MAX_SHAPE_RATIO` in tetrahedra.rs.
const MAX_SHAPE_RATIO: f32 = 4096.0;

// Faces of a tetrahedron as (corner, corner, corner, opposite corner),
// wound counter-clockwise seen from outside when det(e1, e2, e3) > 0.
const TETRA_FACES = array<vec4<u32>, 4>(
    vec4<u32>(1u, 2u, 3u, 0u),
    vec4<u32>(0u, 3u, 2u, 1u),
    vec4<u32>(0u, 1u, 3u, 2u),
    vec4<u32>(0u, 2u, 1u, 3u),
);

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let f = id.x;
    if f >= params.faces {
        return;
    }
    let i0 = faces[3u * f];
    let i1 = faces[3u * f + 1u];
    let i2 = faces[3u * f + 2u];
    let lo = min(min(i0, i1), i2);
    let hi = max(max(i0, i1), i2);
    let sorted = vec3<u32>(lo, i0 + i1 + i2 - lo - hi, hi);
    for (var t = 0u; t < 3u; t++) {
        var idx: array<u32, 4>;
        var p: array<vec3<f32>, 4>;
        var tet: Tetra;
        for (var c = 0u; c < 4u; c++) {
            idx[c] = prism_corner(sorted, params.count, t, c);
            p[c] = corner_position(idx[c]);
            tet.tex[c] = corner_texture(idx[c]);
        }
        let e1 = p[1] - p[0];
        let e2 = p[2] - p[0];
        let e3 = p[3] - p[0];
        let c1 = cross(e2, e3);
        let c2 = cross(e3, e1);
        let c3 = cross(e1, e2);
        let det = dot(e1, c1);
        let slot = 3u * f + t;
        // Shape ratio: the longest edge from corner 0, cubed, over |det| (6 x
        // the volume). It bounds the f32 error of the map below at points
        // inside (45 u x ratio, docs/shell.md). Past MAX_SHAPE_RATIO the
        // tetrahedron is flat, or a sliver about 1/4096 of its edges thin: it
        // is marked and not drawn. A product, so det = 0 is caught too.
        let longest = max(max(dot(e1, e1), dot(e2, e2)), dot(e3, e3));
        if !(abs(det) * MAX_SHAPE_RATIO > longest * sqrt(longest)) {
            tet.origin = vec4<f32>(p[0], 0.0);
            tetras[slot] = tet;
            for (var k = 0u; k < 12u; k++) {
                corners[12u * slot + k] = idx[0];
            }
            continue;
        }
        tet.origin = vec4<f32>(p[0], 1.0);
        tet.bary[0] = vec4<f32>(c1 / det, 0.0);
        tet.bary[1] = vec4<f32>(c2 / det, 0.0);
        tet.bary[2] = vec4<f32>(c3 / det, 0.0);
        tetras[slot] = tet;
        // Outward winding from the one sign of det: TETRA_FACES winds outward
        // for det > 0. (A test per face could disagree with another on a thin one.)
        let flip = det < 0.0;
        for (var face = 0u; face < 4u; face++) {
            let q = TETRA_FACES[face];
            corners[12u * slot + 3u * face] = idx[q.x];
            corners[12u * slot + 3u * face + 1u] = select(idx[q.y], idx[q.z], flip);
            corners[12u * slot + 3u * face + 2u] = select(idx[q.z], idx[q.y], flip);
        }
    }
}
