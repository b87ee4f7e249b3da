//! The answer to `TileStreamer::lookup`: [`TileLookup`].

use crate::persist::TileData;

/// The answer to [`TileStreamer::lookup`](super::TileStreamerExt::lookup).
#[derive(Clone, Debug, PartialEq)]
pub enum TileLookup {
    /// The tile's stored state; `None`: not in the store (never written,
    /// evicted, or unreadable: see [`TileStreamer::take_errors`](super::TileStreamerExt::take_errors)), use fresh snow.
    Ready(Option<TileData>),
    /// Being loaded; ask again on a later frame.
    Pending,
}
