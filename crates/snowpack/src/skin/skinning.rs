//! Skinning pass (`shaders/skinning.wgsl`): a skinned mesh posed by its joint
//! matrices and placed in the world, into a vertex buffer the capture and the
//! renderer draw from, and their normals for the snow coat
//! ([`super::coat`]). One [`SkinnedInstance`] per actor holds its buffers.

use glam::{Mat4, Vec3};

use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

/// Uniforms of the skinning pass (`SkinningParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SkinningParams {
    /// The actor's placement (column-major).
    pub model: [[f32; 4]; 4],
    /// Vertices to skin.
    pub vertex_count: u32,
    /// Joint matrices bound.
    pub joint_count: u32,
    /// Padding to 16 bytes.
    pub _pad: [u32; 2],
}

/// A mesh bound to a skin, in its bind pose: triangle list, up to four joints a vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkinnedMesh {
    /// Vertex positions (mesh space).
    pub positions: Vec<Vec3>,
    /// Joint indices (into the skin's joint list) per vertex.
    pub joints: Vec<[u16; 4]>,
    /// Weights per vertex (summing to 1).
    pub weights: Vec<[f32; 4]>,
    /// Triangle list indices.
    pub indices: Vec<u32>,
}

impl SkinnedMesh {
    /// Checks that the arrays agree, weights are finite and sum to about 1,
    /// and every index and joint is in range for `joint_count` joints (what
    /// [`crate::SnowDeformation::add_skinned_mesh`] refuses, checked before).
    pub fn validate(&self, joint_count: usize) -> Result<(), String> {
        let n = self.positions.len();
        if n == 0 {
            return Err("the mesh has no vertices".into());
        }
        if let Some(k) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(format!("vertex {k} is at {}, not a finite position", self.positions[k]));
        }
        if self.joints.len() != n || self.weights.len() != n {
            return Err(format!("{n} positions but {} joint and {} weight sets", self.joints.len(), self.weights.len()));
        }
        if !self.indices.len().is_multiple_of(3) {
            return Err(format!("{} triangle indices are not whole triples", self.indices.len()));
        }
        if let Some(i) = self.indices.iter().find(|&&i| i as usize >= n) {
            return Err(format!("triangle index {i} is past the {n} vertices"));
        }
        if let Some(j) = self.joints.iter().flatten().find(|&&j| usize::from(j) >= joint_count) {
            return Err(format!("a vertex names joint {j}, the skin has {joint_count}"));
        }
        if let Some((k, w)) =
            self.weights.iter().enumerate().find(|(_, w)| !w.iter().all(|x| x.is_finite() && *x >= 0.0) || (w.iter().sum::<f32>() - 1.0).abs() > 0.01)
        {
            return Err(format!("vertex {k} has weights {w:?}; they must be non-negative and sum to 1"));
        }
        Ok(())
    }
}

/// The pass: one pipeline for every skinned instance.
pub struct SkinningPass {
    /// The pipeline; each instance records through a sibling of its own
    /// (its uniform and buffers).
    pass: ComputePass<SkinningParams>,
}

/// One actor's skinning buffers: the bind pose, its joint matrices this frame
/// and the skinned world positions (`STORAGE | VERTEX`, 12 bytes a vertex),
/// with their normals and the snow the character carries.
pub struct SkinnedInstance {
    /// Skinned positions, world space, packed xyz.
    pub skinned: wgpu::Buffer,
    /// Skinned normals, world space, packed xyz (unit length).
    pub normals: wgpu::Buffer,
    /// Snow on each vertex (m, one f32 a vertex; `STORAGE | VERTEX`): the
    /// snow coat ([`super::coat`]), which a character's material blends in.
    pub coat: wgpu::Buffer,
    /// This frame's positions kept for the next frame's speeds (packed xyz).
    pub(crate) previous: wgpu::Buffer,
    /// Triangle list indices (u32).
    pub indices: wgpu::Buffer,
    /// Number of indices.
    pub index_count: u32,
    /// Number of vertices.
    pub vertex_count: u32,
    joints: wgpu::Buffer,
    joint_count: u32,
    /// The skinning pass with this instance's uniform and buffers bound.
    pass: ComputePass<SkinningParams>,
}

impl SkinningPass {
    /// Builds the pipeline.
    #[must_use]
    pub fn new(device: &wgpu::Device) -> Self {
        let shape = PassShape {
            label: "skinning",
            source: shaders::SKINNING,
            slots: &[Slot::Read, Slot::Read, Slot::Read, Slot::Read, Slot::ReadWrite, Slot::Read, Slot::ReadWrite],
            specialise_on: None,
            constants: &[],
            window: None,
        };
        Self { pass: ComputePass::new(device, &shape, None) }
    }

