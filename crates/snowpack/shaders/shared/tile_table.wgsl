// #import shared/window
// #import shared/tiles

// Resident tiles by key (src/deform/tiles.rs): a tile with a slot in the
// pool is found through the key table, which the including shader declares
// as `tile_table: array<u32>`.

const NO_SLOT: u32 = 0xffffffffu;

// The slot of tile `tile`, from the key table the including shader declares
// as `tile_table: array<u32>`: a toroidal grid of nk x nk tile keys holding
// each resident tile's slot, or NO_SLOT.
fn slot_of(tile: vec2<i32>, nk: u32) -> u32 {
    return tile_table[u32(wrap_index(tile.y, i32(nk))) * nk + u32(wrap_index(tile.x, i32(nk)))];
}

// Whether global texel g's tile has a slot.
fn tile_resident(g: vec2<i32>, side: u32, nk: u32) -> bool {
    return slot_of(vec2<i32>(tile_coord(g.x, side), tile_coord(g.y, side)), nk) != NO_SLOT;
}

// Index into the resident tiles (`planes` planes a slot) of global texel
// g = (column, row), plane `plane`; its tile must be resident (tile_resident).
fn tile_index(g: vec2<i32>, side: u32, nk: u32, planes: u32, plane: u32) -> u32 {
    let tile = vec2<i32>(tile_coord(g.x, side), tile_coord(g.y, side));
    let local = vec2<u32>(u32(g.x - tile.x * i32(side)), u32(g.y - tile.y * i32(side)));
    return (slot_of(tile, nk) * planes + plane) * side * side + local.y * side + local.x;
}
