//! The scene file: TOML with the schema of DESIGN.md, documented key by key
//! in `docs/scene.md`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Quat, Vec3};
use snowpack::ShellSettings;
use snowpack::low_level::render::params::sun_from_angles;
use snowpack::low_level::render::shell::DetailKind;
use snowpack::{DebugView, LightParams, Material, MaterialPreset};
use snowpack::{EnvironmentMap, RenderParams};
use snowpack::{HeightmapTerrain, NoiseTerrain, RimStyle, SnowParams, Technique, TerrainMesh, TerrainSource};

use crate::error::SceneError;
use crate::fields::Fields;
use crate::gltf_file::{GltfFile, SkinnedModel};
use snowpack::low_level::HeightmapTerrainExt;
use snowpack::low_level::RimStyleExt;
use snowpack::low_level::SnowParamsExt;
use snowpack::low_level::SnowfallExt;
use snowpack::low_level::TechniqueExt;
use snowpack::low_level::TerrainMeshExt;
use snowpack::low_level::skin::feet::{DEFAULT_FOOT_PATTERNS, Foot, attach_paws, find_feet, stride_speed};
use snowpack::low_level::skin::sinking::FootLoad;

/// Where the deformation window is centred.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum WindowSpec {
    /// A fixed centre (x, z) in metres.
    Center([f32; 2]),
    /// The camera's position.
    FollowCamera,
    /// The actor with this index (order of `[[actor]]` tables).
    FollowActor(usize),
}

/// The shape of an actor or object.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum ShapeSpec {
    /// A sphere of this radius (m).
    Sphere {
        /// Radius (m).
        radius_m: f32,
    },
    /// A box of this size (m) and orientation.
    Box {
        /// Full size along the box's axes (m).
        size_m: Vec3,
        /// Orientation (from `rotation_deg`, Euler XYZ).
        rotation: Quat,
    },
    /// A plough's blade or a crate's face (`snowpack::Deformer::blade`):
    /// `position` is the middle of its lower edge; it faces its direction
    /// of travel, turned by `angle_deg`.
    Blade {
        /// Width along the edge (m).
        width_m: f32,
        /// Height (m).
        height_m: f32,
        /// Turn from square to the travel (degrees): the pushed snow slides
        /// off the trailing end.
        angle_deg: f32,
    },
    /// A contact point for the points technique (`position` is the foot's lowest point).
    Point {
        /// Footprint curvature (1/m): `h = foot + d^2 * scale_per_m`.
        scale_per_m: f32,
    },
    /// A skinned, animated glTF character (its root at `position`, facing its direction of travel).
    Gltf(GltfActor),
}

/// A `kind = "gltf"` actor: the model, the clip it plays and how.
#[derive(Clone, PartialEq)]
pub struct GltfActor {
    /// The file it came from.
    pub file: PathBuf,
    /// Mesh, skeleton and clips.
    pub model: Arc<SkinnedModel>,
    /// Index of the clip played (`animation`).
    pub clip: usize,
    /// Uniform scale from file units to metres (`scale`).
    pub scale: f32,
    /// Playback speed of the clip (`animation_speed`).
    pub speed: f32,
    /// The feet, found by `feet` name patterns (footstep events).
    pub feet: Vec<Foot>,
    /// Locomotion clips chosen by travel speed (`gaits`); empty: `clip` always.
    pub gaits: Vec<Gait>,
    /// Cross-fade between clips (s) (`fade_s`).
    pub fade_s: f32,
    /// Where the root is put each frame (`placement`).
    pub placement: Placement,
    /// Weight and sole area for the sinking load model (`mass_kg`, `foot_area_m2`).
    pub load: FootLoad,
    /// How it gathers and loses snow on its body (the `coat_*` keys).
    pub coat: snowpack::CoatSettings,
}

/// A locomotion clip and the speed it is made for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gait {
    /// Index of the clip.
    pub clip: usize,
    /// Travel speed (m/s, at the actor's scale) at which its planted feet do
    /// not slide; it plays at `speed / stride_m_per_s`.
    pub stride_m_per_s: f32,
}

/// Where a character's root is put each frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Placement {
    /// At the path's (or position's) height, as written.
    #[default]
    Path,
    /// Feet on the terrain under the snow (the path's y is an offset).
    Ground,
    /// Feet on the snow, sunk to the depth the load model gives (the path's y is an offset).
    Snow,
}

impl Placement {
    /// Every placement in scene-file spelling.
    pub const ALL: [(Self, &'static str); 3] = [(Self::Path, "path"), (Self::Ground, "ground"), (Self::Snow, "snow")];

    /// The scene-file spelling.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        Self::ALL.iter().find(|(p, _)| *p == self).map_or("path", |(_, s)| s)
    }
}

impl GltfActor {
    /// A character from a loaded model with the defaults of a scene file:
    /// clip 0, scale 1, feet found by [`DEFAULT_FOOT_PATTERNS`], no gaits,
    /// placed at the path's height, a fox's load, the default snow coat.
    /// `None` without any foot.
    #[must_use]
    pub fn new(file: PathBuf, model: Arc<SkinnedModel>) -> Option<Self> {
        let mut feet = find_feet(&model.skeleton, &model.clips, &DEFAULT_FOOT_PATTERNS);
        attach_paws(&mut feet, &model.skeleton, &model.clips, &model.mesh);
        (!feet.is_empty()).then(|| Self {
            file,
            model,
            clip: 0,
            scale: 1.0,
            speed: 1.0,
            feet,
            gaits: Vec::new(),
            fade_s: 0.25,
            placement: Placement::Path,
            load: FootLoad::default(),
            coat: snowpack::CoatSettings::default(),
        })
    }

    /// Uses the clips `names` as gaits, each with its stride speed measured at
    /// the current scale; the error names the first clip that is missing.
    pub fn set_gaits(&mut self, names: &[String]) -> Result<(), String> {
        let mut gaits = Vec::with_capacity(names.len());
        for name in names {
            let clip = self.model.clip(name).ok_or_else(|| {
                let all: Vec<&str> = self.model.clips.iter().map(|c| c.name.as_str()).collect();
                format!("{name:?} is not an animation of {} (it has {})", self.file.display(), all.join(", "))
            })?;
            let stride = stride_speed(&self.model.skeleton, &self.model.clips[clip], &self.feet) * self.scale;
            if stride.is_nan() || stride <= 1e-3 {
                return Err(format!("{name:?} does not move its feet backwards while they are down, so it is not a gait"));
            }
            gaits.push(Gait { clip, stride_m_per_s: stride });
        }
        gaits.sort_by(|a, b| a.stride_m_per_s.total_cmp(&b.stride_m_per_s));
        self.gaits = gaits;
        Ok(())
    }
}

impl std::fmt::Debug for GltfActor {
    // The model is large; say what it is instead of printing it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "glTF {} ({} vertices, {} joints, feet {:?}), clip {:?} at speed {}, scale {}",
            self.file.display(),
            self.model.mesh.positions.len(),
            self.model.skeleton.joints.len(),
            self.feet.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(),
            self.model.clips.get(self.clip).map_or("", |c| c.name.as_str()),
            self.speed,
            self.scale
        )?;
        for g in &self.gaits {
            write!(f, ", gait {:?} at {:.2} m/s", self.model.clips.get(g.clip).map_or("", |c| c.name.as_str()), g.stride_m_per_s)?;
        }
        write!(f, ", placed on the {}", self.placement.as_str())
    }
}

