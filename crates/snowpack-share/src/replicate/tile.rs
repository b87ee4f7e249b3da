//! A tile of shared snow: the persistent state of `side`×`side` texels as
//! the window holds it (a deficit below the rest height in whole quanta,
//! the packed footprint, the snowfall lying), with the world clock it is
//! current at, and the merge that makes copies of it converge.
//!
//! Every step of the simulation is monotone in the deficit (a press is a
//! maximum, refill a saturating subtraction, the clamp at the terrain a
//! minimum), so two copies brought to the same clock merge by the
//! texel-wise maximum deficit (and maximum snowfall, minimum footprint):
//! commutative, associative and idempotent. `docs/multiplayer.md` says why
//! and where it is not exact.

use crate::persist::TileKey;

/// Metres per deficit quantum: the persistent snow, tiles and the world
/// clock's refill count in it (snowpack's `deform::snow_word` packs it).
pub const SNOW_QUANTUM_M: f32 = 1e-4;

/// A footprint texel with no footprint (`shared/stamp.wgsl`'s `STAMP_EMPTY`).
pub const NO_STAMP: u32 = u32::MAX;

/// The world clock as cumulative counters: what a tile's contents are
/// current at. Two copies of a tile merge once brought to the later of
/// their clocks ([`SharedTile::catch_up`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShareClock {
    /// World seconds since the world began.
    pub time_s: f64,
    /// Snow refill so far, in deficit quanta ([`SNOW_QUANTUM_M`]).
    pub refill_quanta: u64,
    /// Footprint refill so far, in stamp quanta.
    pub stamp_quanta: u64,
    /// Snowfall so far on open ground (m), capped at the world's most.
    pub fallen_m: f32,
}

impl ShareClock {
    /// Whether `self` is at or after `other` on every counter.
    #[must_use]
    pub fn covers(&self, other: &Self) -> bool {
        self.refill_quanta >= other.refill_quanta && self.stamp_quanta >= other.stamp_quanta && self.fallen_m >= other.fallen_m
    }

    /// The later of two clocks, counter by counter.
    #[must_use]
    pub fn later(&self, other: &Self) -> Self {
        Self {
            time_s: self.time_s.max(other.time_s),
            refill_quanta: self.refill_quanta.max(other.refill_quanta),
            stamp_quanta: self.stamp_quanta.max(other.stamp_quanta),
            fallen_m: self.fallen_m.max(other.fallen_m),
        }
    }
}

/// One tile of shared snow, row-major (row = +z), `side²` texels per plane.
///
/// Texels a sender did not see (outside its window) hold the merge's
/// identity: deficit 0, no footprint, snowfall 0, no packed snow.
#[derive(Clone, Debug, PartialEq)]
pub struct SharedTile {
    /// Where the tile is on the global tile grid.
    pub key: TileKey,
    /// Texels per side.
    pub side: u32,
    /// The clock the contents are current at.
    pub clock: ShareClock,
    /// Rest height minus the persistent snow height, in [`SNOW_QUANTUM_M`] steps.
    pub deficit: Vec<u16>,
    /// Packed footprints (`shared/stamp.wgsl`); empty when the world has none.
    pub stamps: Vec<u32>,
    /// Snowfall lying per texel (m); empty when the world has no snowfall.
    pub fallen: Vec<f32>,
    /// Packed snow per texel ([`SNOW_QUANTUM_M`] steps of fresh snow that
    /// presses squeezed into the column, `docs/mechanics.md`); empty reads
    /// as none.
    pub packed: Vec<u16>,
}

/// How time passing changes a tile: the world's snowfall cap.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CatchUp {
    /// The most snowfall a texel keeps (m).
    pub max_fallen_m: f32,
}

impl SharedTile {
    /// Untouched snow (the merge's identity) at `clock`, with the planes the
    /// world has.
    #[must_use]
    pub fn untouched(key: TileKey, side: u32, clock: ShareClock, stamps: bool, fallen: bool) -> Self {
        let n = (side as usize) * (side as usize);
        Self {
            key,
            side,
            clock,
            deficit: vec![0; n],
            stamps: if stamps { vec![NO_STAMP; n] } else { Vec::new() },
            fallen: if fallen { vec![0.0; n] } else { Vec::new() },
            packed: Vec::new(),
        }
    }

    /// Texels per plane.
    #[must_use]
    pub fn texels(&self) -> usize {
        (self.side as usize) * (self.side as usize)
    }

    /// Whether every plane has `side²` texels (or none, for footprints,
    /// snowfall and packed snow).
    #[must_use]
    pub fn is_consistent(&self) -> bool {
        let n = self.texels();
        self.deficit.len() == n
            && (self.stamps.is_empty() || self.stamps.len() == n)
            && (self.fallen.is_empty() || self.fallen.len() == n)
            && (self.packed.is_empty() || self.packed.len() == n)
    }

