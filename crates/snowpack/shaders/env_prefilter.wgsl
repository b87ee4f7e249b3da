// #import shared/frame

// Environment prefilter: from the downsampled map, level 0 gets irradiance/pi
// (cosine convolution) and level k >= 1 radiance convolved with a GGX lobe of
// roughness k / (levels - 1) (split-sum, n = v = r). Brute force over every
// source texel with its solid angle. CPU twin: `cpu/env_prefilter.rs`.
// Its params are env_downsample's.

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
    if id.x >= params.dst_w || id.y >= params.dst_h || id.z >= params.levels {
        return;
    }
    let n = equirect_dir((f32(id.x) + 0.5) / f32(params.dst_w), (f32(id.y) + 0.5) / f32(params.dst_h));
    let level = id.z;
    let roughness = f32(level) / f32(params.levels - 1u);
    let a = roughness * roughness;
    let a2 = a * a;
    let texel_angle = (2.0 * PI / f32(params.src_w)) * (PI / f32(params.src_h));
    var sum = vec3<f32>(0.0);
    var weight = 0.0;
    for (var y = 0u; y < params.src_h; y++) {
        let v = (f32(y) + 0.5) / f32(params.src_h);
        let solid_angle = texel_angle * sin(v * PI);
        for (var x = 0u; x < params.src_w; x++) {
            let l = equirect_dir((f32(x) + 0.5) / f32(params.src_w), v);
            let n_l = dot(n, l);
            if n_l <= 0.0 {
                continue;
            }
            var w = n_l * solid_angle;
            if level > 0u {
                let dd = n_l * n_l * (a2 - 1.0) + 1.0;
                w *= a2 / (PI * dd * dd);
            }
            sum += src[y * params.src_w + x].rgb * w;
            weight += w;
        }
    }
    var out = sum / PI;
    if level > 0u {
        out = sum / max(weight, 1e-12);
    }
    dst[(level * params.dst_h + id.y) * params.dst_w + id.x] = vec4<f32>(out, 1.0);
}
