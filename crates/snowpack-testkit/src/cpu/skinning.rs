//! CPU twin of `skinning.wgsl`: linear blend skinning of a mesh by up to four
//! joints per vertex, then the actor's placement; normals by the same matrices.

use glam::{Mat4, Vec3};

use snowpack::SkinnedMesh;

/// World positions of `mesh`'s vertices for joint matrices `joints` and placement `model`.
#[must_use]
pub fn skin(mesh: &SkinnedMesh, joints: &[Mat4], model: Mat4) -> Vec<Vec3> {
    let last = joints.len().saturating_sub(1);
    mesh.positions
        .iter()
        .zip(&mesh.joints)
        .zip(&mesh.weights)
        .map(|((p, j), w)| {
            let m = (0..4).fold(Mat4::ZERO, |acc, k| acc + joints[(j[k] as usize).min(last)] * w[k]);
            model.transform_point3(m.transform_point3(*p))
        })
        .collect()
}

/// World normals of `mesh`'s vertices for bind-pose `normals`, as `skinning.wgsl`
/// writes them: the blended skin matrix and the placement applied to the normal
/// as a direction, normalised (straight up where it vanishes).
#[must_use]
pub fn skin_normals(mesh: &SkinnedMesh, normals: &[Vec3], joints: &[Mat4], model: Mat4) -> Vec<Vec3> {
    let last = joints.len().saturating_sub(1);
    mesh.joints
        .iter()
        .zip(&mesh.weights)
        .zip(normals)
        .map(|((j, w), n)| {
            let m = (0..4).fold(Mat4::ZERO, |acc, k| acc + joints[(j[k] as usize).min(last)] * w[k]);
            let v = (model * (m * n.extend(0.0))).truncate();
            let len = v.length();
            if len > 1e-12 { v / len } else { Vec3::Y }
        })
        .collect()
}
