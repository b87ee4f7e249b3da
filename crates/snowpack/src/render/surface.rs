//! The renderer's unpacked surface (`surface_unpack.wgsl`): displayed height
//! and normal per texel, window-local, for the passes that march or draw the
//! height field (ambient occlusion, the terrain draw, the shell), and the
//! packed snow the surface shows, for the terrain draw's compacted look.
//!
//! The deformation keeps one packed `u32` per texel
//! ([`crate::deform::snow_word`]); these renderer-owned buffers (16 bytes a
//! texel) are the price of the demo renderer's height-field passes, not of the
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
    /// `ρmax / ρ0 − 1`: the most packed snow a metre of column holds
    /// ([`crate::mechanics::SnowMechanics::pack_ratio`]).
    pub pack_ratio: f32,
    /// Rest depth (m): the snow words are deficits below terrain + depth + lying snow.
    pub depth_m: f32,
    /// 1 where the window keeps lying snow (`fallen` is bound), else 0.
    pub use_fallen: u32,
    /// Padding to 8 bytes.
    pub _pad: u32,
}

/// Unpacks the deformation's snow words into [`Self::surface`].
pub struct SurfaceUnpackPass {
    pass: ComputePass<UnpackParams>,
    resolution: u32,
    texel_m: f32,
    /// `(f32 height bits, pack2x16snorm(normal.x, normal.z))` per texel, window-local.
    pub surface: wgpu::Buffer,
    /// What the surface shows of the packed snow per texel, window-local
    /// (`surface_packing`: the packed snow in m and the density as a
    /// fraction from fresh to final, 2 × f32): the terrain draw's compacted
    /// look follows it.
    pub packing: wgpu::Buffer,
}

impl SurfaceUnpackPass {
    /// Builds the pipeline and the output buffer for the window of `res`.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "surface unpack",
            source: shaders::SURFACE_UNPACK,
            // snow words, heightmap, terrain, surface, packed snow, packing, lying snow
            slots: &[Slot::Read, Slot::Read, Slot::Uniform, Slot::ReadWrite, Slot::Read, Slot::ReadWrite, Slot::Read],
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
        let packing = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("surface packing"),
            size: texels * 8,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        pass.bind(
            device,
            &[
                res.snow.as_entire_binding(),
                res.heightmap.as_entire_binding(),
                res.terrain_params.as_entire_binding(),
                surface.as_entire_binding(),
                res.packed.as_entire_binding(),
                packing.as_entire_binding(),
                res.fallen.as_entire_binding(),
            ],
        );
        Self { pass, resolution: res.resolution, texel_m: res.texel_m, surface, packing }
    }

    /// Records the unpack of the window at `origin` (global texel of local
    /// (0, 0)) of snow `params`.
    pub fn record(&self, cx: &mut FrameContext<'_>, origin: [i32; 2], params: &crate::SnowParams) {
        let storage_origin = crate::deform::window::storage_origin(origin, self.resolution);
        let p = UnpackParams {
            origin,
            resolution: self.resolution,
            texel_m: self.texel_m,
            storage_origin,
            pack_ratio: params.mechanics().pack_ratio(),
            depth_m: params.depth_m,
            use_fallen: u32::from(params.keeps_lying_snow()),
            _pad: 0,
        };
        let g = layout::groups(self.resolution, 16);
        self.pass.record(cx, None, &p, 0, (g, g));
    }

    /// Bytes of GPU memory held (the unpacked surface and its packing).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.surface.size() + self.packing.size()
    }
}

