//! CPU twin of the capture pass's meshes (`capture_mesh.wgsl`): swept
//! meshes' triangles as the GPU draws them (boxes are analytic shapes:
//! [`super::capture_shapes`]).

use snowpack::low_level::deform::capture::CaptureParams;

/// The triangles a swept mesh is drawn as (`capture_mesh.wgsl`, `vs_swept`):
/// each of `steps + 1` sub-steps t = k / steps, every corner at
/// `mix(previous, current, t)`; `steps = 0` is the current pose alone.
#[must_use]
pub fn swept_triangles(previous: &[[[f32; 3]; 3]], current: &[[[f32; 3]; 3]], steps: u32) -> Vec<[[f32; 3]; 3]> {
    if steps == 0 {
        return current.to_vec();
    }
    let mut out = Vec::with_capacity(current.len() * (steps as usize + 1));
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        out.extend(previous.iter().zip(current).map(|(a, b)| std::array::from_fn(|v| std::array::from_fn(|c| a[v][c] * (1.0 - t) + b[v][c] * t))));
    }
    out
}

/// Adds world-space triangles to `depth` (window-local texels, as
/// [`super::capture_shapes::capture_depths`] returns): the lowest surface per texel centre, and each
/// corner as a point in the texel it lies in, as the GPU draws
/// [`snowpack::low_level::deform::capture::CaptureMesh`]es.
pub fn capture_triangles(depth: &mut [f32], triangles: &[[[f32; 3]; 3]], corner: glam::DVec2, p: &CaptureParams, resolution: u32) {
    // The terrain bake's rasteriser keeps the highest surface; mirror heights to keep the lowest.
    let mirrored: Vec<[[f32; 3]; 3]> =
        triangles.iter().map(|t| t.map(|v| [(f64::from(v[0]) - corner.x) as f32, -v[1], (f64::from(v[2]) - corner.y) as f32])).collect();
    let extent = p.texel_m * resolution as f32;
    let lowest = super::terrain_bake::draw(&mirrored, resolution, resolution, [0.0, 0.0], [extent, extent], f32::NEG_INFINITY);
    let range = p.high_m - p.low_m;
    for (d, y) in depth.iter_mut().zip(lowest) {
        if y.is_finite() {
            let v = (-y - p.low_m) / range;
            // Outside [0, 1] the GPU clips the fragment: no mark.
            if (0.0..=1.0).contains(&v) {
                *d = d.min(v);
            }
        }
    }
    let res = i64::from(resolution);
    for v in mirrored.iter().flatten() {
        let (col, row) = ((f64::from(v[0]) / f64::from(p.texel_m)).floor() as i64, (f64::from(v[2]) / f64::from(p.texel_m)).floor() as i64);
        let depth_of = (-v[1] - p.low_m) / range;
        if (0..res).contains(&col) && (0..res).contains(&row) && (0.0..=1.0).contains(&depth_of) {
            let d = &mut depth[(row * res + col) as usize];
            *d = d.min(depth_of);
        }
    }
}