/// How an actor moves.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Motion {
    /// Fixed position plus constant velocity (m/s).
    Kinematic {
        /// Position at t = 0 (m).
        position: Vec3,
        /// Velocity (m/s).
        velocity: Vec3,
    },
    /// Keyframes `[x, y, z, t]`, linear in between, held at the ends.
    Path(Vec<[f32; 4]>),
    /// Test-bed physics: falls, bounces and slides on the terrain.
    Physics {
        /// Position at t = 0 (m).
        position: Vec3,
        /// Velocity at t = 0 (m/s).
        velocity: Vec3,
    },
}

/// One `[[actor]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct ActorSpec {
    /// Its shape.
    pub shape: ShapeSpec,
    /// Its motion.
    pub motion: Motion,
}

/// One `[[spawn]]`: random physics spheres (Wasmut's test bed).
#[derive(Clone, Debug, PartialEq)]
pub struct SpawnSpec {
    /// How many.
    pub count: u32,
    /// Radius of each (m).
    pub radius_m: f32,
    /// Seed of their positions and velocities.
    pub seed: u64,
}

/// One `[[object]]` that snow settles on.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectSpec {
    /// Unique name.
    pub name: String,
    /// Shape: box or sphere (`size_m.x / 2` is the radius).
    pub kind: String,
    /// Centre (m).
    pub position: Vec3,
    /// Size (m).
    pub size_m: Vec3,
    /// Euler XYZ rotation (degrees).
    pub rotation_deg: Vec3,
    /// Whether its accumulation is dilated (off for thin, holey objects).
    pub dilate: bool,
    /// The triangle mesh of a `gltf` object (its file, `scale` applied).
    pub mesh: Option<Arc<snowpack::low_level::accumulate::ObjectMesh>>,
    /// Constant velocity (m/s); its snow goes with it.
    pub velocity: Vec3,
    /// Constant turn about its own x, y and z axes (degrees per second).
    pub spin_deg_per_s: Vec3,
}

impl ObjectSpec {
    /// Where the object is and how it is turned `t_s` seconds into the run.
    #[must_use]
    pub fn pose_at(&self, t_s: f32) -> (Vec3, glam::Quat) {
        let r = self.rotation_deg * (std::f32::consts::PI / 180.0);
        let spin = self.spin_deg_per_s * (std::f32::consts::PI / 180.0) * t_s;
        let start = glam::Quat::from_euler(glam::EulerRot::XYZ, r.x, r.y, r.z);
        // The spin is about the object's own axes, after its starting rotation.
        (self.position + self.velocity * t_s, start * glam::Quat::from_scaled_axis(spin))
    }

    /// The library's description of this object.
    #[must_use]
    pub fn object(&self) -> snowpack::SnowObject {
        use snowpack::ObjectShape;
        let r = self.rotation_deg * (std::f32::consts::PI / 180.0);
        snowpack::SnowObject {
            name: self.name.clone(),
            shape: match (&self.mesh, self.kind.as_str()) {
                (Some(mesh), _) => ObjectShape::Mesh(Arc::clone(mesh)),
                (None, "sphere") => ObjectShape::Sphere { radius_m: 0.5 * self.size_m.x },
                (None, _) => ObjectShape::Box { size_m: self.size_m },
            },
            position: self.position,
            rotation: glam::Quat::from_euler(glam::EulerRot::XYZ, r.x, r.y, r.z),
            dilate: self.dilate,
        }
    }
}

/// `[snowfall]`: the library's snowfall parameters.
pub type SnowfallSpec = snowpack::Snowfall;

/// `[sim]`.
#[derive(Clone, Debug, PartialEq)]
pub struct SimSpec {
    /// Frames a headless run simulates.
    pub frames: u32,
    /// Seconds per frame.
    pub dt_s: f32,
}

/// `[camera]`.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraSpec {
    /// Eye position (m).
    pub position: Vec3,
    /// Point looked at (m).
    pub target: Vec3,
    /// Vertical field of view (degrees).
    pub fov_deg: f32,
}

/// Where the sky light comes from (`[light] environment`).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum EnvironmentSpec {
    /// The built-in HDR sky (`assets/spiaggia_di_mondello_1k.hdr`).
    Builtin,
    /// A procedural clear sky around the sun.
    Procedural,
    /// An equirectangular Radiance `.hdr` file, decoded.
    File(PathBuf, Arc<EnvironmentMap>),
}

/// The fox every build carries (`file = "builtin:fox"`): `assets/Fox.glb`,
/// model by PixelMannen (CC0), rigging and animation by tomkranis (CC-BY 4.0).
pub const BUILTIN_FOX_GLB: &[u8] = include_bytes!("../assets/Fox.glb");
/// The `file` value that names [`BUILTIN_FOX_GLB`].
pub const BUILTIN_FOX: &str = "builtin:fox";

/// The built-in sky: Poly Haven's "Spiaggia di Mondello" (CC0), 1024x512 RGBE.
pub const BUILTIN_SKY_HDR: &[u8] = include_bytes!("../assets/spiaggia_di_mondello_1k.hdr");

/// `[light]` and `[render]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSpec {
    /// Renderer parameters (material, light, debug view, distances).
    pub params: RenderParams,
    /// The environment.
    pub environment: EnvironmentSpec,
}

impl RenderSpec {
    /// The environment map to light with.
    #[must_use]
    pub fn environment_map(&self) -> Arc<EnvironmentMap> {
        match &self.environment {
            EnvironmentSpec::Builtin => Arc::new(EnvironmentMap::from_hdr(BUILTIN_SKY_HDR).unwrap_or_else(|_| {
                // The embedded file is checked by a test; never reached.
                EnvironmentMap::procedural(self.sun_or_default())
            })),
            EnvironmentSpec::Procedural => Arc::new(EnvironmentMap::procedural(self.sun_or_default())),
            EnvironmentSpec::File(_, map) => Arc::clone(map),
        }
    }

    fn sun_or_default(&self) -> Vec3 {
        self.params.light.sun_direction.unwrap_or_else(|| sun_from_angles(35.0, 135.0))
    }
}

/// Where `[store]` keeps the snow of tiles the window has left.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum StoreKeep {
    /// In memory, then compressed on disk (`keep = "disk"`, the default of a
    /// `[store]` table): trails survive the run and a save resumes it.
    #[default]
    Disk,
    /// In memory only (`keep = "memory"`, what a scene without `[store]`
    /// does): trails stay for the run, within `memory_mb`.
    Memory,
    /// Not at all (`keep = "off"`): texels leaving the window are forgotten.
    Off,
}

impl StoreKeep {
    /// The name in scene files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Disk => "disk",
            Self::Memory => "memory",
            Self::Off => "off",
        }
    }
}

/// `[store]`: where trails are kept when the window moves on (open worlds).
/// A scene without it keeps them in memory ([`snowpack::SnowParams::tile_memory_bytes`]).
#[derive(Clone, Debug, PartialEq)]
pub struct StoreSpec {
    /// Disk (the default), memory only, or off.
    pub keep: StoreKeep,
    /// Store folder (disk only); relative paths resolve against the scene's
    /// folder. `None`: `store/` inside the run's output folder. A save found
    /// there (window position, clock) is loaded when the run starts.
    pub path: Option<PathBuf>,
    /// Tile side (texels): a power of two in 16..=256 dividing the resolution.
    pub tile_texels: u32,
    /// Memory cache of decoded tiles (MiB).
    pub memory_mb: f32,
    /// Disk budget (MiB); 0 = unlimited. The least recently touched tiles go first.
    pub disk_mb: f32,
    /// Save the whole state into the store at the end of a run (disk only).
    pub save: bool,
}

