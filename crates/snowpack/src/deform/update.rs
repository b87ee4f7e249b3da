//! Update pass: the persistent snow height with linear refill, lowered by the
//! captured actors and the stamped footprints, and the packed snow their
//! presses squeeze into the column below (`update.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::height_depth::{SkyTest, sky_depth_texture};
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::shaders;

use super::resources::DeformResources;
use crate::pass::window_bindings::WindowAccess;

/// Uniforms of `update.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
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
    /// `origin` wrapped into the storage (`super::window::storage_origin`):
    /// [`UpdatePass::record`] writes it from `origin` and `resolution`, so
    /// the value given here is not used.
    pub storage_origin: [u32; 2],
    /// Tile side of the changed-tile flags (texels; with [`Self::SHARE`]).
    pub share_side: u32,
    /// Slots per side of the flags ([`crate::replicate::flags::ShareGrid`]).
    pub share_keys: u32,
    /// `ρmax / ρ0 − 1` ([`snowpack_share::mechanics::SnowMechanics::pack_ratio`]):
    /// packed snow a column holds per quantum of its height. 0 packs
    /// nothing (every press displaces what it takes).
    pub pack_ratio: f32,
    /// `(high_m − low_m) × 8 / texel_m`: a step of capture depth in eighths
    /// of a texel's rise (with [`Self::DISPLACE`], the way out of a press).
    pub displace_k: f32,
    /// Snowfall so far on open ground, this frame's included (m): lying
    /// snow beyond it is a berm ([`Self::CONSUME`]).
    pub open_fallen_m: f32,
    /// Padding: the pushers start on a 16-byte boundary.
    pub _pad: u32,
    /// The boxes that push snow this frame, which way (`super::push`;
    /// with [`Self::DISPLACE`]).
    pub pushers: [super::push::Pusher; super::push::MOST_PUSHERS],
}

impl Default for UpdateParams {
    fn default() -> Self {
        Self { pushers: [super::push::NO_PUSHER; super::push::MOST_PUSHERS], ..Zeroable::zeroed() }
    }
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
    /// raised (`res.share_flags`, `crate::replicate::flags`).
    pub const SHARE: u32 = 32;
    /// Footprints refill this frame (`refill_quanta > 0`): set by
    /// [`UpdatePass::record`] so that no branch of the shader tests a
    /// uniform alone (Mesa 22's lavapipe compiles such a shader again at
    /// every dispatch and keeps every copy).
    pub const REFILLS: u32 = 64;
    /// Snow beyond the final density where the actors press moves aside:
    /// the move goes into the upper half of the snow word for the displace
    /// pass (`super::displace`). Needs [`Self::USE_CAPTURE`].
    pub const DISPLACE: u32 = 128;
    /// With [`Self::DISPLACE`] and not sharing: a press on a berm lowers
    /// its lying snow and the deficit together (the surface and the mass
    /// stay), so neither grows without bound while snow streams through a
    /// texel. Off while sharing: copies merge by the larger of each.
    pub const CONSUME: u32 = 256;
    /// Count what snowfall and refill add in the mass ledger
    /// (`shared/mass_ledger.wgsl`).
    pub const LEDGER: u32 = 512;
    /// With [`Self::USE_CAPTURE`]: the analytic shapes were ray cast by
    /// compute this frame (`res.capture_shapes`);
    /// [`super::capture::CapturePass::update_flags`] says.
    pub const CAPTURE_SHAPES: u32 = 1024;
    /// With [`Self::USE_CAPTURE`]: the capture depth target was drawn this
    /// frame (meshes, or shapes drawn);
    /// [`super::capture::CapturePass::update_flags`] says.
    pub const CAPTURE_DRAWN: u32 = 2048;
}

/// Applies refill, snowfall and the captured actors to the persistent snow.
pub struct UpdatePass {
    /// One pipeline per set of [`UpdateParams::flags`] in use.
    pass: ComputePass<UpdateParams>,
    /// A 1x1 occlusion depth for frames without objects (never read: `USE_SKY` is off).
    no_sky: wgpu::TextureView,
    /// The occlusion depth bound, kept to bind again ([`Self::rebind`]).
    sky: Option<wgpu::TextureView>,
}

impl UpdatePass {
    /// Compiles the shader and binds it to `res` (without an occlusion
    /// depth); the pipeline for a set of flags is built on its first frame.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources) -> Self {
        let shape = PassShape {
            label: "update",
            source: shaders::UPDATE,
            // capture depth target, sky, changed-tile flags, packed snow (with the displaced count), shapes' capture by compute
            slots: &[Slot::Depth, Slot::Depth, Slot::ReadWrite, Slot::ReadWrite, Slot::Read],
            specialise_on: Some("UPDATE_FLAGS"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Write),
        };
        let no_sky = sky_depth_texture(device, 1).create_view(&wgpu::TextureViewDescriptor::default());
        let mut update = Self { pass: ComputePass::new(device, &shape, Some(&res.bindings)), no_sky, sky: None };
        update.bind_sky(device, res, None);
        update
    }

    /// Binds the occlusion depth `sky` (of the window's resolution) for
    /// `USE_SKY`, or none again, and the window's changed-tile flags (again
    /// after they were allocated).
    pub fn bind_sky(&mut self, device: &wgpu::Device, res: &DeformResources, sky: Option<&wgpu::TextureView>) {
        self.sky = sky.cloned();
        let sky = sky.unwrap_or(&self.no_sky);
        self.pass.bind(
            device,
            &[
                wgpu::BindingResource::TextureView(&res.capture_view),
                wgpu::BindingResource::TextureView(sky),
                res.share_flags.as_entire_binding(),
                res.packed.as_entire_binding(),
                res.capture_shapes.as_entire_binding(),
            ],
        );
    }

    /// Binds `res` again with the occlusion depth bound before (after
    /// `res` replaced a resource the update reads: the capture depth
    /// target, [`DeformResources::allocate_capture`]).
    pub fn rebind(&mut self, device: &wgpu::Device, res: &DeformResources) {
        let sky = self.sky.clone();
        self.bind_sky(device, res, sky.as_ref());
    }

    /// Records the update for this frame.
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, params: &UpdateParams) {
        let refills = if params.refill_quanta > 0 { UpdateParams::REFILLS } else { 0 };
        let params = &UpdateParams {
            storage_origin: super::window::storage_origin(params.origin, params.resolution),
            flags: (params.flags & !UpdateParams::REFILLS) | refills,
            ..*params
        };
        let g = layout::groups(params.resolution, 16);
        self.pass.record(cx, Some(&res.bindings), params, params.flags, (g, g));
    }
}
