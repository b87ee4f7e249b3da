//! [`SnowInspect`]: what snowpack's own app, tools and tests read and drive
//! of a [`SnowDeformation`] beyond the front door: its resources and state,
//! blocking read-backs of its textures and buffers, counters, and a frame of
//! bare deformers. A named item of `low_level` (an extension trait), so the
//! front-door type has one shape with or without the feature, and a game
//! that reaches in says so by importing it.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, reason = "the renderer reads a few of these; the rest are for the app, the tools and the tests (`low_level`)")
)]

use glam::DVec2;
use snowpack_share::mechanics::SnowColumn;

use crate::accumulate::SnowAccumulation;
use crate::deform::capture::ShapeCapture;
use crate::deform::decal::DecalRing;
use crate::deform::display::DisplayKernel;
use crate::deform::packed_snow;
use crate::deform::query::QueryStats;
use crate::deform::resources::DeformResources;
use crate::deform::snow_word;
use crate::error::SnowError;
use crate::gpu::{GpuContext, PassTimings, read_buffer};
use crate::persist::SnowClock;
use crate::skin::skinning::SkinnedInstance;
use crate::tiles::{TileStats, TileStreaming};
use crate::{Deformer, Technique, TerrainSource};

use super::deformation::SnowDeformation;
use super::skinned::SkinnedId;
use super::snow_frame::SnowFrame;
use crate::terrain::HeightmapTerrainExt;

/// The mass of a window's snow ([`SnowInspect::read_mass`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WindowMass {
    /// Snow in the window now (kg): `ρ0 (h + q)` over its texels.
    pub total_kg: f64,
    /// Snow that presses squeezed beyond the final density since the window
    /// was created (kg): displaced, and not yet put down elsewhere.
    pub displaced_kg: f64,
    /// The mass ledger (`shared/mass_ledger.wgsl`, `docs/mechanics.md`):
    /// snow that entered the window with its moves since it was created,
    /// its first fill included (kg).
    pub entered_kg: f64,
    /// Snow that left the window with its moves (kg).
    pub left_kg: f64,
    /// Snow that snowfall added (kg), counted with
    /// [`SnowInspect::set_count_mass`] (else 0).
    pub snowfall_kg: f64,
    /// Snow that the refill added to trails (kg), counted with
    /// [`SnowInspect::set_count_mass`] (else 0).
    pub refill_kg: f64,
}

impl WindowMass {
    /// What the ledger says the window should hold: what entered, less
    /// what left, plus snowfall and refill, less what was displaced beyond
    /// the final density without [`crate::SnowParams::displace`] (with it,
    /// displaced snow is moved, not lost, and this count only holds what
    /// passed 16 bits of packed snow). Equal to [`WindowMass::total_kg`]
    /// up to a quantum of rounding a texel moved or snowed on, but for
    /// merges (another machine's tiles, a stored tile merged under a
    /// stand-in), and, where it snows or refills, only with
    /// [`SnowInspect::set_count_mass`].
    #[must_use]
    pub fn ledger_kg(&self) -> f64 {
        self.entered_kg - self.left_kg + self.snowfall_kg + self.refill_kg - self.displaced_kg
    }
}

/// What the app, the tools and the tests read and drive of a
/// [`SnowDeformation`] beyond the front door (see the module documentation).
pub trait SnowInspect {
    /// The terrain under the snow.
    #[must_use]
    fn terrain(&self) -> &TerrainSource;

    /// Snowfall so far on open ground (m).
    #[must_use]
    fn fallen_m(&self) -> f32;

    /// Time, refill and snowfall so far.
    #[must_use]
    fn clock(&self) -> SnowClock;

    /// The floating origin (world m).
    #[must_use]
    fn floating_origin(&self) -> DVec2;

    /// The technique in use.
    #[must_use]
    fn technique(&self) -> Technique;

    /// Contact points stamped in the last frame.
    #[must_use]
    fn points_last_frame(&self) -> usize;

    /// Contact points left out so far because a frame brought more than the
    /// stamp pass takes ([`crate::deform::stamp::MAX_POINTS`], about a
    /// million); each time the total doubles a warning says so.
    #[must_use]
    fn points_dropped(&self) -> u64;

