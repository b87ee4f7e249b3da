//! Each `#[repr(C)]` uniform struct has exactly the size naga computes for its WGSL twin.

use snowpack::low_level::accumulate::state::ObjectGpu;
use snowpack::low_level::accumulate::{IncrementParams, OcclusionParams, ScatterParams, SettleParams, SurfaceParams};
use snowpack::low_level::deform::capture::CaptureParams;
use snowpack::low_level::deform::capture_shapes::ShapeParams;
use snowpack::low_level::deform::decal::DecalParams;
use snowpack::low_level::deform::display::DisplayParams;
use snowpack::low_level::deform::query::{QueryParams, RawSample};
use snowpack::low_level::deform::resources::TerrainParams;
use snowpack::low_level::deform::stamp::StampParams;
use snowpack::low_level::deform::terrain_bake::{ResolveParams, TerrainBakeParams};
use snowpack::low_level::deform::update::UpdateParams;
use snowpack::low_level::deform::window::WindowParams;
use snowpack::low_level::render::ao::AoParams;
use snowpack::low_level::render::environment::EnvParams;
use snowpack::low_level::render::frame::FrameUniforms;
use snowpack::low_level::render::ground::GroundParams;
use snowpack::low_level::render::shell::count::CountParams;
use snowpack::low_level::render::shell::peel::{PeelParams, ShellDrawParams};
use snowpack::low_level::render::shell::tetrahedra::{Tetra, TetraParams};
use snowpack::low_level::render::shell::vertices::{BaseVertex, ShellVertex, ShellVertexParams};
use snowpack::low_level::render::surface::UnpackParams;
use snowpack::low_level::replicate::gather::TileGatherParams;
use snowpack::low_level::replicate::merge::TileMergeParams;
use snowpack::low_level::shaders;
use snowpack::low_level::skin::coat::SnowCoatParams;
use snowpack::low_level::skin::skinning::SkinningParams;
use snowpack::low_level::tiles::exchange::ExchangeParams;
use snowpack::low_level::tiles::restore::{RestoreEntry, RestoreParams};
use snowpack::low_level::tiles::seal::SealParams;
use snowpack::low_level::tiles::weather::WeatherParams;
use snowpack::{GroundCamera, SnowWindowUniform};

/// Size naga gives the uniform global `name` in `source`.
fn wgsl_uniform_size(source: &str, name: &str) -> u32 {
    let module = naga::front::wgsl::parse_str(source).expect("shader parses");
    let (_, var) = module
        .global_variables
        .iter()
        .find(|(_, v)| v.name.as_deref() == Some(name) && v.space == naga::AddressSpace::Uniform)
        .unwrap_or_else(|| panic!("no uniform `{name}`"));
    module.types[var.ty].inner.size(module.to_ctx())
}

