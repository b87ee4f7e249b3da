//! Scene parsing: defaults, every key understood, every bad value rejected
//! with the file and the key in the message.

use std::path::Path;

use snowpack::TerrainSource;
use snowpack::low_level::HeightmapTerrainExt;
use snowpack_scene::{Motion, SaveScene, Scene, ShapeSpec, Technique, WindowSpec};

fn parse(text: &str) -> Result<Scene, snowpack_scene::SceneError> {
    Scene::parse(text, Path::new("dir/test-scene.toml"))
}

#[test]
fn empty_scene_gets_the_documented_defaults() {
    let s = parse("").expect("empty scene is valid");
    assert_eq!(s.snow.extent_m, 64.0);
    assert_eq!(s.snow.resolution, 1024);
    assert_eq!(s.snow.depth_m, 0.5);
    assert_eq!(s.snow.refill_m_per_s, 0.0);
    assert_eq!(s.snow.elevation, 1.0);
    assert!(s.snow.blur);
    assert_eq!(s.snow.technique, Technique::Depth);
    assert_eq!(s.snow.range_texels, 64);
    assert_eq!(s.terrain, TerrainSource::Flat { height_m: 0.0 });
    assert_eq!(s.window, WindowSpec::Center([0.0, 0.0]));
    assert_eq!(s.sim.frames, 120);
    assert!((s.sim.dt_s - 1.0 / 60.0).abs() < 1e-7);
    assert_eq!(s.camera.fov_deg, 60.0);
}

#[test]
fn the_bundled_scenes_parse() {
    Scene::default_scene().expect("default scene");
    for name in ["testbed.toml", "drag.toml", "low_sun.toml", "hills.toml", "mound.toml"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name);
        Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    }
}

#[test]
fn the_store_table_is_understood() {
    assert_eq!(parse("").expect("valid").store, None);
    let s = parse("[snow]\nresolution = 256\n[store]\n").expect("valid");
    assert_eq!(s.store, Some(snowpack_scene::StoreSpec::default()));
    let s = parse("[snow]\nresolution = 256\n[store]\npath = \"saves/world\"\ntile_texels = 32\nmemory_mb = 16\ndisk_mb = 512\nsave = false\n").expect("valid");
    let t = s.store.clone().expect("store");
    assert_eq!(t.path.as_deref(), Some(Path::new("dir/saves/world")), "relative to the scene's folder");
    assert_eq!((t.tile_texels, t.memory_mb, t.disk_mb, t.save), (32, 16.0, 512.0, false));
    assert!(s.describe().contains("store: dir/saves/world, tiles of 32²"));
}

#[test]
fn trails_are_kept_in_memory_without_a_store_table_and_keep_chooses() {
    use snowpack_scene::StoreKeep;
    // No [store]: the library's memory keeper, with its default budget.
    let s = parse("[snow]\nresolution = 256\n").expect("valid");
    assert_eq!((s.store.clone(), s.snow.tile_memory_bytes), (None, Some(snowpack::low_level::deform::params::DEFAULT_TILE_MEMORY_BYTES)));
    assert!(s.describe().contains("store: trails kept in memory (no [store]), tiles of 32²"), "{}", s.describe());
    // A [store] table is a disk store unless `keep` says otherwise.
    let s = parse("[snow]\nresolution = 256\n[store]\n").expect("valid");
    assert_eq!(s.store.clone().map(|t| t.keep), Some(StoreKeep::Disk));
    let s = parse("[snow]\nresolution = 256\n[store]\nkeep = \"memory\"\nmemory_mb = 2\n").expect("valid");
    let t = s.store.clone().expect("store");
    assert_eq!((t.keep, t.tile_texels, t.memory_mb, t.save, t.path), (StoreKeep::Memory, 32, 2.0, false, None));
    assert_eq!(s.snow.tile_memory_bytes, Some(2 << 20));
    assert!(s.describe().contains("store: trails kept in memory, tiles of 32², memory 2 MiB"), "{}", s.describe());
    let s = parse("[snow]\nresolution = 48\n[store]\nkeep = \"memory\"\n").expect("valid");
    assert_eq!(s.store.map(|t| t.tile_texels), Some(16), "memory tiles default to a side dividing the resolution");
    let s = parse("[store]\nkeep = \"off\"\n").expect("valid");
    assert_eq!((s.store.clone().map(|t| t.keep), s.snow.tile_memory_bytes), (Some(StoreKeep::Off), None));
    assert!(s.describe().contains("store: off"));
}

