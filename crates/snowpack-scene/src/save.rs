//! Writing a scene back to TOML (the demo's "save"): the tables a session can
//! change (`[snow]`, `[[spawn]]`, `[sim]`, `[camera]`, `[light]`, `[render]`,
//! `[material]`) come from the [`Scene`]'s fields; everything else (terrain,
//! actors, window, objects, snowfall) is kept as it was in the source file,
//! with relative file paths rewritten so they still resolve from the new place.

use std::path::Path;

use glam::Vec3;
use snowpack::Material;
use toml::{Table, Value};

use crate::scene::{EnvironmentSpec, Scene};
use snowpack::low_level::RimStyleExt;
use snowpack::low_level::TechniqueExt;

fn float(x: f32) -> Value {
    // Through the shortest decimal of the f32, so 0.1 is written as 0.1.
    Value::Float(format!("{x}").parse::<f64>().unwrap_or(f64::from(x)))
}

fn vec3(v: Vec3) -> Value {
    Value::Array(vec![float(v.x), float(v.y), float(v.z)])
}

fn material_table(m: &Material) -> Table {
    let mut t = Table::new();
    t.insert("fresh_albedo".into(), vec3(m.fresh_albedo));
    t.insert("fresh_roughness".into(), float(m.fresh_roughness));
    t.insert("packed_albedo".into(), vec3(m.packed_albedo));
    t.insert("packed_roughness".into(), float(m.packed_roughness));
    t.insert("ground_albedo".into(), vec3(m.ground_albedo));
    t.insert("ground_roughness".into(), float(m.ground_roughness));
    t.insert("scatter".into(), vec3(m.scatter));
    t.insert("wrap".into(), float(m.wrap));
    t.insert("sparkle".into(), float(m.sparkle));
    t.insert("detail_strength".into(), float(m.detail_strength));
    t.insert("detail_frequency".into(), float(m.detail_frequency));
    t.insert("macro_variation".into(), float(m.macro_variation));
    t.insert("compaction_full".into(), float(m.compaction_full));
    t.insert("packed_detail".into(), float(m.packed_detail));
    t.insert("packed_sparkle".into(), float(m.packed_sparkle));
    t.insert("ground_show_through".into(), float(m.ground_show_through));
    t
}

/// Rewrites a path relative to `from` so it resolves from `to` (absolute when they differ).
fn rebase(value: &mut Value, from: &Path, to: &Path) {
    if let Value::String(s) = value {
        let p = Path::new(s.as_str());
        // "builtin:..." names something the binary carries, not a file.
        if p.is_relative() && from != to && !s.starts_with("builtin:") {
            let joined = from.join(p);
            let absolute = std::path::absolute(&joined).unwrap_or(joined);
            *s = absolute.display().to_string();
        }
    }
}

/// A scene written back as a scene file: the inverse of [`Scene::load`].
/// A trait beside `Scene`'s one inherent `impl` (parsing, in `scene.rs`),
/// so the writing lives here without the two files naming each other.
pub trait SaveScene {
    /// The scene as TOML text for a file at `dest`; parsing it back gives this scene.
    #[must_use]
    fn to_toml(&self, dest: &Path) -> String;

    /// Writes [`Self::to_toml`] to `dest` atomically (a temporary file renamed
    /// over it), so a failed save leaves the old file whole.
    fn save(&self, dest: &Path) -> std::io::Result<()>;
}

impl SaveScene for Scene {
    fn to_toml(&self, dest: &Path) -> String {
        let mut root = self.source.clone();
        let from = self.path.parent().unwrap_or(Path::new(""));
        let to = dest.parent().unwrap_or(Path::new(""));
        let from = std::path::absolute(from).unwrap_or_else(|_| from.to_owned());
        let to = std::path::absolute(to).unwrap_or_else(|_| to.to_owned());
        if let Some(Value::Table(t)) = root.get_mut("terrain")
            && let Some(v) = t.get_mut("path")
        {
            rebase(v, &from, &to);
        }
        if let Some(Value::Array(actors)) = root.get_mut("actor") {
            for a in actors {
                if let Value::Table(t) = a
                    && let Some(v) = t.get_mut("file")
                {
                    rebase(v, &from, &to);
                }
            }
        }

        root.insert("snow".into(), Value::Table(snow_table(self)));

        if self.spawns.is_empty() {
            root.remove("spawn");
        } else {
            let spawns = self
                .spawns
                .iter()
                .map(|sp| {
                    let mut t = Table::new();
                    t.insert("kind".into(), Value::String("sphere".into()));
                    t.insert("count".into(), Value::Integer(i64::from(sp.count)));
                    t.insert("radius_m".into(), float(sp.radius_m));
                    t.insert("seed".into(), Value::Integer(sp.seed as i64));
                    Value::Table(t)
                })
                .collect();
            root.insert("spawn".into(), Value::Array(spawns));
        }

        let mut sim = Table::new();
        sim.insert("frames".into(), Value::Integer(i64::from(self.sim.frames)));
        sim.insert("dt_s".into(), float(self.sim.dt_s));
        root.insert("sim".into(), Value::Table(sim));

        let mut camera = Table::new();
        camera.insert("position".into(), vec3(self.camera.position));
        camera.insert("target".into(), vec3(self.camera.target));
        camera.insert("fov_deg".into(), float(self.camera.fov_deg));
        root.insert("camera".into(), Value::Table(camera));

        insert_render(self, &mut root);

        let mut text = format!("# snowpack scene, saved from {}\n", self.path.display());
        text.push_str(&toml::to_string(&root).unwrap_or_default());
        text
    }

