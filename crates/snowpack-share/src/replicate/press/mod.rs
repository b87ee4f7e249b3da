//! Presses that travel instead of the snow they pressed.
//!
//! A car's four treaded wheels make about 16,000 texels of new trail a
//! second; as tiles that is 15 KB/s, while what pressed them, four tyres'
//! poses a frame, is a few hundred bytes. So a peer sends the analytic
//! shapes of each frame ([`PressFrame`]: spheres swept to capsules, boxes
//! and wheels with the pose they were swept from) and every machine that
//! receives them presses them into its own copy of the tiles with the same
//! arithmetic the GPU's compute capture and update use: the sweep's
//! sub-steps ([`sweep`], [`wheel`]), the ray casts ([`cast`]), the 16-bit
//! depth codes and the update's press and packing ([`press_tiles`]).
//! What the shapes do not explain (skinned meshes, footprints, berms, a GPU
//! whose arithmetic differs) still goes as tiles: the peer sends a tile only
//! beyond what its presses make (`docs/multiplayer.md`, "Presses").
//!
//! | file | what |
//! |---|---|
//! | `wheel.rs` | tyres and treads: poses, sub-steps, the capture's instance of a pose |
//! | `sweep.rs` | sub-steps of swept boxes (and meshes, in snowpack) |
//! | `cast.rs` | the ray casts: capsule, tyre, box |
//! | `ground.rs` | the terrain they are pressed over: flat, the window's value noise, or a heightmap both ends hold |
//! | `height_grid.rs` | a heightmap as every machine samples it, and as bytes |

pub mod cast;
pub mod ground;
pub mod height_grid;
pub mod sweep;
pub mod wheel;

pub use ground::PressGround;

use glam::{Mat4, Quat, Vec3};

use crate::replicate::tile::{CatchUp, ShareClock, SharedTile};
use crate::replicate::world::{WorldIdentity, WorldSettings};

use sweep::BoxPose;
use wheel::{Tread, WheelPose};

/// Quanta per metre (the shaders multiply by it: exact, where a division is not).
pub const SNOW_QUANTA_PER_M: f32 = 10_000.0;

/// Codes of the capture's 16-bit depth: a depth `d` in 0..1 is stored as
/// `round(d × CAPTURE_CODES)`.
pub const CAPTURE_CODES: f32 = 65_535.0;

/// Quanta of a deficit of `m` metres: rounded to nearest even, clamped to 0..=65535.
#[must_use]
pub fn deficit_quanta(m: f32) -> u32 {
    (m * SNOW_QUANTA_PER_M).round_ties_even().clamp(0.0, 65_535.0) as u32
}

/// The deficit that reaches the terrain under a rest column of `column`
/// metres (depth and lying snow; rounded up; above 65535 under snow deeper
/// than a deficit holds). From the column itself, as `snow_word.wgsl` does,
/// not from the rest height less the terrain: a GPU compiler may simplify
/// (terrain + column) − terrain to the column, or not.
#[must_use]
pub fn ground_quanta(column: f32) -> f32 {
    (column * SNOW_QUANTA_PER_M).ceil().max(0.0)
}

/// The deficit of a press down to `h` (not below the terrain `ground`)
/// under a rest column of `column` metres (rest height `ground + column`).
#[must_use]
pub fn column_press(ground: f32, column: f32, h: f32) -> u32 {
    if h <= ground {
        return ground_quanta(column).min(65_535.0) as u32;
    }
    deficit_quanta((ground + column) - h)
}

/// Most packed snow (quanta) a column `column` quanta high holds at the
/// final density: `floor(column × ratio)`, at most 16 bits (`ratio` is
/// `ρmax / ρ0 − 1`, [`crate::mechanics`]).
#[must_use]
pub fn packed_cap(column: u32, ratio: f32) -> u32 {
    (column as f32 * ratio).floor().min(65_535.0) as u32
}