#[test]
fn bare_ground_is_a_depth_of_zero() {
    let s = parse("[snow]\ndepth_m = 0\n[snowfall]\nrate_m_per_s = 0.01\n").expect("depth_m = 0 is bare ground");
    assert_eq!(s.snow.depth_m, 0.0);
    let err = parse("[snow]\ndepth_m = -0.1\n").expect_err("negative depth");
    assert!(err.to_string().contains("depth_m") && err.to_string().contains("zero or positive"), "{err}");
}

#[test]
fn actors_windows_and_keyframes_are_understood() {
    let s = parse(
        r#"
[snow]
technique = "points"
range_texels = 96
[window]
follow = "actor:1"
[[actor]]
kind = "sphere"
radius_m = 0.7
position = [1, 2, 3]
physics = true
[[actor]]
kind = "box"
size_m = [1.0, 2.0, 3.0]
rotation_deg = [0.0, 90.0, 0.0]
path = [[0, 1, 0, 0], [4, 1, 0, 2.0]]
[[spawn]]
count = 10
radius_m = 0.25
seed = 3
[[object]]
name = "bench"
position = [0.0, 1.0, 0.0]
size_m = [2.0, 0.1, 1.0]
[snowfall]
direction = [0.0, -2.0, 0.0]
"#,
    )
    .expect("valid");
    assert_eq!(s.snow.technique, Technique::Points);
    assert_eq!(s.snow.range_texels, 96);
    assert_eq!(s.window, WindowSpec::FollowActor(1));
    assert_eq!(s.actors[0].shape, ShapeSpec::Sphere { radius_m: 0.7 });
    assert!(matches!(s.actors[0].motion, Motion::Physics { .. }));
    assert!(matches!(&s.actors[1].motion, Motion::Path(k) if k.len() == 2));
    assert_eq!(s.spawns[0].count, 10);
    assert_eq!(s.objects[0].name, "bench");
    assert_eq!(s.snowfall.as_ref().map(|f| f.direction), Some(glam::Vec3::NEG_Y));
    // The window carries the snowfall, with the library's defaults for what the file leaves out.
    assert_eq!(s.snow.snowfall, s.snowfall);
    assert_eq!(s.snowfall.as_ref().map(|f| f.repose_deg), Some(snowpack::Snowfall::default().repose_deg));
    assert!(s.objects[0].dilate);
    let o = s.objects[0].object();
    assert_eq!(o.shape, snowpack::ObjectShape::Box { size_m: glam::Vec3::new(2.0, 0.1, 1.0) });
}

