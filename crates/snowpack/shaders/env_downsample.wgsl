// Environment downsample: box-average blocks of the full equirect map into a
// small one, clamping each texel's luminance first so the sun (lit
// separately as the directional light) is not counted twice. CPU twin:
// `cpu/env_downsample.rs`.

struct EnvParams {
    src_w: u32,
    src_h: u32,
    dst_w: u32,
    dst_h: u32,
    clamp_luminance: f32,
    levels: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: EnvParams;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<f32>>;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.dst_w || id.y >= params.dst_h {
        return;
    }
    let x0 = id.x * params.src_w / params.dst_w;
    let x1 = (id.x + 1u) * params.src_w / params.dst_w;
    let y0 = id.y * params.src_h / params.dst_h;
    let y1 = (id.y + 1u) * params.src_h / params.dst_h;
    var sum = vec3<f32>(0.0);
    for (var y = y0; y < y1; y++) {
        for (var x = x0; x < x1; x++) {
            let c = src[y * params.src_w + x].rgb;
            let lum = dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
            sum += c * min(1.0, params.clamp_luminance / max(lum, 1e-6));
        }
    }
    let n = f32((x1 - x0) * (y1 - y0));
    dst[id.y * params.dst_w + id.x] = vec4<f32>(sum / n, 1.0);
}
