// #import shared/window
// #import shared/terrain
// #import shared/terrain_kind
// #import shared/stamp
// #import shared/snow_word
// #import shared/share_flags
// #import shared/sky_test
// #import shared/packed_snow
// #import shared/pack_press
// #import shared/displace
// #import shared/mass_ledger

// Update pass: the persistent snow, as its deficit below the rest height
// (shared/snow_word.wgsl). Per texel, in height terms,
//   snow = max(terrain, min(snow + fall + refill capped at rest, max(terrain, actor), max(terrain, stamp)))
// where rest = terrain + depth + fallen, actor is the captured lowest actor surface
// (when the technique captures depth) and stamp the footprint height (when it
// stamps points). In deficit terms the fall raises rest and snow together
// (the deficit stays), the refill lowers the deficit by whole quanta, and a
// press raises it to the quantised depth of the press below rest. Footprints
// refill too: they rise by whole quanta (both counts are what the CPU's
// cumulative counters, functions of world time, gained this frame), and
// vanish once their foot is back at rest.
// While it snows (USE_FALLEN), `fallen` grows by fall = rate * dt (up to
// max_fallen_m) on texels the sky reaches, and trails there get the refill;
// texels the occlusion render shows under an object (USE_SKY) gain neither,
// so no snow settles under a table or a roof (Dinh figure 5.1). A texel
// reaches the sky when its surface point, projected along the snowfall onto
// the occlusion map, is no lower (less 2 cm) than what that pixel saw.
// Mass (shared/packed_snow.wgsl): a press that raises the deficit by d
// quanta squeezes d quanta of snow into the column below it, which packs it
// (the packed snow grows by d); once the column would be denser than the
// final density the rest is displaced (counted in `displaced`). Refill and
// snowfall add fresh snow on top and leave the packed snow as it is. With
// LEDGER, what snowfall and refill add is counted (shared/mass_ledger.wgsl).
// With DISPLACE, the snow beyond the final density at a texel the actors
// press moves instead (shared/displace.wgsl): to the texel of the 5x5 that
// best follows the way out of the press (the captured surface rising, or
// gone), at most DISPLACE_MOST_Q quanta a frame, the rest staying packed
// until the next frame; the move goes in the upper half of the snow word
// for the displace pass. No way out (a flat press all around): it stays.
// In place: each texel reads and writes only itself; the displayed half of
// each word is kept (the display pass rewrites it).
// With shared snow (SHARE) a texel whose deficit the captured actors raised
// above the refilled one flags its tile (shared/share_flags.wgsl). Stored
// footprints pressing again as snow and footprints refill at their own
// rates flag nothing: every machine has the same footprints and applies
// the same refill, and so the same presses (the stamp pass flags the
// footprints a frame changes). Refill and snowfall flag nothing either.
// CPU twin: src/cpu/update.rs.

struct UpdateParams {
    origin: vec2<i32>,
    resolution: u32,
    depth_m: f32,
    snow_refill_quanta: u32, // this frame's refill, in snow quanta (SNOW_QUANTUM_M)
    low_m: f32,
    high_m: f32,
    flags: u32,          // 1: apply the capture, 2: apply the stamps
    refill_quanta: u32,  // footprint refill this frame, in stamp quanta
    fall_m: f32,         // snowfall this frame on open ground (m)
    max_fallen_m: f32,   // most snowfall a texel keeps above its rest depth
    texel_m: f32,
    sky: SkyTest,        // the occlusion's projection and range (shared/sky_test.wgsl)
    storage_origin: vec2<u32>, // origin wrapped into 0..resolution (storage_index_wrapped)
    share_side: u32, // changed-tile flags' tile side (with SHARE)
    share_keys: u32, // slots per side of the flags
    pack_ratio: f32, // rho_max / rho_fresh - 1: packed snow a column holds per quantum of its height
    displace_k: f32, // (high_m - low_m) * 8 / texel_m: a capture depth step in eighths of a texel's rise
    open_fallen_m: f32, // snowfall so far on open ground, this frame's included
    _pad2: u32,
    // Boxes that push snow this frame (src/deform/push.rs), two vec4 each:
    // (centre x, z, axis x, z), (half extents along and across the axis,
    // push x, z), window-local metres; unused ones contain nothing.
    pushers: array<vec4<f32>, 16>,
}