impl Default for StoreSpec {
    fn default() -> Self {
        Self { keep: StoreKeep::Disk, path: None, tile_texels: 64, memory_mb: 64.0, disk_mb: 0.0, save: true }
    }
}

/// A parsed, validated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The file it came from (relative paths in it resolve against its folder).
    pub path: PathBuf,
    /// `[snow]` (technique, footprint range and rim style included).
    pub snow: SnowParams,
    /// `[terrain]`, loaded.
    pub terrain: TerrainSource,
    /// `[window]`.
    pub window: WindowSpec,
    /// `[[actor]]`.
    pub actors: Vec<ActorSpec>,
    /// `[[vehicle]]`.
    pub vehicles: Vec<crate::vehicle::VehicleSpec>,
    /// `[[spawn]]`.
    pub spawns: Vec<SpawnSpec>,
    /// `[[object]]`.
    pub objects: Vec<ObjectSpec>,
    /// `[snowfall]`, if present.
    pub snowfall: Option<SnowfallSpec>,
    /// `[store]`, if present.
    pub store: Option<StoreSpec>,
    /// `[sim]`.
    pub sim: SimSpec,
    /// `[camera]`.
    pub camera: CameraSpec,
    /// `[light]` and `[render]`.
    pub render: RenderSpec,
    /// The parsed TOML it came from (kept so a save rewrites only what changed).
    pub source: toml::Table,
}

/// The scene `snowpack` runs with no arguments.
pub const DEFAULT_SCENE: &str = include_str!("../../../scenes/default.toml");

fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |p| p + 1) + 1;
    (line, col)
}

/// `[snow]`: the window's parameters (`tile_memory_bytes` and `snowfall` are set from `[store]` and `[snowfall]` later).
fn parse_snow(root: &mut Fields<'_>) -> Result<SnowParams, SceneError> {
    let defaults = SnowParams::default();
    Ok(match root.table("snow")? {
        None => defaults,
        Some(mut t) => {
            let technique = t.string_opt("technique")?.map_or(Ok(Technique::Depth), |s| s.parse::<Technique>().map_err(|why| t.err("technique", why)))?;
            let rim = t.string_opt("rim")?.map_or(Ok(RimStyle::Rounded), |s| s.parse::<RimStyle>().map_err(|why| t.err("rim", why)))?;
            let snow = SnowParams {
                extent_m: t.positive("extent_m", defaults.extent_m, " of metres")?,
                resolution: t.u32_in("resolution", defaults.resolution, 0..=u64::from(u32::MAX))?,
                depth_m: t.non_negative("depth_m", defaults.depth_m, " of metres")?,
                refill_m_per_s: t.non_negative("refill_m_per_s", defaults.refill_m_per_s, " (m/s)")?,
                elevation: t.non_negative("elevation", defaults.elevation, "")?,
                blur: t.bool("blur", defaults.blur)?,
                technique,
                range_texels: t.u32_in("range_texels", 64, 32..=128)?,
                rim,
                hardness_kpa: t.positive("hardness_kpa", defaults.hardness_kpa, " of kPa")?,
                density_kg_m3: t.positive("density_kg_m3", defaults.density_kg_m3, " of kg/m³")?,
                max_density_kg_m3: t.positive("max_density_kg_m3", defaults.max_density_kg_m3, " of kg/m³")?,
                // Validated with the rest below (an angle in (0, 90) degrees).
                repose_deg: t.f32_opt("repose_deg")?,
                displace: t.bool("displace", defaults.displace)?,
                snowfall: None,
                tile_memory_bytes: defaults.tile_memory_bytes,
                teleport_m: t.non_negative("teleport_m", defaults.teleport_m, " of metres")?,
                store_ground: t.bool("store_ground", defaults.store_ground)?,
            };
            if let Err(snowpack::low_level::error::SnowError::InvalidParameter { field, why }) = snow.validate() {
                return Err(t.err(field, why));
            }
            t.finish()?;
            snow
        }
    })
}

/// `[terrain]`: flat unless it says otherwise; files are read relative to `base_dir`.
fn parse_terrain(root: &mut Fields<'_>, base_dir: &Path, snow: &SnowParams) -> Result<TerrainSource, SceneError> {
    Ok(match root.table("terrain")? {
        None => TerrainSource::Flat { height_m: 0.0 },
        Some(mut t) => {
            let kind = t.choice("kind", "flat", &["flat", "noise", "heightmap", "mesh"])?;
            let terrain = match kind.as_str() {
                "flat" => TerrainSource::Flat { height_m: t.f32("height_m", 0.0)? },
                "noise" => TerrainSource::Noise(NoiseTerrain {
                    seed: t.u32_in("seed", 1, 0..=u64::from(u32::MAX))?,
                    base_m: t.f32("height_m", 0.0)?,
                    amplitude_m: t.non_negative("amplitude_m", 4.0, " of metres")?,
                    wavelength_m: t.positive("wavelength_m", 32.0, " of metres")?,
                }),
                "heightmap" => load_heightmap(&mut t, base_dir, snow.extent_m)?,
                _ => load_terrain_mesh(&mut t, base_dir, snow.texel_m())?,
            };
            t.finish()?;
            terrain
        }
    })
}

/// `[[actor]]` tables, in order.
fn parse_actors(root: &mut Fields<'_>, base_dir: &Path) -> Result<Vec<ActorSpec>, SceneError> {
    let mut actors = Vec::new();
    for mut a in root.tables("actor")? {
        actors.push(parse_actor(&mut a, base_dir)?);
        a.finish()?;
    }
    Ok(actors)
}

/// `[window]`: where the window sits or what it follows, checked against the texel range.
fn parse_window(root: &mut Fields<'_>, path: &Path, snow: &SnowParams, actors: &[ActorSpec]) -> Result<WindowSpec, SceneError> {
    Ok(match root.table("window")? {
        None => WindowSpec::Center([0.0, 0.0]),
        Some(mut w) => {
            let center = w.vec2_opt("center")?;
            let follow = w.string_opt("follow")?;
            let spec = match (center, follow) {
                (Some(_), Some(_)) => return Err(w.err("follow", "give either center or follow, not both")),
                (Some(c), None) => WindowSpec::Center(c),
                (None, None) => WindowSpec::Center([0.0, 0.0]),
                (None, Some(f)) if f == "camera" => WindowSpec::FollowCamera,
                (None, Some(f)) => {
                    let index = f
                        .strip_prefix("actor:")
                        .and_then(|n| n.parse::<usize>().ok())
                        .ok_or_else(|| w.err("follow", format!("{f:?} is neither \"camera\" nor \"actor:N\"")))?;
                    if index >= actors.len() {
                        return Err(w.err("follow", format!("actor:{index} does not exist (the scene has {} [[actor]] tables)", actors.len())));
                    }
                    WindowSpec::FollowActor(index)
                }
            };
            match &spec {
                WindowSpec::Center(c) => {
                    if let Some(why) = texels_overflow(*c, snow) {
                        return Err(w.err("center", why));
                    }
                }
                WindowSpec::FollowActor(index) => {
                    let (key, points): (&str, Vec<[f32; 2]>) = match &actors[*index].motion {
                        Motion::Kinematic { position, .. } | Motion::Physics { position, .. } => ("position", vec![[position.x, position.z]]),
                        Motion::Path(keys) => ("path", keys.iter().map(|k| [k[0], k[2]]).collect()),
                    };
                    if let Some(why) = points.into_iter().find_map(|p| texels_overflow(p, snow)) {
                        return Err(SceneError::new(path, format!("[[actor]][{index}].{key}"), format!("the window follows this actor: {why}")));
                    }
                }
                WindowSpec::FollowCamera => {}
            }
            w.finish()?;
            spec
        }
    })
}

