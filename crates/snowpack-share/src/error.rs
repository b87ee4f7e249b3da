//! The errors of shared snow and the tile store, in detail: of the tile
//! store ([`StoreError`], re-exported by [`crate::persist`]) and of shared
//! snow ([`ShareError`] and [`MessageError`], re-exported by
//! [`crate::replicate`]). snowpack's `SnowError` wraps them.
//!
//! These enums are the errors as the crate builds them; the opaque errors
//! at the root ([`front`]: `snowpack_share::StoreError`, `ShareError` and
//! their kinds) wrap them.

use std::path::{Path, PathBuf};

pub mod front;

/// What can go wrong storing or loading tiles. Every variant but
/// [`StoreError::WorkerGone`] and [`StoreError::NoDisk`] names the file (errors from `decode` alone,
/// which sees bytes and no file, leave the path empty).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StoreError {
    /// The operating system refused (disk full, read-only, a directory gone).
    #[error("cannot {op} {}: {source}", shown(path))]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What was being done, as a verb phrase ("write", "rename into place").
        op: &'static str,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The file is damaged (bad checksum, truncated, not a tile).
    #[error("{} is corrupt: {why}", shown(path))]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    /// The file was written in a format this build does not read.
    #[error("{} is format version {found}; this build reads version {expected}", shown(path))]
    Version {
        /// The file.
        path: PathBuf,
        /// The version in the file.
        found: u32,
        /// The version this build reads and writes.
        expected: u32,
    },
    /// A well-formed file or tile that does not fit (another tile side, another key).
    #[error("{}: {why}", shown(path))]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// What does not match.
        why: String,
    },
    /// A blocking call on the tile store was not answered in time (a disk
    /// that hangs or crawls): tiles to load (`TileStreamer::wait_for`),
    /// a flush, a state read or write, or the worker's last writes when the
    /// streamer is dropped. The call gives up rather than freeze the caller;
    /// what it asked for stays queued and may still be done if the disk
    /// answers later. The limit is snowpack's `StreamerConfig::wait_limit`.
    #[error("gave up after {waited:?} waiting for {what}: the disk is too slow or not answering")]
    TimedOut {
        /// What was waited for ("2 tile(s) to load", "the state `window.state` to be written").
        what: String,
        /// How long the wait lasted.
        waited: std::time::Duration,
    },
    /// The streamer's worker thread has stopped (it panicked or never started).
    #[error("the tile store's worker thread has stopped; tiles can no longer be loaded or saved")]
    WorkerGone,
    /// Tiles are kept in memory only (snowpack's `TileStreamer::in_memory`); saving
    /// needs a disk store.
    #[error("tiles are kept in memory only; saving needs a disk store (a TileStreamer over a TileStore, attached with attach_store)")]
    NoDisk,
}

impl StoreError {
    /// The file the error is about, when there is one.
    #[must_use]
    pub fn path(&self) -> Option<&Path> {
        match self {
            Self::Io { path, .. } | Self::Corrupt { path, .. } | Self::Version { path, .. } | Self::Mismatch { path, .. } => {
                (!path.as_os_str().is_empty()).then_some(path.as_path())
            }
            Self::WorkerGone | Self::NoDisk | Self::TimedOut { .. } => None,
        }
    }

    /// The same error naming `file` where it named none (errors from
    /// [`decode`](crate::persist::decode) and [`TileData::validate`](crate::persist::TileData::validate) see no file).
    #[must_use]
    #[cfg_attr(not(feature = "low_level"), doc(hidden))]
    pub fn at(mut self, file: &Path) -> Self {
        if let Self::Io { path, .. } | Self::Corrupt { path, .. } | Self::Version { path, .. } | Self::Mismatch { path, .. } = &mut self
            && path.as_os_str().is_empty()
        {
            file.clone_into(path);
        }
        self
    }
}

/// How an error shows its path: errors from bytes alone have none.
fn shown(path: &Path) -> String {
    if path.as_os_str().is_empty() { "the tile data".to_owned() } else { path.display().to_string() }
}

/// What can go wrong sharing snow.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ShareError {
    /// The relay's world is another: one phrase per difference, "here"
    /// being this peer's world and "there" the relay's.
    #[error("the relay refused this world: {}", differences.join("; "))]
    Refused {
        /// What differs ("tile side: 32 here, 64 there").
        differences: Vec<String>,
    },
    /// A message that does not decode, or that this side never receives.
    #[error("malformed message: {0}")]
    Malformed(#[from] MessageError),
    /// The relay's tile store failed.
    #[error("tile store: {0}")]
    Store(#[from] StoreError),
    /// The relay's store holds a world that cannot be used.
    #[error("the relay's store: {0}")]
    StoreWorld(String),
}

/// What is wrong with a message's bytes.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MessageError {
    /// The bytes end before the message does.
    #[error("truncated: {what} needs {needed} more byte(s), {left} left")]
    Truncated {
        /// The field being read.
        what: &'static str,
        /// Bytes it needs.
        needed: usize,
        /// Bytes that were left.
        left: usize,
    },
    /// The bytes do not start with `SNWP`.
    #[error("not a snowpack sharing message (no SNWP magic)")]
    BadMagic,
    /// Another protocol version.
    #[error("protocol version {found}; this build speaks version {expected}")]
    BadVersion {
        /// The version in the message.
        found: u16,
        /// The version this build speaks.
        expected: u16,
    },
    /// A kind byte this build does not know.
    #[error("unknown message kind {0}")]
    UnknownKind(u8),
    /// The message is larger than [`MAX_MESSAGE_BYTES`](crate::replicate::MAX_MESSAGE_BYTES).
    #[error("oversized: {bytes} bytes, the most is {max}")]
    Oversized {
        /// The message's size.
        bytes: usize,
        /// The limit.
        max: usize,
    },
    /// A count above its cap.
    #[error("too many {what}: {count}, the most is {max}")]
    TooMany {
        /// What is counted.
        what: &'static str,
        /// The count in the message.
        count: usize,
        /// The cap.
        max: usize,
    },
    /// A tile that cannot be one (side, flags, payload).
    #[error("bad tile: {0}")]
    BadTile(String),
    /// A field with a value it cannot have (text that is not UTF-8, a flag
    /// that is not 0 or 1).
    #[error("bad {what}: {why}")]
    BadValue {
        /// The field.
        what: &'static str,
        /// What is wrong.
        why: String,
    },
    /// A message of a kind the receiver never receives (a relay's `Ack`
    /// sent to a relay, a peer's `Hello` sent to a peer).
    #[error("a {0} message is not expected here")]
    Unexpected(&'static str),
    /// Bytes follow the message's body.
    #[error("{0} trailing byte(s) after the message")]
    TrailingBytes(usize),
}

impl From<crate::bytes::Truncated> for MessageError {
    fn from(t: crate::bytes::Truncated) -> Self {
        Self::Truncated { what: t.what, needed: t.needed, left: t.left }
    }
}
