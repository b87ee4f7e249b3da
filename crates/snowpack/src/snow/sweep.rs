//! Last frame's vertex positions of the meshes that press the snow (skinned
//! characters and caller meshes), so the capture can sweep each over its
//! motion (see [`crate::deform::sweep`]): after a frame's capture is
//! recorded, each mesh's positions are copied into a buffer of its own.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use crate::deform::sweep::{JointReach, skinned_travel, steps_for};

/// A copy of one mesh's vertex positions from the frame before.
struct Previous {
    buffer: wgpu::Buffer,
    /// Bytes of positions copied (12 a vertex).
    bytes: u64,
    /// Recorded in the last encoded frame (a mesh skipped for a frame is not swept).
    fresh: bool,
}

/// Previous positions of skinned meshes (by [`super::SkinnedId`]) and of
/// caller meshes (by index in the frame's meshes, `SnowFrame::with_meshes`).
#[derive(Default)]
pub struct MeshHistory {
    skinned: Vec<Option<Previous>>,
    /// Per skinned mesh: its joints' world matrices last frame and the
    /// bind positions each joint moves, for the motion bound.
    joints: Vec<(Vec<glam::Mat4>, Vec<JointReach>)>,
    caller: Vec<Option<Previous>>,
}

/// Which mesh a previous copy belongs to.
#[derive(Clone, Copy, Debug)]
pub enum MeshKey {
    /// A registered skinned mesh (its index).
    Skinned(usize),
    /// The k-th caller mesh of the frame.
    Caller(usize),
}

impl MeshHistory {
    /// Records what each joint of skinned mesh `k` moves (its bind positions).
    pub fn register_skinned(&mut self, k: usize, reach: Vec<JointReach>) {
        if self.joints.len() <= k {
            self.joints.resize_with(k + 1, || (Vec::new(), Vec::new()));
            self.skinned.resize_with(k + 1, || None);
        }
        self.joints[k] = (Vec::new(), reach);
    }

    fn slot(&mut self, key: MeshKey) -> &mut Option<Previous> {
        let (list, k) = match key {
            MeshKey::Skinned(k) => (&mut self.skinned, k),
            MeshKey::Caller(k) => (&mut self.caller, k),
        };
        if list.len() <= k {
            list.resize_with(k + 1, || None);
        }
        &mut list[k]
    }

    /// The previous positions of `key` when they are from the last frame and
    /// of `bytes` bytes (the same vertices).
    #[must_use]
    pub fn previous(&self, key: MeshKey, bytes: u64) -> Option<&wgpu::Buffer> {
        let slot = match key {
            MeshKey::Skinned(k) => self.skinned.get(k),
            MeshKey::Caller(k) => self.caller.get(k),
        }?;
        slot.as_ref().filter(|p| p.fresh && p.bytes == bytes).map(|p| &p.buffer)
    }

    /// Sub-steps of skinned mesh `k` posed with world joint matrices `world`
    /// (model x joint), or 0 (first pose, a teleport, sweeping off); keeps
    /// `world` for the next frame.
    pub fn skinned_steps(&mut self, k: usize, world: Vec<glam::Mat4>, texel_m: f32, teleport_m: f32) -> u32 {
        let Some((last, reach)) = self.joints.get_mut(k) else { return 0 };
        let steps = if last.len() == world.len() && !last.is_empty() {
            let travel = skinned_travel(last, &world, reach);
            if teleport_m > 0.0 && travel <= teleport_m { steps_for(travel, texel_m) } else { 0 }
        } else {
            0
        };
        *last = world;
        steps
    }

    /// Marks every copy stale: call once a frame's capture is recorded, then
    /// [`Self::remember`] the meshes of that frame (fresh again); a mesh
    /// missing from a frame is not swept in the next.
    pub fn age(&mut self) {
        for p in self.skinned.iter_mut().chain(&mut self.caller).flatten() {
            p.fresh = false;
        }
    }

    /// Forgets every pose: the next frame sweeps no mesh (the floating origin moved).
    pub fn clear(&mut self) {
        self.age();
        for (joints, _) in &mut self.joints {
            joints.clear();
        }
    }

    /// Copies `bytes` bytes of `vertices` (this frame's positions of `key`)
    /// into its previous buffer, after this frame's capture in `encoder`.
    /// A buffer without `COPY_SRC` usage is not copied (that mesh is never swept).
    pub fn remember(&mut self, device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, key: MeshKey, vertices: &wgpu::Buffer, bytes: u64) {
        if !vertices.usage().contains(wgpu::BufferUsages::COPY_SRC) || bytes == 0 || bytes > vertices.size() {
            return;
        }
        let slot = self.slot(key);
        if slot.as_ref().is_none_or(|p| p.bytes != bytes) {
            *slot = Some(Previous {
                buffer: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("previous mesh positions"),
                    size: bytes,
                    usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
                bytes,
                fresh: false,
            });
        }
        if let Some(p) = slot {
            encoder.copy_buffer_to_buffer(vertices, 0, &p.buffer, 0, bytes);
            p.fresh = true;
        }
    }
}
