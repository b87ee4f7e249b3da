//! How much memory the streamer may use and how long it waits for the disk:
//! [`StreamerConfig`] and its default wait, [`WAIT_LIMIT`].

use std::time::Duration;

/// The default [`StreamerConfig::wait_limit`]: the longest any blocking call
/// waits for the worker (tiles to load, a flush, a state read or write, the
/// last writes when the streamer is dropped). A disk that stops answering
/// must not freeze the window, a save or the program's exit for good.
pub const WAIT_LIMIT: Duration = Duration::from_secs(30);

/// Tiles loaded for a request and not yet handed out by `lookup` may use up
/// to this much (or the budget, if larger) before they are dropped, so a
/// small budget cannot drop a tile the window is waiting for before it
/// takes it (which would make it wait forever).
pub(super) const WANTED_FLOOR_BYTES: usize = 64 << 20;

/// How much memory the streamer's cache may use, and how long it waits for
/// the disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamerConfig {
    /// Most bytes of tiles (by `TileData::memory_bytes`) to keep in memory;
    /// beyond it the least recently used are dropped. Exceptions: the tile
    /// most recently added is always kept (a budget smaller than one tile
    /// keeps one); tiles loaded because they were asked for
    /// (`TileStreamer::request`, `TileStreamer::lookup`,
    /// `TileStreamer::wait_for`) and not yet handed out by `lookup` are
    /// dropped last, and only beyond the budget or 64 MiB, whichever is
    /// larger, so the window cannot wait forever for tiles that a small
    /// budget keeps dropping. Tiles queued for writing are held by the
    /// worker until written and are not counted.
    pub memory_budget_bytes: usize,
    /// The longest a blocking call waits for the worker thread (and so for
    /// the disk): `TileStreamer::wait_for`, [`TileStreamer::flush`](super::TileStreamer::flush),
    /// `TileStreamer::write_state` and `TileStreamer::read_state` give up
    /// after it with [`crate::StoreErrorKind::TimedOut`], and dropping the streamer
    /// stops waiting for the last writes after it (logging an error and
    /// leaving the worker to finish, or hang, on its own).
    pub wait_limit: Duration,
    /// A batch run's setting (the headless runner's): a window move whose
    /// tiles the disk has not given yet waits for them (blocking, within
    /// `wait_limit`), as does the first placement, so what a run computes
    /// does not depend on the disk's speed or the machine's load. A game
    /// leaves it off (the default): its frames never wait for the disk;
    /// fresh snow stands in for such tiles and each is merged in live, with
    /// what the window pressed there meanwhile, as it arrives.
    pub moves_wait_for_disk: bool,
}

impl Default for StreamerConfig {
    /// 128 MiB: about 2,700 tiles of 64² texels with all three planes; a
    /// `WAIT_LIMIT` (30 s) wait limit; moves stand in for late tiles rather than wait.
    fn default() -> Self {
        Self { memory_budget_bytes: 128 << 20, wait_limit: WAIT_LIMIT, moves_wait_for_disk: false }
    }
}