    fn save(&self, dest: &Path) -> std::io::Result<()> {
        let text = self.to_toml(dest);
        let tmp = dest.with_extension("toml.tmp");
        std::fs::write(&tmp, text)?;
        std::fs::rename(&tmp, dest).inspect_err(|_| {
            let _ = std::fs::remove_file(&tmp);
        })
    }
}

/// `[snow]` as the scene now has it.
fn snow_table(scene: &Scene) -> Table {
    let p = &scene.snow;
    let mut snow = Table::new();
    snow.insert("extent_m".into(), float(p.extent_m));
    snow.insert("resolution".into(), Value::Integer(i64::from(p.resolution)));
    snow.insert("depth_m".into(), float(p.depth_m));
    snow.insert("technique".into(), Value::String(p.technique.as_str().into()));
    snow.insert("refill_m_per_s".into(), float(p.refill_m_per_s));
    snow.insert("elevation".into(), float(p.elevation));
    snow.insert("blur".into(), Value::Boolean(p.blur));
    snow.insert("range_texels".into(), Value::Integer(i64::from(p.range_texels)));
    snow.insert("rim".into(), Value::String(p.rim.as_str().into()));
    snow.insert("hardness_kpa".into(), float(p.hardness_kpa));
    snow.insert("density_kg_m3".into(), float(p.density_kg_m3));
    snow.insert("max_density_kg_m3".into(), float(p.max_density_kg_m3));
    if let Some(r) = p.repose_deg {
        snow.insert("repose_deg".into(), float(r));
    }
    if p.displace {
        snow.insert("displace".into(), Value::Boolean(true));
    }
    snow.insert("teleport_m".into(), float(p.teleport_m));
    if p.store_ground {
        snow.insert("store_ground".into(), Value::Boolean(true));
    }
    snow
}

/// `[light]`, `[render]`, `[material]` and (when on or present) `[shell]` as the scene now has them.
fn insert_render(scene: &Scene, root: &mut Table) {
    let r = &scene.render.params;
    let mut light = Table::new();
    if let Some(sun) = r.light.sun_direction {
        let sun = sun.normalize();
        let elevation = sun.y.clamp(-1.0, 1.0).asin().to_degrees().clamp(0.5, 90.0);
        let azimuth = sun.x.atan2(sun.z).to_degrees().rem_euclid(360.0);
        light.insert("sun_elevation_deg".into(), float(elevation));
        light.insert("sun_azimuth_deg".into(), float(azimuth));
    }
    light.insert("sun_intensity".into(), float(r.light.sun_intensity));
    light.insert("sky_intensity".into(), float(r.light.sky_intensity));
    light.insert("exposure_ev".into(), float(r.light.exposure_ev));
    let environment = match &scene.render.environment {
        EnvironmentSpec::Builtin => Value::String("builtin".into()),
        EnvironmentSpec::Procedural => Value::String("procedural".into()),
        EnvironmentSpec::File(path, _) => {
            let absolute = std::path::absolute(path).unwrap_or_else(|_| path.clone());
            Value::String(absolute.display().to_string())
        }
    };
    light.insert("environment".into(), environment);
    root.insert("light".into(), Value::Table(light));

    let mut render = Table::new();
    render.insert("material".into(), Value::String(r.material.preset.as_str().into()));
    render.insert("debug_view".into(), Value::String(r.debug_view.as_str().into()));
    render.insert("view_distance_m".into(), float(r.view_distance_m));
    render.insert("shadow_distance_m".into(), float(r.shadow_distance_m));
    render.insert("shadow_map_size".into(), Value::Integer(i64::from(r.shadow_map_size)));
    render.insert("finest_patch_m".into(), float(r.finest_patch_m));
    render.insert("patch_quads".into(), Value::Integer(i64::from(r.patch_quads)));
    render.insert("ao_strength".into(), float(r.ao_strength));
    root.insert("render".into(), Value::Table(render));
    root.insert("material".into(), Value::Table(material_table(&r.material)));
    if r.shell.enabled || root.contains_key("shell") {
        root.insert("shell".into(), Value::Table(shell_table(&r.shell)));
    }
}

/// `[shell]` with every field, so a saved scene reloads the same shell.
fn shell_table(s: &snowpack::ShellSettings) -> Table {
    let mut t = Table::new();
    t.insert("enabled".into(), Value::Boolean(s.enabled));
    t.insert("texture".into(), Value::String(s.texture.name().into()));
    t.insert("texture_size".into(), Value::Integer(i64::from(s.texture_size)));
    for (key, v) in [
        ("thickness_m", s.thickness_m),
        ("tile_m", s.tile_m),
        ("radius_m", s.radius_m),
        ("spacing_m", s.spacing_m),
        ("flatten_m", s.flatten_m),
        ("min_fraction", s.min_fraction),
        ("opacity", s.opacity),
    ] {
        t.insert(key.into(), float(v));
    }
    t.insert("lod".into(), Value::Boolean(s.lod));
    for (key, v) in [("passes", s.passes), ("max_steps", s.max_steps), ("debug_pass", s.debug_pass)] {
        t.insert(key.into(), Value::Integer(i64::from(v)));
    }
    t.insert("seed".into(), Value::Integer(s.seed as i64));
    t
}
