// #import shared/window
// #import shared/stamp

// Resident tiles: the GPU's copy of the world's tiles around the sliding
// window (src/deform/tiles.rs). The world is cut into square tiles of `side`
// texels on the global texel grid; a tile the window partly covers, or one
// near it, lives in a slot of a fixed pool, found through a key table
// (shared/tile_table.wgsl). Tiles wholly inside the window have no slot: their texels live
// in the window's own buffers. A slot holds its
// tile as `planes` planes of side * side u32, row-major: snow height (f32
// bits), the snowfall so far (f32 bits) where the world has snowfall, the
// packed snow (snow quanta, shared/packed_snow.wgsl), and last the packed
// footprints where the window has a footprint buffer: 2 to 4 planes
// (`tiles::planes` in Rust). There is no terrain plane: the passes
// evaluate the ground of a slot texel from the terrain's source
// (texel_ground in shared/terrain_kind.wgsl).

const PLANE_SNOW: u32 = 0u;
const PLANE_FALLEN: u32 = 1u; // only with snowfall

// The packed-snow plane: after the snowfall's where the world has snowfall.
fn plane_packed(use_fallen: bool) -> u32 {
    return select(1u, 2u, use_fallen);
}

// The footprint plane of a slot of `planes` planes (where there is one).
fn plane_stamps(planes: u32) -> u32 {
    return planes - 1u;
}

// Tile index of global texel coordinate g (floor division).
fn tile_coord(g: i32, side: u32) -> i32 {
    let local = wrap_index(g, i32(side));
    return (g - local) / i32(side);
}

// One texel's persistent state.
struct TexelState {
    snow: f32,
    stamp: u32,
    fallen: f32,
    packed: u32, // packed snow (quanta): time passing leaves it as it is
}

// Time passing on a texel that no deformer reaches and the sky sees: what
// update.wgsl does with `visible = 1` and no capture or stamps applied.
// `fall_m`, `refill_m` and `quanta` are the snowfall, refill and footprint
// refill of the time passed; `use_fallen` whether the world has snowfall.
fn pass_time(ground: f32, depth_m: f32, t: TexelState, fall_m: f32, max_fallen_m: f32, refill_m: f32, quanta: u32, low_m: f32, high_m: f32, use_fallen: bool) -> TexelState {
    var out = t;
    var lying = 0.0;
    var gained = 0.0;
    if use_fallen {
        lying = max(t.fallen, min(t.fallen + fall_m, max_fallen_m));
        gained = lying - t.fallen;
        out.fallen = lying;
    }
    let rest = ground + (depth_m + lying);
    let h = min(t.snow + gained + refill_m, rest);
    if t.stamp != STAMP_EMPTY && quanta > 0u {
        // Clamped so a long absence cannot overflow; any 65536 quanta empty it.
        let q = min(quanta, 65536u);
        let hq = t.stamp >> 16u;
        let foot = (t.stamp & 0xffffu) + q;
        if foot > 65535u || stamp_height(foot, low_m, high_m) >= rest {
            out.stamp = STAMP_EMPTY;
        } else {
            out.stamp = (min(hq + q, 65535u) << 16u) | foot;
        }
    }
    out.snow = max(h, ground);
    return out;
}
