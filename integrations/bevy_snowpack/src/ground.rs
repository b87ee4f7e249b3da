//! The snow ground: `ExtendedMaterial<StandardMaterial, SnowGroundExtension>`
//! whose main and prepass vertex shaders displace the mesh to the snow
//! surface with snowpack's exported sampling WGSL, and bounds grown to the
//! snow's height range so the displaced ground is not culled.

use bevy::asset::uuid_handle;
use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::VisibilitySystems;
use bevy::ecs::system::SystemParamItem;
use bevy::ecs::system::lifetimeless::SRes;
use bevy::math::Vec3A;
use bevy::pbr::{ExtendedMaterial, MaterialExtension, MaterialPlugin};
use bevy::prelude::*;
use bevy::render::render_resource::{
    AsBindGroup, AsBindGroupError, BindGroupBuilder, BindGroupLayout, BindGroupLayoutEntry, Buffer, UnpreparedBindingResource,
};
use bevy::render::renderer::RenderDevice;
use bevy::shader::{Shader, ShaderRef};
use snowpack::SnowDeformation;
use snowpack::render::ground::SNOW_SAMPLING_WGSL;
use snowpack::render::sampling::sampling_layout_entries;

use crate::SnowpackSettings;

/// The ground material: Bevy's standard material on a mesh displaced by the snow.
pub type SnowGroundMaterial = ExtendedMaterial<StandardMaterial, SnowGroundExtension>;

/// Binding number of the sampling module's binding 0 in the material's group
/// (the standard material's own bindings are below 100).
pub const FIRST_BINDING: u32 = 100;

const VERTEX_SHADER: Handle<Shader> = uuid_handle!("5b0f3d8e-4f0c-4a55-9d5e-1c2a9d7e6b01");
const PREPASS_SHADER: Handle<Shader> = uuid_handle!("5b0f3d8e-4f0c-4a55-9d5e-1c2a9d7e6b02");

/// The extension that displaces a [`StandardMaterial`]'s mesh to the snow
/// surface (main pass and prepass: depth, normals and shadows match). The
/// mesh supplies x and z only (a flat grid covering the window, with normals;
/// `Plane3d` subdivided does); its heights and normals come from the snow.
#[derive(Asset, Reflect, Clone, Debug, Default)]
pub struct SnowGroundExtension;

/// The deformation's buffers the material binds, in the render world.
#[derive(Resource, Clone)]
pub struct SnowGpuBuffers([Buffer; 4]);

impl SnowGpuBuffers {
    pub(crate) fn new(snow: &SnowDeformation, window: &wgpu::Buffer) -> Self {
        let r = snow.resources();
        Self([window.clone().into(), r.terrain_params.clone().into(), r.heightmap.clone().into(), r.snow.clone().into()])
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
        _render_device: &RenderDevice,
        buffers: &mut SystemParamItem<'_, '_, Self::Param>,
        _force_no_bindless: bool,
        output: &mut BindGroupBuilder,
    ) -> Result<(), AsBindGroupError> {
        // Until the deformation exists (the render world's startup), try again next frame.
        let Some(buffers) = buffers.as_ref() else { return Err(AsBindGroupError::RetryNextUpdate) };
        for (k, b) in buffers.0.iter().enumerate() {
            output.push((FIRST_BINDING + k as u32, UnpreparedBindingResource::Buffer(b.clone())));
        }
        Ok(())
    }

    fn bind_group_layout_entries(_render_device: &RenderDevice, _force_no_bindless: bool) -> Vec<BindGroupLayoutEntry>
    where
        Self: Sized,
    {
        sampling_layout_entries(wgpu::ShaderStages::VERTEX_FRAGMENT)
            .into_iter()
            .map(|mut e| {
                e.binding += FIRST_BINDING;
                e
            })
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
}

/// snowpack's sampling module with its bindings moved into the material's
/// group at [`FIRST_BINDING`]..: WGSL has no preprocessor, so a textual
/// rewrite of its four binding attributes (the module has no others).
#[must_use]
pub fn sampling_module() -> String {
    (0..4).fold(SNOW_SAMPLING_WGSL.to_string(), |s, k| {
        s.replace(&format!("@group(1) @binding({k})"), &format!("@group(constants::MATERIAL_BIND_GROUP) @binding({})", FIRST_BINDING + k))
    })
}

/// A vertex shader's source: its imports, then the sampling module, then its body.
fn shader_source(imports: &str, body: &str) -> String {
    format!("{imports}\n{}\n{body}", sampling_module())
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
    // The handles are constant ids; inserting cannot fail for them.
    let _ = shaders.insert(VERTEX_SHADER.id(), main);
    let _ = shaders.insert(PREPASS_SHADER.id(), prepass);
    app.add_plugins(MaterialPlugin::<SnowGroundMaterial>::default()).add_systems(PostUpdate, grow_ground_bounds.after(VisibilitySystems::CalculateBounds));
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
