// snowpack's snow, sampled from a game's own shaders.
//
// Exported as `snowpack::render::ground::SNOW_SAMPLING_WGSL`, which is
// shared/terrain.wgsl followed by this file: paste it (or concatenate it)
// ahead of your shader. `SnowGround` (ground.wgsl) uses exactly this module.
//
// Bindings, all in one group (default 1; `snow_sampling_wgsl(group)` in Rust
// rewrites the number; `sampling_layout_entries` gives the layout entries and
// `SnowSampling` builds and updates the bind group from a `SnowDeformation`):
//   binding 0  uniform              SnowWindow      where the window is (updated per frame)
//   binding 1  uniform              TerrainParams   the terrain description
//   binding 2  storage, read        array<f32>      heightmap samples (heightmap or mesh terrain)
//   binding 3  storage, read        array<vec2<u32>> the displayed surface, window-local row-major:
//                                   (f32 height bits, pack2x16snorm(normal.x, normal.z))
//
// Functions (world_xz: world (x, z) in metres, relative to the deformation's
// floating origin, which is the world origin unless the game set one):
//   snow_height(world_xz) -> f32          displayed snow surface height (m), rims included
//   snow_normal(world_xz) -> vec3<f32>    unit normal of that surface
//   snow_depth(world_xz) -> f32           snow_height minus the terrain height there, >= 0 (m)
//   snow_compaction(world_xz) -> f32      0 untouched .. 1 pressed to the ground (see below)
//   snow_ground_height(world_xz) -> f32   terrain height under the snow (m)
//   snow_rest_height(world_xz) -> f32     untouched snow: terrain + rest depth (m)
//   snow_inside(world_xz) -> bool         whether the point is inside the deformation window
//
// Inside the window, values are bilinear between texel centres (texel (i, j)
// covers x in corner.x + j*texel .. +texel, z in corner.y + i*texel .. +texel),
// clamped to the outermost centres in the window's outer half texel.
// Outside the window (or before it is placed) they are the untouched rest
// surface: terrain + rest depth, its normal by central differences over one
// texel, compaction 0, depth = rest depth.
//
// Compaction: rest = terrain at the texel centres + rest depth (bilinear like
// the surface), compaction = clamp((rest - snow_height) / rest depth, 0, 1).
// Rims (raised above rest) count as 0. The rest depth is the window's
// `depth_m` plus the snowfall so far on open ground.
//
// Global names this module declares (avoid them in your shader): SnowWindow,
// SnowTaps, snow_window, snow_terrain, heightmap, snow_surface, every snow_*
// function, and shared/terrain.wgsl's TerrainParams, NOISE_OCTAVES,
// lattice_hash, lattice_value, noise_fade, value_noise, fbm, heightmap_at,
// terrain_height.

struct SnowWindow {
    corner: vec2<f32>,          // world (x, z) of local texel (0, 0)'s outer corner, minus the floating origin
    floating_origin: vec2<f32>, // added to world_xz to evaluate the terrain
    origin_texel: vec2<i32>,    // global texel (column, row) of local texel (0, 0)
    texel_m: f32,
    rest_depth_m: f32,
    resolution: u32,
    placed: u32,                // 0 until the deformation has run a frame
    _pad: vec2<u32>,
}

@group(1) @binding(0) var<uniform> snow_window: SnowWindow;
@group(1) @binding(1) var<uniform> snow_terrain: TerrainParams;
@group(1) @binding(2) var<storage, read> heightmap: array<f32>;
@group(1) @binding(3) var<storage, read> snow_surface: array<vec2<u32>>;

fn snow_ground_height(world_xz: vec2<f32>) -> f32 {
    let p = world_xz + snow_window.floating_origin;
    return terrain_height(snow_terrain, p.x, p.y);
}

fn snow_rest_height(world_xz: vec2<f32>) -> f32 {
    return snow_ground_height(world_xz) + snow_window.rest_depth_m;
}

fn snow_inside(world_xz: vec2<f32>) -> bool {
    let extent = f32(snow_window.resolution) * snow_window.texel_m;
    let q = world_xz - snow_window.corner;
    return snow_window.placed != 0u && all(q >= vec2<f32>(0.0)) && all(q <= vec2<f32>(extent));
}

