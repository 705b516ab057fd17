//! The light-transport effects a scene calls for, and restrictions of them.
//!
//! A scene *implies* a set of [`Effect`]s ([`Scene::implied_effects`]); a scene file's
//! `[effects]` table (or a caller, through [`EffectSelection`]) may restrict that set to
//! isolate one error source. The grid pipeline (`crate::pipeline`) plans its passes from the
//! restricted set, and the path tracer is run on exactly the same effects (the mapping to
//! its `Contributions` lives in `reference::effects`, since `solvers` does not depend on
//! `reference`).
//!
//! ## Meaning of each effect, in scattering orders
//! The *order* of a light path is the number of scattering events between its emitter (a
//! light, or a voxel's volume emission j) and the camera.
//! * [`Effect::Attenuation`]: extinction along every ray (σt > 0 somewhere). It cannot be
//!   excluded: every other effect is seen through the medium's transmittance.
//! * [`Effect::SingleScattering`] `{ light }`: order 1 from light `light` (the
//!   `q_ri`-term of FLD Eq 8, evaluated with the scene's phase function).
//! * [`Effect::MultipleScattering`]: orders ≥ 2 from every light, plus orders ≥ 1 from
//!   volume emission when [`Effect::Emission`] is also in the set: the diffusion fluence φ
//!   of FLD Eq 12 is sourced by q_ri + j, so σs·φ/4π in FLD Eq 8 holds both.
//! * [`Effect::Emission`]: volume emission. Alone it is order 0 (the j/4π term of FLD
//!   Eq 8, seen through the medium); with multiple scattering also its scattered part, as
//!   above. Without it, no emission-sourced light of any order is rendered.
//! * [`Effect::Anisotropy`]: the scene's Henyey–Greenstein phase function. Excluding it
//!   replaces the phase function by the isotropic one everywhere (grid pipeline *and*
//!   path tracer: [`Effects::apply_phase`]), so the comparison stays exact.
//!
//! * [`Effect::Background`]: order 0 from the lights — the environment (and sphere lights)
//!   seen by the camera through the medium, L_env·T(camera ray). Implied by an environment
//!   or sphere light unless `[camera] hide_background = true` (Mitsuba's `hide_emitters`);
//!   the grid pipeline renders the environment's (`raymarch_background`, exact: T is a line
//!   integral of the piecewise-constant σt), and refuses a sphere light seen directly.
//!
//! ## Scene-file syntax
//! ```toml
//! [effects]
//! only = ["emission"]                    # keep only these light-transport effects
//! exclude = ["multiple_scattering"]      # then drop these
//! ```
//! Names: `attenuation`, `background`, `single_scattering` (every light) or `single_scattering[i]`
//! (light `i`, 0-based as in `[[light]]`), `multiple_scattering`, `emission`, `anisotropy`.
//! Unknown names, light indices without such a light, and excluding `attenuation` are
//! errors naming the field.

use super::{Light, Phase, Scene};
use serde::Serialize;
use std::collections::BTreeSet;
use std::fmt;
use std::str::FromStr;
use thiserror::Error;

/// One light-transport effect (see the module docs for its meaning in scattering orders).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Effect {
    /// Extinction along rays.
    Attenuation,
    /// Order-0 light from the lights: the environment (and sphere lights) seen by the camera
    /// through the medium, L·T along the camera ray. Implied by an environment or sphere
    /// light and a camera without `hide_background`.
    Background,
    /// Order-1 light from light number `light` (index into `Scene::lights`).
    SingleScattering {
        /// Index of the light.
        light: usize,
    },
    /// Orders ≥ 2 from lights, and orders ≥ 1 from emission when [`Effect::Emission`] is on.
    MultipleScattering,
    /// Volume emission j.
    Emission,
    /// A non-isotropic phase function (g ≠ 0).
    Anisotropy,
}

impl fmt::Display for Effect {
    /// The scene-file name: `single_scattering[2]`, `emission`, …
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Effect::Attenuation => write!(f, "attenuation"),
            Effect::Background => write!(f, "background"),
            Effect::SingleScattering { light } => write!(f, "single_scattering[{light}]"),
            Effect::MultipleScattering => write!(f, "multiple_scattering"),
            Effect::Emission => write!(f, "emission"),
            Effect::Anisotropy => write!(f, "anisotropy"),
        }
    }
}

