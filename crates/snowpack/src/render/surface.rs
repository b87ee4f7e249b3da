//! The renderer's unpacked surface (`surface_unpack.wgsl`): displayed height
//! and normal per texel, window-local, for the passes that march or draw the
//! height field (ambient occlusion, the terrain draw, the shell).
//!
//! The deformation keeps one packed `u32` per texel
//! ([`crate::deform::snow_word`]); this renderer-owned buffer (8 bytes a
//! texel) is the price of the demo renderer's height-field passes, not of the
//! deformation: a game drawing with [`crate::SnowGround`] or its own shader
//! samples the packed words and needs none of it.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use bytemuck::{Pod, Zeroable};

use crate::deform::resources::DeformResources;
use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

/// Uniforms of `surface_unpack.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct UnpackParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// `origin` wrapped into the storage ([`crate::deform::window::storage_origin`]).
    pub storage_origin: [u32; 2],
}

/// Unpacks the deformation's snow words into [`Self::surface`].
pub struct SurfaceUnpackPass {
    pass: ComputePass<UnpackParams>,
    resolution: u32,
    texel_m: f32,
    /// `(f32 height bits, pack2x16snorm(normal.x, normal.z))` per texel, window-local.
    pub surface: wgpu::Buffer,
}

impl SurfaceUnpackPass {
    /// Builds the pipeline and the output buffer for the window of `res`.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "surface unpack",
            source: shaders::SURFACE_UNPACK,
            slots: &[Slot::Read, Slot::Read, Slot::Uniform, Slot::ReadWrite],
            specialise_on: None,
            constants: &res.terrain_constants(),
            window: None,
        };
        let mut pass = ComputePass::new(device, &shape, None);
        let texels = u64::from(res.resolution) * u64::from(res.resolution);
        let surface = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("unpacked surface"),
            size: texels * 8,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        pass.bind(
            device,
            &[res.snow.as_entire_binding(), res.heightmap.as_entire_binding(), res.terrain_params.as_entire_binding(), surface.as_entire_binding()],
        );
        Self { pass, resolution: res.resolution, texel_m: res.texel_m, surface }
    }

    /// Records the unpack of the window at `origin` (global texel of local (0, 0)).
    pub fn record(&self, cx: &mut FrameContext<'_>, origin: [i32; 2]) {
        let storage_origin = crate::deform::window::storage_origin(origin, self.resolution);
        let p = UnpackParams { origin, resolution: self.resolution, texel_m: self.texel_m, storage_origin };
        let g = layout::groups(self.resolution, 16);
        self.pass.record(cx, None, &p, 0, (g, g));
    }

    /// Bytes of GPU memory held (the unpacked surface).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.surface.size()
    }
}

/// Unpacks one unpacked-surface texel into (height, unit normal).
#[must_use]
pub fn unpack_surface(texel: [u32; 2]) -> (f32, [f32; 3]) {
    let snorm = |bits: u32| (f32::from(bits as u16 as i16) / 32767.0).max(-1.0);
    let (nx, nz) = (snorm(texel[1] & 0xffff), snorm(texel[1] >> 16));
    let ny = (1.0 - nx * nx - nz * nz).max(0.0).sqrt();
    (f32::from_bits(texel[0]), [nx, ny, nz])
}
