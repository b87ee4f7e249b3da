//! The snow's terrain from a game's own Bevy assets: a heightmap
//! [`Image`] (R8, R16 or R32F) with its world size and height scale, a
//! [`Mesh`] or every mesh of a spawned glTF scene, baked as the library's
//! terrain once loaded. Put a [`SnowTerrainAsset`] resource in the app; the
//! plugin waits for the asset, converts it and sets
//! [`SnowpackSettings::terrain`], which rebuilds the snow world on it
//! (`crate::world_switch`). [`SnowTerrainStatus`] says where it is; a bad
//! asset is logged with its name and reported there, never a panic.

use std::sync::Arc;

use bevy::asset::{LoadState, UntypedAssetId};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use bevy::transform::TransformSystems;
use snowpack::{HeightmapTerrain, TerrainSource};

use crate::SnowpackSettings;

/// Where the snow's terrain comes from, as Bevy assets (a resource: insert
/// or replace it at any time; the snow is rebuilt on the new terrain once
/// the asset is loaded).
#[derive(Resource, Clone, Debug)]
pub enum SnowTerrainAsset {
    /// A heightmap image: pixel row 0 at the smallest world z, column 0 at
    /// the smallest x; height `base_m + value * height_scale_m`, the value
    /// 0..1 for `R8Unorm`, `R16Unorm` and `R16Uint` (a 16-bit PNG loaded
    /// with `expand_grayscale: false`), and as stored for `R32Float`.
    Heightmap {
        /// The image (its pixel data must be kept in the main world, Bevy's default).
        image: Handle<Image>,
        /// World (x, z) of the image's centre (m).
        center: Vec2,
        /// World size (x, z) the image covers (m).
        size_m: Vec2,
        /// Height of a pixel value of 1 above `base_m` (m).
        height_scale_m: f32,
        /// Height of a pixel value of 0 (m).
        base_m: f32,
    },
    /// A mesh's triangles placed by `transform`, drawn from above into a
    /// grid of `texel_m` (the window's texel when `None`).
    Mesh {
        /// The mesh (a triangle list kept in the main world, Bevy's default).
        mesh: Handle<Mesh>,
        /// Where the mesh lies in the world.
        transform: Transform,
        /// The baked grid's texel (m).
        texel_m: Option<f32>,
    },
    /// Every `Mesh3d` at or below this entity (a glTF scene's root), placed
    /// by their `GlobalTransform`s, once the scene has spawned and its
    /// meshes have loaded.
    Scene {
        /// The scene's root entity.
        root: Entity,
        /// The baked grid's texel (m).
        texel_m: Option<f32>,
    },
}

impl SnowTerrainAsset {
    /// A heightmap image covering `size_m` (x, z) centred on the origin,
    /// a value of 1 being `height_scale_m` metres above 0.
    #[must_use]
    pub fn heightmap(image: Handle<Image>, size_m: Vec2, height_scale_m: f32) -> Self {
        Self::Heightmap { image, center: Vec2::ZERO, size_m, height_scale_m, base_m: 0.0 }
    }

    /// A mesh as it lies (no transform), baked at the window's texel.
    #[must_use]
    pub fn mesh(mesh: Handle<Mesh>) -> Self {
        Self::Mesh { mesh, transform: Transform::IDENTITY, texel_m: None }
    }

    /// Every mesh of a spawned scene below `root`, baked at the window's texel.
    #[must_use]
    pub fn scene(root: Entity) -> Self {
        Self::Scene { root, texel_m: None }
    }
}

/// How far [`SnowTerrainAsset`] has come (a resource).
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub enum SnowTerrainStatus {
    /// No terrain asset, or its asset is still loading (a scene still spawning).
    #[default]
    Waiting,
    /// Converted and set as [`SnowpackSettings::terrain`].
    Applied,
    /// The asset cannot be a terrain: the error, as logged.
    Failed(String),
}

