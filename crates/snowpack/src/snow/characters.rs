//! The characters plug-in: skinned meshes registered once, posed on the GPU
//! each frame (the `skinning` pass), and every mesh that presses the snow
//! (posed characters, then the caller's) with its last frame's positions
//! and sub-steps, so the capture sweeps it over its motion.

use crate::deform::capture::{CaptureMesh, SweptMesh};
use crate::deform::resources::DeformResources;
use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::GpuContext;
use crate::skin::coat::CoatSettings;
use crate::skin::skinning::{SkinnedInstance, SkinnedMesh, SkinningPass};

use super::coat::Coats;
use super::core_window::CoreWindow;
use super::ground_after::GroundAfter;
use super::skinned::SkinnedId;
use super::snow_frame::SnowFrame;
use super::sweep::{MeshHistory, MeshKey};

/// The skinned meshes, their skinning pass and every pressing mesh's history.
pub(super) struct Characters {
    skinning: SkinningPass,
    skinned: Vec<SkinnedInstance>,
    /// Skinned meshes posed in the last encoded frame (indices into `skinned`).
    posed: Vec<usize>,
    /// Last frame's positions of the meshes, to sweep them.
    history: MeshHistory,
    /// Sub-steps of each mesh this frame (posed characters, then the
    /// caller's), kept for its memory.
    steps: Vec<u32>,
    /// The snow the characters carry ([`super::coat`]).
    coats: Coats,
}

impl Characters {
    /// No characters yet, over the window of `res`.
    pub(super) fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        Self {
            skinning: SkinningPass::new(device),
            skinned: Vec::new(),
            posed: Vec::new(),
            history: MeshHistory::default(),
            steps: Vec::new(),
            coats: Coats::new(device, res),
        }
    }

    /// Records the coat pass of every character posed this frame ([`super::coat`]).
    pub(super) fn record_coats(&mut self, cx: &mut FrameContext<'_>, core: &CoreWindow, sky: Option<&wgpu::TextureView>, ground: GroundAfter, dt_s: f32) {
        self.coats.record(cx, core, sky, ground, dt_s, (&self.posed, &self.skinned));
    }

    /// Uploads a skinned mesh (a character's); `joint_count` is its skin's.
    pub(super) fn add(&mut self, ctx: &GpuContext, mesh: &SkinnedMesh, joint_count: usize) -> Result<SkinnedId, SnowError> {
        let instance = self.skinning.instance(&ctx.device, &ctx.queue, mesh, joint_count)?;
        self.skinned.push(instance);
        self.coats.register();
        let reach = crate::deform::sweep::JointReach::of_skin(&mesh.positions, &mesh.joints, &mesh.weights, joint_count);
        self.history.register_skinned(self.skinned.len() - 1, reach);
        Ok(SkinnedId(self.skinned.len() - 1))
    }

    /// The skinning pass for each of `frame.poses`, and every mesh's
    /// sub-steps for the capture (a character's from its joints' sweep, a
    /// caller's from its travel); meshes further than `teleport_m` jumped
    /// and are not swept.
    pub(super) fn record_poses(&mut self, cx: &mut FrameContext<'_>, frame: &SnowFrame<'_>, texel_m: f32, teleport_m: f32) {
        self.posed.clear();
        self.steps.clear();
        for pose in frame.poses {
            let Some(instance) = self.skinned.get(pose.mesh.0) else { continue };
            self.skinning.record(cx, instance, pose.joints, pose.model);
            self.posed.push(pose.mesh.0);
            let world = pose.joints.iter().map(|j| pose.model * *j).collect();
            self.steps.push(self.history.skinned_steps(pose.mesh.0, world, texel_m, teleport_m));
        }
        for k in 0..frame.meshes.len() {
            // No travel given (NaN) compares false: not swept.
            let travel = frame.mesh_travel_m.get(k).copied().unwrap_or(f32::NAN);
            self.steps.push(if teleport_m > 0.0 && travel <= teleport_m { crate::deform::sweep::steps_for(travel, texel_m) } else { 0 });
        }
    }

    /// This frame's pressing meshes, each with its key in the history: the
    /// posed characters, then `caller`'s.
    fn meshes<'a>(&'a self, caller: &'a [CaptureMesh<'a>]) -> impl Iterator<Item = (CaptureMesh<'a>, MeshKey)> + 'a {
        let posed = self.posed.iter().map(|&k| {
            let s = &self.skinned[k];
            (CaptureMesh { vertices: &s.skinned, indices: &s.indices, index_count: s.index_count, vertex_count: s.vertex_count }, MeshKey::Skinned(k))
        });
        posed.chain(caller.iter().enumerate().map(|(k, &mesh)| (mesh, MeshKey::Caller(k))))
    }

    /// This frame's pressing meshes (see [`Self::record_poses`]) with their
    /// last frame's positions, and their sub-steps.
    pub(super) fn swept<'a>(&'a self, caller: &'a [CaptureMesh<'a>]) -> (Vec<SweptMesh<'a>>, &'a [u32]) {
        let swept =
            self.meshes(caller).map(|(mesh, key)| SweptMesh { mesh, previous: self.history.previous(key, u64::from(mesh.vertex_count) * 12) }).collect();
        (swept, &self.steps)
    }

    /// Records the copy of this frame's positions of the pressing meshes
    /// (`caller`'s after the characters'): the next frame's previous ones
    /// (after the frame's passes, which read the old).
    pub(super) fn remember(&mut self, cx: &mut FrameContext<'_>, caller: &[CaptureMesh<'_>]) {
        let mut history = std::mem::take(&mut self.history);
        history.age();
        for (mesh, key) in self.meshes(caller) {
            history.remember(cx.device(), cx.encoder, key, mesh.vertices, u64::from(mesh.vertex_count) * 12);
        }
        self.history = history;
    }

    /// Sets how skinned mesh `id`'s character gathers and loses snow.
    pub(super) fn set_coat(&mut self, id: SkinnedId, settings: CoatSettings) -> Result<(), SnowError> {
        self.coats.set(id, settings)
    }

    /// The snow on skinned mesh `id`'s vertices (m a vertex), when there is such a mesh.
    pub(super) fn coat_buffer(&self, id: SkinnedId) -> Option<&wgpu::Buffer> {
        self.skinned.get(id.0).map(|s| &s.coat)
    }

    /// Forgets every mesh's last positions (the floating origin moved): the next frame sweeps no mesh.
    pub(super) fn forget_positions(&mut self) {
        self.history.clear();
    }

    /// The skinned meshes posed in the last encoded frame, in world space.
    pub(super) fn posed_meshes(&self) -> impl Iterator<Item = &SkinnedInstance> + '_ {
        self.posed.iter().filter_map(|&k| self.skinned.get(k))
    }
}
