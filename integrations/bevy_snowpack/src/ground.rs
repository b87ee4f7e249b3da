//! The snow ground: `ExtendedMaterial<StandardMaterial, SnowGroundExtension>`
//! whose main and prepass vertex shaders displace the mesh to the snow
//! surface with snowpack's exported sampling WGSL, whose fragment shader
//! gives trails the compacted look of snowpack's material, and bounds grown
//! to the snow's height range so the displaced ground is not culled.

use bevy::asset::uuid_handle;
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::VisibilitySystems;
use bevy::ecs::system::SystemParamItem;
use bevy::ecs::system::lifetimeless::SRes;
use bevy::math::Vec3A;
use bevy::pbr::{ExtendedMaterial, MATERIAL_BIND_GROUP_INDEX, MaterialExtension, MaterialPlugin};
use bevy::prelude::*;
use bevy::render::render_resource::{
    AsBindGroup, AsBindGroupError, BindGroupBuilder, BindGroupLayout, BindGroupLayoutEntry, Buffer, UnpreparedBindingResource,
};
use bevy::render::renderer::RenderDevice;
use bevy::shader::{Shader, ShaderRef};
use snowpack::{SnowDeformation, sampling_buffers, sampling_layout_entries, snow_sampling_wgsl_at};

use crate::{SnowSystems, SnowpackSettings};

/// The ground material: Bevy's standard material on a mesh displaced by the snow.
pub type SnowGroundMaterial = ExtendedMaterial<StandardMaterial, SnowGroundExtension>;

/// Binding number of the sampling module's binding 0 in the material's group
/// (the standard material's own bindings are below 100).
pub const FIRST_BINDING: u32 = 100;

/// Binding of the fragment shader's `SnowLook` uniform, after the sampling module's four.
const LOOK_BINDING: u32 = FIRST_BINDING + 4;

const VERTEX_SHADER: Handle<Shader> = uuid_handle!("5b0f3d8e-4f0c-4a55-9d5e-1c2a9d7e6b01");
const PREPASS_SHADER: Handle<Shader> = uuid_handle!("5b0f3d8e-4f0c-4a55-9d5e-1c2a9d7e6b02");
const FRAGMENT_SHADER: Handle<Shader> = uuid_handle!("5b0f3d8e-4f0c-4a55-9d5e-1c2a9d7e6b03");

/// The extension that displaces a [`StandardMaterial`]'s mesh to the snow
/// surface (main pass and prepass: depth, normals and shadows match) and
/// shades trails as snowpack's material does. The mesh supplies x and z only
/// (a flat grid covering the window, with normals; `Plane3d` subdivided
/// does); its heights and normals come from the snow. The standard
/// material's base colour and roughness are the fresh snow's.
#[derive(Asset, Reflect, Clone, Debug, PartialEq)]
pub struct SnowGroundExtension {
    /// Albedo of snow pressed to the full compacted look (linear RGB).
    pub packed_albedo: Vec3,
    /// Roughness of fully compacted snow.
    pub packed_roughness: f32,
    /// Albedo of the ground where the snow is gone or shows through.
    pub ground_albedo: Vec3,
    /// Roughness of the ground.
    pub ground_roughness: f32,
    /// Pressed fraction of the snow's depth at which the compacted look is complete.
    pub compaction_full: f32,
    /// How much ground shows at the bottom of a print pressed to it (0..1).
    pub ground_show_through: f32,
}

impl SnowGroundExtension {
    /// The compacted look, ground and show-through of one of snowpack's materials.
    #[must_use]
    pub fn from_material(m: &snowpack::Material) -> Self {
        Self {
            packed_albedo: m.packed_albedo,
            packed_roughness: m.packed_roughness,
            ground_albedo: m.ground_albedo,
            ground_roughness: m.ground_roughness,
            compaction_full: m.compaction_full,
            ground_show_through: m.ground_show_through,
        }
    }

    /// The `SnowLook` uniform of the fragment shader.
    fn look(&self) -> [f32; 12] {
        let (p, g) = (self.packed_albedo, self.ground_albedo);
        [p.x, p.y, p.z, self.packed_roughness, g.x, g.y, g.z, self.ground_roughness, self.compaction_full, self.ground_show_through, 0.0, 0.0]
    }
}

impl Default for SnowGroundExtension {
    /// snowpack's snow preset.
    fn default() -> Self {
        Self::from_material(&snowpack::Material::default())
    }
}

/// The deformation's buffers the material binds, in the render world.
#[derive(Resource, Clone)]
pub struct SnowGpuBuffers([Buffer; 4]);

impl SnowGpuBuffers {
    pub(crate) fn new(snow: &SnowDeformation, window: &wgpu::Buffer) -> Self {
        let [terrain_params, heightmap, snow] = sampling_buffers(snow);
        Self([window.clone().into(), terrain_params.into(), heightmap.into(), snow.into()])
    }
}

