//! Tile weather pass: refill and snowfall on the resident tiles outside the
//! window (`tile_weather.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
use crate::shaders;

use crate::deform::resources::DeformResources;

/// Uniforms of `tile_weather.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct WeatherParams {
    /// The window's origin `[column, row]`; texels inside it are the update's.
    pub origin: [i32; 2],
    /// Window texels per side.
    pub resolution: u32,
    /// Tile side (texels).
    pub side: u32,
    /// Texel size (m): where a slot texel's ground is evaluated.
    pub texel_m: f32,
    /// [`WeatherParams::USE_FALLEN`].
    pub flags: u32,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// This frame's refill (m).
    pub refill_m: f32,
    /// This frame's snowfall on open ground (m).
    pub fall_m: f32,
    /// Most snowfall a texel keeps (m).
    pub max_fallen_m: f32,
    /// This frame's footprint refill (stamp quanta).
    pub quanta: u32,
    /// Footprint quantisation: lowest height (m).
    pub low_m: f32,
    /// Footprint quantisation: highest height (m).
    pub high_m: f32,
    /// Slots listed for the pass (set by [`TileWeatherPass::record`]).
    pub count: u32,
    /// Planes per resident slot ([`super::planes::planes`]).
    pub planes: u32,
    /// Padding.
    pub _pad: u32,
}

impl WeatherParams {
    /// The world has snowfall.
    pub const USE_FALLEN: u32 = 2;
    /// The slots have a footprint plane: set by [`TileWeatherPass::record`]
    /// from `planes`, so that the shader's choice is a flag.
    pub const STAMP_PLANE: u32 = 4;

    /// Whether this frame changes anything outside the window.
    #[must_use]
    pub fn passes_time(&self) -> bool {
        self.refill_m > 0.0 || self.fall_m > 0.0 || self.quanta > 0
    }
}

/// Lets time pass on resident tiles the window does not cover.
pub struct TileWeatherPass {
    /// One pipeline per set of flags in use.
    pass: ComputePass<WeatherParams>,
    slots: wgpu::Buffer,
}

impl TileWeatherPass {
    /// Builds the pipeline over the slot `owners`, the resident `tiles` and
    /// the terrain description in `res` (the ground under each texel).
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, owners: &wgpu::Buffer, tiles: &wgpu::Buffer) -> Self {
        let shape = PassShape {
            label: "tile weather",
            source: shaders::TILE_WEATHER,
            slots: &[Slot::Read, Slot::ReadWrite, Slot::Read],
            specialise_on: Some("PASS_FLAGS"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Read),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        // One entry per slot at most (the owners buffer holds 16 bytes per slot).
        let slots = super::input_buffer(device, "tile weather slots", owners.size() / 4);
        pass.bind(device, &[owners.as_entire_binding(), tiles.as_entire_binding(), slots.as_entire_binding()]);
        Self { pass, slots }
    }

    /// Records this frame's weather on the listed `slots` (nothing when it
    /// passes no time or lists none).
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, params: &WeatherParams, slots: &[u32]) {
        if !params.passes_time() || slots.is_empty() {
            return;
        }
        let flags = super::planes::with_stamp_plane_flag(params.flags, params.planes, (WeatherParams::USE_FALLEN, WeatherParams::STAMP_PLANE));
        let params = WeatherParams { count: slots.len() as u32, flags, ..*params };
        cx.queue().write_buffer(&self.slots, 0, bytemuck::cast_slice(slots));
        let groups = layout::groups(params.side * params.side, 256);
        self.pass.record(cx, Some(&res.bindings), &params, params.flags, (groups, params.count));
    }

    /// Bytes of GPU memory held (its slot list).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.slots.size()
    }
}
