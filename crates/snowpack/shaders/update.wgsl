// Update pass: the persistent snow height. Per texel,
//   snow = max(terrain, min(snow + refill * dt capped at rest, max(terrain, actor), max(terrain, stamp)))
// where rest = terrain + depth, actor is the captured lowest actor surface
// (when the technique captures depth) and stamp the footprint height (when it
// stamps points). Footprints refill too: they rise by whole quanta (the CPU
// carries the remainder), and vanish once their foot is back at rest.
// In place: each texel reads and writes only itself. CPU twin: src/cpu/update.rs.

struct UpdateParams {
    origin: vec2<i32>,
    resolution: u32,
    depth_m: f32,
    refill_m: f32,   // refill_m_per_s * dt for this frame
    low_m: f32,
    high_m: f32,
    flags: u32,          // 1: apply the capture, 2: apply the stamps
    refill_quanta: u32,  // footprint refill this frame, in stamp quanta
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

const USE_CAPTURE: u32 = 1u;
const USE_STAMPS: u32 = 2u;

@group(0) @binding(0) var<uniform> params: UpdateParams;
// The depth target is bound as an unfilterable float texture: GLSL has no
// texelFetch for depth textures, and this binding works on every backend.
@group(0) @binding(1) var capture: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> terrain: array<f32>;
@group(0) @binding(3) var<storage, read_write> snow: array<f32>;
@group(0) @binding(4) var<storage, read_write> stamps: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let j = gid.x;
    let i = gid.y;
    if i >= params.resolution || j >= params.resolution {
        return;
    }
    let s = storage_index(params.origin, params.resolution, i, j);
    let ground = terrain[s];
    let rest = ground + params.depth_m;
    var h = min(snow[s] + params.refill_m, rest);
    if (params.flags & USE_CAPTURE) != 0u {
        let d = textureLoad(capture, vec2<u32>(j, i), 0).x;
        if d < 1.0 {
            let actor = params.low_m + d * (params.high_m - params.low_m);
            h = min(h, max(ground, actor));
        }
    }
    let st = stamps[s];
    if st != STAMP_EMPTY {
        let hq = st >> 16u;
        let fq = st & 0xffffu;
        if (params.flags & USE_STAMPS) != 0u {
            h = min(h, max(ground, stamp_height(hq, params.low_m, params.high_m)));
        }
        if params.refill_quanta > 0u {
            let foot = fq + params.refill_quanta;
            if foot > 65535u || stamp_height(foot, params.low_m, params.high_m) >= rest {
                stamps[s] = STAMP_EMPTY;
            } else {
                stamps[s] = (min(hq + params.refill_quanta, 65535u) << 16u) | foot;
            }
        }
    }
    snow[s] = max(h, ground);
}
