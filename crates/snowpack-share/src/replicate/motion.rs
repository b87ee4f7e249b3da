//! Where a relay lets a peer write: the positions its deformers were
//! reported at (by the peer, held to a top speed, or by a game server with
//! authority), in a grid hash so that judging one tile costs a fixed number
//! of look-ups however many positions were reported. Std only: the relay's
//! police, apart from its sockets and its GPU-free merging.

use std::collections::{HashMap, VecDeque};

/// The most positions (with their times) a peer's history keeps; beyond
/// it the oldest are forgotten early. 128 snapshots of 256 deformers.
pub const MAX_REMEMBERED: usize = 128 * 256;

/// Distance (m) any deformer may move between two reports, whatever the
/// time between them: a report's own rounding, a foot planted ahead.
pub const MOVE_SLACK_M: f64 = 1.0;

/// How far (in list places) a deformer's report may be from where its
/// previous one was: deformers added or removed shift the ones after them.
pub const REORDER: usize = 8;

/// How many grid cells span the reach: the grid cell is `reach / CELLS_PER_REACH`.
/// Judging a tile looks up `(2 CELLS_PER_REACH + 1)²` cells, and a position
/// counts as anywhere in its cell, so the reach is generous by at most
/// `√2 / CELLS_PER_REACH` of itself.
const CELLS_PER_REACH: f64 = 4.0;

/// What a peer's deformers did, as the relay knows it.
#[derive(Debug, Default)]
pub struct MotionHistory {
    /// Grid cell side (m); 0 before the first position.
    cell_m: f64,
    /// Cell → the latest time a deformer was reported in it.
    cells: HashMap<(i64, i64), f64>,
    /// Positions in the order they were recorded, for expiry and for
    /// rebuilding the grid at another cell size.
    log: VecDeque<(f64, [f64; 2])>,
    /// The last accepted position of each deformer (by its index in the
    /// reports) and when; `None` for an index never accepted.
    last: Vec<Option<([f64; 2], f64)>>,
    /// Whether the peer has reported any positions (its first report may
    /// place deformers anywhere: the relay cannot know where it spawned).
    started: bool,
}

/// What one call cost and refused, for the relay's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MotionWork {
    /// Point-to-point or point-to-cell distance tests made.
    pub distance_tests: u64,
    /// Positions refused as moved faster than allowed.
    pub teleports: u64,
}

impl MotionHistory {
    /// Forgets every position (a game server with authority takes over).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// Records a peer's own report at `now`: each finite position is kept
    /// if that deformer (same index; else any of the peer's last accepted
    /// ones) could have reached it at `max_speed` (m/s) since its last
    /// accepted report, plus [`MOVE_SLACK_M`]. The first report is taken
    /// as it is.
    pub fn report(&mut self, positions: &[[f64; 2]], now: f64, max_speed: f64, reach: f64, memory: f64) -> MotionWork {
        let mut work = MotionWork::default();
        let first = !self.started;
        for (i, p) in positions.iter().enumerate().take(super::message::MAX_DEFORMERS) {
            if !(p[0].is_finite() && p[1].is_finite()) {
                continue;
            }
            if !first && !self.plausible(i, *p, now, max_speed, &mut work) {
                work.teleports += 1;
                continue;
            }
            if self.last.len() <= i {
                self.last.resize(i + 1, None);
            }
            self.last[i] = Some((*p, now));
            self.record(*p, now, reach);
        }
        self.started |= positions.iter().any(|p| p[0].is_finite() && p[1].is_finite());
        self.expire(now - memory);
        work
    }

    /// Records positions a game server with authority reported: no speed test.
    pub fn authoritative(&mut self, positions: &[[f64; 2]], now: f64, reach: f64, memory: f64) {
        for (i, p) in positions.iter().enumerate().take(super::message::MAX_DEFORMERS) {
            if p[0].is_finite() && p[1].is_finite() {
                if self.last.len() <= i {
                    self.last.resize(i + 1, None);
                }
                self.last[i] = Some((*p, now));
                self.record(*p, now, reach);
            }
        }
        self.started = true;
        self.expire(now - memory);
    }

