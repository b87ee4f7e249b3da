// The terrain kind a pass's pipeline is built for (the window passes:
// `DeformResources::terrain_constants`; the terrain draw: `TerrainPass::new`);
// 255, the default, reads it from the params. A constant kind lets the driver
// drop the other kinds' code: SIMD software adapters (llvmpipe, SwiftShader)
// run every case of the switch in `terrain_height` for every texel, however
// uniform the branch, and that was two fifths of a frame on a flat terrain.

override TERRAIN_KIND: u32 = 255u;

fn terrain_as_built(t: TerrainParams) -> TerrainParams {
    var built = t;
    if TERRAIN_KIND != 255u {
        built.kind = TERRAIN_KIND;
    }
    return built;
}
