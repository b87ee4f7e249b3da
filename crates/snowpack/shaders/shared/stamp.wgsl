// Packed footprints of the points technique (Rise of the Tomb Raider, GPU Pro 7):
// one u32 per texel, (height16 << 16) | foot16, so atomicMin keeps the lowest
// footprint height and, among equal heights, the lowest foot. Heights are
// quantised linearly over [low_m, high_m] (the capture range: terrain bounds
// with a 1 m margin, plus the rest depth): a quantum is (high - low) / 65535,
// and rounding to nearest costs at most half of one. CPU twin: src/cpu/stamp.rs.

const STAMP_EMPTY: u32 = 0xffffffffu;

fn stamp_quantise(h: f32, low: f32, high: f32) -> u32 {
    let t = clamp((h - low) / (high - low), 0.0, 1.0);
    return u32(t * 65535.0 + 0.5);
}

fn stamp_height(q: u32, low: f32, high: f32) -> f32 {
    return low + f32(q) / 65535.0 * (high - low);
}
