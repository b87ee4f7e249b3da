//! Tile restore pass: tiles become resident, from the store (brought up to
//! now) or fresh (`tile_restore.wgsl`).

use bytemuck::{Pod, Zeroable};

use crate::frame::FrameContext;
use crate::gpu::layout;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
use crate::shaders;

use crate::deform::resources::DeformResources;

/// Uniforms of `tile_restore.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RestoreParams {
    /// Tile side (texels).
    pub side: u32,
    /// Padding (was the toroidal slot grid's side).
    pub _pad0: u32,
    /// Entries this frame.
    pub count: u32,
    /// [`RestoreParams::USE_FALLEN`].
    pub flags: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Rest depth of fresh snow (m).
    pub depth_m: f32,
    /// Snowfall so far on open ground (m), for fresh tiles.
    pub fallen_m: f32,
    /// Most snowfall a texel keeps (m).
    pub max_fallen_m: f32,
    /// Footprint quantisation: lowest height (m).
    pub low_m: f32,
    /// Footprint quantisation: highest height (m).
    pub high_m: f32,
    /// Planes per resident slot ([`super::planes::planes`]).
    pub planes: u32,
    /// Padding.
    pub _pad: u32,
}

impl RestoreParams {
    /// The world has snowfall.
    pub const USE_FALLEN: u32 = 2;
    /// The slots have a footprint plane: set by [`TileRestorePass::record`]
    /// from `planes`, so that the shader's choice is a flag.
    pub const STAMP_PLANE: u32 = 4;
}

/// One tile made resident (`RestoreEntry` in `tile_restore.wgsl`). The
/// default restores fresh snow into slot 0 with nothing to merge.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct RestoreEntry {
    /// Tile coordinates `[column, row]`.
    pub tile: [i32; 2],
    /// Its slot.
    pub slot: u32,
    /// First u32 of its saved planes in the upload buffer, or [`RestoreEntry::FRESH`].
    pub upload: u32,
    /// Refill of the time it was away (m).
    pub refill_m: f32,
    /// Snowfall of the time it was away (m).
    pub fall_m: f32,
    /// Footprint refill of the time it was away (stamp quanta).
    pub quanta: u32,
    /// 1 when any time counted (0: restored bit for bit).
    pub elapsed: u32,
    /// First u32 of a second tile's planes to merge in (what the window made
    /// in this tile's place while the disk was late with it),
    /// [`RestoreEntry::FRESH`]: none, or [`RestoreEntry::IN_SLOT`]: the
    /// slot's own texels as they are (a live merge).
    pub merge: u32,
    /// Refill of the time the second tile was away (m).
    pub merge_refill_m: f32,
    /// Snowfall of the time the second tile was away (m).
    pub merge_fall_m: f32,
    /// Footprint refill of the time the second tile was away (stamp quanta).
    pub merge_quanta: u32,
}

impl RestoreEntry {
    /// No saved planes: fresh snow (for `upload`), nothing to merge (for `merge`).
    pub const FRESH: u32 = u32::MAX;
    /// For `merge`: fold in the slot's texels as they are now (the window's
    /// stand-in, stashed into the slot), not a second uploaded tile.
    pub const IN_SLOT: u32 = u32::MAX - 1;
}

impl Default for RestoreEntry {
    fn default() -> Self {
        Self {
            tile: [0; 2],
            slot: 0,
            upload: Self::FRESH,
            refill_m: 0.0,
            fall_m: 0.0,
            quanta: 0,
            elapsed: 0,
            merge: Self::FRESH,
            merge_refill_m: 0.0,
            merge_fall_m: 0.0,
            merge_quanta: 0,
        }
    }
}

/// Writes restored or fresh tiles into their slots.
pub struct TileRestorePass {
    /// One pipeline per set of flags in use.
    pass: ComputePass<RestoreParams>,
    entries: wgpu::Buffer,
    upload: wgpu::Buffer,
}

impl TileRestorePass {
    /// Builds the pipeline over the terrain description in `res` and the resident `tiles`.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, tiles: &wgpu::Buffer) -> Self {
        let shape = PassShape {
            label: "tile restore",
            source: shaders::TILE_RESTORE,
            slots: &[Slot::Read, Slot::Read, Slot::ReadWrite],
            specialise_on: Some("PASS_FLAGS"),
            constants: &res.terrain_constants(),
            window: Some(WindowAccess::Read),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        let entries = super::input_buffer(device, "tile restore entries", 64 * size_of::<RestoreEntry>() as u64);
        let upload = super::input_buffer(device, "tile upload", 16);
        pass.bind(device, &[entries.as_entire_binding(), upload.as_entire_binding(), tiles.as_entire_binding()]);
        Self { pass, entries, upload }
    }

    /// Records the restore of `entries`, whose saved planes are `upload`
    /// (indexed by [`RestoreEntry::upload`]); grows its buffers as needed.
    pub fn record(
        &mut self,
        cx: &mut FrameContext<'_>,
        (res, tiles): (&DeformResources, &wgpu::Buffer),
        mut params: RestoreParams,
        entries: &[RestoreEntry],
        upload: &[u32],
    ) {
        params.flags = super::planes::with_stamp_plane_flag(params.flags, params.planes, (RestoreParams::USE_FALLEN, RestoreParams::STAMP_PLANE));
        let (device, queue) = (cx.device(), cx.queue());
        if entries.is_empty() {
            return;
        }
        let entry_bytes = std::mem::size_of_val(entries) as u64;
        let upload_bytes = std::mem::size_of_val(upload) as u64;
        if entry_bytes > self.entries.size() || upload_bytes > self.upload.size() {
            if entry_bytes > self.entries.size() {
                self.entries = super::input_buffer(device, "tile restore entries", entry_bytes.next_power_of_two());
            }
            if upload_bytes > self.upload.size() {
                self.upload = super::input_buffer(device, "tile upload", upload_bytes.next_power_of_two());
            }
            self.pass.bind(device, &[self.entries.as_entire_binding(), self.upload.as_entire_binding(), tiles.as_entire_binding()]);
        }
        params.count = entries.len() as u32;
        queue.write_buffer(&self.entries, 0, bytemuck::cast_slice(entries));
        if !upload.is_empty() {
            queue.write_buffer(&self.upload, 0, bytemuck::cast_slice(upload));
        }
        let groups = layout::groups(params.side * params.side, 256);
        self.pass.record(cx, Some(&res.bindings), &params, params.flags, (groups, params.count));
    }

    /// Bytes of GPU memory held (its upload and entry buffers).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.entries.size() + self.upload.size()
    }
}
