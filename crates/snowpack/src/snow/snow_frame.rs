//! One frame's input to [`crate::SnowDeformation::encode`]: what presses the snow
//! (deformers, posed characters, the caller's meshes) and what is asked of it.
//! A file of its own: the frame's steps and the characters read it, and the
//! orchestrator that runs them is above them.

use crate::Deformer;
use crate::deform::capture::CaptureMesh;

use super::skinned::SkinnedPose;

/// What presses the snow in one frame: the input of [`crate::SnowDeformation::encode`],
/// made with [`SnowFrame::new`] and the `with_` builders.
#[derive(Clone, Copy, Debug, Default)]
pub struct SnowFrame<'a> {
    /// Seconds since the last frame (refill and snowfall advance by it).
    pub(crate) dt_s: f32,
    /// Spheres, boxes and contact points.
    pub(crate) deformers: &'a [Deformer],
    /// Characters: registered skinned meshes in this frame's pose.
    pub(crate) poses: &'a [SkinnedPose<'a>],
    /// World-space triangle meshes the caller has already posed this frame
    /// (recorded into the same encoder before [`crate::SnowDeformation::encode`]).
    pub(crate) meshes: &'a [CaptureMesh<'a>],
    /// How far (m) any vertex of `meshes[k]` moved since the last frame, an
    /// upper bound: mesh k is swept over that motion when it has one here,
    /// its vertex buffer has `COPY_SRC` usage and it had as many vertices
    /// last frame ([`Self::with_mesh_travel`]); otherwise only its current
    /// pose presses.
    pub(crate) mesh_travel_m: &'a [f32],
    /// A stable id per deformer (the same body has the same id every frame),
    /// to find each one's last pose when the list's length or order changes
    /// ([`Self::with_ids`]); empty (or of another length): deformer k is
    /// the same body as last frame's deformer k.
    pub(crate) ids: &'a [u64],
    /// Points (x, z relative to the floating origin, like deformers) to
    /// ask the snow at, as this frame leaves it ([`Self::with_queries`]);
    /// `None`: nothing asked.
    pub(crate) queries: Option<&'a [glam::Vec2]>,
}

impl<'a> SnowFrame<'a> {
    /// A frame of `dt_s` seconds with `deformers` and nothing else.
    #[must_use]
    pub fn new(dt_s: f32, deformers: &'a [Deformer]) -> Self {
        Self { dt_s, deformers, poses: &[], meshes: &[], mesh_travel_m: &[], ids: &[], queries: None }
    }

    /// The same frame with characters in pose.
    #[must_use]
    pub fn with_poses(mut self, poses: &'a [SkinnedPose<'a>]) -> Self {
        self.poses = poses;
        self
    }

    /// The same frame with caller-posed meshes.
    #[must_use]
    pub fn with_meshes(mut self, meshes: &'a [CaptureMesh<'a>]) -> Self {
        self.meshes = meshes;
        self
    }

    /// The same frame with the motion of each caller mesh since the last
    /// frame, so they are swept: `travel_m[k]` is how far (m) any vertex of
    /// mesh k moved, an upper bound. Mesh k is swept over that motion when
    /// it has one here, its vertex buffer has `COPY_SRC` usage and it had as
    /// many vertices last frame; otherwise only its current pose presses.
    #[must_use]
    pub fn with_mesh_travel(mut self, travel_m: &'a [f32]) -> Self {
        self.mesh_travel_m = travel_m;
        self
    }

    /// The same frame with a stable id per deformer (the same body has the
    /// same id every frame), so each is swept from its own last pose when
    /// the list's length or order changes (see `crate::deform::sweep`).
    /// Without ids (or with another number of them), deformer k is the
    /// same body as last frame's deformer k.
    #[must_use]
    pub fn with_ids(mut self, ids: &'a [u64]) -> Self {
        self.ids = ids;
        self
    }

    /// The same frame asking for the snow at `points` (world x, z relative
    /// to the floating origin, like deformers) as this frame leaves it.
    /// [`crate::SnowDeformation::encode`] returns the request's ticket; the
    /// answer, tagged with it, arrives a frame or two later in
    /// [`crate::SnowDeformation::point_answers`], and a frame never waits for it.
    /// If the GPU is so far behind that every staging buffer is in flight,
    /// the request is dropped and counted (`query_stats`, with `low_level`): ask
    /// again (games ask every frame).
    #[must_use]
    pub fn with_queries(mut self, points: &'a [glam::Vec2]) -> Self {
        self.queries = Some(points);
        self
    }
}