    /// Quantisation of the stored footprints: (lowest, highest height, quantum), m.
    #[must_use]
    fn stamp_range(&self) -> (f32, f32, f32);

    /// World (x, z) of the window's corner (local texel (0, 0)'s outer corner), once placed.
    #[must_use]
    fn origin_m(&self) -> Option<DVec2>;

    /// Global texel index `[column, row]` of local (0, 0), once placed.
    #[must_use]
    fn origin_texel(&self) -> Option<[i64; 2]>;

    /// Texels rewritten by window moves so far (the whole window once, then only new strips).
    #[must_use]
    fn exposed_texels(&self) -> u64;

    /// Reads skinned mesh `id`'s coat back (m a vertex); blocks until the GPU is done.
    fn read_coat(&self, ctx: &GpuContext, id: SkinnedId) -> Result<Vec<f32>, SnowError>;

    /// The skinned meshes posed in the last encoded frame, in world space
    /// (what a renderer draws for the characters).
    fn posed_meshes(&self) -> impl Iterator<Item = &SkinnedInstance> + '_;

    /// [`SnowDeformation::step_frame`] with only `deformers` pressing the snow (headless tools and tests).
    fn step(&mut self, ctx: &GpuContext, deformers: &[Deformer], dt_s: f32) -> Result<(), crate::SnowError>;

    /// For tests: while `held`, frames take none of the readbacks that
    /// arrive (point answers, timings, tiles leaving the window, shared
    /// snow), as if the GPU never finished them, so their staging buffers
    /// stay busy; [`SnowDeformation::finish`] still waits for and takes them.
    fn hold_readbacks(&mut self, held: bool);

    /// Requests gathered, answered and skipped so far.
    #[must_use]
    fn query_stats(&self) -> QueryStats;

    /// Median GPU time per pass so far (empty without timestamp support).
    #[must_use]
    fn timings(&self) -> PassTimings;

    /// Forgets timing samples (call after warm-up).
    fn clear_timings(&mut self);

    /// How the capture takes the analytic shapes: chosen for the adapter
    /// ([`ShapeCapture::for_adapter`]) unless set.
    #[must_use]
    fn shape_capture(&self) -> ShapeCapture;

    /// Takes the analytic shapes `by` compute or drawn from the next frame
    /// on (the benchmark compares both on one adapter).
    fn set_shape_capture(&mut self, by: ShapeCapture);

    /// How the display pass maps its work ([`DisplayKernel`]; both give
    /// the same snow, bit for bit).
    #[must_use]
    fn display_kernel(&self) -> DisplayKernel;

    /// Displays with `kernel` from the next frame on (the benchmark
    /// compares the kernels on one adapter).
    fn set_display_kernel(&mut self, kernel: DisplayKernel);

    /// The most GPU memory [`Self::memory_bytes`] summed to after any frame
    /// so far (bytes): with tiles on their way to the CPU, the copy-out
    /// staging they hold for a frame or two.
    #[must_use]
    fn peak_memory_bytes(&self) -> u64;

