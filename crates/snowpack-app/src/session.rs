//! What the demo simulates and draws, apart from the window: the scene, the
//! test-bed world, the player (a sphere or the fox), the deformation window
//! and the renderer, with the operations the panel and the keys ask for.

use std::path::Path;
use std::sync::Arc;

use anyhow::Context as _;
use glam::{DVec2, Vec2, Vec3};
use snowpack::PassTimings;
use snowpack::StoredWindow as _;
use snowpack::low_level::SnowInspect;
use snowpack::low_level::skin::feet::FootstepEvent;
use snowpack::{Deformer, EnvironmentMap, GpuContext, RenderParams, Renderer, SkinnedId, SnowDeformation, SnowParams};
use snowpack_scene::{ActorSpec, GltfActor, Motion, Placement, Scene, ShapeSpec, SpawnSpec, StoreKeep, StoreSpec, WindowSpec, World};

/// Where the demo keeps a tile store whose scene names no folder.
pub const DEMO_OUT: &str = "snowpack-out";

/// What the player drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlayerBody {
    /// A sphere pressed into the snow to a set fraction of its depth.
    Sphere,
    /// The built-in fox, walking (or running with Shift), standing on the
    /// snow as its weight and the snow's hardness say.
    Fox,
    /// A plough's blade scraping the ground, turned from its travel
    /// (`Deformer::blade`): with `[snow] displace` it pushes a windrow.
    Blade,
}

impl PlayerBody {
    /// Every body with its label.
    pub const ALL: [(Self, &'static str); 3] = [(Self::Sphere, "sphere"), (Self::Fox, "fox"), (Self::Blade, "plough blade")];
}

/// The player's plough blade: width, height (m) and turn from its travel (degrees).
pub const PLAYER_BLADE: (f32, f32, f32) = (2.5, 0.9, 30.0);

/// The fox's walking and running speeds (m/s): about its clips' strides.
pub const FOX_WALK_M_PER_S: f32 = 1.0;
/// See [`FOX_WALK_M_PER_S`].
pub const FOX_RUN_M_PER_S: f32 = 2.6;

/// What the player drives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Player {
    /// Whether it is in the world (pressing snow).
    pub enabled: bool,
    /// A sphere or the fox.
    pub body: PlayerBody,
    /// Centre (m).
    pub position: Vec3,
    /// Radius (m).
    pub radius: f32,
    /// How far its lowest point sinks below the rest snow, as a fraction of the depth.
    pub sink: f32,
    /// Walking speed (m/s).
    pub speed: f32,
    /// Which way it last moved (ground plane): where a blade faces.
    pub heading: Vec2,
}

/// Where the deformation window is centred.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindowFollow {
    /// As the scene file says.
    Scene,
    /// The player's sphere.
    Player,
    /// The camera.
    Camera,
}

