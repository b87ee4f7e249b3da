//! Update pass: the persistent snow height with linear refill, lowered by the
//! captured actors and the stamped footprints (`update.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::gpu::specialised::SpecialisedPipeline;
use crate::height_depth::{SkyTest, sky_depth_texture};
use crate::shaders;

use super::resources::DeformResources;

/// Uniforms of `update.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct UpdateParams {
    /// Global texel index of local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Texels per side.
    pub resolution: u32,
    /// Rest depth of snow (m).
    pub depth_m: f32,
    /// Refill this frame in snow quanta ([`super::snow_word::SNOW_QUANTUM_M`]):
    /// what the cumulative refill counter (a function of world time) gained
    /// this frame.
    pub snow_refill_quanta: u32,
    /// Capture depth 0 height (m).
    pub low_m: f32,
    /// Capture depth 1 height (m).
    pub high_m: f32,
    /// [`UpdateParams::USE_CAPTURE`] | [`UpdateParams::USE_STAMPS`].
    pub flags: u32,
    /// Footprint refill this frame, in whole stamp quanta.
    pub refill_quanta: u32,
    /// Snowfall this frame on open ground (m).
    pub fall_m: f32,
    /// Most snowfall a texel keeps above its rest depth (m).
    pub max_fallen_m: f32,
    /// Texel size (m), the occlusion map's too.
    pub texel_m: f32,
    /// The sky test against the objects' occlusion depth (with [`Self::USE_SKY`]).
    pub sky: SkyTest,
    /// `origin` wrapped into the storage ([`super::window::storage_origin`]):
    /// [`UpdatePass::record`] writes it from `origin` and `resolution`, so
    /// the value given here is not used.
    pub storage_origin: [u32; 2],
    /// Tile side of the changed-tile flags (texels; with [`Self::SHARE`]).
    pub share_side: u32,
    /// Slots per side of the flags ([`crate::replicate::flags::ShareGrid`]).
    pub share_keys: u32,
}

impl UpdateParams {
    /// Apply the captured actors.
    pub const USE_CAPTURE: u32 = 1;
    /// Apply the stamped footprints.
    pub const USE_STAMPS: u32 = 2;
    /// Read and grow the `fallen` buffer (it snows, or has snowed).
    pub const USE_FALLEN: u32 = 4;
    /// Test each texel against the occlusion depth (objects hide the sky).
    pub const USE_SKY: u32 = 8;
    /// `flags`: the window has a footprint buffer (refill it; apply it with
    /// [`Self::USE_STAMPS`]). Without it `stamps` is a 4-byte stand-in, never read.
    pub const HAS_STAMPS: u32 = 16;
    /// Shared snow: flag the tile of every texel whose deficit a press
    /// raised (`res.share_flags`, [`crate::replicate::flags`]).
    pub const SHARE: u32 = 32;
    /// Footprints refill this frame (`refill_quanta > 0`): set by
    /// [`UpdatePass::record`] so that no branch of the shader tests a
    /// uniform alone (Mesa 22's lavapipe compiles such a shader again at
    /// every dispatch and keeps every copy).
    pub const REFILLS: u32 = 64;
}

/// Applies refill, snowfall and the captured actors to the persistent snow.
pub struct UpdatePass {
    /// One pipeline per set of [`UpdateParams::flags`] in use.
    pipelines: SpecialisedPipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    /// The uniforms last written, so an unchanged frame writes none.
    written: std::cell::Cell<Option<UpdateParams>>,
    bind_group: wgpu::BindGroup,
    /// A 1x1 occlusion depth for frames without objects (never read: `USE_SKY` is off).
    no_sky: wgpu::TextureView,
}

impl UpdatePass {
    /// Compiles the shader and binds it to `res` (without an occlusion
    /// depth); the pipeline for a set of flags is built on its first frame.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let (pipelines, layout) = SpecialisedPipeline::new(
            device,
            "update",
            shaders::UPDATE,
            &[
                layout::uniform(0, wgpu::ShaderStages::COMPUTE),
                layout::depth_texture(1),
                layout::storage(2, true),
                layout::storage(3, false),
                layout::storage(4, false),
                layout::depth_texture(5),
                layout::storage(6, false),
                layout::uniform(7, wgpu::ShaderStages::COMPUTE),
                layout::storage(8, false),
            ],
            "UPDATE_FLAGS",
            &res.terrain_constants(),
        );
        let params = layout::uniform_buffer::<UpdateParams>(device, "update params");
        let no_sky = sky_depth_texture(device, 1).create_view(&wgpu::TextureViewDescriptor::default());
        let bind_group = Self::group(device, &layout, &params, res, &no_sky);
        Self { pipelines, layout, params, written: std::cell::Cell::new(None), bind_group, no_sky }
    }

    fn group(device: &wgpu::Device, bgl: &wgpu::BindGroupLayout, params: &wgpu::Buffer, res: &DeformResources, sky: &wgpu::TextureView) -> wgpu::BindGroup {
        layout::bind_group(
            device,
            "update",
            bgl,
            &[
                params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&res.capture_view),
                res.heightmap.as_entire_binding(),
                res.snow.as_entire_binding(),
                res.stamps.as_entire_binding(),
                wgpu::BindingResource::TextureView(sky),
                res.fallen.as_entire_binding(),
                res.terrain_params.as_entire_binding(),
                res.share_flags.as_entire_binding(),
            ],
        )
    }

    /// Binds the occlusion depth `sky` (of the window's resolution) for
    /// `USE_SKY`, or none again.
    pub fn bind_sky(&mut self, device: &wgpu::Device, res: &DeformResources, sky: Option<&wgpu::TextureView>) {
        self.bind_group = Self::group(device, &self.layout, &self.params, res, sky.unwrap_or(&self.no_sky));
    }

    /// Records the update for this frame.
    pub fn record(&self, cx: &mut FrameContext<'_>, params: &UpdateParams) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        let refills = if params.refill_quanta > 0 { UpdateParams::REFILLS } else { 0 };
        let params = &UpdateParams {
            storage_origin: super::window::storage_origin(params.origin, params.resolution),
            flags: (params.flags & !UpdateParams::REFILLS) | refills,
            ..*params
        };
        if self.written.get() != Some(*params) {
            queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
            self.written.set(Some(*params));
        }
        let g = layout::groups(params.resolution, 16);
        layout::dispatch(encoder, timer, "update", &self.pipelines.get(params.flags), &self.bind_group, (g, g));
    }
}