/// One analytic shape's motion over a frame, window-local (x and z from the
/// window's corner, y world height): what the capture ray casts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShapeSweep {
    /// A sphere swept from `a` (last frame) to `b` (this frame): the capsule
    /// around the segment, exactly (`a == b` when not swept).
    Capsule {
        /// Last frame's centre.
        a: Vec3,
        /// This frame's centre.
        b: Vec3,
        /// Radius (m).
        radius: f32,
    },
    /// A box, in sub-steps from `then` (none: not swept) to `now`.
    Box {
        /// Last frame's pose.
        then: Option<BoxPose>,
        /// This frame's pose.
        now: BoxPose,
    },
    /// A wheel, in sub-steps from `then` (none: not swept) to `now`.
    Wheel {
        /// Last frame's pose.
        then: Option<WheelPose>,
        /// This frame's pose.
        now: WheelPose,
        /// Outer radius, lugs included (m).
        radius: f32,
        /// Half the tyre's width (m).
        half_width: f32,
        /// The tread.
        tread: Tread,
    },
}

/// The capture's instances of analytic shapes (what `capture_shapes.wgsl`
/// ray casts): capsules `[ax, ay, az, radius, bx, by, bz, 0]`, boxes as
/// column-major model matrices of the unit cube, tyre poses
/// ([`wheel::instance`]); all window-local.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShapeInstances {
    /// Spheres swept to capsules.
    pub capsules: Vec<[f32; 8]>,
    /// Box poses (each sub-step one).
    pub boxes: Vec<[f32; 16]>,
    /// Tyre poses (each sub-step one).
    pub wheels: Vec<[f32; 16]>,
}

impl ShapeInstances {
    /// Empties the lists, keeping their memory.
    pub fn clear(&mut self) {
        self.capsules.clear();
        self.boxes.clear();
        self.wheels.clear();
    }
}

impl ShapeSweep {
    /// The capture's instances of this shape at `texel_m`: one capsule, or
    /// a box or tyre per sub-step (at most [`sweep::MAX_SWEEP_STEPS`] + 1),
    /// counted without making them.
    #[must_use]
    pub fn instance_count(&self, texel_m: f32) -> u32 {
        match *self {
            Self::Capsule { .. } => 1,
            Self::Box { then, now } => Self::box_steps(then, now, texel_m).1 + 1,
            Self::Wheel { then, now, radius, half_width, .. } => Self::wheel_steps(then, now, (radius, half_width), texel_m).1 + 1,
        }
    }

    /// The box's sub-steps and first pose (`then` itself, or `now` unswept).
    fn box_steps(then: Option<BoxPose>, now: BoxPose, texel_m: f32) -> (BoxPose, u32) {
        match then {
            Some(then) => (then, sweep::steps_for(sweep::box_travel(then, now), texel_m)),
            None => (now, 0),
        }
    }

    /// The wheel's sub-steps and first pose.
    fn wheel_steps(then: Option<WheelPose>, now: WheelPose, (radius, half_width): (f32, f32), texel_m: f32) -> (WheelPose, u32) {
        match then {
            Some(then) => (then, sweep::steps_for(wheel::wheel_travel(then, now, radius, half_width), texel_m)),
            None => (now, 0),
        }
    }

    /// Whether the shape can touch a window `extent_m` on a side (its
    /// reach around the segment from its first pose to its last overlaps
    /// the window's square) and has a size: the capture keeps only these.
    #[must_use]
    pub fn touches_window(&self, extent_m: f32, texel_m: f32) -> bool {
        let extent = f64::from(extent_m);
        let outside = |a: Vec3, b: Vec3, reach: f32| {
            let reach = f64::from(reach);
            let (x0, x1) = (f64::from(a.x.min(b.x)) - reach, f64::from(a.x.max(b.x)) + reach);
            let (z0, z1) = (f64::from(a.z.min(b.z)) - reach, f64::from(a.z.max(b.z)) + reach);
            x1 < 0.0 || x0 > extent || z1 < 0.0 || z0 > extent
        };
        match *self {
            Self::Capsule { a, b, radius } => !outside(a, b, radius) && radius > 0.0,
            Self::Box { then, now } => {
                let (then, steps) = Self::box_steps(then, now, texel_m);
                let first = if steps == 0 { now } else { sweep::box_pose(then, now, 0, steps) };
                !outside(first.0, now.0, now.1.length())
            }
            Self::Wheel { then, now, radius, half_width, .. } => {
                let (then, steps) = Self::wheel_steps(then, now, (radius, half_width), texel_m);
                let first = if steps == 0 { now } else { wheel::wheel_pose(then, now, 0, steps) };
                !outside(first.0, now.0, radius.hypot(half_width)) && radius > 0.0 && half_width > 0.0
            }
        }
    }

