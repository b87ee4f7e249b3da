// #import shared/terrain

// snowpack's snow, sampled from a game's own shaders.
//
// Exported as `snowpack::render::ground::SNOW_SAMPLING_WGSL`, which is
// shared/terrain.wgsl (imported above) followed by this file: paste it (or concatenate it)
// ahead of your shader. `SnowGround` (ground.wgsl) uses exactly this module.
//
// Bindings, all in one group (default 1; `snow_sampling_wgsl(group)` in Rust
// rewrites the number; `sampling_layout_entries` gives the layout entries and
// `SnowSampling` builds and updates the bind group from a `SnowDeformation`):
//   binding 0  uniform              SnowWindow      where the window is (updated per frame)
//   binding 1  uniform              TerrainParams   the terrain description
//   binding 2  storage, read        array<f32>      heightmap samples (heightmap or mesh terrain)
//   binding 3  storage, read        array<u32>      the window's snow words, toroidal: global texel
//                                   (col, row) at (row mod res) * res + (col mod res); the
//                                   upper 16 bits of a word are the displayed height above
//                                   the terrain as an f16 (the lower 16 are the persistent
//                                   snow's deficit below rest, not read here)
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
// Normals: the terrain's gradient by central differences over one texel at
// the point, plus the bilinear central differences of the displayed height
// above the terrain between texel centres (no terrain evaluation per texel).
//
// Global names this module declares (avoid them in your shader): SnowWindow,
// SnowTaps, snow_window, snow_terrain, heightmap, snow_words, every snow_*
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
    storage_origin: vec2<u32>,  // origin_texel wrapped into 0..resolution: where local (0, 0) is stored
}

@group(1) @binding(0) var<uniform> snow_window: SnowWindow;
@group(1) @binding(1) var<uniform> snow_terrain: TerrainParams;
@group(1) @binding(2) var<storage, read> heightmap: array<f32>;
@group(1) @binding(3) var<storage, read> snow_words: array<u32>;

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
    // The point's tests first: a branch on the uniform alone has Mesa 22's
    // lavapipe compile the shader again at every draw and keep every copy.
    return all(q >= vec2<f32>(0.0)) && all(q <= vec2<f32>(extent)) && snow_window.placed != 0u;
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

// Displayed height above the terrain of local texel (i, j), clamped into the window.
fn snow_above_ground(i: i32, j: i32) -> f32 {
    let r = snow_window.resolution;
    // Stored at (origin + local) mod r: the origin comes wrapped, so one
    // comparison wraps each (no integer division per tap: a normal takes 20).
    let si = snow_window.storage_origin.y + u32(clamp(i, 0, i32(r) - 1));
    let sj = snow_window.storage_origin.x + u32(clamp(j, 0, i32(r) - 1));
    let h = snow_words[select(si, si - r, si >= r) * r + select(sj, sj - r, sj >= r)] >> 16u;
    // The f16 decoded with integer operations (unpack2x16float needs a
    // capability some downlevel backends lack); snowpack never writes
    // subnormals or infinities.
    let e = (h >> 10u) & 0x1fu;
    let sign = (h & 0x8000u) << 16u;
    if e == 0u {
        return bitcast<f32>(sign);
    }
    return bitcast<f32>(sign | ((e + 112u) << 23u) | ((h & 0x3ffu) << 13u));
}

fn snow_bilinear(k: SnowTaps, a: f32, b: f32, c: f32, d: f32) -> f32 {
    return mix(mix(a, b, k.f.x), mix(c, d, k.f.x), k.f.y);
}

// The displayed height above the terrain, bilinear between texel centres.
fn snow_above_ground_at(k: SnowTaps) -> f32 {
    return snow_bilinear(
        k,
        snow_above_ground(i32(k.i0), i32(k.j0)),
        snow_above_ground(i32(k.i0), i32(k.j1)),
        snow_above_ground(i32(k.i1), i32(k.j0)),
        snow_above_ground(i32(k.i1), i32(k.j1)),
    );
}

fn snow_height(world_xz: vec2<f32>) -> f32 {
    if !snow_inside(world_xz) {
        return snow_rest_height(world_xz);
    }
    let k = snow_taps(world_xz);
    let ground = snow_bilinear(k, snow_texel_ground(k.i0, k.j0), snow_texel_ground(k.i0, k.j1), snow_texel_ground(k.i1, k.j0), snow_texel_ground(k.i1, k.j1));
    return ground + snow_above_ground_at(k);
}

fn snow_normal(world_xz: vec2<f32>) -> vec3<f32> {
    let e = snow_window.texel_m;
    // The terrain's part of the slope (the rest depth is constant over it).
    var dx = snow_ground_height(world_xz + vec2<f32>(e, 0.0)) - snow_ground_height(world_xz - vec2<f32>(e, 0.0));
    var dz = snow_ground_height(world_xz + vec2<f32>(0.0, e)) - snow_ground_height(world_xz - vec2<f32>(0.0, e));
    if snow_inside(world_xz) {
        let k = snow_taps(world_xz);
        let i0 = i32(k.i0);
        let j0 = i32(k.j0);
        let i1 = i32(k.i1);
        let j1 = i32(k.j1);
        // Central differences of the height above the terrain at the four texels.
        dx += snow_bilinear(
            k,
            snow_above_ground(i0, j0 + 1) - snow_above_ground(i0, j0 - 1),
            snow_above_ground(i0, j1 + 1) - snow_above_ground(i0, j1 - 1),
            snow_above_ground(i1, j0 + 1) - snow_above_ground(i1, j0 - 1),
            snow_above_ground(i1, j1 + 1) - snow_above_ground(i1, j1 - 1),
        );
        dz += snow_bilinear(
            k,
            snow_above_ground(i0 + 1, j0) - snow_above_ground(i0 - 1, j0),
            snow_above_ground(i0 + 1, j1) - snow_above_ground(i0 - 1, j1),
            snow_above_ground(i1 + 1, j0) - snow_above_ground(i1 - 1, j0),
            snow_above_ground(i1 + 1, j1) - snow_above_ground(i1 - 1, j1),
        );
    }
    return normalize(vec3<f32>(-dx, 2.0 * e, -dz));
}

fn snow_depth(world_xz: vec2<f32>) -> f32 {
    return max(snow_height(world_xz) - snow_ground_height(world_xz), 0.0);
}

// Terrain at local texel (i, j)'s centre, computed as the deformation does
// (from the global texel index): what the stored heights are above.
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
    // rest - height over the same bilinear terrain: depth - height above it.
    let depth = snow_window.rest_depth_m;
    return clamp((depth - snow_above_ground_at(snow_taps(world_xz))) / max(depth, 1e-4), 0.0, 1.0);
}
