//! CPU twin of `displace.wgsl`, and of the update's side of displacement
//! (`displace_target` and the packing with `DISPLACE` in
//! `update.wgsl` and `shared/pack_press.wgsl`).

use snowpack::low_level::deform::displace::{DisplaceParams, MOST_QUANTA, OFFSETS, PRESSED, code, code_quanta, code_target};
use snowpack::low_level::deform::packed_snow;
use snowpack::low_level::deform::update::UpdateParams;

use super::window::storage_index;

/// How far the way out of a press rises at neighbour `[column, row]` `n`
/// from a texel at capture depth `d0` (eighths of a texel's rise, 0..=63;
/// 63 where nothing presses): `displace_rise`.
fn rise(p: &UpdateParams, capture: &[f32], n: [i32; 2], d0: f32) -> i32 {
    let d = capture[n[1] as usize * p.resolution as usize + n[0] as usize];
    if d >= 1.0 {
        return 63;
    }
    ((d - d0) * p.displace_k).floor().clamp(0.0, 63.0) as i32
}

/// The way the first pusher over window-local point `q` (m) pushes, as an
/// integer vector (its unit direction times 1000): `displace_push`.
fn push(p: &UpdateParams, q: [f32; 2]) -> Option<[i32; 2]> {
    p.pushers.iter().find_map(|[a, b]| {
        let d = [q[0] - a[0], q[1] - a[1]];
        let (u, v) = (d[0] * a[2] + d[1] * a[3], d[1] * a[2] - d[0] * a[3]);
        (u.abs() <= b[0] && v.abs() <= b[1]).then(|| [(b[2] * 1000.0).round_ties_even() as i32, (b[3] * 1000.0).round_ties_even() as i32])
    })
}

/// The offset index ([`OFFSETS`]) that snow at window-local texel (i, j)
/// moves to (`displace_target`): the neighbour in the window closest in
/// direction to the rise's mean direction (under a box that pushes, its
/// push), then the higher rise, then the first, among those the press holds
/// less deep (any, under a box that pushes); without one, the highest rise;
/// `None` where nothing rises.
#[must_use]
pub fn target(p: &UpdateParams, capture: &[f32], i: u32, j: u32) -> Option<usize> {
    let r = p.resolution as i32;
    let d0 = capture[(i * p.resolution + j) as usize];
    let here = [j as i32, i as i32];
    let mut rise_of = [-1i32; 24];
    let mut g = [0i32; 2];
    for (k, o) in OFFSETS.iter().enumerate() {
        let n = [here[0] + o[0], here[1] + o[1]];
        if (0..r).contains(&n[0]) && (0..r).contains(&n[1]) {
            let w = rise(p, capture, n, d0);
            g = [g[0] + w * o[0], g[1] + w * o[1]];
            rise_of[k] = w;
        }
    }
    let q = [(here[0] as f32 + 0.5) * p.texel_m, (here[1] as f32 + 0.5) * p.texel_m];
    let pushing = push(p, q).filter(|v| *v != [0, 0]);
    if let Some(push) = pushing {
        g = push;
    }
    // By the rise alone, only to a neighbour the press holds less deep (or
    // not at all); a moving box carries its snow on across its own texels.
    let least = if pushing.is_some() { 0 } else { 1 };
    let mut best: Option<(usize, u32, u32)> = None;
    for (k, o) in OFFSETS.iter().enumerate() {
        let dot = o[0] * g[0] + o[1] * g[1];
        if rise_of[k] < least || dot <= 0 {
            continue;
        }
        let len = (o[0] * o[0] + o[1] * o[1]) as u32;
        let better = match best {
            None => true,
            Some((b, b_dot, b_len)) => {
                let (x, y) = (dot as u32 * dot as u32 * b_len, b_dot * b_dot * len);
                x > y || (x == y && rise_of[k] > rise_of[b])
            }
        };
        if better {
            best = Some((k, dot as u32, len));
        }
    }
    if let Some((k, ..)) = best {
        return Some(k);
    }
    let mut highest: Option<usize> = None;
    for k in 0..24 {
        if rise_of[k] > 0 && highest.is_none_or(|b| rise_of[k] > rise_of[b]) {
            highest = Some(k);
        }
    }
    highest
}

/// The update's packing at texel `s` of window-local (i, j) in a window
/// that displaces: its deficit rose `from` → `to` (`at_ground` up to the
/// terrain) and the actors press it (`pressed`). Packs up to the final
/// density; what is beyond leaves (at most [`MOST_QUANTA`] in 16-quantum
/// steps) to the [`target`], the rest stays packed. Returns the move's code
/// for the upper half of the snow word ([`PRESSED`] where the actors press
/// and nothing moves, else 0 without a move) and the quanta counted as
/// displaced (beyond 16 bits of packed snow).
#[must_use]
pub fn press(
    p: &UpdateParams,
    capture: &[f32],
    packed: &mut [u32],
    (s, i, j): (usize, u32, u32),
    (from, to, at_ground): (u32, u32, u32),
    pressed: bool,
) -> (u32, u64) {
    let squeezed = packed_snow::get(packed, s) + (to - from.min(to));
    let cap = packed_snow::cap(at_ground - to, p.pack_ratio);
    let leaves = if pressed && squeezed > cap { (squeezed - cap).min(MOST_QUANTA) & !15 } else { 0 };
    let target = if leaves > 0 { target(p, capture, i, j) } else { None };
    let kept = squeezed - if target.is_some() { leaves } else { 0 };
    packed_snow::set(packed, s, kept.min(0xffff));
    let mark = match target {
        Some(t) => code(t, leaves),
        None if pressed => PRESSED,
        None => 0,
    };
    (mark, u64::from(kept.saturating_sub(0xffff)))
}

/// Gathers, at every texel, the moves its neighbours' snow words name it
/// for (upper halves) into its lying snow (`fallen`, metres); with
/// [`DisplaceParams::SHARE`] flags the tile of every texel that gains
/// (`flags`, [`snowpack::low_level::replicate::flags::ShareGrid`]).
pub fn displace(p: &DisplaceParams, snow: &[u32], fallen: &mut [f32], flags: &mut [u32]) {
    let r = p.resolution as i32;
    let grid = snowpack::low_level::replicate::flags::ShareGrid { side: p.share_side.max(1), keys: p.share_keys };
    for i in 0..r {
        for j in 0..r {
            let mut gained = 0u32;
            for (k, o) in OFFSETS.iter().enumerate() {
                let n = [j - o[0], i - o[1]];
                if !(0..r).contains(&n[0]) || !(0..r).contains(&n[1]) {
                    continue;
                }
                let c = snow[storage_index(p.origin, p.resolution, n[1] as u32, n[0] as u32)] >> 16;
                if code_target(c) == k as u32 + 1 {
                    gained += code_quanta(c);
                }
            }
            if gained == 0 {
                continue;
            }
            let s = storage_index(p.origin, p.resolution, i as u32, j as u32);
            fallen[s] += gained as f32 * 0.0001;
            if p.flags & DisplaceParams::SHARE != 0 && !flags.is_empty() {
                flags[grid.slot([i64::from(p.origin[0]) + i64::from(j), i64::from(p.origin[1]) + i64::from(i)])] = 1;
            }
        }
    }
}
