//! The detail volume for shell mapping: a tileable 3D texture of what pokes
//! up through the snow surface (dry grass and twigs, or an ice crust with
//! surface hoar), made once on the CPU with a box-filtered mip chain and, per
//! level, a distance field for skipping empty space.
//!
//! Axes: x and y are horizontal and periodic (the texture tiles), z is up from
//! the snow surface (z = 0) to the top of the shell. Storage order everywhere:
//! x fastest, then y, then z.
//!
//! Features are laid out in continuous tile units (x, y in [0, 1), z in
//! [0, [`SHELL_HEIGHT`]], i.e. normalised height times the shell's aspect) from a
//! seeded generator that never looks at the resolution, then voxelised with
//! distance-based anti-aliasing: every size shows the same features.

use std::f32::consts::TAU;

use glam::{Quat, Vec3};

/// Height of the shell in tile units: the volume is `size` x `size` x `size / 2`
/// voxels of cubic shape, so it is half as tall as it is wide.
pub const SHELL_HEIGHT: f32 = 0.5;

/// One level-0 voxel at size 64, in tile units: the scale the content is designed at.
const V: f32 = 1.0 / 64.0;
const H: f32 = SHELL_HEIGHT;

/// What grows in the shell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DetailKind {
    /// Dry grass tufts and a few twigs poking up through shallow snow, with snow clumps at their feet.
    #[default]
    Grass,
    /// An ice crust of small grains and needles of surface hoar.
    Crust,
}

impl DetailKind {
    /// Parses "grass" / "crust" (for scenes); None otherwise.
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "grass" => Some(Self::Grass),
            "crust" => Some(Self::Crust),
            _ => None,
        }
    }

    /// The name as written in scenes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Grass => "grass",
            Self::Crust => "crust",
        }
    }

    /// Salt mixed into the seed so both kinds differ for the same seed.
    fn salt(self) -> u64 {
        match self {
            Self::Grass => 0x6772_6173_7300_0001,
            Self::Crust => 0x6372_7573_7400_0002,
        }
    }
}

/// One mip level of a detail volume.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeLevel {
    /// Voxels along x, y, z.
    pub size: [u32; 3],
    /// Per voxel: linear albedo (rgb, 0..255) and coverage (a, 0..255). Colour is NOT premultiplied.
    pub rgba: Vec<[u8; 4]>,
    /// Per voxel: Euclidean distance, in voxels of level 0 (this level's voxel
    /// distance times 2^level), from this voxel's centre to the centre of the
    /// nearest voxel of this level with coverage > 0; 0 for voxels with
    /// coverage > 0. Periodic in x and y, not in z. Capped at 255.0.
    pub sdf: Vec<f32>,
}

impl VolumeLevel {
    /// Wraps `rgba` of level `index` and computes its distance field.
    fn new(size: [u32; 3], rgba: Vec<[u8; 4]>, index: u32) -> Self {
        let scale = (1u64 << index) as f32;
        let occupied: Vec<bool> = rgba.iter().map(|v| v[3] > 0).collect();
        // Cap in this level's units so that, scaled, it lands exactly on 255.
        let mut sdf = distance_transform(size, &occupied, 255.0 / scale);
        for d in &mut sdf {
            *d *= scale;
        }
        Self { size, rgba, sdf }
    }

    /// Voxel count.
    fn voxels(&self) -> u64 {
        self.size.iter().map(|&s| u64::from(s)).product()
    }
}

/// A detail volume and its mip chain.
#[derive(Clone, Debug, PartialEq)]
pub struct DetailVolume {
    /// Its kind.
    pub kind: DetailKind,
    /// Level 0 first; each next level halves every axis (never below 1), down to 1x1x1 inclusive.
    pub levels: Vec<VolumeLevel>,
}

impl DetailVolume {
    /// Generates a volume of `size` x `size` x `size / 2` voxels (`size` a power
    /// of two in 8..=512), deterministic for (kind, size, seed), with its whole
    /// mip chain. Sizes differ only in resolution: the features are laid out in
    /// continuous coordinates and then voxelised.
    ///
    /// # Errors
    /// If `size` is not a power of two in 8..=512.
    pub fn generate(kind: DetailKind, size: u32, seed: u64) -> Result<Self, crate::error::SnowError> {
        if !size.is_power_of_two() || !(8..=512).contains(&size) {
            return Err(crate::error::SnowError::InvalidParameter {
                field: "texture_size",
                why: format!("detail volume size {size} is not a power of two in 8..=512"),
            });
        }
        let mut rng = Rng(seed ^ kind.salt());
        let mut grid = Grid::new(size);
        let prims = match kind {
            DetailKind::Grass => grass(&mut rng),
            DetailKind::Crust => {
                let ice = Ice { seed: rng.next_u64() };
                grid.ice(&ice);
                crust(&mut rng, &ice)
            }
        };
        for prim in &prims {
            grid.splat(prim);
        }
        let mut levels = vec![VolumeLevel::new(grid.size(), grid.rgba, 0)];
        while let Some(last) = levels.last().filter(|l| l.size != [1, 1, 1]) {
            let next = downsample(last, levels.len() as u32 - 1);
            levels.push(next);
        }
        Ok(Self { kind, levels })
    }

