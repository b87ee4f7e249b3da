//! CPU twin of the capture pass's spheres (`capture_sphere.wgsl`): the depth
//! each window texel's centre sees looking up from below, by ray casting the
//! same shapes analytically. [`capture_depths`] is the whole pass's instanced
//! shapes: spheres swept over the frame as capsules (here), wheels
//! (`capture_wheel.wgsl`, [`super::capture_wheel::wheel_bottom`]) in the
//! sub-steps [`CaptureInstances`] lists, and boxes (`capture_mesh.wgsl`,
//! whose meshes are [`super::capture_mesh`]).

use glam::{Mat4, Vec3};

use super::capture_mesh::lowest_box_hit;
use super::capture_wheel::wheel_bottom;
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
            let mut best = 1.0_f32;
            for c in &inst.capsules {
                let Some(y) = capsule_bottom([x, z], [c[0], c[1], c[2]], [c[4], c[5], c[6]], c[3]) else { continue };
                let d = (y - p.low_m) / range;
                if d <= 1.0 {
                    best = best.min(d.clamp(0.0, 1.0));
                }
            }
            for w in &inst.wheels {
                let (dx, dz) = (x - w[0], z - w[2]);
                let reach = w[3].hypot(w[7]);
                if dx.abs() > reach || dz.abs() > reach {
                    continue;
                }
                let Some(y) = wheel_bottom(Vec3::new(dx, 0.0, dz), w) else { continue };
                let d = (w[1] + y - p.low_m) / range;
                if d <= 1.0 {
                    best = best.min(d.clamp(0.0, 1.0));
                }
            }
            for inv in &inverses {
                if let Some(y) = lowest_box_hit(inv, x, z, p.low_m) {
                    let d = (y - p.low_m) / range;
                    if d < 1.0 {
                        best = best.min(d.max(0.0));
                    }
                }
            }
            depth[i * r + j] = best;
        }
    }
    depth
}

/// Lowest height where the vertical line through `p` (x, z) meets the sphere
/// at `c` of radius `r`.
fn sphere_bottom(p: [f32; 2], c: [f32; 3], r: f32) -> Option<f32> {
    let (dx, dz) = (p[0] - c[0], p[1] - c[2]);
    let d2 = dx * dx + dz * dz;
    (d2 <= r * r).then(|| c[1] - (r * r - d2).sqrt())
}

/// Lowest height where the vertical line through `p` (x, z) meets the
/// capsule of radius `r` around the segment `a`..`b` (a swept sphere), as
/// `capture_sphere.wgsl` computes it: the lower of the end spheres and the
/// lateral cylinder where its hit projects inside the segment.
#[must_use]
pub fn capsule_bottom(p: [f32; 2], a: [f32; 3], b: [f32; 3], r: f32) -> Option<f32> {
    let ends = [sphere_bottom(p, a, r), sphere_bottom(p, b, r)];
    let mut best = ends.into_iter().flatten().reduce(f32::min);
    let (a, b) = (Vec3::from(a), Vec3::from(b));
    let axis = b - a;
    let len2 = axis.length_squared();
    if len2 < 1e-12 {
        return best;
    }
    let u = axis / len2.sqrt();
    let w0 = Vec3::new(p[0] - a.x, 0.0, p[1] - a.z);
    let wu = w0.dot(u);
    let qa = 1.0 - u.y * u.y;
    if qa < 1e-6 {
        return best;
    }
    let qb = w0.y - wu * u.y;
    let qc = w0.length_squared() - wu * wu - r * r;
    let disc = qb * qb - qa * qc;
    if disc < 0.0 {
        return best;
    }
    let y = (-qb - disc.sqrt()) / qa;
    let t = (wu + y * u.y) / len2.sqrt();
    if (0.0..=1.0).contains(&t) {
        best = Some(best.map_or(a.y + y, |v| v.min(a.y + y)));
    }
    best
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