const USE_CAPTURE: u32 = 1u;
const USE_STAMPS: u32 = 2u;
const USE_FALLEN: u32 = 4u;
const USE_SKY: u32 = 8u;
// The window has a footprint buffer (allocated for points and combined, kept after).
const HAS_STAMPS: u32 = 16u;
// Shared snow: flag the tiles of texels a press changed.
const SHARE: u32 = 32u;
// Footprints refill this frame (refill_quanta > 0): a flag, so that no
// branch tests a uniform alone (Mesa 22's lavapipe compiles such a shader
// again at every dispatch and keeps every copy; docs/deformation.md).
const REFILLS: u32 = 64u;
// Snow beyond the final density moves aside (needs USE_CAPTURE).
const DISPLACE: u32 = 128u;
// With DISPLACE, not sharing: a press on a berm lowers the berm and the
// deficit together.
const CONSUME: u32 = 256u;
// Count what snowfall and refill add in the mass ledger.
const LEDGER: u32 = 512u;
// The analytic shapes were ray cast this frame (read capture_shapes).
const CAPTURE_SHAPES: u32 = 1024u;
// The capture depth target was drawn this frame (read it).
const CAPTURE_DRAWN: u32 = 2048u;

// The flags this pipeline is built for (`UpdatePass` builds one per set in
// use, pass/compute.rs); the default reads `params.flags`.
override UPDATE_FLAGS: u32 = 0xffffffffu;

fn update_flags() -> u32 {
    if UPDATE_FLAGS != 0xffffffffu {
        return UPDATE_FLAGS;
    }
    return params.flags;
}

@group(0) @binding(0) var<uniform> params: UpdateParams;
// The capture depth target (with CAPTURE_DRAWN: meshes, and the shapes when
// drawn) is bound as an unfilterable float texture: GLSL has no texelFetch for depth textures, and
// this binding works on every backend.
@group(0) @binding(1) var capture: texture_2d<f32>;
// The analytic shapes' capture by compute (with CAPTURE_SHAPES; capture_shapes.wgsl):
// two texels a word, each 65535 minus its 16-bit depth code, 0 for nothing.
@group(0) @binding(5) var<storage, read> capture_shapes: array<u32>;
// The terrain's source (shared/terrain.wgsl), evaluated at texel centres.
@group(1) @binding(1) var<storage, read> heightmap: array<f32>;
@group(1) @binding(2) var<storage, read_write> snow: array<u32>; // shared/snow_word.wgsl
@group(1) @binding(3) var<storage, read_write> stamps: array<u32>;
@group(0) @binding(2) var sky: texture_2d<f32>;
@group(1) @binding(4) var<storage, read_write> fallen: array<f32>;
@group(1) @binding(0) var<uniform> terrain_params: TerrainParams;
@group(0) @binding(3) var<storage, read_write> share_flags: array<atomic<u32>>;
// Packed snow, two texels a word, and the displaced count (shared/pack_press.wgsl).
@group(0) @binding(4) var<storage, read_write> packed: array<atomic<u32>>;

// The capture depth at window-local texel (i, j): the lower of the shapes'
// code by compute (decoded as the 16-bit depth target decodes, code /
// 65535) and the depth target's, each where this frame captured it; 1 for
// nothing.
fn capture_depth(i: u32, j: u32) -> f32 {
    var d = 1.0;
    if (update_flags() & CAPTURE_SHAPES) != 0u {
        let v = (capture_shapes[(i * params.resolution + j) >> 1u] >> ((j & 1u) * 16u)) & 0xffffu;
        d = f32(65535u - v) / 65535.0;
    }
    if (update_flags() & CAPTURE_DRAWN) != 0u {
        d = min(d, textureLoad(capture, vec2<u32>(j, i), 0).x);
    }
    return d;
}

// 1 where the sky reaches window-local texel (i, j) whose surface is at height h.
fn sky_visible(i: u32, j: u32, h: f32) -> f32 {
    let q0 = vec2<f32>(f32(j) + 0.5, f32(i) + 0.5) * params.texel_m;
    let pix = sky_test_pixel(params.sky, q0, h, params.texel_m, params.resolution);
    if pix.x < 0 {
        return 1.0;
    }
    return sky_test_seen(params.sky, h, textureLoad(sky, pix, 0).x);
}

// How far the way out of a press rises at neighbour `n` from a texel at
// capture depth `d0`: 0..63 eighths of a texel's rise, 63 where nothing
// presses. In capture depths and one correctly rounded product, so the
// CPU twin picks the same target.
fn displace_rise(n: vec2<i32>, d0: f32) -> i32 {
    let d = capture_depth(u32(n.y), u32(n.x));
    if d >= 1.0 {
        return 63;
    }
    return i32(clamp(floor((d - d0) * params.displace_k), 0.0, 63.0));
}