    /// Level 0's size.
    #[must_use]
    pub fn size(&self) -> [u32; 3] {
        self.levels[0].size
    }

    /// Bytes of all levels as uploaded (4 bytes rgba + 2 bytes sdf per voxel).
    #[must_use]
    pub fn gpu_bytes(&self) -> u64 {
        self.levels.iter().map(|l| l.voxels() * 6).sum()
    }
}

/// The next mip level of `level` (which is level `index`): each output voxel
/// averages its 2x2x2 children (fewer along an axis already 1 voxel long).
/// Coverage is the mean coverage, so it becomes opacity; colour is the
/// coverage-weighted mean colour (0 where no child is covered). Rounds to
/// nearest. The new level's distance field comes from its own coverage, in
/// level-0 voxels.
#[must_use]
pub fn downsample(level: &VolumeLevel, index: u32) -> VolumeLevel {
    let [sx, sy, _] = level.size.map(|s| s as usize);
    let next = level.size.map(|s| (s / 2).max(1));
    let [nx, ny, nz] = next.map(|s| s as usize);
    let kids = level.size.map(|s| if s > 1 { 2usize } else { 1 });
    let mut rgba = Vec::with_capacity(nx * ny * nz);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let (mut a, mut c, mut n) = (0u32, [0u32; 3], 0u32);
                for dz in 0..kids[2] {
                    for dy in 0..kids[1] {
                        for dx in 0..kids[0] {
                            let v = level.rgba[((z * kids[2] + dz) * sy + y * kids[1] + dy) * sx + x * kids[0] + dx];
                            let va = u32::from(v[3]);
                            a += va;
                            for i in 0..3 {
                                c[i] += va * u32::from(v[i]);
                            }
                            n += 1;
                        }
                    }
                }
                // No covered child: no colour.
                let colour = c.map(|ci| (ci + a / 2).checked_div(a).unwrap_or(0) as u8);
                rgba.push([colour[0], colour[1], colour[2], ((a + n / 2) / n) as u8]);
            }
        }
    }
    VolumeLevel::new(next, rgba, index + 1)
}

/// Exact Euclidean distance transform: for a grid of `size` with `occupied`
/// flags (x fastest, then y, then z), the distance in voxels from each voxel
/// centre to the nearest occupied voxel centre, periodic in x and y, not in z,
/// capped at `cap` (also where nothing is occupied).
///
/// Separable Felzenszwalb–Huttenlocher: squared distances, one 1D lower
/// envelope of parabolas per line and axis; periodic lines run over three
/// copies of themselves, which is exact since the nearest image of any site is
/// within half a period.
///
/// # Panics
/// If `occupied` does not hold one flag per voxel.
#[must_use]
pub fn distance_transform(size: [u32; 3], occupied: &[bool], cap: f32) -> Vec<f32> {
    let [sx, sy, sz] = size.map(|s| s as usize);
    assert_eq!(occupied.len(), sx * sy * sz, "one occupancy flag per voxel");
    let mut d2: Vec<f32> = occupied.iter().map(|&o| if o { 0.0 } else { f32::INFINITY }).collect();
    let mut env = Envelope::default();
    let longest = sx.max(sy).max(sz);
    let (mut line, mut out) = (vec![0.0f32; longest], vec![0.0f32; longest]);
    // Along x: rows are contiguous.
    for row in d2.chunks_exact_mut(sx) {
        line[..sx].copy_from_slice(row);
        env.transform(&line[..sx], true, row);
    }
    // Along y: stride sx within each z slice.
    for z in 0..sz {
        for x in 0..sx {
            let at = |y: usize| (z * sy + y) * sx + x;
            for y in 0..sy {
                line[y] = d2[at(y)];
            }
            env.transform(&line[..sy], true, &mut out[..sy]);
            for y in 0..sy {
                d2[at(y)] = out[y];
            }
        }
    }
    // Along z: stride sx * sy, no wrap (space above and below is empty).
    let slice = sx * sy;
    for i in 0..slice {
        for z in 0..sz {
            line[z] = d2[z * slice + i];
        }
        env.transform(&line[..sz], false, &mut out[..sz]);
        for z in 0..sz {
            d2[z * slice + i] = out[z];
        }
    }
    for d in &mut d2 {
        *d = d.sqrt().min(cap);
    }
    d2
}

/// Scratch for the 1D lower envelope of parabolas `(q - p)^2 + f(p)`.
#[derive(Default)]
struct Envelope {
    /// Parabola apexes (site positions).
    site: Vec<f64>,
    /// Their heights f(p).
    height: Vec<f64>,
    /// Left end of each parabola's stretch of the envelope.
    from: Vec<f64>,
}

