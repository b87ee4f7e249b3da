//! Below the front door (feature `low_level`): named items of the library's
//! modules, for snowpack's own app, its scene loader, benchmarks, fuzz
//! targets and tests, and for a game that replaces a pass or drives one by
//! hand. No whole module is re-exported: each module here mirrors the
//! crate's own (a path reads as where the item lives) and names what the
//! project uses of it; `docs/architecture.md` lists them ("`low_level`, item
//! by item", checked by `tests/layering.rs`).
//!
//! Nothing here is covered by the crate's stability promise: passes, their
//! parameter structs and their resources change with the implementation.
//! The root of the crate is the API a game builds on; reach in here only for
//! what it cannot do, and say why where you do. `docs/architecture.md` says
//! what each module owns and how one frame passes through them.

/// What the app, the tools and the tests read or do with the front door's
/// plain types beyond it (terrains, techniques, deformers, parameters,
/// snowfall, skinned meshes, coat settings, the game's ground, adapter
/// requests).
pub use crate::deform::params::SnowParamsExt;
/// The point queries' counters ([`SnowInspect::query_stats`]).
pub use crate::deform::query::{QueryStats, QueryStatsExt};
pub use crate::deform::shape::DeformerExt;
pub use crate::deform::technique::{RimStyleExt, TechniqueExt};
pub use crate::gpu::context::AdapterRequestExt;
/// What the app, the tools and the tests do with a [`crate::GpuContext`]
/// beyond the front door.
pub use crate::gpu::context::GpuContextExt;
/// What the app, the tools and the tests do with a [`crate::TileStreamer`]
/// beyond the front door.
pub use crate::persist::streamer::TileStreamerExt;
pub use crate::render::ground::{SnowGroundDescriptorExt, SnowGroundExt};
pub use crate::render::sampling::SnowWindowUniformExt;
/// The snow-sampling WGSL module in any bind group (the root has
/// [`crate::snow_sampling_wgsl_at`], which also takes the binding offset).
pub use crate::render::sampling::snow_sampling_wgsl;
pub use crate::skin::coat::CoatSettingsExt;
pub use crate::skin::skinning::SkinnedMeshExt;
/// What snowpack's own app, tools and tests read and drive of a
/// [`crate::SnowDeformation`] beyond the front door.
pub use crate::snow::inspect::{SnowInspect, WindowMass};
pub use crate::snowfall::SnowfallExt;
pub use crate::terrain::{HeightmapTerrainExt, TerrainMeshExt, TerrainSourceExt};
pub use snowpack_share::persist::TileStoreExt;
pub use snowpack_share::replicate::{SnowPeerExt, WorldIdentityExt, WorldSettings};

/// Snow settling on objects: the object atlas, its passes and state.
pub mod accumulate {
    pub use crate::accumulate::{
        AtlasLayout, AtlasSurfacePass, IncrementParams, IncrementPass, ObjectMesh, OcclusionParams, ScatterParams, ScatterPass, SettleParams, SettlePass,
        SnowAccumulation, SurfaceParams,
    };
    /// `accumulate::atlas`: what snowpack's app, tools and tests use of it.
    pub mod atlas {
        pub use crate::accumulate::atlas::{AtlasLayout, GUTTER, NO_OWNER};
    }
    /// `accumulate::occlusion`: what snowpack's app, tools and tests use of it.
    pub mod occlusion {
        pub use crate::accumulate::occlusion::FOOTPRINT_FORMAT;
    }
    /// `accumulate::settle`: what snowpack's app, tools and tests use of it.
    pub mod settle {
        pub use crate::accumulate::settle::SettleBuffers;
    }
    /// `accumulate::state`: what snowpack's app, tools and tests use of it.
    pub mod state {
        pub use crate::accumulate::state::ObjectGpu;
    }
}

