// One texel of the window's `snow` buffer: a u32 (src/deform/snow_word.rs).
//   bits 0..15   the deficit: how far the persistent snow lies below its rest
//                height (terrain + depth + snowfall so far there), in steps of
//                SNOW_QUANTUM_M (0.1 mm), so up to 6.5535 m; untouched snow is
//                0 whatever the terrain, and snowfall raising the rest height
//                raises the snow with it
//   bits 16..31  the displayed height (rims, blur) minus the terrain height,
//                as an f16: relative precision 2^-11 (0.12 mm at 0.5 m)
// Refill lowers the deficit by whole quanta (what the CPU's cumulative
// refill counter gained this frame).
// The f16 is encoded here with integer operations, rounding to nearest even
// and flushing subnormals to zero, so every backend and the CPU twin store
// the same bits (WGSL leaves the rounding of pack2x16float open), and
// decoded the same way (see snow_f16_value).

const SNOW_QUANTUM_M: f32 = 0.0001;
const SNOW_QUANTA_PER_M: f32 = 10000.0;

// Quanta of a deficit of `m` metres, rounded, clamped to 0..65535.
fn snow_deficit_quanta(m: f32) -> u32 {
    return u32(clamp(round(m * SNOW_QUANTA_PER_M), 0.0, 65535.0));
}

// The deficit that reaches the terrain under a column of `column` metres at
// rest (depth and lying snow; rounded up; may exceed 65535 under snow deeper
// than the deficit can hold). From the column itself, not from the rest
// height less the terrain: a GPU compiler may simplify (terrain + column) -
// terrain to the column, or not, and the CPU twins and the relay's presses
// must find the same quanta.
fn snow_ground_quanta(column: f32) -> f32 {
    return max(ceil(column * SNOW_QUANTA_PER_M), 0.0);
}

// The persistent snow height of `word` over terrain `ground` under a rest
// column of `column` metres (rest height ground + column): exactly the
// terrain where the deficit reaches it.
fn snow_column_height(word: u32, ground: f32, column: f32) -> f32 {
    let d = f32(word & 0xffffu);
    if d >= snow_ground_quanta(column) {
        return ground;
    }
    return (ground + column) - d * SNOW_QUANTUM_M;
}

// The deficit of a press down to `h` (not below the terrain `ground`) under a
// rest column of `column` metres.
fn snow_column_press(ground: f32, column: f32, h: f32) -> u32 {
    if h <= ground {
        return u32(min(snow_ground_quanta(column), 65535.0));
    }
    return snow_deficit_quanta((ground + column) - h);
}

// The f32 of f16 bits `h` as snow_f16_bits writes them (no subnormals, no
// infinities). Integer operations: unpack2x16float needs a capability
// (f16 in f32) that not every downlevel backend has.
fn snow_f16_value(h: u32) -> f32 {
    let sign = (h & 0x8000u) << 16u;
    let e = (h >> 10u) & 0x1fu;
    if e == 0u {
        return bitcast<f32>(sign);
    }
    return bitcast<f32>(sign | ((e + 112u) << 23u) | ((h & 0x3ffu) << 13u));
}

// The displayed height of `word` over terrain height `ground`.
fn snow_word_shown(word: u32, ground: f32) -> f32 {
    return ground + snow_f16_value(word >> 16u);
}

// f16 bits of `v`: round to nearest even, subnormals to zero, clamped to the
// largest finite f16 (no infinities).
fn snow_f16_bits(v: f32) -> u32 {
    let b = bitcast<u32>(v);
    let sign = (b >> 16u) & 0x8000u;
    let a = b & 0x7fffffffu;
    if a < 0x38800000u {
        return sign;
    }
    if a >= 0x477ff000u {
        return sign | 0x7bffu;
    }
    let r = a - 0x38000000u;
    return sign | ((r + 0xfffu + ((r >> 13u) & 1u)) >> 13u);
}

// `word` with its displayed height set to `shown_above_ground` (m above the terrain).
fn snow_word_with_shown(word: u32, shown_above_ground: f32) -> u32 {
    return (word & 0xffffu) | (snow_f16_bits(shown_above_ground) << 16u);
}
