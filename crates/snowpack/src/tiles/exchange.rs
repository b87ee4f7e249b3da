//! Exchange pass: texels between the sliding window and the resident tiles
//! (`exchange.wgsl`), used when a tile store is attached.

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::gpu::specialised::SpecialisedPipeline;
use crate::shaders;

use crate::deform::resources::DeformResources;
use crate::deform::window::{TexelRect, rect_dispatch};

/// Uniforms of `exchange.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ExchangeParams {
    /// The window's origin after the move: `[column, row]`.
    pub origin: [i32; 2],
    /// Its origin before the move (read by the stash).
    pub old_origin: [i32; 2],
    /// Window texels per side.
    pub resolution: u32,
    /// Tile side (texels).
    pub side: u32,
    /// Side of the toroidal key table (`shared/tiles.wgsl`).
    pub keys_per_side: u32,
    /// [`ExchangeParams::STASH`] | [`ExchangeParams::USE_FALLEN`].
    pub flags: u32,
    /// How many of `rects` are used.
    pub rect_count: u32,
    /// Texel size (m): where the terrain is evaluated.
    pub texel_m: f32,
    /// Planes per resident slot ([`super::planes::planes`]).
    pub planes: u32,
    /// Rest depth (m): the window's snow words are deficits below terrain +
    /// depth + snowfall so far, the tiles' snow planes f32 heights.
    pub depth_m: f32,
    /// Exposed window-local rectangles `[row0, col0, rows, cols]`.
    pub rects: [TexelRect; 2],
}

impl ExchangeParams {
    /// Copy the old window's texels into their tiles (else: fill the new ones from theirs).
    pub const STASH: u32 = 1;
    /// The world has snowfall: the `fallen` plane is exchanged too.
    pub const USE_FALLEN: u32 = 2;
    /// `flags`: the window has a footprint buffer; without it, stashed
    /// tiles get no footprints and loaded tiles' footprints are not copied.
    pub const HAS_STAMPS: u32 = 4;
}

/// One direction of the exchange, with its own uniforms (both run in one frame).
struct Direction {
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

/// Stashes leaving texels into their tiles and loads entering ones from theirs.
pub struct ExchangePass {
    /// One pipeline per set of flags in use.
    pipelines: SpecialisedPipeline,
    stash: Direction,
    load: Direction,
}

impl ExchangePass {
    /// Builds the pipeline over the window's buffers, the resident `tiles`
    /// and their key `table` (tile key -> slot).
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, tiles: &wgpu::Buffer, table: &wgpu::Buffer) -> Self {
        let (pipelines, bgl) = SpecialisedPipeline::new(
            device,
            "exchange",
            shaders::EXCHANGE,
            &[
                layout::uniform(0, wgpu::ShaderStages::COMPUTE),
                layout::storage(1, false),
                layout::storage(2, true),
                layout::storage(3, false),
                layout::storage(4, false),
                layout::storage(5, false),
                layout::storage(6, true),
                layout::uniform(7, wgpu::ShaderStages::COMPUTE),
            ],
            "PASS_FLAGS",
            &res.terrain_constants(),
        );
        let direction = |label: &str| {
            let params = layout::uniform_buffer::<ExchangeParams>(device, label);
            let bind_group = layout::bind_group(
                device,
                label,
                &bgl,
                &[
                    params.as_entire_binding(),
                    tiles.as_entire_binding(),
                    table.as_entire_binding(),
                    res.snow.as_entire_binding(),
                    res.stamps.as_entire_binding(),
                    res.fallen.as_entire_binding(),
                    res.heightmap.as_entire_binding(),
                    res.terrain_params.as_entire_binding(),
                ],
            );
            Direction { params, bind_group }
        };
        Self { pipelines, stash: direction("exchange stash"), load: direction("exchange load") }
    }

    /// Records the stash (with [`ExchangeParams::STASH`] in `params.flags`)
    /// or the load of `rects`; nothing when empty.
    pub fn record(&self, cx: &mut FrameContext<'_>, mut params: ExchangeParams, rects: &[TexelRect]) {
        let (queue, encoder, timer) = (cx.queue(), &mut *cx.encoder, &mut *cx.timer);
        let Some((count, fixed, grid)) = rect_dispatch(rects) else { return };
        params.rect_count = count;
        params.rects = fixed;
        let stash = params.flags & ExchangeParams::STASH != 0;
        let direction = if stash { &self.stash } else { &self.load };
        queue.write_buffer(&direction.params, 0, bytemuck::bytes_of(&params));
        let label = if stash { "tile stash" } else { "tile load" };
        layout::dispatch(encoder, timer, label, &self.pipelines.get(params.flags), &direction.bind_group, grid);
    }
}
