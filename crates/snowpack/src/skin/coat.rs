//! Snow coat pass (`shaders/snow_coat.wgsl`, CPU twin `cpu::snow_coat`): the
//! snow a skinned character carries, one f32 a vertex beside its skinned
//! positions ([`super::skinning::SkinnedInstance::coat`]). Wading through
//! snow cakes the legs, snowfall whitens what faces the sky, and the coat
//! melts and shakes off where the body moves fast. A character's material
//! reads the buffer as a per-vertex attribute (`docs/rendering.md`, "Snow on
//! characters").

use bytemuck::{Pod, Zeroable};

use crate::error::SnowError;
use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::height_depth::SkyTest;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::{WindowAccess, WindowBindings};
use crate::shaders;

use super::skinning::SkinnedInstance;

/// How a character gathers and loses snow (per skinned mesh; the scene's
/// `[[actor]]` keys `coat_*`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoatSettings {
    /// Snow gained wading, per second and per metre the vertex is below the
    /// snow around it (1/s).
    pub cling_per_s: f32,
    /// Most snow a vertex carries (m).
    pub cap_m: f32,
    /// Melt (m/s).
    pub melt_m_per_s: f32,
    /// Speed above which a vertex shakes its snow off (m/s).
    pub shake_speed_m_per_s: f32,
    /// Rate at which a fast vertex loses its snow (1/s: `1 - exp(-rate dt)` a frame).
    pub shake_per_s: f32,
    /// Radius around a vertex in which the snow it wades through is read (m):
    /// wider than a leg, so the trail under it does not hide the snow around.
    pub wade_radius_m: f32,
}

impl Default for CoatSettings {
    fn default() -> Self {
        Self { cling_per_s: 2.0, cap_m: 0.03, melt_m_per_s: 0.000_2, shake_speed_m_per_s: 4.0, shake_per_s: 1.5, wade_radius_m: 0.25 }
    }
}

impl CoatSettings {}

/// Uniforms of the snow coat pass (`SnowCoatParams` in WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SnowCoatParams {
    /// Global texel of the window's local (0, 0).
    pub origin: [i32; 2],
    /// Window resolution.
    pub resolution: u32,
    /// Vertices of the mesh.
    pub vertex_count: u32,
    /// World x, z of the window's corner (m).
    pub corner_m: [f32; 2],
    /// Texel side (m).
    pub texel_m: f32,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// Frame time (s).
    pub dt_s: f32,
    /// This frame's snowfall on open ground (m).
    pub fall_m: f32,
    /// [`CoatSettings::cling_per_s`].
    pub cling_per_s: f32,
    /// [`CoatSettings::cap_m`].
    pub cap_m: f32,
    /// [`CoatSettings::melt_m_per_s`].
    pub melt_m_per_s: f32,
    /// [`CoatSettings::shake_speed_m_per_s`].
    pub shake_speed_m_per_s: f32,
    /// [`CoatSettings::shake_per_s`].
    pub shake_per_s: f32,
    /// [`CoatSettings::wade_radius_m`].
    pub wade_radius_m: f32,
    /// 1 when fallen snow raises the rest surface.
    pub use_fallen: u32,
    /// 1 when the objects' occlusion map is bound.
    pub use_sky: u32,
    /// 1 when `previous` holds last frame's positions.
    pub has_previous: u32,
    /// A vertex that moved farther in one frame jumped (no shaking).
    pub teleport_m: f32,
    /// The sky test against the objects' occlusion depth (with `use_sky`).
    pub sky: SkyTest,
    /// `origin` wrapped into the storage (`storage_origin`, with the
    /// window's bindings): [`SnowCoatPass::record`] writes it from `origin`
    /// and `resolution`, so the value given here is not used.
    pub storage_origin: [u32; 2],
}

impl SnowCoatParams {
    /// The inputs a coat pipeline is built for (`COAT_INPUTS` in
    /// `snow_coat.wgsl`): `use_fallen | use_sky << 1`.
    #[must_use]
    pub fn inputs(&self) -> u32 {
        u32::from(self.use_fallen != 0) | (u32::from(self.use_sky != 0) << 1)
    }

    /// The settings' part of the uniforms.
    #[must_use]
    pub fn with_settings(mut self, s: &CoatSettings) -> Self {
        self.cling_per_s = s.cling_per_s;
        self.cap_m = s.cap_m;
        self.melt_m_per_s = s.melt_m_per_s;
        self.shake_speed_m_per_s = s.shake_speed_m_per_s;
        self.shake_per_s = s.shake_per_s;
        self.wade_radius_m = s.wade_radius_m;
        self
    }
}

