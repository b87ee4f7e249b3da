// Shell mapping (Leshonkov & Frolov 2021, after Porumbescu et al. 2005 and
// Ritsche 2006): the data the shell's construction writes and its drawing
// reads. Mirrored by `src/render/shell/construct.rs` and `src/cpu/shell_*.rs`.

// One base vertex and its offset copy (`ShellVertex` in Rust), written by
// `shell_vertices.wgsl`: the transformed surface S_t and offset surface S'_t.
struct ShellVertex {
    base: vec4<f32>,   // xyz on the surface; w: texture u
    top: vec4<f32>,    // xyz offset along the normal by the local thickness; w: texture v
}

// One tetrahedron (`Tetra` in Rust), written by `shell_tetrahedra.wgsl`:
// the affine map world -> barycentric, lambda_i = dot(bary[i - 1].xyz, p -
// origin.xyz) for i = 1..3 and lambda_0 = 1 - their sum. Its rows are the
// tetrahedron's planes, which give a ray its exit; relative to corner 0 so
// the large world coordinates cancel before the steep gradients multiply.
// origin.w is 1, or 0 for a tetrahedron too flat for an accurate map in f32
// (shape ratio over MAX_SHAPE_RATIO): its map is zero and its twelve corner
// indices are one vertex, so it draws nothing.
struct Tetra {
    origin: vec4<f32>,
    bary: array<vec4<f32>, 3>,
    tex: array<vec4<f32>, 4>,  // texture (u, v, w) of each corner; w 0 at the base, 1 on top
}

// Corner c (0..3) of a prism's tetrahedron t (0..2), as a vertex-data index
// (base vertex k is k, its offset copy is count + k), for a face whose
// vertex indices are sorted a < b < c. Every side quad of the prism is split
// by the diagonal from its lower-indexed base vertex to its higher-indexed
// offset vertex, so two prisms sharing an edge split it the same way with
// no communication (section 3.2).
fn prism_corner(sorted: vec3<u32>, count: u32, t: u32, c: u32) -> u32 {
    let a = sorted.x;
    let b = sorted.y;
    let cc = sorted.z;
    // T0 = (a, b, c, c'), T1 = (a, b, b', c'), T2 = (a, a', b', c').
    var corners = array<u32, 12>(a, b, cc, count + cc, a, b, count + b, count + cc, a, count + a, count + b, count + cc);
    return corners[t * 4u + c];
}
