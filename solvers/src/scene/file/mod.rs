//! Scene files: TOML documents that describe a [`Scene`] (plus what to write), versioned by
//! a top-level `format = 1`.
//!
//! ```toml
//! format = 1
//! description = "optional free text"
//!
//! [medium]
//! generator = "noise_cloud"      # a procedural medium (see generators::GENERATORS) …
//! params = { n = 64, seed = 3 }  # … with its parameters (also as a [medium.params] table)
//! # file = "density.vol"         # … or σt from a Mitsuba .vol grid, path relative to this file
//! density_scale = 1.0            # multiplies σt (default 1)
//! albedo = 0.9                   # number, or "albedo.vol"; default: the generator's (required with `file`)
//! emission = "none"              # "none", number (j per voxel), or "emission.vol"; default: the generator's (none with `file`)
//! min = [0.0, 0.0, 0.0]          # box of the grid (both or neither; default: generator's or the
//! max = [1.0, 1.0, 1.0]          # .vol's); voxels must be cubic: (max − min)/n equal on every axis
//! # vdb = "cloud.vdb"            # … or σt from an OpenVDB float grid (feature `vdb`), with
//! # grid = "density"             # the grid's name (default "density"); needs `albedo`
//! # sigma_t_rgb = [1.0, 0.8, 0.6] # colour: per-channel scales of σt, albedo, emission make
//! # albedo_rgb = [1.0, 1.0, 1.0]  # the scene RGB (three monochrome channels, see
//! # emission_rgb = [1.0, 0.5, 0.2] # SceneFile::channels); generators may give RGB fields
//! interpolation = "nearest"      # or "trilinear" between voxel centres (Mitsuba's and pbrt's
//!                                # default); path tracer, Mitsuba export and restriction
//!
//! [phase]
//! type = "hg"                    # "isotropic" (default) or "hg" with g in (−1, 1)
//! g = 0.3
//!
//! [[light]]                      # any number of lights
//! type = "directional"           # point: position, power | directional: direction, irradiance
//! direction = [0.0, 0.0, -1.0]   # sphere: center, radius, radiance | environment: radiance
//! irradiance = 1.0               # (directions are normalised)
//!
//! [camera]                       # optional
//! eye = [0.5, -2.0, 0.5]
//! target = [0.5, 0.5, 0.5]
//! up = [0.0, 0.0, 1.0]
//! projection = "perspective"     # with fov_y (degrees); or "orthographic" with width
//! fov_y = 30.0
//! resolution = [64, 64]          # width, height
//! hide_background = false        # true: leave out lights seen directly (the environment
//!                                # through the medium; Mitsuba's hide_emitters)
//!
//! [sampler]                      # default spp = 16, seed = 0
//! spp = 64
//! seed = 1
//!
//! [outputs]
//! write = ["image"]              # "image" (camera render) and/or "fluence" (φ of the
//!                                # multiple-scattering solve; `render` writes fluence.vol)
//!
//! [effects]                      # optional restriction of the rendered effects
//! only = ["single_scattering"]   # (see scene::effects); default: everything the scene implies
//! exclude = ["anisotropy"]
//! ```
//!
//! Every table rejects unknown keys. Errors are [`SceneFileError::Invalid`], naming the field
//! as a TOML path (`light[1].direction`), the problem, and the line and column where the file
//! has them; a TOML syntax error (an unclosed `[medium` header, say) names no field, only
//! where the text breaks, and a missing `[medium]` table is named as such. A later format adds keys under a new `format` number; this build reads format 1
//! and says so for any other.
//!
//! Decisions: voxel fields keep their values when `min`/`max` move or scale a generator's box
//! (σt stays in inverse world units, so optical depths scale with the box); a constant
//! `emission` fills every voxel of the box, vacuum ones included (j is a source per volume
//! whatever σt is); `.vol` data are `f32`, so writing a scene rounds its fields to `f32`.
//!
//! The code is split by job: `schema` (the serde view of the document), `locate` (TOML
//! path ⇄ span ⇄ line:column for errors), `convert` (phase, lights, camera, effects,
//! `[medium]` overrides), `medium` (the base medium from a generator, a `.vol` or a `.vdb`
//! file, and RGB scales) and `write` ([`SceneFile::write`]).

