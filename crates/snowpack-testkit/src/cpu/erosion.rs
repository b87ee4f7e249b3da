//! CPU twin of `erosion.wgsl`: one iteration, four half-sweeps of pairs.

use snowpack::low_level::deform::erosion::ErosionParams;
use snowpack::low_level::deform::packed_snow;
use snowpack::low_level::deform::snow_word::column_press;

use super::window::storage_index;

/// Runs one half-sweep (`p.axis`, `p.offset`) over the toroidal snow words,
/// packed snow (two texels a word) and lying snow (`fallen`, read and
/// written with `p.use_fallen`), with `terrain` per texel, toroidal.
pub fn erode(p: &ErosionParams, terrain: &[f32], fallen: &mut [f32], snow: &mut [u32], packed: &mut [u32]) {
    let res = p.resolution;
    let column = |s: usize, fallen: &[f32]| {
        let ground = terrain[s];
        let column = p.depth_m + if p.use_fallen != 0 { fallen[s] } else { 0.0 };
        column_press(ground, column, ground)
    };
    // `lying_quanta`: a product then a rounding.
    let lying = |s: usize, fallen: &[f32]| if p.use_fallen != 0 { (fallen[s] * 10000.0).round_ties_even() as i32 } else { 0 };
    for a in 0..res {
        for k in 0..res.div_ceil(2) {
            let (i0, j0, i1, j1) = if p.axis == 0 { (a, 2 * k + p.offset, a, 2 * k + p.offset + 1) } else { (2 * k + p.offset, a, 2 * k + p.offset + 1, a) };
            if i1.max(j1) >= res {
                continue;
            }
            let (s0, s1) = (storage_index(p.origin, res, i0, j0), storage_index(p.origin, res, i1, j1));
            if p.marks != 0 && ((snow[s0] >> 27) | (snow[s1] >> 27)) != 0 {
                continue;
            }
            let (d0, d1) = (snow[s0] & 0xffff, snow[s1] & 0xffff);
            let (l0, l1) = (lying(s0, fallen) - d0 as i32, lying(s1, fallen) - d1 as i32);
            let ((sa, da), (sb, db)) = if l1 > l0 { ((s1, d1), (s0, d0)) } else { ((s0, d0), (s1, d1)) };
            let diff = (l1 - l0).unsigned_abs();
            if diff <= p.threshold_q {
                continue;
            }
            let ga = column(sa, fallen);
            let column_a = ga - da.min(ga);
            let moved = ((diff - p.threshold_q) / 2).min(column_a);
            if moved == 0 {
                continue;
            }
            let (qa, qb) = (packed_snow::get(packed, sa), packed_snow::get(packed, sb));
            let carried = moved * qa / column_a;
            let filled = moved.min(db);
            snow[sa] = (snow[sa] & 0xffff_0000) | (da + moved);
            snow[sb] = (snow[sb] & 0xffff_0000) | (db - filled);
            if moved > filled {
                fallen[sb] += (moved - filled) as f32 * 0.0001;
            }
            packed_snow::set(packed, sa, qa - carried);
            packed_snow::set(packed, sb, (qb + carried).min(0xffff));
        }
    }
}

/// One iteration: pairs along x (even, odd), then along z (even, odd), as
/// [`snowpack::low_level::deform::erosion::ErosionPass::record`] dispatches them.
pub fn iterate(p: &ErosionParams, terrain: &[f32], fallen: &mut [f32], snow: &mut [u32], packed: &mut [u32]) {
    for (axis, offset) in ErosionParams::SWEEPS {
        erode(&ErosionParams { axis, offset, ..*p }, terrain, fallen, snow, packed);
    }
}
