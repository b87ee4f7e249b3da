//! [`CpuSnow`]: a [`SharedSnow`] on the CPU for tests of shared snow
//! without a device: a square window of deficits at a movable origin (not
//! toroidal: moving it copies what stays), discs and analytic shapes
//! pressed into it (the shapes' frames reported as a GPU window reports
//! them), refill by the world clock, and the tiles it changed.

use snowpack_share::replicate::WorldIdentityExt;
use std::collections::BTreeSet;

use snowpack::WorldIdentity;
use snowpack::low_level::persist::TileKey;
use snowpack::low_level::replicate::{CatchUp, ShareClock, SharedSnow, SharedTile};
use snowpack_share::replicate::press::{PressFrame, PressGround, ShapeSweep, press_tiles};

/// Tiles ahead of the snow's clock kept until it reaches them; beyond it
/// the oldest are dropped.
const MAX_HELD: usize = 4096;

/// A window of snow deficits on the CPU (see the module documentation).
#[derive(Clone, Debug)]
pub struct CpuSnow {
    world: WorldIdentity,
    resolution: u32,
    origin: [i64; 2],
    /// Row-major (row = +z), `resolution²`, in deficit quanta.
    deficit: Vec<u16>,
    time_s: f64,
    clock: ShareClock,
    changed: BTreeSet<TileKey>,
    held: Vec<SharedTile>,
    /// The frames of analytic presses not taken yet.
    frames: Vec<PressFrame>,
    /// The last frame of analytic presses, reported or not.
    last_press: Option<PressFrame>,
    /// Whether analytic presses are reported as frames (a window that
    /// shares them) or go as tiles alone.
    reports_presses: bool,
}

impl CpuSnow {
    /// Fresh snow of `world`, `resolution` texels a side, first texel at
    /// global texel `origin`, at world time `time_s`.
    #[must_use]
    pub fn new(world: WorldIdentity, resolution: u32, origin: [i64; 2], time_s: f64) -> Self {
        let n = resolution as usize * resolution as usize;
        let clock = world.clock_at(time_s);
        Self {
            world,
            resolution,
            origin,
            deficit: vec![0; n],
            time_s,
            clock,
            changed: BTreeSet::new(),
            held: Vec::new(),
            frames: Vec::new(),
            last_press: None,
            reports_presses: true,
        }
    }

    /// Global texel of the window's first texel.
    #[must_use]
    pub fn origin(&self) -> [i64; 2] {
        self.origin
    }

    /// Texels per window side.
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// World seconds the snow is at.
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The window's deficits, row-major (row = +z), in quanta.
    #[must_use]
    pub fn deficits(&self) -> &[u16] {
        &self.deficit
    }

    /// The deficit at global texel (`col`, `row`), if it is in the window.
    #[must_use]
    pub fn deficit_at(&self, col: i64, row: i64) -> Option<u16> {
        let (j, i) = (col - self.origin[0], row - self.origin[1]);
        let r = i64::from(self.resolution);
        ((0..r).contains(&j) && (0..r).contains(&i)).then(|| self.deficit[(i * r + j) as usize])
    }

    /// Moves the window so its first texel is `origin`: texels in both
    /// places keep their deficits, newly exposed ones are fresh snow.
    pub fn set_origin(&mut self, origin: [i64; 2]) {
        if origin == self.origin {
            return;
        }
        let r = i64::from(self.resolution);
        let mut next = vec![0u16; self.deficit.len()];
        for i in 0..r {
            for j in 0..r {
                if let Some(d) = self.deficit_at(origin[0] + j, origin[1] + i) {
                    next[(i * r + j) as usize] = d;
                }
            }
        }
        self.deficit = next;
        self.origin = origin;
    }

    /// Centres the window on world (`x_m`, `z_m`), snapped to whole texels.
    pub fn center_on(&mut self, x_m: f64, z_m: f64) {
        let texel = f64::from(self.world.settings().texel_m);
        let half = i64::from(self.resolution / 2);
        self.set_origin([(x_m / texel).floor() as i64 - half, (z_m / texel).floor() as i64 - half]);
    }

    /// Presses a disc: every texel whose centre is within `radius_m` of
    /// world `center_xz` gets at least `deficit` quanta; the tiles it
    /// deepened are marked changed.
    pub fn press_disc(&mut self, center_xz: [f64; 2], radius_m: f64, deficit: u16) {
        let texel = f64::from(self.world.settings().texel_m);
        let r = i64::from(self.resolution);
        for i in 0..r {
            for j in 0..r {
                let (col, row) = (self.origin[0] + j, self.origin[1] + i);
                let (x, z) = ((col as f64 + 0.5) * texel, (row as f64 + 0.5) * texel);
                if (x - center_xz[0]).hypot(z - center_xz[1]) <= radius_m {
                    let d = &mut self.deficit[(i * r + j) as usize];
                    if deficit > *d {
                        *d = deficit;
                        self.changed.insert(TileKey::containing(col, row, self.world.settings().tile_side));
                    }
                }
            }
        }
    }