impl Serialize for Effect {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

/// Errors in effect names and restrictions.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum EffectsError {
    /// Not an effect name.
    #[error(
        "unknown effect `{0}`; known: attenuation, background, single_scattering, single_scattering[i], multiple_scattering, emission, anisotropy"
    )]
    UnknownName(String),
    /// `single_scattering[i]` names a light the scene does not have.
    #[error("`single_scattering[{index}]`: the scene has {lights} light(s)")]
    NoSuchLight {
        /// The index given.
        index: usize,
        /// How many lights the scene has.
        lights: usize,
    },
    /// Attenuation cannot be excluded.
    #[error(
        "attenuation cannot be excluded: every other effect is seen through the medium's transmittance"
    )]
    AttenuationExcluded,
}

/// A pattern in an `[effects]` list: an effect, or single scattering of every light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EffectPattern {
    /// [`Effect::Attenuation`].
    Attenuation,
    /// [`Effect::Background`].
    Background,
    /// [`Effect::SingleScattering`] of light `Some(i)`, or of every light (`None`).
    SingleScattering(Option<usize>),
    /// [`Effect::MultipleScattering`].
    MultipleScattering,
    /// [`Effect::Emission`].
    Emission,
    /// [`Effect::Anisotropy`].
    Anisotropy,
}

impl EffectPattern {
    /// Whether `effect` matches.
    pub fn matches(&self, effect: &Effect) -> bool {
        match (self, effect) {
            (EffectPattern::Attenuation, Effect::Attenuation)
            | (EffectPattern::Background, Effect::Background)
            | (EffectPattern::MultipleScattering, Effect::MultipleScattering)
            | (EffectPattern::Emission, Effect::Emission)
            | (EffectPattern::Anisotropy, Effect::Anisotropy)
            | (EffectPattern::SingleScattering(None), Effect::SingleScattering { .. }) => true,
            (EffectPattern::SingleScattering(Some(i)), Effect::SingleScattering { light }) => {
                i == light
            }
            _ => false,
        }
    }
}

impl FromStr for EffectPattern {
    type Err = EffectsError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim();
        Ok(match t {
            "attenuation" => EffectPattern::Attenuation,
            "background" => EffectPattern::Background,
            "single_scattering" => EffectPattern::SingleScattering(None),
            "multiple_scattering" => EffectPattern::MultipleScattering,
            "emission" => EffectPattern::Emission,
            "anisotropy" => EffectPattern::Anisotropy,
            _ => {
                let index = t
                    .strip_prefix("single_scattering[")
                    .and_then(|r| r.strip_suffix(']'))
                    .and_then(|i| i.trim().parse::<usize>().ok())
                    .ok_or_else(|| EffectsError::UnknownName(t.to_string()))?;
                EffectPattern::SingleScattering(Some(index))
            }
        })
    }
}

impl fmt::Display for EffectPattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EffectPattern::SingleScattering(None) => write!(f, "single_scattering"),
            EffectPattern::SingleScattering(Some(i)) => write!(f, "single_scattering[{i}]"),
            EffectPattern::Attenuation => write!(f, "attenuation"),
            EffectPattern::Background => write!(f, "background"),
            EffectPattern::MultipleScattering => write!(f, "multiple_scattering"),
            EffectPattern::Emission => write!(f, "emission"),
            EffectPattern::Anisotropy => write!(f, "anisotropy"),
        }
    }
}

/// A restriction of the implied effects: keep the single-scattering, multiple-scattering
/// and emission effects that match `only` (if given; attenuation and anisotropy are
/// properties of the medium, which `only` leaves alone), then drop those matching
/// `exclude` (anisotropy can be excluded, attenuation cannot). Anisotropy is dropped when
/// nothing that scatters remains. The default restricts nothing.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct EffectSelection {
    /// Keep only effects matching one of these (`None`: keep all).
    pub only: Option<Vec<EffectPattern>>,
    /// Drop effects matching one of these.
    pub exclude: Vec<EffectPattern>,
}

impl EffectSelection {
    /// No restriction.
    pub fn all() -> Self {
        Self::default()
    }

    /// Keep only the named effects (e.g. `["emission"]`).
    pub fn only(names: &[&str]) -> Result<Self, EffectsError> {
        Ok(Self {
            only: Some(names.iter().map(|n| n.parse()).collect::<Result<_, _>>()?),
            exclude: Vec::new(),
        })
    }