    /// Appends the capture's instances of this shape to `out`: one capsule,
    /// or a box or tyre per sub-step (`texel_m` spaces them).
    pub fn expand_into(&self, texel_m: f32, out: &mut ShapeInstances) {
        match *self {
            Self::Capsule { a, b, radius } => out.capsules.push([a.x, a.y, a.z, radius, b.x, b.y, b.z, 0.0]),
            Self::Box { then, now } => {
                let matrix = |(c, h, q): BoxPose| Mat4::from_scale_rotation_translation(h, q, c).to_cols_array();
                let (then, steps) = Self::box_steps(then, now, texel_m);
                if steps == 0 {
                    out.boxes.push(matrix(now));
                } else {
                    out.boxes.extend((0..=steps).map(|k| matrix(sweep::box_pose(then, now, k, steps))));
                }
            }
            Self::Wheel { then, now, radius, half_width, tread } => {
                let instance = |(c, a, roll): WheelPose| wheel::instance(c, a, radius, half_width, &tread, f64::from(roll));
                let (then, steps) = Self::wheel_steps(then, now, (radius, half_width), texel_m);
                if steps == 0 {
                    out.wheels.push(instance(now));
                } else {
                    out.wheels.extend((0..=steps).map(|k| instance(wheel::wheel_pose(then, now, k, steps))));
                }
            }
        }
    }
}

/// One frame's analytic presses as the window pressed them: the shapes,
/// where the window was, the capture's height range and the clock the
/// frame's update left the snow at.
#[derive(Clone, Debug, PartialEq)]
pub struct PressFrame {
    /// The world clock after the frame (its refill applied before the press).
    pub clock: ShareClock,
    /// Global texel (column, row) of the window's first texel.
    pub origin: [i64; 2],
    /// Texels per window side.
    pub resolution: u32,
    /// World height of capture depth 0 (m).
    pub low_m: f32,
    /// World height of capture depth 1 (m).
    pub high_m: f32,
    /// `ρmax / ρ0 − 1` of the window's snow: how much packed snow a column holds.
    pub pack_ratio: f32,
    /// The shapes, window-local.
    pub shapes: Vec<ShapeSweep>,
}

/// A frame's shapes as ray casts, each with its window-local bounds
/// (x0, z0, x1, z1 in m) so a tile tests only those that can reach it.
#[derive(Debug, Default)]
pub struct FrameCasts {
    capsules: Vec<([f32; 8], [f32; 4])>,
    boxes: Vec<(Mat4, [f32; 4])>,
    wheels: Vec<([f32; 16], [f32; 4])>,
}

impl FrameCasts {
    /// Every instance's bounds.
    fn bounds(&self) -> impl Iterator<Item = [f32; 4]> + '_ {
        self.capsules.iter().map(|c| c.1).chain(self.boxes.iter().map(|b| b.1)).chain(self.wheels.iter().map(|w| w.1))
    }

    /// The instances whose bounds overlap window-local rectangle `rect`
    /// (x0, z0, x1, z1 in m).
    #[must_use]
    fn within(&self, rect: [f32; 4]) -> Self {
        Self {
            capsules: self.capsules.iter().filter(|c| overlaps(c.1, rect)).copied().collect(),
            boxes: self.boxes.iter().filter(|b| overlaps(b.1, rect)).copied().collect(),
            wheels: self.wheels.iter().filter(|w| overlaps(w.1, rect)).copied().collect(),
        }
    }

    /// The tiles (of `side` texels) of `frame`'s window that some
    /// instance's bounds overlap.
    fn tiles(&self, frame: &PressFrame, side: u32, texel_m: f32) -> std::collections::BTreeSet<crate::TileKey> {
        let mut keys = std::collections::BTreeSet::new();
        for b in self.bounds() {
            let Some((cols, rows)) = frame.texels_under(b, texel_m) else { continue };
            let tile = |t: i64| t.div_euclid(i64::from(side));
            for row in tile(rows.0)..=tile(rows.1) {
                keys.extend((tile(cols.0)..=tile(cols.1)).map(|col| crate::TileKey::new(col, row)));
            }
        }
        keys
    }

    /// Ray casts pressing `frame` costs at most: per tile of `side` texels
    /// an instance's bounds overlap, a cast a texel (counted without
    /// walking the tiles, so judging a hostile frame costs little).
    #[must_use]
    fn work(&self, frame: &PressFrame, side: u32, texel_m: f32) -> u64 {
        let tile = |t: i64| t.div_euclid(i64::from(side));
        self.bounds()
            .filter_map(|b| frame.texels_under(b, texel_m))
            .map(|(cols, rows)| ((tile(cols.1) - tile(cols.0) + 1) * (tile(rows.1) - tile(rows.0) + 1)) as u64 * u64::from(side) * u64::from(side))
            .sum()
    }

    /// The capture depth (0..1; 1 where nothing is) at window-local point
    /// (x, z), as `capture_shapes.wgsl` finds it: the lowest of the shapes
    /// that reach it.
    fn depth_at(&self, (x, z): (f32, f32), (low, range): (f32, f32)) -> f32 {
        let inside = |b: [f32; 4]| x >= b[0] && x <= b[2] && z >= b[1] && z <= b[3];
        let capsules = self.capsules.iter().filter(|c| inside(c.1)).map(|c| c.0);
        let wheels = self.wheels.iter().filter(|w| inside(w.1)).map(|w| w.0);
        let boxes = self.boxes.iter().filter(|b| inside(b.1)).map(|b| b.0);
        cast::lowest_depth((capsules, wheels, boxes), [x, z], low, range)
    }
}

