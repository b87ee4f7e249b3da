//! What the resident tiles report: [`TileStats`], and the counters behind
//! it that the streaming's parts bump as they go.

use crate::persist::StoreStats;

/// Tile traffic so far, with the store's own figures.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileStats {
    /// The streamer's memory cache and disk store.
    pub store: StoreStats,
    /// Tiles resident on the GPU.
    pub resident: usize,
    /// Slots on the GPU.
    pub slots: usize,
    /// Frames the window stayed put because a tile it needed was still on
    /// its way back from the GPU (copied out a frame or two before). A tile
    /// the disk has not given yet does not hold the window: fresh snow
    /// stands in for it ([`Self::stood_in`]) until it is merged live
    /// ([`Self::merged_live`]); a batch run waits for the disk instead
    /// (`StreamerConfig::moves_wait_for_disk`, [`Self::blocking_loads`]).
    pub window_waits: u64,
    /// Window moves too long for the slot pool in one frame, done in
    /// batches of their own submissions (blocking): the first placement,
    /// jumps, moves of more than a tile or two.
    pub batched_moves: u64,
    /// Times a frame waited for the GPU: the first placement onto tiles
    /// still on their way out, or a move the slot pool could not hold in
    /// one step (none is planned). A save (`SnowDeformation::save`) waits
    /// by design and is not counted.
    pub gpu_waits: u64,
    /// Tiles restored from the store.
    pub restored: u64,
    /// Tiles made resident with fresh snow (never seen before).
    pub fresh: u64,
    /// Tiles the window stood in for with fresh snow (or what it had made
    /// there before) because the disk did not give the stored version in time
    /// or could not read it; what it makes there is merged with the stored
    /// version later, never written over it.
    pub stood_in: u64,
    /// Restores that merged a stored tile into what the window had made in
    /// its place (shared snow's merge: the deeper deficit wins).
    pub merged: u64,
    /// Stored tiles merged live: arrived from the disk while the window was
    /// on the tile, standing in for it with fresh snow, and folded into what
    /// it has there now (the deeper deficit wins), in a submission before a
    /// frame's move.
    pub merged_live: u64,
    /// Tiles of the window and the resident ring that fresh snow still
    /// stands in for, their stored version not merged yet (where the last
    /// frame left the window).
    pub awaiting_merge: usize,
    /// Tiles copied out of the GPU for the store.
    pub evicted: u64,
    /// Tiles on their way back from the GPU.
    pub evicting: usize,
    /// Tiles the memory cache dropped between being found ready and being
    /// used, read again from disk within the frame (blocking; rare, with a
    /// memory budget smaller than the tiles the window needs at once); and
    /// with `StreamerConfig::moves_wait_for_disk`, the moves that waited
    /// for the disk where a game's window would have held.
    pub blocking_loads: u64,
    /// GPU memory of the resident tiles, their upload buffers and the
    /// copy-out staging buffers still in flight (bytes).
    pub gpu_bytes: u64,
    /// The tiles are kept in memory only (no disk store behind them).
    pub memory_only: bool,
}

/// The traffic counters of [`TileStats`] that the planner, the arrivals and
/// the copy-outs bump (the rest are read from their owners).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct TileCounters {
    /// [`TileStats::window_waits`].
    pub(super) window_waits: u64,
    /// [`TileStats::gpu_waits`].
    pub(super) gpu_waits: u64,
    /// [`TileStats::blocking_loads`].
    pub(super) blocking_loads: u64,
    /// [`TileStats::restored`].
    pub(super) restored: u64,
    /// [`TileStats::fresh`].
    pub(super) fresh: u64,
    /// [`TileStats::stood_in`].
    pub(super) stood_in: u64,
    /// [`TileStats::merged`].
    pub(super) merged: u64,
    /// [`TileStats::merged_live`].
    pub(super) merged_live: u64,
    /// [`TileStats::evicted`].
    pub(super) evicted: u64,
}