impl Envelope {
    /// Squared distance transform of `f` (infinite where there is no site) into `out`.
    fn transform(&mut self, f: &[f32], periodic: bool, out: &mut [f32]) {
        let n = f.len();
        let (copies, first) = if periodic { (3, n) } else { (1, 0) };
        self.site.clear();
        self.height.clear();
        self.from.clear();
        for k in 0..copies * n {
            let fk = f[k % n];
            if !fk.is_finite() {
                continue;
            }
            let (q, fq) = (k as f64, f64::from(fk));
            let mut s = f64::NEG_INFINITY;
            while let (Some(&p), Some(&fp), Some(&start)) = (self.site.last(), self.height.last(), self.from.last()) {
                s = ((fq + q * q) - (fp + p * p)) / (2.0 * (q - p));
                // The first parabola starts at -inf, so it is never popped.
                if s > start {
                    break;
                }
                self.site.pop();
                self.height.pop();
                self.from.pop();
                s = f64::NEG_INFINITY;
            }
            self.site.push(q);
            self.height.push(fq);
            self.from.push(s);
        }
        if self.site.is_empty() {
            out.fill(f32::INFINITY);
            return;
        }
        let mut k = 0;
        for (i, o) in out.iter_mut().enumerate() {
            let q = (first + i) as f64;
            while k + 1 < self.site.len() && self.from[k + 1] < q {
                k += 1;
            }
            let d = q - self.site[k];
            *o = (d * d + self.height[k]) as f32;
        }
    }
}

/// splitmix64: small, fast, and good enough for placing grass.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.0)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform in lo..=hi.
    fn int(&mut self, lo: u32, hi: u32) -> u32 {
        lo + (self.next_u64() % u64::from(hi - lo + 1)) as u32
    }

    /// Random unit vector.
    fn direction(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let a = self.range(0.0, TAU);
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * a.cos(), r * a.sin(), z)
    }
}

/// The splitmix64 finaliser.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Value noise on a lattice that wraps every `period` cells, in [0, 1].
fn periodic_noise(x: f32, y: f32, period: i32, seed: u64) -> f32 {
    let (fx, fy) = (x.floor(), y.floor());
    let fade = |t: f32| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (sx, sy) = (fade(x - fx), fade(y - fy));
    let (ix, iy) = (fx as i32, fy as i32);
    let v = |i: i32, j: i32| {
        let (i, j) = (u64::from(i.rem_euclid(period) as u32), u64::from(j.rem_euclid(period) as u32));
        (mix64(seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ j.wrapping_mul(0xC2B2_AE3D_27D4_EB4F)) >> 40) as f32 / (1u64 << 24) as f32
    };
    let (a, b, c, d) = (v(ix, iy), v(ix + 1, iy), v(ix, iy + 1), v(ix + 1, iy + 1));
    let ab = a + (b - a) * sx;
    let cd = c + (d - c) * sx;
    ab + (cd - ab) * sy
}

/// Tileable fractal noise over the tile (x, y in tile units), in [0, 1].
fn fbm(x: f32, y: f32, seed: u64) -> f32 {
    let (mut sum, mut norm, mut amp) = (0.0, 0.0, 1.0);
    for (i, cells) in [3, 6, 12, 24, 48].into_iter().enumerate() {
        sum += amp * periodic_noise(x * cells as f32, y * cells as f32, cells, seed.wrapping_add(i as u64));
        norm += amp;
        amp *= 0.55;
    }
    sum / norm
}

/// Tile-periodic horizontal distance between two points.
fn periodic_distance(a: Vec3, b: Vec3) -> f32 {
    let wrap = |d: f32| d - d.round();
    wrap(a.x - b.x).hypot(wrap(a.y - b.y))
}

/// Shapes the content is made of, in tile units.
enum Shape {
    /// A segment whose radius varies linearly from `ra` at `a` to `rb` at `b`
    /// (a round cone, with the distance approximated by the nearest point on the axis).
    Cone { a: Vec3, b: Vec3, ra: f32, rb: f32 },
    /// An axis-aligned ellipsoid.
    Ellipsoid { centre: Vec3, radii: Vec3 },
}

/// A shape and its colour (linear albedo; along a cone, from `a` to `b`).
struct Prim {
    shape: Shape,
    colour: [Vec3; 2],
}

impl Prim {
    fn cone(a: Vec3, b: Vec3, ra: f32, rb: f32, ca: Vec3, cb: Vec3) -> Self {
        Self { shape: Shape::Cone { a, b, ra, rb }, colour: [ca, cb] }
    }

    fn ellipsoid(centre: Vec3, radii: Vec3, colour: Vec3) -> Self {
        Self { shape: Shape::Ellipsoid { centre, radii }, colour: [colour; 2] }
    }

    /// Axis-aligned bounds in tile units.
    fn bounds(&self) -> (Vec3, Vec3) {
        match self.shape {
            Shape::Cone { a, b, ra, rb } => {
                let r = Vec3::splat(ra.max(rb));
                (a.min(b) - r, a.max(b) + r)
            }
            Shape::Ellipsoid { centre, radii } => (centre - radii, centre + radii),
        }
    }

