//! [`SlotTable`]: the pool of resident tile slots, which tile holds each,
//! the key table the passes find a tile's slot through (tile key → slot or
//! [`NO_SLOT`], `shared/tile_table.wgsl`), when each slot was last needed,
//! and which slots to give up for a move. The GPU copies of the table and of
//! the slots' owners are written from here.

use std::collections::{HashMap, HashSet};

use crate::persist::TileKey;

use super::grid::{PREFETCH_MARGIN_TILES, TileGrid};
use super::planes::NO_SLOT;

/// The slot pool: see the module documentation.
pub(super) struct SlotTable {
    grid: TileGrid,
    /// The tile in each slot of the pool.
    owners: Vec<Option<TileKey>>,
    /// Each resident tile's slot.
    slots: HashMap<TileKey, usize>,
    /// When each slot's tile was last needed (a move count), for eviction.
    last_needed: Vec<u64>,
    /// The key table and its GPU copy.
    table: Vec<u32>,
    table_buffer: wgpu::Buffer,
    /// Each slot's owner as `(col, row, resident, 0)` (the weather pass's input).
    owners_buffer: wgpu::Buffer,
}

impl SlotTable {
    /// An empty pool of `grid.slot_count()` slots; its table written empty.
    pub(super) fn new(device: &wgpu::Device, queue: &wgpu::Queue, grid: TileGrid) -> Self {
        let owners_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("tile owners"),
            size: grid.slot_count() as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let table = vec![NO_SLOT; (grid.keys_per_side() * grid.keys_per_side()) as usize];
        let table_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("tile key table"),
            size: table.len() as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&table_buffer, 0, bytemuck::cast_slice(&table));
        Self { grid, owners: vec![None; grid.slot_count()], slots: HashMap::new(), last_needed: vec![0; grid.slot_count()], table, table_buffer, owners_buffer }
    }

    /// Whether `key` holds a slot.
    pub(super) fn contains(&self, key: TileKey) -> bool {
        self.slots.contains_key(&key)
    }

    /// The slot `key` holds.
    pub(super) fn slot(&self, key: TileKey) -> Option<usize> {
        self.slots.get(&key).copied()
    }

    /// Gives `slot` to `key`, needed at move `now`.
    pub(super) fn assign(&mut self, key: TileKey, slot: usize, now: u64) {
        self.owners[slot] = Some(key);
        self.slots.insert(key, slot);
        self.last_needed[slot] = now;
        self.table[self.grid.table_entry(key)] = slot as u32;
    }

    /// Frees `key`'s slot, if it holds one.
    pub(super) fn release(&mut self, key: TileKey) {
        if let Some(slot) = self.slots.remove(&key) {
            self.owners[slot] = None;
            self.table[self.grid.table_entry(key)] = NO_SLOT;
        }
    }

    /// A free slot, if there is one.
    pub(super) fn free_slot(&self) -> Option<usize> {
        self.owners.iter().position(Option::is_none)
    }

    /// Free slots.
    pub(super) fn free_count(&self) -> usize {
        self.owners.iter().filter(|o| o.is_none()).count()
    }

    /// Resident tiles.
    pub(super) fn len(&self) -> usize {
        self.slots.len()
    }

    /// Slots in the pool.
    pub(super) fn capacity(&self) -> usize {
        self.owners.len()
    }

    /// Every resident tile, in slot order.
    pub(super) fn keys(&self) -> impl Iterator<Item = TileKey> + '_ {
        self.owners.iter().flatten().copied()
    }

    /// Every occupied slot and its tile.
    pub(super) fn owned(&self) -> impl Iterator<Item = (usize, TileKey)> + '_ {
        self.owners.iter().enumerate().filter_map(|(s, o)| o.map(|k| (s, k)))
    }

    /// Gives up the slots a step to `origin` needs for the `required` tiles
    /// at move `now`: tiles that drifted away from the window first (the
    /// table's span), then the least recently needed; returns the evicted
    /// tiles and their slots, to copy out.
    pub(super) fn evict_for(&mut self, required: &[TileKey], origin: [i64; 2], now: u64) -> Vec<(TileKey, usize)> {
        let g = self.grid;
        let wanted: HashSet<TileKey> = required.iter().copied().collect();
        let mut evicting: Vec<(TileKey, usize)> = Vec::new();
        for slot in 0..self.owners.len() {
            if let Some(k) = self.owners[slot]
                && !g.near(k, origin, PREFETCH_MARGIN_TILES)
            {
                evicting.push((k, slot));
                self.release(k);
            }
        }
        for &k in required {
            if let Some(&slot) = self.slots.get(&k) {
                self.last_needed[slot] = now;
            }
        }
        let missing = required.iter().filter(|k| !self.contains(**k)).count();
        let free = self.free_count();
        if missing > free {
            let mut candidates: Vec<(u64, usize)> =
                self.owners.iter().enumerate().filter_map(|(s, o)| o.filter(|k| !wanted.contains(k)).map(|_| (self.last_needed[s], s))).collect();
            candidates.sort_unstable();
            for &(_, slot) in candidates.iter().take(missing - free) {
                let key = self.owners[slot].expect("a candidate has an owner");
                evicting.push((key, slot));
                self.release(key);
            }
        }
        evicting
    }

    /// Writes the key table and the owners to their GPU copies.
    pub(super) fn write(&self, queue: &wgpu::Queue) {
        queue.write_buffer(&self.table_buffer, 0, bytemuck::cast_slice(&self.table));
        self.write_owners(queue);
    }

    /// Writes the owners alone.
    fn write_owners(&self, queue: &wgpu::Queue) {
        let owners: Vec<[i32; 4]> = self.owners.iter().map(|o| o.map_or([0; 4], |k| [k.col as i32, k.row as i32, 1, 0])).collect();
        queue.write_buffer(&self.owners_buffer, 0, bytemuck::cast_slice(&owners));
    }

    /// Writes a key table holding only `keys` (resident tiles), for a load
    /// that must leave every other texel of the window as it is.
    pub(super) fn write_only(&self, queue: &wgpu::Queue, keys: &[TileKey]) {
        let mut table = vec![NO_SLOT; self.table.len()];
        for &k in keys {
            if let Some(&slot) = self.slots.get(&k) {
                table[self.grid.table_entry(k)] = slot as u32;
            }
        }
        queue.write_buffer(&self.table_buffer, 0, bytemuck::cast_slice(&table));
    }

    /// The key table's GPU copy.
    pub(super) fn table_buffer(&self) -> &wgpu::Buffer {
        &self.table_buffer
    }

    /// The owners' GPU copy.
    pub(super) fn owners_buffer(&self) -> &wgpu::Buffer {
        &self.owners_buffer
    }

    /// Bytes of GPU memory held (the table and the owners).
    pub(super) fn gpu_bytes(&self) -> u64 {
        self.owners_buffer.size() + self.table_buffer.size()
    }
}