    /// Whether deformer `i` may be at `p` now: near the last accepted
    /// position of deformer `i` or of one up to [`REORDER`] places from it
    /// (deformers come and go, shifting the list), so at most
    /// `2 REORDER + 1` tests a position.
    fn plausible(&self, i: usize, p: [f64; 2], now: f64, max_speed: f64, work: &mut MotionWork) -> bool {
        let near = |(q, at): ([f64; 2], f64)| (p[0] - q[0]).hypot(p[1] - q[1]) <= max_speed.max(0.0) * (now - at).max(0.0) + MOVE_SLACK_M;
        let (lo, hi) = (i.saturating_sub(REORDER), (i + REORDER + 1).min(self.last.len()));
        let mut order = std::iter::once(i).chain((lo..hi).filter(|&j| j != i));
        order.any(|j| match self.last.get(j).copied().flatten() {
            Some(l) => {
                work.distance_tests += 1;
                near(l)
            }
            None => false,
        })
    }

    /// Whether some position recorded since `oldest` lies within `reach` of
    /// `centre` (counting a position as anywhere in its grid cell).
    pub fn near(&mut self, centre: [f64; 2], reach: f64, oldest: f64, work: &mut MotionWork) -> bool {
        if self.cells.is_empty() || !(reach.is_finite() && reach > 0.0) {
            return false;
        }
        self.fit_cells(reach);
        let c = self.cell_m;
        // A position within the reach is at most CELLS_PER_REACH cells away on each axis.
        let k = CELLS_PER_REACH as i64;
        let (ci, cj) = ((centre[0] / c).floor(), (centre[1] / c).floor());
        if !(ci.abs() < 4e18 && cj.abs() < 4e18) {
            return false;
        }
        let (ci, cj) = (ci as i64, cj as i64);
        for dj in -k..=k {
            for di in -k..=k {
                let cell = (ci + di, cj + dj);
                work.distance_tests += 1;
                if self.cells.get(&cell).is_some_and(|&at| at >= oldest) && cell_distance(cell, c, centre) <= reach {
                    return true;
                }
            }
        }
        false
    }

    /// Positions remembered now.
    #[must_use]
    pub fn len(&self) -> usize {
        self.log.len()
    }

    /// Whether no position is remembered.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.log.is_empty()
    }

    fn record(&mut self, p: [f64; 2], now: f64, reach: f64) {
        if self.cell_m <= 0.0 {
            self.cell_m = cell_for(reach);
        }
        let cell = cell_of(p, self.cell_m);
        let newer = self.cells.get(&cell).is_none_or(|&at| at < now);
        if newer {
            self.cells.insert(cell, now);
        }
        self.log.push_back((now, p));
        while self.log.len() > MAX_REMEMBERED {
            self.pop_oldest();
        }
    }

    /// Drops positions older than `oldest`.
    fn expire(&mut self, oldest: f64) {
        while self.log.front().is_some_and(|(at, _)| *at < oldest) {
            self.pop_oldest();
        }
    }

    fn pop_oldest(&mut self) {
        if let Some((at, p)) = self.log.pop_front() {
            let cell = cell_of(p, self.cell_m);
            // Only if no later position refreshed the cell.
            if self.cells.get(&cell).is_some_and(|&t| t <= at) {
                self.cells.remove(&cell);
            }
        }
    }

    /// Rebuilds the grid when the reach changed (the relay's settings did).
    fn fit_cells(&mut self, reach: f64) {
        let want = cell_for(reach);
        if (self.cell_m - want).abs() <= want * 1e-9 {
            return;
        }
        self.cell_m = want;
        self.cells.clear();
        for &(at, p) in &self.log {
            let slot = self.cells.entry(cell_of(p, want)).or_insert(at);
            *slot = slot.max(at);
        }
    }
}

fn cell_for(reach: f64) -> f64 {
    if reach.is_finite() && reach > 0.0 { reach / CELLS_PER_REACH } else { 1.0 }
}

fn cell_of(p: [f64; 2], cell_m: f64) -> (i64, i64) {
    // Saturating casts: far positions share the edge cells, which no real tile is near.
    ((p[0] / cell_m).floor() as i64, (p[1] / cell_m).floor() as i64)
}

