// Shared by every pass that maps window-local texels to the toroidal storage.
//
// The window's local texel (i, j) (row i = +z, column j = +x) is the global
// texel (origin.y + i, origin.x + j); it is stored at the global index modulo
// the resolution, so sliding the window never moves stored texels.

// Euclidean remainder with only non-negative operands: GLSL leaves `%` of
// negative integers undefined, and naga's GL output inherits that.
fn wrap_index(g: i32, res: i32) -> i32 {
    if g >= 0 {
        return g % res;
    }
    return (res - 1) - ((-1 - g) % res);
}

fn storage_index(origin: vec2<i32>, res: u32, i: u32, j: u32) -> u32 {
    let r = i32(res);
    let si = wrap_index(origin.y + i32(i), r);
    let sj = wrap_index(origin.x + i32(j), r);
    return u32(si) * res + u32(sj);
}

// The same index without a division, for the passes that visit every texel
// every frame: `wrapped` is the origin already wrapped into 0..res on the CPU
// (`storage_origin` in src/deform/window.rs) and i, j are below `res`, so one
// comparison wraps each. A division per texel, by a value the compiler does
// not know, was the costliest step of the display pass on a SIMD software
// rasteriser (it divides lane by lane), and is a long sequence on GPUs too.
// (Wrapping `origin` here instead would branch on uniforms alone, which Mesa's
// lavapipe answers by recompiling the pipeline whenever the window moves.)
fn storage_index_wrapped(wrapped: vec2<u32>, res: u32, i: u32, j: u32) -> u32 {
    let si = wrapped.y + i;
    let sj = wrapped.x + j;
    return select(si, si - res, si >= res) * res + select(sj, sj - res, sj >= res);
}

// Window-local texel (i, j) of the k-th texel of the exposed rectangles
// (row0, col0, rows, cols; `count` of them used, row-major within each),
// with z = 1, or z = 0 when k is past them.
fn rect_texel(k_in: u32, rects: array<vec4<u32>, 2>, count: u32) -> vec3<u32> {
    var k = k_in;
    var rect = rects[0];
    if k >= rect.z * rect.w {
        k -= rect.z * rect.w;
        rect = rects[1];
        // Past the last rectangle; `count` tested with `k`, never alone
        // (a branch on a uniform alone: docs/deformation.md).
        if k >= rect.z * rect.w || count < 2u {
            return vec3<u32>(0u);
        }
    }
    return vec3<u32>(rect.x + k / rect.w, rect.y + k % rect.w, 1u);
}