/// Bounds (x0, z0, x1, z1) widened by a millimetre: they only skip shapes
/// that cannot reach a point, whatever the rounding of the test.
fn slack(b: [f32; 4]) -> [f32; 4] {
    [b[0] - 1e-3, b[1] - 1e-3, b[2] + 1e-3, b[3] + 1e-3]
}

/// Whether two rectangles (x0, z0, x1, z1) overlap.
fn overlaps(a: [f32; 4], b: [f32; 4]) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

impl PressFrame {
    /// Whether this frame presses nothing `previous` (the frame before it)
    /// did not: the same shapes, resting where they were, in the same
    /// window and range, and no refill or snowfall since. Pressing it again
    /// changes no texel (a press is a maximum), so a parked car or a ball
    /// at rest sends nothing more.
    #[must_use]
    pub fn repeats(&self, previous: &Self) -> bool {
        let resting = self.shapes.iter().all(|s| match *s {
            ShapeSweep::Capsule { a, b, .. } => a == b,
            ShapeSweep::Box { then, now } => then.is_none_or(|t| t == now),
            ShapeSweep::Wheel { then, now, .. } => then.is_none_or(|t| t == now),
        });
        resting
            && self.shapes == previous.shapes
            && (self.origin, self.resolution) == (previous.origin, previous.resolution)
            && (self.low_m, self.high_m, self.pack_ratio) == (previous.low_m, previous.high_m, previous.pack_ratio)
            && (self.clock.refill_quanta, self.clock.stamp_quanta) == (previous.clock.refill_quanta, previous.clock.stamp_quanta)
            && self.clock.fallen_m.to_bits() == previous.clock.fallen_m.to_bits()
    }

    /// The frame's ray casts, with the bounds they can reach.
    #[must_use]
    pub fn casts(&self, texel_m: f32) -> FrameCasts {
        let mut inst = ShapeInstances::default();
        for s in &self.shapes {
            s.expand_into(texel_m, &mut inst);
        }
        let capsules =
            inst.capsules.iter().map(|c| (*c, slack([c[0].min(c[4]) - c[3], c[2].min(c[6]) - c[3], c[0].max(c[4]) + c[3], c[2].max(c[6]) + c[3]]))).collect();
        let wheels = inst
            .wheels
            .iter()
            .map(|w| {
                let reach = w[3].hypot(w[7]);
                (*w, slack([w[0] - reach, w[2] - reach, w[0] + reach, w[2] + reach]))
            })
            .collect();
        let boxes = inst
            .boxes
            .iter()
            .map(|m| {
                let model = Mat4::from_cols_array(m);
                let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                for k in 0..8 {
                    let s = Vec3::new(if k & 1 == 0 { -1.0 } else { 1.0 }, if k & 2 == 0 { -1.0 } else { 1.0 }, if k & 4 == 0 { -1.0 } else { 1.0 });
                    let p = model.transform_point3(s);
                    (lo, hi) = (lo.min(p), hi.max(p));
                }
                (model.inverse(), slack([lo.x, lo.z, hi.x, hi.z]))
            })
            .collect();
        FrameCasts { capsules, boxes, wheels }
    }

