// #import shared/terrain
// #import shared/terrain_kind
// #import shared/shell

// Shell construction, step 1 of 2 (Figure 4): the base surface S as it is
// drawn this frame (S_t) and the offset surface S'_t along its normals.
// Snow mode reads the displayed snow surface at the patch's texels; the
// shell thins where the snow is pressed below rest, so grass lies flat in a
// trail. Mesh mode takes positions and normals as given. CPU twin:
// `src/cpu/shell_vertices.rs`.

struct ShellVertexParams {
    mode: u32,            // 0 mesh, 1 snow
    count: u32,           // vertices
    side: u32,            // snow: vertices per side of the patch
    stride: u32,          // snow: texels between vertices
    origin: vec2<i32>,    // snow: window-local texel (column, row) of vertex 0
    resolution: u32,      // snow: window texels per side
    _pad0: u32,
    corner: vec2<f32>,    // snow: world (x, z) of the window's corner
    texel_m: f32,
    depth_m: f32,         // rest depth of fresh snow
    thickness_m: f32,     // shell thickness over undisturbed snow
    flatten_m: f32,       // pressing that flattens the shell to `min_fraction`
    min_fraction: f32,
    tile_m: f32,          // snow: world size of one repeat of the detail texture
}

struct BaseVertex {
    position: vec4<f32>,  // xyz; w: texture u
    normal: vec4<f32>,    // xyz (unit); w: texture v
}

@group(0) @binding(0) var<uniform> params: ShellVertexParams;
@group(0) @binding(1) var<storage, read> base: array<BaseVertex>;
@group(0) @binding(2) var<storage, read> surface: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read> heightmap: array<f32>;
@group(0) @binding(4) var<uniform> terrain_params: TerrainParams;

// The mode this pipeline is built for (`ShellVertexPass` builds one per
// mode in use, pass/compute.rs); the default reads `params.mode`. Built
// in, no branch tests a uniform alone: Mesa 22's lavapipe compiles such a
// shader again at every dispatch and keeps every copy (docs/deformation.md,
// "Branches on uniforms").
override SHELL_MODE: u32 = 0xffffffffu;

fn shell_mode() -> u32 {
    if SHELL_MODE != 0xffffffffu {
        return SHELL_MODE;
    }
    return params.mode;
}
@group(0) @binding(5) var<storage, read_write> vertices: array<ShellVertex>;

// cos and sin of the texture's turn (0.5 rad), as in the CPU twin.
const TILE_COS: f32 = 0.87758256;
const TILE_SIN: f32 = 0.47942554;

fn unpack_normal(bits: u32) -> vec3<f32> {
    let xz = unpack2x16snorm(bits);
    return vec3<f32>(xz.x, sqrt(max(1.0 - dot(xz, xz), 0.0)), xz.y);
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x;
    if k >= params.count {
        return;
    }
    if shell_mode() == 0u {
        let v = base[k];
        let top = v.position.xyz + v.normal.xyz * params.thickness_m;
        vertices[k] = ShellVertex(v.position, vec4<f32>(top, v.normal.w));
        return;
    }
    let last = i32(params.resolution) - 1;
    let col = clamp(params.origin.x + i32((k % params.side) * params.stride), 0, last);
    let row = clamp(params.origin.y + i32((k / params.side) * params.stride), 0, last);
    let texel = surface[u32(row) * params.resolution + u32(col)];
    let x = params.corner.x + (f32(col) + 0.5) * params.texel_m;
    let z = params.corner.y + (f32(row) + 0.5) * params.texel_m;
    let y = bitcast<f32>(texel.x);
    let n = unpack_normal(texel.y);
    let rest = terrain_height_built(terrain_params, x, z) + params.depth_m;
    let pressed = max(rest - y, 0.0);
    let fraction = clamp(1.0 - pressed / params.flatten_m, params.min_fraction, 1.0);
    let p = vec3<f32>(x, y, z);
    let top = p + n * (params.thickness_m * fraction);
    // Texture axes turned off the world's, so the tiling does not line up
    // with the view or the window's rows.
    let u = (x * TILE_COS + z * TILE_SIN) / params.tile_m;
    let v = (z * TILE_COS - x * TILE_SIN) / params.tile_m;
    vertices[k] = ShellVertex(vec4<f32>(p, u), vec4<f32>(top, v));
}