    /// Presses analytic shapes, window-local as the capture takes them
    /// (x and z from the window's corner), with a capture range of
    /// `range_m` (low, high world heights) and the packing `pack_ratio`, as
    /// a GPU window does this frame (`snowpack_share::replicate::press`, the same
    /// arithmetic); the frame is kept for the peer unless
    /// [`Self::set_reports_presses`] turned that off. Needs terrain the
    /// world's identity says whole (flat, or value noise) or holds (a
    /// heightmap: [`PressGround::of_identity`]).
    pub fn press_shapes(&mut self, shapes: Vec<ShapeSweep>, range_m: (f32, f32), pack_ratio: f32) {
        let settings = self.world.settings().clone();
        let Some(ground) = PressGround::of_identity(&self.world) else { return };
        // As the capture keeps them: shapes that reach the window.
        let extent_m = settings.texel_m * self.resolution as f32;
        let shapes: Vec<ShapeSweep> = shapes.into_iter().filter(|s| s.touches_window(extent_m, settings.texel_m)).collect();
        if shapes.is_empty() {
            return;
        }
        let frame = PressFrame { clock: self.clock, origin: self.origin, resolution: self.resolution, low_m: range_m.0, high_m: range_m.1, pack_ratio, shapes };
        let casts = [frame.casts(settings.texel_m)];
        let side = i64::from(settings.tile_side);
        for tile in press_tiles(std::slice::from_ref(&frame), &casts, &settings, &ground, settings.tile_side) {
            let first = tile.key.first_texel(settings.tile_side);
            for (k, &d) in tile.deficit.iter().enumerate() {
                let (col, row) = (first[0] + k as i64 % side, first[1] + k as i64 / side);
                let (j, i) = (col - self.origin[0], row - self.origin[1]);
                let r = i64::from(self.resolution);
                if (0..r).contains(&j) && (0..r).contains(&i) && d > self.deficit[(i * r + j) as usize] {
                    self.deficit[(i * r + j) as usize] = d;
                    self.changed.insert(tile.key);
                }
            }
        }
        // As a GPU window keeps them: not a frame repeating the one before.
        if self.reports_presses && !self.last_press.as_ref().is_some_and(|last| frame.repeats(last)) {
            self.frames.push(frame.clone());
        }
        self.last_press = Some(frame);
    }

    /// Whether [`Self::press_shapes`] reports its frames to the peer (on
    /// by default): off, its presses go as tiles alone.
    pub fn set_reports_presses(&mut self, on: bool) {
        self.reports_presses = on;
    }

    /// Advances `dt_s` seconds: refill by the quanta the world clock
    /// passed, then the held tiles the clock has reached are merged.
    pub fn step(&mut self, dt_s: f64) {
        self.time_s += dt_s;
        let to = self.world.clock_at(self.time_s);
        self.advance_to(to);
    }

    fn advance_to(&mut self, to: ShareClock) {
        let refill = to.refill_quanta.saturating_sub(self.clock.refill_quanta);
        if refill > 0 {
            let q = u16::try_from(refill).unwrap_or(u16::MAX);
            for d in &mut self.deficit {
                *d = d.saturating_sub(q);
            }
        }
        self.clock = self.clock.later(&to);
        if !self.held.is_empty() {
            let held = std::mem::take(&mut self.held);
            self.merge_tiles(&held);
        }
    }

    /// The tile `key` as the window holds it (texels outside it untouched).
    fn tile(&self, key: TileKey) -> SharedTile {
        let side = self.world.settings().tile_side;
        let mut t = SharedTile::untouched(key, side, self.clock, false, false);
        let first = key.first_texel(side);
        for i in 0..i64::from(side) {
            for j in 0..i64::from(side) {
                if let Some(d) = self.deficit_at(first[0] + j, first[1] + i) {
                    t.deficit[(i * i64::from(side) + j) as usize] = d;
                }
            }
        }
        t
    }
}

impl SharedSnow for CpuSnow {
    fn share_clock(&self) -> ShareClock {
        self.clock
    }

    /// Moves the clock forward to `clock` (refilling on the way); a clock
    /// behind the snow's is ignored, since the snow cannot unrefill.
    fn join_clock(&mut self, clock: ShareClock) {
        if clock.covers(&self.clock) {
            self.time_s = self.time_s.max(clock.time_s);
            self.advance_to(clock);
        }
    }

