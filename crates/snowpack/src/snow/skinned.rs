//! The handles of the characters plug-in ([`super::characters`]): a
//! registered skinned mesh and one frame's pose of it. Apart from the
//! plug-in, which the coats and the frame's input both name.

/// A skinned mesh registered with [`super::SnowDeformation::add_skinned_mesh`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SkinnedId(pub(super) usize);

/// One character's pose for a frame: which mesh, its joint matrices and its placement.
#[derive(Clone, Copy, Debug)]
pub struct SkinnedPose<'a> {
    /// The registered mesh.
    pub mesh: SkinnedId,
    /// Skinning matrix of each joint (`crate::skin::Skeleton::joint_matrices`).
    pub joints: &'a [glam::Mat4],
    /// Position, heading and scale in the world.
    pub model: glam::Mat4,
}