impl WindowFollow {
    /// Every option with its label.
    pub const ALL: [(Self, &'static str); 3] = [(Self::Scene, "as the scene says"), (Self::Player, "the player"), (Self::Camera, "the camera")];
}

/// Per-pass GPU medians over the last timing period.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TimingReport {
    /// Deformation passes (name, ms).
    pub deform: Vec<(String, f64)>,
    /// Render passes (name, ms).
    pub render: Vec<(String, f64)>,
}

fn passes(t: PassTimings) -> Vec<(String, f64)> {
    t.passes.into_iter().map(|(n, ms, _)| (n, ms)).collect()
}

/// The simulation and its renderer.
pub struct Session {
    /// The scene as loaded, with the panel's edits applied to its fields.
    pub scene: Scene,
    /// Actors and test-bed spheres.
    pub world: World,
    /// The deformation window.
    pub snow: SnowDeformation,
    /// The renderer, drawing into the window's format.
    pub renderer: Renderer,
    /// The player's sphere.
    pub player: Player,
    /// What the window follows.
    pub follow: WindowFollow,
    /// Simulation paused.
    pub paused: bool,
    /// Test-bed physics on.
    pub physics: bool,
    /// Frames simulated since the last reset.
    pub frames: u64,
    /// Deformation parameters as the panel edits them (applied each frame).
    pub snow_params: SnowParams,
    /// Render parameters as the panel edits them.
    pub render_params: RenderParams,
    /// Latest timing medians.
    pub timings: TimingReport,
    /// Footsteps since the last reset, and the latest.
    pub footsteps: (u64, Option<FootstepEvent>),
    /// The tile store's latest errors (the frame goes on without them).
    pub store_errors: Vec<String>,
    /// Points (world x, z) asked about every frame besides the characters'
    /// soles; their answers are in the deformation's `point_answers` (the
    /// browser build's test reads a trail and untouched snow this way).
    pub probes: Vec<Vec2>,
    /// The player's fox in the world (actor index), once it has been chosen.
    fox: Option<usize>,
    /// Skinned meshes registered with the deformation, by actor.
    skins: Vec<(usize, SkinnedId)>,
    /// The panel's snow coat for every character, once edited there
    /// (until then each keeps its scene's `coat_*` keys).
    pub coat: Option<snowpack::CoatSettings>,
    env: Arc<EnvironmentMap>,
    format: wgpu::TextureFormat,
    step_once: bool,
    reset_seed: u64,
}

impl Session {
    /// Builds everything for `scene`, drawing into `format`.
    pub fn new(ctx: &GpuContext, scene: Scene, format: wgpu::TextureFormat) -> anyhow::Result<Self> {
        let env = scene.render.environment_map();
        let world = World::new(&scene);
        let snow_params = scene.snow.clone();
        let render_params = scene.render.params;
        let center = crate::characters::window_center(&scene, &world);
        let snow = crate::characters::new_window(ctx, &scene, snow_params.clone(), center, "creating the deformation window")?;
        let renderer = Renderer::new(ctx, &snow, &env, render_params, format).context("creating the renderer")?;
        let start = Vec2::new(center.x as f32, center.y as f32);
        let radius = 0.5;
        let mut player = Player { enabled: true, body: PlayerBody::Sphere, position: Vec3::ZERO, radius, sink: 0.6, speed: 4.0, heading: Vec2::X };
        player.position = player_height(&scene, &snow_params, start, &player);
        let mut session = Self {
            follow: WindowFollow::Scene,
            world,
            snow,
            renderer,
            player,
            paused: false,
            physics: true,
            frames: 0,
            snow_params,
            render_params,
            timings: TimingReport::default(),
            env,
            format,
            step_once: false,
            reset_seed: scene.spawns.first().map_or(7, |s| s.seed),
            footsteps: (0, None),
            store_errors: Vec::new(),
            probes: Vec::new(),
            fox: None,
            skins: Vec::new(),
            coat: None,
            scene,
        };
        session.attach_store(ctx)?;
        session.register_skins(ctx)?;
        Ok(session)
    }

    /// Attaches the scene's `[store]` (default folder `snowpack-out/store`);
    /// when it holds a save, the window resumes there.
    fn attach_store(&mut self, ctx: &GpuContext) -> anyhow::Result<()> {
        if let Some(spec) = self.scene.store.clone() {
            crate::characters::attach_store(ctx, &mut self.snow, &self.scene, &spec, (Path::new(DEMO_OUT), false))?;
        }
        Ok(())
    }

    /// Where trails are kept now: a disk store, memory (a scene without
    /// `[store]`, or `keep = "memory"`), or nowhere.
    #[must_use]
    pub fn store_keep(&self) -> StoreKeep {
        match &self.scene.store {
            Some(spec) => spec.keep,
            None if self.snow_params.tile_memory_bytes.is_some() => StoreKeep::Memory,
            None => StoreKeep::Off,
        }
    }

