//! The window's own state in a save: where it is and what time it is, kept
//! beside the tiles in the store (`TileStreamer::write_state`, which frames
//! it with a magic, a format version and a checksum).

use glam::DVec2;
use snowpack_share::bytes::{ByteReader, Truncated};

use crate::persist::{SnowClock, StoreError};

/// Name of the window's state in the store.
pub const STATE_NAME: &str = "window";
/// Version of the layout below.
pub const STATE_VERSION: u32 = 1;

/// Everything besides the tiles that a loaded game needs to go on.
#[derive(Clone, Debug, PartialEq)]
pub struct SavedWindow {
    /// Window texels per side.
    pub resolution: u32,
    /// Tile side (texels).
    pub tile_side: u32,
    /// Texel size (m).
    pub texel_m: f32,
    /// Rest depth (m).
    pub depth_m: f32,
    /// Footprint quantisation range (m): saved footprints mean nothing in another.
    pub stamp_range_m: [f32; 2],
    /// Global texel of the window's corner.
    pub origin: [i64; 2],
    /// The window's centre (world m).
    pub center: DVec2,
    /// The simulation clock.
    pub clock: SnowClock,
    /// Snowfall so far on open ground (m), capped as the window uses it.
    pub fallen_m: f32,
    /// Footprint refill carried below one quantum (m). Refill now follows
    /// the world clock (cumulative quanta from cumulative time), so windows
    /// save 0 and a loaded value is not used; the field keeps the format.
    pub stamp_carry_m: f32,
    /// Frames recorded.
    pub frame: u64,
}

impl SavedWindow {
    /// Little-endian bytes, version first.
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(128);
        b.extend_from_slice(&STATE_VERSION.to_le_bytes());
        b.extend_from_slice(&self.resolution.to_le_bytes());
        b.extend_from_slice(&self.tile_side.to_le_bytes());
        for v in [self.texel_m, self.depth_m, self.stamp_range_m[0], self.stamp_range_m[1]] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for v in self.origin {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for v in [self.center.x, self.center.y, self.clock.time_s, self.clock.refill_m, self.clock.fallen_m] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.clock.stamp_quanta.to_le_bytes());
        b.extend_from_slice(&self.fallen_m.to_le_bytes());
        b.extend_from_slice(&self.stamp_carry_m.to_le_bytes());
        b.extend_from_slice(&self.frame.to_le_bytes());
        b
    }

    /// Parses [`Self::encode`]'s bytes; `path` names the file in errors.
    pub fn decode(bytes: &[u8], path: &std::path::Path) -> Result<Self, StoreError> {
        let truncated = |t: Truncated| StoreError::Corrupt { path: path.to_path_buf(), why: format!("the window state is {t}") };
        let mut r = ByteReader::new(bytes);
        let version = r.u32("version").map_err(truncated)?;
        if version != STATE_VERSION {
            return Err(StoreError::Version { path: path.to_path_buf(), found: version, expected: STATE_VERSION });
        }
        Self::fields(&mut r).map_err(truncated)
    }

    /// The fields after the version, in [`Self::encode`]'s order.
    fn fields(r: &mut ByteReader<'_>) -> Result<Self, Truncated> {
        let (resolution, tile_side) = (r.u32("resolution")?, r.u32("tile side")?);
        let (texel_m, depth_m, low, high) = (r.f32("texel")?, r.f32("depth")?, r.f32("footprint low")?, r.f32("footprint high")?);
        let origin = [r.u64("origin x")? as i64, r.u64("origin z")? as i64];
        let center = DVec2::new(r.f64("centre x")?, r.f64("centre z")?);
        let clock = SnowClock { time_s: r.f64("time")?, refill_m: r.f64("refill")?, fallen_m: r.f64("fallen")?, stamp_quanta: r.u64("stamp quanta")? };
        let (fallen_m, stamp_carry_m, frame) = (r.f32("lying snow")?, r.f32("stamp carry")?, r.u64("frame")?);
        Ok(Self { resolution, tile_side, texel_m, depth_m, stamp_range_m: [low, high], origin, center, clock, fallen_m, stamp_carry_m, frame })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_truncation() {
        let s = SavedWindow {
            resolution: 256,
            tile_side: 64,
            texel_m: 0.0625,
            depth_m: 0.5,
            stamp_range_m: [-1.0, 3.5],
            origin: [1_600_000_123, -42],
            center: DVec2::new(100_000.031_25, -2.5),
            clock: SnowClock { time_s: 12.5, refill_m: 0.01, fallen_m: 0.02, stamp_quanta: 77 },
            fallen_m: 0.02,
            stamp_carry_m: 1e-6,
            frame: 750,
        };
        let path = std::path::Path::new("window.state");
        let bytes = s.encode();
        assert_eq!(SavedWindow::decode(&bytes, path).expect("decodes"), s);
        assert!(matches!(SavedWindow::decode(&bytes[..bytes.len() - 1], path), Err(StoreError::Corrupt { .. })));
        let mut other = bytes.clone();
        other[0] = 9;
        assert!(matches!(SavedWindow::decode(&other, path), Err(StoreError::Version { found: 9, .. })));
    }
}
