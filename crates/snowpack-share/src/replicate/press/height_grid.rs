//! A heightmap as every machine samples it ([`HeightGrid`]): the window's
//! CPU twins (snowpack's `HeightmapTerrain` shares one), the presses over a
//! heightmap ([`super::ground::PressGround::Heightmap`]), the world
//! identity that holds one, and the relay's store, which keeps its bytes.

/// Largest side of a [`HeightGrid`] (samples): wgpu's default texture limit.
pub const HEIGHT_GRID_MAX_SIDE: u32 = 8192;

/// A heightmap as every machine samples it: `width × height` heights
/// (row `r` at larger world z than row `r - 1`) covering `size_m` (x, z)
/// metres centred on `center_m`, sampled bilinearly between sample centres
/// and clamped at the edges ([`HeightGrid::height_at`], the twin of
/// `heightmap_at` in `shared/terrain.wgsl`). Checked when made, so
/// sampling never fails; its digest is computed once.
#[derive(Clone, PartialEq)]
pub struct HeightGrid {
    width: u32,
    height: u32,
    heights_m: Vec<f32>,
    center_m: [f32; 2],
    size_m: [f32; 2],
    /// `1 / size_m`, rounded once: the sampling multiplies by it, as the
    /// shader does (a GPU's division may round otherwise).
    per_size_m: [f32; 2],
    digest: u64,
}

impl std::fmt::Debug for HeightGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeightGrid")
            .field("samples", &(self.width, self.height))
            .field("center_m", &self.center_m)
            .field("size_m", &self.size_m)
            .field("digest", &format_args!("{:016x}", self.digest))
            .finish()
    }
}

/// A [`HeightGrid`] that cannot be made: which of its inputs (`heightmap`,
/// `heightmap size_m`, `heightmap center_m`) and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("invalid {field}: {why}")]
pub struct HeightGridError {
    /// The input at fault, as a scene names it.
    pub field: &'static str,
    /// Why it is refused.
    pub why: String,
}

impl HeightGrid {
    /// A grid of `width × height` samples, `heights_m` row-major. Refused,
    /// naming what is wrong: a zero side or one above
    /// [`HEIGHT_GRID_MAX_SIDE`], a sample count other than `width ×
    /// height`, a height that is not finite, a size that is not positive
    /// and finite (or whose inverse is not), a centre that is not finite.
    pub fn new(width: u32, height: u32, heights_m: Vec<f32>, center_m: [f32; 2], size_m: [f32; 2]) -> Result<Self, HeightGridError> {
        let bad = |field: &'static str, why: String| Err(HeightGridError { field, why });
        if width == 0 || height == 0 {
            return bad("heightmap", format!("{width}x{height} pixels: both sides must be at least 1"));
        }
        if width > HEIGHT_GRID_MAX_SIDE || height > HEIGHT_GRID_MAX_SIDE {
            return bad("heightmap", format!("{width}x{height} pixels: at most {HEIGHT_GRID_MAX_SIDE} on a side are supported"));
        }
        let count = u64::from(width) * u64::from(height);
        if heights_m.len() as u64 != count {
            return bad("heightmap", format!("{} heights for {width}x{height} pixels (needs {count})", heights_m.len()));
        }
        if let Some(k) = heights_m.iter().position(|h| !h.is_finite()) {
            return bad("heightmap", format!("height {} at pixel {k} is not a finite number of metres", heights_m[k]));
        }
        let per_size_m = size_m.map(|s| 1.0 / s);
        if !size_m.iter().chain(&per_size_m).all(|s| s.is_finite() && *s > 0.0) {
            return bad("heightmap size_m", format!("{size_m:?} must be two positive, finite sizes in metres"));
        }
        if !center_m.iter().all(|c| c.is_finite()) {
            return bad("heightmap center_m", format!("{center_m:?} must be finite"));
        }
        let digest = digest([width, height, center_m[0].to_bits(), center_m[1].to_bits(), size_m[0].to_bits(), size_m[1].to_bits()], &heights_m);
        Ok(Self { width, height, heights_m, center_m, size_m, per_size_m, digest })
    }

    /// Samples per row.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Heights (m), row-major, `width × height` of them.
    #[must_use]
    pub fn heights_m(&self) -> &[f32] {
        &self.heights_m
    }

    /// World (x, z) of the covered area's centre (m).
    #[must_use]
    pub fn center_m(&self) -> [f32; 2] {
        self.center_m
    }

    /// World size (x, z) of the covered area (m).
    #[must_use]
    pub fn size_m(&self) -> [f32; 2] {
        self.size_m
    }

    /// `1 / size_m`, as the sampling and the shader's uniforms use it.
    #[must_use]
    pub fn per_size_m(&self) -> [f32; 2] {
        self.per_size_m
    }

