// #import shared/snow_word
// The window's mass ledger (docs/mechanics.md, "The ledger";
// src/deform/packed_snow.rs): what snow entered and left the window with
// its moves, and what snowfall and refill added, counted in the packed-snow
// buffer's last words, each count a u64 (low word first). From the end:
//   2  displaced beyond the final density (shared/pack_press.wgsl), quanta
//   4  refill, quanta
//   6  snowfall, LEDGER_FINE_PER_M steps of fresh snow
//   8  entered with the window's moves, quanta
//  10  left with them, quanta
// The importing shader declares packed: array<atomic<u32>>. Invocations add
// into the workgroup's sums (ledger_add), then every invocation reaches
// ledger_flush in uniform control flow, and one adds the sums to the
// counts: one global atomic per workgroup and count, not one per texel.
// Twin: src/deform/packed_snow.rs (`LedgerCounts`) and the passes' CPU twins.

const LEDGER_DISPLACED: u32 = 2u;
const LEDGER_REFILL: u32 = 4u;
const LEDGER_SNOWFALL: u32 = 6u;
const LEDGER_ENTERED: u32 = 8u;
const LEDGER_LEFT: u32 = 10u;
// Snowfall is counted in 0.1 um steps: a frame's is a small part of a
// quantum.
const LEDGER_FINE_PER_M: f32 = 10000000.0;

var<workgroup> ledger_sums: array<atomic<u32>, 2>;

// Adds `v` to the workgroup's sum `k` (0 or 1).
fn ledger_add(k: u32, v: u32) {
    if v > 0u {
        atomicAdd(&ledger_sums[k], v);
    }
}

// Adds `v` to the count `back` words from the buffer's end, carrying into
// its high word.
fn ledger_count(back: u32, v: u32) {
    if v == 0u {
        return;
    }
    let low = arrayLength(&packed) - back;
    let before = atomicAdd(&packed[low], v);
    if before + v < before {
        atomicAdd(&packed[low + 1u], 1u);
    }
}

// Once every invocation of the workgroup has added: sum 0 into the count
// `first` words from the end, sum 1 into the count `second` words from it.
fn ledger_flush(local_index: u32, first: u32, second: u32) {
    workgroupBarrier();
    if local_index == 0u {
        ledger_count(first, atomicLoad(&ledger_sums[0]));
        ledger_count(second, atomicLoad(&ledger_sums[1]));
    }
}

// A window texel's snow in quanta of fresh snow: its height above the
// terrain (rest depth and snowfall lying, rounded to quanta, less the
// deficit, never below 0) and its packed snow `q`. No terrain needed: the
// update keeps the deficit within the column.
fn ledger_column(word: u32, depth_m: f32, lying: f32, q: u32) -> u32 {
    let at_rest = u32(max(round((depth_m + lying) * SNOW_QUANTA_PER_M), 0.0));
    return at_rest - min(word & 0xffffu, at_rest) + q;
}
