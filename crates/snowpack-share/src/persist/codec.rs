//! The tile file format: a fixed little-endian header, then the planes
//! delta-coded, byte-shuffled and deflated.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `SNOWTILE` |
//! | 8 | 4 | format version (u32) |
//! | 12 | 4 | side (u32) |
//! | 16 | 16 | key: col, row (i64 each) |
//! | 32 | 32 | clock: time_s, refill_m, fallen_m (f64 each), stamp_quanta (u64) |
//! | 64 | 4 | plane flags (u32): 1 snow, 2 stamps, 4 fallen, 8 packed snow |
//! | 68 | 4 | uncompressed payload length (u32) |
//! | 72 | 4 | compressed payload length (u32) |
//! | 76 | 4 | CRC32 of bytes 0..76 followed by the payload |
//! | 80 | .. | payload |
//!
//! Payload before deflate: for each present plane in flag order, its texels
//! as u32 bit patterns, each minus its left neighbour (the first texel of a
//! row minus the first texel of the row before), with wrapping arithmetic,
//! then byte-shuffled (every residual's lowest byte, then every second byte,
//! ...). Untouched snow is smooth, so the residuals are small and their high
//! bytes are runs of 0x00 or 0xff that deflate to almost nothing. Integer
//! arithmetic on the bit patterns makes the round trip exact for any f32,
//! NaN payloads and negative zero included. The packed-snow plane (u16
//! values widened to u32) came with version 2; version 1 files, which lack
//! it, still read (as fresh snow).

use crate::bytes::{ByteReader, Truncated};
use std::path::PathBuf;

use super::{MAX_SIDE, SnowClock, StoreError, TileData, TileKey};

/// The tile format version this build writes; it reads this one and
/// [`OLDEST_READ_VERSION`] onwards.
pub const FORMAT_VERSION: u32 = 2;
/// The oldest tile format version this build reads (version 1 has no
/// packed-snow plane).
pub const OLDEST_READ_VERSION: u32 = 1;

/// Whether this build reads files of format `version` (tiles and the
/// store's own records alike).
#[must_use]
pub(crate) fn readable(version: u32) -> bool {
    (OLDEST_READ_VERSION..=FORMAT_VERSION).contains(&version)
}

/// Identifies a tile file.
const MAGIC: &[u8; 8] = b"SNOWTILE";
/// Header bytes before the payload.
pub const HEADER_BYTES: usize = 80;
/// Where the CRC sits (it covers everything before it and the payload).
const CRC_AT: usize = 76;

/// Plane flag: the snow height plane is present.
const PLANE_SNOW: u32 = 1;
/// Plane flag: the stamp plane is present.
const PLANE_STAMPS: u32 = 2;
/// Plane flag: the snowfall plane is present.
const PLANE_FALLEN: u32 = 4;
/// Plane flag: the packed-snow plane is present (version 2 on).
const PLANE_PACKED: u32 = 8;

/// Deflate level: 6 is zlib's default; higher levels gain little on the
/// shuffled residuals and cost time on the worker.
pub(crate) const DEFLATE_LEVEL: u8 = 6;

