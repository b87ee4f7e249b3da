//! The window's packed snow (`shared/packed_snow.wgsl`): per texel, the
//! fresh snow that presses squeezed into its column, in snow quanta
//! ([`super::snow_word::SNOW_QUANTUM_M`]), 16 bits a texel and two texels a
//! `u32` (storage index `s` in word `s / 2`, the odd texel in the high half).
//!
//! With the snow word's deficit it is the column of
//! [`snowpack_share::mechanics`]: height `h` above the terrain and packed
//! snow `q`, mass `ρ0 (h + q)`, density `ρ0 (1 + q / h)`. A press that
//! raises the deficit by `d` quanta adds `d` to `q` (the update pass), up to
//! [`cap`]; what is squeezed beyond the final density is displaced. Refill
//! and snowfall leave it as it is. 16 bits hold 6.55 m of packed snow: the
//! most a 1.6 m column holds at five times the fresh density.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

/// Words after the texels': the mass ledger's counts, each a u64 (low
/// word first; `shared/mass_ledger.wgsl`), from the end: displaced (the
/// last two, `shared/pack_press.wgsl`), refill, snowfall, entered, left.
pub const COUNT_WORDS: u64 = 10;

/// Steps per metre of fresh snow of the ledger's snowfall count
/// (`LEDGER_FINE_PER_M`: a frame's snowfall is a small part of a quantum).
pub const LEDGER_FINE_PER_M: f32 = 1.0e7;

/// The mass ledger's counts (`shared/mass_ledger.wgsl`), since the window
/// was created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LedgerCounts {
    /// Snow that left with the window's moves (quanta of fresh snow).
    pub left_q: u64,
    /// Snow that entered with them, the first fill included (quanta).
    pub entered_q: u64,
    /// Snowfall added ([`LEDGER_FINE_PER_M`] steps).
    pub snowfall_fine: u64,
    /// Refill added (quanta).
    pub refill_q: u64,
    /// Displaced beyond the final density (quanta).
    pub displaced_q: u64,
}

impl LedgerCounts {
    /// Adds `other`'s counts (a CPU twin's frame) to these.
    pub fn add(&mut self, other: Self) {
        self.left_q += other.left_q;
        self.entered_q += other.entered_q;
        self.snowfall_fine += other.snowfall_fine;
        self.refill_q += other.refill_q;
        self.displaced_q += other.displaced_q;
    }
}

/// The ledger's counts in the packed buffer's last `COUNT_WORDS` words
/// (zeros for a buffer too short to hold them).
#[must_use]
pub fn ledger(buffer: &[u32]) -> LedgerCounts {
    let Some(at) = buffer.len().checked_sub(COUNT_WORDS as usize) else { return LedgerCounts::default() };
    let wide = |k: usize| u64::from(buffer[at + k]) | (u64::from(buffer[at + k + 1]) << 32);
    LedgerCounts { left_q: wide(0), entered_q: wide(2), snowfall_fine: wide(4), refill_q: wide(6), displaced_q: wide(8) }
}

/// The displaced snow quanta counted in the packed buffer's last words
/// ([`ledger`]'s `displaced_q`).
#[must_use]
pub fn displaced_count(buffer: &[u32]) -> u64 {
    ledger(buffer).displaced_q
}

/// A window texel's snow in quanta of fresh snow, as the ledger counts it
/// (`ledger_column`): its height above the terrain (rest depth and
/// snowfall lying, rounded to quanta, less the deficit in `word`, never
/// below 0) and its packed snow `q`.
#[must_use]
pub fn ledger_column(word: u32, depth_m: f32, lying: f32, q: u32) -> u32 {
    let at_rest = ((depth_m + lying) * super::snow_word::SNOW_QUANTA_PER_M).round_ties_even().max(0.0) as u32;
    at_rest - (word & 0xffff).min(at_rest) + q
}

/// `v` metres of fresh snow in the ledger's fine steps, rounded (`ledger_fine` in `update.wgsl`).
#[must_use]
pub fn ledger_fine(v: f32) -> u32 {
    (v * LEDGER_FINE_PER_M).round_ties_even().max(0.0) as u32
}

/// Words of packed snow for a window of `resolution` texels a side (the
/// buffer holds [`COUNT_WORDS`] more).
#[must_use]
pub fn words(resolution: u32) -> u64 {
    (u64::from(resolution) * u64::from(resolution)).div_ceil(2)
}

/// Texel `s`'s packed snow (quanta).
#[must_use]
pub fn get(packed: &[u32], s: usize) -> u32 {
    (packed[s / 2] >> ((s % 2) * 16)) & 0xffff
}

/// Sets texel `s`'s packed snow to `q` quanta (at most 16 bits).
pub fn set(packed: &mut [u32], s: usize, q: u32) {
    let shift = (s % 2) * 16;
    packed[s / 2] = (packed[s / 2] & !(0xffff << shift)) | ((q.min(0xffff)) << shift);
}

/// Most packed snow (quanta) a column `column` quanta high holds at the
/// final density: `floor(column × ratio)`, at most 16 bits
/// (`packed_cap`; `ratio` is `ρmax / ρ0 − 1`).
#[must_use]
pub fn cap(column: u32, ratio: f32) -> u32 {
    snowpack_share::replicate::press::packed_cap(column, ratio)
}

/// The packed snow of `words` as one value a texel, in storage order.
#[must_use]
pub fn unpack(words: &[u32], texels: usize) -> Vec<u32> {
    (0..texels).map(|s| get(words, s)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_are_independent_and_capped() {
        let mut p = vec![0u32; 2];
        set(&mut p, 1, 7);
        set(&mut p, 0, 0x1_2345);
        set(&mut p, 3, 9);
        assert_eq!((get(&p, 0), get(&p, 1), get(&p, 2), get(&p, 3)), (0xffff, 7, 0, 9));
        assert_eq!(unpack(&p, 4), vec![0xffff, 7, 0, 9]);
        assert_eq!(cap(1000, 4.0), 4000);
        assert_eq!(cap(60_000, 4.0), 65_535);
        assert_eq!(words(16), 128);
    }
}
