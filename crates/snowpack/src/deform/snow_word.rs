//! One texel of the window's `snow` buffer (`shared/snow_word.wgsl`): the
//! persistent snow and the displayed surface in one `u32`.
//!
//! | bits | what |
//! |---|---|
//! | 0..15 | the deficit: rest height (terrain + depth + snowfall so far) minus the persistent snow height, in [`SNOW_QUANTUM_M`] steps (0.1 mm, up to [`MAX_DEFICIT_M`]) |
//! | 16..31 | the displayed height (rims, blur) minus the terrain height, f16 |
//!
//! Precision: the persistent snow is within half a quantum (0.05 mm) of the
//! f32 height it stands for; a press deeper than [`MAX_DEFICIT_M`] below the
//! rest height stops there. The displayed height has an f16's relative
//! precision, 2^-11 of its height above the terrain (0.12 mm at 0.5 m, 1 mm
//! at 4 m). Untouched snow is deficit 0 over any terrain, so snowfall, which
//! raises the rest height, raises untouched snow and trails alike; refill
//! lowers the deficit by whole quanta (the frame applies what the world
//! clock's refill counter gained: `SnowDeformation::share_clock`).
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

/// Metres per deficit quantum (the shared-snow crate's: tiles and their clock count in it).
pub use snowpack_share::SNOW_QUANTUM_M;
pub use snowpack_share::replicate::press::{SNOW_QUANTA_PER_M, column_press, deficit_quanta, ground_quanta};

/// The persistent snow height of `word` over terrain `ground` under a rest
/// column of `column` metres (depth and lying snow; rest height `ground +
/// column`): exactly the terrain where the deficit reaches it.
#[must_use]
pub fn column_height(word: u32, ground: f32, column: f32) -> f32 {
    let d = (word & 0xffff) as f32;
    if d >= ground_quanta(column) {
        return ground;
    }
    (ground + column) - d * SNOW_QUANTUM_M
}

/// The displayed height of `word` over terrain height `ground`.
#[must_use]
pub fn shown(word: u32, ground: f32) -> f32 {
    ground + f16_to_f32(word >> 16)
}

/// `word` with its displayed height set to `above_ground` (m above the terrain).
#[must_use]
pub fn with_shown(word: u32, above_ground: f32) -> u32 {
    (word & 0xffff) | (f16_bits(above_ground) << 16)
}

/// f16 bits of `v` as `snow_f16_bits` computes them: round to nearest even,
/// subnormals to zero, clamped to the largest finite f16.
#[must_use]
pub fn f16_bits(v: f32) -> u32 {
    let b = v.to_bits();
    let sign = (b >> 16) & 0x8000;
    let a = b & 0x7fff_ffff;
    if a < 0x3880_0000 {
        return sign;
    }
    if a >= 0x477f_f000 {
        return sign | 0x7bff;
    }
    let r = a - 0x3800_0000;
    sign | ((r + 0xfff + ((r >> 13) & 1)) >> 13)
}

/// The f32 an f16's bits stand for (exact; WGSL's `unpack2x16float`).
#[must_use]
pub fn f16_to_f32(bits: u32) -> f32 {
    let bits = bits & 0xffff;
    let sign = (bits & 0x8000) << 16;
    let exp = (bits >> 10) & 0x1f;
    let man = bits & 0x3ff;
    let magnitude = match exp {
        0 => man as f32 * f32::from_bits(0x3380_0000), // subnormal: man * 2^-24
        31 => f32::from_bits(0x7f80_0000 | (man << 13)),
        _ => f32::from_bits(((exp + 112) << 23) | (man << 13)),
    };
    f32::from_bits(sign | magnitude.to_bits())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f16_round_trips_every_finite_half() {
        for bits in 0..0x7c00u32 {
            if bits >> 10 == 0 && bits != 0 {
                continue; // subnormals flush to zero on the way in
            }
            for sign in [0, 0x8000] {
                let v = f16_to_f32(bits | sign);
                assert_eq!(f16_bits(v), bits | sign, "{bits:#x}");
            }
        }
    }

    #[test]
    fn f16_rounds_to_nearest_even_and_clamps() {
        // 1 + 2^-11 is halfway between 1 and the next half: ties to even (1).
        assert_eq!(f16_bits(1.0 + 2f32.powi(-11)), 0x3c00);
        // 1 + 3 * 2^-11 is halfway between two halves: to the even one above.
        assert_eq!(f16_bits(1.0 + 3.0 * 2f32.powi(-11)), 0x3c02);
        assert_eq!(f16_bits(1e6), 0x7bff);
        assert_eq!(f16_bits(-1e6), 0xfbff);
        assert_eq!(f16_bits(1e-7), 0);
        assert!((f16_to_f32(f16_bits(0.3)) - 0.3).abs() < 0.3 * 2f32.powi(-11));
    }

    #[test]
    fn deficits_quantise_within_half_a_step_and_clamp() {
        for k in 0..1000 {
            let m = k as f32 * 0.000_37;
            let q = deficit_quanta(m);
            assert!((column_height(q, 0.0, 10.0) - (10.0 - m)).abs() <= 0.5 * SNOW_QUANTUM_M + 1e-6, "{m}");
        }
        assert_eq!(deficit_quanta(-1.0), 0);
        assert_eq!(deficit_quanta(100.0), 65_535);
        assert_eq!(shown(with_shown(7, 0.25), 1.0), 1.25);
        // A press to the terrain reads as the terrain, whatever the rounding.
        for column in [0.3, 0.123_456_7, 1.000_05, 6.5] {
            let ground = 0.017;
            assert_eq!(column_height(column_press(ground, column, ground - 1.0), ground, column), ground);
            assert!(column_height(column_press(ground, column, ground + 0.001), ground, column) > ground);
        }
        // Deeper than a deficit holds: the deepest press stops above the terrain.
        assert!(column_height(column_press(0.0, 10.0, 0.0), 0.0, 10.0) > 3.0);
        assert_eq!(with_shown(7, 0.25) & 0xffff, 7);
    }
}