// The way the first box pushing over window-local texel centre `q` (m)
// pushes, as an integer vector (its unit direction times 1000), or zero.
fn displace_push(q: vec2<f32>) -> vec2<i32> {
    for (var k = 0u; k < 8u; k++) {
        let a = params.pushers[2u * k];
        let b = params.pushers[2u * k + 1u];
        let d = q - a.xy;
        let u = d.x * a.z + d.y * a.w;
        let v = d.y * a.z - d.x * a.w;
        if abs(u) <= b.x && abs(v) <= b.y {
            return vec2<i32>(round(b.zw * 1000.0));
        }
    }
    return vec2<i32>(0, 0);
}

// The offset index (displace_offset) that snow at window-local texel
// (i, j) moves to, or 24 for none: the neighbour in the window whose
// direction is closest to the rise's mean direction (or, under a box that
// pushes, its push; integer cosines),
// then the higher rise, then the first; without a mean direction the
// highest rise; none where nothing rises.
fn displace_target(i: u32, j: u32) -> u32 {
    let d0 = capture_depth(i, j);
    let here = vec2<i32>(i32(j), i32(i));
    let r = i32(params.resolution);
    // Under a box that pushes, its way; else the rises' mean direction.
    // The rises are read again in each loop rather than kept in an array
    // (a private array is slow here), and only where they count.
    let push = displace_push((vec2<f32>(here) + 0.5) * params.texel_m);
    let pushing = any(push != vec2<i32>(0));
    var g = push;
    if !pushing {
        for (var k = 0u; k < 24u; k++) {
            let n = here + displace_offset(k);
            if all(n >= vec2<i32>(0)) && all(n < vec2<i32>(r)) {
                g += displace_rise(n, d0) * displace_offset(k);
            }
        }
    }
    // By the rise alone, only to a neighbour the press holds less deep (or
    // not at all); a moving box carries its snow on across its own texels.
    let least = select(1, 0, pushing);
    var best = 24u;
    var best_dot = 0;
    var best_len = 1;
    var best_rise = -1;
    for (var k = 0u; k < 24u; k++) {
        let o = displace_offset(k);
        let n = here + o;
        let dot_o = o.x * g.x + o.y * g.y;
        if dot_o <= 0 || any(n < vec2<i32>(0)) || any(n >= vec2<i32>(r)) {
            continue;
        }
        let w = displace_rise(n, d0);
        if w < least {
            continue;
        }
        let len = o.x * o.x + o.y * o.y;
        // dot/|o| compared without roots: dot^2 |o_best|^2 against dot_best^2 |o|^2 (u32: at most 7560^2 * 8).
        let a = u32(dot_o) * u32(dot_o) * u32(best_len);
        let b = u32(best_dot) * u32(best_dot) * u32(len);
        if best == 24u || a > b || (a == b && w > best_rise) {
            best = k;
            best_dot = dot_o;
            best_len = len;
            best_rise = w;
        }
    }
    if best == 24u {
        // No neighbour along the way: the highest rise, if any.
        var highest_rise = 0;
        for (var k = 0u; k < 24u; k++) {
            let n = here + displace_offset(k);
            if any(n < vec2<i32>(0)) || any(n >= vec2<i32>(r)) {
                continue;
            }
            let w = displace_rise(n, d0);
            if w > highest_rise {
                best = k;
                highest_rise = w;
            }
        }
    }
    return best;
}

// `v` metres of fresh snow in the ledger's fine steps.
fn ledger_fine(v: f32) -> u32 {
    return u32(max(round(v * LEDGER_FINE_PER_M), 0.0));
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if gid.y < params.resolution && gid.x < params.resolution {
        update_texel(gid.y, gid.x);
    }
    if (update_flags() & LEDGER) != 0u {
        ledger_flush(li, LEDGER_SNOWFALL, LEDGER_REFILL);
    }
}