/// The core deformation: the window's resources and passes.
pub mod deform {
    /// `deform::capture`: what snowpack's app, tools and tests use of it.
    pub mod capture {
        pub use crate::deform::capture::{CaptureInstances, CaptureMesh, CaptureParams, CapturePass, ShapeCapture, SweptMesh};
    }
    /// `deform::capture_shapes`: what snowpack's app, tools and tests use of it.
    pub mod capture_shapes {
        pub use crate::deform::capture_shapes::ShapeParams;
    }
    /// `deform::decal`: what snowpack's app, tools and tests use of it.
    pub mod decal {
        pub use crate::deform::decal::DecalParams;
    }
    /// `deform::displace`: what snowpack's app, tools and tests use of it.
    pub mod displace {
        pub use crate::deform::displace::{DisplaceParams, DisplacePass, MOST_QUANTA, OFFSETS, PRESSED, code, code_quanta, code_target};
    }
    /// `deform::display`: what snowpack's app, tools and tests use of it.
    pub mod display {
        pub use crate::deform::display::{DisplayKernel, DisplayParams, DisplayPass, normals_of};
    }
    /// `deform::erosion`: what snowpack's app, tools and tests use of it.
    pub mod erosion {
        pub use crate::deform::erosion::{ErosionParams, ErosionPass};
    }
    /// `deform::packed_snow`: what snowpack's app, tools and tests use of it.
    pub mod packed_snow {
        pub use crate::deform::packed_snow::{LEDGER_FINE_PER_M, LedgerCounts, cap, displaced_count, get, ledger, ledger_column, ledger_fine, set};
    }
    /// `deform::params`: what snowpack's app, tools and tests use of it.
    pub mod params {
        pub use crate::deform::params::{DEFAULT_TILE_MEMORY_BYTES, RESOLUTION_RANGE, default_tile_texels};
    }
    /// `deform::push`: what snowpack's app, tools and tests use of it.
    pub mod push {
        pub use crate::deform::push::pushers;
    }
    /// `deform::query`: what snowpack's app, tools and tests use of it.
    pub mod query {
        pub use crate::deform::query::{QueryParams, RawSample};
    }
    /// `deform::resources`: what snowpack's app, tools and tests use of it.
    pub mod resources {
        pub use crate::deform::resources::{DeformResources, TerrainParams};
    }
    /// `deform::snow_word`: what snowpack's app, tools and tests use of it.
    pub mod snow_word {
        pub use crate::deform::snow_word::{SNOW_QUANTA_PER_M, SNOW_QUANTUM_M, column_height, column_press, deficit_quanta, f16_to_f32, shown, with_shown};
    }
    /// `deform::stamp`: what snowpack's app, tools and tests use of it.
    pub mod stamp {
        pub use crate::deform::stamp::{MAX_POINTS, STAMP_EMPTY, StampParams, StampPass, contact_points};
    }
    /// `deform::technique`: what snowpack's app, tools and tests use of it.
    pub mod technique {
        pub use crate::deform::technique::RIM_PEAK;
    }
    /// `deform::terrain_bake`: what snowpack's app, tools and tests use of it.
    pub mod terrain_bake {
        pub use crate::deform::terrain_bake::{ResolveParams, TerrainBakeParams, TerrainBakePass};
    }
    /// `deform::traffic`: what snowpack's app, tools and tests use of it.
    pub mod traffic {
        pub use crate::deform::traffic::{frame_traffic, known_bandwidth_gb_per_s};
    }
    /// `deform::update`: what snowpack's app, tools and tests use of it.
    pub mod update {
        pub use crate::deform::update::{UpdateParams, UpdatePass};
    }
    /// `deform::wheel`: what snowpack's app, tools and tests use of it.
    pub mod wheel {
        pub use crate::deform::wheel::{Tread, TreadPattern, forward, instance};
    }
    /// `deform::window`: what snowpack's app, tools and tests use of it.
    pub mod window {
        pub use crate::deform::window::{SlidingWindow, TexelRect, WindowParams, WindowPass};
    }
    /// `deform::window_ground`: what snowpack's app, tools and tests use of it.
    pub mod window_ground {
        pub use crate::deform::window_ground::WindowGroundPass;
    }
}

/// The library's error type.
pub mod error {
    pub use crate::error::{MessageError, ShareError, SnowError, StoreError};
}

/// The per-frame recording context and window placement handed to plug-ins.
pub mod frame {
    pub use crate::frame::{FrameContext, WindowFrame};
}

/// Device, readback and timing plumbing.
pub mod gpu {
    pub use crate::gpu::{GpuTimer, ReadbackRing, read_buffer};
    /// `gpu::context`: what snowpack's app, tools and tests use of it.
    pub mod context {
        pub use crate::gpu::context::{GL_CONTEXT_LOCK_PANIC, panic_text};
    }
    /// `gpu::layout`: what snowpack's app, tools and tests use of it.
    pub mod layout {
        pub use crate::gpu::layout::{bind_group, compute_pipeline, depth_texture, dispatch, storage};
    }
    /// `gpu::readback`: what snowpack's app, tools and tests use of it.
    pub mod readback {
        pub use crate::gpu::readback::{TextureReadback, read_buffer, read_buffer_async};
    }
    /// `gpu::timing`: what snowpack's app, tools and tests use of it.
    pub mod timing {
        pub use crate::gpu::timing::median;
    }
}