    /// The deepest deficit in the tile (m).
    #[must_use]
    pub fn deepest_m(&self) -> f32 {
        f32::from(self.deficit.iter().copied().max().unwrap_or(0)) * SNOW_QUANTUM_M
    }

    /// Brings the tile forward to `to` (a clock at or after its own, counter
    /// by counter; counters behind are left as they are): refill lowers each
    /// deficit by the quanta passed (saturating), footprints rise by the
    /// stamp quanta passed (gone once their foot leaves the quantised range),
    /// snowfall lying grows by the snowfall passed, up to the cap.
    ///
    /// This treats every texel as open to the sky, as the tile weather pass
    /// does for tiles away from the window.
    pub fn catch_up(&mut self, to: &ShareClock, c: CatchUp) {
        let refill = to.refill_quanta.saturating_sub(self.clock.refill_quanta);
        if refill > 0 {
            let r = u16::try_from(refill).unwrap_or(u16::MAX);
            for d in &mut self.deficit {
                *d = d.saturating_sub(r);
            }
        }
        let quanta = to.stamp_quanta.saturating_sub(self.clock.stamp_quanta);
        if quanta > 0 {
            let q = u32::try_from(quanta.min(65_536)).unwrap_or(65_536);
            for s in &mut self.stamps {
                *s = refill_stamp(*s, q);
            }
        }
        let fall = to.fallen_m - self.clock.fallen_m;
        if fall > 0.0 {
            for f in &mut self.fallen {
                *f = f.max((*f + fall).min(c.max_fallen_m));
            }
        }
        self.clock = self.clock.later(to);
    }

    /// Folds `other` (the same key and side) into `self`: both are brought
    /// to the later of their clocks, then each texel takes the deeper
    /// deficit, the lower footprint, the deeper snowfall and the more packed
    /// snow. A plane one
    /// side lacks counts as untouched. Returns whether `self` changed
    /// (beyond its clock).
    ///
    /// # Panics
    /// Never on consistent tiles; tiles of different keys or sides are left
    /// unchanged (returns `false`).
    pub fn merge(&mut self, other: &Self, c: CatchUp) -> bool {
        if other.key != self.key || other.side != self.side || !other.is_consistent() || !self.is_consistent() {
            return false;
        }
        let to = self.clock.later(&other.clock);
        self.catch_up(&to, c);
        let theirs_owned;
        let theirs = if other.clock == to {
            other
        } else {
            let mut o = other.clone();
            o.catch_up(&to, c);
            theirs_owned = o;
            &theirs_owned
        };
        if !theirs.stamps.is_empty() && self.stamps.is_empty() {
            self.stamps = vec![NO_STAMP; self.texels()];
        }
        if !theirs.fallen.is_empty() && self.fallen.is_empty() {
            self.fallen = vec![0.0; self.texels()];
        }
        if !theirs.packed.is_empty() && self.packed.is_empty() {
            self.packed = vec![0; self.texels()];
        }
        let mut changed = false;
        for k in 0..self.texels() {
            let (mine, other) = (self.texel(k), theirs.texel(k));
            let merged = mine.merge(other);
            if !merged.same(mine) {
                changed = true;
                // Both deficits are u16: so is their maximum.
                self.deficit[k] = merged.deficit as u16;
                if let Some(s) = self.stamps.get_mut(k) {
                    *s = merged.stamp;
                }
                if let Some(f) = self.fallen.get_mut(k) {
                    *f = merged.fallen_m;
                }
                if let Some(p) = self.packed.get_mut(k) {
                    // Both are u16: so is their maximum.
                    *p = merged.packed as u16;
                }
            }
        }
        changed
    }

    /// What `self` adds to `base` (the same key and side: a copy the other
    /// side is known to hold): `self` at the later of the two clocks with
    /// every texel `base` already covers (its merge with `base`'s texel is
    /// `base`'s) set to the merge's identity (deficit 0, no footprint, no
    /// snowfall, no packed snow), which deflates to almost nothing. Merged into anything
    /// that holds `base`, it gives what `self` would. `None` when it adds
    /// nothing, or when the tiles do not match.
    #[must_use]
    pub fn beyond(&self, base: &Self, c: CatchUp) -> Option<Self> {
        if base.key != self.key || base.side != self.side || !base.is_consistent() || !self.is_consistent() {
            return None;
        }
        let to = self.clock.later(&base.clock);
        let mut out = self.clone();
        out.catch_up(&to, c);
        let mut base = base.clone();
        base.catch_up(&to, c);
        let mut adds = false;
        for k in 0..out.texels() {
            let (theirs, mine) = (base.texel(k), out.texel(k));
            let merged = theirs.merge(mine);
            if merged.same(theirs) {
                out.deficit[k] = 0;
                if let Some(s) = out.stamps.get_mut(k) {
                    *s = NO_STAMP;
                }
                if let Some(f) = out.fallen.get_mut(k) {
                    *f = 0.0;
                }
                if let Some(p) = out.packed.get_mut(k) {
                    *p = 0;
                }
            } else {
                adds = true;
            }
        }
        adds.then_some(out)
    }

