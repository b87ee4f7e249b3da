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
