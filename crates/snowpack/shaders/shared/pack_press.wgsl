// #import shared/displace
// #import shared/mass_ledger
// A press's packing (docs/mechanics.md), for the passes that raise deficits
// (the update and the tile merge). The importing shader declares
//   packed: array<atomic<u32>>
// in shared/packed_snow.wgsl's layout, whose last words are the mass
// ledger's counts, the displaced snow last (shared/mass_ledger.wgsl): one
// binding, so the tile merge stays within 8 storage buffers.
// Twin: the same steps in src/cpu/update.rs and src/cpu/tile_merge.rs.

// Adds `q` quanta to the ledger's displaced count.
fn count_displaced(q: u32) {
    ledger_count(LEDGER_DISPLACED, q);
}

// Sets texel `s`'s packed snow from `before` to `after` quanta (at most 16
// bits): one atomic add or subtract on its half of the word, so the texel
// beside it in the word, another thread's, is left as it is.
fn packed_set(s: u32, before: u32, after: u32) {
    let k = packed_index(s);
    if after > before {
        atomicAdd(&packed[k], (after - before) << packed_shift(s));
    } else if after < before {
        atomicSub(&packed[k], (before - after) << packed_shift(s));
    }
}

// Texel `s`'s packed snow before a press (x) and squeezed by it (y): the
// press raised its deficit from `was` to `now` quanta.
fn pack_squeezed(s: u32, was: u32, now: u32) -> vec2<u32> {
    let before = packed_get(atomicLoad(&packed[packed_index(s)]), s);
    return vec2<u32>(before, before + (now - min(was, now)));
}

// Texel `s`'s deficit rose from `was` to `now` quanta (its column, up to
// the terrain, `at_ground` quanta at rest): the snow it lost goes into its
// packed snow, up to the final density (`ratio` = rho_max / rho_fresh - 1);
// the rest is displaced.
fn pack_press(s: u32, was: u32, now: u32, at_ground: u32, ratio: f32) {
    if now <= was {
        return;
    }
    let q = pack_squeezed(s, was, now);
    let cap = packed_cap(at_ground - now, ratio);
    packed_set(s, q.x, min(q.y, cap));
    if q.y > cap {
        count_displaced(q.y - cap);
    }
}

// Keeps `kept` quanta of packed snow at texel `s` (it had `before`), for a
// window that displaces: beyond the cap for the next frames to move on,
// beyond 16 bits counted as displaced.
fn pack_keep(s: u32, before: u32, kept: u32) {
    let after = min(kept, 65535u);
    if kept > after {
        count_displaced(kept - after);
    }
    packed_set(s, before, after);
}