#[test]
fn uniform_sizes_match_naga() {
    let cases: &[(&str, &str, usize)] = &[
        (shaders::WINDOW, "params", size_of::<WindowParams>()),
        (shaders::WINDOW_GROUND, "params", size_of::<WindowParams>()),
        (shaders::WINDOW_GROUND, "terrain_params", size_of::<TerrainParams>()),
        (shaders::UPDATE, "terrain_params", size_of::<TerrainParams>()),
        (shaders::CAPTURE_SHAPES, "params", size_of::<ShapeParams>()),
        (shaders::CAPTURE_MESH, "params", size_of::<CaptureParams>()),
        (shaders::STAMP, "params", size_of::<StampParams>()),
        (shaders::DECAL, "params", size_of::<DecalParams>()),
        (shaders::UPDATE, "params", size_of::<UpdateParams>()),
        (shaders::DISPLAY, "params", size_of::<DisplayParams>()),
        (shaders::SURFACE_UNPACK, "params", size_of::<UnpackParams>()),
        (shaders::QUERY, "params", size_of::<QueryParams>()),
        (shaders::TERRAIN_BAKE, "params", size_of::<TerrainBakeParams>()),
        (shaders::TERRAIN_RESOLVE, "params", size_of::<ResolveParams>()),
        (shaders::TERRAIN_DRAW, "frame", size_of::<FrameUniforms>()),
        (shaders::TERRAIN_DRAW, "terrain_params", size_of::<TerrainParams>()),
        (shaders::ACTOR_DRAW, "frame", size_of::<FrameUniforms>()),
        (shaders::SKY, "frame", size_of::<FrameUniforms>()),
        (shaders::TONEMAP, "frame", size_of::<FrameUniforms>()),
        (shaders::AO, "params", size_of::<AoParams>()),
        (shaders::ENV_DOWNSAMPLE, "params", size_of::<EnvParams>()),
        (shaders::ENV_PREFILTER, "params", size_of::<EnvParams>()),
        (shaders::SKINNING, "params", size_of::<SkinningParams>()),
        (shaders::SNOW_COAT, "params", size_of::<SnowCoatParams>()),
        (shaders::SNOW_COAT, "terrain_params", size_of::<TerrainParams>()),
        (shaders::OCCLUSION, "params", size_of::<OcclusionParams>()),
        (shaders::SCATTER, "params", size_of::<ScatterParams>()),
        (shaders::INCREMENT, "params", size_of::<IncrementParams>()),
        (shaders::SETTLE, "params", size_of::<SettleParams>()),
        (shaders::ATLAS_SURFACE, "params", size_of::<SurfaceParams>()),
        (shaders::OBJECT_DRAW, "frame", size_of::<FrameUniforms>()),
        (shaders::OBJECT_DRAW, "atlas_info", size_of::<[u32; 4]>()),
        (shaders::EXCHANGE, "params", size_of::<ExchangeParams>()),
        (shaders::TILE_RESTORE, "params", size_of::<RestoreParams>()),
        (shaders::TILE_RESTORE, "terrain_params", size_of::<TerrainParams>()),
        (shaders::TILE_WEATHER, "params", size_of::<WeatherParams>()),
        (shaders::TILE_SEAL, "params", size_of::<SealParams>()),
        (shaders::TILE_GATHER, "params", size_of::<TileGatherParams>()),
        (shaders::TILE_MERGE, "params", size_of::<TileMergeParams>()),
        (shaders::TILE_MERGE, "terrain_params", size_of::<TerrainParams>()),
        (shaders::SHELL_VERTICES, "params", size_of::<ShellVertexParams>()),
        (shaders::SHELL_VERTICES, "terrain_params", size_of::<TerrainParams>()),
        (shaders::SHELL_TETRAHEDRA, "params", size_of::<TetraParams>()),
        (shaders::SHELL_DRAW, "frame", size_of::<FrameUniforms>()),
        (shaders::SHELL_DRAW, "shell", size_of::<ShellDrawParams>()),
        (shaders::SHELL_RESOLVE, "params", size_of::<PeelParams>()),
        (shaders::PEEL_COUNT, "params", size_of::<CountParams>()),
        (shaders::SNOW_SAMPLING, "snow_window", size_of::<SnowWindowUniform>()),
        (shaders::SNOW_SAMPLING, "snow_terrain", size_of::<TerrainParams>()),
        (shaders::GROUND, "camera", size_of::<GroundCamera>()),
        (shaders::GROUND, "ground", size_of::<GroundParams>()),
    ];
    for (source, name, rust) in cases {
        assert_eq!(wgsl_uniform_size(source, name) as usize, *rust, "uniform `{name}`");
    }
}

/// Stride naga gives the element type of the storage array `name` in `source`.
fn wgsl_storage_stride(source: &str, name: &str) -> u32 {
    let module = naga::front::wgsl::parse_str(source).expect("shader parses");
    let (_, var) = module.global_variables.iter().find(|(_, v)| v.name.as_deref() == Some(name)).unwrap_or_else(|| panic!("no global `{name}`"));
    match module.types[var.ty].inner {
        naga::TypeInner::Array { stride, .. } => stride,
        ref other => panic!("`{name}` is not an array: {other:?}"),
    }
}

#[test]
fn object_struct_matches_naga() {
    for source in [shaders::OCCLUSION, shaders::SETTLE, shaders::ATLAS_SURFACE, shaders::OBJECT_DRAW] {
        assert_eq!(wgsl_storage_stride(source, "objects") as usize, size_of::<ObjectGpu>());
    }
}

#[test]
fn query_structs_match_naga() {
    assert_eq!(wgsl_storage_stride(shaders::QUERY, "samples") as usize, size_of::<RawSample>());
    assert_eq!(wgsl_storage_stride(shaders::QUERY, "points") as usize, size_of::<glam::Vec2>());
}