/// What the coat reads of the ground: the window's bindings (heights, snow
/// words, fallen snow, the terrain) and the occlusion map.
#[derive(Clone, Copy)]
pub struct CoatGround<'a> {
    /// The window's buffers (`DeformResources::bindings`).
    pub window: &'a WindowBindings,
    /// Occlusion depth (a 1x1 stand-in when no objects are set).
    pub sky: &'a wgpu::TextureView,
}

/// The pass: one pipeline for every character.
pub struct SnowCoatPass {
    /// One pipeline per set of inputs in use ([`SnowCoatParams::inputs`]),
    /// and the first character's uniform.
    pass: ComputePass<SnowCoatParams>,
    /// The other characters' uniforms (every dispatch of a frame reads its own).
    more: Vec<ComputePass<SnowCoatParams>>,
}

impl SnowCoatPass {
    /// Builds the pipeline for the window `window`, whose terrain kind
    /// `terrain_constants` names.
    #[must_use]
    pub fn new(device: &wgpu::Device, window: &WindowBindings, terrain_constants: &[(&'static str, f64)]) -> Self {
        let shape = PassShape {
            label: "snow coat",
            source: shaders::SNOW_COAT,
            slots: &[Slot::Read, Slot::Read, Slot::Read, Slot::ReadWrite, Slot::Depth],
            specialise_on: Some("COAT_INPUTS"),
            constants: terrain_constants,
            window: Some(WindowAccess::Read),
        };
        Self { pass: ComputePass::new(device, &shape, Some(window)), more: Vec::new() }
    }

    /// Makes sure `characters` characters can be recorded in one frame: one
    /// uniform buffer each, kept (every dispatch of a frame reads its own).
    pub fn reserve(&mut self, device: &wgpu::Device, characters: usize) {
        while self.more.len() + 1 < characters {
            self.more.push(self.pass.sibling(device));
        }
    }

    /// Records the coat update of the `k`-th character of this frame (its
    /// skinning already recorded; [`Self::reserve`]d for), then keeps its
    /// positions for the next frame's speeds. Nothing for a `k` not reserved.
    pub fn record(&self, cx: &mut FrameContext<'_>, k: usize, instance: &SkinnedInstance, ground: CoatGround<'_>, params: &SnowCoatParams) {
        let Some(pass) = k.checked_sub(1).map_or(Some(&self.pass), |m| self.more.get(m)) else { return };
        let group = pass.make_group(
            cx.device(),
            &[
                instance.skinned.as_entire_binding(),
                instance.previous.as_entire_binding(),
                instance.normals.as_entire_binding(),
                instance.coat.as_entire_binding(),
                wgpu::BindingResource::TextureView(ground.sky),
            ],
        );
        let storage_origin = crate::pass::window_bindings::storage_origin(params.origin, params.resolution);
        let params = SnowCoatParams { vertex_count: instance.vertex_count, storage_origin, ..*params };
        pass.record_with(cx, &group, Some(ground.window), &params, params.inputs(), (layout::groups(instance.vertex_count, 64), 1));
        let encoder = &mut *cx.encoder;
        encoder.copy_buffer_to_buffer(&instance.skinned, 0, &instance.previous, 0, u64::from(instance.vertex_count) * 12);
    }
}

/// What snowpack's own app, tools and tests do with [`CoatSettings`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`CoatSettings`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait CoatSettingsExt: Sized {
    /// Checks every value; the error names the field.
    fn validate(&self) -> Result<(), SnowError>;
}

impl CoatSettingsExt for CoatSettings {
    fn validate(&self) -> Result<(), SnowError> {
        let fields = [
            ("coat_cling_per_s", self.cling_per_s),
            ("coat_cap_m", self.cap_m),
            ("coat_melt_m_per_s", self.melt_m_per_s),
            ("coat_shake_speed_m_per_s", self.shake_speed_m_per_s),
            ("coat_shake_per_s", self.shake_per_s),
            ("coat_wade_radius_m", self.wade_radius_m),
        ];
        match fields.into_iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
            Some((field, v)) => Err(SnowError::InvalidParameter { field, why: format!("{v} must be zero or positive") }),
            None => Ok(()),
        }
    }
}
