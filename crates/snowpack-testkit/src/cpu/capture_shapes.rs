//! CPU twin of the capture pass's analytic shapes (`capture_shapes.wgsl`,
//! its functions in `shared/capture_shapes.wgsl`): the depth each window
//! texel's centre sees looking up from below, by ray casting the same
//! shapes with the same operations. [`capture_depths`] is the whole
//! list: spheres swept over the frame as capsules ([`capsule_bottom`]),
//! tyre poses in the sub-steps [`CaptureInstances`] lists
//! ([`wheel_bottom`]) and boxes; [`quantise_depths`] rounds to the 16-bit
//! codes and [`shape_codes`] packs them as the pass stores them. The
//! shader culls shapes by tile first; culling only skips shapes that
//! cannot reach a texel, so the twin tests every shape at every texel.

use glam::Mat4;

pub use snowpack_share::replicate::press::cast::{capsule_bottom, lowest_box_hit, lowest_depth, wheel_bottom};

use snowpack::low_level::deform::capture::{CaptureInstances, CaptureParams};

/// Depth per window-local texel (row-major), 1.0 where nothing was captured.
#[must_use]
pub fn capture_depths(inst: &CaptureInstances, p: &CaptureParams, resolution: u32) -> Vec<f32> {
    let r = resolution as usize;
    let mut depth = vec![1.0_f32; r * r];
    let range = p.high_m - p.low_m;
    let inverses: Vec<Mat4> = inst.boxes.iter().map(|m| Mat4::from_cols_array(m).inverse()).collect();
    for i in 0..r {
        for j in 0..r {
            let x = (j as f32 + 0.5) * p.texel_m;
            let z = (i as f32 + 0.5) * p.texel_m;
            let shapes = (inst.capsules.iter().copied(), inst.wheels.iter().copied(), inverses.iter().copied());
            let best = lowest_depth(shapes, [x, z], p.low_m, range);
            depth[i * r + j] = best;
        }
    }
    depth
}

/// Rounds depths to the capture target's 16-bit codes
/// ([`snowpack::low_level::height_depth::CAPTURE_FORMAT`]), as the GPU stores them:
/// call after [`capture_depths`] and [`super::capture_mesh::capture_triangles`] (rounding is
/// monotonic, so the lowest surface stays the lowest).
pub fn quantise_depths(depth: &mut [f32]) {
    use snowpack::low_level::height_depth::CAPTURE_CODES;
    for d in depth {
        *d = (*d * CAPTURE_CODES).round() / CAPTURE_CODES;
    }
}

/// The depths as `capture_shapes.wgsl` stores them (after
/// [`quantise_depths`]): two texels a word, even column in the low half,
/// each 65535 minus its 16-bit code, 0 where nothing was captured.
#[must_use]
pub fn shape_codes(depth: &[f32]) -> Vec<u32> {
    use snowpack::low_level::height_depth::CAPTURE_CODES;
    let stored = |d: f32| if d >= 1.0 { 0 } else { 65535 - (d * CAPTURE_CODES + 0.5).floor() as u32 };
    depth.chunks(2).map(|pair| stored(pair[0]) | (stored(pair.get(1).copied().unwrap_or(1.0)) << 16)).collect()
}
