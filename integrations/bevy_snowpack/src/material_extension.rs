//! Snow on a game's own meshes: [`SnowCoverMaterial`]
//! (`ExtendedMaterial<StandardMaterial, SnowCoverExtension>`) raises each
//! vertex of any mesh the game draws (terrain tiles, slopes, a road's edge)
//! by the snow's height above the terrain at its world (x, z), adds the
//! snow's slope to its normal, and covers the game's material with the
//! snow's look where there is snow. The snow reaches the shaders as a
//! texture the render world copies from the deformation each frame
//! ([`CoverTexture`]); the window's place is the `SnowWindow` uniform the
//! plugin already writes.

use bevy::asset::uuid_handle;
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::VisibilitySystems;
use bevy::ecs::system::SystemParamItem;
use bevy::ecs::system::lifetimeless::SRes;
use bevy::math::Vec3A;
use bevy::pbr::{ExtendedMaterial, MATERIAL_BIND_GROUP_INDEX, MaterialExtension, MaterialPlugin};
use bevy::prelude::*;
use bevy::render::render_resource::{
    AsBindGroup, AsBindGroupError, BindGroupBuilder, BindGroupLayout, BindGroupLayoutEntry, Buffer, TextureView, UnpreparedBindingResource,
};
use bevy::render::renderer::RenderDevice;
use bevy::shader::{Shader, ShaderRef};
use snowpack::{SnowDeformation, sampling_buffers};

use crate::{SnowSystems, SnowpackSettings};

/// A game's own standard material with the snow lying on its mesh.
pub type SnowCoverMaterial = ExtendedMaterial<StandardMaterial, SnowCoverExtension>;

/// Bindings of the extension in the material group (the standard material's own are below 100).
const WINDOW_BINDING: u32 = 100;
const WORDS_BINDING: u32 = 101;
const LOOK_BINDING: u32 = 102;

const VERTEX_SHADER: Handle<Shader> = uuid_handle!("7c1e2a44-9b3d-4f61-8a2e-5d0c6b9f3a11");
const PREPASS_SHADER: Handle<Shader> = uuid_handle!("7c1e2a44-9b3d-4f61-8a2e-5d0c6b9f3a12");
const FRAGMENT_SHADER: Handle<Shader> = uuid_handle!("7c1e2a44-9b3d-4f61-8a2e-5d0c6b9f3a13");

/// The extension that lays the snow on any mesh drawn with a
/// [`StandardMaterial`]: its vertices rise by the snow's displayed height
/// above the terrain at their world (x, z) (the rest depth outside the
/// window), in the main pass and the prepass (depth and shadows match), and
/// its fragments take the snow's look where the snow is deeper than
/// [`Self::cover_from_m`]. The mesh keeps its own shape and the standard
/// material is the ground under the snow, seen where the snow is gone.
///
/// The mesh should lie on the snow's terrain (the one the snow was
/// configured with, for example from the same heightmap through
/// [`crate::SnowTerrainAsset`]): the snow is lifted off the mesh by its
/// depth over that terrain. Meshes must not be skinned or morphed.
#[derive(Asset, Reflect, Clone, Debug, PartialEq)]
pub struct SnowCoverExtension {
    /// Albedo of untouched snow (linear RGB).
    pub fresh_albedo: Vec3,
    /// Roughness of untouched snow.
    pub fresh_roughness: f32,
    /// Albedo of snow pressed to the full compacted look (linear RGB).
    pub packed_albedo: Vec3,
    /// Roughness of fully compacted snow.
    pub packed_roughness: f32,
    /// Pressed fraction of the snow's depth at which the compacted look is complete.
    pub compaction_full: f32,
    /// How much of the game's material shows at the bottom of a print pressed to the ground (0..1).
    pub ground_show_through: f32,
    /// Snow depth (m) below which the game's material shows unchanged.
    pub cover_from_m: f32,
    /// Snow depth (m) from which the snow's look covers the material completely.
    pub cover_full_m: f32,
}

impl SnowCoverExtension {
    /// The snow's look from one of snowpack's materials; covering from 5 mm, complete at 3 cm.
    #[must_use]
    pub fn from_material(m: &snowpack::Material) -> Self {
        Self {
            fresh_albedo: m.fresh_albedo,
            fresh_roughness: m.fresh_roughness,
            packed_albedo: m.packed_albedo,
            packed_roughness: m.packed_roughness,
            compaction_full: m.compaction_full,
            ground_show_through: m.ground_show_through,
            cover_from_m: 0.005,
            cover_full_m: 0.03,
        }
    }

