//! How much disk a store may use and what it does when full:
//! [`StoreConfig`], [`WhenFull`], and the decisions they make.

use std::io;
use std::path::Path;

use crate::persist::StoreError;

/// The disk budget of [`StoreConfig::default`]: 1 GiB of tile files (some
/// 200,000 tiles of 32² texels as a relay keeps them, a few thousand of a
/// game's 64² height tiles).
pub const DEFAULT_DISK_BUDGET_BYTES: u64 = 1 << 30;

/// What a store does when a write would take it past its disk budget.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WhenFull {
    /// Deletes the least recently touched tiles (they come back as fresh
    /// snow): a game's store, a cache of the world around its player.
    #[default]
    EvictOldest,
    /// Keeps every tile and refuses to write a new one
    /// (an I/O error, of kind `std::io::ErrorKind::StorageFull`); tiles
    /// already kept may still be rewritten. A server's store, whose
    /// tiles are other players' trails.
    RefuseNew,
}

/// How the store may use the disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoreConfig {
    /// Most bytes of tile files to keep (0 = unlimited; default
    /// 1 GiB, `DEFAULT_DISK_BUDGET_BYTES`). Beyond it, `when_full` says what
    /// goes. `store.meta` and state blobs are not counted, and the tile just
    /// written is never deleted, so a budget smaller than one tile keeps
    /// exactly one.
    pub disk_budget_bytes: u64,
    /// What a write past the budget does.
    pub when_full: WhenFull,
}

impl Default for StoreConfig {
    fn default() -> Self {
        Self { disk_budget_bytes: DEFAULT_DISK_BUDGET_BYTES, when_full: WhenFull::EvictOldest }
    }
}

/// With [`WhenFull::RefuseNew`], refuses a tile not yet `kept` whose `len`
/// bytes would take a store holding `total` bytes past its budget.
pub(super) fn refuse_if_full(config: &StoreConfig, total: u64, kept: bool, len: u64, path: &Path) -> Result<(), StoreError> {
    let budget = config.disk_budget_bytes;
    if config.when_full != WhenFull::RefuseNew || budget == 0 || kept || total + len <= budget {
        return Ok(());
    }
    let why = format!("the store's disk budget of {budget} bytes is spent ({total} bytes kept); new tiles are refused, kept ones stay");
    Err(StoreError::Io { path: path.to_owned(), op: "write a new tile to", source: io::Error::new(io::ErrorKind::StorageFull, why) })
}

/// The budget eviction keeps to: none (0) when the store refuses new tiles instead.
pub(super) fn eviction_budget(config: &StoreConfig) -> u64 {
    if config.when_full == WhenFull::RefuseNew { 0 } else { config.disk_budget_bytes }
}

/// Whether a new tile may still be written to a store holding `total` bytes.
pub(super) fn has_room(config: &StoreConfig, total: u64) -> bool {
    let budget = config.disk_budget_bytes;
    config.when_full == WhenFull::EvictOldest || budget == 0 || total < budget
}