/// `[[vehicle]]` tables, in order.
fn parse_vehicles(root: &mut Fields<'_>) -> Result<Vec<crate::vehicle::VehicleSpec>, SceneError> {
    let mut vehicles = Vec::new();
    for mut v in root.tables("vehicle")? {
        vehicles.push(crate::vehicle::VehicleSpec::parse(&mut v)?);
        v.finish()?;
    }
    Ok(vehicles)
}

/// `[[spawn]]` tables, in order.
fn parse_spawns(root: &mut Fields<'_>) -> Result<Vec<SpawnSpec>, SceneError> {
    let mut spawns = Vec::new();
    for mut s in root.tables("spawn")? {
        s.choice("kind", "sphere", &["sphere"])?;
        spawns.push(SpawnSpec {
            count: s.u32_in("count", 256, 0..=100_000)?,
            radius_m: s.positive("radius_m", 1.0, " of metres")?,
            seed: u64::from(s.u32_in("seed", 7, 0..=u64::from(u32::MAX))?),
        });
        s.finish()?;
    }
    Ok(spawns)
}

/// `[[object]]` tables, in order; names are unique.
fn parse_objects(root: &mut Fields<'_>, base_dir: &Path) -> Result<Vec<ObjectSpec>, SceneError> {
    let mut objects: Vec<ObjectSpec> = Vec::new();
    for mut o in root.tables("object")? {
        let name = o.string_opt("name")?.ok_or_else(|| o.err("name", "every [[object]] needs a name"))?;
        if objects.iter().any(|x| x.name == name) {
            return Err(o.err("name", format!("{name:?} is used by another [[object]]")));
        }
        let kind = o.choice("kind", "box", &["box", "sphere", "gltf"])?;
        let mesh = if kind == "gltf" {
            let rel = o.string_opt("file")?.ok_or_else(|| o.err("file", "a gltf object needs a file (.glb or .gltf)"))?;
            let scale = o.positive("scale", 1.0, "")?;
            let full = base_dir.join(&rel);
            // `open` names the file in its errors; what it is used for does not.
            let gltf = GltfFile::open(&full).map_err(|why| o.err("file", why))?;
            let mesh = gltf.object_mesh(scale).map_err(|why| o.err("file", format!("{}: {why}", full.display())))?;
            Some(Arc::new(mesh))
        } else {
            None
        };
        let position = o.vec3("position", Vec3::ZERO)?;
        let size_m = o.vec3("size_m", Vec3::ONE)?;
        if size_m.min_element() <= 0.0 {
            return Err(o.err("size_m", format!("every side must be positive, got {size_m}")));
        }
        let rotation_deg = o.vec3("rotation_deg", Vec3::ZERO)?;
        let dilate = o.bool("dilate", true)?;
        let velocity = o.vec3("velocity", Vec3::ZERO)?;
        let spin_deg_per_s = o.vec3("spin_deg_per_s", Vec3::ZERO)?;
        o.finish()?;
        objects.push(ObjectSpec { name, kind, position, size_m, rotation_deg, dilate, mesh, velocity, spin_deg_per_s });
    }
    Ok(objects)
}

/// `[snowfall]`, when the scene has it.
fn parse_snowfall(root: &mut Fields<'_>) -> Result<Option<SnowfallSpec>, SceneError> {
    Ok(match root.table("snowfall")? {
        None => None,
        Some(mut s) => {
            let d = SnowfallSpec::default();
            let direction = s.vec3("direction", d.direction)?;
            if direction.length() < 1e-6 {
                return Err(s.err("direction", "must not be the zero vector"));
            }
            let spec = SnowfallSpec {
                direction: direction.normalize(),
                rate_m_per_s: s.non_negative("rate_m_per_s", d.rate_m_per_s, " (m/s)")?,
                flutter_deg: s.non_negative("flutter_deg", d.flutter_deg, " degrees")?,
                noise: s.non_negative("noise", d.noise, "")?,
                repose_deg: s.non_negative("repose_deg", d.repose_deg, " degrees")?,
                falloff_per_s: s.non_negative("falloff_per_s", d.falloff_per_s, " (1/s)")?,
                max_m: s.positive("max_m", d.max_m, " of metres")?,
                atlas_resolution: s.u32_in("atlas_resolution", d.atlas_resolution, 16..=8192)?,
            };
            if let Err(snowpack::low_level::error::SnowError::InvalidParameter { field, why }) = spec.validate() {
                return Err(s.err(field, why));
            }
            s.finish()?;
            Some(spec)
        }
    })
}

/// `[store]`, when the scene has it: how trails are kept, checked against `[snow]`'s tile grid.
fn parse_store(root: &mut Fields<'_>, base_dir: &Path, snow: &SnowParams) -> Result<Option<StoreSpec>, SceneError> {
    Ok(match root.table("store")? {
        None => None,
        Some(mut t) => {
            let d = StoreSpec::default();
            let keep = match t.choice("keep", "disk", &["disk", "memory", "off"])?.as_str() {
                "memory" => StoreKeep::Memory,
                "off" => StoreKeep::Off,
                _ => StoreKeep::Disk,
            };
            // Keys that mean nothing for this kind of keeping are mistakes, not defaults.
            let only_disk: &[&str] = &["path", "disk_mb", "save"];
            let unused: &[&str] = match keep {
                StoreKeep::Disk => &[],
                StoreKeep::Memory => only_disk,
                StoreKeep::Off => &["path", "disk_mb", "save", "tile_texels", "memory_mb"],
            };
            if let Some(key) = unused.iter().find(|k| t.has(k)) {
                return Err(t.err(key.as_ref(), format!("has no effect with keep = \"{}\"", keep.as_str())));
            }
            let tile_default = if keep == StoreKeep::Disk { d.tile_texels } else { snowpack::low_level::deform::params::default_tile_texels(snow.resolution) };
            let spec = StoreSpec {
                keep,
                path: t.string_opt("path")?.map(|p| base_dir.join(p)),
                tile_texels: t.u32_in("tile_texels", tile_default, 16..=256)?,
                memory_mb: t.non_negative("memory_mb", d.memory_mb, " of MiB")?,
                disk_mb: t.non_negative("disk_mb", d.disk_mb, " of MiB")?,
                save: t.bool("save", keep == StoreKeep::Disk && d.save)?,
            };
            if let Err(snowpack::low_level::error::SnowError::InvalidParameter { why, .. }) =
                snowpack::low_level::tiles::streaming::TileGrid::new(snow.resolution, spec.tile_texels)
            {
                return Err(t.err("tile_texels", why));
            }
            t.finish()?;
            Some(spec)
        }
    })
}

/// `[sim]`: frames and time step.
fn parse_sim(root: &mut Fields<'_>) -> Result<SimSpec, SceneError> {
    Ok(match root.table("sim")? {
        None => SimSpec { frames: 120, dt_s: 1.0 / 60.0 },
        Some(mut s) => {
            let sim = SimSpec { frames: s.u32_in("frames", 120, 1..=1_000_000)?, dt_s: s.positive("dt_s", 1.0 / 60.0, " of seconds")? };
            if sim.dt_s > 1.0 {
                return Err(s.err("dt_s", format!("{} s per frame is more than 1 s", sim.dt_s)));
            }
            s.finish()?;
            sim
        }
    })
}

