//! Reading the files a scene names: regular files only, and no more than a
//! limit each, so a path to `/dev/zero`, a named pipe or a device cannot make
//! a load read for ever or allocate without bound (found while writing the
//! loaders' fuzz targets, issue 34).

use std::io::Read as _;
use std::path::Path;

/// Largest scene file (bytes).
pub(crate) const MAX_SCENE_BYTES: u64 = 16 << 20;
/// Largest glTF file or external buffer (bytes): a few of the largest
/// accessors `gltf_file` accepts.
pub(crate) const MAX_GLTF_BYTES: u64 = 1 << 30;
/// Largest heightmap PNG (bytes): twice the largest heightmap's raw 16-bit
/// samples (`HEIGHTMAP_MAX_SIDE`²), for files that compress badly.
pub(crate) const MAX_HEIGHTMAP_BYTES: u64 = 4 * (snowpack::low_level::terrain::HEIGHTMAP_MAX_SIDE as u64).pow(2);
/// Largest HDR sky (bytes): the largest accepted image uncompressed (4 bytes
/// a texel), with room for its header.
pub(crate) const MAX_SKY_BYTES: u64 =
    4 * (snowpack::low_level::render::environment::ENVIRONMENT_MAX_W as u64) * snowpack::low_level::render::environment::ENVIRONMENT_MAX_H as u64 + (1 << 20);

/// The contents of `path`, if it is a regular file (symbolic links followed)
/// of at most `limit` bytes; otherwise why not, in words (the caller names
/// the file and what it is for: "cannot read x.glb: {why}").
pub(crate) fn bounded(path: &Path, limit: u64) -> Result<Vec<u8>, String> {
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if !meta.is_file() {
        return Err("it is not a regular file (a folder, a device or a pipe)".into());
    }
    if meta.len() > limit {
        return Err(format!("it is {} bytes; at most {limit} are read", meta.len()));
    }
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    // The length can change between the look and the read: never more than the limit.
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| e.to_string())?;
    if bytes.len() as u64 > limit {
        return Err(format!("it grew past {limit} bytes while it was read"));
    }
    Ok(bytes)
}