    /// Coverage (0..1) and colour at `p` for voxels of `voxel` tile units.
    fn eval(&self, p: Vec3, voxel: f32) -> (f32, Vec3) {
        match self.shape {
            Shape::Cone { a, b, ra, rb } => {
                let ba = b - a;
                let t = ((p - a).dot(ba) / ba.length_squared().max(1e-12)).clamp(0.0, 1.0);
                let r = ra + (rb - ra) * t;
                let d = ((p - (a + ba * t)).length() - r) / voxel;
                // Features thinner than a voxel fade rather than fill whole voxels.
                let thin = (2.0 * r / voxel).min(1.0);
                ((0.5 - d).clamp(0.0, 1.0) * thin, self.colour[0].lerp(self.colour[1], t))
            }
            Shape::Ellipsoid { centre, radii } => {
                let q = p - centre;
                let k0 = (q / radii).length();
                let k1 = (q / (radii * radii)).length();
                // Inigo Quilez's bound: good near the surface, which is all that matters here.
                let d = if k1 > 1e-12 { k0 * (k0 - 1.0) / k1 } else { -radii.min_element() };
                ((0.5 - d / voxel).clamp(0.0, 1.0), self.colour[0])
            }
        }
    }
}

/// Level 0 being voxelised: each voxel keeps the colour of the feature covering it most.
struct Grid {
    n: usize,
    depth: usize,
    rgba: Vec<[u8; 4]>,
}

impl Grid {
    fn new(size: u32) -> Self {
        let (n, depth) = (size as usize, (size / 2) as usize);
        Self { n, depth, rgba: vec![[0; 4]; n * n * depth] }
    }

    fn size(&self) -> [u32; 3] {
        [self.n as u32, self.n as u32, self.depth as u32]
    }

    /// Keeps (coverage, colour) at voxel (x, y, z) if it covers more than what is there.
    fn put(&mut self, x: usize, y: usize, z: usize, coverage: f32, colour: Vec3) {
        let a = (coverage * 255.0).round() as u8;
        let v = &mut self.rgba[(z * self.n + y) * self.n + x];
        if a > v[3] {
            let c = (colour.clamp(Vec3::ZERO, Vec3::ONE) * 255.0).round();
            *v = [c.x as u8, c.y as u8, c.z as u8, a];
        }
    }

    /// Voxelises one primitive over its bounding box only, wrapping in x and y.
    fn splat(&mut self, prim: &Prim) {
        let (lo, hi) = prim.bounds();
        let n = self.n as f32;
        let voxel = 1.0 / n;
        // Voxel i's centre is at (i + 0.5) / n; a voxel of margin covers the anti-aliased edge.
        let span = |lo: f32, hi: f32| ((lo * n - 1.5).floor() as i64, (hi * n + 0.5).ceil() as i64);
        let (x0, x1) = span(lo.x, hi.x);
        let (y0, y1) = span(lo.y, hi.y);
        let (z0, z1) = span(lo.z, hi.z);
        let (x1, y1) = (x1.min(x0 + self.n as i64 - 1), y1.min(y0 + self.n as i64 - 1));
        let (z0, z1) = (z0.max(0), z1.min(self.depth as i64 - 1));
        let period = self.n as i64;
        let wrap = |i: i64| i.rem_euclid(period) as usize;
        for z in z0..=z1 {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    // Evaluated at the unwrapped position, so the feature continues across the edge.
                    let p = (Vec3::new(x as f32, y as f32, z as f32) + 0.5) * voxel;
                    let (coverage, colour) = prim.eval(p, voxel);
                    if coverage > 0.0 {
                        self.put(wrap(x), wrap(y), z as usize, coverage, colour);
                    }
                }
            }
        }
    }

    /// Voxelises the crust's ice layer, column by column.
    fn ice(&mut self, ice: &Ice) {
        let n = self.n as f32;
        let (voxel, e) = (1.0 / n, 0.5 / n);
        for y in 0..self.n {
            for x in 0..self.n {
                let (px, py) = ((x as f32 + 0.5) * voxel, (y as f32 + 0.5) * voxel);
                let h = ice.height(px, py);
                let gx = (ice.height(px + e, py) - ice.height(px - e, py)) / (2.0 * e);
                let gy = (ice.height(px, py + e) - ice.height(px, py - e)) / (2.0 * e);
                // Vertical distance to a sloped surface overstates the true one by the slope's secant.
                let cos = 1.0 / (1.0 + gx * gx + gy * gy).sqrt();
                let tint = periodic_noise(px * 20.0, py * 20.0, 20, ice.seed ^ 0x1CE);
                let top = ((h * n + 0.5).ceil() as usize).min(self.depth - 1);
                for z in 0..=top {
                    let zc = (z as f32 + 0.5) * voxel;
                    let coverage = (0.5 - (zc - h) / voxel * cos).clamp(0.0, 1.0);
                    // Bluer and a touch darker deeper in the ice, whiter at the rime on top.
                    let below = ((h - zc) / (4.0 * V)).clamp(0.0, 1.0);
                    let colour = ICE_TOP.lerp(ICE_DEEP, below * (0.6 + 0.4 * tint));
                    if coverage > 0.0 {
                        self.put(x, y, z, coverage, colour);
                    }
                }
            }
        }
    }
}