/// `[camera]`: position, target and field of view.
fn parse_camera(root: &mut Fields<'_>) -> Result<CameraSpec, SceneError> {
    Ok(match root.table("camera")? {
        None => CameraSpec { position: Vec3::new(0.0, 10.0, -20.0), target: Vec3::ZERO, fov_deg: 60.0 },
        Some(mut c) => {
            let cam = CameraSpec {
                position: c.vec3("position", Vec3::new(0.0, 10.0, -20.0))?,
                target: c.vec3("target", Vec3::ZERO)?,
                fov_deg: c.positive("fov_deg", 60.0, " degrees")?,
            };
            if cam.fov_deg >= 180.0 {
                return Err(c.err("fov_deg", format!("{} must be below 180 degrees", cam.fov_deg)));
            }
            c.finish()?;
            cam
        }
    })
}

fn rotation_from_deg(deg: Vec3) -> Quat {
    Quat::from_euler(glam::EulerRot::XYZ, deg.x.to_radians(), deg.y.to_radians(), deg.z.to_radians())
}

impl Scene {
    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        let bytes =
            crate::read::bounded(path, crate::read::MAX_SCENE_BYTES).map_err(|why| SceneError::new(path, "", format!("cannot read the scene file: {why}")))?;
        let text = String::from_utf8(bytes).map_err(|e| SceneError::new(path, "", format!("the scene file is not UTF-8 text: {e}")))?;
        Self::parse(&text, path)
    }

    /// The built-in default scene.
    pub fn default_scene() -> Result<Self, SceneError> {
        Self::parse(DEFAULT_SCENE, Path::new("scenes/default.toml"))
    }

    /// Parses and validates scene text; `path` names it in errors and anchors relative files.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SceneError> {
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            let at = e.span().map(|s| line_col(text, s.start));
            let place = at.map_or(String::new(), |(l, c)| format!(" at line {l}, column {c}"));
            SceneError::new(path, "", format!("malformed TOML{place}: {}", e.message()))
        })?;
        let source = table.clone();
        let mut root = Fields::new(path, "", table);
        let base_dir = path.parent().map(Path::to_owned).unwrap_or_default();

        let snow = parse_snow(&mut root)?;
        let terrain = parse_terrain(&mut root, &base_dir, &snow)?;
        let actors = parse_actors(&mut root, &base_dir)?;
        let window = parse_window(&mut root, path, &snow, &actors)?;
        let vehicles = parse_vehicles(&mut root)?;
        let spawns = parse_spawns(&mut root)?;
        let objects = parse_objects(&mut root, &base_dir)?;
        let snowfall = parse_snowfall(&mut root)?;
        let store = parse_store(&mut root, &base_dir, &snow)?;
        let sim = parse_sim(&mut root)?;
        let camera = parse_camera(&mut root)?;
        if window == WindowSpec::FollowCamera
            && let Some(why) = texels_overflow([camera.position.x, camera.position.z], &snow)
        {
            return Err(SceneError::new(path, "[camera].position", format!("the window follows the camera: {why}")));
        }
        let render = parse_render(&mut root, &base_dir)?;
        root.finish()?;
        // The window carries the snowfall (its ground gains snow).
        // Trails: in memory unless `[store]` says otherwise (a disk store or
        // `keep = "memory"` is attached by the runner; `off` forgets).
        let tile_memory_bytes = match &store {
            None => snow.tile_memory_bytes,
            Some(spec) if spec.keep == StoreKeep::Off => None,
            Some(spec) => Some((f64::from(spec.memory_mb) * 1024.0 * 1024.0) as usize),
        };
        let snow = SnowParams { snowfall: snowfall.clone(), tile_memory_bytes, ..snow };
        Ok(Self { path: path.to_owned(), snow, terrain, window, actors, vehicles, spawns, objects, snowfall, store, sim, camera, render, source })
    }

    /// Everything that was understood, for `snowpack check-scene`.
    #[must_use]
    pub fn describe(&self) -> String {
        let mut s = String::new();
        let p = &self.snow;
        let _ = writeln!(s, "scene {}", self.path.display());
        let _ = writeln!(
            s,
            "snow: extent {} m, resolution {}² ({:.4} m/texel), depth {} m, refill {} m/s, elevation {}, blur {}, technique {}, range {} texels, rim {}, hardness {} kPa, density {} kg/m³ packing to {} kg/m³, angle of repose {}, beyond it {}, teleport {} m",
            p.extent_m,
            p.resolution,
            p.texel_m(),
            p.depth_m,
            p.refill_m_per_s,
            p.elevation,
            p.blur,
            p.technique.as_str(),
            p.range_texels,
            p.rim.as_str(),
            p.hardness_kpa,
            p.density_kg_m3,
            p.max_density_kg_m3,
            p.repose_deg.map_or_else(|| "none".to_owned(), |r| format!("{r}°")),
            if p.displace { "displaced into berms" } else { "counted and gone" },
            p.teleport_m
        );
        let terrain = self.describe_terrain();
        let _ = writeln!(s, "terrain: {terrain}");
        let _ = writeln!(s, "window: {:?}", self.window);
        let _ = writeln!(s, "actors: {}", self.actors.len());
        for (k, a) in self.actors.iter().enumerate() {
            let _ = writeln!(s, "  [{k}] {:?}, {:?}", a.shape, a.motion);
        }
        self.describe_things(&mut s);
        if let Some(f) = &self.snowfall {
            let _ = writeln!(
                s,
                "snowfall: direction {}, {} m/s, flutter {} deg, noise {}, repose {} deg, falloff {}/s, at most {} m, atlas {}²",
                f.direction, f.rate_m_per_s, f.flutter_deg, f.noise, f.repose_deg, f.falloff_per_s, f.max_m, f.atlas_resolution
            );
        }
        self.describe_store(&mut s);
        let _ = writeln!(s, "sim: {} frames of {} s", self.sim.frames, self.sim.dt_s);
        let _ = write!(s, "camera: at {} looking at {}, fov {} deg", self.camera.position, self.camera.target, self.camera.fov_deg);
        s
    }

    /// The terrain line of [`Self::describe`].
    fn describe_terrain(&self) -> String {
        match &self.terrain {
            TerrainSource::Flat { height_m } => format!("flat at {height_m} m"),
            TerrainSource::Noise(n) => format!("noise, seed {}, height {} m, amplitude {} m, wavelength {} m", n.seed, n.base_m, n.amplitude_m, n.wavelength_m),
            TerrainSource::Heightmap(h) => {
                format!(
                    "heightmap {}x{} px over {:?} m centred at {:?}, heights {:?} m",
                    h.width(),
                    h.height(),
                    h.size_m(),
                    h.center_m(),
                    self.terrain.height_bounds()
                )
            }
            TerrainSource::Mesh(m) => format!(
                "mesh of {} triangles drawn into {}x{} texels over {:?} m centred at {:?}, heights {:?} m",
                m.triangles().len(),
                m.grid().width(),
                m.grid().height(),
                m.grid().size_m(),
                m.grid().center_m(),
                self.terrain.height_bounds()
            ),
            // A terrain kind added to the library after this describer.
            other => format!("{other:?}"),
        }
    }

    /// The vehicles, spawns and objects of [`Self::describe`], a line each.
    fn describe_things(&self, s: &mut String) {
        for v in &self.vehicles {
            let _ = writeln!(
                s,
                "vehicle: {} kg, wheelbase {} m, track {} m, wheels {} m radius x {} m wide (sinking {:.3} m), tread {} every {} m, {} m deep, {} lug, slip {}, path {:?}",
                v.mass_kg,
                v.wheelbase_m,
                v.track_m,
                v.wheel_radius_m,
                v.wheel_width_m,
                v.wheel_load().sinkage_m(&self.snow.mechanics(), snowpack::mechanics::SnowColumn::fresh(self.snow.depth_m)),
                v.tread.pattern.as_str(),
                v.tread.spacing_m,
                v.tread.depth_m,
                v.tread.lug_fraction,
                v.slip,
                v.path
            );
        }
        for sp in &self.spawns {
            let _ = writeln!(s, "spawn: {} spheres of radius {} m, seed {}", sp.count, sp.radius_m, sp.seed);
        }
        for o in &self.objects {
            let _ = writeln!(
                s,
                "object {:?}: {} at {} size {} m, rotated {} deg{}",
                o.name,
                o.kind,
                o.position,
                o.size_m,
                o.rotation_deg,
                if o.dilate { "" } else { ", not dilated" }
            );
            if o.velocity != Vec3::ZERO || o.spin_deg_per_s != Vec3::ZERO {
                let _ = writeln!(s, "  moving at {} m/s, turning {} deg/s", o.velocity, o.spin_deg_per_s);
            }
        }
    }

    /// The store line of [`Self::describe`].
    fn describe_store(&self, s: &mut String) {
        match &self.store {
            Some(t) if t.keep == StoreKeep::Disk => {
                let at = t.path.as_ref().map_or("store/ in the output folder".to_owned(), |p| p.display().to_string());
                let disk = if t.disk_mb > 0.0 { format!("{} MiB", t.disk_mb) } else { "unlimited".to_owned() };
                let _ = writeln!(s, "store: {at}, tiles of {}², memory {} MiB, disk {disk}, save at the end {}", t.tile_texels, t.memory_mb, t.save);
            }
            Some(t) if t.keep == StoreKeep::Memory => {
                let _ = writeln!(s, "store: trails kept in memory, tiles of {}², memory {} MiB", t.tile_texels, t.memory_mb);
            }
            Some(_) => {
                let _ = writeln!(s, "store: off, trails are forgotten when the window moves on");
            }
            None => {
                let mib = self.snow.tile_memory_bytes.map_or(0.0, |b| b as f64 / (1024.0 * 1024.0));
                let _ = writeln!(
                    s,
                    "store: trails kept in memory (no [store]), tiles of {}², memory {mib} MiB",
                    snowpack::low_level::deform::params::default_tile_texels(self.snow.resolution)
                );
            }
        }
    }
}