    /// Texel `k`'s copy; a plane the tile lacks reads as the merge's identity.
    fn texel(&self, k: usize) -> TexelCopy {
        TexelCopy {
            deficit: u32::from(self.deficit[k]),
            stamp: self.stamps.get(k).copied().unwrap_or(NO_STAMP),
            fallen_m: self.fallen.get(k).copied().unwrap_or(0.0),
            packed: u32::from(self.packed.get(k).copied().unwrap_or(0)),
        }
    }

    /// A 64-bit digest of the clock's counters and the planes (FNV-1a over
    /// their bytes): equal tiles have equal digests, on every machine.
    #[must_use]
    pub fn digest(&self) -> u64 {
        let mut h = Fnv::new();
        h.write(&self.key.col.to_le_bytes());
        h.write(&self.key.row.to_le_bytes());
        h.write(&self.side.to_le_bytes());
        h.write(&self.clock.refill_quanta.to_le_bytes());
        h.write(&self.clock.stamp_quanta.to_le_bytes());
        h.write(&self.clock.fallen_m.to_bits().to_le_bytes());
        for d in &self.deficit {
            h.write(&d.to_le_bytes());
        }
        h.write(&[u8::from(!self.stamps.is_empty())]);
        for s in &self.stamps {
            h.write(&s.to_le_bytes());
        }
        h.write(&[u8::from(!self.fallen.is_empty())]);
        for f in &self.fallen {
            h.write(&f.to_bits().to_le_bytes());
        }
        // No packed snow reads as a plane of zeros, whichever the tile
        // holds, so both digest alike (and as they did before the plane).
        if self.packed.iter().any(|&p| p != 0) {
            h.write(&[1]);
            for p in &self.packed {
                h.write(&p.to_le_bytes());
            }
        }
        h.finish()
    }

    /// Snow depth above the terrain (m) at texel (`x`, `z`) of the tile:
    /// the rest depth plus the snowfall lying there, less the deficit, not
    /// below zero. Needs no terrain: the deficit is measured from the rest
    /// height, which is the terrain plus both.
    #[must_use]
    pub fn depth_at(&self, x: usize, z: usize, depth_m: f32) -> f32 {
        let k = z * self.side as usize + x;
        let lying = self.fallen.get(k).copied().unwrap_or(0.0);
        let d = f32::from(self.deficit.get(k).copied().unwrap_or(0)) * SNOW_QUANTUM_M;
        (depth_m + lying - d).max(0.0)
    }

    /// Packed snow (m of fresh snow squeezed into the column) at texel
    /// (`x`, `z`) of the tile.
    #[must_use]
    pub fn packed_at(&self, x: usize, z: usize) -> f32 {
        let k = z * self.side as usize + x;
        f32::from(self.packed.get(k).copied().unwrap_or(0)) * SNOW_QUANTUM_M
    }
}

/// One texel of a copy of the snow, brought to a common clock with the
/// other copies it merges with: the deficit below its rest height (quanta),
/// its packed footprint, the snowfall lying there, its packed snow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelCopy {
    /// Rest height minus the persistent snow height ([`SNOW_QUANTUM_M`] steps).
    pub deficit: u32,
    /// Packed footprint ([`NO_STAMP`]: none).
    pub stamp: u32,
    /// Snowfall lying (m).
    pub fallen_m: f32,
    /// Packed snow ([`SNOW_QUANTUM_M`] steps).
    pub packed: u32,
}

impl TexelCopy {
    /// The merge of two copies of a texel, the rule every copy of the snow
    /// converges by: the deeper deficit, the lower footprint, the deeper
    /// snowfall, the more packed snow (commutative, associative,
    /// idempotent). Presses only ever raise the deficit and the packed
    /// snow together, so copies that only saw presses merge exactly
    /// (`docs/mechanics.md`, "What merges"). [`SharedTile::merge`]
    /// folds shared tiles with it; the tile restore pass folds a stored tile
    /// into what the window made in its place while the disk was late
    /// (`tile_restore.wgsl` runs the same rule, `cpu::tile_restore` is its twin).
    #[must_use]
    pub fn merge(self, other: Self) -> Self {
        // Bit patterns of non-negative floats order as the floats do.
        let fallen_m = if other.fallen_m.to_bits() > self.fallen_m.to_bits() && other.fallen_m >= 0.0 { other.fallen_m } else { self.fallen_m };
        Self { deficit: self.deficit.max(other.deficit), stamp: self.stamp.min(other.stamp), fallen_m, packed: self.packed.max(other.packed) }
    }