mod convert;
mod locate;
mod medium;
mod schema;
mod write;

#[cfg(test)]
mod tests;

use super::effects::EffectSelection;
use super::{Interpolation, Sampler, Scene};
use crate::Medium;
use convert::Cx;
use locate::Locator;
use schema::{Doc, FormatProbe, SamplerDoc};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// The scene-file format this build reads and writes.
pub const FORMAT_VERSION: i64 = 1;

/// Errors loading or writing a scene file.
#[derive(Debug, Error)]
pub enum SceneFileError {
    /// A file could not be read or written (the I/O error is the source, not repeated here).
    #[error("{}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The document is malformed or a value is invalid.
    #[error("{}", describe(.file, .field, *.line, *.column, .problem))]
    Invalid {
        /// The scene file.
        file: PathBuf,
        /// The TOML path of the offending field, e.g. `light[1].direction` (empty when the
        /// document as a whole is at fault).
        field: String,
        /// 1-based line, when known.
        line: Option<usize>,
        /// 1-based column, when known.
        column: Option<usize>,
        /// What is wrong.
        problem: String,
    },
}

impl SceneFileError {
    /// The TOML path of the offending field, if the error is about one.
    pub fn field(&self) -> Option<&str> {
        match self {
            SceneFileError::Invalid { field, .. } => Some(field),
            SceneFileError::Io { .. } => None,
        }
    }
}

fn describe(
    file: &Path,
    field: &str,
    line: Option<usize>,
    column: Option<usize>,
    problem: &str,
) -> String {
    let place = match (line, column) {
        (Some(l), Some(c)) => format!("{}:{l}:{c}", file.display()),
        (Some(l), None) => format!("{}:{l}", file.display()),
        _ => file.display().to_string(),
    };
    if field.is_empty() {
        format!("{place}: {problem}")
    } else {
        format!("{place}: `{field}`: {problem}")
    }
}

/// What a run of a scene file should write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    /// The camera image (needs `[camera]`).
    Image,
    /// The fluence on the voxel grid.
    Fluence,
}

impl OutputKind {
    /// The name used in `[outputs] write`.
    pub fn name(self) -> &'static str {
        match self {
            OutputKind::Image => "image",
            OutputKind::Fluence => "fluence",
        }
    }

    const ALL: [OutputKind; 2] = [OutputKind::Image, OutputKind::Fluence];
}

/// A loaded scene file: the scene and the file-level settings around it.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneFile {
    /// The scene.
    pub scene: Scene,
    /// What to write (default: the image if there is a camera, else the fluence).
    pub outputs: Vec<OutputKind>,
    /// Free-text description.
    pub description: Option<String>,
    /// The `[effects]` restriction (default: none; see [`super::effects`]).
    pub effects: EffectSelection,
    /// Per-channel (R, G, B) media of a coloured scene, `None` for a monochrome one; see
    /// [`SceneFile::channels`].
    pub colour: Option<Box<[Medium<f64>; 3]>>,
}

impl SceneFile {
    /// The scene per colour channel: one monochrome scene, or three (R, G, B) that differ
    /// only in their medium. RGB is rendered as three independent monochrome transport
    /// problems (lights are white: the same light in every channel), so every renderer — the
    /// grid pipeline and the path tracer — handles colour by rendering each channel.
    ///
    /// A coloured scene comes from a generator with per-channel fields (e.g. `plume`'s
    /// blackbody emission) and/or from `[medium]` scale triplets `sigma_t_rgb`,
    /// `albedo_rgb`, `emission_rgb`, which multiply σt, albedo and j per channel (the
    /// albedo product must stay ≤ 1). [`SceneFile::scene`] is then the unscaled
    /// monochrome medium.
    pub fn channels(&self) -> Vec<Scene> {
        match &self.colour {
            None => vec![self.scene.clone()],
            Some(ch) => ch
                .iter()
                .map(|m| Scene {
                    medium: m.clone(),
                    ..self.scene.clone()
                })
                .collect(),
        }
    }
}

/// Loads the scene of the file at `path` (shorthand for [`SceneFile::load`]).
pub fn load_scene(path: &Path) -> Result<Scene, SceneFileError> {
    Ok(SceneFile::load(path)?.scene)
}

// ---------------------------------------------------------------------------------------
// Loading.

