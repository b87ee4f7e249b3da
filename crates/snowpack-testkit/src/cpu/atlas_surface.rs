//! CPU twin of `atlas_surface.wgsl`.

use snowpack::low_level::accumulate::SurfaceParams;
use snowpack::low_level::accumulate::atlas::NO_OWNER;

/// (height, slope x, slope y, owned) per atlas texel from the accumulation;
/// `dilate[o]` says whether object `o` is dilated.
#[must_use]
pub fn atlas_surface(p: &SurfaceParams, dilate: &[bool], owner: &[u32], acc: &[f32]) -> Vec<[f32; 4]> {
    let n = p.atlas_resolution as i32;
    let mut out = vec![[0.0; 4]; (n * n) as usize];
    let dilated = |o: u32| o != NO_OWNER && dilate[o as usize];
    for y in 0..n {
        for x in 0..n {
            let k = (y * n + x) as usize;
            let own = owner[k];
            let centre = if own == NO_OWNER { 0.0 } else { acc[k] };
            let mut shown = centre;
            let mut s = [0.0f32; 9];
            for dy in -1i32..=1 {
                for dx in -1i32..=1 {
                    let (sx, sy) = (x + dx, y + dy);
                    let mut h = centre;
                    if sx >= 0 && sy >= 0 && sx < n && sy < n {
                        let m = (sy * n + sx) as usize;
                        let o = owner[m];
                        if dilated(o) && (own == NO_OWNER || o == own) {
                            shown = shown.max(acc[m]);
                        }
                        if o == own && own != NO_OWNER {
                            h = acc[m];
                        }
                    }
                    s[((dy + 1) * 3 + dx + 1) as usize] = h;
                }
            }
            if own != NO_OWNER && !dilated(own) {
                shown = centre;
            }
            let sx = (3.0 * (s[2] - s[0]) + 10.0 * (s[5] - s[3]) + 3.0 * (s[8] - s[6])) / 32.0;
            let sy = (3.0 * (s[6] - s[0]) + 10.0 * (s[7] - s[1]) + 3.0 * (s[8] - s[2])) / 32.0;
            out[k] = [shown, sx, sy, if own == NO_OWNER { 0.0 } else { 1.0 }];
        }
    }
    out
}
