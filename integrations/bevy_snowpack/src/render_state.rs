//! The snow world in the render world: [`SnowRenderState`] (the deformation
//! on Bevy's device and what the plugin keeps beside it), how a world is
//! made from the settings, put in the render world and retired. Below the
//! render systems (`render.rs`), the settings applied live (`settings.rs`)
//! and the world switch (`world_switch.rs`), which all use it.

use std::collections::HashMap;
use std::sync::{Mutex, MutexGuard};

use bevy::prelude::*;
use snowpack::{GpuContext, ObjectShape, SkinnedId, SnowDeformation, SnowWindowUniform, StoredWindow as _, TileStore, TileStreamer};

use crate::from_render::{FromRender, ToMainWorld};
use crate::material_extension::CoverTexture;
use crate::mesh_deformer::MeshRegistration;
use crate::query::SnowTicket;
use crate::snowpack_settings::dvec2;
use crate::{SnowStoreSettings, SnowpackSettings};

/// The plugin's deformation in the render world, on Bevy's device and queue.
/// Tests and tools read it back (`deformation().read_snow(context())`).
#[derive(Resource)]
pub struct SnowRenderState {
    pub(crate) ctx: GpuContext,
    /// Behind a mutex because resources are `Sync` and the deformation is only `Send`
    /// (its tile streamer's channel); the systems reach it through `get_mut`, without locking.
    pub(crate) snow: Mutex<SnowDeformation>,
    /// The `SnowWindow` uniform of the sampling WGSL, rewritten each frame.
    pub(crate) window: wgpu::Buffer,
    /// Library tickets of the combined requests in flight, with the callers' tickets and ranges.
    pub(crate) in_flight: Vec<(snowpack::QueryTicket, Split)>,
    /// Mesh deformers registered with the library, by mesh entity.
    pub(crate) meshes: HashMap<u64, SkinnedId>,
    /// The objects the accumulation was laid out for (entity, shape, dilate), in its order.
    pub(crate) objects: Vec<(Entity, ObjectShape, bool)>,
    /// The mesh deformers' snow coats: settings applied and readbacks.
    pub(crate) coats: crate::coat::CoatReadbacks,
    /// Every mesh deformer registered so far, so a rebuilt world registers them again.
    pub(crate) registrations: Vec<MeshRegistration>,
    /// Which snow world this is (0 the first); draws made for an older one are made again.
    pub(crate) generation: u64,
    /// The snow words as a texture, for [`crate::SnowCoverMaterial`].
    pub(crate) cover: CoverTexture,
}

impl SnowRenderState {
    /// The deformation (locked while the guard lives; the render systems never wait on it
    /// except while a tool in the render world holds it).
    pub fn deformation(&self) -> MutexGuard<'_, SnowDeformation> {
        self.snow.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The deformation, to change settings at run time (refill, technique, blur).
    pub fn deformation_mut(&mut self) -> &mut SnowDeformation {
        self.snow.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The context and the deformation together (the shared snow's peer
    /// switches sharing on with both).
    pub(crate) fn context_and_deformation(&mut self) -> (&GpuContext, &mut SnowDeformation) {
        (&self.ctx, self.snow.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner))
    }

    /// snowpack's context over Bevy's device and queue.
    #[must_use]
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Puts this world in the render world with what the materials bind
    /// (the caller records the settings it was made from: `AppliedSettings`).
    pub(crate) fn insert_into(self, world: &mut World) {
        let snow = self.snow.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        world.insert_resource(crate::ground::SnowGpuBuffers::new(&snow, &self.window));
        drop(snow);
        world.insert_resource(self.cover.bindings(&self.window));
        world.insert_resource(self);
    }

    /// Ends this world: its snow saved to its disk store when `save` (the
    /// store's files closed once it is dropped); gives back what the next
    /// world needs: the context, the mesh registrations and the generation.
    pub(crate) fn retire(self, save: bool) -> (GpuContext, Vec<MeshRegistration>, u64) {
        let Self { ctx, snow, registrations, generation, .. } = self;
        let mut snow = snow.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
        if save && let Err(e) = snow.save(&ctx) {
            tracing::error!("bevy_snowpack: the old snow world could not be saved to its store: {e}");
        }
        drop(snow);
        (ctx, registrations, generation)
    }

    /// Which snow world this is: 0 for the first, one more for each rebuild
    /// ([`crate::SnowpackSettings`] changed where it cannot change live).
    #[must_use]
    pub fn generation(&self) -> u64 {
        self.generation
    }
}

/// How one combined request splits back into the callers' requests: their tickets and ranges.
pub(crate) type Split = Vec<(SnowTicket, std::ops::Range<usize>)>;

/// A snow world made from `s`: the deformation on `ctx`, its store attached
/// (a save loaded, reported to the main world), the meshes of an earlier
/// world registered again.
pub(crate) fn create_world(
    ctx: GpuContext,
    s: &SnowpackSettings,
    to_main: &ToMainWorld,
    generation: u64,
    registrations: Vec<MeshRegistration>,
) -> Result<SnowRenderState, snowpack::SnowError> {
    let created = SnowDeformation::new(&ctx, s.params.clone(), s.terrain.clone(), dvec2(s.center)).and_then(|mut snow| {
        let loaded = match &s.store {
            Some(store) => attach_store(&ctx, &mut snow, store)?,
            None => false,
        };
        Ok((snow, loaded))
    });
    let (mut snow, loaded) = created?;
    to_main.send(FromRender::LoadedSave(loaded));
    let mut meshes = HashMap::new();
    for MeshRegistration { key, mesh, joint_count } in &registrations {
        match snow.add_skinned_mesh(&ctx, mesh, *joint_count) {
            Ok(id) => {
                meshes.insert(*key, id);
            }
            Err(e) => tracing::error!("bevy_snowpack: a mesh deformer cannot be registered in the new snow world: {e}"),
        }
    }
    let window = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bevy_snowpack window"),
        size: std::mem::size_of::<SnowWindowUniform>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue.write_buffer(&window, 0, bytemuck::bytes_of(&SnowWindowUniform::new(&snow)));
    let cover = CoverTexture::new(&ctx.device, &snow);
    Ok(SnowRenderState {
        ctx,
        snow: Mutex::new(snow),
        window,
        in_flight: Vec::new(),
        meshes,
        objects: Vec::new(),
        coats: crate::coat::CoatReadbacks::default(),
        registrations,
        generation,
        cover,
    })
}

/// The disk store of the settings, attached before the first frame, and
/// the window's tiles loaded (the world's creation is the loading screen:
/// without it the first frames would show fresh snow where the disk is
/// slower than a frame, merged in as it answers); `Ok(true)`: a save was loaded.
fn attach_store(ctx: &GpuContext, snow: &mut SnowDeformation, store: &SnowStoreSettings) -> Result<bool, snowpack::SnowError> {
    let tiles = TileStore::open(&store.dir, store.tile_texels, store.disk)?;
    let loaded = snow.attach_store(ctx, TileStreamer::new(tiles, store.memory))?;
    snow.preload(ctx)?;
    Ok(loaded)
}