    /// The global texel columns and rows (first, last) of the window's
    /// texels under window-local bounds `b` (x0, z0, x1, z1 in m), `None`
    /// when they miss the window.
    fn texels_under(&self, b: [f32; 4], texel_m: f32) -> Option<((i64, i64), (i64, i64))> {
        let last = f64::from(self.resolution) - 1.0;
        let texel = |m: f32| (f64::from(m) / f64::from(texel_m)).floor();
        let (c0, c1, r0, r1) = (texel(b[0]).max(0.0), texel(b[2]).min(last), texel(b[1]).max(0.0), texel(b[3]).min(last));
        (c0 <= c1 && r0 <= r1).then(|| ((self.origin[0] + c0 as i64, self.origin[0] + c1 as i64), (self.origin[1] + r0 as i64, self.origin[1] + r1 as i64)))
    }

    /// The window-local rows and columns of `tile` inside this frame's window
    /// (`None` when they miss it), as ranges over the window.
    fn span(&self, key: crate::TileKey, side: u32) -> Option<((u32, u32), (u32, u32))> {
        let r = i64::from(self.resolution);
        let (c0, r0) = (key.col * i64::from(side) - self.origin[0], key.row * i64::from(side) - self.origin[1]);
        let (c1, r1) = (c0 + i64::from(side), r0 + i64::from(side));
        let cols = (c0.clamp(0, r), c1.clamp(0, r));
        let rows = (r0.clamp(0, r), r1.clamp(0, r));
        (cols.0 < cols.1 && rows.0 < rows.1).then_some(((rows.0 as u32, rows.1 as u32), (cols.0 as u32, cols.1 as u32)))
    }

    /// Presses the frame into `tile` over `ground` in `world`: the tile is
    /// brought to the frame's clock, then each texel inside the window
    /// takes the update's press of the shapes' capture depth (16-bit
    /// codes, as the GPU stores them) and packs what it lost up to the
    /// final density, as `update.wgsl` does where nothing displaces, no
    /// footprint presses and no snowfall lies.
    fn press(&self, tile: &mut SharedTile, casts: &FrameCasts, world: &WorldSettings, ground: &PressGround) {
        tile.catch_up(&self.clock, CatchUp { max_fallen_m: world.max_fallen_m });
        let Some((rows, cols)) = self.span(tile.key, tile.side) else { return };
        let side = i64::from(tile.side);
        let (tile_c0, tile_r0) = (tile.key.col * side - self.origin[0], tile.key.row * side - self.origin[1]);
        let texel_m = world.texel_m;
        let range = self.high_m - self.low_m;
        if tile.packed.is_empty() {
            tile.packed = vec![0; tile.texels()];
        }
        for i in rows.0..rows.1 {
            for j in cols.0..cols.1 {
                let d = casts.depth_at(((j as f32 + 0.5) * texel_m, (i as f32 + 0.5) * texel_m), (self.low_m, range));
                if d >= 1.0 {
                    continue;
                }
                // As stored (a 16-bit code) and read back by the update.
                let code = (d * CAPTURE_CODES + 0.5).floor() as u32;
                let d = code as f32 / CAPTURE_CODES;
                if d >= 1.0 {
                    continue;
                }
                let k = ((i64::from(i) - tile_r0) * side + (i64::from(j) - tile_c0)) as usize;
                let terrain = ground.at_texel([self.origin[0] + i64::from(j), self.origin[1] + i64::from(i)], texel_m);
                // As the update adds the lying snow (none where presses travel).
                let column = world.depth_m + 0.0;
                let at_ground = column_press(terrain, column, terrain);
                let refilled = u32::from(tile.deficit[k]);
                let deficit = refilled.max(column_press(terrain, column, self.low_m + d * range)).min(at_ground);
                if deficit > refilled {
                    let squeezed = u32::from(tile.packed[k]) + (deficit - refilled);
                    tile.packed[k] = squeezed.min(packed_cap(at_ground - deficit, self.pack_ratio)).min(0xffff) as u16;
                    tile.deficit[k] = deficit as u16;
                }
            }
        }
    }
}

