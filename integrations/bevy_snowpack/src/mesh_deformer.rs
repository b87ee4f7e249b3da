//! Meshes that press the snow in their current pose: [`SnowDeformer::Mesh`],
//! and [`SnowDeformer::Capsule`] as the triangles of Bevy's `Capsule3d`.
//!
//! Each mesh entity under a `SnowDeformer::Mesh` is registered once with the
//! library as a skinned mesh (`SnowDeformation::add_skinned_mesh`): a Bevy
//! skinned mesh with its own joints and weights, any other mesh as a skin of
//! one joint placed by the entity's `GlobalTransform`. Every frame only the
//! joint matrices travel to the render world; the library skins the mesh on
//! the GPU and sweeps it from its last pose, so a walking character and a
//! thrown crate both press what their triangles cover.

use std::collections::HashMap;
use std::sync::Arc;

use bevy::mesh::skinning::{SkinnedMesh as BevySkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::prelude::*;
use snowpack::SkinnedMesh;

use crate::SnowDeformer;

/// A mesh to register with the library: its key (the mesh entity), the mesh
/// in its bind pose and its skin's joint count.
#[derive(Clone)]
pub(crate) struct MeshRegistration {
    pub key: u64,
    pub mesh: Arc<SkinnedMesh>,
    pub joint_count: usize,
}

/// One mesh's pose this frame: world matrices that take its bind-pose
/// vertices to the world (Bevy's joint transform times inverse bind pose).
#[derive(Clone)]
pub(crate) struct MeshPose {
    pub key: u64,
    pub joints: Vec<Mat4>,
    /// The deformer's [`crate::SnowCoatSettings`], if it has some.
    pub coat: Option<snowpack::CoatSettings>,
}

/// What the main world hands the render world about mesh deformers each frame.
#[derive(Resource, Clone, Default)]
pub(crate) struct MeshDeformerFrame {
    /// Meshes seen for the first time (or whose mesh asset changed) this frame.
    pub registrations: Vec<MeshRegistration>,
    /// Every mesh deformer's pose this frame.
    pub poses: Vec<MeshPose>,
}

/// Which mesh asset each mesh entity was registered with, and the size
/// (radius and half length, as bits) each capsule's was made for.
#[derive(Default)]
struct Registered(HashMap<Entity, AssetId<Mesh>>, HashMap<Entity, [u32; 2]>);

/// Triangles of a capsule's mesh around its circumference (Bevy's default is 32).
const CAPSULE_LONGITUDES: u32 = 24;

pub(crate) fn build(app: &mut App) {
    app.init_resource::<MeshDeformerFrame>().add_systems(PostUpdate, pose_mesh_deformers.in_set(crate::SnowSystems::Gather));
}

/// A Bevy mesh as the library's skinned mesh: its own skin when it has
/// joints and weights, else one joint (index 0, weight 1). `None` when it has
/// no triangles or positions the main world can read.
pub(crate) fn library_mesh(mesh: &Mesh, skinned: bool) -> Option<SkinnedMesh> {
    let Ok(VertexAttributeValues::Float32x3(positions)) = mesh.try_attribute(Mesh::ATTRIBUTE_POSITION) else { return None };
    let positions: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
    let n = positions.len();
    let indices: Vec<u32> = match mesh.try_indices_option() {
        Ok(Some(Indices::U16(i))) => i.iter().map(|&k| u32::from(k)).collect(),
        Ok(Some(Indices::U32(i))) => i.clone(),
        // Unindexed: a triangle list in vertex order.
        Ok(None) => (0..u32::try_from(n).ok()?).collect(),
        Err(_) => return None,
    };
    let indices: Vec<u32> = indices.chunks_exact(3).filter(|t| t.iter().all(|&k| (k as usize) < n)).flatten().copied().collect();
    if n == 0 || indices.is_empty() {
        return None;
    }
    let skin = match (mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_INDEX), mesh.try_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT)) {
        (Ok(VertexAttributeValues::Uint16x4(j)), Ok(VertexAttributeValues::Float32x4(w))) if skinned && j.len() == n && w.len() == n => {
            Some((j.clone(), w.iter().map(|&w| normalised(w)).collect()))
        }
        _ => None,
    };
    let (joints, weights) = skin.unwrap_or_else(|| (vec![[0; 4]; n], vec![[1.0, 0.0, 0.0, 0.0]; n]));
    Some(SkinnedMesh { positions, joints, weights, indices })
}

/// Weights that sum to 1 (glTF exporters leave small errors; all zero binds to the first joint).
fn normalised(w: [f32; 4]) -> [f32; 4] {
    let w = w.map(|x| if x.is_finite() { x.max(0.0) } else { 0.0 });
    let sum: f32 = w.iter().sum();
    if sum > 1e-6 { w.map(|x| x / sum) } else { [1.0, 0.0, 0.0, 0.0] }
}