impl SceneFile {
    /// Loads a scene file; `.vol` paths in it are relative to its directory.
    pub fn load(path: &Path) -> Result<Self, SceneFileError> {
        let io = |source| SceneFileError::Io {
            path: path.to_path_buf(),
            source,
        };
        let bytes = crate::budget::read_regular(path, crate::budget::MAX_TOML_BYTES).map_err(io)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("not UTF-8 text: {e}"),
            ))
        })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        Self::parse(&text, dir, path)
    }

    /// Parses scene-file text; `.vol` paths are relative to `dir`, and errors name `file`.
    pub fn parse(text: &str, dir: &Path, file: &Path) -> Result<Self, SceneFileError> {
        let (loc, syntax) = Locator::new(text, file);
        if let Some(e) = syntax.first() {
            return Err(loc.syntax_err(e));
        }
        let probe: FormatProbe = toml::from_str(text).map_err(|e| loc.toml_err(&e, ""))?;
        match probe.format {
            None => {
                return Err(loc.err(
                    "format",
                    format!("missing: a scene file starts with `format = {FORMAT_VERSION}`"),
                ));
            }
            Some(toml::Value::Integer(FORMAT_VERSION)) => {}
            Some(v) => {
                return Err(loc.err(
                    "format",
                    format!("unsupported format {v}: this build reads format {FORMAT_VERSION}"),
                ));
            }
        }
        if !loc.has("medium") {
            return Err(loc.err(
                "medium",
                "missing: a scene file needs a [medium] table (with `generator`, `file` or `vdb`)",
            ));
        }
        let doc: Doc = toml::from_str(text).map_err(|e| loc.toml_err(&e, ""))?;
        let cx = Cx {
            loc: &loc,
            dir,
            text,
        };
        let (medium, colour) = cx.medium(&doc.medium)?;
        let phase = cx.phase(doc.phase.as_ref())?;
        let lights = doc
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| cx.light(i, l))
            .collect::<Result<Vec<_>, _>>()?;
        let camera = doc.camera.as_ref().map(|c| cx.camera(c)).transpose()?;
        if let Some(c) = &camera {
            let [w, h] = c.resolution;
            crate::budget::check(
                format!("camera.resolution = [{w}, {h}]"),
                crate::budget::image_bytes(w, h),
            )
            .map_err(|e| loc.err("camera.resolution", e.to_string()))?;
        }
        let sampler = match &doc.sampler {
            Some(s) => {
                if s.spp == 0 {
                    return Err(loc.err("sampler.spp", "must be at least 1"));
                }
                Sampler {
                    spp: s.spp,
                    seed: s.seed,
                }
            }
            None => {
                let d = SamplerDoc::default();
                Sampler {
                    spp: d.spp,
                    seed: d.seed,
                }
            }
        };
        let outputs = match &doc.outputs {
            Some(o) => o
                .write
                .iter()
                .enumerate()
                .map(|(i, name)| {
                    OutputKind::ALL
                        .into_iter()
                        .find(|k| k.name() == name)
                        .ok_or_else(|| {
                            loc.err(
                                &format!("outputs.write[{i}]"),
                                format!("unknown output `{name}`; known: image, fluence"),
                            )
                        })
                })
                .collect::<Result<Vec<_>, _>>()?,
            None if camera.is_some() => vec![OutputKind::Image],
            None => vec![OutputKind::Fluence],
        };
        if outputs.contains(&OutputKind::Image) && camera.is_none() {
            return Err(loc.err("outputs.write", "`image` needs a [camera] table"));
        }
        let interpolation = match doc.medium.interpolation.as_deref() {
            None | Some("nearest") => Interpolation::Nearest,
            Some("trilinear") => Interpolation::Trilinear,
            Some(other) => {
                return Err(loc.err(
                    "medium.interpolation",
                    format!("unknown interpolation `{other}`; known: nearest, trilinear"),
                ));
            }
        };
        let scene = Scene {
            interpolation,
            medium,
            phase,
            lights,
            camera,
            sampler,
        };
        scene.validate().map_err(|e| loc.err("", e.to_string()))?;
        let effects = cx.effects(doc.effects.as_ref(), scene.lights.len())?;
        Ok(Self {
            scene,
            outputs,
            description: doc.description,
            effects,
            colour,
        })
    }
}
