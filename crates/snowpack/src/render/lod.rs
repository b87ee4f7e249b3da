//! Level of detail for the snow terrain: a CDLOD quadtree (Strugar 2010) of
//! instanced grid patches chosen on the CPU each frame.
//!
//! * Level 0 patches are `finest_m` wide; each level doubles. A level-`i`
//!   patch is drawn where the LOD distance is within `range_i = range_factor *
//!   size_i`, and its odd vertices geomorph onto the next level's grid over the
//!   last part of that range, so levels meet without popping.
//! * The LOD distance is the distance to the eye (with a fixed vertical term
//!   per frame, so it depends on x and z only) minus a *detail bonus* that
//!   brings detail closer over the deformation window: trails get finer
//!   triangles than undisturbed snow at the same distance.
//! * No cracks: a patch that borders a coarser one has its edge vertices fully
//!   morphed there, and the coarser one is not yet morphing. That holds when
//!   the LOD distance varies slowly enough across a patch, which the range
//!   factor guarantees (see `docs/rendering.md`; `tests::seams_are_crack_free`
//!   checks it).
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use glam::{Mat4, Vec2, Vec4};

/// One patch instance as the vertex shader reads it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PatchInstance {
    /// Origin x, origin z, size (m), quads per side.
    pub node: [f32; 4],
    /// Morph start, morph end (LOD distance, m), level, unused.
    pub morph: [f32; 4],
}

impl PatchInstance {
    /// Quads per side.
    #[must_use]
    pub fn quads(&self) -> u32 {
        self.node[3] as u32
    }

    /// Level (0 finest).
    #[must_use]
    pub fn level(&self) -> u32 {
        self.morph[2] as u32
    }

    /// Triangles drawn.
    #[must_use]
    pub fn triangles(&self) -> u32 {
        self.quads() * self.quads() * 2
    }
}

/// Inputs of the selection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodSettings {
    /// Side of a level-0 patch (m).
    pub finest_m: f32,
    /// Quads per patch side (a multiple of 4).
    pub quads: u32,
    /// `range_i / size_i`; at least 8 keeps seams crack-free with the detail bonus.
    pub range_factor: f32,
    /// Morph starts at this fraction of the range.
    pub morph_start: f32,
    /// Morph is complete at this fraction of the range (below 1 for rounding slack).
    pub morph_end: f32,
    /// Nothing is drawn beyond this LOD distance (m).
    pub view_distance_m: f32,
    /// Detail bonus over the deformation window (m).
    pub bonus_m: f32,
    /// Distance over which the bonus fades outside the window (m); at least `bonus_m`.
    pub bonus_margin_m: f32,
    /// Deformation window (corner x, z; extent), if placed.
    pub window: Option<(Vec2, f32)>,
    /// Vertical term of the LOD distance: the eye's height above the terrain below it (m).
    pub vertical_m: f32,
}

impl LodSettings {
    /// Range of `level` (m of LOD distance).
    #[must_use]
    pub fn range(&self, level: u32) -> f32 {
        self.range_factor * self.size(level)
    }

    /// Patch side at `level` (m).
    #[must_use]
    pub fn size(&self, level: u32) -> f32 {
        self.finest_m * (1u64 << level) as f32
    }

    /// The coarsest level: the first whose range reaches the view distance.
    #[must_use]
    pub fn top_level(&self) -> u32 {
        (0..24).find(|&l| self.range(l) >= self.view_distance_m).unwrap_or(24)
    }

    /// Detail bonus at a point (same as `lod_bonus` in `terrain_draw.wgsl`).
    #[cfg(test)]
    #[must_use]
    pub fn bonus(&self, xz: Vec2) -> f32 {
        let Some((lo, extent)) = self.window else { return 0.0 };
        let hi = lo + Vec2::splat(extent);
        let q = (lo - xz).max(xz - hi).max(Vec2::ZERO);
        self.bonus_m * (1.0 - q.length() / self.bonus_margin_m).clamp(0.0, 1.0)
    }

    /// LOD distance at a point (same as `lod_distance` in `terrain_draw.wgsl`).
    #[cfg(test)]
    #[must_use]
    pub fn distance(&self, eye_xz: Vec2, xz: Vec2) -> f32 {
        let d = (xz - eye_xz).length_squared() + self.vertical_m * self.vertical_m;
        (d.sqrt() - self.bonus(xz)).max(0.0)
    }