    /// Keeps trails on disk, in memory or not at all (rebuilds the window).
    pub fn set_store(&mut self, ctx: &GpuContext, keep: StoreKeep) -> anyhow::Result<()> {
        let old = self.scene.store.take().filter(|s| s.keep == StoreKeep::Disk);
        self.scene.store = match keep {
            StoreKeep::Disk => Some(old.unwrap_or_default()),
            // The library's default memory keeper.
            StoreKeep::Memory => None,
            StoreKeep::Off => Some(StoreSpec { keep, save: false, ..StoreSpec::default() }),
        };
        self.snow_params.tile_memory_bytes = (keep != StoreKeep::Off).then_some(snowpack::low_level::deform::params::DEFAULT_TILE_MEMORY_BYTES);
        self.rebuild(ctx)
    }

    /// Saves the whole snow state into the tile store.
    pub fn save_store(&mut self, ctx: &GpuContext) -> anyhow::Result<String> {
        self.snow.save(ctx).context("saving into the tile store")?;
        let dir = self.scene.store.as_ref().and_then(|s| s.path.clone()).unwrap_or_else(|| Path::new(DEMO_OUT).join("store"));
        Ok(format!("saved the snow into {}", dir.display()))
    }

    /// Uploads the skinned mesh of every character in the world and places the
    /// scene's objects (fresh deformation).
    fn register_skins(&mut self, ctx: &GpuContext) -> anyhow::Result<()> {
        self.skins = crate::characters::register_characters(ctx, &self.world, &mut self.snow)?;
        self.apply_coat()?;
        let objects: Vec<_> = self.scene.objects.iter().map(snowpack_scene::ObjectSpec::object).collect();
        self.snow.set_objects(ctx, &objects).context("placing the [[object]]s")?;
        Ok(())
    }

    /// Makes the player a sphere or the fox; the fox joins the world where the
    /// player is, the first time.
    pub fn set_body(&mut self, ctx: &GpuContext, body: PlayerBody) -> anyhow::Result<()> {
        self.player.body = body;
        if body == PlayerBody::Fox && self.fox.is_none() {
            let fox = player_fox()?;
            let at = self.player.position;
            let spec =
                ActorSpec { shape: ShapeSpec::Gltf(fox.clone()), motion: Motion::Kinematic { position: Vec3::new(at.x, 0.0, at.z), velocity: Vec3::ZERO } };
            let k = self.world.add_actor(&spec);
            let id = self.snow.add_skinned_mesh(ctx, &fox.model.mesh, fox.model.skeleton.joints.len()).context("uploading the fox")?;
            if let Some(coat) = self.coat {
                self.snow.set_coat(id, coat).context("the fox's snow coat")?;
            }
            self.skins.push((k, id));
            self.fox = Some(k);
        }
        if let Some(k) = self.fox {
            self.world.set_enabled(k, self.player.enabled && body == PlayerBody::Fox);
            if let Some(p) = self.world.actor_position(k) {
                self.player.position = p;
            }
        }
        Ok(())
    }

    /// Gives every character the panel's snow coat, once it was edited there.
    pub fn apply_coat(&mut self) -> anyhow::Result<()> {
        if let Some(coat) = self.coat {
            for (_, id) in &self.skins {
                self.snow.set_coat(*id, coat).context("the characters' snow coat")?;
            }
        }
        Ok(())
    }

    /// Spheres of the test bed now.
    #[must_use]
    pub fn sphere_count(&self) -> usize {
        self.world.body_count()
    }

    /// Advances one frame even while paused.
    pub fn single_step(&mut self) {
        self.step_once = true;
    }

    /// A stable id for each of [`Self::deformers`] (the world's, then the
    /// player's sphere), so each is swept from its own last pose.
    #[must_use]
    pub fn deformer_ids(&self) -> Vec<u64> {
        let mut ids = self.world.deformer_ids();
        if self.player.enabled && matches!(self.player.body, PlayerBody::Sphere | PlayerBody::Blade) {
            ids.push(u64::MAX);
        }
        ids
    }