#[test]
fn every_bad_value_names_the_file_and_the_key() {
    let cases: &[(&str, &str)] = &[
        ("[snow]\nresolution = 0\n", "[snow].resolution"),
        ("[snow]\nresolution = 100000\n", "[snow].resolution"),
        ("[snow]\nresolution = 1000\n", "[snow].resolution"),
        ("[snow]\nextent_m = -4.0\n", "[snow].extent_m"),
        ("[snow]\ndepth_m = nan\n", "[snow].depth_m"),
        ("[snow]\ndepth_m = inf\n", "[snow].depth_m"),
        ("[snow]\ndepth_m = \"deep\"\n", "[snow].depth_m"),
        ("[snow]\nblur = 1\n", "[snow].blur"),
        ("[snow]\ntechnique = \"magic\"\n", "[snow].technique"),
        ("[snow]\nrange_texels = 8\n", "[snow].range_texels"),
        ("[snow]\nbogus_key = 1\n", "[snow].bogus_key"),
        ("bogus_table = 1\n", "bogus_table"),
        ("[terrain]\nkind = \"lava\"\n", "[terrain].kind"),
        ("[terrain]\nkind = \"heightmap\"\npath = \"nowhere.png\"\n", "[terrain].path"),
        ("[terrain]\nkind = \"noise\"\nwavelength_m = 0\n", "[terrain].wavelength_m"),
        ("[[actor]]\nkind = \"sphere\"\nradius_m = -1.0\n", "[[actor]][0].radius_m"),
        ("[[actor]]\nkind = \"box\"\nsize_m = [1.0, 0.0, 1.0]\n", "[[actor]][0].size_m"),
        ("[[actor]]\nkind = \"box\"\nsize_m = [1.0, 1.0]\n", "[[actor]][0].size_m"),
        ("[[actor]]\nkind = \"blob\"\n", "[[actor]][0].kind"),
        ("[[actor]]\nposition = [0, nan, 0]\n", "[[actor]][0].position"),
        ("[[actor]]\npath = [[0, 0, 0, 1], [1, 0, 0, 1]]\n", "[[actor]][0].path"),
        ("[[actor]]\nkind = \"gltf\"\nfile = \"missing.glb\"\n", "[[actor]][0].file"),
        ("[[actor]]\nradius = 1\n", "[[actor]][0].radius"),
        ("[window]\nfollow = \"actor:3\"\n", "[window].follow"),
        ("[window]\nfollow = \"dog\"\n", "[window].follow"),
        ("[[spawn]]\ncount = -5\n", "[[spawn]][0].count"),
        ("[[object]]\nname = \"a\"\n[[object]]\nname = \"a\"\n", "[[object]][1].name"),
        ("[snowfall]\ndirection = [0, 0, 0]\n", "[snowfall].direction"),
        ("[snowfall]\ndirection = [1, 0.05, 0]\n", "[snowfall].direction"),
        ("[snowfall]\nrepose_deg = 100\n", "[snowfall].repose_deg"),
        ("[snowfall]\nnoise = 2\n", "[snowfall].noise"),
        ("[snowfall]\nmax_m = 0\n", "[snowfall].max_m"),
        ("[snowfall]\natlas_resolution = 8\n", "[snowfall].atlas_resolution"),
        ("[snowfall]\nflutter_deg = 60\n", "[snowfall].flutter_deg"),
        ("[[object]]\nname = \"g\"\nkind = \"gltf\"\n", "[[object]][0].file"),
        ("[[object]]\nname = \"g\"\nkind = \"gltf\"\nfile = \"nowhere.glb\"\n", "[[object]][0].file"),
        ("[[object]]\nname = \"d\"\ndilate = 1\n", "[[object]][0].dilate"),
        ("[store]\ntile_texels = 48\n", "[store].tile_texels"),
        ("[store]\ntile_texels = 512\n", "[store].tile_texels"),
        ("[store]\nmemory_mb = -1\n", "[store].memory_mb"),
        ("[store]\ndisk_mb = \"big\"\n", "[store].disk_mb"),
        ("[store]\nsave = 1\n", "[store].save"),
        ("[store]\nresume = true\n", "[store].resume"),
        ("[store]\nkeep = \"cloud\"\n", "[store].keep"),
        ("[store]\nkeep = false\n", "[store].keep"),
        ("[store]\nkeep = \"memory\"\npath = \"saves\"\n", "[store].path"),
        ("[store]\nkeep = \"memory\"\nsave = true\n", "[store].save"),
        ("[store]\nkeep = \"memory\"\ndisk_mb = 5\n", "[store].disk_mb"),
        ("[store]\nkeep = \"memory\"\nmemory_mb = -2\n", "[store].memory_mb"),
        ("[store]\nkeep = \"off\"\nmemory_mb = 8\n", "[store].memory_mb"),
        ("[store]\nkeep = \"off\"\ntile_texels = 32\n", "[store].tile_texels"),
        ("[snow]\ndepth_m = -0.1\n", "[snow].depth_m"),
        ("[sim]\nframes = 0\n", "[sim].frames"),
        ("[sim]\ndt_s = -0.1\n", "[sim].dt_s"),
        ("[camera]\nfov_deg = 200\n", "[camera].fov_deg"),
        ("[light]\nsun_elevation_deg = 30\n", "[light].sun_azimuth_deg"),
        ("[light]\nsun_elevation_deg = 95\nsun_azimuth_deg = 0\n", "[light].sun_elevation_deg"),
        ("[light]\nsun_intensity = -1\n", "[light].sun_intensity"),
        ("[light]\nexposure_ev = 40\n", "[light].exposure_ev"),
        ("[light]\nenvironment = \"missing.hdr\"\n", "[light].environment"),
        ("[render]\nmaterial = \"lava\"\n", "[render].material"),
        ("[render]\ndebug_view = \"xray\"\n", "[render].debug_view"),
        ("[render]\npatch_quads = 18\n", "[render].patch_quads"),
        ("[render]\nshadow_map_size = 100\n", "[render].shadow_map_size"),
        ("[render]\nview_distance_m = 0\n", "[render].view_distance_m"),
        ("[material]\ncompaction_full = 0.01\n", "[material].compaction_full"),
        ("[material]\npacked_detail = 1.5\n", "[material].packed_detail"),
        ("[material]\npacked_sparkle = -0.1\n", "[material].packed_sparkle"),
        ("[material]\nground_show_through = 2\n", "[material].ground_show_through"),
    ];
    for (text, key) in cases {
        let err = parse(text).expect_err(text);
        let msg = err.to_string();
        assert!(msg.starts_with("dir/test-scene.toml: "), "{text:?}: {msg}");
        assert_eq!(&err.key, key, "{text:?}: {msg}");
        assert!(msg.contains(key), "{text:?}: {msg}");
    }
}