/// The capture and occlusion depth format.
pub mod height_depth {
    pub use crate::height_depth::{CAPTURE_CODES, CAPTURE_FORMAT, sky_depth_texture};
}

/// The one shape of a compute pass and the window's shared bindings.
pub mod pass {
    /// `pass::window_bindings`: what snowpack's app, tools and tests use of it.
    pub mod window_bindings {
        pub use crate::pass::window_bindings::{WindowAccess, window_layout_entries};
    }
}

/// The tile store, its codec and disks, and the streamer.
pub mod persist {
    pub use crate::persist::{SnowClock, StoreError, TileData, TileKey, TileLookup, decode, encode};
    /// `persist::disk`: what snowpack's app, tools and tests use of it.
    pub mod disk {
        pub use crate::persist::disk::{DirEntry, Disk, DiskFile, DiskLock, OsDisk};
    }
}

/// snowpack's own renderer (the demo's and the headless runner's), its
/// parameters, and the ground drawn into a game's pass.
pub mod render {
    /// `render::ao`: what snowpack's app, tools and tests use of it.
    pub mod ao {
        pub use crate::render::ao::{AoParams, AoPass};
    }
    /// `render::environment`: what snowpack's app, tools and tests use of it.
    pub mod environment {
        pub use crate::render::environment::{
            CLAMP_LUMINANCE, DOWNSAMPLED_H, DOWNSAMPLED_W, ENVIRONMENT_MAX_H, ENVIRONMENT_MAX_W, EnvParams, EnvironmentPass, PREFILTERED_H, PREFILTERED_LEVELS,
            PREFILTERED_W, dir_equirect, equirect_dir,
        };
    }
    /// `render::frame`: what snowpack's app, tools and tests use of it.
    pub mod frame {
        pub use crate::render::frame::FrameUniforms;
    }
    /// `render::ground`: what snowpack's app, tools and tests use of it.
    pub mod ground {
        pub use crate::render::ground::{GroundParams, SnowSampling, snow_sampling_wgsl};
    }
    /// `render::params`: what snowpack's app, tools and tests use of it.
    pub mod params {
        pub use crate::render::params::sun_from_angles;
    }
    /// `render::shell`: what snowpack's app, tools and tests use of it.
    pub mod shell {
        pub use crate::render::shell::{DetailKind, ShellPatch};
        /// `render::shell::count`: what snowpack's app, tools and tests use of it.
        pub mod count {
            pub use crate::render::shell::count::{CountParams, PeelCountPass};
        }
        /// `render::shell::peel`: what snowpack's app, tools and tests use of it.
        pub mod peel {
            pub use crate::render::shell::peel::{PeelParams, ShellDrawParams};
        }
        /// `render::shell::tetrahedra`: what snowpack's app, tools and tests use of it.
        pub mod tetrahedra {
            pub use crate::render::shell::tetrahedra::{CORNERS_PER_TETRA, MAX_SHAPE_RATIO, ShellTetraPass, Tetra, TetraParams};
        }
        /// `render::shell::vertices`: what snowpack's app, tools and tests use of it.
        pub mod vertices {
            pub use crate::render::shell::vertices::{BaseVertex, ShellVertex, ShellVertexParams, ShellVertexPass, SnowSurface};
        }
    }
    /// `render::surface`: what snowpack's app, tools and tests use of it.
    pub mod surface {
        pub use crate::render::surface::{SurfaceUnpackPass, UnpackParams};
    }
}

/// Shared snow: mergeable tiles, their clock, the world identity, the wire
/// messages, peers and relays, and the window's gather and merge passes.
pub mod replicate {
    pub use crate::replicate::{CatchUp, Message, NO_STAMP, ShareClock, ShareError, SharedSnow, SharedTile, decode, encode, terrain_identity};
    /// `replicate::flags`: what snowpack's app, tools and tests use of it.
    pub mod flags {
        pub use crate::replicate::flags::ShareGrid;
    }
    /// `replicate::gather`: what snowpack's app, tools and tests use of it.
    pub mod gather {
        pub use crate::replicate::gather::{PACKED_PLANES, TileGatherParams, TileGatherPass, gpu_keys};
    }
    /// `replicate::merge`: what snowpack's app, tools and tests use of it.
    pub mod merge {
        pub use crate::replicate::merge::{FrameRecord, HISTORY_FRAMES, TileMergeParams, TileMergePass, carries_packed, pack_tiles};
    }
    /// `replicate::message`: what snowpack's app, tools and tests use of it.
    pub mod message {
        pub use crate::replicate::message::{MAX_DEFORMERS, MAX_KEYS, MIN_TILE_SIDE, encode_world};
    }
    /// `replicate::relay`: what snowpack's app, tools and tests use of it.
    pub mod relay {
        pub use crate::replicate::relay::MAX_INTEREST_TILES;
    }
    /// `replicate::tile`: what snowpack's app, tools and tests use of it.
    pub mod tile {
        pub use crate::replicate::tile::TexelCopy;
    }
    /// `replicate::world`: what snowpack's app, tools and tests use of it.
    pub mod world {
        pub use crate::replicate::world::{WorldSnow, WorldSnowfall, WorldTerrain};
    }
}

