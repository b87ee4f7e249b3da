// #import shared/window
// #import shared/window_params
// #import shared/pass_flags
// #import shared/packed_snow
// #import shared/snow_word
// #import shared/mass_ledger

// Window pass: writes fresh snow (deficit 0: at its rest height) into the texels that the
// sliding window has just exposed (at most two rectangles: new rows, new
// columns), and nothing else; their footprints are cleared (when the window
// has a footprint buffer: the points and combined techniques). New texels get
// the snowfall so far (as if the sky reached them) and no packed snow.
// With COUNT_LEFT the snow the overwritten texels held is counted as left
// (not on the window's first fill, over buffers that held nothing), and the
// fresh snow as entered (shared/mass_ledger.wgsl). CPU twin: src/cpu/window.rs.

@group(0) @binding(0) var<uniform> params: WindowParams;
@group(1) @binding(2) var<storage, read_write> snow: array<u32>; // shared/snow_word.wgsl
@group(1) @binding(3) var<storage, read_write> stamps: array<u32>;
@group(1) @binding(4) var<storage, read_write> fallen: array<f32>;
// Packed snow, two texels a word (shared/packed_snow.wgsl).
@group(0) @binding(1) var<storage, read_write> packed: array<atomic<u32>>;

const WORKGROUP: u32 = 256u;
const WRITE_FALLEN: u32 = 1u;
const WRITE_STAMPS: u32 = 2u;
const COUNT_LEFT: u32 = 4u;

// Window texel `s`'s snow as the ledger counts it.
fn texel_column(s: u32) -> u32 {
    var lying = 0.0;
    if (pass_flags() & WRITE_FALLEN) != 0u {
        lying = fallen[s];
    }
    return ledger_column(snow[s], params.depth_m, lying, packed_get(atomicLoad(&packed[packed_index(s)]), s));
}

// Fresh snow at window-local texel (i, j).
fn expose(i: u32, j: u32) {
    let s = storage_index(params.origin, params.resolution, i, j);
    if (pass_flags() & COUNT_LEFT) != 0u {
        ledger_add(0u, texel_column(s));
    }
    if (pass_flags() & WRITE_FALLEN) != 0u {
        fallen[s] = params.fallen_m;
    }
    // Untouched: no deficit below the rest height. The displayed half is
    // written by the display pass later in the frame.
    snow[s] = 0u;
    atomicAnd(&packed[packed_index(s)], ~(0xffffu << packed_shift(s)));
    if (pass_flags() & WRITE_STAMPS) != 0u {
        stamps[s] = 0xffffffffu; // no footprint yet
    }
    ledger_add(1u, texel_column(s));
}

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let texel = rect_texel(gid.x + gid.y * groups.x * WORKGROUP, params.rects, params.rect_count);
    if texel.z != 0u {
        expose(texel.x, texel.y);
    }
    ledger_flush(li, LEDGER_LEFT, LEDGER_ENTERED);
}