    fn window(&self) -> Option<([i64; 2], u32)> {
        Some((self.origin, self.resolution))
    }

    fn take_changed_tiles(&mut self) -> Vec<SharedTile> {
        let keys = std::mem::take(&mut self.changed);
        keys.into_iter().map(|k| self.tile(k)).collect()
    }

    fn take_press_frames(&mut self) -> Vec<PressFrame> {
        std::mem::take(&mut self.frames)
    }

    fn merge_tiles(&mut self, tiles: &[SharedTile]) {
        let c = CatchUp { max_fallen_m: self.world.settings().max_fallen_m };
        let side = self.world.settings().tile_side;
        for t in tiles {
            if t.side != side || !t.is_consistent() {
                continue;
            }
            if !self.clock.covers(&t.clock) {
                if self.held.len() >= MAX_HELD {
                    self.held.remove(0);
                }
                self.held.push(t.clone());
                continue;
            }
            let mut t = t.clone();
            t.catch_up(&self.clock, c);
            // In i128: a tile may lie anywhere on the i64 grid.
            let first = [i128::from(t.key.col) * i128::from(side), i128::from(t.key.row) * i128::from(side)];
            let r = i128::from(self.resolution);
            for i in 0..i128::from(side) {
                for j in 0..i128::from(side) {
                    let (wj, wi) = (first[0] + j - i128::from(self.origin[0]), first[1] + i - i128::from(self.origin[1]));
                    if (0..r).contains(&wj) && (0..r).contains(&wi) {
                        let d = &mut self.deficit[(wi * r + wj) as usize];
                        *d = (*d).max(t.deficit[(i * i128::from(side) + j) as usize]);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use snowpack_share::replicate::WorldSettings;

    fn world() -> WorldIdentity {
        WorldIdentity::from_settings(WorldSettings {
            texel_m: 0.125,
            tile_side: 8,
            terrain: "flat at 0 m".to_owned(),
            depth_m: 0.5,
            refill_m_per_s: 0.001,
            snowfall_m_per_s: 0.0,
            max_fallen_m: 0.0,
            has_snowfall: false,
            stamp_range_m: [-1.0, 1.0],
        })
    }

    #[test]
    fn presses_refill_by_the_world_clock_and_moving_exposes_fresh_snow() {
        let mut snow = CpuSnow::new(world(), 16, [0, 0], 0.0);
        snow.press_disc([1.0, 1.0], 0.2, 100);
        assert_eq!(snow.deficit_at(8, 8), Some(100));
        let changed = snow.take_changed_tiles();
        assert_eq!(changed.iter().map(|t| t.key).collect::<Vec<_>>(), vec![TileKey::new(0, 0), TileKey::new(0, 1), TileKey::new(1, 0), TileKey::new(1, 1)]);
        assert!(snow.take_changed_tiles().is_empty(), "taken once");
        snow.step(0.5); // 0.5 mm of refill: 5 quanta
        assert_eq!(snow.deficit_at(8, 8), Some(95));
        snow.set_origin([8, 8]);
        assert_eq!(snow.deficit_at(8, 8), Some(95), "kept where the windows overlap");
        snow.set_origin([0, 0]);
        assert_eq!(snow.deficit_at(0, 0), Some(0));
        assert_eq!(snow.deficit_at(8, 8), Some(95));
    }

    #[test]
    fn tiles_ahead_of_the_clock_wait_for_it() {
        let w = world();
        let mut snow = CpuSnow::new(w.clone(), 16, [0, 0], 0.0);
        let mut ahead = SharedTile::untouched(TileKey::new(0, 0), 8, w.clock_at(1.0), false, false);
        ahead.deficit[0] = 50;
        snow.merge_tiles(std::slice::from_ref(&ahead));
        assert_eq!(snow.deficit_at(0, 0), Some(0), "held");
        snow.step(1.0);
        assert_eq!(snow.deficit_at(0, 0), Some(50), "merged once the clock reached it");
        let mut behind = SharedTile::untouched(TileKey::new(0, 0), 8, w.clock_at(0.0), false, false);
        behind.deficit[1] = 50;
        snow.merge_tiles(&[behind]);
        assert_eq!(snow.deficit_at(1, 0), Some(40), "caught up by the 10 quanta it missed");
        // Anywhere on the grid, without overflow.
        let far = SharedTile::untouched(TileKey::new(i64::MAX, i64::MIN), 8, w.clock_at(0.0), false, false);
        snow.merge_tiles(&[far]);
    }
}
