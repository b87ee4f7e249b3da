//! Snow on the characters (snowpack's snow coat, `docs/characters.md`): each
//! mesh of a [`SnowDeformer::Mesh`](crate::SnowDeformer) carries the snow it
//! waded through and the snow that fell on it, kept on the GPU by the
//! library. The plugin reads it back a few times a second into
//! [`SnowCoat`] on the mesh entity (gameplay: a snowy character is slower, or
//! shakes itself), and [`SnowCoatMaterial`] draws it: Bevy's standard
//! material with the snow blended over it, for the meshes under a
//! [`SnowCoatLook`].

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use bevy::asset::uuid_handle;
use bevy::mesh::VertexAttributeValues;
use bevy::pbr::{ExtendedMaterial, MaterialExtension, MaterialPlugin};
use bevy::prelude::*;
use bevy::render::render_resource::{AsBindGroup, ShaderType};
use bevy::shader::{Shader, ShaderRef};
use snowpack::{CoatSettings, GpuContext, SkinnedId, SnowDeformation};

use crate::SnowSystems;
use crate::from_render::{FromRender, ToMainWorld};

/// How a mesh deformer's meshes gather and lose snow: put it on the
/// [`SnowDeformer::Mesh`](crate::SnowDeformer) entity (the library's defaults
/// without it). Changes reach the snow at the next frame. The library's
/// settings are opaque to reflection (`reflect_clone` copies them).
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq)]
#[reflect(Component, Clone, Debug, Default, PartialEq)]
pub struct SnowCoatSettings(#[reflect(ignore, clone)] pub CoatSettings);

/// The snow on a mesh deformer's mesh: one thickness a vertex (m), in the
/// mesh's vertex order. Inserted on the mesh entity and refreshed every
/// [`COAT_READ_FRAMES`] frames, a frame or two after the GPU wrote it.
#[derive(Component, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Component, Clone, Debug, Default, PartialEq)]
pub struct SnowCoat {
    /// Snow on each vertex (m).
    pub thickness_m: Vec<f32>,
}

impl SnowCoat {
    /// The most snow on any vertex (m).
    #[must_use]
    pub fn max_m(&self) -> f32 {
        self.thickness_m.iter().copied().fold(0.0, f32::max)
    }

    /// The fraction of the vertices carrying more than `min_m`.
    #[must_use]
    pub fn covered_fraction(&self, min_m: f32) -> f32 {
        self.thickness_m.iter().filter(|&&c| c > min_m).count() as f32 / self.thickness_m.len().max(1) as f32
    }
}

/// Put on a [`SnowDeformer::Mesh`](crate::SnowDeformer) entity (a glTF
/// scene's root, say): its meshes' [`StandardMaterial`]s are swapped for
/// [`SnowCoatMaterial`]s with the same settings, and their vertex colours
/// carry the coat (the material reads them; a mesh asset shared with other
/// entities shows the coat of one of them).
#[derive(Component, Reflect, Clone, Copy, Debug, Default)]
#[reflect(Component, Clone, Debug, Default)]
pub struct SnowCoatLook;

/// Frames between two readbacks of the coats (10 a second at 60 Hz).
pub const COAT_READ_FRAMES: u64 = 6;

/// A character's material: Bevy's standard material with the snow it carries blended over it.
pub type SnowCoatMaterial = ExtendedMaterial<StandardMaterial, SnowCoatExtension>;

/// The snow's look on a character, as snowpack's renderer draws it
/// (`docs/rendering.md`, "Snow on characters").
#[derive(Asset, AsBindGroup, Reflect, Debug, Clone)]
pub struct SnowCoatExtension {
    /// The snow's albedo and roughness, and where its cover ramps in.
    #[uniform(100)]
    pub look: CoatLook,
}

/// `CoatLook` in `shaders/coat_fragment.wesl`.
#[derive(ShaderType, Reflect, Debug, Clone, Copy)]
pub struct CoatLook {
    /// Albedo (linear rgb) and perceptual roughness of the snow.
    pub snow: Vec4,
    /// Coat (m) at which the cover starts and is full, the noise on the coat
    /// (m) and the noise's cell size (m).
    pub ramp: Vec4,
}

impl Default for SnowCoatExtension {
    fn default() -> Self {
        // snowpack's fresh snow, and its renderer's ramp (skinned_draw.wgsl).
        Self { look: CoatLook { snow: Vec4::new(0.9, 0.92, 0.95, 0.6), ramp: Vec4::new(0.001, 0.015, 0.006, 0.04) } }
    }
}

const FRAGMENT_SHADER: Handle<Shader> = uuid_handle!("5b0f3d8e-4f0c-4a55-9d5e-1c2a9d7e6c01");

impl MaterialExtension for SnowCoatExtension {
    fn fragment_shader() -> ShaderRef {
        ShaderRef::Handle(FRAGMENT_SHADER)
    }
}

/// Coats arrived from the render world, by mesh entity, not yet applied.
#[derive(Resource, Default)]
pub(crate) struct ArrivedCoats(pub HashMap<Entity, Vec<f32>>);

pub(crate) fn build(app: &mut App) {
    let mut shaders = app.world_mut().resource_mut::<Assets<Shader>>();
    let fragment = Shader::from_wesl(include_str!("shaders/coat_fragment.wesl"), "embedded://bevy_snowpack/coat_fragment.wesl");
    // The handle is a constant id; inserting cannot fail for it.
    let _ = shaders.insert(FRAGMENT_SHADER.id(), fragment);
    app.add_plugins(MaterialPlugin::<SnowCoatMaterial>::default())
        .register_type::<SnowCoatSettings>()
        .register_type::<SnowCoat>()
        .register_type::<SnowCoatLook>()
        .init_resource::<ArrivedCoats>()
        .add_systems(PreUpdate, apply_coats.in_set(SnowSystems::Receive).after(crate::systems::Delivered))
        .add_systems(PostUpdate, swap_materials.in_set(SnowSystems::Gather));
}

/// The meshes under a [`SnowCoatLook`] get a [`SnowCoatMaterial`] made from their standard one.
fn swap_materials(
    mut commands: Commands,
    looks: Query<Entity, With<SnowCoatLook>>,
    children: Query<&Children>,
    standard: Query<&MeshMaterial3d<StandardMaterial>>,
    standard_assets: Res<Assets<StandardMaterial>>,
    mut coat_assets: ResMut<Assets<SnowCoatMaterial>>,
) {
    for root in &looks {
        for entity in std::iter::once(root).chain(children.iter_descendants(root)) {
            let Ok(material) = standard.get(entity) else { continue };
            let Some(base) = standard_assets.get(&material.0) else { continue };
            let coat = coat_assets.add(SnowCoatMaterial { base: base.clone(), extension: SnowCoatExtension::default() });
            commands.entity(entity).remove::<MeshMaterial3d<StandardMaterial>>().insert(MeshMaterial3d(coat));
        }
    }
}

/// Puts the coats that arrived on their mesh entities ([`SnowCoat`]) and,
/// where a [`SnowCoatMaterial`] draws the mesh, into its vertex colours.
fn apply_coats(
    mut commands: Commands,
    mut arrived: ResMut<ArrivedCoats>,
    meshes: Query<(&Mesh3d, Has<MeshMaterial3d<SnowCoatMaterial>>)>,
    mut mesh_assets: ResMut<Assets<Mesh>>,
) {
    for (entity, thickness_m) in arrived.0.drain() {
        let Ok((mesh3d, drawn)) = meshes.get(entity) else { continue };
        if drawn && let Some(mut mesh) = mesh_assets.get_mut(&mesh3d.0) {
            // Only when the mesh is the one the coat was made for.
            if mesh.count_vertices() == thickness_m.len() {
                let colours: Vec<[f32; 4]> = thickness_m.iter().map(|&c| [c, 0.0, 0.0, 1.0]).collect();
                mesh.insert_attribute(Mesh::ATTRIBUTE_COLOR, VertexAttributeValues::Float32x4(colours));
            }
        }
        commands.entity(entity).insert(SnowCoat { thickness_m });
    }
}

/// The render world's side: each mesh's coat settings as last applied, and
/// its staging buffer with whether a readback is in flight.
#[derive(Default)]
pub(crate) struct CoatReadbacks(HashMap<u64, CoatSlot>);

struct CoatSlot {
    applied: Option<CoatSettings>,
    staging: Option<wgpu::Buffer>,
    busy: Arc<AtomicBool>,
}

impl CoatReadbacks {
    /// Applies changed settings to the mesh `key` (registered as `id`).
    pub(crate) fn apply(&mut self, snow: &mut SnowDeformation, key: u64, id: SkinnedId, settings: Option<CoatSettings>) {
        let slot = self.0.entry(key).or_insert_with(|| CoatSlot { applied: None, staging: None, busy: Arc::new(AtomicBool::new(false)) });
        let wanted = settings.unwrap_or_default();
        if slot.applied != Some(wanted) {
            if let Err(e) = snow.set_coat(id, wanted) {
                tracing::error!("bevy_snowpack: the snow coat of a mesh deformer: {e}");
            }
            slot.applied = Some(wanted);
        }
    }

    /// Every [`COAT_READ_FRAMES`] frames, records the copy of each posed
    /// mesh's coat into its staging buffer, mapped when `encoder` is
    /// submitted; the mapping's callback sends it to the main world.
    pub(crate) fn record(
        &mut self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        snow: &SnowDeformation,
        posed: &[(u64, SkinnedId)],
        to_main: &ToMainWorld,
    ) {
        if !snow.frame().is_multiple_of(COAT_READ_FRAMES) {
            return;
        }
        for &(key, id) in posed {
            let (Some(coat), Some(slot)) = (snow.coat_buffer(id), self.0.get_mut(&key)) else { continue };
            // A readback still in flight (the GPU is behind): this one is skipped.
            if slot.busy.swap(true, Ordering::AcqRel) {
                continue;
            }
            let size = coat.size();
            let staging = slot
                .staging
                .get_or_insert_with(|| {
                    ctx.device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("bevy_snowpack coat readback"),
                        size,
                        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    })
                })
                .clone();
            encoder.copy_buffer_to_buffer(coat, 0, &staging, 0, size);
            let (busy, sender, entity) = (Arc::clone(&slot.busy), to_main.0.clone(), Entity::from_bits(key));
            let mapped = staging.clone();
            encoder.map_buffer_on_submit(&staging, wgpu::MapMode::Read, .., move |result| {
                if result.is_ok() {
                    let thickness_m: Option<Vec<f32>> = mapped.slice(..).get_mapped_range().ok().map(|view| bytemuck::pod_collect_to_vec(&view));
                    mapped.unmap();
                    if let Some(thickness_m) = thickness_m {
                        // A main world that has gone (the app is closing) is not an error.
                        let _ = sender.send(FromRender::Coat(entity, thickness_m));
                    }
                }
                busy.store(false, Ordering::Release);
            });
        }
    }
}