    /// Everything pressing the snow this frame.
    #[must_use]
    pub fn deformers(&self) -> Vec<Deformer> {
        let mut d = self.world.deformers();
        if self.player.enabled {
            let p = self.player.position;
            match self.player.body {
                PlayerBody::Sphere => d.push(Deformer::Sphere { center: p, radius: self.player.radius }),
                PlayerBody::Blade => {
                    // Its lower edge just under the terrain: it scrapes the ground.
                    let edge = Vec3::new(p.x, self.scene.terrain.height_at(p.x, p.z) - 0.02, p.z);
                    let (width_m, height_m, angle_deg) = PLAYER_BLADE;
                    d.push(Deformer::blade(edge, Vec3::new(self.player.heading.x, 0.0, self.player.heading.y), angle_deg, (width_m, height_m)));
                }
                PlayerBody::Fox => {}
            }
        }
        d
    }

    /// Moves the player by `dir` (ground plane, length up to 1) for `dt`
    /// seconds: the sphere at once, the fox by steering it (it walks, or
    /// runs when `fast`, from the next simulated frame on).
    pub fn drive_player(&mut self, dir: Vec2, fast: bool, dt: f32) {
        let dir = dir.clamp_length_max(1.0);
        match (self.player.body, self.fox) {
            (PlayerBody::Fox, Some(k)) => {
                self.world.set_enabled(k, self.player.enabled);
                self.world.steer(k, dir * if fast { FOX_RUN_M_PER_S } else { FOX_WALK_M_PER_S });
                if let Some(p) = self.world.actor_position(k) {
                    self.player.position = p;
                }
            }
            _ => {
                if dir.length() > 1e-3 {
                    self.player.heading = dir.normalize();
                }
                let step = dir * self.player.speed * if fast { 2.5 } else { 1.0 } * dt;
                let xz = Vec2::new(self.player.position.x, self.player.position.z) + step;
                self.player.position = player_height(&self.scene, &self.snow_params, xz, &self.player);
            }
        }
    }

    /// Centre of the deformation window this frame.
    fn window_center(&self, camera: Vec3) -> DVec2 {
        match self.follow {
            WindowFollow::Scene => match self.scene.window {
                WindowSpec::FollowCamera => DVec2::new(f64::from(camera.x), f64::from(camera.z)),
                _ => crate::characters::window_center(&self.scene, &self.world),
            },
            WindowFollow::Player => DVec2::new(f64::from(self.player.position.x), f64::from(self.player.position.z)),
            WindowFollow::Camera => DVec2::new(f64::from(camera.x), f64::from(camera.z)),
        }
    }

    /// Applies the panel's parameters that change without rebuilding.
    fn apply_live_params(&mut self) {
        let p = &self.snow_params;
        let live = self.snow.params().clone();
        if live.technique != p.technique {
            self.snow.set_technique(p.technique);
        }
        if live.refill_m_per_s != p.refill_m_per_s {
            self.snow.set_refill(p.refill_m_per_s);
        }
        if live.elevation != p.elevation {
            self.snow.set_elevation(p.elevation);
        }
        if live.blur != p.blur {
            self.snow.set_blur(p.blur);
        }
        if live.repose_deg != p.repose_deg {
            // The panel's range is valid; a refusal keeps the old angle.
            let _ = self.snow.set_repose(p.repose_deg);
        }
        if live.range_texels != p.range_texels || live.rim != p.rim {
            self.snow.set_points(p.range_texels, p.rim);
        }
        if live.snowfall != p.snowfall && live.snowfall.is_some() && p.snowfall.is_some() {
            // Validated by the panel's ranges; a refusal leaves the old snowfall.
            let _ = self.snow.set_snowfall(p.snowfall.clone());
        }
        self.world.set_snow(live.depth_m, p.mechanics());
        if *self.renderer.params() != self.render_params {
            self.renderer.set_params(self.render_params);
        }
    }