/// Encodes a tile into its file bytes.
///
/// The planes are written as they are; a tile that fails
/// [`TileData::validate`] encodes into bytes that [`decode`] rejects, so the
/// store validates before it writes.
#[must_use]
pub fn encode(tile: &TileData) -> Vec<u8> {
    let mut flags = 0;
    let mut raw = Vec::with_capacity(4 * (tile.snow_xor_rest.len() + tile.stamps.len() + tile.fallen.len() + tile.packed.len()));
    let side = tile.side as usize;
    if !tile.snow_xor_rest.is_empty() {
        flags |= PLANE_SNOW;
        shuffle_into(&delta(tile.snow_xor_rest.iter().copied(), side), &mut raw);
    }
    if !tile.stamps.is_empty() {
        flags |= PLANE_STAMPS;
        shuffle_into(&delta(tile.stamps.iter().copied(), side), &mut raw);
    }
    if !tile.fallen.is_empty() {
        flags |= PLANE_FALLEN;
        shuffle_into(&delta(tile.fallen.iter().map(|v| v.to_bits()), side), &mut raw);
    }
    if !tile.packed.is_empty() {
        flags |= PLANE_PACKED;
        shuffle_into(&delta(tile.packed.iter().map(|&v| u32::from(v)), side), &mut raw);
    }
    let payload = miniz_oxide::deflate::compress_to_vec(&raw, DEFLATE_LEVEL);

    let mut out = Vec::with_capacity(HEADER_BYTES + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&tile.side.to_le_bytes());
    out.extend_from_slice(&tile.key.col.to_le_bytes());
    out.extend_from_slice(&tile.key.row.to_le_bytes());
    out.extend_from_slice(&tile.clock.time_s.to_le_bytes());
    out.extend_from_slice(&tile.clock.refill_m.to_le_bytes());
    out.extend_from_slice(&tile.clock.fallen_m.to_le_bytes());
    out.extend_from_slice(&tile.clock.stamp_quanta.to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    // Lengths fit u32: a valid tile's raw payload is at most 4 * 4 * 1024² bytes,
    // and deflate expands incompressible data by well under 1%.
    out.extend_from_slice(&(raw.len() as u32).to_le_bytes());
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    let crc = checksum(&out, &payload);
    out.extend_from_slice(&crc.to_le_bytes());
    out.extend_from_slice(&payload);
    out
}

/// Decodes a tile's file bytes. Errors name no file (the store adds it):
/// [`StoreError::Version`] for another format version, [`StoreError::Corrupt`]
/// for anything else that is wrong.
pub fn decode(bytes: &[u8]) -> Result<TileData, StoreError> {
    let corrupt = |why: String| StoreError::Corrupt { path: PathBuf::new(), why };
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err(corrupt("not a snow tile (no SNOWTILE magic)".to_owned()));
    }
    if bytes.len() < HEADER_BYTES {
        return Err(corrupt(format!("truncated: {} bytes, the header alone is {HEADER_BYTES}", bytes.len())));
    }
    // The header's length is checked above: running out here would be a bug, reported as corruption.
    let mut h = ByteReader::new(&bytes[MAGIC.len()..HEADER_BYTES]);
    let short = |t: Truncated| corrupt(t.to_string());
    let version = h.u32("format version").map_err(short)?;
    if !readable(version) {
        return Err(StoreError::Version { path: PathBuf::new(), found: version, expected: FORMAT_VERSION });
    }
    let side = h.u32("side").map_err(short)?;
    let key = TileKey { col: h.i64("column").map_err(short)?, row: h.i64("row").map_err(short)? };
    let (time_s, refill_m, fallen_m) = (h.f64("time").map_err(short)?, h.f64("refill").map_err(short)?, h.f64("fallen").map_err(short)?);
    let clock = SnowClock { time_s, refill_m, fallen_m, stamp_quanta: h.u64("stamp quanta").map_err(short)? };
    let flags = h.u32("flags").map_err(short)?;
    let raw_len = h.u32("raw length").map_err(short)? as usize;
    let packed_len = h.u32("packed length").map_err(short)? as usize;
    let crc = h.u32("checksum").map_err(short)?;

    if side == 0 || side > MAX_SIDE {
        return Err(corrupt(format!("tile side {side} is outside 1..={MAX_SIDE}")));
    }
    let payload = &bytes[HEADER_BYTES..];
    if payload.len() < packed_len {
        return Err(corrupt(format!("truncated: the payload has {} of {packed_len} bytes", payload.len())));
    }
    if payload.len() > packed_len {
        return Err(corrupt(format!("length mismatch: {} bytes follow the header, it announces {packed_len}", payload.len())));
    }
    let found = checksum(&bytes[..CRC_AT], payload);
    if found != crc {
        return Err(corrupt(format!("bad CRC32: stored {crc:#010x}, computed {found:#010x}")));
    }
    // Past the CRC the header is what the writer wrote; these checks catch a
    // writer with a bug rather than a damaged disk.
    let known = if version >= 2 { PLANE_SNOW | PLANE_STAMPS | PLANE_FALLEN | PLANE_PACKED } else { PLANE_SNOW | PLANE_STAMPS | PLANE_FALLEN };
    if flags & !known != 0 || flags & (PLANE_SNOW | PLANE_STAMPS) != PLANE_SNOW | PLANE_STAMPS {
        return Err(corrupt(format!("plane flags {flags:#x}: snow and stamps are required, fallen and (from version 2) packed snow optional, nothing else")));
    }
    let texels = side as usize * side as usize;
    let expected = 4 * texels * flags.count_ones() as usize;
    if raw_len != expected {
        return Err(corrupt(format!("length mismatch: {raw_len} payload bytes announced, {side}² tile with flags {flags:#x} has {expected}")));
    }
    // The limit bounds the allocation whatever the compressed stream claims.
    let raw = miniz_oxide::inflate::decompress_to_vec_with_limit(payload, expected).map_err(|e| corrupt(format!("the payload does not inflate: {e}")))?;
    if raw.len() != expected {
        return Err(corrupt(format!("length mismatch: the payload inflates to {} bytes, expected {expected}", raw.len())));
    }

    let side_us = side as usize;
    let mut planes = raw.chunks_exact(4 * texels).map(|plane| undelta(&unshuffle(plane), side_us));
    // The flags check above guarantees the first two planes.
    let snow_xor_rest = planes.next().unwrap_or_default();
    let stamps = planes.next().unwrap_or_default();
    let fallen = if flags & PLANE_FALLEN != 0 { planes.next().map(|p| p.into_iter().map(f32::from_bits).collect()).unwrap_or_default() } else { Vec::new() };
    let mut packed = Vec::new();
    if flags & PLANE_PACKED != 0 {
        for v in planes.next().unwrap_or_default() {
            packed.push(u16::try_from(v).map_err(|_| corrupt(format!("packed snow {v} does not fit 16 bits")))?);
        }
    }
    Ok(TileData { key, side, clock, snow_xor_rest, stamps, fallen, packed })
}

