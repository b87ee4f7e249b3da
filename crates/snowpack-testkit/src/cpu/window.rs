//! CPU twin of `window.wgsl`.

use snowpack::TerrainSource;
use snowpack::low_level::deform::packed_snow::{self, LedgerCounts};
use snowpack::low_level::deform::window::{TexelRect, WindowParams};
pub use snowpack::low_level::terrain::texel_ground;

/// Toroidal storage index of window-local texel (i, j).
#[must_use]
pub fn storage_index(origin: [i32; 2], res: u32, i: u32, j: u32) -> usize {
    let r = res as i32;
    let si = (origin[1] + i as i32).rem_euclid(r) as usize;
    let sj = (origin[0] + j as i32).rem_euclid(r) as usize;
    si * res as usize + sj
}

/// The ground under every texel of a window at `origin`, toroidal: what the
/// passes evaluate per texel, as the array the CPU twins take.
#[must_use]
pub fn ground_plane(terrain: &TerrainSource, origin: [i32; 2], res: u32, texel_m: f32) -> Vec<f32> {
    let mut out = vec![0.0; (res * res) as usize];
    for i in 0..res {
        for j in 0..res {
            out[storage_index(origin, res, i, j)] = texel_ground(terrain, [origin[0] + j as i32, origin[1] + i as i32], texel_m);
        }
    }
    out
}

/// Writes fresh snow (snow words with no deficit: at rest, the snowfall so
/// far included, no packed snow) into the texels of `rects` and clears
/// their footprints; returns the ledger's counts of what left (with
/// [`WindowParams::COUNT_LEFT`]) and entered.
pub fn expose(p: &WindowParams, rects: &[TexelRect], snow: &mut [u32], stamps: &mut [u32], (fallen, packed): (&mut [f32], &mut [u32])) -> LedgerCounts {
    let mut ledger = LedgerCounts::default();
    let write_fallen = p.flags & WindowParams::WRITE_FALLEN != 0;
    for rect in rects.iter().take(2) {
        for i in rect[0]..rect[0] + rect[2] {
            for j in rect[1]..rect[1] + rect[3] {
                let s = storage_index(p.origin, p.resolution, i, j);
                if p.flags & WindowParams::COUNT_LEFT != 0 {
                    let lying = if write_fallen { fallen[s] } else { 0.0 };
                    ledger.left_q += u64::from(packed_snow::ledger_column(snow[s], p.depth_m, lying, packed_snow::get(packed, s)));
                }
                ledger.entered_q += u64::from(packed_snow::ledger_column(0, p.depth_m, if write_fallen { p.fallen_m } else { 0.0 }, 0));
                snow[s] = 0;
                packed_snow::set(packed, s, 0);
                if p.flags & WindowParams::WRITE_STAMPS != 0 {
                    stamps[s] = super::stamp::STAMP_EMPTY;
                }
                if write_fallen {
                    fallen[s] = p.fallen_m;
                }
            }
        }
    }
    ledger
}