/// Gathers the mesh deformers' poses (after transforms and skins are propagated).
#[allow(clippy::too_many_arguments, reason = "a Bevy system: each argument is a query or resource it reads")]
fn pose_mesh_deformers(
    mut frame: ResMut<MeshDeformerFrame>,
    mut registered: Local<Registered>,
    deformers: Query<(Entity, &SnowDeformer, Option<&crate::SnowCoatSettings>)>,
    children: Query<&Children>,
    meshes: Query<(&Mesh3d, &GlobalTransform, Option<&BevySkinnedMesh>)>,
    joints: Query<&GlobalTransform>,
    mesh_assets: Res<Assets<Mesh>>,
    bindposes: Res<Assets<SkinnedMeshInverseBindposes>>,
) {
    frame.registrations.clear();
    frame.poses.clear();
    for (root, deformer, coat) in &deformers {
        if let SnowDeformer::Capsule { radius, half_length } = *deformer {
            pose_capsule(&mut frame, &mut registered.1, root, (radius, half_length), coat.map(|c| c.0), joints.get(root).ok());
        }
    }
    for (root, _, coat) in deformers.iter().filter(|(_, d, _)| matches!(d, SnowDeformer::Mesh)) {
        let coat = coat.map(|c| c.0);
        // The entity's own mesh, or (a glTF scene's root) every mesh below it.
        let targets: Vec<Entity> = if meshes.contains(root) { vec![root] } else { children.iter_descendants(root).filter(|&e| meshes.contains(e)).collect() };
        for entity in targets {
            let Ok((mesh3d, transform, skin)) = meshes.get(entity) else { continue };
            // A skinned mesh is placed by its joints: world = joint * inverse bind pose.
            let pose: Option<Vec<Mat4>> = match skin {
                Some(skin) => bindposes
                    .get(&skin.inverse_bindposes)
                    .and_then(|inverse| skin.joints.iter().zip(inverse.iter()).map(|(&j, inv)| joints.get(j).ok().map(|g| g.to_matrix() * *inv)).collect()),
                None => Some(vec![transform.to_matrix()]),
            };
            let Some(pose) = pose else { continue };
            let key = entity.to_bits();
            if registered.0.get(&entity) != Some(&mesh3d.id()) {
                let Some(mesh) = mesh_assets.get(&mesh3d.0).and_then(|m| library_mesh(m, skin.is_some())) else { continue };
                // A skin whose vertices name joints it lacks is not one the library can pose.
                if mesh.validate(pose.len()).is_err() {
                    tracing::warn!("bevy_snowpack: the mesh of {entity} does not fit its skin of {} joints; it does not press the snow", pose.len());
                    registered.0.insert(entity, mesh3d.id());
                    continue;
                }
                registered.0.insert(entity, mesh3d.id());
                frame.registrations.push(MeshRegistration { key, mesh: Arc::new(mesh), joint_count: pose.len() });
            }
            frame.poses.push(MeshPose { key, joints: pose, coat });
        }
    }
}

/// A capsule deformer: its mesh registered once per size (a skin of one
/// joint, the entity's transform), its pose every frame.
fn pose_capsule(
    frame: &mut MeshDeformerFrame,
    registered: &mut HashMap<Entity, [u32; 2]>,
    entity: Entity,
    (radius, half_length): (f32, f32),
    coat: Option<snowpack::CoatSettings>,
    transform: Option<&GlobalTransform>,
) {
    let Some(transform) = transform else { return };
    let key = entity.to_bits();
    let size = [radius.to_bits(), half_length.to_bits()];
    if registered.get(&entity) != Some(&size) {
        registered.insert(entity, size);
        if !(radius > 0.0 && half_length >= 0.0 && radius.is_finite() && half_length.is_finite()) {
            tracing::warn!("bevy_snowpack: the capsule of {entity} (radius {radius}, half length {half_length}) does not press the snow");
            return;
        }
        let mesh = Capsule3d::new(radius, 2.0 * half_length).mesh().longitudes(CAPSULE_LONGITUDES).build();
        let Some(mesh) = library_mesh(&mesh, false) else { return };
        frame.registrations.push(MeshRegistration { key, mesh: Arc::new(mesh), joint_count: 1 });
    }
    frame.poses.push(MeshPose { key, joints: vec![transform.to_matrix()], coat });
}

#[cfg(test)]
mod tests {
    use bevy::asset::RenderAssetUsages;
    use bevy::mesh::PrimitiveTopology;

    use super::*;

    #[test]
    fn a_plain_mesh_is_a_skin_of_one_joint_and_a_skinned_one_keeps_its_weights() {
        let mut mesh = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default());
        mesh.insert_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]);
        mesh.insert_indices(Indices::U16(vec![0, 1, 2, 2, 1, 3, 0, 9, 1]));
        let plain = library_mesh(&mesh, false).expect("a plain mesh");
        // The triangle naming vertex 9 is dropped.
        assert_eq!(plain.indices, vec![0, 1, 2, 2, 1, 3]);
        assert!(plain.joints.iter().all(|j| *j == [0; 4]) && plain.weights.iter().all(|w| *w == [1.0, 0.0, 0.0, 0.0]));
        assert!(plain.validate(1).is_ok());

        mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(vec![[0, 1, 0, 0], [1, 0, 0, 0], [2, 0, 0, 0], [0, 0, 0, 0]]));
        mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, vec![[0.5, 0.49, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0], [0.0; 4]]);
        let skinned = library_mesh(&mesh, true).expect("a skinned mesh");
        assert_eq!(skinned.joints[2], [2, 0, 0, 0]);
        assert!((skinned.weights[0][0] - 0.5 / 0.99).abs() < 1e-6);
        assert_eq!(skinned.weights[2], [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(skinned.weights[3], [1.0, 0.0, 0.0, 0.0]);
        assert!(skinned.validate(3).is_ok());
        // Joint 2 needs a skin of three joints.
        assert!(skinned.validate(2).is_err());
    }
}