/// CRC32 of `head` followed by `payload`.
fn checksum(head: &[u8], payload: &[u8]) -> u32 {
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(head);
    hasher.update(payload);
    hasher.finalize()
}

/// Residuals of a row-major plane `side` texels wide: each texel minus its
/// left neighbour, the first of a row minus the first of the row before.
pub(crate) fn delta(values: impl Iterator<Item = u32>, side: usize) -> Vec<u32> {
    let values: Vec<u32> = values.collect();
    let side = side.max(1);
    let mut out = Vec::with_capacity(values.len());
    for (k, &v) in values.iter().enumerate() {
        let prev = if k % side != 0 {
            values[k - 1]
        } else if k >= side {
            values[k - side]
        } else {
            0
        };
        out.push(v.wrapping_sub(prev));
    }
    out
}

/// Inverse of [`delta`].
pub(crate) fn undelta(residuals: &[u32], side: usize) -> Vec<u32> {
    let side = side.max(1);
    let mut out: Vec<u32> = Vec::with_capacity(residuals.len());
    for (k, &r) in residuals.iter().enumerate() {
        let prev = if k % side != 0 {
            out[k - 1]
        } else if k >= side {
            out[k - side]
        } else {
            0
        };
        out.push(r.wrapping_add(prev));
    }
    out
}

/// Appends the residuals byte-plane by byte-plane (all lowest bytes first).
pub(crate) fn shuffle_into(residuals: &[u32], out: &mut Vec<u8>) {
    for byte in 0..4 {
        out.extend(residuals.iter().map(|r| r.to_le_bytes()[byte]));
    }
}