/// Tile `key` (of `side` texels) after `frame` pressed it: `tile`, or
/// untouched snow at the frame's clock when `None`; `None` when the
/// frame's shapes do not reach the tile (and `tile` was `None`).
#[must_use]
pub(crate) fn press_tile(
    frame: &PressFrame,
    casts: &FrameCasts,
    key: crate::TileKey,
    side: u32,
    (world, ground): (&WorldSettings, &PressGround),
    tile: Option<SharedTile>,
) -> Option<SharedTile> {
    let (rows, cols) = frame.span(key, side)?;
    let t = world.texel_m;
    let rect = [cols.0 as f32 * t, rows.0 as f32 * t, cols.1 as f32 * t, rows.1 as f32 * t];
    let local = casts.within(rect);
    if local.capsules.is_empty() && local.boxes.is_empty() && local.wheels.is_empty() {
        return tile;
    }
    let mut tile = tile.unwrap_or_else(|| SharedTile::untouched(key, side, frame.clock, false, false));
    frame.press(&mut tile, &local, world, ground);
    Some(tile)
}

/// The tiles (of `side` texels) `frames` press, in order, each from
/// untouched snow at the clock of the first frame that reaches it, over
/// `ground` (`casts[k]` is `frames[k].casts(world.texel_m)`): what a
/// machine that receives the frames merges.
#[must_use]
pub fn press_tiles(frames: &[PressFrame], casts: &[FrameCasts], world: &WorldSettings, ground: &PressGround, side: u32) -> Vec<SharedTile> {
    press_tiles_where(frames, casts, (world, ground, side), |_| true)
}

/// The most ray-cast instances (shapes times their sub-steps) one
/// `Presses` message may make a machine build: a car's four wheels over
/// eight frames make about 320. The relay refuses more from a peer; a peer
/// drops more from its relay.
const MAX_PRESS_INSTANCES: u64 = 16_384;

/// `frames`' ray casts at `texel_m` and the most casts pressing them into
/// tiles of `side` costs ([`FrameCasts::work`]); `None`, with nothing
/// made, when they would make more than [`MAX_PRESS_INSTANCES`] instances
/// (counted first). What the relay and a watcher judge a message by.
pub(crate) fn costed_casts(frames: &[PressFrame], texel_m: f32, side: u32) -> Option<(Vec<FrameCasts>, u64)> {
    let instances: u64 = frames.iter().flat_map(|f| &f.shapes).map(|s| u64::from(s.instance_count(texel_m))).sum();
    if instances > MAX_PRESS_INSTANCES {
        return None;
    }
    let casts: Vec<FrameCasts> = frames.iter().map(|f| f.casts(texel_m)).collect();
    let work = frames.iter().zip(&casts).map(|(f, c)| c.work(f, side, texel_m)).sum();
    Some((casts, work))
}

/// [`press_tiles`] of the tiles `keep` keeps only (a watcher presses those
/// near its window; the rest it would not hold).
pub(crate) fn press_tiles_where(
    frames: &[PressFrame],
    casts: &[FrameCasts],
    (world, ground, side): (&WorldSettings, &PressGround, u32),
    keep: impl Fn(crate::TileKey) -> bool,
) -> Vec<SharedTile> {
    let mut tiles: std::collections::BTreeMap<crate::TileKey, SharedTile> = std::collections::BTreeMap::new();
    for (frame, casts) in frames.iter().zip(casts) {
        for key in casts.tiles(frame, side, world.texel_m).into_iter().filter(|k| keep(*k)) {
            if let Some(t) = press_tile(frame, casts, key, side, (world, ground), tiles.remove(&key)) {
                tiles.insert(key, t);
            }
        }
    }
    tiles.into_values().collect()
}

/// Whether presses can travel in `world` on its settings alone: terrain
/// its identity says whole (flat or value noise: [`PressGround::of_world`];
/// a machine without the terrain then knows its height) and no lying snow
/// (a press's rest height would depend on the snowfall and berms under it,
/// which only the window knows: those worlds send tiles). Over a heightmap
/// they travel between machines that hold it ([`PressGround::of_identity`]):
/// the relay says in its `Welcome` whether it does.
#[must_use]
pub fn presses_travel(world: &WorldSettings) -> bool {
    PressGround::of_world(world).is_some() && !world.has_snowfall
}

/// The terrain presses are pressed over in `world` on this machine: its
/// identity's, or the heightmap it holds; none with lying snow (then
/// presses go as tiles). A relay presses its peers' frames, and a peer
/// sends and presses frames, only where this is some.
#[must_use]
pub fn press_ground(world: &WorldIdentity) -> Option<PressGround> {
    PressGround::of_identity(world).filter(|_| !world.settings.has_snowfall)
}