const STRAW_LIGHT: Vec3 = Vec3::new(0.45, 0.36, 0.18);
const STRAW_DARK: Vec3 = Vec3::new(0.30, 0.25, 0.12);
const WEATHERED: Vec3 = Vec3::new(0.30, 0.29, 0.26);
const TWIG: Vec3 = Vec3::new(0.12, 0.08, 0.05);
const SNOW: Vec3 = Vec3::new(0.85, 0.88, 0.92);
const ICE_TOP: Vec3 = Vec3::new(0.84, 0.89, 0.96);
const ICE_DEEP: Vec3 = Vec3::new(0.72, 0.80, 0.92);
const GRAIN: Vec3 = Vec3::new(0.87, 0.91, 0.96);
const HOAR: Vec3 = Vec3::new(0.93, 0.95, 0.98);

/// `count` points over the tile, kept `spacing` apart (periodically) where the tries allow.
fn scatter(rng: &mut Rng, count: u32, spacing: f32) -> Vec<Vec3> {
    let mut points: Vec<Vec3> = Vec::new();
    for _ in 0..count {
        let mut p = Vec3::ZERO;
        for _ in 0..40 {
            p = Vec3::new(rng.unit(), rng.unit(), 0.0);
            if points.iter().all(|&q| periodic_distance(p, q) >= spacing) {
                break;
            }
        }
        points.push(p);
    }
    points
}

/// A lumpy snow clump: an ellipsoid and a smaller lobe beside it.
fn clump(prims: &mut Vec<Prim>, rng: &mut Rng, centre: Vec3, radii: Vec3) {
    let white = (SNOW * rng.range(0.97, 1.03)).min(Vec3::ONE);
    prims.push(Prim::ellipsoid(centre, radii, white));
    let a = rng.range(0.0, TAU);
    let offset = Vec3::new(a.cos() * radii.x, a.sin() * radii.y, rng.range(-0.2, 0.3) * radii.z) * 0.65;
    prims.push(Prim::ellipsoid(centre + offset, radii * rng.range(0.5, 0.75), white));
}

/// Dry grass tufts and twigs with snow at their feet.
fn grass(rng: &mut Rng) -> Vec<Prim> {
    let mut prims = Vec::new();
    let tufts = rng.int(8, 14);
    for foot in scatter(rng, tufts, 0.14) {
        let mut tone = STRAW_LIGHT.lerp(STRAW_DARK, rng.unit());
        if rng.unit() < 0.35 {
            tone = tone.lerp(WEATHERED, rng.range(0.4, 0.8));
        }
        let blades = rng.int(5, 12);
        let phase = rng.range(0.0, TAU);
        // The whole tuft leans a little one way (wind, snow load), so tufts are not stars.
        let a = rng.range(0.0, TAU);
        let lean = Vec3::new(a.cos(), a.sin(), 0.0) * rng.range(0.0, 0.35);
        for i in 0..blades {
            let az = phase + TAU * i as f32 / blades as f32 + rng.range(-0.5, 0.5);
            let colour = (tone * rng.range(0.85, 1.12)).min(Vec3::ONE);
            blade(&mut prims, rng, foot, az, lean, colour);
        }
        for _ in 0..rng.int(5, 7) {
            let a = rng.range(0.0, TAU);
            let centre = foot + Vec3::new(a.cos(), a.sin(), 0.0) * rng.range(0.5, 4.5) * V + Vec3::Z * rng.range(-1.0, 1.2) * V;
            let radii = Vec3::new(rng.range(2.5, 5.0), rng.range(2.5, 5.0), rng.range(1.5, 3.0)) * V;
            clump(&mut prims, rng, centre, radii);
        }
    }
    // A few loose lumps on the open snow between tufts.
    for _ in 0..rng.int(6, 10) {
        let centre = Vec3::new(rng.unit(), rng.unit(), rng.range(-1.5, 0.5) * V);
        let radii = Vec3::new(rng.range(2.0, 4.5), rng.range(2.0, 4.5), rng.range(1.5, 2.5)) * V;
        clump(&mut prims, rng, centre, radii);
    }
    for _ in 0..rng.int(2, 3) {
        twig(&mut prims, rng);
    }
    prims
}