/// Why a window centred on world (x, z) = `center` would have texel (or
/// tile) coordinates outside i32, which the GPU passes index with; `None`
/// when they fit.
fn texels_overflow(center: [f32; 2], snow: &SnowParams) -> Option<String> {
    let texel = f64::from(snow.texel_m());
    let r = f64::from(snow.resolution);
    let fits = |x: f32| {
        let t = (f64::from(x) / texel).floor();
        t - r >= f64::from(i32::MIN) && t + r <= f64::from(i32::MAX)
    };
    if fits(center[0]) && fits(center[1]) {
        return None;
    }
    let limit = (f64::from(i32::MAX) - r) * texel;
    Some(format!(
        "{center:?} m is beyond the texel grid: with {texel} m texels the window's texel coordinates are 32-bit, so x and z must be within ±{limit:.0} m"
    ))
}

fn load_terrain_mesh(t: &mut Fields<'_>, base_dir: &Path, default_texel: f32) -> Result<TerrainSource, SceneError> {
    let rel = t.string_opt("path")?.ok_or_else(|| t.err("path", "mesh terrain needs a path to a glTF file (.glb or .gltf)"))?;
    let scale = t.positive("scale", 1.0, "")?;
    let texel = t.positive("texel_m", default_texel, " of metres")?;
    let file = base_dir.join(&rel);
    let gltf = GltfFile::open(&file).map_err(|why| t.err("path", why))?;
    let triangles = gltf.world_triangles(scale).map_err(|why| t.err("path", format!("{}: {why}", file.display())))?;
    let mesh = TerrainMesh::new(triangles, texel).map_err(|e| t.err("path", format!("{}: {e}", file.display())))?;
    Ok(TerrainSource::Mesh(Arc::new(mesh)))
}

fn load_heightmap(t: &mut Fields<'_>, base_dir: &Path, default_extent: f32) -> Result<TerrainSource, SceneError> {
    let rel = t.string_opt("path")?.ok_or_else(|| t.err("path", "heightmap terrain needs a path to a 16-bit PNG"))?;
    let scale = t.f32("height_scale_m", 10.0)?;
    let size = t.vec2_opt("size_m")?.unwrap_or([default_extent, default_extent]);
    if size[0] <= 0.0 || size[1] <= 0.0 {
        return Err(t.err("size_m", format!("both sides must be positive, got {size:?}")));
    }
    let center = t.vec2_opt("center")?.unwrap_or([0.0, 0.0]);
    let file = base_dir.join(&rel);
    let gray = read_heightmap_png(&file).map_err(|why| t.err("path", format!("heightmap {}: {why}", file.display())))?;
    let (width, height) = gray.dimensions();
    // Image row 0 is the top of the picture; put it at the far (+z) edge so the
    // map reads like a map seen from above with +z up.
    let mut heights_m = Vec::with_capacity((width * height) as usize);
    for row in (0..height).rev() {
        for col in 0..width {
            heights_m.push(f32::from(gray.get_pixel(col, row)[0]) / 65535.0 * scale);
        }
    }
    let heightmap = HeightmapTerrain::new(width, height, heights_m, center, size).map_err(|e| {
        // The library names its field; the scene names the key that set it.
        let key = match e.as_ref() {
            snowpack::low_level::error::SnowError::InvalidParameter { field: "heightmap size_m", .. } => "size_m",
            snowpack::low_level::error::SnowError::InvalidParameter { field: "heightmap center_m", .. } => "center",
            _ => "height_scale_m",
        };
        t.err(key, format!("heightmap {}: {e}", file.display()))
    })?;
    Ok(TerrainSource::Heightmap(heightmap))
}

/// A heightmap file as 16-bit grey: a PNG (by its contents, whatever its
/// name), 8- or 16-bit grey (alpha ignored), 2 to `HEIGHTMAP_MAX_SIDE`
/// pixels on a side, checked from its header before it is decoded.
fn read_heightmap_png(file: &Path) -> Result<image::ImageBuffer<image::Luma<u16>, Vec<u16>>, String> {
    use image::ImageDecoder as _;
    use snowpack::low_level::terrain::HEIGHTMAP_MAX_SIDE;
    // By its contents only: a file named .png that is not one says so.
    let bytes = crate::read::bounded(file, crate::read::MAX_HEIGHTMAP_BYTES).map_err(|why| format!("cannot read it: {why}"))?;
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| format!("cannot read it: {e}"))?;
    if reader.format() != Some(image::ImageFormat::Png) {
        return Err("it is not a PNG file (heightmaps are 16-bit greyscale PNGs)".into());
    }
    let decoder = reader.into_decoder().map_err(|e| format!("not a readable PNG: {e}"))?;
    let (width, height) = decoder.dimensions();
    if width < 2 || height < 2 || width > HEIGHTMAP_MAX_SIDE || height > HEIGHTMAP_MAX_SIDE {
        return Err(format!("it is {width}x{height} pixels; a heightmap has 2 to {HEIGHTMAP_MAX_SIDE} on a side"));
    }
    let colour = decoder.color_type();
    if !matches!(colour, image::ColorType::L8 | image::ColorType::L16 | image::ColorType::La8 | image::ColorType::La16) {
        return Err(format!("its pixels are {colour:?}; a heightmap is 8- or 16-bit greyscale (16-bit for smooth slopes)"));
    }
    let img = image::DynamicImage::from_decoder(decoder).map_err(|e| format!("cannot decode it: {e}"))?;
    Ok(img.to_luma16())
}