    /// The `SnowCoverLook` uniform of the shaders.
    fn look(&self) -> [f32; 12] {
        let (f, p) = (self.fresh_albedo, self.packed_albedo);
        [
            f.x,
            f.y,
            f.z,
            self.fresh_roughness,
            p.x,
            p.y,
            p.z,
            self.packed_roughness,
            self.compaction_full,
            self.ground_show_through,
            self.cover_from_m,
            self.cover_full_m,
        ]
    }
}

impl Default for SnowCoverExtension {
    /// snowpack's snow preset.
    fn default() -> Self {
        Self::from_material(&snowpack::Material::default())
    }
}

/// The deformation's snow words as a texture (R32Uint, the deformation's
/// toroidal order), copied from its buffer after each frame's passes, for
/// [`SnowCoverMaterial`]'s shaders. Made with each snow world.
pub(crate) struct CoverTexture {
    texture: wgpu::Texture,
    resolution: u32,
}

impl CoverTexture {
    /// A texture for `snow`'s window.
    pub(crate) fn new(device: &wgpu::Device, snow: &SnowDeformation) -> Self {
        let resolution = snow.params().resolution;
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("bevy_snowpack cover"),
            size: wgpu::Extent3d { width: resolution, height: resolution, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Uint,
            usage: wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        Self { texture, resolution }
    }

    /// The material's bindings: the window uniform and a view of this texture.
    pub(crate) fn bindings(&self, window: &wgpu::Buffer) -> SnowCoverBindings {
        let view = self.texture.create_view(&wgpu::TextureViewDescriptor::default());
        SnowCoverBindings { window: window.clone().into(), words: view.into() }
    }

    /// Records the copy of `snow`'s words into the texture (after the frame's passes).
    pub(crate) fn record(&self, encoder: &mut wgpu::CommandEncoder, snow: &SnowDeformation) {
        let [_, _, words] = sampling_buffers(snow);
        let r = self.resolution;
        // Rows in one copy where their bytes meet the copy alignment, else a copy a row.
        let rows = if (r * 4).is_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) { r } else { 1 };
        for row in (0..r).step_by(rows as usize) {
            encoder.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer: &words,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: u64::from(row) * u64::from(r) * 4,
                        bytes_per_row: (rows > 1).then_some(r * 4),
                        rows_per_image: None,
                    },
                },
                wgpu::TexelCopyTextureInfo {
                    texture: &self.texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d { x: 0, y: row, z: 0 },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::Extent3d { width: r, height: rows, depth_or_array_layers: 1 },
            );
        }
    }
}

/// What [`SnowCoverMaterial`] binds, in the render world: replaced with each snow world.
#[derive(Resource, Clone)]
pub struct SnowCoverBindings {
    window: Buffer,
    words: TextureView,
}

impl AsBindGroup for SnowCoverExtension {
    type Data = ();
    type Param = Option<SRes<SnowCoverBindings>>;

    fn label() -> &'static str {
        "snow_cover_extension"
    }

    fn bind_group_data(&self) -> Self::Data {}

    fn build_bind_group(
        &self,
        _layout: &BindGroupLayout,
        render_device: &RenderDevice,
        bindings: &mut SystemParamItem<'_, '_, Self::Param>,
        _force_no_bindless: bool,
        output: &mut BindGroupBuilder,
    ) -> Result<(), AsBindGroupError> {
        // Until the deformation exists (the render world's startup), try again next frame.
        let Some(bindings) = bindings.as_ref() else { return Err(AsBindGroupError::RetryNextUpdate) };
        output.push((WINDOW_BINDING, UnpreparedBindingResource::Buffer(bindings.window.clone())));
        output.push((WORDS_BINDING, UnpreparedBindingResource::TextureView(wgpu::TextureViewDimension::D2, bindings.words.clone())));
        let look = render_device.create_buffer_with_data(&wgpu::util::BufferInitDescriptor {
            label: Some("snow_cover_look"),
            contents: bytemuck::cast_slice(&self.look()),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        output.push((LOOK_BINDING, UnpreparedBindingResource::Buffer(look)));
        Ok(())
    }

    fn bind_group_layout_entries(_render_device: &RenderDevice, _force_no_bindless: bool) -> Vec<BindGroupLayoutEntry>
    where
        Self: Sized,
    {
        let uniform = |binding: u32, size: u64| BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: wgpu::BufferSize::new(size) },
            count: None,
        };
        let words = BindGroupLayoutEntry {
            binding: WORDS_BINDING,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Texture { sample_type: wgpu::TextureSampleType::Uint, view_dimension: wgpu::TextureViewDimension::D2, multisampled: false },
            count: None,
        };
        let window_size = std::mem::size_of::<snowpack::SnowWindowUniform>() as u64;
        vec![uniform(WINDOW_BINDING, window_size), words, uniform(LOOK_BINDING, 48)]
    }
}

