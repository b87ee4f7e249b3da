//! What the fox's examples share: the types a glTF scene's world holds,
//! registered for reflection.

use bevy::prelude::*;

/// Registers the components a glTF scene's world holds for reflection, which
/// spawning it needs: Bevy's `reflect_auto_register` (a default feature this
/// crate leaves off to keep Bevy's build small) would do it.
pub struct GltfTypesPlugin;

impl Plugin for GltfTypesPlugin {
    fn build(&self, app: &mut App) {
        use bevy::animation::{AnimatedBy, AnimationTargetId};
        use bevy::camera::primitives::Aabb;
        use bevy::camera::visibility::{DynamicSkinnedMeshBounds, NoFrustumCulling};
        use bevy::gltf::{GltfExtras, GltfMaterialExtras, GltfMaterialName, GltfMeshExtras, GltfMeshName, GltfSceneExtras, GltfSceneName};
        use bevy::mesh::skinning::SkinnedMesh;
        app.register_type::<Transform>()
            .register_type::<GlobalTransform>()
            .register_type::<bevy::transform::components::TransformTreeChanged>()
            .register_type::<Visibility>()
            .register_type::<InheritedVisibility>()
            .register_type::<ViewVisibility>()
            .register_type::<Name>()
            .register_type::<ChildOf>()
            .register_type::<Children>()
            .register_type::<Mesh3d>()
            .register_type::<MeshMaterial3d<StandardMaterial>>()
            .register_type::<SkinnedMesh>()
            .register_type::<Aabb>()
            .register_type::<NoFrustumCulling>()
            .register_type::<DynamicSkinnedMeshBounds>()
            .register_type::<AnimationPlayer>()
            .register_type::<AnimationTargetId>()
            .register_type::<AnimatedBy>()
            .register_type::<GltfExtras>()
            .register_type::<GltfSceneExtras>()
            .register_type::<GltfMeshExtras>()
            .register_type::<GltfMaterialExtras>()
            .register_type::<GltfSceneName>()
            .register_type::<GltfMeshName>()
            .register_type::<GltfMaterialName>();
    }
}