fn parse_actor(a: &mut Fields<'_>, base_dir: &Path) -> Result<ActorSpec, SceneError> {
    let kind = a.choice("kind", "sphere", &["sphere", "box", "blade", "point", "gltf"])?;
    let shape = match kind.as_str() {
        "sphere" => ShapeSpec::Sphere { radius_m: a.positive("radius_m", 0.5, " of metres")? },
        "box" => {
            let size_m = a.vec3("size_m", Vec3::ONE)?;
            if size_m.min_element() <= 0.0 {
                return Err(a.err("size_m", format!("every side must be a positive number of metres, got {size_m}")));
            }
            ShapeSpec::Box { size_m, rotation: rotation_from_deg(a.vec3("rotation_deg", Vec3::ZERO)?) }
        }
        "blade" => {
            let angle_deg = a.f32("angle_deg", 30.0)?;
            if !(-80.0..=80.0).contains(&angle_deg) {
                return Err(a.err("angle_deg", format!("{angle_deg} must be between -80 and 80 degrees from square to the travel")));
            }
            ShapeSpec::Blade { width_m: a.positive("width_m", 2.5, " of metres")?, height_m: a.positive("height_m", 0.8, " of metres")?, angle_deg }
        }
        "point" => ShapeSpec::Point { scale_per_m: a.positive("scale_per_m", 1.0, " (1/m)")? },
        _ => ShapeSpec::Gltf(parse_gltf_actor(a, base_dir)?),
    };
    let position = a.vec3("position", Vec3::new(0.0, 1.0, 0.0))?;
    let velocity = a.vec3("velocity", Vec3::ZERO)?;
    let physics = a.bool("physics", false)?;
    let path = a.rows4_opt("path")?;
    let motion = match (path, physics) {
        (Some(_), true) => return Err(a.err("path", "an actor cannot have both a path and physics = true")),
        (Some(keys), false) => {
            if keys.is_empty() {
                return Err(a.err("path", "needs at least one [x, y, z, t] keyframe"));
            }
            if keys.windows(2).any(|w| w[1][3] <= w[0][3]) {
                return Err(a.err("path", "keyframe times must increase strictly"));
            }
            Motion::Path(keys)
        }
        (None, true) => {
            if !matches!(shape, ShapeSpec::Sphere { .. }) {
                return Err(a.err("physics", "physics is available for spheres only"));
            }
            Motion::Physics { position, velocity }
        }
        (None, false) => Motion::Kinematic { position, velocity },
    };
    Ok(ActorSpec { shape, motion })
}

/// A glTF `[[actor]]`: its file (or the built-in fox), clip, feet, gaits, load and coat.
fn parse_gltf_actor(a: &mut Fields<'_>, base_dir: &Path) -> Result<GltfActor, SceneError> {
    let file = a.string_opt("file")?.ok_or_else(|| a.err("file", "a gltf actor needs a file"))?;
    let builtin = file == BUILTIN_FOX;
    let full = if builtin { PathBuf::from(BUILTIN_FOX) } else { base_dir.join(&file) };
    if !builtin && !full.is_file() {
        return Err(a.err("file", format!("{} does not exist", full.display())));
    }
    let opened = if builtin { GltfFile::from_bytes(BUILTIN_FOX_GLB, &full) } else { GltfFile::open(&full) };
    let model = opened.map_err(|why| a.err("file", why))?.skinned_model().map_err(|why| a.err("file", format!("{}: {why}", full.display())))?;
    let names: Vec<&str> = model.clips.iter().map(|c| c.name.as_str()).collect();
    if names.is_empty() {
        return Err(a.err("file", format!("{} has no animations; a gltf actor plays one", full.display())));
    }
    let clip = match a.string_opt("animation")? {
        None => 0,
        Some(name) => {
            model.clip(&name).ok_or_else(|| a.err("animation", format!("{name:?} is not an animation of {} (it has {})", full.display(), names.join(", "))))?
        }
    };
    let scale = a.positive("scale", 1.0, "")?;
    let speed = a.non_negative("animation_speed", 1.0, "")?;
    let patterns = a.strings_opt("feet")?.unwrap_or_else(|| DEFAULT_FOOT_PATTERNS.iter().map(|p| (*p).to_owned()).collect());
    let pattern_refs: Vec<&str> = patterns.iter().map(String::as_str).collect();
    let mut feet = find_feet(&model.skeleton, &model.clips, &pattern_refs);
    attach_paws(&mut feet, &model.skeleton, &model.clips, &model.mesh);
    if feet.is_empty() {
        return Err(a.err("feet", format!("no joint of {} matches {patterns:?}", full.display())));
    }
    let placement_name = a.choice("placement", "path", &Placement::ALL.map(|(_, s)| s))?;
    let placement = Placement::ALL.iter().find(|(_, s)| *s == placement_name).map_or(Placement::Path, |(p, _)| *p);
    let defaults = FootLoad::default();
    let load =
        FootLoad { mass_kg: a.positive("mass_kg", defaults.mass_kg, " of kg")?, foot_area_m2: a.positive("foot_area_m2", defaults.foot_area_m2, " of m²")? };
    let fade_s = a.non_negative("fade_s", 0.25, " of seconds")?;
    let coat = parse_coat(a)?;
    let mut actor = GltfActor { file: full, model: Arc::new(model), clip, scale, speed, feet, gaits: Vec::new(), fade_s, placement, load, coat };
    if let Some(names) = a.strings_opt("gaits")? {
        actor.set_gaits(&names).map_err(|why| a.err("gaits", why))?;
    }
    Ok(actor)
}

/// The `coat_*` keys of a glTF `[[actor]]`: the snow on its body.
fn parse_coat(a: &mut Fields<'_>) -> Result<snowpack::CoatSettings, SceneError> {
    let d = snowpack::CoatSettings::default();
    Ok(snowpack::CoatSettings {
        cling_per_s: a.non_negative("coat_cling_per_s", d.cling_per_s, " (1/s)")?,
        cap_m: a.non_negative("coat_cap_m", d.cap_m, " of metres")?,
        melt_m_per_s: a.non_negative("coat_melt_m_per_s", d.melt_m_per_s, " of m/s")?,
        shake_speed_m_per_s: a.non_negative("coat_shake_speed_m_per_s", d.shake_speed_m_per_s, " of m/s")?,
        shake_per_s: a.non_negative("coat_shake_per_s", d.shake_per_s, " (1/s)")?,
        wade_radius_m: a.non_negative("coat_wade_radius_m", d.wade_radius_m, " of metres")?,
    })
}

