// #import shared/window
// #import shared/window_params
// #import shared/terrain
// #import shared/terrain_kind

// Window ground pass: the terrain under each texel a move exposed (at most
// two rectangles, as the window pass), stored at the texel's place in the
// window's ground, for noise hills (TERRAIN_STORED_NOISE). The update,
// display, erosion and unpack passes then read four bytes a texel where
// they evaluated four octaves of hashed noise, several times a texel a
// frame. Runs after the move's snow (the window pass or the tiles'
// exchange, which evaluate the ground themselves: the stash reads the
// leaving texels' ground before this overwrites it). CPU twin: the value
// is `cpu::window::texel_ground`'s (snowpack-testkit), as `texel_ground`.

@group(0) @binding(0) var<uniform> params: WindowParams; // shared/window_params.wgsl (the window pass's)
@group(0) @binding(1) var<uniform> terrain_params: TerrainParams;
// The window's ground (its heightmap binding: one f32 a window texel).
@group(0) @binding(2) var<storage, read_write> heightmap: array<f32>;

const WORKGROUP: u32 = 256u;

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let texel = rect_texel(gid.x + gid.y * groups.x * WORKGROUP, params.rects, params.rect_count);
    if texel.z == 0u {
        return;
    }
    let s = storage_index(params.origin, params.resolution, texel.x, texel.y);
    heightmap[s] = texel_ground(terrain_params, params.origin + vec2<i32>(i32(texel.y), i32(texel.x)), params.texel_m);
}
