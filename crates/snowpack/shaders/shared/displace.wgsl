// Displacement (docs/mechanics.md, "Displacement"): snow a press squeezes
// beyond the final density leaves its texel for one of the 24 texels of
// the 5x5 around it. Between the update pass (which chooses and writes it)
// and the display pass (which rewrites that half), the upper half of the
// snow word holds the move:
//   bits 11..15  target + 1 (k of displace_offset; 0: none;
//                31: pressed, nothing moves, so erosion leaves it be)
//   bits  0..10  the snow moved, in 16-quantum steps (at most 32752 quanta, 3.3 m)
// The displace pass gathers, at each texel, the moves of its 24 neighbours
// that name it. Twin: src/deform/displace.rs (the same table and codes).

const DISPLACE_MOST_Q: u32 = 32752u;

// The 5x5 around a texel without its centre, (column, row) offsets, rows
// first (k in 0..24): the order breaks ties between equally good targets.
// Arithmetic rather than a constant array: a constant array indexed by a
// loop counter is copied into each invocation's memory by some compilers.
fn displace_offset(k: u32) -> vec2<i32> {
    let n = i32(k + select(0u, 1u, k >= 12u));
    return vec2<i32>(n % 5 - 2, n / 5 - 2);
}

// The mark of a texel the actors press that sends nothing.
const DISPLACE_PRESSED: u32 = 31u << 11u;

// The move of `quanta` (a multiple of 16, at most DISPLACE_MOST_Q) to offset index `to`.
fn displace_code(to: u32, quanta: u32) -> u32 {
    return ((to + 1u) << 11u) | (quanta >> 4u);
}

// The target offset index + 1 of move `code` (0: none).
fn displace_code_target(code: u32) -> u32 {
    return code >> 11u;
}

// The quanta of move `code`.
fn displace_code_quanta(code: u32) -> u32 {
    return (code & 0x7ffu) << 4u;
}