/// One blade from a tuft's foot: a tapering quadratic arc curving outward
/// along azimuth `az` and bending over with height.
fn blade(prims: &mut Vec<Prim>, rng: &mut Rng, foot: Vec3, az: f32, lean: Vec3, colour: Vec3) {
    const SEGMENTS: usize = 8;
    let dir = Vec3::new(az.cos(), az.sin(), 0.0);
    let side = Vec3::new(-dir.y, dir.x, 0.0);
    // Rooted a voxel below the surface so the base is full thickness at z = 0.
    let start = foot + dir * rng.range(0.0, 1.5) * V - Vec3::Z * V;
    let height = H * rng.range(0.4, 0.96);
    // Short blades stand up; long ones arch further out and droop more.
    let long = (height / H - 0.4) / 0.56;
    let reach = height * rng.range(0.15, 0.5 + 0.4 * long);
    let droop = rng.range(0.0, 0.5 + 0.5 * long);
    let control = dir * (0.15 * reach) + Vec3::Z * (height * (1.0 + 0.7 * droop));
    let tip = dir * reach + side * (rng.range(-0.25, 0.25) * reach) + lean * height + Vec3::Z * (height * (1.0 - 0.45 * droop));
    let arc = |t: f32| control * (2.0 * t * (1.0 - t)) + tip * (t * t);
    let top = (0..=SEGMENTS).map(|k| arc(k as f32 / SEGMENTS as f32).z).fold(0.0, f32::max);
    // Rescaled so the highest point of the arc sits exactly at the blade's height.
    let lift = (height - start.z) / top;
    let point = |t: f32| {
        let p = arc(t);
        start + Vec3::new(p.x, p.y, p.z * lift)
    };
    let r0 = rng.range(0.5, 0.75) * V;
    let radius = |t: f32| r0 * (1.0 - t).powf(0.8) + 0.04 * V;
    // Darker, damp-looking at the foot; bleached toward the tip.
    let (base, bleached) = (colour * 0.7, (colour * 1.2 + Vec3::splat(0.03)).min(Vec3::ONE));
    let shade = |t: f32| if t < 0.3 { base.lerp(colour, t / 0.3) } else { colour.lerp(bleached, (t - 0.3) / 0.7) };
    for k in 0..SEGMENTS {
        let (ta, tb) = (k as f32 / SEGMENTS as f32, (k + 1) as f32 / SEGMENTS as f32);
        prims.push(Prim::cone(point(ta), point(tb), radius(ta), radius(tb), shade(ta), shade(tb)));
    }
}

/// A thin dark twig: kinked straight segments leaning 30–60° from vertical,
/// one fork, snow where it leaves the surface and often on the fork.
fn twig(prims: &mut Vec<Prim>, rng: &mut Rng) {
    const STEPS: usize = 4;
    let base = Vec3::new(rng.unit(), rng.unit(), -1.5 * V);
    let lean = rng.range(30f32, 60.0).to_radians();
    let az = rng.range(0.0, TAU);
    let height = H * rng.range(0.3, 0.7);
    let len = (height - base.z) / lean.cos();
    let colour = (TWIG * rng.range(0.85, 1.2)).min(Vec3::ONE);
    let mut dir = Vec3::new(lean.sin() * az.cos(), lean.sin() * az.sin(), lean.cos());
    let mut pts = vec![base];
    for _ in 0..STEPS {
        dir = (Quat::from_axis_angle(rng.direction(), rng.range(-0.18, 0.18)) * dir).normalize();
        let last = pts[pts.len() - 1];
        pts.push(last + dir * (len / STEPS as f32));
    }
    // Kinks move the top; pull it back to the chosen height.
    let lift = (height - base.z) / (pts[STEPS].z - base.z).max(V);
    for p in &mut pts {
        p.z = base.z + (p.z - base.z) * lift;
    }
    let r0 = rng.range(1.0, 1.25) * V;
    let radius = |k: usize| r0 * (1.0 - 0.45 * k as f32 / STEPS as f32);
    let bark = |k: usize| colour * (1.0 + 0.25 * k as f32 / STEPS as f32);
    for k in 0..STEPS {
        prims.push(Prim::cone(pts[k], pts[k + 1], radius(k), radius(k + 1), bark(k), bark(k + 1)));
    }

    // The fork, halfway up: a thinner branch turned aside and a little more upright.
    let fork = pts[STEPS / 2];
    let stem = (pts[STEPS / 2 + 1] - fork).normalize();
    let turn = rng.range(0.5, 0.9) * if rng.unit() < 0.5 { -1.0 } else { 1.0 };
    let mut bdir = (Quat::from_rotation_z(turn) * stem + Vec3::Z * rng.range(0.1, 0.5)).normalize();
    let mut blen = len * rng.range(0.3, 0.45);
    // Keep the branch inside the shell.
    let room = 0.95 * H - fork.z;
    if bdir.z * blen > room {
        blen = room / bdir.z;
    }
    let rf = radius(STEPS / 2) * 0.75;
    let mid = fork + bdir * (blen * 0.5);
    bdir = (Quat::from_axis_angle(rng.direction(), rng.range(-0.2, 0.2)) * bdir).normalize();
    let end = mid + bdir * (blen * 0.5);
    let end = Vec3::new(end.x, end.y, end.z.min(0.95 * H));
    prims.push(Prim::cone(fork, mid, rf, rf * 0.75, bark(STEPS / 2), bark(STEPS)));
    prims.push(Prim::cone(mid, end, rf * 0.75, r0 * 0.35, bark(STEPS), bark(STEPS)));

    if rng.unit() < 0.75 {
        let r = Vec3::new(rng.range(1.6, 2.6), rng.range(1.6, 2.6), rng.range(1.0, 1.6)) * V;
        // Sits in the crotch, on top of the wood.
        let crotch = fork + ((stem + bdir) * 0.5).with_z(0.0) * r.x * 0.3 + Vec3::Z * (radius(STEPS / 2) + 0.4 * r.z);
        clump(prims, rng, crotch, r);
    }
    let emerge = base + (pts[1] - base) * ((-base.z) / (pts[1].z - base.z).max(1e-6));
    let radii = Vec3::new(rng.range(2.0, 3.5), rng.range(2.0, 3.5), rng.range(1.2, 2.2)) * V;
    clump(prims, rng, emerge.with_z(0.0), radii);
}

