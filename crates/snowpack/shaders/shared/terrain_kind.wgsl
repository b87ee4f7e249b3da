// #import shared/terrain

// The terrain kind a pass's pipeline is built for (the window passes:
// `DeformResources::terrain_constants`; the terrain draw: `TerrainPass::new`);
// 255, the default, reads it from the params. A constant kind lets the driver
// drop the other kinds' code: SIMD software adapters (llvmpipe, SwiftShader)
// run every case of the switch in `terrain_height` for every texel, however
// uniform the branch, and that was two fifths of a frame on a flat terrain.

override TERRAIN_KIND: u32 = 255u;

// The kind this pipeline is built for (the params' without the constant).
// Read through the constant, not by overwriting the params' field, so no
// branch on the terrain tests a uniform alone (Mesa 22's lavapipe compiles
// such a shader again at every dispatch and keeps every copy;
// docs/deformation.md, "Branches on uniforms").
fn terrain_kind(t: TerrainParams) -> u32 {
    if TERRAIN_KIND != 255u {
        return TERRAIN_KIND;
    }
    return t.kind;
}

// `terrain_height` for the kind this pipeline is built for.
fn terrain_height_built(t: TerrainParams, x: f32, z: f32) -> f32 {
    return terrain_height_of_kind(terrain_kind(t), t, x, z);
}

// Terrain height at the centre of global texel g = (column, row) of a grid of
// `texel_m` texels: what the deformation passes use as the ground under a
// texel (evaluated where needed rather than stored per texel), for the kind
// the pipeline is built for. CPU twin: `cpu::window::texel_ground`.
fn texel_ground(tp: TerrainParams, g: vec2<i32>, texel_m: f32) -> f32 {
    let x = (f32(g.x) + 0.5) * texel_m;
    let z = (f32(g.y) + 0.5) * texel_m;
    return terrain_height_built(tp, x, z);
}

// The pipeline's kind for noise hills whose value at every window texel is
// stored in the window's ground (`heightmap` then holds one f32 a window
// texel, toroidal like the snow; `window_ground.wgsl` writes the texels a
// move exposes): `DeformResources::terrain_constants`.
const TERRAIN_STORED_NOISE: u32 = 3u;

// The terrain under window texel `g` (global), stored at index `s`: read
// from the window's ground where it is stored, else as `texel_ground`.
// The same value either way (the stored one is `texel_ground`'s), but the
// noise is four octaves of hashes a texel, most of a window pass's
// arithmetic, where the read is four bytes. Only for texels of the current
// window, after this frame's move: the update, display, erosion and
// surface unpack passes and the snow coat.
fn window_ground(tp: TerrainParams, s: u32, g: vec2<i32>, texel_m: f32) -> f32 {
    if terrain_kind(tp) == TERRAIN_STORED_NOISE {
        return heightmap[s];
    }
    return texel_ground(tp, g, texel_m);
}