#[test]
fn light_and_render_keys_are_understood() {
    use snowpack::{DebugView, MaterialPreset};
    let s = parse(
        r#"
[light]
sun_elevation_deg = 90.0
sun_azimuth_deg = 0.0
sun_intensity = 2.0
exposure_ev = -1.0
environment = "procedural"
[render]
material = "sand"
debug_view = "wireframe"
patch_quads = 32
ao_strength = 0.5
"#,
    )
    .expect("valid");
    let p = s.render.params;
    let sun = p.light.sun_direction.expect("sun given");
    assert!((sun - glam::Vec3::Y).length() < 1e-5, "{sun}");
    assert_eq!((p.light.sun_intensity, p.light.exposure_ev), (2.0, -1.0));
    assert_eq!(p.material.preset, MaterialPreset::Sand);
    assert_eq!(p.debug_view, DebugView::Wireframe);
    assert_eq!((p.patch_quads, p.ao_strength), (32, 0.5));
    assert_eq!(s.render.environment, snowpack_scene::EnvironmentSpec::Procedural);
}

#[test]
fn compacted_snow_keys_are_understood_and_default_to_the_preset() {
    use snowpack::MaterialPreset;
    let s = parse("[render]\nmaterial = \"mud\"\n[material]\ncompaction_full = 0.5\npacked_detail = 1.0\npacked_sparkle = 0.25\n").expect("valid");
    let m = s.render.params.material;
    let mud = MaterialPreset::Mud.material();
    assert_eq!((m.compaction_full, m.packed_detail, m.packed_sparkle), (0.5, 1.0, 0.25));
    assert_eq!(m.ground_show_through, mud.ground_show_through, "unset keys keep the preset's value");
    // The neutral material of docs/rendering.md's "off" image.
    let off =
        parse("[material]\npacked_albedo = [0.92, 0.94, 0.98]\npacked_roughness = 0.8\npacked_detail = 1.0\npacked_sparkle = 1.0\nground_show_through = 0.0\n")
            .expect("valid")
            .render
            .params
            .material;
    assert_eq!(off, MaterialPreset::Snow.material().without_compaction());
}

#[test]
fn malformed_toml_reports_line_and_column() {
    let err = parse("[snow]\nresolution = = 3\n").expect_err("malformed");
    let msg = err.to_string();
    assert!(msg.contains("malformed TOML at line 2"), "{msg}");
}