/// The crust's bumpy ice layer: its top over the tile.
struct Ice {
    seed: u64,
}

impl Ice {
    /// Height of the ice top at (x, y) (tile units): 10–25% of the shell.
    fn height(&self, x: f32, y: f32) -> f32 {
        let f = ((fbm(x, y, self.seed) - 0.5) * 2.6 + 0.5).clamp(0.0, 1.0);
        H * (0.10 + 0.15 * f)
    }
}

/// Grains and surface hoar on the ice layer (voxelised separately).
fn crust(rng: &mut Rng, ice: &Ice) -> Vec<Prim> {
    let mut prims = Vec::new();
    for _ in 0..rng.int(90, 130) {
        let (x, y) = (rng.unit(), rng.unit());
        let r = rng.range(1.0, 3.0) * V;
        let radii = Vec3::new(rng.range(0.8, 1.2), rng.range(0.8, 1.2), rng.range(0.7, 1.0)) * r;
        // Resting on the ice, partly sunk into it.
        let centre = Vec3::new(x, y, ice.height(x, y) + r * rng.range(-0.3, 0.6));
        prims.push(Prim::ellipsoid(centre, radii, (GRAIN * rng.range(0.96, 1.04)).min(Vec3::ONE)));
    }
    for _ in 0..rng.int(20, 40) {
        feather(&mut prims, rng, ice);
    }
    prims
}

