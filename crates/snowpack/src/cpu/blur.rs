//! CPU twin of `blur.wgsl`: one axis of the (1 4 6 4 1)/16 Gaussian, clamped at the edges.

/// Blurs window-local `src` along `axis` (0: x, 1: z).
#[must_use]
pub fn blur_axis(src: &[f32], resolution: u32, axis: u32) -> Vec<f32> {
    let r = resolution as i32;
    let at = |along: i32, across: i32| {
        let a = along.clamp(0, r - 1);
        if axis == 0 { src[(across * r + a) as usize] } else { src[(a * r + across) as usize] }
    };
    let mut dst = vec![0.0; src.len()];
    for across in 0..r {
        for along in 0..r {
            let sum = at(along - 2, across) + 4.0 * at(along - 1, across) + 6.0 * at(along, across) + 4.0 * at(along + 1, across) + at(along + 2, across);
            let out = if axis == 0 { across * r + along } else { along * r + across };
            dst[out as usize] = sum * (1.0 / 16.0);
        }
    }
    dst
}

/// The full separable 5x5 blur: x then z.
#[must_use]
pub fn blur(src: &[f32], resolution: u32) -> Vec<f32> {
    blur_axis(&blur_axis(src, resolution, 0), resolution, 1)
}
