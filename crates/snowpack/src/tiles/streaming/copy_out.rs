//! Tiles on their way from the GPU to the streamer: the copy-outs in
//! flight (staging buffers mapped asynchronously) and the tiles made from
//! a sealed slot's planes when they arrive.

use std::collections::HashSet;

use super::layout::SlotLayout;
use crate::gpu::GpuContext;
use crate::gpu::context::GpuContextExt;
use crate::gpu::readback::{MapFlag, MapState};
use crate::persist::streamer::TileStreamerExt;
use crate::persist::{SnowClock, StoreError, TileData, TileKey, TileStreamer};
use crate::tiles::planes::{PLANE_FALLEN, PLANE_SNOW, plane_packed, plane_stamps};

/// Tiles copied out of their slots in one frame, on their way to the CPU.
struct Eviction {
    buffer: wgpu::Buffer,
    keys: Vec<TileKey>,
    clock: SnowClock,
    /// The slots' layout when they were copied (a switch to footprints
    /// adds a plane to the slots while a copy-out is in flight).
    layout: SlotLayout,
    /// Its mapping, started when the encoder holding the copy is submitted.
    flag: MapFlag,
}

/// Every copy-out in flight, and the tiles they carry.
#[derive(Default)]
pub(super) struct CopyOuts {
    evictions: Vec<Eviction>,
    in_flight: HashSet<TileKey>,
}

impl CopyOuts {
    /// Whether no copy-out is in flight.
    pub(super) fn is_empty(&self) -> bool {
        self.evictions.is_empty()
    }

    /// Whether `key` is on its way back from the GPU.
    pub(super) fn carries(&self, key: TileKey) -> bool {
        self.in_flight.contains(&key)
    }

    /// Tiles on their way back.
    pub(super) fn tiles(&self) -> usize {
        self.in_flight.len()
    }

    /// GPU memory of the staging buffers in flight (bytes).
    pub(super) fn gpu_bytes(&self) -> u64 {
        self.evictions.iter().map(|e| e.buffer.size()).sum::<u64>()
    }

    /// Copies the sealed `slots` of `tiles` (laid out as `layout` says) into a
    /// staging buffer of their own in `encoder`, mapped once it is submitted.
    pub(super) fn record(
        &mut self,
        (device, encoder): (&wgpu::Device, &mut wgpu::CommandEncoder),
        tiles: &wgpu::Buffer,
        slots: &[(TileKey, usize)],
        layout: SlotLayout,
        clock: SnowClock,
    ) {
        let slot_bytes = (layout.planes() * layout.grid.area() * 4) as u64;
        let size = slot_bytes * slots.len() as u64;
        // Exactly this copy-out's size, dropped once read back: GPU memory
        // only while tiles are on their way to the CPU (counted in
        // `TileStats::gpu_bytes` meanwhile), none kept for reuse.
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("tile copy-out"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        for (k, &(key, slot)) in slots.iter().enumerate() {
            encoder.copy_buffer_to_buffer(tiles, slot as u64 * slot_bytes, &buffer, k as u64 * slot_bytes, slot_bytes);
            self.in_flight.insert(key);
        }
        let flag = MapFlag::on_submit(encoder, &buffer, size);
        self.evictions.push(Eviction { buffer, keys: slots.iter().map(|s| s.0).collect(), clock, layout, flag });
    }

    /// Hands arrived copy-outs to `streamer`; with `wait`, waits for all.
    /// Tiles that could not be read back are reported in `errors`.
    pub(super) fn collect(&mut self, ctx: &GpuContext, wait: bool, streamer: &mut TileStreamer, errors: &mut Vec<StoreError>) {
        if wait
            && !self.evictions.is_empty()
            && let Err(e) = ctx.wait_idle("reading back tiles for the store")
        {
            tracing::warn!("{e}");
        }
        let mut k = 0;
        while k < self.evictions.len() {
            let state = self.evictions[k].flag.state();
            if state == MapState::Pending {
                k += 1;
                continue;
            }
            let eviction = self.evictions.swap_remove(k);
            let layout = eviction.layout;
            let (area, side) = (layout.grid.area(), layout.grid.side());
            let used = (eviction.keys.len() * layout.planes() * area * 4) as u64;
            let words: Option<Vec<u32>> =
                if state == MapState::Mapped { eviction.buffer.slice(..used).get_mapped_range().map(|v| bytemuck::pod_collect_to_vec(&v)).ok() } else { None };
            for key in &eviction.keys {
                self.in_flight.remove(key);
            }
            let Some(words) = words else {
                errors.push(StoreError::Mismatch {
                    path: streamer.dir().to_path_buf(),
                    why: format!("{} tiles could not be read back from the GPU and are lost", eviction.keys.len()),
                });
                continue;
            };
            eviction.buffer.unmap();
            for (t, key) in eviction.keys.iter().enumerate() {
                let n = layout.planes();
                let planes = &words[t * n * area..(t + 1) * n * area];
                streamer.put(tile_from_planes(*key, side, eviction.clock, planes, (layout.use_fallen, layout.has_stamps)));
            }
        }
    }
}

/// A tile from its sealed slot's planes (snow XOR rest height, fallen where
/// the world has snowfall, packed snow, stamps where the window has
/// footprints: [`planes`](crate::tiles::planes::planes)), for the store. The seal (`tile_seal.wgsl`) XORed the heights
/// with their rest height (terrain + depth + fallen, as `tile_restore.wgsl`
/// recomputes it) on the GPU, so untouched snow is 0 and the round trip is
/// exact on any terrain. Without a footprint plane the tile has no footprints.
#[must_use]
pub fn tile_from_planes(key: TileKey, side: u32, clock: SnowClock, planes: &[u32], (use_fallen, has_stamps): (bool, bool)) -> TileData {
    let area = (side * side) as usize;
    let plane = |p: usize| &planes[p * area..(p + 1) * area];
    let fallen: Vec<f32> = if use_fallen { plane(PLANE_FALLEN).iter().map(|&b| f32::from_bits(b)).collect() } else { Vec::new() };
    let stamps = if has_stamps { plane(plane_stamps(crate::tiles::planes::planes(use_fallen, true))).to_vec() } else { vec![u32::MAX; area] };
    // The plane holds u16 values (the exchange and the restore clamp them).
    let packed = plane(plane_packed(use_fallen)).iter().map(|&q| q.min(0xffff) as u16).collect();
    TileData { key, side, clock, snow_xor_rest: plane(PLANE_SNOW).to_vec(), stamps, fallen, packed }
}
