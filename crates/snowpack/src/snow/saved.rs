//! The window's own state in a save: where it is and what time it is, kept
//! beside the tiles in the store (`TileStreamer::write_state`, which frames
//! it with a magic, a format version and a checksum).

use glam::DVec2;

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
        let mut r = Reader { bytes, at: 0, path };
        let version = r.u32()?;
        if version != STATE_VERSION {
            return Err(StoreError::Version { path: path.to_path_buf(), found: version, expected: STATE_VERSION });
        }
        let (resolution, tile_side) = (r.u32()?, r.u32()?);
        let (texel_m, depth_m, low, high) = (r.f32()?, r.f32()?, r.f32()?, r.f32()?);
        let origin = [r.u64()? as i64, r.u64()? as i64];
        let center = DVec2::new(r.f64()?, r.f64()?);
        let clock = SnowClock { time_s: r.f64()?, refill_m: r.f64()?, fallen_m: r.f64()?, stamp_quanta: r.u64()? };
        let (fallen_m, stamp_carry_m, frame) = (r.f32()?, r.f32()?, r.u64()?);
        Ok(Self { resolution, tile_side, texel_m, depth_m, stamp_range_m: [low, high], origin, center, clock, fallen_m, stamp_carry_m, frame })
    }
}

/// Little-endian fields in order, with a clear error at the end of the bytes.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a std::path::Path,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], StoreError> {
        let s = self
            .bytes
            .get(self.at..self.at + N)
            .ok_or_else(|| StoreError::Corrupt { path: self.path.to_path_buf(), why: "the window state is truncated".to_owned() })?;
        self.at += N;
        let mut out = [0u8; N];
        out.copy_from_slice(s);
        Ok(out)
    }

    fn u32(&mut self) -> Result<u32, StoreError> {
        Ok(u32::from_le_bytes(self.take()?))
    }

    fn f32(&mut self) -> Result<f32, StoreError> {
        Ok(f32::from_le_bytes(self.take()?))
    }

    fn u64(&mut self) -> Result<u64, StoreError> {
        Ok(u64::from_le_bytes(self.take()?))
    }

    fn f64(&mut self) -> Result<f64, StoreError> {
        Ok(f64::from_le_bytes(self.take()?))
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