    /// A lower bound of the LOD distance over a square.
    fn min_distance(&self, eye_xz: Vec2, lo: Vec2, size: f32) -> f32 {
        let hi = lo + Vec2::splat(size);
        let nearest = eye_xz.clamp(lo, hi);
        let d = ((nearest - eye_xz).length_squared() + self.vertical_m * self.vertical_m).sqrt();
        let bonus = match self.window {
            None => 0.0,
            Some((wlo, extent)) => {
                // Distance between the square and the window rectangle.
                let whi = wlo + Vec2::splat(extent);
                let gap = (wlo - hi).max(lo - whi).max(Vec2::ZERO);
                self.bonus_m * (1.0 - gap.length() / self.bonus_margin_m).clamp(0.0, 1.0)
            }
        };
        (d - bonus).max(0.0)
    }

    fn instance(&self, lo: Vec2, size: f32, quads: u32, level: u32, top: u32) -> PatchInstance {
        let (start, end) = if level == top {
            // Nothing coarser to morph into.
            (f32::MAX / 4.0, f32::MAX / 2.0)
        } else {
            (self.range(level) * self.morph_start, self.range(level) * self.morph_end)
        };
        PatchInstance { node: [lo.x, lo.y, size, quads as f32], morph: [start, end, level as f32, 0.0] }
    }

    /// The patches covering the view for an eye at `eye_xz`, finest near the eye.
    #[must_use]
    pub fn select(&self, eye_xz: Vec2) -> Vec<PatchInstance> {
        let top = self.top_level();
        let root = self.size(top);
        let reach = self.view_distance_m + self.bonus_m;
        // World-aligned roots, so the selection does not shift with the eye.
        let first = ((eye_xz - Vec2::splat(reach)) / root).floor();
        let last = ((eye_xz + Vec2::splat(reach)) / root).floor();
        let mut out = Vec::new();
        let mut z = first.y;
        while z <= last.y {
            let mut x = first.x;
            while x <= last.x {
                let lo = Vec2::new(x, z) * root;
                if self.min_distance(eye_xz, lo, root) <= self.view_distance_m {
                    self.visit(eye_xz, lo, top, top, &mut out);
                }
                x += 1.0;
            }
            z += 1.0;
        }
        out
    }

    /// Selects a node; false when it lies beyond its level's range (its parent draws it).
    fn visit(&self, eye: Vec2, lo: Vec2, level: u32, top: u32, out: &mut Vec<PatchInstance>) -> bool {
        let size = self.size(level);
        let d = self.min_distance(eye, lo, size);
        if level != top && d > self.range(level) {
            return false;
        }
        if level == 0 || d > self.range(level - 1) {
            out.push(self.instance(lo, size, self.quads, level, top));
            return true;
        }
        let half = size * 0.5;
        for (cx, cz) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let child = lo + Vec2::new(cx, cz) * half;
            if !self.visit(eye, child, level - 1, top, out) {
                // This quarter stays at this level: half the quads over half the side.
                out.push(self.instance(child, half, self.quads / 2, level, top));
            }
        }
        true
    }
}

/// The side planes of a clip-space volume (`view_proj`), as `ax + by + cz + d >= 0` inside.
#[must_use]
pub fn side_planes(view_proj: Mat4) -> [Vec4; 4] {
    let r0 = view_proj.row(0);
    let r1 = view_proj.row(1);
    let r3 = view_proj.row(3);
    [r3 + r0, r3 - r0, r3 + r1, r3 - r1]
}