    /// Snowfall so far on open ground (m).
    #[must_use]
    pub fn snow_fallen_m(&self) -> f32 {
        self.snow.fallen_m()
    }

    /// How many objects gather snow, if any.
    #[must_use]
    pub fn accumulation_objects(&self) -> Option<usize> {
        self.snow.accumulation().map(|a| a.objects().len())
    }

    /// Whether the panel changed a parameter that needs [`Self::rebuild`].
    #[must_use]
    pub fn needs_rebuild(&self) -> bool {
        let live = self.snow.params();
        live.extent_m != self.snow_params.extent_m
            || live.resolution != self.snow_params.resolution
            || live.depth_m != self.snow_params.depth_m
            || live.snowfall.is_some() != self.snow_params.snowfall.is_some()
            || live.displace != self.snow_params.displace
            || self.renderer.params().shadow_map_size != self.render_params.shadow_map_size
            || self.renderer.params().patch_quads != self.render_params.patch_quads
    }

    /// Records one simulation frame (when running) into `encoder`; nothing
    /// is called after the submit (the next frame takes the readbacks).
    pub fn encode_step(&mut self, ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, camera: Vec3) -> bool {
        self.apply_live_params();
        if self.paused && !self.step_once {
            return false;
        }
        self.step_once = false;
        let dt = self.scene.sim.dt_s;
        if self.physics {
            // Characters on the snow stand in it as the latest answers show it (older trails).
            let answers = self.snow.point_answers();
            self.world.step_on(dt, &|x, z| crate::characters::sole_sample(answers, x, z));
            for mut step in self.world.take_footsteps() {
                step.snow_depth_m = crate::characters::sole_sample(answers, step.position.x, step.position.z).map(|s| s.depth_m());
                self.footsteps = (self.footsteps.0 + 1, Some(step));
            }
        }
        let asked = (self.physics || !self.probes.is_empty()).then(|| {
            let mut asked = if self.physics { crate::characters::sole_points(&self.world) } else { Vec::new() };
            asked.extend_from_slice(&self.probes);
            asked
        });
        if let (PlayerBody::Fox, Some(k)) = (self.player.body, self.fox)
            && let Some(p) = self.world.actor_position(k)
        {
            self.player.position = p;
        }
        self.snow.set_center(self.window_center(camera));
        let t = self.frames as f32 * dt;
        for (k, o) in self.scene.objects.iter().enumerate() {
            let (position, rotation) = o.pose_at(t);
            self.snow.set_object_pose(k, position, rotation);
        }
        let deformers = self.deformers();
        let characters = self.world.characters();
        let poses = crate::characters::poses(&self.skins, &characters);
        let ids = self.deformer_ids();
        let frame = snowpack::SnowFrame::new(dt, &deformers).with_ids(&ids).with_poses(&poses);
        let frame = asked.as_deref().map_or(frame, |points| frame.with_queries(points));
        self.snow.encode(ctx, encoder, &frame);
        for e in self.snow.take_store_errors() {
            self.store_errors.push(e.to_string());
        }
        let keep = self.store_errors.len().saturating_sub(4);
        self.store_errors.drain(..keep);
        self.frames += 1;
        if self.frames.is_multiple_of(30) {
            self.timings = TimingReport { deform: passes(self.snow.timings()), render: passes(self.renderer.timings()) };
            self.snow.clear_timings();
            self.renderer.clear_timings();
        }
        true
    }

    /// Restores fresh snow and places `count` test-bed spheres anew (a new seed
    /// each time), keeping every parameter.
    pub fn reset(&mut self, ctx: &GpuContext, count: u32) -> anyhow::Result<()> {
        self.reset_seed = self.reset_seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407) >> 1;
        let radius = self.scene.spawns.first().map_or(0.5, |s| s.radius_m);
        self.scene.spawns = vec![SpawnSpec { count, radius_m: radius, seed: self.reset_seed & 0xffff_ffff }];
        self.rebuild(ctx)
    }