impl MaterialExtension for SnowCoverExtension {
    fn vertex_shader() -> ShaderRef {
        ShaderRef::Handle(VERTEX_SHADER)
    }

    fn prepass_vertex_shader() -> ShaderRef {
        ShaderRef::Handle(PREPASS_SHADER)
    }

    fn deferred_vertex_shader() -> ShaderRef {
        ShaderRef::Handle(PREPASS_SHADER)
    }

    fn fragment_shader() -> ShaderRef {
        ShaderRef::Handle(FRAGMENT_SHADER)
    }

    fn deferred_fragment_shader() -> ShaderRef {
        ShaderRef::Handle(FRAGMENT_SHADER)
    }
}

/// A shader's source with the cover sampling module in place of its marker line.
fn shader_source(shader: &str) -> String {
    let group = u32::try_from(MATERIAL_BIND_GROUP_INDEX).unwrap_or(u32::MAX);
    let sampling = include_str!("shaders/cover_sampling.wgsl").replace("MATERIAL_GROUP", &group.to_string());
    shader.replace("// @snow_cover_sampling\n", &sampling)
}

pub(crate) fn build(app: &mut App) {
    let mut shaders = app.world_mut().resource_mut::<Assets<Shader>>();
    let sources = [
        (VERTEX_SHADER, include_str!("shaders/cover_vertex.wesl"), "embedded://bevy_snowpack/cover_vertex.wesl"),
        (PREPASS_SHADER, include_str!("shaders/cover_prepass.wesl"), "embedded://bevy_snowpack/cover_prepass.wesl"),
        (FRAGMENT_SHADER, include_str!("shaders/cover_fragment.wesl"), "embedded://bevy_snowpack/cover_fragment.wesl"),
    ];
    for (handle, source, path) in sources {
        // The handles are constant ids; inserting cannot fail for them.
        let _ = shaders.insert(handle.id(), Shader::from_wesl(shader_source(source), path));
    }
    app.add_plugins(MaterialPlugin::<SnowCoverMaterial>::default())
        .add_systems(PostUpdate, grow_cover_bounds.in_set(SnowSystems::Bounds).after(VisibilitySystems::CalculateBounds));
}

/// The lift a [`SnowCoverMaterial`] gives a point: the CPU twin of the
/// shaders' `snow_cover_lift`, over the snow's displayed heights above the
/// terrain (`above_m`, window-local row-major, row i at +z, `resolution`
/// squared values, as the library's `read_surface` minus the terrain
/// gives them) of a window whose local texel (0, 0) has its outer corner at
/// `corner` (world x, z) with texels of `texel_m`: bilinear between texel
/// centres, clamped to the outermost centres, `rest_depth_m` outside the window.
#[must_use]
pub fn snow_cover_lift(above_m: &[f32], resolution: u32, corner: Vec2, texel_m: f32, rest_depth_m: f32, world_xz: Vec2) -> f32 {
    let extent = resolution as f32 * texel_m;
    let q = world_xz - corner;
    if resolution == 0 || above_m.len() < (resolution * resolution) as usize || q.min_element() < 0.0 || q.max_element() > extent {
        return rest_depth_m;
    }
    let last = (resolution - 1) as f32;
    let t = (q / texel_m - 0.5).clamp(Vec2::ZERO, Vec2::splat(last));
    let c = t.floor();
    let f = t - c;
    let r = resolution as usize;
    let at = |i: usize, j: usize| above_m[i.min(r - 1) * r + j.min(r - 1)];
    let (j, i) = (c.x as usize, c.y as usize);
    let lower = at(i, j) + (at(i, j + 1) - at(i, j)) * f.x;
    let upper = at(i + 1, j) + (at(i + 1, j + 1) - at(i + 1, j)) * f.x;
    lower + (upper - lower) * f.y
}

/// The covered meshes' bounds reach up by the lift the snow can give them:
/// grown when Bevy computes them (a new or changed mesh), so they never grow twice.
#[allow(clippy::type_complexity, reason = "a query's filter")]
fn grow_cover_bounds(settings: Res<SnowpackSettings>, mut covered: Query<&mut Aabb, (With<MeshMaterial3d<SnowCoverMaterial>>, Changed<Aabb>)>) {
    let fall = settings.params.snowfall.as_ref().map_or(0.0, |_| 2.0);
    let lift = 2.0 * settings.params.depth_m + fall;
    for mut aabb in &mut covered {
        // Up by half the lift at the centre and the top: the bottom stays (an unscaled mesh is assumed).
        let half = Vec3A::new(aabb.half_extents.x, aabb.half_extents.y + 0.5 * lift, aabb.half_extents.z);
        aabb.center = Vec3A::new(aabb.center.x, aabb.center.y + 0.5 * lift, aabb.center.z);
        aabb.half_extents = half;
    }
}