/// The patches whose boxes (heights `y_range`) touch the volume inside `planes`.
#[must_use]
pub fn cull(patches: &[PatchInstance], planes: &[Vec4], y_range: (f32, f32)) -> Vec<PatchInstance> {
    patches
        .iter()
        .filter(|p| {
            let lo = glam::Vec3::new(p.node[0], y_range.0, p.node[1]);
            let hi = glam::Vec3::new(p.node[0] + p.node[2], y_range.1, p.node[1] + p.node[2]);
            planes.iter().all(|pl| {
                // The box corner farthest along the plane's normal.
                let c = glam::Vec3::new(if pl.x >= 0.0 { hi.x } else { lo.x }, if pl.y >= 0.0 { hi.y } else { lo.y }, if pl.z >= 0.0 { hi.z } else { lo.z });
                pl.truncate().dot(c) + pl.w >= 0.0
            })
        })
        .copied()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(window: Option<(Vec2, f32)>) -> LodSettings {
        LodSettings {
            finest_m: 1.0,
            quads: 16,
            range_factor: 8.0,
            morph_start: 0.8,
            morph_end: 0.98,
            view_distance_m: 1000.0,
            bonus_m: 32.0,
            bonus_margin_m: 32.0,
            window,
            vertical_m: 3.0,
        }
    }

    fn covers(p: &PatchInstance, xz: Vec2) -> bool {
        xz.x >= p.node[0] && xz.x < p.node[0] + p.node[2] && xz.y >= p.node[1] && xz.y < p.node[1] + p.node[2]
    }

    #[test]
    fn patches_tile_the_view_once() {
        let s = settings(Some((Vec2::new(-20.0, 5.0), 64.0)));
        let eye = Vec2::new(3.3, -7.1);
        let patches = s.select(eye);
        for k in 0..4000 {
            // A spiral of sample points out to 90% of the view distance.
            let t = k as f32 / 4000.0;
            let a = k as f32 * 2.399_963;
            let xz = eye + Vec2::new(a.cos(), a.sin()) * (t.sqrt() * 900.0) + Vec2::splat(0.013);
            let n = patches.iter().filter(|p| covers(p, xz)).count();
            assert_eq!(n, 1, "point {xz} covered {n} times");
        }
    }

    /// Where two patches of different levels share an edge, the finer one is
    /// fully morphed and the coarser one not morphing at all, all along it.
    #[test]
    fn seams_are_crack_free() {
        for (eye, window) in [
            (Vec2::new(0.5, 0.5), None),
            (Vec2::new(3.3, -7.1), Some((Vec2::new(-20.0, 5.0), 64.0))),
            (Vec2::new(-150.0, 80.0), Some((Vec2::new(-32.0, -32.0), 64.0))),
        ] {
            let s = settings(window);
            let patches = s.select(eye);
            let mut seams = 0;
            for a in &patches {
                for b in &patches {
                    if a.level() >= b.level() {
                        continue;
                    }
                    // a is finer: find a shared edge segment.
                    let (alo, asz) = (Vec2::new(a.node[0], a.node[1]), a.node[2]);
                    let (blo, bsz) = (Vec2::new(b.node[0], b.node[1]), b.node[2]);
                    let (ahi, bhi) = (alo + Vec2::splat(asz), blo + Vec2::splat(bsz));
                    let touch_x = (ahi.x - blo.x).abs() < 1e-3 || (bhi.x - alo.x).abs() < 1e-3;
                    let touch_z = (ahi.y - blo.y).abs() < 1e-3 || (bhi.y - alo.y).abs() < 1e-3;
                    let overlap_z = ahi.y.min(bhi.y) - alo.y.max(blo.y);
                    let overlap_x = ahi.x.min(bhi.x) - alo.x.max(blo.x);
                    let segment = if touch_x && overlap_z > 0.0 {
                        let x = if (ahi.x - blo.x).abs() < 1e-3 { ahi.x } else { alo.x };
                        Some((Vec2::new(x, alo.y.max(blo.y)), Vec2::new(x, ahi.y.min(bhi.y))))
                    } else if touch_z && overlap_x > 0.0 {
                        let z = if (ahi.y - blo.y).abs() < 1e-3 { ahi.y } else { alo.y };
                        Some((Vec2::new(alo.x.max(blo.x), z), Vec2::new(ahi.x.min(bhi.x), z)))
                    } else {
                        None
                    };
                    let Some((p0, p1)) = segment else { continue };
                    seams += 1;
                    assert_eq!(b.level(), a.level() + 1, "levels {} and {} meet", a.level(), b.level());
                    for k in 0..=16 {
                        let p = p0.lerp(p1, k as f32 / 16.0);
                        let d = s.distance(eye, p);
                        assert!(d >= a.morph[1], "fine side not fully morphed at {p}: {d} < {}", a.morph[1]);
                        assert!(d <= b.morph[0], "coarse side already morphing at {p}: {d} > {}", b.morph[0]);
                    }
                }
            }
            assert!(seams > 10, "only {seams} seams checked");
        }
    }

    #[test]
    fn deformed_snow_gets_finer_patches() {
        let eye = Vec2::new(0.0, 0.0);
        let window = (Vec2::new(60.0, -32.0), 64.0);
        let level_at = |s: &LodSettings, xz: Vec2| s.select(eye).iter().find(|p| covers(p, xz)).map(PatchInstance::level);
        let probe = Vec2::new(80.0, 0.0);
        let plain = level_at(&settings(None), probe).expect("covered");
        let near = level_at(&settings(Some(window)), probe).expect("covered");
        assert!(near < plain, "level {near} inside the window, {plain} without it");
    }

    #[test]
    fn culling_keeps_what_is_in_front() {
        let s = settings(None);
        let patches = s.select(Vec2::ZERO);
        let cam = crate::render::Camera { position: glam::Vec3::new(0.0, 3.0, 0.0), target: glam::Vec3::new(0.0, 0.0, -10.0), fov_deg: 60.0 };
        let kept = cull(&patches, &side_planes(cam.view_proj(16.0 / 9.0)), (-1.0, 1.0));
        assert!(kept.len() < patches.len() / 2, "{} of {}", kept.len(), patches.len());
        assert!(kept.iter().all(|p| p.node[1] < 5.0), "a patch behind the eye survived");
        assert!(kept.iter().any(|p| covers(p, Vec2::new(0.0, -20.0))));
    }
}
