//! The objects plug-in's front: objects snow settles on ([`SnowAccumulation`],
//! which owns their atlas and passes), placed over the core window and read
//! back here for `SnowDeformation::set_objects` and
//! `SnowDeformation::read_object_stats`. Its frame steps (occlusion, atlas)
//! are in [`super::steps`].

use crate::accumulate::{ObjectStats, SnowAccumulation, SnowObject};

use crate::gpu::GpuContext;
use crate::snowfall::Snowfall;

use super::core_window::CoreWindow;
use crate::gpu::context::GpuContextExt;

/// Places `objects` in `accumulation` (replacing any before, and their
/// snow; none: no accumulation): lays out their atlas, builds the
/// accumulation passes and binds their occlusion map to `core`'s update.
/// An error building them leaves the objects before in place.
pub(super) fn place(
    ctx: &GpuContext,
    core: &mut CoreWindow,
    accumulation: &mut Option<SnowAccumulation>,
    objects: &[SnowObject],
) -> Result<(), crate::SnowError> {
    if objects.is_empty() {
        *accumulation = None;
        core.bind_sky(&ctx.device, None);
        return Ok(());
    }
    let p = core.params();
    let atlas = p.snowfall.as_ref().map_or(Snowfall::default().atlas_resolution, |s| s.atlas_resolution);
    let acc = SnowAccumulation::new(&ctx.device, objects, atlas, p.resolution, p.texel_m())?;
    core.bind_sky(&ctx.device, Some(acc.sky_view()));
    *accumulation = Some(acc);
    ctx.check("creating the accumulation passes")
}

/// The snow on each object of `accumulation` (in placing order), read back
/// from the GPU (blocking); empty without objects.
pub(super) fn read_stats(ctx: &GpuContext, accumulation: Option<&SnowAccumulation>) -> Result<Vec<ObjectStats>, crate::SnowError> {
    match accumulation {
        Some(acc) => Ok(acc.stats(&acc.read_atlas(ctx)?)),
        None => Ok(Vec::new()),
    }
}
