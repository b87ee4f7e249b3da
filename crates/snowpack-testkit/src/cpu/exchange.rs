//! CPU twin of `exchange.wgsl` and `tile_index` in `shared/tiles.wgsl`.

use snowpack::low_level::deform::packed_snow::{self, LedgerCounts};
use snowpack::low_level::deform::snow_word;
use snowpack::low_level::deform::window::TexelRect;
use snowpack::low_level::tiles::exchange::ExchangeParams;
use snowpack::low_level::tiles::streaming::{PLANE_FALLEN, PLANE_SNOW, plane_packed, plane_stamps};

use super::window::storage_index;

/// The key table's "no slot".
pub const NO_SLOT: u32 = u32::MAX;

/// Index into the resident tiles (`planes` planes a slot) of global texel
/// `g` (`[column, row]`), plane `plane`, through the key `table` of `nk`²
/// entries; `None` where its tile has no slot.
#[must_use]
pub fn tile_index(g: [i32; 2], side: u32, nk: u32, table: &[u32], planes: usize, plane: usize) -> Option<usize> {
    let s = side as i32;
    let (tc, tr) = (g[0].div_euclid(s), g[1].div_euclid(s));
    let (lx, ly) = ((g[0] - tc * s) as usize, (g[1] - tr * s) as usize);
    let slot = table[(tr.rem_euclid(nk as i32) * nk as i32 + tc.rem_euclid(nk as i32)) as usize];
    (slot != NO_SLOT).then(|| (slot as usize * planes + plane) * (side * side) as usize + ly * side as usize + lx)
}

/// The window's toroidal buffers the exchange reads and writes.
#[derive(Debug)]
pub struct WindowBuffers<'a> {
    /// The terrain's source: the rest height the snow words are below.
    pub terrain: &'a snowpack::TerrainSource,
    /// Snow words (`shared/snow_word.wgsl`).
    pub snow: &'a mut [u32],
    /// Packed footprints.
    pub stamps: &'a mut [u32],
    /// Snowfall so far (one texel without snowfall).
    pub fallen: &'a mut [f32],
    /// Packed snow, two texels a word: stashed with the texel and loaded back.
    pub packed: &'a mut [u32],
}

/// Stashes (with [`ExchangeParams::STASH`]) or loads the texels of `rects`
/// whose tiles have a slot in the key `table`, or with
/// [`ExchangeParams::SWEEP`] moves nothing; returns the ledger's counts
/// (with [`ExchangeParams::COUNT`]: what a stash or a sweep with `STASH`
/// moved out as left, what a load or a sweep without it moved in as entered).
pub fn exchange(p: &ExchangeParams, rects: &[TexelRect], table: &[u32], tiles: &mut [u32], w: &mut WindowBuffers<'_>) -> LedgerCounts {
    let use_fallen = p.flags & ExchangeParams::USE_FALLEN != 0;
    let stashing = p.flags & ExchangeParams::STASH != 0;
    let mut moved = 0u64;
    for rect in rects.iter().take(2) {
        for i in rect[0]..rect[0] + rect[2] {
            for j in rect[1]..rect[1] + rect[3] {
                let s = storage_index(p.origin, p.resolution, i, j);
                let done = if p.flags & ExchangeParams::SWEEP != 0 {
                    true
                } else if stashing {
                    stash(p, s, (table, &mut *tiles), w)
                } else {
                    load(p, [i, j], s, (table, &*tiles), w)
                };
                if done {
                    let lying = if use_fallen { w.fallen[s] } else { 0.0 };
                    moved += u64::from(packed_snow::ledger_column(w.snow[s], p.depth_m, lying, packed_snow::get(w.packed, s)));
                }
            }
        }
    }
    let counted = if p.flags & ExchangeParams::COUNT != 0 { moved } else { 0 };
    if stashing { LedgerCounts { left_q: counted, ..LedgerCounts::default() } } else { LedgerCounts { entered_q: counted, ..LedgerCounts::default() } }
}

/// The old window's texel at storage `s` into its tile; `false` where its
/// tile has no slot.
fn stash(p: &ExchangeParams, s: usize, (table, tiles): (&[u32], &mut [u32]), w: &WindowBuffers<'_>) -> bool {
    let res = p.resolution as i32;
    let use_fallen = p.flags & ExchangeParams::USE_FALLEN != 0;
    let (side, planes) = (p.side, p.planes as usize);
    let (sj, si) = ((s % p.resolution as usize) as i32, (s / p.resolution as usize) as i32);
    let o = p.old_origin;
    let g = [o[0] + (sj - o[0]).rem_euclid(res), o[1] + (si - o[1]).rem_euclid(res)];
    let Some(at) = tile_index(g, side, p.keys_per_side, table, planes, 0) else { return false };
    let idx = |plane: usize| at + plane * (side * side) as usize;
    let ground = super::window::texel_ground(w.terrain, g, p.texel_m);
    let column = p.depth_m + if use_fallen { w.fallen[s] } else { 0.0 };
    tiles[idx(PLANE_SNOW)] = snow_word::column_height(w.snow[s], ground, column).to_bits();
    if p.flags & ExchangeParams::HAS_STAMPS != 0 {
        tiles[idx(plane_stamps(planes))] = w.stamps[s];
    }
    if use_fallen {
        tiles[idx(PLANE_FALLEN)] = w.fallen[s].to_bits();
    }
    tiles[idx(plane_packed(use_fallen))] = packed_snow::get(w.packed, s);
    true
}

/// Window-local texel `[i, j]` (at storage `s`) from its tile; `false`
/// where its tile has no slot.
fn load(p: &ExchangeParams, [i, j]: [u32; 2], s: usize, (table, tiles): (&[u32], &[u32]), w: &mut WindowBuffers<'_>) -> bool {
    let use_fallen = p.flags & ExchangeParams::USE_FALLEN != 0;
    let (side, planes) = (p.side, p.planes as usize);
    let g = [p.origin[0] + j as i32, p.origin[1] + i as i32];
    let Some(at) = tile_index(g, side, p.keys_per_side, table, planes, 0) else { return false };
    let idx = |plane: usize| at + plane * (side * side) as usize;
    let ground = super::window::texel_ground(w.terrain, g, p.texel_m);
    let mut column = p.depth_m;
    if p.flags & ExchangeParams::HAS_STAMPS != 0 {
        w.stamps[s] = tiles[idx(plane_stamps(planes))];
    }
    if use_fallen {
        let lying = f32::from_bits(tiles[idx(PLANE_FALLEN)]);
        w.fallen[s] = lying;
        column += lying;
    }
    let h = f32::from_bits(tiles[idx(PLANE_SNOW)]);
    w.snow[s] = snow_word::column_press(ground, column, h);
    packed_snow::set(w.packed, s, tiles[idx(plane_packed(use_fallen))].min(0xffff));
    true
}
