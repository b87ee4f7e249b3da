//! Tile gather pass (`tile_gather.wgsl`): whole tiles of the global grid
//! copied out of the window's toroidal buffers into a packed buffer, to be
//! read back and sent as [`SharedTile`]s.

use bytemuck::{Pod, Zeroable};

use crate::deform::resources::DeformResources;
use crate::frame::FrameContext;
use crate::pass::compute::{ComputePass, PassShape, Slot};
use crate::pass::window_bindings::WindowAccess;
use crate::persist::TileKey;
use crate::shaders;

use super::tile::{ShareClock, SharedTile};

/// Planes per packed tile: deficit (with the packed snow in its high half),
/// footprint, snowfall (f32 bits).
pub const PACKED_PLANES: usize = 3;

/// Uniforms of `tile_gather.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TileGatherParams {
    /// Global texel of window-local (0, 0): `[column, row]`.
    pub origin: [i32; 2],
    /// Window texels per side.
    pub resolution: u32,
    /// Tile side (texels).
    pub side: u32,
    /// Tiles to gather.
    pub count: u32,
    /// [`Self::HAS_STAMPS`] | [`Self::USE_FALLEN`].
    pub flags: u32,
    /// 8x8 blocks per tile side (`ceil(side / 8)`); [`TileGatherPass::record`] sets it.
    pub blocks: u32,
    /// Padding to 8 bytes.
    pub _pad: u32,
}

impl TileGatherParams {
    /// The window has a footprint buffer (else footprints gather as none).
    pub const HAS_STAMPS: u32 = 1;
    /// The window has snowfall (else it gathers as 0).
    pub const USE_FALLEN: u32 = 2;
}

/// Bytes of one packed tile of `side`.
#[must_use]
pub fn packed_tile_bytes(side: u32) -> u64 {
    u64::from(side) * u64::from(side) * PACKED_PLANES as u64 * 4
}

/// Keys as the passes take them: `[column, row]` in i32 (tiles near a
/// window, whose texels fit i32, do).
#[must_use]
pub fn gpu_keys(keys: &[TileKey]) -> Vec<[i32; 2]> {
    keys.iter().map(|k| [k.col as i32, k.row as i32]).collect()
}

/// The gathered tiles of `keys` from `packed` (as the pass writes it), at
/// `clock`, with the planes the world has.
#[must_use]
pub fn unpack_tiles(keys: &[TileKey], side: u32, clock: ShareClock, packed: &[u32], (stamps, fallen): (bool, bool)) -> Vec<SharedTile> {
    let area = (side as usize) * (side as usize);
    keys.iter()
        .zip(packed.chunks_exact(area * PACKED_PLANES))
        .map(|(&key, planes)| SharedTile {
            key,
            side,
            clock,
            // The deficit's low half, the packed snow the high half.
            deficit: planes[..area].iter().map(|&d| (d & 0xffff) as u16).collect(),
            packed: planes[..area].iter().map(|&d| (d >> 16) as u16).collect(),
            stamps: if stamps { planes[area..2 * area].to_vec() } else { Vec::new() },
            fallen: if fallen { planes[2 * area..].iter().map(|&b| f32::from_bits(b)).collect() } else { Vec::new() },
        })
        .collect()
}

/// Copies whole tiles out of the window.
pub struct TileGatherPass {
    /// One pipeline per set of flags in use.
    pass: ComputePass<TileGatherParams>,
    keys: wgpu::Buffer,
    packed: wgpu::Buffer,
    capacity: u32,
}

impl TileGatherPass {
    /// Builds the pipeline over the window's buffers, for up to `capacity`
    /// tiles of `side` a dispatch.
    #[must_use]
    pub fn new(device: &wgpu::Device, res: &DeformResources, side: u32, capacity: u32) -> Self {
        let shape = PassShape {
            label: "tile gather",
            source: shaders::TILE_GATHER,
            // keys, the gathered tiles, the window's packed snow
            slots: &[Slot::Read, Slot::ReadWrite, Slot::Read],
            specialise_on: Some("PASS_FLAGS"),
            constants: &[],
            window: Some(WindowAccess::Read),
        };
        let mut pass = ComputePass::new(device, &shape, Some(&res.bindings));
        let keys = crate::tiles::input_buffer(device, "tile gather keys", u64::from(capacity) * 8);
        let packed = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("tile gather packed"),
            size: packed_tile_bytes(side) * u64::from(capacity.max(1)),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        pass.bind(device, &[keys.as_entire_binding(), packed.as_entire_binding(), res.packed.as_entire_binding()]);
        Self { pass, keys, packed, capacity }
    }

    /// Tiles one dispatch gathers at most.
    #[must_use]
    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    /// The packed tiles the last dispatch wrote ([`PACKED_PLANES`] planes a tile).
    #[must_use]
    pub fn packed(&self) -> &wgpu::Buffer {
        &self.packed
    }

    /// GPU memory held (bytes).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.packed.size() + self.keys.size()
    }

    /// Records the gather of `keys` (at most [`Self::capacity`]; the rest
    /// are left out) into [`Self::packed`]; returns how many it gathers.
    pub fn record(&self, cx: &mut FrameContext<'_>, res: &DeformResources, params: TileGatherParams, keys: &[[i32; 2]]) -> u32 {
        let keys = &keys[..keys.len().min(self.capacity as usize)];
        if keys.is_empty() {
            return 0;
        }
        let blocks = params.side.div_ceil(8);
        let p = TileGatherParams { count: keys.len() as u32, blocks, ..params };
        cx.queue().write_buffer(&self.keys, 0, bytemuck::cast_slice(keys));
        self.pass.record(cx, Some(&res.bindings), &p, p.flags, (blocks * blocks, p.count));
        p.count
    }
}
