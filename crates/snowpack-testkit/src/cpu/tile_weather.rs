//! CPU twin of `tile_weather.wgsl` and of `pass_time` in `shared/tiles.wgsl`.

use snowpack::TerrainSource;
use snowpack::low_level::tiles::streaming::{PLANE_FALLEN, PLANE_SNOW, plane_packed, plane_stamps};
use snowpack::low_level::tiles::weather::WeatherParams;

use super::stamp::{STAMP_EMPTY, height};

/// One texel's persistent state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelState {
    /// Snow height (m).
    pub snow: f32,
    /// Packed footprint.
    pub stamp: u32,
    /// Snowfall so far above the rest depth (m).
    pub fallen: f32,
    /// Packed snow (snow quanta); time passing leaves it as it is.
    pub packed: u32,
}

/// The time that passes: snowfall, refill and footprint refill (quanta).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TimePassed {
    /// Snowfall on open ground (m).
    pub fall_m: f32,
    /// Trail refill (m).
    pub refill_m: f32,
    /// Footprint refill (stamp quanta).
    pub quanta: u32,
}

/// The snow's constants `pass_time` needs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SnowConstants {
    /// Rest depth (m).
    pub depth_m: f32,
    /// Most snowfall a texel keeps (m).
    pub max_fallen_m: f32,
    /// Footprint quantisation range (m).
    pub low_m: f32,
    /// Footprint quantisation range (m).
    pub high_m: f32,
    /// Whether the world has snowfall.
    pub use_fallen: bool,
}

/// Time passing on untouched, open texel over `ground`: what the update gives it.
#[must_use]
pub fn pass_time(ground: f32, c: &SnowConstants, t: TexelState, time: &TimePassed) -> TexelState {
    let mut out = t;
    let (mut lying, mut gained) = (0.0, 0.0);
    if c.use_fallen {
        lying = t.fallen.max((t.fallen + time.fall_m).min(c.max_fallen_m));
        gained = lying - t.fallen;
        out.fallen = lying;
    }
    let rest = ground + (c.depth_m + lying);
    let h = (t.snow + gained + time.refill_m).min(rest);
    if t.stamp != STAMP_EMPTY && time.quanta > 0 {
        let q = time.quanta.min(65536);
        let (hq, fq) = (t.stamp >> 16, t.stamp & 0xffff);
        let foot = fq + q;
        out.stamp = if foot > 65535 || height(foot, c.low_m, c.high_m) >= rest { STAMP_EMPTY } else { ((hq + q).min(65535) << 16) | foot };
    }
    out.snow = h.max(ground);
    out
}

/// How a slot is laid out: texels per plane, planes, and whether it has the
/// snowfall plane (the footprint plane is there when a plane is left over:
/// the passes' `STAMP_PLANE` flag, `tiles::streaming::with_stamp_plane_flag`).
#[derive(Clone, Copy, Debug)]
pub struct SlotLayout {
    /// Texels per plane.
    pub area: usize,
    /// Planes per slot ([`snowpack::low_level::tiles::streaming::planes`]).
    pub planes: usize,
    /// The world has snowfall (the slot a snowfall plane).
    pub use_fallen: bool,
}

impl SlotLayout {
    fn has_stamps(self) -> bool {
        self.planes > 2 + usize::from(self.use_fallen)
    }
}

/// Reads texel `k` of slot `slot`: its state (no footprint, 0 m of
/// snowfall, where the slot has no plane for them). The weather pass
/// leaves the packed snow as it is and reads none (0 here).
#[must_use]
pub fn read_texel(tiles: &[u32], slot: usize, l: SlotLayout, k: usize) -> TexelState {
    let (area, base) = (l.area, slot * l.planes * l.area + k);
    let fallen = if l.use_fallen { f32::from_bits(tiles[base + PLANE_FALLEN * area]) } else { 0.0 };
    let stamp = if l.has_stamps() { tiles[base + plane_stamps(l.planes) * area] } else { STAMP_EMPTY };
    TexelState { snow: f32::from_bits(tiles[base + PLANE_SNOW * area]), stamp, fallen, packed: 0 }
}

/// Writes texel `k` of slot `slot`, all but its packed snow ([`write_packed`]).
pub fn write_texel(tiles: &mut [u32], slot: usize, l: SlotLayout, k: usize, t: TexelState) {
    let (area, base) = (l.area, slot * l.planes * l.area + k);
    tiles[base + PLANE_SNOW * area] = t.snow.to_bits();
    if l.use_fallen {
        tiles[base + PLANE_FALLEN * area] = t.fallen.to_bits();
    }
    if l.has_stamps() {
        tiles[base + plane_stamps(l.planes) * area] = t.stamp;
    }
}

/// Writes texel `k`'s packed snow (the restore does; the weather does not).
pub fn write_packed(tiles: &mut [u32], slot: usize, l: SlotLayout, k: usize, packed: u32) {
    tiles[(slot * l.planes + plane_packed(l.use_fallen)) * l.area + k] = packed;
}

/// One frame of weather on the resident `tiles` of the listed `slots`,
/// outside the window, over `terrain`; `owners` holds `(col, row, resident, 0)` per slot.
pub fn weather(p: &WeatherParams, owners: &[[i32; 4]], slots: &[u32], terrain: &TerrainSource, tiles: &mut [u32]) {
    if !p.passes_time() {
        return;
    }
    let side = p.side as i32;
    let area = (p.side * p.side) as usize;
    let c = SnowConstants {
        depth_m: p.depth_m,
        max_fallen_m: p.max_fallen_m,
        low_m: p.low_m,
        high_m: p.high_m,
        use_fallen: p.flags & WeatherParams::USE_FALLEN != 0,
    };
    let time = TimePassed { fall_m: p.fall_m, refill_m: p.refill_m, quanta: p.quanta };
    let res = p.resolution as i32;
    for &slot in slots {
        let (slot, owner) = (slot as usize, owners[slot as usize]);
        if owner[2] == 0 {
            continue;
        }
        for k in 0..area {
            let g = [owner[0] * side + (k as i32 % side), owner[1] * side + (k as i32 / side)];
            let d = [g[0] - p.origin[0], g[1] - p.origin[1]];
            if d[0] >= 0 && d[1] >= 0 && d[0] < res && d[1] < res {
                continue;
            }
            let layout = SlotLayout { area, planes: p.planes as usize, use_fallen: c.use_fallen };
            let t = read_texel(tiles, slot, layout, k);
            let ground = super::window::texel_ground(terrain, g, p.texel_m);
            write_texel(tiles, slot, layout, k, pass_time(ground, &c, t, &time));
        }
    }
}
