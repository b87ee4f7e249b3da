//! CPU references of every GPU pass, one file per WGSL file and named after
//! it (`shaders/X.wgsl` is twinned by `X.rs`; `shaders::tests` checks). They
//! mirror the shaders' arithmetic (same operations, same order) so tests can
//! compare the GPU's output with them on random inputs.

pub mod ao;
pub mod atlas_surface;
pub mod capture_mesh;
pub mod capture_shapes;
pub mod displace;
pub mod display;
pub mod env_downsample;
pub mod env_prefilter;
pub mod erosion;
pub mod exchange;
pub mod increment;
pub mod peel_count;
pub mod query;
pub mod scatter;
pub mod settle;
pub mod shell_tetrahedra;
pub mod shell_vertices;
pub mod skinning;
pub mod snow_coat;
pub mod snow_sampling;
pub mod stamp;
pub mod surface_unpack;
pub mod terrain_bake;
pub mod tile_gather;
pub mod tile_merge;
pub mod tile_restore;
pub mod tile_seal;
pub mod tile_weather;
pub mod update;
pub mod window;
