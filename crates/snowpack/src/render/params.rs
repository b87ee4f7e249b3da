//! What a technical artist tunes: the material preset, the light, the level
//! of detail and the debug view.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use glam::Vec3;

/// Surface materials that swap in by name (Wasmut section 6; the blog's mud and sand).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum MaterialPreset {
    /// Fresh powder over compacted trails: bright, rough, blue-tinted scattering, sparkle.
    #[default]
    Snow,
    /// Wet mud: dark, smoother and darker where pressed, no sparkle.
    Mud,
    /// Dry sand: warm, rough, slightly darker where pressed.
    Sand,
}

impl MaterialPreset {
    /// Every preset with its name.
    pub const ALL: [(Self, &'static str); 3] = [(Self::Snow, "snow"), (Self::Mud, "mud"), (Self::Sand, "sand")];

    /// The preset's name in scene files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        Self::ALL.iter().find(|(p, _)| *p == self).map_or("snow", |(_, n)| n)
    }

    /// The preset named `name`, if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(_, n)| *n == name).map(|(p, _)| *p)
    }

    /// The preset's parameters.
    #[must_use]
    pub fn material(self) -> Material {
        match self {
            Self::Snow => Material {
                preset: self,
                fresh_albedo: Vec3::new(0.92, 0.94, 0.98),
                fresh_roughness: 0.8,
                packed_albedo: Vec3::new(0.6, 0.66, 0.76),
                packed_roughness: 0.45,
                ground_albedo: Vec3::new(0.22, 0.19, 0.16),
                ground_roughness: 0.9,
                scatter: Vec3::new(0.45, 0.7, 1.0),
                wrap: 0.45,
                sparkle: 1.0,
                detail_strength: 0.25,
                detail_frequency: 0.6,
                macro_variation: 0.05,
                compaction_full: 0.35,
                packed_detail: 0.3,
                packed_sparkle: 0.1,
                ground_show_through: 0.6,
            },
            Self::Mud => Material {
                preset: self,
                fresh_albedo: Vec3::new(0.26, 0.19, 0.13),
                fresh_roughness: 0.6,
                packed_albedo: Vec3::new(0.15, 0.11, 0.075),
                packed_roughness: 0.3,
                ground_albedo: Vec3::new(0.2, 0.16, 0.12),
                ground_roughness: 0.8,
                scatter: Vec3::new(0.35, 0.22, 0.12),
                wrap: 0.1,
                sparkle: 0.0,
                detail_strength: 0.35,
                detail_frequency: 0.8,
                macro_variation: 0.15,
                compaction_full: 0.3,
                packed_detail: 0.5,
                packed_sparkle: 0.0,
                ground_show_through: 0.35,
            },
            Self::Sand => Material {
                preset: self,
                fresh_albedo: Vec3::new(0.74, 0.62, 0.44),
                fresh_roughness: 0.9,
                packed_albedo: Vec3::new(0.6, 0.49, 0.33),
                packed_roughness: 0.8,
                ground_albedo: Vec3::new(0.45, 0.38, 0.28),
                ground_roughness: 0.9,
                scatter: Vec3::new(1.0, 0.8, 0.6),
                wrap: 0.15,
                sparkle: 0.12,
                detail_strength: 0.4,
                detail_frequency: 1.2,
                macro_variation: 0.1,
                compaction_full: 0.4,
                packed_detail: 0.6,
                packed_sparkle: 0.3,
                ground_show_through: 0.3,
            },
        }
    }
}

/// A surface material: fresh and compacted looks, bare ground, scattering and detail.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// The preset it started from (what `[render] material` names).
    pub preset: MaterialPreset,
    /// Albedo of undisturbed snow (linear RGB).
    pub fresh_albedo: Vec3,
    /// Roughness of undisturbed snow (GGX, perceptual).
    pub fresh_roughness: f32,
    /// Albedo where pressed to the full depth (trails are darker).
    pub packed_albedo: Vec3,
    /// Roughness where pressed (trails are smoother).
    pub packed_roughness: f32,
    /// Albedo of bare ground where the snow is gone.
    pub ground_albedo: Vec3,
    /// Roughness of bare ground.
    pub ground_roughness: f32,
    /// Tint of light wrapped past the terminator (subsurface approximation).
    pub scatter: Vec3,
    /// Wrap amount: 0 is Lambert, 1 lights the whole sphere.
    pub wrap: f32,
    /// Strength of grain glints at grazing light (0 off).
    pub sparkle: f32,
    /// Strength of the detail normal map.
    pub detail_strength: f32,
    /// Frequency of the detail normal map (repeats per metre).
    pub detail_frequency: f32,
    /// Amplitude of the low-frequency brightness drift.
    pub macro_variation: f32,
    /// The compacted look (`packed_*`) follows the packed snow the surface
    /// shows, on the scale of its hardness (`docs/rendering.md`); it is
    /// complete where that is as much as a press of this fraction of the
    /// rest depth (0..1) packs.
    pub compaction_full: f32,
    /// Fraction of the detail normal kept in fully compacted snow (1: as fresh).
    pub packed_detail: f32,
    /// Fraction of the sparkle kept in fully compacted snow (1: as fresh).
    pub packed_sparkle: f32,
    /// How much of the ground colour shows at the bottom of a print pressed
    /// to the ground (0 none, 1 the ground's albedo and roughness); it rises
    /// over the last quarter of the depth, so a deep print shows it before
    /// the snow is gone.
    pub ground_show_through: f32,
}