    /// An FNV-1a digest of the size, placement and heights (their bits):
    /// two machines with the same heightmap agree on it, and the world's
    /// identity names the terrain by it ([`Self::terrain_identity`]).
    #[must_use]
    pub fn digest(&self) -> u64 {
        self.digest
    }

    /// The terrain as a world's identity names it: `"heightmap D"`, the
    /// digest in 16 hex digits.
    #[must_use]
    pub fn terrain_identity(&self) -> String {
        format!("heightmap {:016x}", self.digest)
    }

    /// Lowest and highest sample (m).
    #[must_use]
    pub fn height_range(&self) -> (f32, f32) {
        self.heights_m.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &h| (lo.min(h), hi.max(h)))
    }

    /// Bilinear height (m) at world (x, z), clamped to the edge samples
    /// outside the covered area: `heightmap_at` in `shared/terrain.wgsl`,
    /// the same operations in the same order, with no division.
    #[must_use]
    pub fn height_at(&self, x: f32, z: f32) -> f32 {
        let (w, h) = (self.width as i32, self.height as i32);
        // Continuous sample coordinates with sample centres at integer + 0.5.
        let u = ((x - self.center_m[0]) * self.per_size_m[0] + 0.5) * self.width as f32 - 0.5;
        let v = ((z - self.center_m[1]) * self.per_size_m[1] + 0.5) * self.height as f32 - 0.5;
        let u = u.clamp(0.0, (w - 1) as f32);
        let v = v.clamp(0.0, (h - 1) as f32);
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let (i0, j0) = (v0 as i32, u0 as i32);
        let (i1, j1) = ((i0 + 1).min(h - 1), (j0 + 1).min(w - 1));
        let at = |i: i32, j: i32| self.heights_m[(i * w + j) as usize];
        let (a, b, c, d) = (at(i0, j0), at(i0, j1), at(i1, j0), at(i1, j1));
        let ab = a + (b - a) * fu;
        let cd = c + (d - c) * fu;
        ab + (cd - ab) * fv
    }

    /// The grid as bytes, little-endian: `SNHG`, format 1 (u32), width and
    /// height (u32), centre and size (2 × f32 each), then the heights
    /// (f32, row-major). What a relay keeps in its store, so a server that
    /// cannot load the scene's heightmap (the server-only build) presses
    /// over it too.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(GRID_HEADER_BYTES + 4 * self.heights_m.len());
        out.extend_from_slice(GRID_MAGIC);
        for w in [GRID_FORMAT, self.width, self.height] {
            out.extend_from_slice(&w.to_le_bytes());
        }
        for v in self.center_m.iter().chain(&self.size_m).chain(&self.heights_m) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// A grid from [`Self::to_bytes`]'s bytes, checked as [`Self::new`]
    /// checks one; anything else is refused, saying why (field
    /// `"heightmap bytes"` for what is not such bytes at all).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, HeightGridError> {
        let bad = |why: String| HeightGridError { field: "heightmap bytes", why };
        let word = |k: usize| u32::from_le_bytes([bytes[4 * k], bytes[4 * k + 1], bytes[4 * k + 2], bytes[4 * k + 3]]);
        if bytes.len() < GRID_HEADER_BYTES || &bytes[..4] != GRID_MAGIC {
            return Err(bad(format!("{} bytes that do not start a heightmap", bytes.len())));
        }
        if word(1) != GRID_FORMAT {
            return Err(bad(format!("format {}; this build reads format {GRID_FORMAT}", word(1))));
        }
        let (width, height) = (word(2), word(3));
        let count = u64::from(width) * u64::from(height);
        let len = (bytes.len() - GRID_HEADER_BYTES) as u64;
        if len != 4 * count {
            return Err(bad(format!("{len} bytes of heights for {width}x{height} samples (needs {})", 4 * count)));
        }
        let float = |k: usize| f32::from_bits(word(k));
        let heights_m = (0..count as usize).map(|k| float(GRID_HEADER_BYTES / 4 + k)).collect();
        Self::new(width, height, heights_m, [float(4), float(5)], [float(6), float(7)])
    }
}

/// Identifies a [`HeightGrid`] as bytes ([`HeightGrid::to_bytes`]).
const GRID_MAGIC: &[u8; 4] = b"SNHG";
/// The format of [`HeightGrid::to_bytes`].
const GRID_FORMAT: u32 = 1;
/// Bytes before the heights: magic, format, sides, centre, size.
const GRID_HEADER_BYTES: usize = 4 + 4 + 8 + 16;

/// FNV-1a over `header`'s words and then `heights`' bits, each little-endian.
fn digest(header: [u32; 6], heights: &[f32]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for w in header.into_iter().chain(heights.iter().map(|v| v.to_bits())) {
        for b in w.to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}
