//! CPU twin of `update.wgsl`.

use snowpack::low_level::deform::packed_snow::{self, LedgerCounts};
use snowpack::low_level::deform::snow_word::{SNOW_QUANTA_PER_M, SNOW_QUANTUM_M, column_height, column_press};
use snowpack::low_level::deform::update::UpdateParams;

use super::stamp::{STAMP_EMPTY, height};
use super::window::storage_index;

/// 1 where the sky reaches window-local texel (i, j) whose surface is at `h`,
/// by the window-local occlusion depth `sky` (`SkyTest::reaches`).
#[must_use]
pub fn sky_visible(p: &UpdateParams, sky: &[f32], i: u32, j: u32, h: f32) -> f32 {
    p.sky.reaches([(j as f32 + 0.5) * p.texel_m, (i as f32 + 0.5) * p.texel_m], h, p.texel_m, p.resolution, sky)
}

/// The update's inputs besides its parameters: window-local capture and
/// occlusion depths, and the toroidal terrain.
#[derive(Clone, Copy, Debug)]
pub struct UpdateInputs<'a> {
    /// Capture depth, window-local.
    pub capture_depth: &'a [f32],
    /// Occlusion depth, window-local (read with [`UpdateParams::USE_SKY`]).
    pub sky_depth: &'a [f32],
    /// Terrain height, toroidal.
    pub terrain: &'a [f32],
}

/// What the update changes in place: the toroidal snow words
/// (`shared/snow_word.wgsl`), footprints (refilled), snowfall so far, packed
/// snow (two texels a word, [`snowpack::low_level::deform::packed_snow`]) and, with
/// [`UpdateParams::SHARE`], the changed-tile flags
/// ([`snowpack::low_level::replicate::flags::ShareGrid`]; empty: not flagged).
#[derive(Debug)]
pub struct UpdateState<'a> {
    /// Snow words.
    pub snow: &'a mut [u32],
    /// Packed footprints.
    pub stamps: &'a mut [u32],
    /// Snowfall so far (m).
    pub fallen: &'a mut [f32],
    /// Packed snow, two texels a word.
    pub packed: &'a mut [u32],
    /// Changed-tile flags: set for every texel whose deficit the capture
    /// raised above the refilled one (stored footprints press the same on
    /// every machine; the stamp pass flags the footprints it changes).
    pub flags: &'a mut [u32],
}

