//! Conversion of the schema into the data model: the context [`Cx`] (locator, directory of
//! `.vol` paths, document text) and its conversions of the phase function, lights, camera,
//! effects and the `[medium]` keys that override a base medium (box, density scale, albedo,
//! emission). The base medium itself comes from [`super::medium`].

use super::SceneFileError;
use super::locate::Locator;
use super::schema::{CameraDoc, EffectsDoc, LightDoc, MediumDoc, PhaseDoc};
use crate::error::{Compact, indefinite};
use crate::scene::effects::{EffectPattern, EffectSelection, EffectsError};
use crate::scene::vol::{VolError, VolGrid};
use crate::scene::{Camera, Light, Phase, Projection};
use crate::{Grid, Medium, SolverError};
use std::path::Path;

/// Conversion context: the locator, the directory `.vol` paths are relative to, and the text.
pub(super) struct Cx<'a> {
    pub(super) loc: &'a Locator<'a>,
    pub(super) dir: &'a Path,
    pub(super) text: &'a str,
}

pub(super) fn finite3(v: [f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Cx<'_> {
    pub(super) fn read_vol(&self, field: &str, rel: &str) -> Result<VolGrid, SceneFileError> {
        let path = self.dir.join(rel);
        VolGrid::read(&path).map_err(|e| match e {
            VolError::Io { source, .. } => self
                .loc
                .err(field, format!("cannot read `{}`: {source}", path.display())),
            e => self.loc.err(
                field,
                format!(
                    "`{}` is not a valid .vol file: {}",
                    path.display(),
                    crate::error::chain(&e)
                ),
            ),
        })
    }

    /// A one-channel field of a `.vol` file that must have `dims` cells.
    fn vol_field(
        &self,
        field: &str,
        rel: &str,
        dims: [usize; 3],
    ) -> Result<Vec<f64>, SceneFileError> {
        let v = self.read_vol(field, rel)?;
        if v.dims != dims {
            return Err(self.loc.err(
                field,
                format!(
                    "`{rel}` has {:?} cells but the density grid has {dims:?}",
                    v.dims
                ),
            ));
        }
        self.single_channel(field, rel, &v)
    }

    pub(super) fn single_channel(
        &self,
        field: &str,
        rel: &str,
        v: &VolGrid,
    ) -> Result<Vec<f64>, SceneFileError> {
        match v.channels {
            1 => v
                .channel(0)
                .ok_or_else(|| self.loc.err(field, "empty grid")),
            c => Err(self.loc.err(
                field,
                format!("`{rel}` has {c} channels; scatterbench media are monochrome (1 channel)"),
            )),
        }
    }

    /// Applies the box, density scale, albedo and emission keys of `[medium]` to `base`.
    pub(super) fn overrides(
        &self,
        m: &MediumDoc,
        base: Medium<f64>,
        density_field: &str,
    ) -> Result<Medium<f64>, SceneFileError> {
        let loc = self.loc;
        let Medium {
            mut grid,
            mut sigma_t,
            mut albedo,
            mut emission,
        } = base;
        // Box.
        match (m.min, m.max) {
            (None, None) => {}
            (Some(_), None) => return Err(loc.err("medium.min", "give `max` with `min`")),
            (None, Some(_)) => return Err(loc.err("medium.max", "give `min` with `max`")),
            (Some(min), Some(max)) => {
                if !finite3(min) {
                    return Err(loc.err("medium.min", "coordinates must be finite"));
                }
                if !finite3(max) || (0..3).any(|a| max[a] <= min[a]) {
                    return Err(loc.err(
                        "medium.max",
                        "coordinates must be finite and larger than `min` on every axis",
                    ));
                }
                let edges = [0, 1, 2].map(|a| (max[a] - min[a]) / grid.n[a] as f64);
                if edges.iter().any(|e| (e - edges[0]).abs() > 1e-9 * edges[0]) {
                    return Err(loc.err(
                        "medium.max",
                        format!(
                            "voxels are not cubic: the box {:?}..{:?} over {:?} cells gives edges {:?}; make (max - min)/n equal on every axis",
                            min, max, grid.n, edges
                        ),
                    ));
                }
                grid = Grid::with_origin(grid.n, edges[0], min)
                    .map_err(|e| loc.err("medium.max", e.to_string()))?;
            }
        }
        if let Some(s) = m.density_scale {
            if !(s.is_finite() && s >= 0.0) {
                return Err(loc.err("medium.density_scale", "must be finite and >= 0"));
            }
            sigma_t.iter_mut().for_each(|v| *v *= s);
        }
        let n = grid.len();
        match &m.albedo {
            None => {}
            Some(toml::Value::Float(_) | toml::Value::Integer(_)) => {
                let a = number(m.albedo.as_ref()).unwrap_or(f64::NAN);
                if !(0.0..=1.0).contains(&a) {
                    return Err(loc.err("medium.albedo", format!("{a} is outside [0, 1]")));
                }
                albedo = vec![a; n];
            }
            Some(toml::Value::String(rel)) => {
                albedo = self.vol_field("medium.albedo", rel, grid.n)?;
            }
            Some(v) => {
                return Err(loc.err(
                    "medium.albedo",
                    format!("expected a number or a .vol path, found {}", v.type_str()),
                ));
            }
        }
        match &m.emission {
            None => {}
            Some(toml::Value::String(s)) if s == "none" => emission = vec![0.0; n],
            Some(toml::Value::Float(_) | toml::Value::Integer(_)) => {
                let j = number(m.emission.as_ref()).unwrap_or(f64::NAN);
                if !(j.is_finite() && j >= 0.0) {
                    return Err(loc.err("medium.emission", format!("{j} must be finite and >= 0")));
                }
                emission = vec![j; n];
            }
            Some(toml::Value::String(rel)) => {
                emission = self.vol_field("medium.emission", rel, grid.n)?;
            }
            Some(v) => {
                return Err(loc.err(
                    "medium.emission",
                    format!(
                        "expected \"none\", a number or a .vol path, found {}",
                        v.type_str()
                    ),
                ));
            }
        }
        Medium::new(grid, sigma_t, albedo, emission).map_err(|e| match e {
            SolverError::FieldValue {
                field: "sigma_t", ..
            } => loc.err(density_field, e.to_string()),
            SolverError::FieldValue { field, .. } => {
                loc.err(&format!("medium.{field}"), e.to_string())
            }
            e => loc.err("medium", e.to_string()),
        })
    }

    pub(super) fn effects(
        &self,
        e: Option<&EffectsDoc>,
        lights: usize,
    ) -> Result<EffectSelection, SceneFileError> {
        let Some(e) = e else {
            return Ok(EffectSelection::all());
        };
        let list = |key: &str, names: &[String]| -> Result<Vec<EffectPattern>, SceneFileError> {
            names
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    let field = format!("effects.{key}[{i}]");
                    let p: EffectPattern = n
                        .parse()
                        .map_err(|e: EffectsError| self.loc.err(&field, e.to_string()))?;
                    if let EffectPattern::SingleScattering(Some(index)) = p {
                        if index >= lights {
                            return Err(self.loc.err(
                                &field,
                                format!(
                                    "the scene has {lights} light(s), so there is no light {index}"
                                ),
                            ));
                        }
                    }
                    if key == "exclude" && p == EffectPattern::Attenuation {
                        return Err(self
                            .loc
                            .err(&field, EffectsError::AttenuationExcluded.to_string()));
                    }
                    Ok(p)
                })
                .collect()
        };
        Ok(EffectSelection {
            only: e.only.as_deref().map(|o| list("only", o)).transpose()?,
            exclude: list("exclude", e.exclude.as_deref().unwrap_or_default())?,
        })
    }

    pub(super) fn phase(&self, p: Option<&PhaseDoc>) -> Result<Phase, SceneFileError> {
        let Some(p) = p else {
            return Ok(Phase::Isotropic);
        };
        let phase = match (p.kind.as_str(), p.g) {
            ("isotropic", None) => Phase::Isotropic,
            ("isotropic", Some(_)) => {
                return Err(self
                    .loc
                    .err("phase.g", "an isotropic phase function takes no `g`"));
            }
            ("hg", Some(g)) => Phase::HenyeyGreenstein { g },
            ("hg", None) => {
                return Err(self.loc.err("phase", "type \"hg\" needs `g` in (-1, 1)"));
            }
            (other, _) => {
                return Err(self.loc.err(
                    "phase.type",
                    format!("unknown phase function `{other}`; known: isotropic, hg"),
                ));
            }
        };
        phase
            .validate()
            .map_err(|_| self.loc.err("phase.g", "must lie in (-1, 1)"))?;
        Ok(phase)
    }

    pub(super) fn light(&self, i: usize, l: &LightDoc) -> Result<Light, SceneFileError> {
        let at = |f: &str| format!("light[{i}].{f}");
        let present: [(&str, bool); 7] = [
            ("position", l.position.is_some()),
            ("power", l.power.is_some()),
            ("direction", l.direction.is_some()),
            ("irradiance", l.irradiance.is_some()),
            ("center", l.center.is_some()),
            ("radius", l.radius.is_some()),
            ("radiance", l.radiance.is_some()),
        ];
        let takes: &[&str] = match l.kind.as_str() {
            "point" => &["position", "power"],
            "directional" => &["direction", "irradiance"],
            "sphere" => &["center", "radius", "radiance"],
            "environment" => &["radiance"],
            other => {
                return Err(self.loc.err(
                    &at("type"),
                    format!("unknown light type `{other}`; known: point, directional, sphere, environment"),
                ));
            }
        };
        for (name, is) in present {
            if is && !takes.contains(&name) {
                return Err(self.loc.err(
                    &at(name),
                    format!(
                        "not a parameter of {} light (it takes {})",
                        indefinite(&l.kind),
                        takes.join(", ")
                    ),
                ));
            }
            if !is && takes.contains(&name) {
                return Err(self.loc.err(
                    &format!("light[{i}]"),
                    format!("{} light needs `{name}`", indefinite(&l.kind)),
                ));
            }
        }
        let z3 = [0.0; 3];
        let light = match l.kind.as_str() {
            "point" => Light::Point {
                position: l.position.unwrap_or(z3),
                power: l.power.unwrap_or(0.0),
            },
            "directional" => {
                let d = l.direction.unwrap_or(z3);
                Light::directional(d, l.irradiance.unwrap_or(0.0))
                    .map_err(|e| self.light_err(i, e))?
            }
            "sphere" => Light::Sphere {
                center: l.center.unwrap_or(z3),
                radius: l.radius.unwrap_or(0.0),
                radiance: l.radiance.unwrap_or(0.0),
            },
            _ => Light::Environment {
                radiance: l.radiance.unwrap_or(0.0),
            },
        };
        light.validate().map_err(|e| self.light_err(i, e))?;
        Ok(light)
    }

    fn light_err(&self, i: usize, e: SolverError) -> SceneFileError {
        match e {
            SolverError::BadParameter {
                name,
                value,
                reason,
            } => {
                let field = name.strip_prefix("light.").unwrap_or(name);
                self.loc.err(
                    &format!("light[{i}].{field}"),
                    format!("{} is invalid: {reason}", Compact(value)),
                )
            }
            e => self.loc.err(&format!("light[{i}]"), e.to_string()),
        }
    }

    pub(super) fn camera(&self, c: &CameraDoc) -> Result<Camera, SceneFileError> {
        let loc = self.loc;
        let projection = match (c.projection.as_str(), c.width, c.fov_y) {
            ("orthographic", Some(width), None) => Projection::Orthographic { width },
            ("perspective", None, Some(fov_y_degrees)) => Projection::Perspective { fov_y_degrees },
            ("orthographic", None, _) => {
                return Err(loc.err("camera", "an orthographic camera needs `width`"));
            }
            ("orthographic", Some(_), Some(_)) => {
                return Err(loc.err(
                    "camera.fov_y",
                    "an orthographic camera takes `width`, not `fov_y`",
                ));
            }
            ("perspective", _, None) => {
                return Err(loc.err("camera", "a perspective camera needs `fov_y` (degrees)"));
            }
            ("perspective", Some(_), Some(_)) => {
                return Err(loc.err(
                    "camera.width",
                    "a perspective camera takes `fov_y`, not `width`",
                ));
            }
            (other, _, _) => {
                return Err(loc.err(
                    "camera.projection",
                    format!("unknown projection `{other}`; known: orthographic, perspective"),
                ));
            }
        };
        for (name, v) in [("eye", c.eye), ("target", c.target), ("up", c.up)] {
            if !finite3(v) {
                return Err(loc.err(&format!("camera.{name}"), "coordinates must be finite"));
            }
        }
        let camera = Camera {
            hide_background: c.hide_background.unwrap_or(false),
            eye: c.eye,
            target: c.target,
            up: c.up,
            projection,
            resolution: c.resolution,
        };
        camera.validate().map_err(|e| match e {
            SolverError::BadParameter {
                name,
                value,
                reason,
            } => {
                let field = match name {
                    "camera.fov_y_degrees" => "camera.fov_y",
                    n => n,
                };
                loc.err(field, format!("{} is invalid: {reason}", Compact(value)))
            }
            e => loc.err("camera", e.to_string()),
        })?;
        Ok(camera)
    }
}

fn number(v: Option<&toml::Value>) -> Option<f64> {
    match v? {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}
