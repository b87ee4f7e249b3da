//! Whole-window readbacks and the window's GPU resources, for the renderer,
//! the app, tools and tests (`low_level`): blocking, never in a frame loop.
//! `WindowLayout` lays the window's toroidal buffers out window-local.

use crate::deform::packed_snow;
use crate::deform::snow_word::SNOW_QUANTUM_M;

/// How a window's toroidal buffers lie: its texels per side and the global
/// texel of its corner (`CoreWindow::layout`).
#[derive(Clone, Copy, Debug)]
pub(super) struct WindowLayout {
    /// Window texels per side.
    pub resolution: u32,
    /// Global texel index of local (0, 0).
    pub origin: [i64; 2],
}

impl WindowLayout {
    /// A toroidal window buffer laid out window-local row-major.
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    pub(super) fn untorus<T: Copy + Default>(&self, toroidal: &[T]) -> Vec<T> {
        untorus(self.resolution, self.origin, toroidal)
    }

    /// The packed snow (m of fresh snow) per texel, window-local, from the
    /// packed buffer's words as read back (its count words after the texels').
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
    pub(super) fn packed_m(&self, words: &[u32]) -> Vec<f32> {
        let texels = self.resolution as usize * self.resolution as usize;
        let quanta = self.untorus(&packed_snow::unpack(words, texels));
        quanta.iter().map(|&q| q as f32 * SNOW_QUANTUM_M).collect()
    }
}

/// A toroidal window buffer (origin texel `origin`) laid out window-local row-major.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
fn untorus<T: Copy + Default>(resolution: u32, origin: [i64; 2], toroidal: &[T]) -> Vec<T> {
    let r = resolution as usize;
    let ri = r as i64;
    let (oc, or) = (origin[0].rem_euclid(ri) as usize, origin[1].rem_euclid(ri) as usize);
    let mut out = vec![T::default(); r * r];
    for i in 0..r {
        let si = (or + i) % r;
        for j in 0..r {
            out[i * r + j] = toroidal[si * r + (oc + j) % r];
        }
    }
    out
}
