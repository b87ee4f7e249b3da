//! The deformation techniques Wasmut 2019 compares, behind one switch, and
//! the rim formulas of the points technique.
#![cfg_attr(
    not(feature = "low_level"),
    allow(dead_code, unused_imports, reason = "what the app, the scene loader and the tests use beyond the front door, reached through `low_level`")
)]

use std::str::FromStr;

/// How actors deform the snow (Wasmut 2019 compares the four).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Technique {
    /// Actors' depth captured from below (Horizon Zero Dawn, Hanák).
    #[default]
    Depth,
    /// Deferred point deformation (Rise of the Tomb Raider).
    Points,
    /// Decals that never change the height field.
    Decals,
    /// Depth and points, the lower of the two.
    Combined,
}

impl Technique {
    /// Every technique, in scene-file spelling.
    #[cfg(feature = "low_level")]
    pub const ALL: [Technique; 4] = [Self::Depth, Self::Points, Self::Decals, Self::Combined];
    /// Every technique, in scene-file spelling.
    #[cfg(not(feature = "low_level"))]
    #[allow(dead_code, reason = "the app's and the tests' list of techniques (`low_level`)")]
    pub(crate) const ALL: [Technique; 4] = [Self::Depth, Self::Points, Self::Decals, Self::Combined];
}

impl FromStr for Technique {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|t| t.as_str() == s).ok_or_else(|| format!("{s:?} is not one of depth, points, decals, combined"))
    }
}

/// How the points technique raises rims from the stored foot height
/// (Wasmut 2019, sections 2.2.2 and 4.2.2). Both use the elevation distance
/// `e = sqrt(h - foot) - sqrt(rest - foot)` over its maximum
/// `M = sqrt(rest - foot)`, `ratio = e / M`, and a peak of
/// `elevation * RIM_PEAK * (rest - foot)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum RimStyle {
    /// Michels and Sikachev (GPU Pro 7): `1 - (0.5 - 2 ratio)^2` times the
    /// peak. It starts at 0.75 of the peak at the depression's edge (a step),
    /// peaks at ratio 0.25 and is gone at 0.75.
    Ms16,
    /// Wasmut's rounded variant: `1 - (2 ratio - 1)^2` times the peak; zero at
    /// the depression's edge and at `M`, highest half way: a rounded rim.
    #[default]
    Rounded,
}

impl RimStyle {}

impl FromStr for RimStyle {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "ms16" => Ok(Self::Ms16),
            "rounded" => Ok(Self::Rounded),
            _ => Err(format!("{s:?} is not one of ms16, rounded")),
        }
    }
}

/// Peak rim height as a fraction of the depression's depth at `elevation = 1`.
pub const RIM_PEAK: f32 = 0.25;

/// What snowpack's own app, tools and tests read of a [`Technique`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`Technique`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait TechniqueExt: Sized {
    /// The scene-file spelling.
    #[must_use]
    fn as_str(&self) -> &'static str;

    /// Whether the technique stamps contact points' footprints (and so needs
    /// the window's footprint buffer).
    #[must_use]
    fn uses_stamps(self) -> bool;
}

impl TechniqueExt for Technique {
    fn as_str(&self) -> &'static str {
        match self {
            Self::Depth => "depth",
            Self::Points => "points",
            Self::Decals => "decals",
            Self::Combined => "combined",
        }
    }

    fn uses_stamps(self) -> bool {
        matches!(self, Self::Points | Self::Combined)
    }
}

/// What snowpack's own app, tools and tests read of a [`RimStyle`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`RimStyle`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait RimStyleExt: Sized {
    /// The scene-file spelling.
    #[must_use]
    fn as_str(&self) -> &'static str;
}

impl RimStyleExt for RimStyle {
    fn as_str(&self) -> &'static str {
        match self {
            Self::Ms16 => "ms16",
            Self::Rounded => "rounded",
        }
    }
}