impl Material {
    /// This material with the compacted look switched off: trails have the
    /// fresh albedo, roughness, detail and sparkle and no ground shows
    /// through (bare ground where the snow is gone still shows). For
    /// before/after comparisons.
    #[must_use]
    pub fn without_compaction(self) -> Self {
        Self {
            packed_albedo: self.fresh_albedo,
            packed_roughness: self.fresh_roughness,
            packed_detail: 1.0,
            packed_sparkle: 1.0,
            ground_show_through: 0.0,
            ..self
        }
    }
}

/// What the terrain and actors show instead of the lit image (Wasmut's appendix).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum DebugView {
    /// The lit image.
    #[default]
    Lit,
    /// World-space normals as colour.
    Normals,
    /// Ambient occlusion.
    AmbientOcclusion,
    /// Level of detail, one colour per level.
    LevelOfDetail,
    /// The patch grid over the lit image.
    Wireframe,
    /// Depth pressed below rest (red) and raised rims (blue).
    Deformation,
}

impl DebugView {
    /// Every view with its name.
    pub const ALL: [(Self, &'static str); 6] = [
        (Self::Lit, "lit"),
        (Self::Normals, "normals"),
        (Self::AmbientOcclusion, "ao"),
        (Self::LevelOfDetail, "lod"),
        (Self::Wireframe, "wireframe"),
        (Self::Deformation, "deformation"),
    ];

    /// The view's name in scene files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        Self::ALL.iter().find(|(p, _)| *p == self).map_or("lit", |(_, n)| n)
    }

    /// The view named `name`, if any.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(_, n)| *n == name).map(|(p, _)| *p)
    }

    /// Index the shaders switch on (`VIEW_*` in `shared/frame.wgsl`).
    #[must_use]
    pub fn index(self) -> u32 {
        Self::ALL.iter().position(|(p, _)| *p == self).unwrap_or(0) as u32
    }
}

/// The sun and the sky.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightParams {
    /// Unit vector toward the sun; `None` takes the environment's brightest direction.
    pub sun_direction: Option<Vec3>,
    /// Sun irradiance relative to the sky's (linear).
    pub sun_intensity: f32,
    /// Multiplier on the environment (sky light and background).
    pub sky_intensity: f32,
    /// Exposure in stops, applied before the tone map.
    pub exposure_ev: f32,
}

impl Default for LightParams {
    fn default() -> Self {
        Self { sun_direction: None, sun_intensity: 3.0, sky_intensity: 1.0, exposure_ev: 0.0 }
    }
}

/// Sun direction from elevation above the horizon and azimuth (degrees,
/// clockwise from +z toward +x seen from above).
#[must_use]
pub fn sun_from_angles(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
}

impl Default for Material {
    fn default() -> Self {
        MaterialPreset::Snow.material()
    }
}

/// Everything the renderer is told besides the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderParams {
    /// Surface material: a preset's parameters, possibly tuned.
    pub material: Material,
    /// Sun and sky.
    pub light: LightParams,
    /// What to show.
    pub debug_view: DebugView,
    /// Terrain drawn out to this distance from the camera (m).
    pub view_distance_m: f32,
    /// Shadows drawn out to this distance (m); the shadow map covers it.
    pub shadow_distance_m: f32,
    /// Side of the shadow map (texels).
    pub shadow_map_size: u32,
    /// Side of the finest patch (m); each coarser level doubles it.
    pub finest_patch_m: f32,
    /// Quads per patch side (even).
    pub patch_quads: u32,
    /// Strength of the height-field ambient occlusion (0 off, 1 full).
    pub ao_strength: f32,
    /// Draw this colour instead of the sky (tests and seam checks).
    pub background: Option<Vec3>,
    /// Drawn spheres' mesh: segments around and rings from pole to pole
    /// (`segments+1` x `rings+1` vertices); fixed when the renderer is built.
    /// The capture does not use it (it ray-casts spheres exactly).
    pub sphere_mesh: [u32; 2],
    /// Volumetric detail over the snow near the camera (shell mapping); off by default.
    pub shell: crate::render::shell::ShellSettings,
}

impl Default for RenderParams {
    fn default() -> Self {
        Self {
            material: MaterialPreset::Snow.material(),
            light: LightParams::default(),
            debug_view: DebugView::Lit,
            view_distance_m: 1000.0,
            shadow_distance_m: 80.0,
            shadow_map_size: 2048,
            finest_patch_m: 1.0,
            patch_quads: 16,
            ao_strength: 1.0,
            background: None,
            sphere_mesh: [32, 16],
            shell: crate::render::shell::ShellSettings::default(),
        }
    }
}
