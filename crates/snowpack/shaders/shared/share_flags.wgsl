// #import shared/window

// Changed-tile flags of shared snow (src/replicate/flags.rs is the CPU twin).
// One u32 per tile slot; tiles of `side` texels on the global grid map to
// slots toroidally by key: slot = (row mod keys) * keys + (col mod keys),
// with keys = ceil(resolution / side) + 1, so the tiles one window overlaps
// (at most keys per axis) never share a slot. Non-zero: a press changed the
// tile since the flags were last copied out and cleared.

// Floor division for any sign (WGSL's `/` truncates towards zero).
fn share_floor_div(g: i32, side: i32) -> i32 {
    if g >= 0 {
        return g / side;
    }
    return -1 - (-1 - g) / side;
}

// Slot of the tile holding global texel `g` = (column, row).
fn share_slot(g: vec2<i32>, side: u32, keys: u32) -> u32 {
    let k = i32(keys);
    let c = wrap_index(share_floor_div(g.x, i32(side)), k);
    let r = wrap_index(share_floor_div(g.y, i32(side)), k);
    return u32(r) * keys + u32(c);
}
