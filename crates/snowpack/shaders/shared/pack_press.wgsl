// #import shared/displace
// A press's packing (docs/mechanics.md), for the passes that raise deficits
// (the update and the tile merge). The importing shader declares
//   packed: array<atomic<u32>>
// in shared/packed_snow.wgsl's layout, whose last two words are the count
// of displaced snow quanta (a u64, low word first): one binding, so the
// tile merge stays within 8 storage buffers.
// Twin: the same steps in src/cpu/update.rs and src/cpu/tile_merge.rs.

// Adds `q` quanta to the displaced count, carrying into its high word.
fn count_displaced(q: u32) {
    let low = arrayLength(&packed) - 2u;
    let before = atomicAdd(&packed[low], q);
    if before + q < before {
        atomicAdd(&packed[low + 1u], 1u);
    }
}

// Texel `s`'s deficit rose from `was` to `now` quanta (its column, up to
// the terrain, `at_ground` quanta at rest): the snow it lost goes into its
// packed snow, up to the final density (`ratio` = rho_max / rho_fresh - 1);
// the rest is displaced.
fn pack_press(s: u32, was: u32, now: u32, at_ground: u32, ratio: f32) {
    if now <= was {
        return;
    }
    let k = packed_index(s);
    let shift = packed_shift(s);
    let before = packed_get(atomicLoad(&packed[k]), s);
    let squeezed = before + (now - was);
    let cap = packed_cap(at_ground - now, ratio);
    let after = min(squeezed, cap);
    if after > before {
        atomicAdd(&packed[k], (after - before) << shift);
    } else if after < before {
        atomicSub(&packed[k], (before - after) << shift);
    }
    if squeezed > cap {
        count_displaced(squeezed - cap);
    }
}

// As pack_press, for a window that displaces (update.wgsl's DISPLACE):
// where the actors press (`pressed`), the snow beyond the final density,
// new or left from earlier frames, leaves the column, at most
// DISPLACE_MOST_Q quanta in whole 16-quantum steps; the rest stays packed
// (beyond the cap) for the next frames. Returns what leaves. Packed snow
// beyond 16 bits is counted as displaced.
fn pack_press_excess(s: u32, was: u32, now: u32, at_ground: u32, ratio: f32, pressed: bool) -> u32 {
    let k = packed_index(s);
    let shift = packed_shift(s);
    let before = packed_get(atomicLoad(&packed[k]), s);
    let squeezed = before + (now - min(was, now));
    let cap = packed_cap(at_ground - now, ratio);
    var leaves = 0u;
    if pressed && squeezed > cap {
        leaves = min(squeezed - cap, DISPLACE_MOST_Q) & ~15u;
    }
    let kept = squeezed - leaves;
    let after = min(kept, 65535u);
    if kept > after {
        count_displaced(kept - after);
    }
    if after > before {
        atomicAdd(&packed[k], (after - before) << shift);
    } else if after < before {
        atomicSub(&packed[k], (before - after) << shift);
    }
    return leaves;
}

// Puts `quanta` that pack_press_excess took out of texel `s` back into its
// packed snow (no way out of the press), counting what 16 bits cannot hold.
fn pack_press_keep(s: u32, quanta: u32) {
    if quanta == 0u {
        return;
    }
    let k = packed_index(s);
    let before = packed_get(atomicLoad(&packed[k]), s);
    let after = min(before + quanta, 65535u);
    atomicAdd(&packed[k], (after - before) << packed_shift(s));
    if before + quanta > after {
        count_displaced(before + quanta - after);
    }
}