    /// Whether two copies are the same bit for bit.
    #[must_use]
    pub fn same(self, other: Self) -> bool {
        self.deficit == other.deficit && self.stamp == other.stamp && self.fallen_m.to_bits() == other.fallen_m.to_bits() && self.packed == other.packed
    }
}

/// One frame's footprint refill of `q` quanta on packed footprint `s`,
/// without the rest-height test (which needs the terrain; the window's merge
/// pass applies it).
#[must_use]
pub fn refill_stamp(s: u32, q: u32) -> u32 {
    if s == NO_STAMP || q == 0 {
        return s;
    }
    let (hq, fq) = (s >> 16, s & 0xffff);
    let foot = fq + q;
    if foot > 65_535 { NO_STAMP } else { ((hq + q).min(65_535) << 16) | foot }
}

/// FNV-1a, 64 bits: a digest that is the same on every platform and build
/// (std's hashers promise neither).
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clock(q: u64) -> ShareClock {
        ShareClock { time_s: q as f64, refill_quanta: q, stamp_quanta: q, fallen_m: 0.0 }
    }

    #[test]
    fn merging_takes_the_deeper_deficit_after_catching_up() {
        let key = TileKey::new(0, 0);
        let mut a = SharedTile::untouched(key, 2, clock(0), false, false);
        a.deficit = vec![100, 0, 50, 7];
        let mut b = SharedTile::untouched(key, 2, clock(10), false, false);
        b.deficit = vec![80, 30, 0, 0];
        assert!(a.merge(&b, CatchUp::default()));
        assert_eq!(a.deficit, vec![90, 30, 40, 0]);
        assert_eq!(a.clock.refill_quanta, 10);
        assert!(!a.clone().merge(&b, CatchUp::default()), "idempotent");
    }

    /// A random tile of side 8 at `clock` (xorshift over `state`).
    fn random_tile(state: &mut u64, clock: ShareClock) -> SharedTile {
        let mut next = || {
            *state ^= *state << 13;
            *state ^= *state >> 7;
            *state ^= *state << 17;
            *state
        };
        let mut t = SharedTile::untouched(TileKey::new(3, -2), 8, clock, true, true);
        // Half the tiles carry packed snow, the others none (as older peers send).
        if next() % 2 == 0 {
            t.packed = vec![0; t.texels()];
        }
        for k in 0..t.texels() {
            let r = next();
            t.deficit[k] = if r % 3 == 0 { 0 } else { (r >> 8) as u16 % 900 };
            t.stamps[k] = if r % 5 == 0 { ((r >> 20) as u32 % 60_000) << 16 | ((r >> 40) as u32 % 60_000) } else { NO_STAMP };
            t.fallen[k] = if r % 7 == 0 { ((r >> 30) % 100) as f32 * 1e-3 } else { 0.0 };
            if let Some(p) = t.packed.get_mut(k) {
                *p = if r % 4 == 0 { (r >> 50) as u16 % 900 } else { 0 };
            }
        }
        t
    }

    /// What a tile adds to a copy the relay holds, merged into anything
    /// that holds that copy, gives what the whole tile would: for random
    /// tiles, copies and relays, at equal and later clocks.
    #[test]
    fn what_a_tile_adds_to_an_acknowledged_copy_merges_as_the_whole_tile() {
        let c = CatchUp { max_fallen_m: 0.2 };
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let (mut smaller, mut none) = (0, 0);
        for round in 0..200u64 {
            let acked = random_tile(&mut state, clock(round % 3));
            // What the peer holds now: the acknowledged copy and new presses.
            let mut now = acked.clone();
            now.merge(&random_tile(&mut state, clock(round % 5)), c);
            if round % 4 == 0 {
                now = acked.clone();
            }
            // The relay: the acknowledged copy and others' presses.
            let mut relay = acked.clone();
            relay.merge(&random_tile(&mut state, clock(round % 4)), c);
            let mut whole = relay.clone();
            whole.merge(&now, c);
            match now.beyond(&acked, c) {
                Some(delta) => {
                    let mut by_delta = relay.clone();
                    by_delta.merge(&delta, c);
                    assert_eq!(by_delta, whole, "round {round}");
                    smaller += usize::from(crate::replicate::message::encode_tile(&delta).len() < crate::replicate::message::encode_tile(&now).len());
                }
                None => {
                    none += 1;
                    assert_eq!(
                        whole,
                        {
                            let mut r = relay.clone();
                            r.catch_up(&whole.clock, c);
                            r
                        },
                        "round {round}: nothing added, yet the merge changed"
                    );
                }
            }
        }
        assert!(none >= 40 && smaller > 100, "{none} tiles added nothing, {smaller} deltas were smaller");
    }
}