/// Why an asset cannot be the snow's terrain; each names the asset.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TerrainAssetError {
    /// The asset did not load.
    #[error("terrain asset {asset}: it failed to load: {why}")]
    LoadFailed {
        /// The asset's path or id.
        asset: String,
        /// The loader's error.
        why: String,
    },
    /// The heightmap's pixel format is not one a height can be read from.
    #[error(
        "terrain heightmap {asset}: unsupported pixel format {format:?} (R8Unorm, R16Unorm, R16Uint or R32Float; load a grayscale PNG with `expand_grayscale: false`)"
    )]
    UnsupportedFormat {
        /// The image's path or id.
        asset: String,
        /// Its format.
        format: TextureFormat,
    },
    /// The heightmap's data is missing or does not match its size.
    #[error("terrain heightmap {asset}: {why}")]
    BadImage {
        /// The image's path or id.
        asset: String,
        /// What is wrong.
        why: String,
    },
    /// The mesh has no usable triangles.
    #[error("terrain mesh {asset}: {why}")]
    BadMesh {
        /// The mesh's path or id.
        asset: String,
        /// What is wrong.
        why: String,
    },
    /// The library refused the terrain (a size, a height or a vertex not finite, no extent seen from above).
    #[error("terrain asset {asset}: {source}")]
    Terrain {
        /// The asset's path or id.
        asset: String,
        /// The library's error.
        source: snowpack::SnowError,
    },
}

/// The heights of a heightmap image, as the library's terrain (see
/// [`SnowTerrainAsset::Heightmap`]); `asset` names it in errors.
pub fn heightmap_from_image(
    image: &Image,
    asset: &str,
    center: Vec2,
    size_m: Vec2,
    height_scale_m: f32,
    base_m: f32,
) -> Result<HeightmapTerrain, TerrainAssetError> {
    let format = image.texture_descriptor.format;
    let bad = |why: String| TerrainAssetError::BadImage { asset: asset.to_owned(), why };
    let bytes = match format {
        TextureFormat::R8Unorm => 1,
        TextureFormat::R16Unorm | TextureFormat::R16Uint => 2,
        TextureFormat::R32Float => 4,
        _ => return Err(TerrainAssetError::UnsupportedFormat { asset: asset.to_owned(), format }),
    };
    let size = image.texture_descriptor.size;
    if size.depth_or_array_layers != 1 {
        return Err(bad(format!("{} layers; a heightmap is one 2D image", size.depth_or_array_layers)));
    }
    let Some(data) = image.data.as_ref() else {
        return Err(bad("its pixels are not in the main world (load it with RenderAssetUsages::MAIN_WORLD)".into()));
    };
    let (w, h) = (size.width, size.height);
    let want = u64::from(w) * u64::from(h) * bytes;
    if data.len() as u64 != want {
        return Err(bad(format!("{} bytes of pixel data for {w}x{h} pixels of {format:?} (needs {want})", data.len())));
    }
    let value = |p: &[u8]| match p.len() {
        1 => f32::from(p[0]) / 255.0,
        2 => f32::from(u16::from_le_bytes([p[0], p[1]])) / 65535.0,
        _ => f32::from_le_bytes([p[0], p[1], p[2], p[3]]),
    };
    let heights = data.chunks_exact(bytes as usize).map(|p| base_m + value(p) * height_scale_m).collect();
    HeightmapTerrain::new(w, h, heights, center.to_array(), size_m.to_array()).map_err(|source| TerrainAssetError::Terrain { asset: asset.to_owned(), source })
}

/// The world-space triangles of a triangle-list mesh placed by `transform`; `asset` names it in errors.
pub fn triangles_from_mesh(mesh: &Mesh, asset: &str, transform: &GlobalTransform) -> Result<Vec<[[f32; 3]; 3]>, TerrainAssetError> {
    let bad = |why: String| TerrainAssetError::BadMesh { asset: asset.to_owned(), why };
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(bad(format!("{:?}; a terrain mesh is a triangle list", mesh.primitive_topology())));
    }
    let Some(VertexAttributeValues::Float32x3(positions)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        return Err(bad("no Float32x3 positions (is the mesh kept in the main world?)".into()));
    };
    let affine = transform.affine();
    let world: Vec<[f32; 3]> = positions.iter().map(|p| affine.transform_point3(Vec3::from(*p)).to_array()).collect();
    let corners: Vec<usize> = match mesh.indices() {
        Some(Indices::U16(i)) => i.iter().map(|&k| usize::from(k)).collect(),
        Some(Indices::U32(i)) => i.iter().map(|&k| k as usize).collect(),
        None => (0..world.len()).collect(),
    };
    if let Some(&k) = corners.iter().find(|&&k| k >= world.len()) {
        return Err(bad(format!("an index ({k}) names a vertex it lacks ({} vertices)", world.len())));
    }
    Ok(corners.chunks_exact(3).map(|t| [world[t[0]], world[t[1]], world[t[2]]]).collect())
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<SnowTerrainStatus>().add_systems(PostUpdate, apply_terrain_asset.after(TransformSystems::Propagate));
}