/// Distance from `centre` to the nearest point of grid cell `cell`.
fn cell_distance(cell: (i64, i64), c: f64, centre: [f64; 2]) -> f64 {
    let axis = |i: i64, x: f64| {
        let (lo, hi) = (i as f64 * c, (i + 1) as f64 * c);
        if x < lo {
            lo - x
        } else if x > hi {
            x - hi
        } else {
            0.0
        }
    };
    axis(cell.0, centre[0]).hypot(axis(cell.1, centre[1]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_first_report_goes_anywhere_and_later_ones_at_the_top_speed() {
        let mut h = MotionHistory::default();
        let reach = 8.0;
        assert_eq!(h.report(&[[1000.0, 5.0]], 0.0, 60.0, reach, 30.0).teleports, 0);
        // 1 s later, 59 m on: plausible. 1 s after that, 500 m on: not.
        assert_eq!(h.report(&[[1059.0, 5.0]], 1.0, 60.0, reach, 30.0).teleports, 0);
        assert_eq!(h.report(&[[1559.0, 5.0]], 2.0, 60.0, reach, 30.0).teleports, 1);
        let mut w = MotionWork::default();
        assert!(h.near([1059.0, 5.0], reach, 0.0, &mut w));
        assert!(!h.near([1559.0, 5.0], reach, 0.0, &mut w));
        // The refused report did not move the deformer: 10 s on, 500 m is reachable.
        assert_eq!(h.report(&[[1559.0, 5.0]], 11.0, 60.0, reach, 30.0).teleports, 0);
        // An empty report does not restart the history.
        h.report(&[], 12.0, 60.0, reach, 30.0);
        assert_eq!(h.report(&[[-9000.0, 0.0]], 12.5, 60.0, reach, 30.0).teleports, 1);
    }

    #[test]
    fn a_shifted_list_is_not_a_teleport_but_a_shuffled_one_is() {
        let mut h = MotionHistory::default();
        let line: Vec<[f64; 2]> = (0..40).map(|k| [f64::from(k) * 100.0, 0.0]).collect();
        h.report(&line, 0.0, 60.0, 8.0, 30.0);
        // One removed at the front: every other moves one place.
        assert_eq!(h.report(&line[1..], 0.1, 60.0, 8.0, 30.0).teleports, 0);
        let mut reversed = line.clone();
        reversed.reverse();
        let work = h.report(&reversed, 0.2, 60.0, 8.0, 30.0);
        assert!(work.teleports >= 20, "{work:?}");
        assert!(work.distance_tests <= 40 * (2 * REORDER as u64 + 1), "{work:?}");
    }

    #[test]
    fn judging_a_tile_costs_the_same_however_many_positions() {
        let mut h = MotionHistory::default();
        let reach = 8.0;
        let many: Vec<[f64; 2]> = (0..256).map(|k| [f64::from(k) * 0.01, 0.0]).collect();
        for t in 0..200 {
            h.authoritative(&many, f64::from(t) * 0.1, reach, 30.0);
        }
        assert!(h.len() <= MAX_REMEMBERED);
        let mut w = MotionWork::default();
        assert!(!h.near([500.0, 500.0], reach, 0.0, &mut w));
        let side = 2 * CELLS_PER_REACH as u64 + 1;
        assert_eq!(w.distance_tests, side * side);
        // Near, with the cell's slack at most √2 / 4 of the reach.
        assert!(h.near([reach + 2.5, 0.0], reach, 0.0, &mut w));
        assert!(!h.near([reach * (1.0 + std::f64::consts::SQRT_2 / CELLS_PER_REACH) + 3.0, 0.0], reach, 0.0, &mut w));
    }

    #[test]
    fn old_positions_expire() {
        let mut h = MotionHistory::default();
        h.authoritative(&[[0.0, 0.0]], 0.0, 8.0, 30.0);
        h.authoritative(&[[100.0, 0.0]], 40.0, 8.0, 30.0);
        let mut w = MotionWork::default();
        assert!(!h.near([0.0, 0.0], 8.0, 10.0, &mut w));
        assert!(h.near([100.0, 0.0], 8.0, 10.0, &mut w));
        assert_eq!(h.len(), 1);
    }
}
