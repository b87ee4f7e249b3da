//! CPU twin of `shaders/peel_count.wgsl`: the pixels a peeling pass shades.

/// Counts the pixels of `peel_depth` holding a layer (depth > 0, reverse-Z)
/// and sets bit `pass_index` of their `shaded` mask (pass 0 clears the mask first).
pub fn peel_count(peel_depth: &[f32], pass_index: u32, shaded: &mut [u32]) -> u32 {
    let mut count = 0;
    for (depth, mask) in peel_depth.iter().zip(shaded.iter_mut()) {
        if pass_index == 0 {
            *mask = 0;
        }
        if *depth > 0.0 {
            count += 1;
            *mask |= 1 << pass_index;
        }
    }
    count
}