#[test]
fn tile_structs_match_naga() {
    assert_eq!(wgsl_storage_stride(shaders::TILE_RESTORE, "entries") as usize, size_of::<RestoreEntry>());
    assert_eq!(wgsl_storage_stride(shaders::TILE_WEATHER, "owners") as usize, size_of::<[i32; 4]>());
}

#[test]
fn shell_structs_match_naga() {
    assert_eq!(wgsl_storage_stride(shaders::SHELL_VERTICES, "base") as usize, size_of::<BaseVertex>());
    assert_eq!(wgsl_storage_stride(shaders::SHELL_VERTICES, "vertices") as usize, size_of::<ShellVertex>());
    assert_eq!(wgsl_storage_stride(shaders::SHELL_TETRAHEDRA, "tetras") as usize, size_of::<Tetra>());
    assert_eq!(wgsl_storage_stride(shaders::SHELL_DRAW, "tetras") as usize, size_of::<Tetra>());
    assert_eq!(wgsl_storage_stride(shaders::SHELL_DRAW, "vertices") as usize, size_of::<ShellVertex>());
}

#[test]
fn every_shader_is_listed_and_valid() {
    // One constant per file in shaders/ (the passes and SNOW_SAMPLING, the
    // exported module); the shared snippets are imported into them.
    let files = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/shaders"))
        .expect("shaders/")
        .filter(|e| e.as_ref().is_ok_and(|e| e.path().extension().is_some_and(|x| x == "wgsl")))
        .count();
    assert_eq!(shaders::ALL.len(), files);
    for (name, source) in shaders::ALL {
        let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{name}: {e}"));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

/// Every compute shader that binds group 1 binds the window's buffers there
/// as `pass::window_bindings` lays them out: each binding at its number,
/// under its name, in its address space, and the snow, footprints and
/// snowfall all read-only or all read-write (one of the two layouts).
#[test]
fn every_window_pass_binds_group_1_as_the_window_bindings() {
    use snowpack::low_level::pass::window_bindings::{WindowAccess, window_layout_entries};
    const NAMES: [&str; 5] = ["terrain_params", "heightmap", "snow", "stamps", "fallen"];
    let read_only = |access| {
        window_layout_entries(access).map(|e| match e.ty {
            wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, .. } => Some(read_only),
            _ => None,
        })
    };
    let layouts = [read_only(WindowAccess::Read), read_only(WindowAccess::Write)];
    let mut passes = Vec::new();
    for (name, source) in shaders::ALL {
        let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{name}: {e}"));
        if !module.entry_points.iter().any(|e| e.stage == naga::ShaderStage::Compute) {
            continue;
        }
        let mut access = [None; 5];
        for (_, var) in module.global_variables.iter() {
            let Some(binding) = var.binding.as_ref().filter(|b| b.group == 1) else { continue };
            let b = binding.binding as usize;
            let var_name = var.name.as_deref().unwrap_or("");
            assert!(b < NAMES.len() && NAMES[b] == var_name, "{name}: group 1 binding {b} is `{var_name}`, not the window's");
            access[b] = Some(match var.space {
                naga::AddressSpace::Uniform => None,
                naga::AddressSpace::Storage { access } => Some(!access.contains(naga::StorageAccess::STORE)),
                other => panic!("{name}: `{var_name}` in {other:?}"),
            });
        }
        if access.iter().all(Option::is_none) {
            continue;
        }
        let fits = layouts.iter().any(|layout| access.iter().zip(layout).all(|(a, l)| a.is_none_or(|a| a == *l)));
        assert!(fits, "{name}: group 1 {access:?} is neither window layout {layouts:?}");
        passes.push(*name);
    }
    let expected = [
        "DISPLACE",
        "DISPLAY",
        "EROSION",
        "EXCHANGE",
        "QUERY",
        "SNOW_COAT",
        "STAMP",
        "TILE_GATHER",
        "TILE_MERGE",
        "TILE_RESTORE",
        "TILE_SEAL",
        "TILE_WEATHER",
        "UPDATE",
        "WINDOW",
    ];
    passes.sort_unstable();
    assert_eq!(passes, expected, "the passes over the window");
}