/// Every pass's composed WGSL, validated by naga at build time.
pub mod shaders {
    pub use crate::shaders::{
        ACTOR_DRAW, ALL, AO, ATLAS_SURFACE, CAPTURE_MESH, CAPTURE_SHAPES, CAPTURE_SPHERE, CAPTURE_WHEEL, DECAL, DISPLAY, ENV_DOWNSAMPLE, ENV_PREFILTER,
        EXCHANGE, GROUND, INCREMENT, OBJECT_DRAW, OCCLUSION, PEEL_COUNT, QUERY, SCATTER, SETTLE, SHELL_DRAW, SHELL_RESOLVE, SHELL_TETRAHEDRA, SHELL_VERTICES,
        SKINNING, SKY, SNOW_COAT, SNOW_SAMPLING, STAMP, SURFACE_UNPACK, TERRAIN_BAKE, TERRAIN_DRAW, TERRAIN_RESOLVE, TILE_GATHER, TILE_MERGE, TILE_RESTORE,
        TILE_SEAL, TILE_WEATHER, TONEMAP, UPDATE, WINDOW, WINDOW_GROUND,
    };
}

/// Skeletons, clips, feet and GPU skinning of characters.
pub mod skin {
    pub use crate::skin::{AnimationPlayer, Channel, Clip, Interpolation, Node, Property, Skeleton, Transform};
    /// `skin::coat`: what snowpack's app, tools and tests use of it.
    pub mod coat {
        pub use crate::skin::coat::{CoatGround, SnowCoatParams, SnowCoatPass};
    }
    /// `skin::feet`: what snowpack's app, tools and tests use of it.
    pub mod feet {
        pub use crate::skin::feet::{DEFAULT_FOOT_PATTERNS, Foot, FootTracker, FootstepEvent, attach_paws, find_feet, mean_feet_down, stride_speed};
    }
    /// `skin::sinking`: what snowpack's app, tools and tests use of it.
    pub mod sinking {
        pub use crate::skin::sinking::{FootLoad, WheelLoad};
    }
    /// `skin::skinning`: what snowpack's app, tools and tests use of it.
    pub mod skinning {
        pub use crate::skin::skinning::{SkinningParams, SkinningPass};
    }
}

/// [`crate::SnowDeformation`]'s modules: the orchestrator, its saved state
/// and sharing.
pub mod snow {
    /// `snow::inspect`: what snowpack's app, tools and tests use of it.
    pub mod inspect {
        pub use crate::snow::inspect::SnowInspect;
    }
    /// `snow::saved`: what snowpack's app, tools and tests use of it.
    pub mod saved {
        pub use crate::snow::saved::SavedWindow;
    }
}

/// Terrain sources and their evaluation.
pub mod terrain {
    pub use crate::terrain::{HEIGHTMAP_MAX_SIDE, draw_from_above, texel_ground};
}

/// The resident tiles around the window and their passes.
pub mod tiles {
    /// `tiles::exchange`: what snowpack's app, tools and tests use of it.
    pub mod exchange {
        pub use crate::tiles::exchange::{ExchangeParams, ExchangePass};
    }
    /// `tiles::restore`: what snowpack's app, tools and tests use of it.
    pub mod restore {
        pub use crate::tiles::restore::{RestoreEntry, RestoreParams, TileRestorePass};
    }
    /// `tiles::seal`: what snowpack's app, tools and tests use of it.
    pub mod seal {
        pub use crate::tiles::seal::{SealParams, TileSealPass};
    }
    /// `tiles::streaming`: what snowpack's app, tools and tests use of it.
    pub mod streaming {
        pub use crate::tiles::streaming::{PLANE_FALLEN, PLANE_SNOW, PLANES, TileGrid, plane_packed, plane_stamps, planes};
    }
    /// `tiles::weather`: what snowpack's app, tools and tests use of it.
    pub mod weather {
        pub use crate::tiles::weather::{TileWeatherPass, WeatherParams};
    }
}