    /// Rebuilds the window and renderer with the panel's parameters (fresh snow).
    pub fn rebuild(&mut self, ctx: &GpuContext) -> anyhow::Result<()> {
        self.scene.snow = self.snow_params.clone();
        self.scene.render.params = self.render_params;
        self.world = World::new(&self.scene);
        let center = crate::characters::window_center(&self.scene, &self.world);
        let snow = crate::characters::new_window(ctx, &self.scene, self.snow_params.clone(), center, "rebuilding the deformation window")?;
        let renderer = Renderer::new(ctx, &snow, &self.env, self.render_params, self.format).context("rebuilding the renderer")?;
        // The old window lets go of its store (flushing it) before the new one opens it.
        self.snow = snow;
        self.renderer = renderer;
        self.store_errors.clear();
        if let Err(e) = self.attach_store(ctx) {
            self.scene.store = None;
            return Err(e.context("the window was rebuilt without a tile store"));
        }
        self.frames = 0;
        self.footsteps = (0, None);
        let xz = Vec2::new(center.x as f32, center.y as f32);
        self.player.position = player_height(&self.scene, &self.snow_params, xz, &self.player);
        self.fox = None;
        self.register_skins(ctx)?;
        self.set_body(ctx, self.player.body)
    }

    /// Replaces the scene (a loaded file) and rebuilds everything.
    pub fn load(&mut self, ctx: &GpuContext, scene: Scene) -> anyhow::Result<()> {
        let fresh = Self::new(ctx, scene, self.format)?;
        let body = self.player.body;
        *self = Self { follow: self.follow, paused: self.paused, ..fresh };
        self.set_body(ctx, body)
    }

    /// The scene with the panel's edits, for saving; `camera` is the view now.
    #[must_use]
    pub fn scene_to_save(&self, camera: &snowpack::Camera) -> Scene {
        let mut scene = self.scene.clone();
        scene.snow = self.snow_params.clone();
        scene.render.params = self.render_params;
        scene.camera.position = camera.position;
        scene.camera.target = camera.target;
        scene.camera.fov_deg = camera.fov_deg;
        scene
    }

    /// GPU memory held by snowpack's resources (deformation and renderer).
    #[must_use]
    pub fn memory_bytes(&self) -> u64 {
        self.snow.memory_bytes().iter().map(|m| m.1).sum::<u64>() + self.renderer.memory_bytes()
    }
}

/// The player's fox: the built-in model, walking and running by speed, on the snow.
fn player_fox() -> anyhow::Result<GltfActor> {
    let file = std::path::PathBuf::from(snowpack_scene::BUILTIN_FOX);
    let model =
        snowpack_scene::gltf_file::GltfFile::from_bytes(snowpack_scene::BUILTIN_FOX_GLB, &file).and_then(|g| g.skinned_model()).map_err(anyhow::Error::msg)?;
    let mut fox = GltfActor::new(file, Arc::new(model)).context("the fox has no feet")?;
    fox.scale = 0.01;
    fox.clip = fox.model.clip("Survey").unwrap_or(0);
    fox.placement = Placement::Snow;
    fox.set_gaits(&["Walk".to_owned(), "Run".to_owned()]).map_err(anyhow::Error::msg)?;
    Ok(fox)
}

/// The player's centre at `xz`: its lowest point `sink` of the depth below the rest snow.
fn player_height(scene: &Scene, snow: &SnowParams, xz: Vec2, player: &Player) -> Vec3 {
    let rest = scene.terrain.height_at(xz.x, xz.y) + snow.depth_m;
    Vec3::new(xz.x, rest - player.sink * snow.depth_m + player.radius, xz.y)
}
