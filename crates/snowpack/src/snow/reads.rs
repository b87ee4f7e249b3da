//! Whole-window readbacks and the window's GPU resources, for the renderer,
//! the app, tools and tests (`low_level`): blocking, never in a frame loop.

use crate::TerrainSource;
#[cfg(feature = "low_level")]
use crate::deform::decal::DecalRing;
use crate::deform::resources::DeformResources;
#[cfg(feature = "low_level")]
use crate::deform::snow_word;
use crate::error::SnowError;
use crate::gpu::{GpuContext, read_buffer};

use super::SnowDeformation;

impl SnowDeformation {
    low_level_pub! {
        /// The GPU resources, for renderers (`surface`) and tools.
        #[must_use]
        fn resources(&self) -> &DeformResources {
            &self.core.res
        }
    }

    #[cfg(feature = "low_level")]
    /// The decal ring (each actor's last contacts).
    #[must_use]
    pub fn decals(&self) -> &DecalRing {
        &self.core.decals
    }

    low_level_pub! {
        /// The decal layer (window-local RGBA8: normal x, z, tint, coverage), drawn
        /// with the decals technique; transparent otherwise. Until the decals
        /// technique's first frame it is a transparent 1x1 placeholder; that
        /// frame replaces it with the full layer, so a renderer that bound it
        /// rebinds when the texture returned here changes (wgpu textures compare
        /// by identity).
        #[must_use]
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
        fn decal_layer(&self) -> &wgpu::Texture {
            &self.core.decal_pass.layer
        }
    }

    #[cfg(feature = "low_level")]
    /// The decal layer read back, window-local row-major; blocking. All
    /// transparent before the decals technique's first frame.
    pub fn read_decals(&self, ctx: &GpuContext) -> Result<Vec<[u8; 4]>, SnowError> {
        let r = self.core.params.resolution;
        if self.core.decal_pass.layer.width() != r {
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
            self.core.decal_pass.layer.as_image_copy(),
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

    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    fn untorus<T: Copy + Default>(&self, toroidal: &[T]) -> Vec<T> {
        untorus(self.core.params.resolution, self.core.window.origin().unwrap_or([0, 0]), toroidal)
    }

    low_level_pub! {
        /// The snow words ([`crate::deform::snow_word`]), window-local row-major (row i
        /// = +z); blocking. [`Self::read_snow`] and [`Self::read_surface`]
        /// decode them.
        #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
        fn read_snow_words(&self, ctx: &GpuContext) -> Result<Vec<u32>, SnowError> {
            let raw = read_buffer(ctx, &self.core.res.snow)?;
            Ok(self.untorus(&bytemuck::pod_collect_to_vec::<u8, u32>(&raw)))
        }
    }

    #[cfg(feature = "low_level")]
    /// [`Self::read_snow_words`] without blocking: the words as the GPU has
    /// them once the frames submitted so far are done (the browser build's
    /// path; see [`crate::gpu::readback::MappedRead`]).
    pub fn read_snow_words_async(&self, ctx: &GpuContext) -> impl std::future::Future<Output = Result<Vec<u32>, SnowError>> + 'static {
        let mapped = crate::gpu::readback::read_buffer_async(ctx, &self.core.res.snow);
        let (resolution, origin) = (self.core.params.resolution, self.core.window.origin().unwrap_or([0, 0]));
        async move { Ok(untorus(resolution, origin, &bytemuck::pod_collect_to_vec::<u8, u32>(&mapped.await?))) }
    }

    #[cfg(feature = "low_level")]
    /// Persistent snow height (m), window-local row-major (row i = +z); blocking.
    pub fn read_snow(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        let words = self.read_snow_words(ctx)?;
        let terrain = self.read_terrain(ctx)?;
        let fallen: Vec<f32> = if self.core.params.snowfall.is_some() {
            self.untorus(&bytemuck::pod_collect_to_vec::<u8, f32>(&read_buffer(ctx, &self.core.res.fallen)?))
        } else {
            vec![0.0; words.len()]
        };
        Ok(words.iter().zip(&terrain).zip(&fallen).map(|((&w, &g), &l)| snow_word::height(w, g + self.core.params.depth_m + l, g)).collect())
    }

    low_level_pub! {
    /// Terrain height (m) at the texel centres, window-local row-major; for
    /// mesh terrain blocking. Evaluated on the CPU with the GPU's formula
    /// (`texel_ground`), so they agree to rounding: from the terrain's
    /// description, and for a mesh terrain from the grid the GPU baked (read
    /// back), which is what the passes sample. No GPU buffer holds the
    /// terrain per texel.
    #[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the renderer, the app and the tests (`low_level`)"))]
    fn read_terrain(&self, ctx: &GpuContext) -> Result<Vec<f32>, SnowError> {
        let baked;
        let source = match &self.core.terrain {
            TerrainSource::Mesh(mesh) => {
                let n = (mesh.grid.width() * mesh.grid.height()) as usize;
                let heights: Vec<f32> = bytemuck::pod_collect_to_vec(&read_buffer(ctx, &self.core.res.heightmap)?);
                baked = TerrainSource::Heightmap(mesh.grid.with_heights(heights[..n].to_vec())?);
                &baked
            }
            other => other,
        };
        let r = self.core.params.resolution;
        let origin = self.core.window.origin().unwrap_or([0, 0]);
        let o = [origin[0] as i32, origin[1] as i32];
        let texel = self.core.params.texel_m();
        Ok((0..r)
            .flat_map(|i| (0..r).map(move |j| (i, j)))
            .map(|(i, j)| crate::terrain::texel_ground(source, [o[0] + j as i32, o[1] + i as i32], texel))
            .collect())
    }
    }

    #[cfg(feature = "low_level")]
    /// Displayed height (m) and unit normal per texel, window-local; blocking.
    /// The normals are central differences of the displayed heights, as the
    /// renderer and the point queries compute them.
    pub fn read_surface(&self, ctx: &GpuContext) -> Result<(Vec<f32>, Vec<[f32; 3]>), SnowError> {
        let words = self.read_snow_words(ctx)?;
        let terrain = self.read_terrain(ctx)?;
        let heights: Vec<f32> = words.iter().zip(&terrain).map(|(&w, &g)| snow_word::shown(w, g)).collect();
        let normals = crate::deform::display::normals_of(&heights, self.core.params.resolution, self.core.params.texel_m());
        Ok((heights, normals))
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
