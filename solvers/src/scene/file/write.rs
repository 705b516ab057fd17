//! Writing a scene as a format-1 file with its voxel fields as `.vol` files beside it.

use super::schema::{
    CameraDoc, Doc, EffectsDoc, LightDoc, MediumDoc, OutputsDoc, PhaseDoc, SamplerDoc,
};
use super::{FORMAT_VERSION, SceneFile, SceneFileError};
use crate::scene::effects::EffectSelection;
use crate::scene::vol::{VolError, VolGrid};
use crate::scene::{Interpolation, Light, Phase, Projection};
use std::path::Path;

impl SceneFile {
    /// Writes the scene as a format-1 file at `path`, with its voxel fields as `.vol` files
    /// beside it (`<stem>.sigma_t.vol`, and `<stem>.albedo.vol` / `<stem>.emission.vol`
    /// unless the field is constant). Fields are rounded to `f32` by the `.vol` format.
    /// Coloured scenes (see [`SceneFile::channels`]) cannot be written yet: the `.vol`
    /// reader takes one channel; they are an error naming `medium`.
    pub fn write(&self, path: &Path) -> Result<(), SceneFileError> {
        if self.colour.is_some() {
            return Err(SceneFileError::Invalid {
                file: path.to_path_buf(),
                field: "medium".into(),
                line: None,
                column: None,
                problem: "writing coloured (RGB) scenes is not supported".into(),
            });
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".to_string());
        let s = &self.scene;
        let g = &s.medium.grid;
        let vol_err = |e: VolError| match e {
            VolError::Io { path, source } => SceneFileError::Io { path, source },
            e => SceneFileError::Invalid {
                file: path.to_path_buf(),
                field: "medium".into(),
                line: None,
                column: None,
                problem: crate::error::chain(&e),
            },
        };
        let write_field = |name: &str, values: &[f64]| -> Result<toml::Value, SceneFileError> {
            if values.iter().all(|&v| v == values[0]) {
                return Ok(toml::Value::Float(values[0]));
            }
            let file = format!("{stem}.{name}.vol");
            VolGrid::from_field(g, values)
                .and_then(|v| v.write(&dir.join(&file)))
                .map_err(vol_err)?;
            Ok(toml::Value::String(file))
        };
        let sigma_file = format!("{stem}.sigma_t.vol");
        VolGrid::from_field(g, &s.medium.sigma_t)
            .and_then(|v| v.write(&dir.join(&sigma_file)))
            .map_err(vol_err)?;
        let albedo = write_field("albedo", &s.medium.albedo)?;
        let emission = if s.medium.emission.iter().all(|&j| j == 0.0) {
            toml::Value::String("none".into())
        } else {
            write_field("emission", &s.medium.emission)?
        };
        let doc = Doc {
            format: FORMAT_VERSION,
            description: self.description.clone(),
            medium: MediumDoc {
                file: Some(sigma_file),
                albedo: Some(albedo),
                emission: Some(emission),
                interpolation: (s.interpolation != Interpolation::Nearest)
                    .then(|| s.interpolation.name().to_string()),
                ..MediumDoc::default()
            },
            phase: Some(match s.phase {
                Phase::Isotropic => PhaseDoc {
                    kind: "isotropic".into(),
                    g: None,
                },
                Phase::HenyeyGreenstein { g } => PhaseDoc {
                    kind: "hg".into(),
                    g: Some(g),
                },
            }),
            lights: s.lights.iter().map(light_doc).collect(),
            camera: s.camera.map(|c| {
                let (projection, width, fov_y) = match c.projection {
                    Projection::Orthographic { width } => ("orthographic", Some(width), None),
                    Projection::Perspective { fov_y_degrees } => {
                        ("perspective", None, Some(fov_y_degrees))
                    }
                };
                CameraDoc {
                    eye: c.eye,
                    target: c.target,
                    up: c.up,
                    projection: projection.into(),
                    width,
                    fov_y,
                    resolution: c.resolution,
                    hide_background: c.hide_background.then_some(true),
                }
            }),
            sampler: Some(SamplerDoc {
                spp: s.sampler.spp,
                seed: s.sampler.seed,
            }),
            outputs: Some(OutputsDoc {
                write: self.outputs.iter().map(|o| o.name().to_string()).collect(),
            }),
            effects: (self.effects != EffectSelection::all()).then(|| EffectsDoc {
                only: self
                    .effects
                    .only
                    .as_ref()
                    .map(|o| o.iter().map(|p| p.to_string()).collect()),
                exclude: (!self.effects.exclude.is_empty())
                    .then(|| self.effects.exclude.iter().map(|p| p.to_string()).collect()),
            }),
        };
        let text = toml::to_string(&doc).map_err(|e| SceneFileError::Invalid {
            file: path.to_path_buf(),
            field: String::new(),
            line: None,
            column: None,
            problem: format!("cannot serialise: {e}"),
        })?;
        std::fs::write(path, text).map_err(|source| SceneFileError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

fn light_doc(l: &Light) -> LightDoc {
    match *l {
        Light::Point { position, power } => LightDoc {
            kind: "point".into(),
            position: Some(position),
            power: Some(power),
            ..LightDoc::default()
        },
        Light::Directional {
            direction,
            irradiance,
        } => LightDoc {
            kind: "directional".into(),
            direction: Some(direction),
            irradiance: Some(irradiance),
            ..LightDoc::default()
        },
        Light::Sphere {
            center,
            radius,
            radiance,
        } => LightDoc {
            kind: "sphere".into(),
            center: Some(center),
            radius: Some(radius),
            radiance: Some(radiance),
            ..LightDoc::default()
        },
        Light::Environment { radiance } => LightDoc {
            kind: "environment".into(),
            radiance: Some(radiance),
            ..LightDoc::default()
        },
    }
}