/// Inverse of [`shuffle_into`] for one plane.
pub(crate) fn unshuffle(bytes: &[u8]) -> Vec<u32> {
    let n = bytes.len() / 4;
    (0..n).map(|k| u32::from_le_bytes([bytes[k], bytes[n + k], bytes[2 * n + k], bytes[3 * n + k]])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{self, Rng};

    fn tile(side: u32, snow: impl Fn(usize, usize) -> f32, fallen: bool) -> TileData {
        let n = side as usize;
        let mut plane = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                plane.push(snow(i, j));
            }
        }
        TileData {
            key: TileKey::new(-3, 7),
            side,
            clock: SnowClock { time_s: 12.5, refill_m: 0.25, fallen_m: 0.125, stamp_quanta: 99 },
            snow_xor_rest: plane.iter().map(|v| v.to_bits()).collect(),
            stamps: vec![0; n * n],
            fallen: if fallen { vec![0.125; n * n] } else { Vec::new() },
            packed: Vec::new(),
        }
    }

    /// Bit patterns of every plane and clock field, so NaNs compare equal.
    #[derive(Debug, PartialEq)]
    struct Bits {
        key: TileKey,
        side: u32,
        clock: [u64; 4],
        planes: [Vec<u32>; 4],
    }

    fn bits(t: &TileData) -> Bits {
        Bits {
            key: t.key,
            side: t.side,
            clock: [t.clock.time_s.to_bits(), t.clock.refill_m.to_bits(), t.clock.fallen_m.to_bits(), t.clock.stamp_quanta],
            planes: [
                t.snow_xor_rest.clone(),
                t.stamps.clone(),
                t.fallen.iter().map(|v| v.to_bits()).collect(),
                t.packed.iter().map(|&q| u32::from(q)).collect(),
            ],
        }
    }

    /// Rewrites the CRC after a test edits the header, so a later check is reached.
    fn reseal(bytes: &mut [u8]) {
        let crc = checksum(&bytes[..CRC_AT], &bytes[HEADER_BYTES..]);
        bytes[CRC_AT..HEADER_BYTES].copy_from_slice(&crc.to_le_bytes());
    }

    fn corrupt_why(bytes: &[u8]) -> String {
        match decode(bytes) {
            Err(StoreError::Corrupt { why, path }) => {
                assert!(path.as_os_str().is_empty(), "decode names no file");
                why
            }
            other => panic!("expected Corrupt, got {other:?}"),
        }
    }

    #[test]
    fn round_trip_is_bit_exact_on_random_bits() {
        let seed = testing::seed("round_trip_is_bit_exact_on_random_bits");
        let mut rng = Rng::new(seed);
        for case in 0..24 {
            let side = [1, 2, 3, 17, 64][case % 5];
            let n = (side * side) as usize;
            let random_f32 = |rng: &mut Rng| match rng.next_u64() % 4 {
                // Quiet and signalling NaNs with random payloads and signs.
                0 => f32::from_bits(0x7f80_0000 | (rng.next_u64() as u32 & 0x807f_ffff) | 1),
                1 => rng.range(-5.0, 5.0),
                _ => f32::from_bits(rng.next_u64() as u32),
            };
            let t = TileData {
                key: TileKey::new(rng.next_u64() as i64, rng.next_u64() as i64),
                side,
                clock: SnowClock {
                    time_s: f64::from_bits(rng.next_u64()),
                    refill_m: f64::from_bits(rng.next_u64()),
                    fallen_m: f64::NAN,
                    stamp_quanta: rng.next_u64(),
                },
                snow_xor_rest: (0..n).map(|_| random_f32(&mut rng).to_bits()).collect(),
                stamps: (0..n).map(|_| rng.next_u64() as u32).collect(),
                fallen: if case % 2 == 0 { (0..n).map(|_| random_f32(&mut rng)).collect() } else { Vec::new() },
                packed: if case % 3 == 0 { Vec::new() } else { (0..n).map(|_| rng.next_u64() as u16).collect() },
            };
            let bytes = encode(&t);
            let back = decode(&bytes).unwrap_or_else(|e| panic!("seed {seed} case {case}: {e}"));
            assert!(bits(&back) == bits(&t), "seed {seed} case {case}: round trip changed the tile");
        }
    }

    #[test]
    fn special_values_round_trip() {
        let specials = [0.0, -0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, f32::MIN_POSITIVE / 2.0, f32::MAX, -f32::MAX];
        let t = tile(4, |i, j| specials[(i * 4 + j) % specials.len()], true);
        assert_eq!(bits(&decode(&encode(&t)).expect("decode")), bits(&t));
    }

    #[test]
    fn untouched_snow_compresses_to_a_few_hundred_bytes() {
        let side = 64;
        // Flat ground: every texel at the same height.
        let constant = tile(side, |_, _| 2.5, true);
        // A gentle slope: smooth, but every texel different.
        let plane = tile(side, |i, j| 100.0 + 0.01 * i as f32 + 0.02 * j as f32, true);
        // Rolling terrain (sum of sines, metres of relief) with 0.5 m of snow on it.
        let terrain = |i: usize, j: usize| {
            let (x, z) = (j as f32 * 0.0625 + 1000.0, i as f32 * 0.0625 - 300.0);
            10.0 + 3.0 * (x * 0.21).sin() * (z * 0.17).cos() + 0.7 * (x * 0.9 + z * 0.4).sin() + 0.5
        };
        let rolling = tile(side, terrain, true);
        // The same with a trail: a 0.6 m wide, 0.3 m deep rut across it, rims beside it.
        let mut trail = tile(side, terrain, true);
        for i in 0..64 {
            for j in 0..64 {
                let d = (j as f32 - 20.0 - 0.3 * i as f32).abs() * 0.0625;
                if d < 0.3 {
                    trail.snow_xor_rest[i * 64 + j] = (f32::from_bits(trail.snow_xor_rest[i * 64 + j]) - 0.3 * (1.0 - d / 0.3)).to_bits();
                    trail.stamps[i * 64 + j] = 0x1234_0000 | (i * 64 + j) as u32;
                } else if d < 0.45 {
                    trail.snow_xor_rest[i * 64 + j] = (f32::from_bits(trail.snow_xor_rest[i * 64 + j]) + 0.05).to_bits();
                }
            }
        }
        let mut sizes = Vec::new();
        for (name, t) in [("constant", &constant), ("linear slope", &plane), ("rolling terrain", &rolling), ("trail", &trail)] {
            let bytes = encode(t);
            assert_eq!(bits(&decode(&bytes).expect("decode")), bits(t), "{name}");
            eprintln!(
                "{name}: {} bytes for a 64² tile with 3 planes ({} raw, ratio {:.1})",
                bytes.len(),
                t.memory_bytes(),
                t.memory_bytes() as f64 / bytes.len() as f64
            );
            // Timing for the docs only (debug builds are slower); not asserted.
            let start = std::time::Instant::now();
            for _ in 0..10 {
                let _ = decode(&encode(t));
            }
            eprintln!("  encode + decode: {:.2} ms", start.elapsed().as_secs_f64() * 100.0);
            sizes.push(bytes.len());
        }
        assert!(sizes[0] < 300, "constant tile {} bytes", sizes[0]);
        assert!(sizes[1] < 1000, "smooth plane {} bytes", sizes[1]);
        // Rolling terrain and trails are bounded by the raw size with a good margin.
        assert!(sizes[2] < 16 * 1024, "rolling terrain {} bytes", sizes[2]);
        assert!(sizes[3] < 20 * 1024, "trail {} bytes", sizes[3]);
        // What tiles really hold: heights XOR the rest height. Untouched
        // snow over any terrain is zero; only the trail's texels are not.
        let mut real = tile(side, |_, _| 0.0, true);
        for i in 0..64 {
            for j in 0..64 {
                let d = (j as f32 - 20.0 - 0.3 * i as f32).abs() * 0.0625;
                let rest = terrain(i, j);
                let snow = if d < 0.3 {
                    rest - 0.3 * (1.0 - d / 0.3)
                } else if d < 0.45 {
                    rest + 0.05
                } else {
                    rest
                };
                real.snow_xor_rest[i * 64 + j] = snow.to_bits() ^ rest.to_bits();
            }
        }
        let untouched = encode(&tile(side, |_, _| 0.0, true)).len();
        let trail_xor = encode(&real).len();
        eprintln!("as stored (snow XOR rest): untouched {untouched} bytes, trail {trail_xor} bytes");
        assert!(untouched < 300, "untouched tile {untouched} bytes");
        assert!(trail_xor < sizes[3], "XOR against the rest must beat raw heights: {trail_xor} vs {}", sizes[3]);
    }

    #[test]
    fn decoding_rejects_damaged_bytes() {
        let good = encode(&tile(8, |i, j| (i * 8 + j) as f32 * 0.01, true));
        assert!(decode(&good).is_ok());

        let mut magic = good.clone();
        magic[0] = b'X';
        assert!(corrupt_why(&magic).contains("magic"));
        assert!(corrupt_why(b"SNOW").contains("magic"));

        let mut version = good.clone();
        version[8..12].copy_from_slice(&7u32.to_le_bytes());
        reseal(&mut version);
        match decode(&version) {
            Err(StoreError::Version { found: 7, expected: FORMAT_VERSION, .. }) => {}
            other => panic!("expected Version, got {other:?}"),
        }

        assert!(corrupt_why(&good[..40]).contains("truncated"));
        assert!(corrupt_why(&good[..good.len() - 1]).contains("truncated"));
        let mut longer = good.clone();
        longer.push(0);
        assert!(corrupt_why(&longer).contains("length mismatch"));

        let mut raw_len = good.clone();
        let announced = u32::from_le_bytes([raw_len[68], raw_len[69], raw_len[70], raw_len[71]]);
        raw_len[68..72].copy_from_slice(&(announced + 4).to_le_bytes());
        reseal(&mut raw_len);
        assert!(corrupt_why(&raw_len).contains("length mismatch"));

        for at in [HEADER_BYTES + 3, good.len() - 1, 20, CRC_AT] {
            let mut flipped = good.clone();
            flipped[at] ^= 0x10;
            assert!(corrupt_why(&flipped).contains("CRC"), "flipping byte {at}");
        }

        for side in [0u32, MAX_SIDE + 1] {
            let mut bad = good.clone();
            bad[12..16].copy_from_slice(&side.to_le_bytes());
            reseal(&mut bad);
            assert!(corrupt_why(&bad).contains("side"), "side {side}");
        }

        let mut flags = good.clone();
        flags[64..68].copy_from_slice(&PLANE_SNOW.to_le_bytes());
        reseal(&mut flags);
        assert!(corrupt_why(&flags).contains("flags"));

        // A consistent header over a payload that is not deflate.
        let mut garbage = good[..HEADER_BYTES].to_vec();
        garbage.extend_from_slice(&[0xff; 32]);
        garbage[72..76].copy_from_slice(&32u32.to_le_bytes());
        reseal(&mut garbage);
        assert!(corrupt_why(&garbage).contains("inflate"));
    }

    #[test]
    fn version_1_files_read_as_fresh_snow_and_packed_snow_is_version_2() {
        let mut t = tile(8, |i, j| (i * 8 + j) as f32 * 0.01, true);
        let mut v1 = encode(&t);
        v1[8..12].copy_from_slice(&1u32.to_le_bytes());
        reseal(&mut v1);
        assert_eq!(bits(&decode(&v1).expect("a version 1 file reads")), bits(&t));
        t.packed = (0..64).map(|k| k * 700).collect();
        let v2 = encode(&t);
        assert_eq!(bits(&decode(&v2).expect("decode")), bits(&t));
        // A version 1 file cannot hold the packed plane.
        let mut mislabelled = v2;
        mislabelled[8..12].copy_from_slice(&1u32.to_le_bytes());
        reseal(&mut mislabelled);
        assert!(corrupt_why(&mislabelled).contains("flags"));
    }

    #[test]
    fn an_inconsistent_tile_encodes_into_rejected_bytes() {
        let mut t = tile(8, |_, _| 1.0, false);
        t.snow_xor_rest.pop();
        assert!(t.validate().is_err());
        assert!(decode(&encode(&t)).is_err());
    }
}
