// Packed snow (src/deform/packed_snow.rs): per texel, the fresh snow that
// presses squeezed into its column (snow quanta, 16 bits), two texels a
// u32, then two words counting the snow quanta presses displaced
// (shared/pack_press.wgsl); with the snow word's deficit it gives the column's mass and density
// (snowpack_share::mechanics). A texel's half is changed with atomic adds
// and ands, so neighbouring texels' threads never clobber each other.

// Word of texel storage index `s`.
fn packed_index(s: u32) -> u32 {
    return s >> 1u;
}

// Bit offset of texel `s`'s half in its word.
fn packed_shift(s: u32) -> u32 {
    return (s & 1u) << 4u;
}

// Texel `s`'s packed snow (quanta) in its word.
fn packed_get(word: u32, s: u32) -> u32 {
    return (word >> packed_shift(s)) & 0xffffu;
}

// Most packed snow (quanta) a column of `column` quanta holds at the final
// density: floor(column * (rho_max / rho_fresh - 1)), at most 16 bits. The
// product is correctly rounded on every backend, so the CPU twin agrees.
fn packed_cap(column: u32, ratio: f32) -> u32 {
    return u32(min(floor(f32(column) * ratio), 65535.0));
}