    /// Uploads `mesh` for a skin of `joint_count` joints.
    pub fn instance(&self, device: &wgpu::Device, queue: &wgpu::Queue, mesh: &SkinnedMesh, joint_count: usize) -> Result<SkinnedInstance, SnowError> {
        mesh.validate(joint_count).map_err(|why| SnowError::InvalidParameter { field: "skinned mesh", why })?;
        let storage = |label: &str, bytes: &[u8], extra: wgpu::BufferUsages| {
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (bytes.len() as u64).max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
                mapped_at_creation: false,
            });
            queue.write_buffer(&buffer, 0, bytes);
            buffer
        };
        let rest: Vec<[f32; 4]> = mesh.positions.iter().map(|p| p.extend(1.0).to_array()).collect();
        let ids: Vec<[u32; 4]> = mesh.joints.iter().map(|j| j.map(u32::from)).collect();
        let n = mesh.positions.len() as u64;
        let rest = storage("skin rest", bytemuck::cast_slice(&rest), wgpu::BufferUsages::empty());
        let ids = storage("skin joint ids", bytemuck::cast_slice(&ids), wgpu::BufferUsages::empty());
        let weights = storage("skin weights", bytemuck::cast_slice(&mesh.weights), wgpu::BufferUsages::empty());
        let joints = storage("skin joints", &vec![0u8; joint_count.max(1) * 64], wgpu::BufferUsages::empty());
        let indices = storage("skin indices", bytemuck::cast_slice(&mesh.indices), wgpu::BufferUsages::INDEX);
        let rest_normals: Vec<[f32; 4]> = mesh.vertex_normals().iter().map(|n| n.extend(0.0).to_array()).collect();
        let rest_normals = storage("skin rest normals", bytemuck::cast_slice(&rest_normals), wgpu::BufferUsages::empty());
        let output = |label: &str, size: u64, extra: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | extra,
                mapped_at_creation: false,
            })
        };
        let skinned = output("skinned positions", n * 12, wgpu::BufferUsages::VERTEX);
        let normals = output("skinned normals", n * 12, wgpu::BufferUsages::empty());
        // Zeroed at creation (wgpu's guarantee): a character starts clean.
        let coat = output("snow coat", n * 4, wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST);
        let previous = output("snow coat previous positions", n * 12, wgpu::BufferUsages::COPY_DST);
        let mut pass = self.pass.sibling(device);
        pass.bind(
            device,
            &[
                rest.as_entire_binding(),
                ids.as_entire_binding(),
                weights.as_entire_binding(),
                joints.as_entire_binding(),
                skinned.as_entire_binding(),
                rest_normals.as_entire_binding(),
                normals.as_entire_binding(),
            ],
        );
        Ok(SkinnedInstance {
            skinned,
            normals,
            coat,
            previous,
            indices,
            index_count: mesh.indices.len() as u32,
            vertex_count: n as u32,
            joints,
            joint_count: joint_count.max(1) as u32,
            pass,
        })
    }

    /// Records skinning of `instance` with `joints` (one matrix per skin joint) placed by `model`.
    /// (The instance records through its own sibling of this pass: `self`
    /// only says which pass the instance is of.)
    pub fn record(&self, cx: &mut FrameContext<'_>, instance: &SkinnedInstance, joints: &[Mat4], model: Mat4) {
        let count = joints.len().min(instance.joint_count as usize);
        let matrices: Vec<[[f32; 4]; 4]> = joints[..count].iter().map(Mat4::to_cols_array_2d).collect();
        cx.queue().write_buffer(&instance.joints, 0, bytemuck::cast_slice(&matrices));
        let params = SkinningParams { model: model.to_cols_array_2d(), vertex_count: instance.vertex_count, joint_count: count.max(1) as u32, _pad: [0; 2] };
        instance.pass.record(cx, None, &params, 0, (layout::groups(instance.vertex_count, 64), 1));
    }
}

/// What snowpack's own passes, tools and tests read of a [`SkinnedMesh`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`SkinnedMesh`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait SkinnedMeshExt: Sized {
    /// Bind-pose vertex normals: the area-weighted sum of the normals of the
    /// triangles around each vertex (either winding counts the same way as
    /// long as a mesh is consistent), straight up where a vertex has none.
    #[must_use]
    fn vertex_normals(&self) -> Vec<Vec3>;
}

impl SkinnedMeshExt for SkinnedMesh {
    fn vertex_normals(&self) -> Vec<Vec3> {
        let mut sum = vec![Vec3::ZERO; self.positions.len()];
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
            let (Some(&pa), Some(&pb), Some(&pc)) = (self.positions.get(a), self.positions.get(b), self.positions.get(c)) else { continue };
            // The cross product's length is twice the area: larger faces weigh more.
            let n = (pb - pa).cross(pc - pa);
            for k in [a, b, c] {
                sum[k] += n;
            }
        }
        sum.into_iter().map(|n| n.try_normalize().unwrap_or(Vec3::Y)).collect()
    }
}