/// One surface-hoar crystal: a leaning, one-voxel-thin stem with barbs on
/// both sides in a plane, longest a third of the way up, like a feather.
fn feather(prims: &mut Vec<Prim>, rng: &mut Rng, ice: &Ice) {
    let (x, y) = (rng.unit(), rng.unit());
    let root = Vec3::new(x, y, ice.height(x, y) - 0.5 * V);
    let top = H * rng.range(0.3, 0.6);
    let lean = rng.range(10f32, 40.0).to_radians();
    let az = rng.range(0.0, TAU);
    let dir = Vec3::new(lean.sin() * az.cos(), lean.sin() * az.sin(), lean.cos());
    let len = (top - root.z).max(4.0 * V) / lean.cos();
    let (e1, e2) = dir.any_orthonormal_pair();
    let psi = rng.range(0.0, TAU);
    let wing = e1 * psi.cos() + e2 * psi.sin();
    let white = HOAR * rng.range(0.97, 1.02);
    let (r_stem, r_barb) = (0.5 * V, 0.42 * V);
    prims.push(Prim::cone(root, root + dir * len, r_stem, 0.3 * V, white, white));
    // Some crystals are bare needles, the rest feathers of few or many barbs.
    let barbs = if rng.unit() < 0.25 { 0 } else { rng.int(4, 9) };
    let spread = rng.range(0.35, 0.55) * len;
    let angle = rng.range(35f32, 55.0).to_radians();
    for k in 1..=barbs {
        let t = k as f32 / (barbs + 1) as f32;
        let at = root + dir * (len * t);
        // Feather outline: widest a third of the way up, closing to the tip.
        let outline = (std::f32::consts::PI * t.powf(0.63)).sin();
        for side in [-1.0, 1.0] {
            let bdir = (dir * angle.cos() + wing * (side * angle.sin())).normalize();
            let bl = spread * outline * rng.range(0.75, 1.1);
            if bl > V {
                prims.push(Prim::cone(at, at + bdir * bl, r_barb, 0.25 * V, white, white));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_force(size: [u32; 3], occupied: &[bool], cap: f32) -> Vec<f32> {
        let [sx, sy, _] = size.map(|s| s as i64);
        let coords = |i: usize| {
            let i = i as i64;
            (i % sx, (i / sx) % sy, i / (sx * sy))
        };
        let wrap = |d: i64, n: i64| {
            let d = d.rem_euclid(n);
            d.min(n - d)
        };
        (0..occupied.len())
            .map(|i| {
                let (x, y, z) = coords(i);
                let mut best = f32::INFINITY;
                for (j, _) in occupied.iter().enumerate().filter(|(_, o)| **o) {
                    let (ox, oy, oz) = coords(j);
                    let (dx, dy, dz) = (wrap(x - ox, sx), wrap(y - oy, sy), z - oz);
                    best = best.min(((dx * dx + dy * dy + dz * dz) as f32).sqrt());
                }
                best.min(cap)
            })
            .collect()
    }

    #[test]
    fn distance_transform_matches_brute_force() {
        let mut rng = Rng(7);
        for size in [[7, 5, 4], [8, 8, 3], [1, 6, 5], [9, 1, 1], [3, 3, 9]] {
            let n = size.iter().product::<u32>() as usize;
            for density in [0.0, 0.02, 0.1, 0.5] {
                let occupied: Vec<bool> = (0..n).map(|_| rng.unit() < density).collect();
                for cap in [255.0, 2.5] {
                    let fast = distance_transform(size, &occupied, cap);
                    let slow = brute_force(size, &occupied, cap);
                    for (i, (a, b)) in fast.iter().zip(&slow).enumerate() {
                        assert!((a - b).abs() < 1e-4, "size {size:?} density {density} voxel {i}: {a} vs {b}");
                    }
                }
            }
        }
    }

    #[test]
    fn mip_chain_halves_and_keeps_coverage() {
        let volume = DetailVolume::generate(DetailKind::Grass, 32, 3).unwrap();
        let sizes: Vec<[u32; 3]> = volume.levels.iter().map(|l| l.size).collect();
        assert_eq!(sizes, [[32, 32, 16], [16, 16, 8], [8, 8, 4], [4, 4, 2], [2, 2, 1], [1, 1, 1]]);
        let mean = |l: &VolumeLevel| l.rgba.iter().map(|v| f64::from(v[3])).sum::<f64>() / l.rgba.len() as f64 / 255.0;
        assert!((mean(&volume.levels[0]) - mean(&volume.levels[1])).abs() <= 1.0 / 255.0);
        for level in &volume.levels {
            assert_eq!(level.rgba.len(), level.sdf.len());
            for (v, d) in level.rgba.iter().zip(&level.sdf) {
                assert_eq!(v[3] > 0, *d == 0.0, "coverage {} sdf {d}", v[3]);
                assert!(*d <= 255.0);
            }
        }
        let bytes: u64 = volume.levels.iter().map(|l| l.rgba.len() as u64 * 6).sum();
        assert_eq!(volume.gpu_bytes(), bytes);
        assert_eq!(volume.size(), [32, 32, 16]);
    }

    #[test]
    fn sdf_is_in_level_zero_voxels() {
        let size = [16, 16, 16];
        let mut rgba = vec![[0u8; 4]; 16 * 16 * 16];
        rgba[0] = [200, 100, 50, 255];
        let mut level = VolumeLevel::new(size, rgba, 0);
        assert_eq!(level.sdf[1], 1.0);
        assert_eq!(level.sdf[16 * 16], 1.0);
        assert_eq!(level.sdf[15], 1.0, "periodic in x");
        assert_eq!(level.sdf[15 * 16 * 16], 15.0, "not periodic in z");
        for index in 0..3 {
            level = downsample(&level, index);
            let l = index + 1;
            assert!(level.rgba[0][3] > 0, "level {l} still covered");
            assert_eq!(level.rgba[0][..3], [200, 100, 50], "colour is not darkened by coverage");
            let n = level.size[0] as usize;
            assert_eq!(level.sdf[0], 0.0);
            assert_eq!(level.sdf[1], (1u32 << l) as f32, "neighbour at level {l}");
            assert_eq!(level.sdf[n * n], (1u32 << l) as f32, "neighbour above at level {l}");
        }
        assert_eq!(level.rgba[0][3], 1, "255 / 8^3 rounds to 0.5 then up");
    }

    #[test]
    fn generates_deterministic_tiling_content() {
        for kind in [DetailKind::Grass, DetailKind::Crust] {
            for size in [32, 64] {
                let a = DetailVolume::generate(kind, size, 11).unwrap();
                let b = DetailVolume::generate(kind, size, 11).unwrap();
                let c = DetailVolume::generate(kind, size, 12).unwrap();
                assert_eq!(a, b, "{kind:?} {size} deterministic");
                assert_ne!(a.levels[0], c.levels[0], "{kind:?} {size} seeds differ");
                let l0 = &a.levels[0];
                let [n, _, depth] = l0.size.map(|s| s as usize);
                let mean = l0.rgba.iter().map(|v| f64::from(v[3])).sum::<f64>() / l0.rgba.len() as f64 / 255.0;
                assert!((0.02..=0.40).contains(&mean), "{kind:?} {size}: coverage {mean}");
                let covered = |x: usize, y: usize, z: usize| l0.rgba[(z * n + y) * n + x][3] > 0;
                if kind == DetailKind::Grass {
                    let high = (depth * 3 / 4..depth).any(|z| (0..n).any(|y| (0..n).any(|x| covered(x, y, z))));
                    assert!(high, "{size}: grass reaches the top quarter");
                    let above = (depth / 4..depth).any(|z| (0..n).any(|y| covered(0, y, z) && covered(n - 1, y, z)));
                    assert!(above, "{size}: grass crosses the tile edge");
                }
                let wraps = (0..depth).any(|z| (0..n).any(|y| covered(0, y, z) && covered(n - 1, y, z)));
                assert!(wraps, "{kind:?} {size}: features wrap around x");
            }
        }
        assert_eq!(DetailKind::parse("crust"), Some(DetailKind::Crust));
        assert_eq!(DetailKind::parse(DetailKind::Grass.name()), Some(DetailKind::Grass));
        assert_eq!(DetailKind::parse("moss"), None);
    }

    #[test]
    fn sizes_are_checked() {
        for size in [0, 1, 4, 7, 48, 100, 1024] {
            assert!(DetailVolume::generate(DetailKind::Grass, size, 0).is_err(), "{size}");
        }
        assert!(DetailVolume::generate(DetailKind::Crust, 8, 0).is_ok());
    }
}
