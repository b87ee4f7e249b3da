// #import shared/objects

// Atlas surface pass: what the renderer draws from the accumulation. Height:
// dilated (3x3 maximum over the same object's texels, and gutter texels take
// the largest neighbour of a dilated object) or as it is, per object. Slopes:
// the Scharr filter (3, 10, 3) over the undilated accumulation, neighbours of
// another chart replaced by the centre, in metres of height per atlas texel:
//   dx = (3 (h[+1,-1] - h[-1,-1]) + 10 (h[+1,0] - h[-1,0]) + 3 (h[+1,+1] - h[-1,+1])) / 32.
// Output per texel: (height, dx, dy, owned ? 1 : 0).
// CPU twin: src/cpu/atlas_surface.rs.

struct SurfaceParams {
    atlas_resolution: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: SurfaceParams;
@group(0) @binding(1) var<storage, read> objects: array<ObjectGpu>;
@group(0) @binding(2) var<storage, read> owner: array<u32>;
@group(0) @binding(3) var<storage, read> acc: array<f32>;
@group(0) @binding(4) var<storage, read_write> surface: array<vec4<f32>>;

fn texel(x: i32, y: i32) -> i32 {
    let n = i32(params.atlas_resolution);
    if x < 0 || y < 0 || x >= n || y >= n {
        return -1;
    }
    return y * n + x;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = params.atlas_resolution;
    if gid.x >= n || gid.y >= n {
        return;
    }
    let k = gid.y * n + gid.x;
    let own = owner[k];
    let cx = i32(gid.x);
    let cy = i32(gid.y);
    var centre = 0.0;
    if own != NO_OWNER {
        centre = acc[k];
    }
    var shown = centre;
    var samples: array<f32, 9>;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let m = texel(cx + dx, cy + dy);
            var h = centre;
            if m >= 0 {
                let o = owner[m];
                if o != NO_OWNER && (objects[o].flags.x & DILATE) != 0u && (own == NO_OWNER || o == own) {
                    shown = max(shown, acc[m]);
                }
                if o == own && own != NO_OWNER {
                    h = acc[m];
                }
            }
            samples[(dy + 1) * 3 + dx + 1] = h;
        }
    }
    if own != NO_OWNER && (objects[own].flags.x & DILATE) == 0u {
        shown = centre;
    }
    let sx = (3.0 * (samples[2] - samples[0]) + 10.0 * (samples[5] - samples[3]) + 3.0 * (samples[8] - samples[6])) / 32.0;
    let sy = (3.0 * (samples[6] - samples[0]) + 10.0 * (samples[7] - samples[1]) + 3.0 * (samples[8] - samples[2])) / 32.0;
    var owned = 0.0;
    if own != NO_OWNER {
        owned = 1.0;
    }
    surface[k] = vec4<f32>(shown, sx, sy, owned);
}