    /// Drop the named effects (e.g. `["multiple_scattering"]`).
    pub fn exclude(names: &[&str]) -> Result<Self, EffectsError> {
        Ok(Self {
            only: None,
            exclude: names.iter().map(|n| n.parse()).collect::<Result<_, _>>()?,
        })
    }

    /// Checks light indices against a scene with `lights` lights and that attenuation is
    /// not excluded.
    pub fn validate(&self, lights: usize) -> Result<(), EffectsError> {
        for p in self.only.iter().flatten().chain(&self.exclude) {
            if let EffectPattern::SingleScattering(Some(index)) = *p {
                if index >= lights {
                    return Err(EffectsError::NoSuchLight { index, lights });
                }
            }
        }
        if self.exclude.contains(&EffectPattern::Attenuation) {
            return Err(EffectsError::AttenuationExcluded);
        }
        Ok(())
    }
}

/// A set of effects.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Effects(pub BTreeSet<Effect>);

impl Effects {
    /// The empty set.
    pub fn none() -> Self {
        Self::default()
    }

    /// Whether `e` is in the set.
    pub fn contains(&self, e: Effect) -> bool {
        self.0.contains(&e)
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The lights whose single scattering is in the set, ascending.
    pub fn single_scattering_lights(&self) -> Vec<usize> {
        self.0
            .iter()
            .filter_map(|e| match e {
                Effect::SingleScattering { light } => Some(*light),
                _ => None,
            })
            .collect()
    }

    /// The union of two sets.
    pub fn union(&self, other: &Effects) -> Effects {
        Effects(self.0.union(&other.0).copied().collect())
    }

    /// The set restricted by `sel` (which must be valid for a scene with `lights` lights).
    pub fn restrict(&self, sel: &EffectSelection, lights: usize) -> Result<Effects, EffectsError> {
        sel.validate(lights)?;
        Ok(Effects(
            self.0
                .iter()
                .filter(|e| {
                    matches!(e, Effect::Attenuation | Effect::Anisotropy)
                        || sel
                            .only
                            .as_ref()
                            .is_none_or(|only| only.iter().any(|p| p.matches(e)))
                })
                .filter(|e| !sel.exclude.iter().any(|p| p.matches(e)))
                .copied()
                .collect(),
        )
        .drop_orphan_anisotropy())
    }

    /// Anisotropy only matters while something scatters: without single or multiple
    /// scattering in the set it is dropped.
    fn drop_orphan_anisotropy(mut self) -> Effects {
        let scatters = self.0.iter().any(|e| {
            matches!(
                e,
                Effect::SingleScattering { .. } | Effect::MultipleScattering
            )
        });
        if !scatters {
            self.0.remove(&Effect::Anisotropy);
        }
        self
    }

    /// The phase function a renderer of this effect set uses for `scene`: the scene's, or
    /// isotropic when [`Effect::Anisotropy`] is not in the set.
    pub fn apply_phase(&self, phase: Phase) -> Phase {
        if self.contains(Effect::Anisotropy) {
            phase
        } else {
            Phase::Isotropic
        }
    }

    /// The names, comma-separated (for `--explain`).
    pub fn names(&self) -> String {
        if self.0.is_empty() {
            return "(none)".to_string();
        }
        self.0
            .iter()
            .map(|e| e.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl Scene {
    /// The effects this scene calls for:
    /// * attenuation if σt > 0 somewhere;
    /// * single scattering of light i if σs = α·σt > 0 somewhere (for every light);
    /// * multiple scattering if σs > 0 somewhere and there is a source (a light, or j > 0);
    /// * emission if j > 0 somewhere;
    /// * anisotropy if g ≠ 0 and σs > 0 somewhere;
    /// * background if the camera sees the lights directly (an environment or sphere light,
    ///   and a camera without `hide_background`).
    pub fn implied_effects(&self) -> Effects {
        let m = &self.medium;
        let mut set = BTreeSet::new();
        if m.sigma_t.iter().any(|&s| s > 0.0) {
            set.insert(Effect::Attenuation);
        }
        let scatters = m.sigma_t.iter().zip(&m.albedo).any(|(&s, &a)| s * a > 0.0);
        let emits = m.emission.iter().any(|&j| j > 0.0);
        if scatters {
            for light in 0..self.lights.len() {
                set.insert(Effect::SingleScattering { light });
            }
            if !self.lights.is_empty() || emits {
                set.insert(Effect::MultipleScattering);
            }
            if self.phase.mean_cosine() != 0.0 {
                set.insert(Effect::Anisotropy);
            }
        }
        if emits {
            set.insert(Effect::Emission);
        }
        let seen = self
            .lights
            .iter()
            .any(|l| matches!(l, Light::Environment { .. } | Light::Sphere { .. }));
        if seen && self.camera.is_some_and(|c| !c.hide_background) {
            set.insert(Effect::Background);
        }
        Effects(set)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Light, Sampler};
    use crate::{Grid, Medium};

    fn scene(albedo: f64, j: f64, lights: usize, g: f64) -> Scene {
        let grid = Grid::cube(4, 1.0).unwrap();
        let mut medium = Medium::homogeneous(grid, 2.0, albedo).unwrap();
        medium.emission = vec![j; grid.len()];
        Scene {
            interpolation: Default::default(),
            medium,
            phase: if g == 0.0 {
                Phase::Isotropic
            } else {
                Phase::HenyeyGreenstein { g }
            },
            lights: (0..lights)
                .map(|_| Light::directional([0.0, 0.0, -1.0], 1.0).unwrap())
                .collect(),
            camera: None,
            sampler: Sampler { spp: 1, seed: 0 },
        }
    }

    #[test]
    fn implied_effects_follow_the_scene() {
        use Effect::*;
        let s = scene(0.5, 1.0, 2, 0.3).implied_effects();
        assert_eq!(
            s.0.iter().copied().collect::<Vec<_>>(),
            vec![
                Attenuation,
                SingleScattering { light: 0 },
                SingleScattering { light: 1 },
                MultipleScattering,
                Emission,
                Anisotropy
            ]
        );
        // Albedo 0: nothing scatters, so no scattering and no anisotropy.
        let s = scene(0.0, 1.0, 2, 0.3).implied_effects();
        assert_eq!(s.names(), "attenuation, emission");
        // No lights, no emission: attenuation only (nothing to see).
        let s = scene(0.9, 0.0, 0, 0.0).implied_effects();
        assert_eq!(s.names(), "attenuation");
        // Emission but no lights: multiple scattering of the emission.
        let s = scene(0.9, 1.0, 0, 0.0).implied_effects();
        assert_eq!(s.names(), "attenuation, multiple_scattering, emission");
    }

    #[test]
    fn restrictions_keep_only_then_exclude() {
        let full = scene(0.5, 1.0, 2, 0.3).implied_effects();
        let only = EffectSelection::only(&["emission"]).unwrap();
        assert_eq!(
            full.restrict(&only, 2).unwrap().names(),
            "attenuation, emission"
        );
        let ex =
            EffectSelection::exclude(&["multiple_scattering", "single_scattering[1]"]).unwrap();
        assert_eq!(
            full.restrict(&ex, 2).unwrap().names(),
            "attenuation, single_scattering[0], emission, anisotropy"
        );
        let ss = EffectSelection::only(&["single_scattering"]).unwrap();
        assert_eq!(
            full.restrict(&ss, 2).unwrap().single_scattering_lights(),
            vec![0, 1]
        );
        assert_eq!(
            "bounce".parse::<EffectPattern>(),
            Err(EffectsError::UnknownName("bounce".into()))
        );
        let bad = EffectSelection::only(&["single_scattering[2]"]).unwrap();
        assert_eq!(
            full.restrict(&bad, 2),
            Err(EffectsError::NoSuchLight {
                index: 2,
                lights: 2
            })
        );
        let bad = EffectSelection::exclude(&["attenuation"]).unwrap();
        assert_eq!(
            full.restrict(&bad, 2),
            Err(EffectsError::AttenuationExcluded)
        );
        let no_aniso = full
            .restrict(&EffectSelection::exclude(&["anisotropy"]).unwrap(), 2)
            .unwrap();
        assert_eq!(
            no_aniso.apply_phase(Phase::HenyeyGreenstein { g: 0.3 }),
            Phase::Isotropic
        );
        assert_eq!(
            full.apply_phase(Phase::HenyeyGreenstein { g: 0.3 }),
            Phase::HenyeyGreenstein { g: 0.3 }
        );
    }
}