// The four texels around a point inside the window and the bilinear weights.
struct SnowTaps {
    i0: u32,    // row of the lower pair
    j0: u32,    // column of the left pair
    i1: u32,
    j1: u32,
    f: vec2<f32>,
}

fn snow_taps(world_xz: vec2<f32>) -> SnowTaps {
    let r = snow_window.resolution;
    let last = f32(r - 1u);
    let t = clamp((world_xz - snow_window.corner) / snow_window.texel_m - 0.5, vec2<f32>(0.0), vec2<f32>(last));
    let c0 = floor(t);
    let j0 = u32(c0.x);
    let i0 = u32(c0.y);
    return SnowTaps(i0, j0, min(i0 + 1u, r - 1u), min(j0 + 1u, r - 1u), t - c0);
}

fn snow_texel(i: u32, j: u32) -> vec2<u32> {
    return snow_surface[i * snow_window.resolution + j];
}

fn snow_unpack_normal(bits: u32) -> vec3<f32> {
    let xz = unpack2x16snorm(bits);
    return vec3<f32>(xz.x, sqrt(max(1.0 - dot(xz, xz), 0.0)), xz.y);
}

fn snow_bilinear(k: SnowTaps, a: f32, b: f32, c: f32, d: f32) -> f32 {
    return mix(mix(a, b, k.f.x), mix(c, d, k.f.x), k.f.y);
}

fn snow_height(world_xz: vec2<f32>) -> f32 {
    if !snow_inside(world_xz) {
        return snow_rest_height(world_xz);
    }
    let k = snow_taps(world_xz);
    return snow_bilinear(
        k,
        bitcast<f32>(snow_texel(k.i0, k.j0).x),
        bitcast<f32>(snow_texel(k.i0, k.j1).x),
        bitcast<f32>(snow_texel(k.i1, k.j0).x),
        bitcast<f32>(snow_texel(k.i1, k.j1).x),
    );
}

fn snow_normal(world_xz: vec2<f32>) -> vec3<f32> {
    if !snow_inside(world_xz) {
        let e = snow_window.texel_m;
        let dx = snow_rest_height(world_xz + vec2<f32>(e, 0.0)) - snow_rest_height(world_xz - vec2<f32>(e, 0.0));
        let dz = snow_rest_height(world_xz + vec2<f32>(0.0, e)) - snow_rest_height(world_xz - vec2<f32>(0.0, e));
        return normalize(vec3<f32>(-dx, 2.0 * e, -dz));
    }
    let k = snow_taps(world_xz);
    let a = snow_unpack_normal(snow_texel(k.i0, k.j0).y);
    let b = snow_unpack_normal(snow_texel(k.i0, k.j1).y);
    let c = snow_unpack_normal(snow_texel(k.i1, k.j0).y);
    let d = snow_unpack_normal(snow_texel(k.i1, k.j1).y);
    return normalize(mix(mix(a, b, k.f.x), mix(c, d, k.f.x), k.f.y));
}

fn snow_depth(world_xz: vec2<f32>) -> f32 {
    return max(snow_height(world_xz) - snow_ground_height(world_xz), 0.0);
}

// Terrain at local texel (i, j)'s centre, computed as the window pass does
// (from the global texel index), so untouched snow has compaction 0 exactly.
fn snow_texel_ground(i: u32, j: u32) -> f32 {
    let g = snow_window.origin_texel + vec2<i32>(i32(j), i32(i));
    let x = (f32(g.x) + 0.5) * snow_window.texel_m;
    let z = (f32(g.y) + 0.5) * snow_window.texel_m;
    return terrain_height(snow_terrain, x, z);
}

fn snow_compaction(world_xz: vec2<f32>) -> f32 {
    if !snow_inside(world_xz) {
        return 0.0;
    }
    let k = snow_taps(world_xz);
    let ground = snow_bilinear(k, snow_texel_ground(k.i0, k.j0), snow_texel_ground(k.i0, k.j1), snow_texel_ground(k.i1, k.j0), snow_texel_ground(k.i1, k.j1));
    let depth = snow_window.rest_depth_m;
    return clamp((ground + depth - snow_height(world_xz)) / max(depth, 1e-4), 0.0, 1.0);
}
