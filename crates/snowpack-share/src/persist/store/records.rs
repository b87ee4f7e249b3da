//! The store's small records, framed and checked: `store.meta`, a
//! `.state` blob and `save.commit`.

use std::path::{Path, PathBuf};

use crate::persist::StoreError;
use crate::persist::codec::{FORMAT_VERSION, readable};

/// Identifies `store.meta`.
const META_MAGIC: &[u8; 8] = b"SNOWSTOR";
/// Identifies a `.state` file.
const STATE_MAGIC: &[u8; 8] = b"SNOWSTAT";
/// Identifies `save.commit`.
const SAVE_MAGIC: &[u8; 8] = b"SNOWSAVE";

/// A `.state` file's bytes: magic, format version, length, CRC32, then `bytes`.
pub(super) fn frame_state(bytes: &[u8]) -> Vec<u8> {
    let mut framed = Vec::with_capacity(24 + bytes.len());
    framed.extend_from_slice(STATE_MAGIC);
    framed.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    framed.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    let mut crc = crc32fast::Hasher::new();
    crc.update(&framed);
    crc.update(bytes);
    framed.extend_from_slice(&crc.finalize().to_le_bytes());
    framed.extend_from_slice(bytes);
    framed
}

/// The blob a `.state` file at `path` holds, once its magic, version, length and CRC check out.
pub(super) fn unframe_state(path: PathBuf, framed: &[u8]) -> Result<Vec<u8>, StoreError> {
    let corrupt = |why: &str| StoreError::Corrupt { path: path.clone(), why: why.to_owned() };
    if framed.len() < 24 || &framed[..8] != STATE_MAGIC {
        return Err(corrupt("not a snowpack state file (no SNOWSTAT magic or too short)"));
    }
    let version = u32::from_le_bytes([framed[8], framed[9], framed[10], framed[11]]);
    if !readable(version) {
        return Err(StoreError::Version { path, found: version, expected: FORMAT_VERSION });
    }
    let mut len = [0; 8];
    len.copy_from_slice(&framed[12..20]);
    let stored = u32::from_le_bytes([framed[20], framed[21], framed[22], framed[23]]);
    let payload = &framed[24..];
    if u64::from_le_bytes(len) != payload.len() as u64 {
        return Err(corrupt("length mismatch (truncated?)"));
    }
    let mut crc = crc32fast::Hasher::new();
    crc.update(&framed[..20]);
    crc.update(payload);
    if crc.finalize() != stored {
        return Err(corrupt("bad CRC32"));
    }
    Ok(payload.to_vec())
}

/// `save.commit`: magic, format version, generation, state count, then each
/// state's name length, name, byte length and bytes; CRC32 of all that last.
pub(super) fn encode_save(generation: u64, states: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(SAVE_MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&generation.to_le_bytes());
    out.extend_from_slice(&(states.len() as u32).to_le_bytes());
    for (name, bytes) in states {
        out.extend_from_slice(&(name.len() as u32).to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Named state blobs, as `save.commit` holds them.
pub(super) type NamedStates = Vec<(String, Vec<u8>)>;

/// The generation and states of a `save.commit`, once its magic, CRC, version and lengths check out.
pub(super) fn decode_save(path: &Path, bytes: &[u8]) -> Result<(u64, NamedStates), StoreError> {
    let corrupt = |why: &str| StoreError::Corrupt { path: path.to_owned(), why: why.to_owned() };
    if bytes.len() < 28 || &bytes[..8] != SAVE_MAGIC {
        return Err(corrupt("not a snowpack save record (no SNOWSAVE magic or too short)"));
    }
    let (body, crc) = bytes.split_at(bytes.len() - 4);
    if crc32fast::hash(body).to_le_bytes() != crc {
        return Err(corrupt("bad CRC32"));
    }
    let mut at = 8;
    let mut take = |n: usize| -> Result<&[u8], StoreError> {
        let field = body.get(at..at + n).ok_or_else(|| corrupt("length mismatch"))?;
        at += n;
        Ok(field)
    };
    let u32_at = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let u64_at = |b: &[u8]| u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]);
    let version = u32_at(take(4)?);
    if !readable(version) {
        return Err(StoreError::Version { path: path.to_owned(), found: version, expected: FORMAT_VERSION });
    }
    let generation = u64_at(take(8)?);
    let count = u32_at(take(4)?);
    let mut states = Vec::new();
    for _ in 0..count {
        let name_len = u32_at(take(4)?) as usize;
        let name = String::from_utf8(take(name_len)?.to_vec()).map_err(|_| corrupt("a state name is not UTF-8"))?;
        let len = usize::try_from(u64_at(take(8)?)).map_err(|_| corrupt("length mismatch"))?;
        states.push((name, take(len)?.to_vec()));
    }
    if at != body.len() {
        return Err(corrupt("length mismatch (bytes after the last state)"));
    }
    Ok((generation, states))
}

/// The bytes of a `store.meta` for tiles of `side`² texels: magic, format
/// version, side, CRC32.
pub(super) fn meta_bytes(side: u32) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(20);
    bytes.extend_from_slice(META_MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&side.to_le_bytes());
    let crc = crc32fast::hash(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    bytes
}

/// Checks a `store.meta` and that it records tiles of `side`² texels.
pub(super) fn check_meta(path: &Path, bytes: &[u8], side: u32) -> Result<(), StoreError> {
    let found_side = meta_side(path, bytes)?;
    if found_side != side {
        return Err(StoreError::Mismatch { path: path.to_owned(), why: format!("the store holds {found_side}² tiles, {side}² were asked for") });
    }
    Ok(())
}

/// The tile side a `store.meta` records, once its magic, CRC and version check out.
pub(super) fn meta_side(path: &Path, bytes: &[u8]) -> Result<u32, StoreError> {
    let field = |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    if bytes.len() != 20 || &bytes[..8] != META_MAGIC {
        return Err(StoreError::Corrupt { path: path.to_owned(), why: "not a snowpack store description".to_owned() });
    }
    if crc32fast::hash(&bytes[..16]) != field(16) {
        return Err(StoreError::Corrupt { path: path.to_owned(), why: "bad CRC32".to_owned() });
    }
    let version = field(8);
    if !readable(version) {
        return Err(StoreError::Version { path: path.to_owned(), found: version, expected: FORMAT_VERSION });
    }
    Ok(field(12))
}
