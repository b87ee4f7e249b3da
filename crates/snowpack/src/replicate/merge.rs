//! Tile merge pass (`tile_merge.wgsl`): tiles from other machines, brought
//! to the window's clock (caught up on the CPU, or by replaying the
//! window's own last frames), folded into the window by the texel-wise
//! deeper deficit, deeper snowfall and lower footprint.

use bytemuck::{Pod, Zeroable};

use crate::deform::resources::DeformResources;
use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
use crate::shaders;

use super::gather::{PACKED_PLANES, packed_tile_bytes};
use super::tile::{NO_STAMP, SharedTile};

/// Uniforms of `tile_merge.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TileMergeParams {
    /// Global texel of window-local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Window texels per side.
    pub resolution: u32,
    /// Tile side (texels).
    pub side: u32,
    /// Tiles to merge.
    pub count: u32,
    /// [`Self::HAS_STAMPS`] | [`Self::USE_FALLEN`].
    pub flags: u32,
    /// 8x8 blocks per tile side; [`TileMergePass::record`] sets it.
    pub blocks: u32,
    /// Rest depth (m).
    pub depth_m: f32,
    /// Texel size (m): where the terrain is evaluated.
    pub texel_m: f32,
    /// Footprint quantisation range, low end (m).
    pub low_m: f32,
    /// Footprint quantisation range, high end (m).
    pub high_m: f32,
    /// Frames in the history ([`TileMergePass::record`] sets it).
    pub frames: u32,
    /// The most snowfall a texel keeps (m).
    pub max_fallen_m: f32,
    /// `ρmax / ρ0 − 1`: what a deficit the merge raises packs into the
    /// column, as a press would (`shared/pack_press.wgsl`).
    pub pack_ratio: f32,
}

/// Frames of its own a window remembers to replay for tiles gathered then.
pub const HISTORY_FRAMES: usize = 64;

/// One of the window's frames as the update pass ran it, for the merge
/// pass to replay on a tile gathered before it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRecord {
    /// The world clock after the frame.
    pub after: super::tile::ShareClock,
    /// Snow refill (deficit quanta).
    pub snow_quanta: u32,
    /// Footprint refill (stamp quanta).
    pub stamp_quanta: u32,
    /// Snowfall on open ground (m).
    pub fall_m: f32,
    /// Whether the stored footprints pressed the snow (the technique stamps).
    pub stamps_pressed: bool,
}

impl FrameRecord {
    /// As `tile_merge.wgsl`'s `history` holds it.
    #[must_use]
    pub fn gpu(&self) -> [u32; 4] {
        [self.snow_quanta, self.stamp_quanta, self.fall_m.to_bits(), u32::from(self.stamps_pressed)]
    }
}

impl TileMergeParams {
    /// The window has a footprint buffer (footprints are merged).
    pub const HAS_STAMPS: u32 = 1;
    /// The window has snowfall (snowfall is merged).
    pub const USE_FALLEN: u32 = 2;
}

/// `tiles` (of one side, distinct keys) packed as the passes take them
/// (the packed snow in the deficit word's high half): a plane a tile lacks
/// is the merge's identity. A tile without packed snow merges as a press
/// (its key's `CARRIES_PACKED` bit unset, [`carries_packed`]).
#[must_use]
pub fn pack_tiles(tiles: &[&SharedTile]) -> Vec<u32> {
    let mut out = Vec::new();
    for t in tiles {
        let n = t.texels();
        let packed = |k: usize| u32::from(t.packed.get(k).copied().unwrap_or(0)) << 16;
        out.extend(t.deficit.iter().enumerate().map(|(k, &d)| u32::from(d) | packed(k)));
        if t.stamps.len() == n {
            out.extend_from_slice(&t.stamps);
        } else {
            out.extend(std::iter::repeat_n(NO_STAMP, n));
        }
        if t.fallen.len() == n {
            out.extend(t.fallen.iter().map(|f| f.to_bits()));
        } else {
            out.extend(std::iter::repeat_n(0, n));
        }
    }
    out
}

/// A merge key's last field where the tile carries packed snow: the merge
/// then takes the larger packed snow of the two copies (a lattice, as the
/// deficit's), where a tile without it packs the raised deficit as a press.
pub const CARRIES_PACKED: i32 = 1;

/// The last field of `t`'s merge key: `CARRIES_PACKED` or 0.
#[must_use]
pub fn carries_packed(t: &SharedTile) -> i32 {
    if t.packed.len() == t.texels() { CARRIES_PACKED } else { 0 }
}

/// Folds uploaded tiles into the window.
pub struct TileMergePass {
    /// One pipeline per set of flags in use.
    pass: ComputePass<TileMergeParams>,
    keys: wgpu::Buffer,
    tiles: wgpu::Buffer,
    history: wgpu::Buffer,
    capacity: u32,
}

impl TileMergePass {
    /// Builds the pipeline over the window's buffers, for up to `capacity`
    /// tiles of `side` a dispatch.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, side: u32, capacity: u32) -> Self {
        let shape = PassShape {
            label: "tile merge",
            source: shaders::TILE_MERGE,
            // keys, tiles, history, packed snow (with the displaced count)
            slots: &[Slot::Read, Slot::Read, Slot::Read, Slot::ReadWrite],
            specialise_on: Some("PASS_FLAGS"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Write),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        let keys = crate::tiles::input_buffer(device, "tile merge keys", u64::from(capacity) * 16);
        let history = crate::tiles::input_buffer(device, "tile merge history", HISTORY_FRAMES as u64 * 16);
        let tiles = crate::tiles::input_buffer(device, "tile merge upload", packed_tile_bytes(side) * u64::from(capacity.max(1)));
        pass.bind(device, &[keys.as_entire_binding(), tiles.as_entire_binding(), history.as_entire_binding(), res.packed.as_entire_binding()]);
        Self { pass, keys, tiles, history, capacity }
    }

    /// Tiles one dispatch merges at most.
    #[must_use]
    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    /// GPU memory held (bytes).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.tiles.size() + self.keys.size() + self.history.size()
    }

    /// Records the merge of packed `tiles` ([`pack_tiles`]) at `keys`
    /// (`[column, row, first frame of history to replay, `[`carries_packed`]`]`, distinct
    /// tiles; at most [`Self::capacity`], the rest are left out), replaying
    /// `history` (at most [`HISTORY_FRAMES`], oldest first, as
    /// [`FrameRecord::gpu`]); returns how many tiles it merges.
    pub fn record(
        &self,
        cx: &mut FrameContext<'_>,
        res: &DeformResources,
        params: TileMergeParams,
        (keys, history): (&[[i32; 4]], &[[u32; 4]]),
        tiles: &[u32],
    ) -> u32 {
        let area = (params.side as usize) * (params.side as usize);
        let count = keys.len().min(self.capacity as usize).min(tiles.len() / (area * PACKED_PLANES).max(1));
        if count == 0 {
            return 0;
        }
        let blocks = params.side.div_ceil(8);
        let history = &history[..history.len().min(HISTORY_FRAMES)];
        let p = TileMergeParams { count: count as u32, blocks, frames: history.len() as u32, ..params };
        let queue = cx.queue();
        queue.write_buffer(&self.keys, 0, bytemuck::cast_slice(&keys[..count]));
        if !history.is_empty() {
            queue.write_buffer(&self.history, 0, bytemuck::cast_slice(history));
        }
        queue.write_buffer(&self.tiles, 0, bytemuck::cast_slice(&tiles[..count * area * PACKED_PLANES]));
        self.pass.record(cx, Some(&res.bindings), &p, p.flags, (blocks * blocks, p.count));
        p.count
    }
}