/// The asset's name for errors: its path, or its id for one made in code.
fn name_of(server: &AssetServer, id: impl Into<UntypedAssetId>) -> String {
    let id = id.into();
    server.get_path(id).map_or_else(|| format!("{id:?}"), |p| p.to_string())
}

/// `Ok(None)` while the asset loads, its error once it failed.
fn loaded<'a, A: Asset>(assets: &'a Assets<A>, server: &AssetServer, handle: &Handle<A>) -> Result<Option<&'a A>, TerrainAssetError> {
    if let Some(asset) = assets.get(handle) {
        return Ok(Some(asset));
    }
    match server.get_load_state(handle.id()) {
        Some(LoadState::Failed(e)) => Err(TerrainAssetError::LoadFailed { asset: name_of(server, handle.id()), why: e.to_string() }),
        _ => Ok(None),
    }
}

/// What the terrain assets are read from.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct TerrainInputs<'w, 's> {
    images: Res<'w, Assets<Image>>,
    meshes: Res<'w, Assets<Mesh>>,
    server: Res<'w, AssetServer>,
    children: Query<'w, 's, &'static Children>,
    placed: Query<'w, 's, (&'static Mesh3d, &'static GlobalTransform)>,
}

/// The asset as the library's terrain: `Ok(None)` while it loads.
fn convert(asset: &SnowTerrainAsset, inputs: &TerrainInputs, window_texel_m: f32) -> Result<Option<TerrainSource>, TerrainAssetError> {
    let baked = |triangles: Vec<[[f32; 3]; 3]>, texel: Option<f32>, name: String| {
        snowpack::TerrainMesh::new(triangles, texel.unwrap_or(window_texel_m))
            .map(|m| Some(TerrainSource::Mesh(Arc::new(m))))
            .map_err(|source| TerrainAssetError::Terrain { asset: name, source })
    };
    match asset {
        SnowTerrainAsset::Heightmap { image, center, size_m, height_scale_m, base_m } => {
            let Some(pixels) = loaded(&inputs.images, &inputs.server, image)? else { return Ok(None) };
            let name = name_of(&inputs.server, image.id());
            heightmap_from_image(pixels, &name, *center, *size_m, *height_scale_m, *base_m).map(|h| Some(TerrainSource::Heightmap(h)))
        }
        SnowTerrainAsset::Mesh { mesh, transform, texel_m } => {
            let Some(m) = loaded(&inputs.meshes, &inputs.server, mesh)? else { return Ok(None) };
            let name = name_of(&inputs.server, mesh.id());
            baked(triangles_from_mesh(m, &name, &GlobalTransform::from(*transform))?, *texel_m, name)
        }
        SnowTerrainAsset::Scene { root, texel_m } => {
            let placed: Vec<_> = std::iter::once(*root).chain(inputs.children.iter_descendants(*root)).filter_map(|e| inputs.placed.get(e).ok()).collect();
            // A scene that has not spawned yet has no meshes: wait for it.
            let mut triangles = Vec::new();
            for (mesh, transform) in &placed {
                let Some(m) = loaded(&inputs.meshes, &inputs.server, &mesh.0)? else { return Ok(None) };
                triangles.extend(triangles_from_mesh(m, &name_of(&inputs.server, mesh.id()), transform)?);
            }
            if placed.is_empty() {
                return Ok(None);
            }
            baked(triangles, *texel_m, format!("scene {root}"))
        }
    }
}

/// Converts the terrain asset once it has loaded and sets it as the snow's terrain.
pub(crate) fn apply_terrain_asset(
    asset: Option<Res<SnowTerrainAsset>>,
    mut status: ResMut<SnowTerrainStatus>,
    mut settings: ResMut<SnowpackSettings>,
    inputs: TerrainInputs,
) {
    let Some(asset) = asset else { return };
    if asset.is_changed() {
        status.set_if_neq(SnowTerrainStatus::Waiting);
    }
    if *status != SnowTerrainStatus::Waiting {
        return;
    }
    match convert(&asset, &inputs, settings.params.texel_m()) {
        Ok(None) => {}
        Ok(Some(terrain)) => {
            if settings.terrain != terrain {
                settings.terrain = terrain;
            }
            *status = SnowTerrainStatus::Applied;
        }
        Err(e) => {
            tracing::error!("bevy_snowpack: {e}");
            *status = SnowTerrainStatus::Failed(e.to_string());
        }
    }
}
