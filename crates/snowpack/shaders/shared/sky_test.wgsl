// The sky test against the objects' occlusion depth (occlusion.wgsl): a
// point of the window, projected along the snowfall onto the occlusion map,
// is reached by the sky when nothing there is above it. The update's
// snowfall and the snow coat test it. `SkyTest` in `src/height_depth.rs`,
// whose `reaches` is the CPU twin of the two functions below.

struct SkyTest {
    shear: vec2<f32>,       // d.xz / -d.y for the fall direction d
    offset_m: vec2<f32>,    // the occlusion's jitter against the window (m)
    y0_m: f32,              // height of the projection plane (m)
    low_m: f32,             // height at occlusion depth 1 (m)
    high_m: f32,            // height at occlusion depth 0 (m)
    _pad: u32,
}

// Below the surface the occlusion saw by less than this, a point still counts as seen (m).
const SKY_BIAS_M: f32 = 0.02;

// The occlusion map's pixel under window-local point q0 (m) at height h, in a
// window of `resolution` texels of `texel_m`; (-1, -1) off the map, where the sky reaches.
fn sky_test_pixel(s: SkyTest, q0: vec2<f32>, h: f32, texel_m: f32, resolution: u32) -> vec2<i32> {
    let q = q0 + s.shear * (h - s.y0_m) + s.offset_m;
    let pix = floor(q / texel_m);
    let r = f32(resolution);
    if pix.x < 0.0 || pix.y < 0.0 || pix.x >= r || pix.y >= r {
        return vec2<i32>(-1, -1);
    }
    return vec2<i32>(pix);
}

// 1 where a point at height h is reached by the sky, the occlusion depth at its pixel being `seen`.
fn sky_test_seen(s: SkyTest, h: f32, seen: f32) -> f32 {
    let here = (s.high_m - (h + SKY_BIAS_M)) / (s.high_m - s.low_m);
    return select(0.0, 1.0, here <= seen);
}