// One texel's frame: window-local row i, column j.
fn update_texel(i: u32, j: u32) {
    let s = storage_index_wrapped(params.storage_origin, params.resolution, i, j);
    let ground = window_ground(terrain_params, s, params.origin + vec2<i32>(i32(j), i32(i)), params.texel_m);
    let word = snow[s];
    var lying = 0.0;
    if (update_flags() & USE_FALLEN) != 0u {
        lying = fallen[s];
    }
    var visible = 1.0;
    if (update_flags() & USE_SKY) != 0u {
        visible = sky_visible(i, j, snow_column_height(word, ground, params.depth_m + lying));
    }
    if (update_flags() & USE_FALLEN) != 0u {
        let before = lying;
        lying = max(before, min(before + params.fall_m * visible, params.max_fallen_m));
        fallen[s] = lying;
        if (update_flags() & LEDGER) != 0u {
            ledger_add(0u, ledger_fine(lying - before));
        }
    }
    // The rest column (depth and lying snow) and the rest height over the terrain.
    let column = params.depth_m + lying;
    let rest = ground + column;
    var deficit = word & 0xffffu;
    if visible > 0.0 {
        deficit -= min(deficit, params.snow_refill_quanta);
    }
    let refilled = deficit;
    if (update_flags() & LEDGER) != 0u {
        ledger_add(1u, (word & 0xffffu) - refilled);
    }
    // Whether the captured actors reach down to the snow here (what displaces).
    var pressed = false;
    if (update_flags() & USE_CAPTURE) != 0u {
        let d = capture_depth(i, j);
        if d < 1.0 {
            let actor = params.low_m + d * (params.high_m - params.low_m);
            let press = snow_column_press(ground, column, actor);
            pressed = press >= refilled;
            deficit = max(deficit, press);
        }
    }
    let captured = deficit;
    var st = STAMP_EMPTY;
    if (update_flags() & HAS_STAMPS) != 0u {
        st = stamps[s];
    }
    if st != STAMP_EMPTY {
        let hq = st >> 16u;
        let fq = st & 0xffffu;
        if (update_flags() & USE_STAMPS) != 0u {
            deficit = max(deficit, snow_column_press(ground, column, stamp_height(hq, params.low_m, params.high_m)));
        }
        if (update_flags() & REFILLS) != 0u {
            let foot = fq + params.refill_quanta;
            if foot > 65535u || stamp_height(foot, params.low_m, params.high_m) >= rest {
                stamps[s] = STAMP_EMPTY;
            } else {
                stamps[s] = (min(hq + params.refill_quanta, 65535u) << 16u) | foot;
            }
        }
    }
    // Never below the terrain.
    let at_ground = snow_column_press(ground, column, ground);
    deficit = min(deficit, at_ground);
    // What the presses took from the column's height goes into its packed
    // snow, up to the final density; the rest is displaced: counted, or
    // with DISPLACE moved aside by the displace pass.
    if (update_flags() & DISPLACE) != 0u {
        // Where the actors press, the snow beyond the final density, new or
        // left from earlier frames, leaves: at most DISPLACE_MOST_Q quanta in
        // whole 16-quantum steps, and only where it has somewhere to go;
        // the rest stays packed (beyond the cap) for the next frames.
        let q = pack_squeezed(s, refilled, deficit);
        let cap = packed_cap(at_ground - deficit, params.pack_ratio);
        var leaves = 0u;
        if pressed && q.y > cap {
            leaves = min(q.y - cap, DISPLACE_MOST_Q) & ~15u;
        }
        var code = 0u;
        if leaves > 0u {
            let to = displace_target(i, j);
            if to < 24u {
                code = displace_code(to, leaves);
            } else {
                leaves = 0u;
            }
        }
        pack_keep(s, q.x, q.y - leaves);
        if pressed && code == 0u {
            code = DISPLACE_PRESSED;
        }
        var stored = deficit;
        if (update_flags() & CONSUME) != 0u && pressed {
            // A berm under a press: its lying snow (beyond the snowfall so
            // far) and the deficit below it stand for the same snow, so both
            // drop by it (the surface and the mass stay) and neither grows
            // without bound while snow streams through. Not while sharing:
            // copies merge by the larger of each.
            let berm = u32(max(floor((lying - params.open_fallen_m) * SNOW_QUANTA_PER_M), 0.0));
            let consumed = min(berm, deficit);
            stored = deficit - consumed;
            fallen[s] = lying - f32(consumed) * SNOW_QUANTUM_M;
        }
        snow[s] = (code << 16u) | stored;
    } else {
        snow[s] = (word & 0xffff0000u) | deficit;
        pack_press(s, refilled, deficit, at_ground, params.pack_ratio);
    }
    // The capture raised it (after the clamp, which only lowers).
    if (update_flags() & SHARE) != 0u && min(captured, at_ground) > refilled {
        atomicStore(&share_flags[share_slot(params.origin + vec2<i32>(i32(j), i32(i)), params.share_side, params.share_keys)], 1u);
    }
}
