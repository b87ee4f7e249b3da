//! World time as the snow counts it: the clock a tile away from the window
//! missed, the refill counters (whole quanta, counted from the world time so
//! that machines with different frame times agree) and the snowfall so far.

use crate::SnowParams;
use crate::deform::snow_word::SNOW_QUANTUM_M;
use crate::persist::SnowClock;
use crate::replicate::ShareClock;

/// Where the cumulative refill counters are counted from: at world time
/// `t` they are `base + floor(rate * (t - time_s) / quantum)` (f64), so two
/// machines agree whatever their frame times; set when the rate changes or a
/// clock is joined or loaded. The world's own base is (0, 0, 0)
/// ([`crate::replicate::WorldIdentity::clock_at`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct RefillBase {
    /// World time the counters start from (s).
    pub time_s: f64,
    /// Snow quanta at `time_s`.
    pub snow_quanta: u64,
    /// Stamp quanta at `time_s`.
    pub stamp_quanta: u64,
}

impl RefillBase {
    /// Quanta counted from `base` by `time_s` at `rate_m_per_s`, `quantum_m` each.
    pub(super) fn quanta_at(&self, base: u64, time_s: f64, rate_m_per_s: f32, quantum_m: f32) -> u64 {
        let quantum = f64::from(quantum_m);
        if quantum <= 0.0 {
            return base;
        }
        // The same expression as `WorldIdentity::clock_at` with a zero base.
        let refill_m = f64::from(rate_m_per_s.max(0.0)) * (time_s - self.time_s).max(0.0);
        base + (refill_m / quantum).floor() as u64
    }
}

/// The snow's time: its clock, refill counters and snowfall so far.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SnowTime {
    /// Time, refill and snowfall so far: what a tile away from the window missed.
    pub clock: SnowClock,
    /// Snow refill so far, in deficit quanta: the world clock's counter
    /// ([`super::SnowDeformation::share_clock`]); the stamp quanta are `clock.stamp_quanta`.
    pub snow_quanta: u64,
    /// Where the refill counters are counted from: they are a function of
    /// the time since (see [`RefillBase`]).
    pub refill_base: RefillBase,
    /// Snowfall so far on open ground (m), given to texels the window exposes.
    pub fallen_m: f32,
}

/// What one frame of `dt_s` seconds adds: refill and snowfall in metres and
/// the quanta the passes apply, and the counters after it.
#[derive(Clone, Copy, Debug)]
pub(super) struct FrameRefill {
    /// Refill this frame (m).
    pub refill_m: f32,
    /// Snowfall this frame on open ground (m).
    pub fall_m: f32,
    /// Footprint quanta this frame (at most 65,536: a footprint is gone after that).
    pub refill_quanta: u32,
    /// Deficit quanta this frame (at most 65,535: a deficit is gone after that).
    pub snow_refill_quanta: u32,
    /// World time after the frame (s).
    time_after: f64,
    /// Footprint quanta so far, after the frame.
    stamp_total: u64,
    /// Deficit quanta so far, after the frame.
    snow_total: u64,
}

impl SnowTime {
    /// This frame's refill and snowfall under `params`, footprints quantised
    /// by `stamp_quantum_m`. Footprints and the snow refill by whole quanta,
    /// counted from the world time (RefillBase): the frame applies what the
    /// counters gained, so machines with different frame times agree.
    pub(super) fn refill(&self, params: &SnowParams, dt_s: f32, stamp_quantum_m: f32) -> FrameRefill {
        let refill_m = params.refill_m_per_s * dt_s.max(0.0);
        let fall_m = params.snowfall.as_ref().map_or(0.0, |s| s.rate_m_per_s * dt_s.max(0.0));
        let time_after = self.clock.time_s + f64::from(dt_s.max(0.0));
        let base = self.refill_base;
        let stamp_total = base.quanta_at(base.stamp_quanta, time_after, params.refill_m_per_s, stamp_quantum_m).max(self.clock.stamp_quanta);
        let snow_total = base.quanta_at(base.snow_quanta, time_after, params.refill_m_per_s, SNOW_QUANTUM_M).max(self.snow_quanta);
        // A footprint is gone after 65536 quanta and a deficit after 65535,
        // so larger steps (a long pause) change nothing more.
        let refill_quanta = (stamp_total - self.clock.stamp_quanta).min(65_536) as u32;
        let snow_refill_quanta = (snow_total - self.snow_quanta).min(65_535) as u32;
        FrameRefill { refill_m, fall_m, refill_quanta, snow_refill_quanta, time_after, stamp_total, snow_total }
    }

    /// Moves the time on by a frame's `refill`; the snowfall so far stops at `max_fallen_m`.
    pub(super) fn advance(&mut self, refill: &FrameRefill, max_fallen_m: f32) {
        self.clock.time_s = refill.time_after;
        self.clock.refill_m += f64::from(refill.refill_m);
        self.clock.fallen_m += f64::from(refill.fall_m);
        self.clock.stamp_quanta = refill.stamp_total;
        self.snow_quanta = refill.snow_total;
        self.fallen_m = (self.fallen_m + refill.fall_m).min(max_fallen_m);
    }

    /// The counters go on from now (the refill rate changed).
    pub(super) fn rebase(&mut self) {
        self.refill_base = RefillBase { time_s: self.clock.time_s, snow_quanta: self.snow_quanta, stamp_quanta: self.clock.stamp_quanta };
    }

    /// The world clock now: time, refill and footprint quanta, snowfall.
    pub(super) fn share_clock(&self) -> ShareClock {
        ShareClock { time_s: self.clock.time_s, refill_quanta: self.snow_quanta, stamp_quanta: self.clock.stamp_quanta, fallen_m: self.fallen_m }
    }

    /// Sets the time to a shared world's `clock` (joining it), the refill
    /// at `refill_m_per_s`. When its counters are `world`'s own at that
    /// time (the world's refill from time 0), they go on being counted from
    /// the world's beginning, as on every other machine; else from now.
    pub(super) fn join(&mut self, clock: ShareClock, world: ShareClock, refill_m_per_s: f32) {
        self.clock.time_s = clock.time_s;
        self.clock.stamp_quanta = clock.stamp_quanta;
        self.clock.refill_m = f64::from(refill_m_per_s) * clock.time_s;
        self.clock.fallen_m = f64::from(clock.fallen_m);
        self.snow_quanta = clock.refill_quanta;
        self.fallen_m = clock.fallen_m;
        self.refill_base = if world.refill_quanta == clock.refill_quanta && world.stamp_quanta == clock.stamp_quanta {
            RefillBase::default()
        } else {
            RefillBase { time_s: clock.time_s, snow_quanta: clock.refill_quanta, stamp_quanta: clock.stamp_quanta }
        };
    }

    /// Takes up a saved `clock` and snowfall so far (`fallen_m`, loading a
    /// save): the refill counters go on from the saved clock.
    #[cfg_attr(not(feature = "store"), expect(dead_code, reason = "for `StoredWindow`'s calls (feature `store`)"))]
    pub(super) fn resume(&mut self, clock: SnowClock, fallen_m: f32) {
        self.clock = clock;
        self.fallen_m = fallen_m;
        self.snow_quanta = (clock.refill_m / f64::from(SNOW_QUANTUM_M)).floor() as u64;
        self.refill_base = RefillBase { time_s: clock.time_s, snow_quanta: self.snow_quanta, stamp_quanta: clock.stamp_quanta };
    }
}
