//! What a slot holds: the grid the tiles are cut on, the planes per slot
//! and the snow's depth, and the pass uniforms and window strips that
//! follow from them.

use crate::deform::resources::DeformResources;
use crate::deform::window::TexelRect;
use crate::frame::WindowFrame;
use crate::persist::TileKey;
use crate::tiles::exchange::ExchangeParams;
use crate::tiles::grid::TileGrid;
use crate::tiles::planes::planes;
use crate::tiles::restore::RestoreParams;
use crate::tiles::seal::SealParams;

/// The slots' shape: the grid, the snow's depth and which planes a slot has.
#[derive(Clone, Copy, Debug)]
pub(super) struct SlotLayout {
    pub(super) grid: TileGrid,
    pub(super) depth_m: f32,
    pub(super) use_fallen: bool,
    /// Whether the slots have a footprint plane (the window a footprint buffer).
    pub(super) has_stamps: bool,
}

impl SlotLayout {
    /// Planes per slot now.
    pub(super) fn planes(&self) -> usize {
        planes(self.use_fallen, self.has_stamps)
    }

    /// The exchange's uniforms; `kind` is [`ExchangeParams::STASH`],
    /// [`ExchangeParams::COUNT`] and [`ExchangeParams::SWEEP`] as the step needs.
    pub(super) fn exchange_params(&self, res: &DeformResources, old: [i64; 2], origin: [i64; 2], kind: u32) -> ExchangeParams {
        let flags = if self.use_fallen { ExchangeParams::USE_FALLEN } else { 0 } | if res.has_stamps() { ExchangeParams::HAS_STAMPS } else { 0 } | kind;
        ExchangeParams {
            origin: [origin[0] as i32, origin[1] as i32],
            old_origin: [old[0] as i32, old[1] as i32],
            resolution: res.resolution,
            side: self.grid.side(),
            keys_per_side: self.grid.keys_per_side(),
            flags,
            texel_m: res.texel_m,
            planes: self.planes() as u32,
            depth_m: self.depth_m,
            ..ExchangeParams::default()
        }
    }

    /// The restore's uniforms for this frame's window.
    pub(super) fn restore_params(&self, frame: &WindowFrame) -> RestoreParams {
        RestoreParams {
            side: self.grid.side(),
            flags: if frame.use_fallen { RestoreParams::USE_FALLEN } else { 0 },
            planes: self.planes() as u32,
            texel_m: frame.texel_m,
            depth_m: frame.depth_m,
            fallen_m: frame.fallen_m,
            max_fallen_m: frame.max_fallen_m,
            low_m: frame.low_m,
            high_m: frame.high_m,
            ..RestoreParams::default()
        }
    }

    /// The seal's uniforms for the window of `res`.
    pub(super) fn seal_params(&self, res: &DeformResources) -> SealParams {
        SealParams {
            side: self.grid.side(),
            planes: self.planes() as u32,
            flags: if self.use_fallen { SealParams::USE_FALLEN } else { 0 },
            texel_m: res.texel_m,
            depth_m: self.depth_m,
            ..SealParams::default()
        }
    }

    /// The window-local rectangles (at most two, as the exchange takes)
    /// that cover the texels of `batch`'s tiles in the window at `origin`:
    /// the bounds of its tiles left of the window's middle and of those
    /// right of it. A batch of a jump is a run of rows or the edge columns,
    /// so a batch's stash or load reads a strip of the window, not all of it
    /// (64 passes over the whole window made a jump at 1024² take 2 s on
    /// lavapipe).
    pub(super) fn batch_rects(&self, batch: &[TileKey], origin: [i64; 2]) -> Vec<TexelRect> {
        let (s, n) = (i64::from(self.grid.side()), i64::from(self.grid.resolution()));
        let mut bounds: [Option<[i64; 4]>; 2] = [None, None];
        for k in batch {
            // The tile's texels in window-local coordinates, clipped to the window.
            let (c0, c1) = ((k.col * s - origin[0]).max(0), ((k.col + 1) * s - origin[0]).min(n));
            let (r0, r1) = ((k.row * s - origin[1]).max(0), ((k.row + 1) * s - origin[1]).min(n));
            if c0 >= c1 || r0 >= r1 {
                continue;
            }
            let half = usize::from(c0 + c1 > n);
            let b = bounds[half].get_or_insert([r0, c0, r1, c1]);
            *b = [b[0].min(r0), b[1].min(c0), b[2].max(r1), b[3].max(c1)];
        }
        bounds.into_iter().flatten().map(|[r0, c0, r1, c1]| [r0 as u32, c0 as u32, (r1 - r0) as u32, (c1 - c0) as u32]).collect()
    }
}