#[test]
fn heightmaps_load_from_16_bit_png_relative_to_the_scene() {
    let dir = std::env::temp_dir().join(format!("snowpack-hm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(4, 2, |x, y| image::Luma([(x * 1000 + y * 20000) as u16]));
    img.save(dir.join("ground.png")).expect("png");
    let scene_path = dir.join("s.toml");
    std::fs::write(&scene_path, "[terrain]\nkind = \"heightmap\"\npath = \"ground.png\"\nheight_scale_m = 65.535\nsize_m = [4.0, 2.0]\n").expect("write");
    let s = Scene::load(&scene_path).expect("loads");
    let TerrainSource::Heightmap(h) = &s.terrain else { panic!("not a heightmap") };
    assert_eq!((h.width(), h.height()), (4, 2));
    // Image row 0 (y = 0) is the far edge (+z): terrain row 1.
    assert!((h.heights_m()[4 + 3] - 3.0).abs() < 1e-4, "{:?}", h.heights_m());
    assert!((h.heights_m()[3] - 23.0).abs() < 1e-4, "{:?}", h.heights_m());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn saved_scenes_load_back_the_same() {
    use snowpack::MaterialPreset;
    use snowpack::low_level::render::params::sun_from_angles;
    let dir = std::env::temp_dir().join(format!("snowpack-save-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let mut scene = Scene::default_scene().expect("default");
    scene.snow.technique = Technique::Combined;
    scene.snow.refill_m_per_s = 0.003;
    scene.snow.blur = false;
    scene.snow.store_ground = true;
    scene.spawns[0].count = 17;
    scene.camera.position = glam::Vec3::new(1.5, 2.25, -3.0);
    scene.render.params.material = MaterialPreset::Mud.material();
    scene.render.params.material.wrap = 0.3;
    scene.render.params.light.sun_direction = Some(sun_from_angles(12.0, 250.0));
    scene.render.params.light.exposure_ev = -0.5;
    scene.render.params.shell = snowpack::ShellSettings {
        enabled: true,
        texture: snowpack::low_level::render::shell::DetailKind::Crust,
        texture_size: 32,
        thickness_m: 0.05,
        passes: 6,
        debug_pass: 2,
        lod: false,
        ..Default::default()
    };
    let dest = dir.join("saved.toml");
    scene.save(&dest).expect("save");
    let back = Scene::load(&dest).unwrap_or_else(|e| panic!("{e}\n{}", std::fs::read_to_string(&dest).unwrap_or_default()));
    assert_eq!(back.snow, scene.snow);
    assert_eq!(back.terrain, scene.terrain);
    assert_eq!(back.actors, scene.actors);
    assert_eq!(back.spawns, scene.spawns);
    assert_eq!(back.camera, scene.camera);
    assert_eq!(back.sim, scene.sim);
    assert_eq!(back.render.params.material, scene.render.params.material);
    assert_eq!(back.render.params.light.exposure_ev, -0.5);
    assert_eq!(back.render.params.shell, scene.render.params.shell);
    let (a, b) = (back.render.params.light.sun_direction.expect("sun"), sun_from_angles(12.0, 250.0));
    assert!((a - b).length() < 1e-5, "sun {a} vs {b}");
    assert!(!dir.join("saved.toml.tmp").exists(), "temporary file left behind");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_shell_table_is_understood() {
    use snowpack::ShellSettings;
    use snowpack::low_level::render::shell::DetailKind;
    assert!(!parse("").expect("empty").render.params.shell.enabled, "the shell is off without [shell]");
    let on = parse("[shell]\n").expect("shell");
    assert_eq!(on.render.params.shell, ShellSettings { enabled: true, ..ShellSettings::default() });
    let s = parse("[shell]\ntexture = \"crust\"\ntexture_size = 128\nthickness_m = 0.04\npasses = 8\ndebug_pass = 3\nlod = false\nenabled = false\n")
        .expect("shell")
        .render
        .params
        .shell;
    assert_eq!((s.texture, s.texture_size, s.thickness_m, s.passes, s.debug_pass, s.lod, s.enabled), (DetailKind::Crust, 128, 0.04, 8, 3, false, false));
    for (text, key) in [("[shell]\nmin_fraction = 2.0\n", "min_fraction"), ("[shell]\nopacity = 0.0\n", "opacity"), ("[shell]\ncolour = 1\n", "colour")] {
        let e = parse(text).expect_err(text).to_string();
        assert!(e.contains("test-scene.toml") && e.contains(key), "{e}");
    }
}