impl AsBindGroup for SnowGroundExtension {
    type Data = ();
    type Param = Option<SRes<SnowGpuBuffers>>;

    fn label() -> &'static str {
        "snow_ground_extension"
    }

    fn bind_group_data(&self) -> Self::Data {}

    fn build_bind_group(
        &self,
        _layout: &BindGroupLayout,
        render_device: &RenderDevice,
        buffers: &mut SystemParamItem<'_, '_, Self::Param>,
        _force_no_bindless: bool,
        output: &mut BindGroupBuilder,
    ) -> Result<(), AsBindGroupError> {
        // Until the deformation exists (the render world's startup), try again next frame.
        let Some(buffers) = buffers.as_ref() else { return Err(AsBindGroupError::RetryNextUpdate) };
        for (k, b) in buffers.0.iter().enumerate() {
            output.push((FIRST_BINDING + k as u32, UnpreparedBindingResource::Buffer(b.clone())));
        }
        let look = render_device.create_buffer_with_data(&wgpu::util::BufferInitDescriptor {
            label: Some("snow_ground_look"),
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
        let look = BindGroupLayoutEntry {
            binding: LOOK_BINDING,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: wgpu::BufferSize::new(48) },
            count: None,
        };
        sampling_layout_entries(wgpu::ShaderStages::VERTEX_FRAGMENT)
            .into_iter()
            .map(|mut e| {
                e.binding += FIRST_BINDING;
                e
            })
            .chain([look])
            .collect()
    }
}

impl MaterialExtension for SnowGroundExtension {
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

/// A shader's source: its imports, then the library's sampling module with
/// its bindings in the material's group at [`FIRST_BINDING`].., then its body.
/// (The module is plain WGSL with no imports of its own, so it is placed
/// after the shader's imports rather than imported as a WESL module.)
fn shader_source(imports: &str, body: &str) -> String {
    let group = u32::try_from(MATERIAL_BIND_GROUP_INDEX).unwrap_or(u32::MAX);
    format!("{imports}\n{}\n{body}", snow_sampling_wgsl_at(group, FIRST_BINDING))
}

/// World heights the displaced ground can reach (m): the terrain's range,
/// up to the rest depth above it plus as much again for rims and drifts, and
/// the snowfall to come.
#[must_use]
pub fn snow_height_range(settings: &SnowpackSettings) -> (f32, f32) {
    let (lo, hi) = settings.terrain.height_bounds();
    let fall = settings.params.snowfall.as_ref().map_or(0.0, |_| 2.0);
    (lo, hi + 2.0 * settings.params.depth_m + fall)
}

pub(crate) fn build(app: &mut App) {
    let mut shaders = app.world_mut().resource_mut::<Assets<Shader>>();
    let main = Shader::from_wesl(
        shader_source(include_str!("shaders/ground_vertex.wesl"), include_str!("shaders/ground_vertex_main.wesl")),
        "embedded://bevy_snowpack/ground_vertex.wesl",
    );
    let prepass = Shader::from_wesl(
        shader_source(include_str!("shaders/ground_prepass.wesl"), include_str!("shaders/ground_prepass_main.wesl")),
        "embedded://bevy_snowpack/ground_prepass.wesl",
    );
    let fragment = Shader::from_wesl(
        shader_source(include_str!("shaders/ground_fragment.wesl"), include_str!("shaders/ground_fragment_main.wesl")),
        "embedded://bevy_snowpack/ground_fragment.wesl",
    );
    // The handles are constant ids; inserting cannot fail for them.
    let _ = shaders.insert(VERTEX_SHADER.id(), main);
    let _ = shaders.insert(PREPASS_SHADER.id(), prepass);
    let _ = shaders.insert(FRAGMENT_SHADER.id(), fragment);
    app.add_plugins(MaterialPlugin::<SnowGroundMaterial>::default())
        .add_systems(PostUpdate, grow_ground_bounds.in_set(SnowSystems::Bounds).after(VisibilitySystems::CalculateBounds));
}

/// The ground mesh's bounds span the heights the snow can displace it to.
fn grow_ground_bounds(settings: Res<SnowpackSettings>, mut grounds: Query<(&mut Aabb, &GlobalTransform), With<MeshMaterial3d<SnowGroundMaterial>>>) {
    let (lo, hi) = snow_height_range(&settings);
    for (mut aabb, transform) in &mut grounds {
        // Local y: the mesh is displaced to world heights; an unrotated, unscaled ground is assumed.
        let y0 = transform.translation().y;
        let (center, half) = (0.5 * (lo + hi) - y0, 0.5 * (hi - lo));
        if aabb.center.y != center || aabb.half_extents.y != half {
            aabb.center = Vec3A::new(aabb.center.x, center, aabb.center.z);
            aabb.half_extents = Vec3A::new(aabb.half_extents.x, half, aabb.half_extents.z);
        }
    }
}