    /// GPU memory held, by resource (bytes), including the point queries' buffers.
    #[must_use]
    fn memory_bytes(&self) -> Vec<(&'static str, u64)>;

    /// The GPU resources, for renderers (`surface`) and tools.
    #[must_use]
    fn resources(&self) -> &DeformResources;

    /// The decal ring (each actor's last contacts).
    #[must_use]
    fn decals(&self) -> &DecalRing;

    /// The decal layer (window-local RGBA8: normal x, z, tint, coverage), drawn
    /// with the decals technique; transparent otherwise. Until the decals
    /// technique's first frame it is a transparent 1x1 placeholder; that
    /// frame replaces it with the full layer, so a renderer that bound it
    /// rebinds when the texture returned here changes (wgpu textures compare
    /// by identity).
    #[must_use]
    fn decal_layer(&self) -> &wgpu::Texture;

    /// The decal layer read back, window-local row-major; blocking. All
    /// transparent before the decals technique's first frame.
    fn read_decals(&self, ctx: &GpuContext) -> Result<Vec<[u8; 4]>, SnowError>;

    /// The snow words (`crate::deform::snow_word`), window-local row-major (row i
    /// = +z); blocking. [`Self::read_snow`] and [`Self::read_surface`]
    /// decode them.
    fn read_snow_words(&self, ctx: &GpuContext) -> Result<Vec<u32>, SnowError>;

    /// [`Self::read_snow_words`] without blocking: the words as the GPU has
    /// them once the frames submitted so far are done (the browser build's
    /// path; see `crate::gpu::readback::MappedRead`).
    fn read_snow_words_async(&self, ctx: &GpuContext) -> impl std::future::Future<Output = Result<Vec<u32>, SnowError>> + 'static;

    /// Persistent snow height (m), window-local row-major (row i = +z); blocking.
    fn read_snow(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError>;

    /// Packed snow per texel (m of fresh snow that presses squeezed into the
    /// column, `crate::deform::packed_snow`), window-local row-major; blocking.
    fn read_packed(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError>;

    /// The window's snow mass (`docs/mechanics.md`): what it holds now and
    /// what presses have displaced beyond the final density since it was
    /// created; blocking.
    fn read_mass(&self, ctx: &GpuContext) -> Result<WindowMass, SnowError>;

    /// Whether the mass ledger also counts what snowfall and refill add,
    /// each frame (`docs/mechanics.md`, "The ledger"): a sum over each
    /// workgroup of the update pass, which costs it (about half again on a
    /// software rasteriser) in frames that snow or refill. What enters and
    /// leaves with the window's moves is counted either way. Off at first;
    /// the headless runner turns it on for `meta.json`.
    fn set_count_mass(&mut self, on: bool);

    /// Terrain height (m) at the texel centres, window-local row-major; for
    /// mesh terrain blocking. Evaluated on the CPU with the GPU's formula
    /// (`texel_ground`), so they agree to rounding: from the terrain's
    /// description, and for a mesh terrain from the grid the GPU baked (read
    /// back), which is what the passes sample. No GPU buffer holds the
    /// terrain per texel.
    fn read_terrain(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError>;

    /// Displayed height (m) and unit normal per texel, window-local; blocking.
    /// The normals are central differences of the displayed heights, as the
    /// renderer and the point queries compute them.
    fn read_surface(&self, ctx: &GpuContext) -> Result<(Vec<f32>, Vec<[f32; 3]>), SnowError>;

    /// The objects' accumulation, when there are objects.
    #[must_use]
    fn accumulation(&self) -> Option<&SnowAccumulation>;

    /// Whether `SharedWindow::enable_sharing` was called on this window.
    #[must_use]
    fn is_sharing(&self) -> bool;

    /// Tile traffic and store figures, when tiles are kept (in memory or in
    /// an attached store).
    #[must_use]
    fn tile_stats(&self) -> Option<TileStats>;
}

impl SnowInspect for SnowDeformation {
    fn terrain(&self) -> &TerrainSource {
        self.core.terrain()
    }

    fn fallen_m(&self) -> f32 {
        self.time.fallen_m
    }

    fn clock(&self) -> SnowClock {
        self.time.clock
    }

    fn floating_origin(&self) -> DVec2 {
        self.core.floating_origin()
    }

    fn technique(&self) -> Technique {
        self.core.params().technique
    }

    fn points_last_frame(&self) -> usize {
        self.core.points_last_frame()
    }

    fn points_dropped(&self) -> u64 {
        self.core.points_dropped()
    }

    fn stamp_range(&self) -> (f32, f32, f32) {
        self.core.stamp_range()
    }

    fn origin_m(&self) -> Option<DVec2> {
        let texel = f64::from(self.core.params().texel_m());
        self.core.window_origin().map(|o| DVec2::new(o[0] as f64 * texel, o[1] as f64 * texel))
    }

    fn origin_texel(&self) -> Option<[i64; 2]> {
        self.core.window_origin()
    }

    fn exposed_texels(&self) -> u64 {
        self.core.exposed_texels()
    }

    fn read_coat(&self, ctx: &GpuContext, id: SkinnedId) -> Result<Vec<f32>, SnowError> {
        let buffer = self.coat_buffer(id).ok_or(SnowError::InvalidParameter { field: "skinned mesh", why: format!("no skinned mesh {}", id.0) })?;
        Ok(bytemuck::pod_collect_to_vec(&crate::gpu::read_buffer(ctx, buffer)?))
    }

    fn posed_meshes(&self) -> impl Iterator<Item = &SkinnedInstance> + '_ {
        self.characters.posed_meshes()
    }

    fn step(&mut self, ctx: &GpuContext, deformers: &[Deformer], dt_s: f32) -> Result<(), crate::SnowError> {
        self.step_frame(ctx, &SnowFrame::new(dt_s, deformers)).map(|_| ())
    }

    fn hold_readbacks(&mut self, held: bool) {
        self.readbacks_held = held;
    }

    fn query_stats(&self) -> QueryStats {
        self.core.query_stats()
    }

    fn timings(&self) -> PassTimings {
        self.timer.medians()
    }

    fn clear_timings(&mut self) {
        self.timer.clear();
    }

    fn shape_capture(&self) -> ShapeCapture {
        self.core.shape_capture()
    }

    fn set_shape_capture(&mut self, by: ShapeCapture) {
        self.core.set_shape_capture(by);
    }

    fn display_kernel(&self) -> DisplayKernel {
        self.core.display_kernel()
    }

    fn set_display_kernel(&mut self, kernel: DisplayKernel) {
        self.core.set_display_kernel(kernel);
    }

    fn peak_memory_bytes(&self) -> u64 {
        self.peak_memory_bytes.max(self.memory_total())
    }

    fn memory_bytes(&self) -> Vec<(&'static str, u64)> {
        let mut list = self.core.memory_bytes();
        if let Some(acc) = &self.accumulation {
            list.extend(acc.memory_bytes());
        }
        if let Some(tiles) = &self.tiles {
            list.push(("resident tiles", tiles.stats().gpu_bytes));
        }
        if let Some(sharing) = &self.sharing {
            list.push(("shared snow", sharing.memory_bytes()));
        }
        list
    }

    fn resources(&self) -> &DeformResources {
        self.core.res()
    }

    fn decals(&self) -> &DecalRing {
        self.core.decals()
    }

    fn decal_layer(&self) -> &wgpu::Texture {
        self.core.decal_layer()
    }

    fn read_decals(&self, ctx: &GpuContext) -> Result<Vec<[u8; 4]>, SnowError> {
        let r = self.core.params().resolution;
        if self.core.decal_layer().width() != r {
            return Ok(vec![[0; 4]; (r * r) as usize]);
        }
        let row = (r * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("decal layer copy"),
            size: u64::from(row) * u64::from(r),
            usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("decal layer copy") });
        encoder.copy_texture_to_buffer(
            self.core.decal_layer().as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: Some(r) },
            },
            wgpu::Extent3d { width: r, height: r, depth_or_array_layers: 1 },
        );
        ctx.queue.submit([encoder.finish()]);
        let raw = read_buffer(ctx, &staging)?;
        Ok(raw.chunks_exact(row as usize).flat_map(|line| line[..(r * 4) as usize].chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]])).collect())
    }

    fn read_snow_words(&self, ctx: &GpuContext) -> Result<Vec<u32>, SnowError> {
        let raw = read_buffer(ctx, &self.core.res().snow)?;
        Ok(self.core.layout().untorus(&bytemuck::pod_collect_to_vec::<u8, u32>(&raw)))
    }

    fn read_snow_words_async(&self, ctx: &GpuContext) -> impl std::future::Future<Output = Result<Vec<u32>, SnowError>> + 'static {
        let mapped = crate::gpu::readback::read_buffer_async(ctx, &self.core.res().snow);
        let layout = self.core.layout();
        async move { Ok(layout.untorus(&bytemuck::pod_collect_to_vec::<u8, u32>(&mapped.await?))) }
    }

    fn read_snow(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        let words = self.read_snow_words(ctx)?;
        let terrain = self.read_terrain(ctx)?;
        let fallen: Vec<f32> = if self.core.params().keeps_lying_snow() {
            self.core.layout().untorus(&bytemuck::pod_collect_to_vec::<u8, f32>(&read_buffer(ctx, &self.core.res().fallen)?))
        } else {
            vec![0.0; words.len()]
        };
        Ok(words.iter().zip(&terrain).zip(&fallen).map(|((&w, &g), &l)| snow_word::column_height(w, g, self.core.params().depth_m + l)).collect())
    }

    fn read_packed(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &self.core.res().packed)?);
        Ok(self.core.layout().packed_m(&words))
    }

    fn set_count_mass(&mut self, on: bool) {
        self.core.set_count_mass(on);
    }

    fn read_mass(&self, ctx: &GpuContext) -> Result<WindowMass, SnowError> {
        // One readback of the packed buffer: the texels' packed snow and, in its last words, the displaced count.
        let counted: Vec<u32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &self.core.res().packed)?);
        let (height, terrain, packed) = (self.read_snow(ctx)?, self.read_terrain(ctx)?, self.core.layout().packed_m(&counted));
        let mechanics = self.core.params().mechanics();
        let area = f64::from(self.core.params().texel_m()).powi(2);
        let total: f64 =
            height.iter().zip(&terrain).zip(&packed).map(|((&h, &g), &q)| f64::from(mechanics.mass_kg_m2(SnowColumn { depth_m: h - g, packed_m: q }))).sum();
        let ledger = packed_snow::ledger(&counted);
        // Quanta (and the snowfall's fine steps) of fresh snow to kilograms.
        let kg = |count: u64, per_m: f64| count as f64 / per_m * f64::from(mechanics.fresh_density_kg_m3) * area;
        let quanta = f64::from(snow_word::SNOW_QUANTA_PER_M);
        Ok(WindowMass {
            total_kg: total * area,
            displaced_kg: kg(ledger.displaced_q, quanta),
            entered_kg: kg(ledger.entered_q, quanta),
            left_kg: kg(ledger.left_q, quanta),
            snowfall_kg: kg(ledger.snowfall_fine, f64::from(packed_snow::LEDGER_FINE_PER_M)),
            refill_kg: kg(ledger.refill_q, quanta),
        })
    }

    fn read_terrain(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        let baked;
        let source = match self.core.terrain() {
            TerrainSource::Mesh(mesh) => {
                let n = (mesh.grid.width() * mesh.grid.height()) as usize;
                let heights: Vec<f32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &self.core.res().heightmap)?);
                baked = TerrainSource::Heightmap(mesh.grid.with_heights(heights[..n].to_vec())?);
                &baked
            }
            other => other,
        };
        let r = self.core.params().resolution;
        let origin = self.core.layout().origin;
        let o = [origin[0] as i32, origin[1] as i32];
        let texel = self.core.params().texel_m();
        Ok((0..r)
            .flat_map(|i| (0..r).map(move |j| (i, j)))
            .map(|(i, j)| crate::terrain::texel_ground(source, [o[0] + j as i32, o[1] + i as i32], texel))
            .collect())
    }

    fn read_surface(&self, ctx: &GpuContext) -> Result<(Vec<f32>, Vec<[f32; 3]>), SnowError> {
        let words = self.read_snow_words(ctx)?;
        let terrain = self.read_terrain(ctx)?;
        let heights: Vec<f32> = words.iter().zip(&terrain).map(|(&w, &g)| snow_word::shown(w, g)).collect();
        let normals = crate::deform::display::normals_of(&heights, self.core.params().resolution, self.core.params().texel_m());
        Ok((heights, normals))
    }

    fn accumulation(&self) -> Option<&SnowAccumulation> {
        self.accumulation.as_ref()
    }

    fn is_sharing(&self) -> bool {
        self.sharing.is_some()
    }

    fn tile_stats(&self) -> Option<TileStats> {
        self.tiles.as_ref().map(TileStreaming::stats)
    }
}
