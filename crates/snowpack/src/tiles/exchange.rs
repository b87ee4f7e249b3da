//! Exchange pass: texels between the sliding window and the resident tiles
//! (`exchange.wgsl`), used when a tile store is attached.

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
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
    /// `flags`: count what moves in the mass ledger (a stash's texels as
    /// left, a load's as entered; `shared/mass_ledger.wgsl`).
    pub const COUNT: u32 = 8;
    /// `flags`: move nothing, only count the window's texels in `rects`
    /// (with [`Self::COUNT`]: as left with [`Self::STASH`], else as
    /// entered); a long move's batches sweep the window before and after.
    pub const SWEEP: u32 = 16;
}

/// Stashes leaving texels into their tiles and loads entering ones from theirs.
pub struct ExchangePass {
    /// One pipeline per set of flags in use, and the stash's uniform.
    stash: ComputePass<ExchangeParams>,
    /// The same pipelines and the load's uniform (both may be recorded in one submission).
    load: ComputePass<ExchangeParams>,
    /// The same pipelines and a sweep's uniform (a submission of its own).
    sweep: ComputePass<ExchangeParams>,
}

impl ExchangePass {
    /// Builds the pipeline over the window's buffers, the resident `tiles`
    /// and their key `table` (tile key -> slot).
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, tiles: &wgpu::Buffer, table: &wgpu::Buffer) -> Self {
        let shape = PassShape {
            label: "exchange",
            source: shaders::EXCHANGE,
            // tiles, key table, packed snow
            slots: &[Slot::ReadWrite, Slot::Read, Slot::ReadWrite],
            specialise_on: Some("PASS_FLAGS"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Write),
        };
        let mut stash = ComputePass::new(device, &shape, Some(&res.bindings));
        let mut load = stash.sibling(device);
        let mut sweep = stash.sibling(device);
        for pass in [&mut stash, &mut load, &mut sweep] {
            pass.bind(device, &[tiles.as_entire_binding(), table.as_entire_binding(), res.packed.as_entire_binding()]);
        }
        Self { stash, load, sweep }
    }

    /// Records the stash (with [`ExchangeParams::STASH`] in `params.flags`),
    /// the load or the sweep ([`ExchangeParams::SWEEP`]) of `rects`;
    /// nothing when empty.
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, mut params: ExchangeParams, rects: &[TexelRect]) {
        let Some((count, fixed, grid)) = rect_dispatch(rects) else { return };
        params.rect_count = count;
        params.rects = fixed;
        let (pass, label) = if params.flags & ExchangeParams::SWEEP != 0 {
            (&self.sweep, "ledger sweep")
        } else if params.flags & ExchangeParams::STASH != 0 {
            (&self.stash, "tile stash")
        } else {
            (&self.load, "tile load")
        };
        pass.record_labelled(cx, label, Some(&res.bindings), &params, params.flags, grid);
    }
}