fn parse_render(root: &mut Fields<'_>, base_dir: &Path) -> Result<RenderSpec, SceneError> {
    let defaults = RenderParams::default();
    let mut light = LightParams::default();
    let mut environment = EnvironmentSpec::Builtin;
    if let Some(mut l) = root.table("light")? {
        let elevation = l.f32_opt("sun_elevation_deg")?;
        let azimuth = l.f32_opt("sun_azimuth_deg")?;
        light.sun_direction = match (elevation, azimuth) {
            (None, None) => None,
            (Some(e), Some(a)) => {
                if !(0.5..=90.0).contains(&e) {
                    return Err(l.err("sun_elevation_deg", format!("{e} must be between 0.5 and 90 degrees")));
                }
                Some(sun_from_angles(e, a))
            }
            (Some(_), None) => return Err(l.err("sun_azimuth_deg", "is needed with sun_elevation_deg")),
            (None, Some(_)) => return Err(l.err("sun_elevation_deg", "is needed with sun_azimuth_deg")),
        };
        light.sun_intensity = l.non_negative("sun_intensity", light.sun_intensity, "")?;
        light.sky_intensity = l.non_negative("sky_intensity", light.sky_intensity, "")?;
        light.exposure_ev = l.f32("exposure_ev", light.exposure_ev)?;
        if light.exposure_ev.abs() > 20.0 {
            return Err(l.err("exposure_ev", format!("{} stops is beyond +-20", light.exposure_ev)));
        }
        if let Some(env) = l.string_opt("environment")? {
            environment = match env.as_str() {
                "builtin" => EnvironmentSpec::Builtin,
                "procedural" => EnvironmentSpec::Procedural,
                file => {
                    let path = base_dir.join(file);
                    let bytes = crate::read::bounded(&path, crate::read::MAX_SKY_BYTES)
                        .map_err(|why| l.err("environment", format!("cannot read {}: {why}", path.display())))?;
                    let map = EnvironmentMap::from_hdr(&bytes).map_err(|e| l.err("environment", format!("{}: {e}", path.display())))?;
                    EnvironmentSpec::File(path, Arc::new(map))
                }
            };
        }
        l.finish()?;
    }
    let mut params = RenderParams { light, ..defaults };
    if let Some(mut r) = root.table("render")? {
        let names: Vec<&str> = MaterialPreset::ALL.iter().map(|(_, n)| *n).collect();
        let material = r.choice("material", defaults.material.preset.as_str(), &names)?;
        params.material = MaterialPreset::from_name(&material).unwrap_or_default().material();
        let names: Vec<&str> = DebugView::ALL.iter().map(|(_, n)| *n).collect();
        let view = r.choice("debug_view", defaults.debug_view.as_str(), &names)?;
        params.debug_view = DebugView::from_name(&view).unwrap_or_default();
        params.view_distance_m = r.positive("view_distance_m", defaults.view_distance_m, " of metres")?;
        params.shadow_distance_m = r.positive("shadow_distance_m", defaults.shadow_distance_m, " of metres")?;
        params.shadow_map_size = r.u32_in("shadow_map_size", defaults.shadow_map_size, 256..=8192)?;
        params.finest_patch_m = r.positive("finest_patch_m", defaults.finest_patch_m, " of metres")?;
        params.patch_quads = r.u32_in("patch_quads", defaults.patch_quads, 4..=64)?;
        if !params.patch_quads.is_multiple_of(4) {
            return Err(r.err("patch_quads", format!("{} is not a multiple of 4", params.patch_quads)));
        }
        params.ao_strength = r.non_negative("ao_strength", defaults.ao_strength, "")?;
        if params.view_distance_m / params.finest_patch_m > 1e6 {
            return Err(r.err("finest_patch_m", "is too small for the view distance (over 20 levels)"));
        }
        r.finish()?;
    }
    if let Some(mut m) = root.table("material")? {
        params.material = parse_material(&mut m, params.material)?;
        m.finish()?;
    }
    if let Some(mut t) = root.table("shell")? {
        params.shell = parse_shell(&mut t)?;
        t.finish()?;
    }
    Ok(RenderSpec { params, environment })
}

/// `[shell]`: volumetric detail over the snow near the camera (shell mapping).
fn parse_shell(t: &mut Fields<'_>) -> Result<ShellSettings, SceneError> {
    let d = ShellSettings::default();
    let names: Vec<&str> = [DetailKind::Grass, DetailKind::Crust].iter().map(|k| k.name()).collect();
    let texture = t.choice("texture", d.texture.name(), &names)?;
    let settings = ShellSettings {
        enabled: t.bool("enabled", true)?,
        texture: DetailKind::parse(&texture).unwrap_or_default(),
        texture_size: t.u32_in("texture_size", d.texture_size, 8..=512)?,
        thickness_m: t.positive("thickness_m", d.thickness_m, " of metres")?,
        tile_m: t.positive("tile_m", d.tile_m, " of metres")?,
        radius_m: t.positive("radius_m", d.radius_m, " of metres")?,
        spacing_m: t.positive("spacing_m", d.spacing_m, " of metres")?,
        flatten_m: t.positive("flatten_m", d.flatten_m, " of metres")?,
        min_fraction: t.positive("min_fraction", d.min_fraction, "")?,
        lod: t.bool("lod", d.lod)?,
        passes: t.u32_in("passes", d.passes, 1..=16)?,
        opacity: t.positive("opacity", d.opacity, "")?,
        max_steps: t.u32_in("max_steps", d.max_steps, 1..=1024)?,
        debug_pass: t.u32_in("debug_pass", d.debug_pass, 0..=16)?,
        seed: u64::from(t.u32_in("seed", d.seed as u32, 0..=u64::from(u32::MAX))?),
    };
    if let Err(snowpack::low_level::error::SnowError::InvalidParameter { field, why }) = settings.validate() {
        return Err(t.err(field, why));
    }
    Ok(settings)
}

/// `[material]`: per-field overrides of the `[render] material` preset.
fn parse_material(m: &mut Fields<'_>, base: Material) -> Result<Material, SceneError> {
    let colour = |m: &mut Fields<'_>, key: &str, default: Vec3, max: f32| -> Result<Vec3, SceneError> {
        let c = m.vec3(key, default)?;
        if c.min_element() < 0.0 || c.max_element() > max {
            return Err(m.err(key, format!("components must be in 0..={max}, got {c}")));
        }
        Ok(c)
    };
    let unit = |m: &mut Fields<'_>, key: &str, default: f32| -> Result<f32, SceneError> {
        let x = m.f32(key, default)?;
        if !(0.0..=1.0).contains(&x) {
            return Err(m.err(key, format!("must be in 0..=1, got {x}")));
        }
        Ok(x)
    };
    Ok(Material {
        preset: base.preset,
        fresh_albedo: colour(m, "fresh_albedo", base.fresh_albedo, 1.0)?,
        fresh_roughness: unit(m, "fresh_roughness", base.fresh_roughness)?,
        packed_albedo: colour(m, "packed_albedo", base.packed_albedo, 1.0)?,
        packed_roughness: unit(m, "packed_roughness", base.packed_roughness)?,
        ground_albedo: colour(m, "ground_albedo", base.ground_albedo, 1.0)?,
        ground_roughness: unit(m, "ground_roughness", base.ground_roughness)?,
        scatter: colour(m, "scatter", base.scatter, 4.0)?,
        wrap: unit(m, "wrap", base.wrap)?,
        sparkle: m.non_negative("sparkle", base.sparkle, "")?,
        detail_strength: m.non_negative("detail_strength", base.detail_strength, "")?,
        detail_frequency: m.positive("detail_frequency", base.detail_frequency, " of repeats per metre")?,
        macro_variation: unit(m, "macro_variation", base.macro_variation)?,
        compaction_full: {
            let x = m.f32("compaction_full", base.compaction_full)?;
            if !(0.05..=1.0).contains(&x) {
                return Err(m.err("compaction_full", format!("must be in 0.05..=1 (a fraction of the depth), got {x}")));
            }
            x
        },
        packed_detail: unit(m, "packed_detail", base.packed_detail)?,
        packed_sparkle: unit(m, "packed_sparkle", base.packed_sparkle)?,
        ground_show_through: unit(m, "ground_show_through", base.ground_show_through)?,
    })
}