/// Quaternion rotation normalised as the sender's box poses are (checked on
/// the wire: a hostile frame may not carry a scaled rotation).
#[must_use]
pub(crate) fn is_unit(q: Quat) -> bool {
    q.is_finite() && (q.length_squared() - 1.0).abs() < 1e-3
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(shapes: Vec<ShapeSweep>, refill_quanta: u64) -> PressFrame {
        let clock = ShareClock { time_s: 1.0, refill_quanta, stamp_quanta: 0, fallen_m: 0.0 };
        PressFrame { clock, origin: [0, 0], resolution: 64, low_m: -1.0, high_m: 1.0, pack_ratio: 3.0, shapes }
    }

    #[test]
    fn only_shapes_at_rest_with_no_refill_since_repeat_a_frame() {
        let at = Vec3::new(2.0, 0.3, 2.0);
        let resting = vec![ShapeSweep::Capsule { a: at, b: at, radius: 0.3 }];
        let moving = vec![ShapeSweep::Capsule { a: at - Vec3::X * 0.1, b: at, radius: 0.3 }];
        assert!(frame(resting.clone(), 5).repeats(&frame(resting.clone(), 5)));
        assert!(!frame(resting.clone(), 6).repeats(&frame(resting.clone(), 5)), "refill since: the rest presses again");
        assert!(!frame(moving.clone(), 5).repeats(&frame(moving, 5)), "a moving shape presses new snow");
        let elsewhere = vec![ShapeSweep::Capsule { a: at + Vec3::X, b: at + Vec3::X, radius: 0.3 }];
        assert!(!frame(elsewhere, 5).repeats(&frame(resting, 5)));
    }

    #[test]
    fn flat_and_noise_terrain_are_read_from_the_world_and_nothing_else_is() {
        let mut w = WorldSettings {
            texel_m: 0.0625,
            tile_side: 32,
            terrain: "flat at -2.25 m".to_owned(),
            depth_m: 0.5,
            refill_m_per_s: 0.0,
            snowfall_m_per_s: 0.0,
            max_fallen_m: 0.0,
            has_snowfall: false,
            stamp_range_m: [-1.0, 1.0],
        };
        assert_eq!(PressGround::of_world(&w), Some(PressGround::Flat(-2.25)));
        assert!(presses_travel(&w));
        w.has_snowfall = true;
        assert!(!presses_travel(&w), "lying snow stays in tiles");
        w.has_snowfall = false;
        w.terrain = "noise seed 7 base -0.5 m amplitude 1.25 m wavelength 9 m".to_owned();
        let noise = PressGround::Noise { seed: 7, base_m: -0.5, amplitude_m: 1.25, wavelength_m: 9.0 };
        assert_eq!(PressGround::of_world(&w), Some(noise.clone()));
        assert!(presses_travel(&w));
        // The height under a texel is the window's noise at its centre.
        let h = noise.at_texel([37, -12], 0.25);
        assert_eq!(h.to_bits(), ground::noise_height(37.5 * 0.25, -11.5 * 0.25, (7, -0.5, 1.25, 9.0)).to_bits());
        for bad in [
            "flat at NaN m",
            "heightmap 00000000deadbeef",
            "mesh of 12 triangles 00000000deadbeef",
            "noise seed 7 base 0 m amplitude 1 m wavelength 0 m",
            "noise seed 7 base 0 m amplitude inf m wavelength 9 m",
            "noise seed -7 base 0 m amplitude 1 m wavelength 9 m",
            "noise seed 7 base 0 m amplitude 1 m wavelength 9 m and more",
        ] {
            w.terrain = bad.to_owned();
            assert_eq!(PressGround::of_world(&w), None, "{bad}");
        }
    }

    #[test]
    fn a_heightmap_is_pressed_over_only_where_this_machine_holds_it() {
        use crate::replicate::world::{WorldIdentity, WorldIdentityExt, WorldSnow, WorldTerrain};
        use std::sync::Arc;
        let heights: Vec<f32> = (0..7 * 5).map(|k| ((k * 37) % 11) as f32 * 0.125 - 0.5).collect();
        let grid = Arc::new(ground::HeightGrid::new(7, 5, heights, [1.5, -2.0], [6.0, 4.5]).expect("a grid"));
        let snow = WorldSnow { texel_m: 0.125, depth_m: 0.5, refill_m_per_s: 0.0, snowfall: None, displace: false };
        let world = WorldIdentity::new(&snow, &WorldTerrain::heightmap(Arc::clone(&grid)), 16);
        assert_eq!(world.settings().terrain, format!("heightmap {:016x}", grid.digest()));
        // The settings alone (a relay's store, the wire) name it, not hold it.
        assert!(!presses_travel(world.settings()));
        assert_eq!(PressGround::of_identity(&WorldIdentity::from_settings(world.settings().clone())), None);
        let held = PressGround::of_identity(&world).expect("the identity holds the grid");
        assert_eq!(press_ground(&world), Some(held.clone()));
        // The height under a texel is the grid's at its centre, the edges clamped.
        for g in [[0_i64, 0], [13, -17], [-40, 9], [60, 60], [-60, -60]] {
            let (x, z) = ((g[0] as f32 + 0.5) * 0.125, (g[1] as f32 + 0.5) * 0.125);
            assert_eq!(held.at_texel(g, 0.125).to_bits(), grid.height_at(x, z).to_bits(), "{g:?}");
        }
        let (lo, hi) = grid.height_range();
        assert!((-0.5..=0.75).contains(&lo) && hi <= 0.75 && lo < hi);
        assert_eq!(grid.height_at(-100.0, -100.0), grid.heights_m()[0]);
        assert_eq!(grid.height_at(100.0, 100.0), grid.heights_m()[7 * 5 - 1]);
        // Bilinear between sample centres: the middle of four samples is their mean.
        // (sample coordinates 0.5, 0.5: the covered area's corner plus a sample)
        let (cx, cz) = (1.5 - 3.0 + 6.0 / 7.0, -2.0 - 2.25 + 4.5 / 5.0);
        let mean = (grid.heights_m()[0] + grid.heights_m()[1] + grid.heights_m()[7] + grid.heights_m()[8]) / 4.0;
        assert!((grid.height_at(cx, cz) - mean).abs() < 1e-5, "{} against {mean}", grid.height_at(cx, cz));
        // Lying snow keeps tiles over a heightmap too.
        let fall = WorldSnow { displace: true, ..snow };
        assert_eq!(press_ground(&WorldIdentity::new(&fall, &WorldTerrain::heightmap(grid), 16)), None);
    }

    #[test]
    fn a_height_grid_names_what_is_wrong() {
        use ground::HeightGrid;
        let field = |r: Result<HeightGrid, ground::HeightGridError>| r.expect_err("refused").field;
        assert_eq!(field(HeightGrid::new(0, 3, vec![], [0.0; 2], [1.0; 2])), "heightmap");
        assert_eq!(field(HeightGrid::new(2, 2, vec![0.0; 3], [0.0; 2], [1.0; 2])), "heightmap");
        assert_eq!(field(HeightGrid::new(2, 1, vec![0.0, f32::NAN], [0.0; 2], [1.0; 2])), "heightmap");
        assert_eq!(field(HeightGrid::new(1, 1, vec![0.0], [0.0; 2], [1.0, 0.0])), "heightmap size_m");
        assert_eq!(field(HeightGrid::new(1, 1, vec![0.0], [0.0; 2], [1.0, 1e-39])), "heightmap size_m");
        assert_eq!(field(HeightGrid::new(1, 1, vec![0.0], [f32::INFINITY, 0.0], [1.0; 2])), "heightmap center_m");
        let a = HeightGrid::new(1, 2, vec![0.0, 1.0], [0.0; 2], [1.0; 2]).expect("a grid");
        let b = HeightGrid::new(1, 2, vec![0.0, 1.5], [0.0; 2], [1.0; 2]).expect("a grid");
        assert_ne!(a.digest(), b.digest());
        // As bytes: back the same; anything else refused, saying why.
        assert_eq!(HeightGrid::from_bytes(&a.to_bytes()), Ok(a.clone()));
        let bytes = a.to_bytes();
        assert_eq!(field(HeightGrid::from_bytes(&bytes[..bytes.len() - 1])), "heightmap bytes");
        assert_eq!(field(HeightGrid::from_bytes(b"SNWP")), "heightmap bytes");
        let mut format = bytes.clone();
        format[4] = 2;
        assert_eq!(field(HeightGrid::from_bytes(&format)), "heightmap bytes");
        let mut nan = bytes;
        let last = nan.len() - 4;
        nan[last..].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(field(HeightGrid::from_bytes(&nan)), "heightmap");
    }
}
