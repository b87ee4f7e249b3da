//! The objects plug-in's front: objects snow settles on ([`SnowAccumulation`],
//! which owns their atlas and passes), placed, moved and read back through
//! [`SnowDeformation`]. Its frame steps (occlusion, atlas) are in [`super::steps`].

use crate::accumulate::{SnowAccumulation, SnowObject};

use crate::gpu::GpuContext;
use crate::snowfall::Snowfall;

use super::SnowDeformation;
use crate::gpu::context::GpuContextExt;

impl SnowDeformation {
    /// Places `objects` for snow to settle on (replacing any before, and their
    /// snow): lays out their atlas and builds the accumulation passes.
    pub fn set_objects(&mut self, ctx: &GpuContext, objects: &[SnowObject]) -> Result<(), crate::SnowError> {
        ctx.guarded(|| self.set_objects_unguarded(ctx, objects))
    }

    fn set_objects_unguarded(&mut self, ctx: &GpuContext, objects: &[SnowObject]) -> Result<(), crate::SnowError> {
        if objects.is_empty() {
            self.accumulation = None;
            self.core.update_pass.bind_sky(&ctx.device, &self.core.res, None);
            return Ok(());
        }
        let atlas = self.core.params.snowfall.as_ref().map_or(Snowfall::default().atlas_resolution, |s| s.atlas_resolution);
        let acc = SnowAccumulation::new(&ctx.device, objects, atlas, self.core.params.resolution, self.core.params.texel_m())?;
        self.core.update_pass.bind_sky(&ctx.device, &self.core.res, Some(acc.sky_view()));
        self.accumulation = Some(acc);
        ctx.check("creating the accumulation passes")
    }

    /// The snow on each object (in [`Self::set_objects`] order): read back
    /// from the GPU, so this blocks; for a save, a test or a debug panel, not
    /// every frame. Empty without objects.
    pub fn read_object_stats(&self, ctx: &GpuContext) -> Result<Vec<crate::accumulate::ObjectStats>, crate::SnowError> {
        ctx.guarded(|| self.read_object_stats_unguarded(ctx))
    }

    fn read_object_stats_unguarded(&self, ctx: &GpuContext) -> Result<Vec<crate::accumulate::ObjectStats>, crate::SnowError> {
        match &self.accumulation {
            Some(acc) => Ok(acc.stats(&acc.read_atlas(ctx)?)),
            None => Ok(Vec::new()),
        }
    }

    /// Moves and turns object `k` (in [`Self::set_objects`] order); its snow goes with it.
    pub fn set_object_pose(&mut self, k: usize, position: glam::Vec3, rotation: glam::Quat) {
        if let Some(acc) = &mut self.accumulation {
            acc.set_pose(k, position, rotation);
        }
    }
}
