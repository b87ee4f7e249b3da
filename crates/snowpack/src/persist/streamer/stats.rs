//! The counters of the streamer's cache and store: [`StoreStats`].

/// Counters of the cache and the store.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StoreStats {
    /// Tiles in the memory cache.
    pub memory_tiles: usize,
    /// Their [`TileData::memory_bytes`](crate::persist::TileData::memory_bytes).
    pub memory_bytes: usize,
    /// Tiles on disk (as of the worker's last reply).
    pub disk_tiles: usize,
    /// Bytes of tile files on disk (as of the worker's last reply).
    pub disk_bytes: u64,
    /// Lookups answered from memory (a cached tile, or known to be absent).
    pub hits: u64,
    /// Lookups that had to start a load from disk. (Asking again while the
    /// load is in flight counts neither.)
    pub misses: u64,
    /// Loads the worker has answered.
    pub loads: u64,
    /// Tiles written to disk.
    pub writes: u64,
    /// Bytes of those writes (compressed, headers included).
    pub bytes_written: u64,
    /// Tiles that failed to decode (answered as absent, set aside on disk).
    pub corrupt: u64,
    /// Errors of any kind (each returned by
    /// [`TileStreamer::flush`](super::TileStreamer::flush) or in
    /// [`TileStreamer::take_errors`](super::TileStreamerExt::take_errors)).
    pub errors: u64,
    /// Dirty tiles dropped from memory after their write had failed: their
    /// latest version is lost. For a memory-only streamer
    /// ([`TileStreamer::in_memory`](super::TileStreamerExt::in_memory)): every tile the budget dropped (it comes
    /// back as fresh snow).
    pub lost: u64,
    /// Tiles deleted from disk to keep within its budget.
    pub evicted: u64,
}

impl StoreStats {
    /// `hits / (hits + misses)`, 0 before any lookup.
    #[must_use]
    pub fn hit_rate(&self) -> f64 {
        let total = self.hits + self.misses;
        if total == 0 { 0.0 } else { self.hits as f64 / total as f64 }
    }
}
