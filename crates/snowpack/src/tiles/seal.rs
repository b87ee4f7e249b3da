//! Tile seal pass: the snow plane of slots about to be copied out becomes
//! height XOR rest height, the form the store keeps (`tile_seal.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
use crate::shaders;

use crate::deform::resources::DeformResources;

/// Uniforms of `tile_seal.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SealParams {
    /// Tile side (texels).
    pub side: u32,
    /// Planes per resident slot ([`super::planes::planes`]).
    pub planes: u32,
    /// [`SealParams::USE_FALLEN`].
    pub flags: u32,
    /// Entries listed (set by [`TileSealPass::record`]).
    pub count: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// Padding.
    pub _pad: [u32; 2],
}

impl SealParams {
    /// The world has snowfall (the rest height includes each texel's).
    pub const USE_FALLEN: u32 = 2;
}

/// Seals the snow plane of listed slots, `[col, row, slot, 0]` each.
pub struct TileSealPass {
    /// One pipeline per set of flags in use.
    pass: ComputePass<SealParams>,
    entries: wgpu::Buffer,
}

impl TileSealPass {
    /// Builds the pipeline over the terrain description in `res` and the resident `tiles`.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, tiles: &wgpu::Buffer) -> Self {
        let shape = PassShape {
            label: "tile seal",
            source: shaders::TILE_SEAL,
            slots: &[Slot::Read, Slot::ReadWrite],
            specialise_on: Some("PASS_FLAGS"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Read),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        let entries = super::input_buffer(device, "tile seal entries", 64 * 16);
        pass.bind(device, &[entries.as_entire_binding(), tiles.as_entire_binding()]);
        Self { pass, entries }
    }

    /// Records the seal of `entries` (`[col, row, slot, 0]`); grows its entry
    /// buffer as needed; nothing when empty. One record per submission (its
    /// uniforms and entries are written through the queue).
    pub fn record(&mut self, cx: &mut FrameContext<'_>, (res, tiles): (&DeformResources, &wgpu::Buffer), mut params: SealParams, entries: &[[i32; 4]]) {
        let (device, queue) = (cx.device(), cx.queue());
        if entries.is_empty() {
            return;
        }
        let bytes = std::mem::size_of_val(entries) as u64;
        if bytes > self.entries.size() {
            self.entries = super::input_buffer(device, "tile seal entries", bytes.next_power_of_two());
            self.pass.bind(device, &[self.entries.as_entire_binding(), tiles.as_entire_binding()]);
        }
        params.count = entries.len() as u32;
        queue.write_buffer(&self.entries, 0, bytemuck::cast_slice(entries));
        let groups = layout::groups(params.side * params.side, 256);
        self.pass.record(cx, Some(&res.bindings), &params, params.flags, (groups, params.count));
    }

    /// Bytes of GPU memory held (its entry list).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.entries.size()
    }
}