/// Runs the update over every texel of `state`; returns what `update.wgsl`
/// adds to the mass ledger: the snow quanta displaced beyond the final
/// density and, with [`UpdateParams::LEDGER`], the snowfall and refill added.
pub fn update(p: &UpdateParams, input: &UpdateInputs<'_>, state: &mut UpdateState<'_>) -> LedgerCounts {
    let UpdateState { snow, stamps, fallen, packed, flags } = state;
    let mut ledger = LedgerCounts::default();
    let counts = p.flags & UpdateParams::LEDGER != 0;
    let grid = snowpack::low_level::replicate::flags::ShareGrid { side: p.share_side.max(1), keys: p.share_keys };
    let share = p.flags & UpdateParams::SHARE != 0 && !flags.is_empty();
    let r = p.resolution;
    for i in 0..r {
        for j in 0..r {
            let s = storage_index(p.origin, r, i, j);
            let ground = input.terrain[s];
            let word = snow[s];
            let mut lying = if p.flags & UpdateParams::USE_FALLEN != 0 { fallen[s] } else { 0.0 };
            let visible =
                if p.flags & UpdateParams::USE_SKY != 0 { sky_visible(p, input.sky_depth, i, j, column_height(word, ground, p.depth_m + lying)) } else { 1.0 };
            if p.flags & UpdateParams::USE_FALLEN != 0 {
                let before = lying;
                lying = before.max((before + p.fall_m * visible).min(p.max_fallen_m));
                fallen[s] = lying;
                ledger.snowfall_fine += if counts { u64::from(packed_snow::ledger_fine(lying - before)) } else { 0 };
            }
            // The rest column (depth and lying snow) over the terrain.
            let column = p.depth_m + lying;
            let mut deficit = word & 0xffff;
            if visible > 0.0 {
                deficit -= deficit.min(p.snow_refill_quanta);
            }
            let refilled = deficit;
            ledger.refill_q += if counts { u64::from((word & 0xffff) - refilled) } else { 0 };
            let mut pressed = false;
            if p.flags & UpdateParams::USE_CAPTURE != 0 {
                let d = input.capture_depth[(i * r + j) as usize];
                if d < 1.0 {
                    let actor = p.low_m + d * (p.high_m - p.low_m);
                    let press = column_press(ground, column, actor);
                    pressed = press >= refilled;
                    deficit = deficit.max(press);
                }
            }
            let captured = deficit;
            if p.flags & UpdateParams::HAS_STAMPS != 0 {
                deficit = footprint(p, &mut stamps[s], (ground, column), deficit);
            }
            // Never below the terrain.
            let at_ground = column_press(ground, column, ground);
            deficit = deficit.min(at_ground);
            if p.flags & UpdateParams::DISPLACE != 0 {
                let (code, lost) = super::displace::press(p, input.capture_depth, packed, (s, i, j), (refilled, deficit, at_ground), pressed);
                let mut stored = deficit;
                if p.flags & UpdateParams::CONSUME != 0 && pressed {
                    let berm = ((lying - p.open_fallen_m) * SNOW_QUANTA_PER_M).floor().max(0.0) as u32;
                    let consumed = berm.min(deficit);
                    stored = deficit - consumed;
                    fallen[s] = lying - consumed as f32 * SNOW_QUANTUM_M;
                }
                snow[s] = (code << 16) | stored;
                ledger.displaced_q += lost;
            } else {
                snow[s] = (word & 0xffff_0000) | deficit;
                ledger.displaced_q += pack_press(packed, s, (refilled, deficit), at_ground, p.pack_ratio);
            }
            if share && captured.min(at_ground) > refilled {
                flags[grid.slot([i64::from(p.origin[0]) + i64::from(j), i64::from(p.origin[1]) + i64::from(i)])] = 1;
            }
        }
    }
    ledger
}

/// The stored footprint `st` at a texel with terrain `ground` under a rest
/// column `column`: it presses the snow to its height (with
/// [`UpdateParams::USE_STAMPS`]; returns the deficit) and refills.
fn footprint(p: &UpdateParams, st: &mut u32, (ground, column): (f32, f32), deficit: u32) -> u32 {
    let rest = ground + column;
    if *st == STAMP_EMPTY {
        return deficit;
    }
    let (hq, fq) = (*st >> 16, *st & 0xffff);
    let pressed = if p.flags & UpdateParams::USE_STAMPS != 0 { deficit.max(column_press(ground, column, height(hq, p.low_m, p.high_m))) } else { deficit };
    if p.refill_quanta > 0 {
        let foot = fq + p.refill_quanta;
        *st = if foot > 65535 || height(foot, p.low_m, p.high_m) >= rest { STAMP_EMPTY } else { ((hq + p.refill_quanta).min(65535) << 16) | foot };
    }
    pressed
}

/// Texel `s`'s deficit rose `from` → `to` quanta (`at_ground` up to the
/// terrain): the snow it lost goes into its packed snow up to the final
/// density (`ratio`); returns the quanta displaced beyond
/// (`shared/pack_press.wgsl`).
pub fn pack_press(packed: &mut [u32], s: usize, (from, to): (u32, u32), at_ground: u32, ratio: f32) -> u64 {
    if to <= from {
        return 0;
    }
    let squeezed = packed_snow::get(packed, s) + (to - from);
    let cap = packed_snow::cap(at_ground - to, ratio);
    packed_snow::set(packed, s, squeezed.min(cap));
    u64::from(squeezed.saturating_sub(cap))
}
