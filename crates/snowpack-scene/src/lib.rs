//! Scene files, procedural terrain and the sphere test bed for snowpack.
//!
//! [`Scene`] parses and validates a TOML scene (schema in `docs/scene.md`);
//! [`World`] moves its actors: still, kinematic, keyframed, and physics
//! spheres that bounce and slide on the terrain.

mod error;
mod fields;
pub mod gltf_file;
mod read;
mod save;
mod scene;
mod vehicle;
mod world;

pub use error::SceneError;
pub use save::SaveScene;
pub use scene::{
    ActorSpec, BUILTIN_FOX, BUILTIN_FOX_GLB, BUILTIN_SKY_HDR, CameraSpec, DEFAULT_SCENE, EnvironmentSpec, Gait, GltfActor, Motion, ObjectSpec, Placement,
    RenderSpec, Scene, ShapeSpec, SimSpec, SnowfallSpec, SpawnSpec, StoreKeep, StoreSpec, WindowSpec,
};
pub use snowpack::{RimStyle, Technique};
pub use vehicle::VehicleSpec;
pub use world::{CharacterPose, FRICTION, GRAVITY, RESTITUTION, World};
