// The uniforms of the passes over the texels a window move exposed: the
// window pass (window.wgsl, fresh snow) and the window ground pass
// (window_ground.wgsl, the terrain under them). Rust: `WindowParams` in
// src/deform/window.rs.

struct WindowParams {
    origin: vec2<i32>,      // global texel index of local (0, 0): x = column, y = row
    resolution: u32,
    texel_m: f32,
    depth_m: f32,
    rect_count: u32,
    fallen_m: f32,          // snowfall so far on open ground, given to new texels
    flags: u32,             // 1: write `fallen`, 2: write `stamps`, 4: count what the texels held as left

    rects: array<vec4<u32>, 2>, // local (row0, col0, rows, cols)
}
