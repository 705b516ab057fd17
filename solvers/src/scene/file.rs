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
//!
//! [sampler]                      # default spp = 16, seed = 0
//! spp = 64
//! seed = 1
//!
//! [outputs]
//! write = ["image"]              # "image" (camera render) and/or "fluence" (voxel grid)
//!
//! [effects]                      # optional restriction of the rendered effects
//! only = ["single_scattering"]   # (see scene::effects); default: everything the scene implies
//! exclude = ["anisotropy"]
//! ```
//!
//! Every table rejects unknown keys. Errors are [`SceneFileError::Invalid`], naming the field
//! as a TOML path (`light[1].direction`), the problem, and the line and column where the file
//! has them. A later format adds keys under a new `format` number; this build reads format 1
//! and says so for any other.
//!
//! Decisions: voxel fields keep their values when `min`/`max` move or scale a generator's box
//! (σt stays in inverse world units, so optical depths scale with the box); a constant
//! `emission` fills every voxel of the box, vacuum ones included (j is a source per volume
//! whatever σt is); `.vol` data are `f32`, so writing a scene rounds its fields to `f32`.

use super::effects::{EffectPattern, EffectSelection};
use super::generators::{self, GeneratorError};
use super::vol::{VolError, VolGrid};
use super::{Camera, Light, Phase, Projection, Sampler, Scene};
use crate::{Grid, Medium, SolverError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;
use toml::de::{DeTable, DeValue};

/// The scene-file format this build reads and writes.
pub const FORMAT_VERSION: i64 = 1;

/// Errors loading or writing a scene file.
#[derive(Debug, Error)]
pub enum SceneFileError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
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
// The file schema (serde), separate from the data model.

#[derive(Deserialize)]
struct FormatProbe {
    format: Option<toml::Value>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct Doc {
    format: i64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    description: Option<String>,
    medium: MediumDoc,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    phase: Option<PhaseDoc>,
    #[serde(default, rename = "light", skip_serializing_if = "Vec::is_empty")]
    lights: Vec<LightDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    camera: Option<CameraDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sampler: Option<SamplerDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    outputs: Option<OutputsDoc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    effects: Option<EffectsDoc>,
}

#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct EffectsDoc {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    only: Option<Vec<String>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    exclude: Option<Vec<String>>,
}

#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct MediumDoc {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    generator: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    params: Option<toml::Table>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    file: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    density_scale: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    albedo: Option<toml::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    emission: Option<toml::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    min: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    max: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_t_rgb: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    albedo_rgb: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    emission_rgb: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    vdb: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    grid: Option<String>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct PhaseDoc {
    #[serde(rename = "type")]
    kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    g: Option<f64>,
}

#[derive(Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct LightDoc {
    #[serde(rename = "type")]
    kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    position: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    power: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    direction: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    irradiance: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    center: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    radiance: Option<f64>,
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct CameraDoc {
    eye: [f64; 3],
    target: [f64; 3],
    up: [f64; 3],
    projection: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    width: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fov_y: Option<f64>,
    resolution: [usize; 2],
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct SamplerDoc {
    #[serde(default = "default_spp")]
    spp: u32,
    #[serde(default)]
    seed: u64,
}

fn default_spp() -> u32 {
    16
}

#[derive(Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct OutputsDoc {
    #[serde(default)]
    write: Vec<String>,
}

// ---------------------------------------------------------------------------------------
// Error locations: TOML paths ⇄ byte spans, through toml's spanned document tree.

/// The parsed document with spans, for turning error spans into paths and paths into lines.
struct Locator<'a> {
    text: &'a str,
    file: &'a Path,
    tree: Option<DeTable<'a>>,
}

#[derive(Debug, Clone, PartialEq)]
enum Seg {
    Key(String),
    Index(usize),
}

fn format_path(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

fn parse_path(path: &str) -> Vec<Seg> {
    let mut segs = Vec::new();
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let mut pieces = part.split('[');
        if let Some(key) = pieces.next().filter(|k| !k.is_empty()) {
            segs.push(Seg::Key(key.to_string()));
        }
        for idx in pieces {
            if let Ok(i) = idx.trim_end_matches(']').parse() {
                segs.push(Seg::Index(i));
            }
        }
    }
    segs
}

fn contains(span: &std::ops::Range<usize>, pos: usize) -> bool {
    span.start <= pos && pos < span.end.max(span.start + 1)
}

/// Appends to `path` the deepest key or array element of `table` whose key or value span
/// contains `pos`; returns whether one was found.
fn find_in_table(table: &DeTable<'_>, pos: usize, path: &mut Vec<Seg>) -> bool {
    for (k, v) in table.iter() {
        path.push(Seg::Key(k.get_ref().to_string()));
        if find_in_value(v.get_ref(), pos, path)
            || contains(&k.span(), pos)
            || contains(&v.span(), pos)
        {
            return true;
        }
        path.pop();
    }
    false
}

fn find_in_value(value: &DeValue<'_>, pos: usize, path: &mut Vec<Seg>) -> bool {
    match value {
        DeValue::Table(t) => find_in_table(t, pos, path),
        DeValue::Array(a) => {
            for (i, item) in a.iter().enumerate() {
                path.push(Seg::Index(i));
                if find_in_value(item.get_ref(), pos, path) || contains(&item.span(), pos) {
                    return true;
                }
                path.pop();
            }
            false
        }
        _ => false,
    }
}

impl<'a> Locator<'a> {
    fn new(text: &'a str, file: &'a Path) -> (Self, Vec<toml::de::Error>) {
        let (tree, errors) = DeTable::parse_recoverable(text);
        (
            Self {
                text,
                file,
                tree: Some(tree.into_inner()),
            },
            errors,
        )
    }

    fn line_col(&self, pos: usize) -> (usize, usize) {
        let pos = pos.min(self.text.len());
        let before = self.text.get(..pos).unwrap_or("");
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, col)
    }

    fn span_of(&self, path: &str) -> Option<std::ops::Range<usize>> {
        let mut table = self.tree.as_ref()?;
        let mut value: Option<&toml::Spanned<DeValue<'_>>> = None;
        let mut span = None;
        for seg in parse_path(path) {
            match seg {
                Seg::Key(k) => {
                    let (key, v) = table.iter().find(|(key, _)| key.get_ref() == &k)?;
                    span = Some(if v.get_ref().is_table() || v.get_ref().is_array() {
                        key.span()
                    } else {
                        v.span()
                    });
                    value = Some(v);
                }
                Seg::Index(i) => {
                    let item = value?.get_ref().as_array()?.get(i)?;
                    span = Some(item.span());
                    value = Some(item);
                }
            }
            if let Some(t) = value.and_then(|v| v.get_ref().as_table()) {
                table = t;
            }
        }
        span
    }

    fn path_at(&self, pos: usize) -> String {
        let mut path = Vec::new();
        if let Some(tree) = &self.tree {
            find_in_table(tree, pos, &mut path);
        }
        format_path(&path)
    }

    /// An error about `field`, located at its span if the document has it.
    fn err(&self, field: &str, problem: impl Into<String>) -> SceneFileError {
        let (line, column) = match self.span_of(field) {
            Some(s) => {
                let (l, c) = self.line_col(s.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        SceneFileError::Invalid {
            file: self.file.to_path_buf(),
            field: field.to_string(),
            line,
            column,
            problem: problem.into(),
        }
    }

    /// A toml error, located by its span (the field is the path at the span).
    fn toml_err(&self, e: &toml::de::Error, fallback_field: &str) -> SceneFileError {
        match e.span() {
            Some(s) => {
                let (l, c) = self.line_col(s.start);
                let field = self.path_at(s.start);
                SceneFileError::Invalid {
                    file: self.file.to_path_buf(),
                    field: if field.is_empty() {
                        fallback_field.to_string()
                    } else {
                        field
                    },
                    line: Some(l),
                    column: Some(c),
                    problem: e.message().trim().to_string(),
                }
            }
            None => self.err(fallback_field, e.message().trim()),
        }
    }
}

// ---------------------------------------------------------------------------------------
// Loading.

impl SceneFile {
    /// Loads a scene file; `.vol` paths in it are relative to its directory.
    pub fn load(path: &Path) -> Result<Self, SceneFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        Self::parse(&text, dir, path)
    }

    /// Parses scene-file text; `.vol` paths are relative to `dir`, and errors name `file`.
    pub fn parse(text: &str, dir: &Path, file: &Path) -> Result<Self, SceneFileError> {
        let (loc, syntax) = Locator::new(text, file);
        if let Some(e) = syntax.first() {
            return Err(loc.toml_err(e, ""));
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
            None => Sampler {
                spp: default_spp(),
                seed: 0,
            },
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
        let scene = Scene {
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

/// Conversion context: the locator, the directory `.vol` paths are relative to, and the text.
struct Cx<'a> {
    loc: &'a Locator<'a>,
    dir: &'a Path,
    text: &'a str,
}

fn finite3(v: [f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Cx<'_> {
    fn read_vol(&self, field: &str, rel: &str) -> Result<VolGrid, SceneFileError> {
        let path = self.dir.join(rel);
        VolGrid::read(&path).map_err(|e| match e {
            VolError::Io { source, .. } => self
                .loc
                .err(field, format!("cannot read `{}`: {source}", path.display())),
            e => self.loc.err(
                field,
                format!("`{}` is not a valid .vol file: {e}", path.display()),
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

    fn single_channel(
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

    /// The monochrome medium and, for a coloured scene, the three channel media.
    #[allow(clippy::type_complexity)]
    fn medium(
        &self,
        m: &MediumDoc,
    ) -> Result<(Medium<f64>, Option<Box<[Medium<f64>; 3]>>), SceneFileError> {
        let loc = self.loc;
        if m.vdb.is_none() && m.grid.is_some() {
            return Err(loc.err("medium.grid", "`grid` names a grid of a `vdb` file"));
        }
        let sources = [m.generator.is_some(), m.file.is_some(), m.vdb.is_some()];
        if sources.iter().filter(|&&b| b).count() > 1 {
            let field = if m.vdb.is_some() {
                "medium.vdb"
            } else {
                "medium.file"
            };
            return Err(loc.err(field, "give one of `generator`, `file` or `vdb`, not both"));
        }
        let mut base_channels = None;
        // The base medium: a generator's or σt from a file.
        let (base, density_field) = match (&m.generator, m.file.as_ref().or(m.vdb.as_ref())) {
            (Some(_), Some(_)) => {
                return Err(loc.err("medium.file", "give either `generator` or `file`, not both"));
            }
            (None, None) => {
                return Err(loc.err(
                    "medium",
                    format!(
                        "needs `generator = \"…\"` (one of {}) or `file = \"….vol\"`",
                        generators::names()
                    ),
                ));
            }
            (Some(name), None) => {
                let entry = generators::find(name).ok_or_else(|| {
                    loc.err(
                        "medium.generator",
                        format!("unknown generator `{name}`; known: {}", generators::names()),
                    )
                })?;
                let medium = entry.build_from_document(self.text).map_err(|e| match e {
                    GeneratorError::Params(e) => loc.toml_err(&e, "medium.params"),
                    GeneratorError::Solver(SolverError::BadParameter {
                        name,
                        value,
                        reason,
                    }) if m.params.as_ref().is_some_and(|p| p.contains_key(name)) => loc.err(
                        &format!("medium.params.{name}"),
                        format!("{value} is invalid: {reason}"),
                    ),
                    GeneratorError::Solver(e) => {
                        loc.err("medium.params", format!("generator `{name}`: {e}"))
                    }
                })?;
                base_channels = entry
                    .build_channels_from_document(self.text)
                    .map_err(|e| loc.err("medium.params", format!("generator `{name}`: {e}")))?;
                (medium, "medium.params")
            }
            (None, Some(_)) if m.vdb.is_some() => {
                let rel = m.vdb.as_deref().unwrap_or_default();
                if m.params.is_some() {
                    return Err(loc.err(
                        "medium.params",
                        "parameters belong to a `generator`; this medium reads `vdb`",
                    ));
                }
                let grid_name = m.grid.as_deref().unwrap_or("density");
                let path = self.dir.join(rel);
                let (dims, sigma_t) = super::vdb::read_float_grid(&path, grid_name)
                    .map_err(|e| loc.err("medium.vdb", e.to_string()))?;
                let grid = Grid::new(dims, 1.0 / dims.into_iter().max().unwrap_or(1) as f64)
                    .map_err(|e| loc.err("medium.vdb", format!("`{rel}`: {e}")))?;
                let n = grid.len();
                if m.albedo.is_none() {
                    return Err(loc.err(
                        "medium.albedo",
                        "required with `vdb`: a number in [0, 1] or a .vol path",
                    ));
                }
                (
                    Medium {
                        grid,
                        sigma_t,
                        albedo: vec![0.0; n],
                        emission: vec![0.0; n],
                    },
                    "medium.vdb",
                )
            }
            (None, Some(rel)) => {
                if m.params.is_some() {
                    return Err(loc.err(
                        "medium.params",
                        "parameters belong to a `generator`; this medium reads `file`",
                    ));
                }
                let vol = self.read_vol("medium.file", rel)?;
                let sigma_t = self.single_channel("medium.file", rel, &vol)?;
                let grid = if m.min.is_some() || m.max.is_some() {
                    // Replaced below by the explicit box; only the dimensions matter here.
                    Grid::new(vol.dims, 1.0)
                        .map_err(|e| loc.err("medium.file", format!("`{rel}`: {e}")))?
                } else {
                    vol.grid()
                        .map_err(|e| loc.err("medium.file", format!("`{rel}`: {e}")))?
                };
                let n = grid.len();
                let medium = Medium {
                    grid,
                    sigma_t,
                    albedo: vec![0.0; n],
                    emission: vec![0.0; n],
                };
                if m.albedo.is_none() {
                    return Err(loc.err(
                        "medium.albedo",
                        "required with `file`: a number in [0, 1] or a .vol path",
                    ));
                }
                (medium, "medium.file")
            }
        };
        let mono = self.overrides(m, base, density_field)?;
        let mut channels = match base_channels {
            Some(ch) => {
                let [r, g, b] = ch;
                Some([
                    self.overrides(m, r, density_field)?,
                    self.overrides(m, g, density_field)?,
                    self.overrides(m, b, density_field)?,
                ])
            }
            None => None,
        };
        let scales = [
            ("medium.sigma_t_rgb", m.sigma_t_rgb),
            ("medium.albedo_rgb", m.albedo_rgb),
            ("medium.emission_rgb", m.emission_rgb),
        ];
        if scales.iter().any(|(_, v)| v.is_some()) {
            for (field, v) in scales {
                if let Some(v) = v {
                    if v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                        return Err(loc.err(field, "channel scales must be finite and >= 0"));
                    }
                }
            }
            let mut ch = channels.unwrap_or_else(|| [mono.clone(), mono.clone(), mono.clone()]);
            for (c, medium) in ch.iter_mut().enumerate() {
                let scale = |v: Option<[f64; 3]>| v.map_or(1.0, |v| v[c]);
                let (s, a, e) = (
                    scale(m.sigma_t_rgb),
                    scale(m.albedo_rgb),
                    scale(m.emission_rgb),
                );
                medium.sigma_t.iter_mut().for_each(|x| *x *= s);
                medium.albedo.iter_mut().for_each(|x| *x *= a);
                medium.emission.iter_mut().for_each(|x| *x *= e);
                medium.validate().map_err(|e| match e {
                    SolverError::FieldValue {
                        field: "albedo", ..
                    } => loc.err(
                        "medium.albedo_rgb",
                        format!("channel {c}: {e} (albedo times its channel scale must stay <= 1)"),
                    ),
                    e => loc.err("medium", format!("channel {c}: {e}")),
                })?;
            }
            channels = Some(ch);
        }
        Ok((mono, channels.map(Box::new)))
    }

    /// Applies the box, density scale, albedo and emission keys of `[medium]` to `base`.
    fn overrides(
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

    fn effects(
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
                    let p: EffectPattern =
                        n.parse().map_err(|e: super::effects::EffectsError| {
                            self.loc.err(&field, e.to_string())
                        })?;
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
                        return Err(self.loc.err(
                            &field,
                            super::effects::EffectsError::AttenuationExcluded.to_string(),
                        ));
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

    fn phase(&self, p: Option<&PhaseDoc>) -> Result<Phase, SceneFileError> {
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

    fn light(&self, i: usize, l: &LightDoc) -> Result<Light, SceneFileError> {
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
                        "not a parameter of a {} light (it takes {})",
                        l.kind,
                        takes.join(", ")
                    ),
                ));
            }
            if !is && takes.contains(&name) {
                return Err(self.loc.err(
                    &format!("light[{i}]"),
                    format!("a {} light needs `{name}`", l.kind),
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
                    format!("{value} is invalid: {reason}"),
                )
            }
            e => self.loc.err(&format!("light[{i}]"), e.to_string()),
        }
    }

    fn camera(&self, c: &CameraDoc) -> Result<Camera, SceneFileError> {
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
                loc.err(field, format!("{value} is invalid: {reason}"))
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

// ---------------------------------------------------------------------------------------
// Writing.

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
                problem: e.to_string(),
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

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
format = 1
description = "test"

[medium]
generator = "homogeneous"
params = { n = 6, sigma_t = 2.0, albedo = 0.5 }
emission = 0.25
min = [-1.0, -1.0, -1.0]
max = [2.0, 2.0, 2.0]

[phase]
type = "hg"
g = 0.4

[[light]]
type = "directional"
direction = [0.0, 0.0, -2.0]
irradiance = 3.0

[[light]]
type = "sphere"
center = [0.5, 0.5, 0.5]
radius = 0.1
radiance = 5.0

[[light]]
type = "point"
position = [0.0, 0.0, 4.0]
power = 2.0

[[light]]
type = "environment"
radiance = 0.5

[camera]
eye = [0.5, -3.0, 0.5]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "perspective"
fov_y = 30.0
resolution = [16, 8]

[sampler]
spp = 4
seed = 9

[outputs]
write = ["image", "fluence"]
"#;

    fn parse(text: &str) -> Result<SceneFile, SceneFileError> {
        SceneFile::parse(text, Path::new("."), Path::new("test.toml"))
    }

    /// Replaces the first occurrence of `from` in GOOD and parses; returns the error.
    fn broken(from: &str, to: &str) -> SceneFileError {
        assert!(GOOD.contains(from), "{from}");
        let text = GOOD.replacen(from, to, 1);
        match parse(&text) {
            Ok(_) => panic!("`{from}` → `{to}` parsed"),
            Err(e) => e,
        }
    }

    fn assert_field(e: &SceneFileError, field: &str, line: Option<usize>, needle: &str) {
        let msg = e.to_string();
        assert_eq!(e.field(), Some(field), "{msg}");
        if let SceneFileError::Invalid { line: l, .. } = e {
            if line.is_some() {
                assert_eq!(*l, line, "{msg}");
            }
        }
        assert!(msg.contains(field) && msg.contains(needle), "{msg}");
    }

    #[test]
    fn a_full_file_converts_into_the_scene_it_describes() {
        let f = parse(GOOD).unwrap();
        let s = &f.scene;
        assert_eq!(s.medium.grid.n, [6; 3]);
        assert_eq!(s.medium.grid.origin, [-1.0; 3]);
        assert!((s.medium.grid.dl - 0.5).abs() < 1e-15);
        assert!(s.medium.emission.iter().all(|&j| j == 0.25));
        assert_eq!(s.phase, Phase::HenyeyGreenstein { g: 0.4 });
        assert_eq!(s.lights.len(), 4);
        assert_eq!(
            s.lights[0],
            Light::Directional {
                direction: [0.0, 0.0, -1.0],
                irradiance: 3.0
            }
        );
        let cam = s.camera.unwrap();
        assert_eq!(cam.resolution, [16, 8]);
        assert_eq!(s.sampler, Sampler { spp: 4, seed: 9 });
        assert_eq!(f.outputs, vec![OutputKind::Image, OutputKind::Fluence]);
        assert_eq!(f.description.as_deref(), Some("test"));
    }

    #[test]
    fn invalid_files_name_the_field_line_and_problem() {
        // Wrong type inside the second light: toml's error, located by its span.
        let e = broken("radius = 0.1", "radius = \"big\"");
        assert_field(&e, "light[1].radius", Some(24), "invalid type");
        // A zero direction: our validation, located by the path.
        let e = broken(
            "direction = [0.0, 0.0, -2.0]",
            "direction = [0.0, 0.0, 0.0]",
        );
        assert_field(&e, "light[0].direction", Some(18), "non-zero");
        // Unknown key.
        let e = broken("irradiance = 3.0", "irradiance = 3.0\ncolour = 1");
        assert_field(&e, "light[0].colour", Some(20), "unknown field");
        // A parameter of another light type.
        let e = broken("power = 2.0", "power = 2.0\nradius = 1.0");
        assert_field(
            &e,
            "light[2].radius",
            Some(31),
            "not a parameter of a point light",
        );
        // A missing one.
        let e = broken("radiance = 5.0\n", "\n");
        assert_field(&e, "light[1]", None, "needs `radiance`");
        // Phase, camera, sampler, outputs, format.
        let e = broken("g = 0.4", "g = 1.5");
        assert_field(&e, "phase.g", Some(14), "(-1, 1)");
        let e = broken("fov_y = 30.0", "fov_y = 200.0");
        assert_field(&e, "camera.fov_y", Some(41), "(0, 180)");
        let e = broken("up = [0.0, 0.0, 1.0]", "up = [0.0, 1.0, 0.0]");
        assert_field(&e, "camera.up", Some(39), "parallel");
        let e = broken("spp = 4", "spp = -4");
        assert_field(&e, "sampler.spp", Some(45), "invalid value");
        let e = broken("\"image\", \"fluence\"", "\"image\", \"movie\"");
        assert_field(&e, "outputs.write[1]", Some(49), "unknown output `movie`");
        let e = broken("format = 1", "format = 2");
        assert_field(&e, "format", Some(2), "unsupported format 2");
        // Medium: generator parameters (spans through the registry), box, albedo.
        let e = broken("sigma_t = 2.0,", "sigma_t = 2.0, sigma_s = 1.0,");
        assert_field(&e, "medium.params.sigma_s", Some(7), "unknown field");
        let e = broken("n = 6,", "n = 2,");
        assert_field(&e, "medium.params", Some(7), "at least 3");
        let e = broken("max = [2.0, 2.0, 2.0]", "max = [2.0, 2.0, 3.0]");
        assert_field(&e, "medium.max", Some(10), "not cubic");
        let e = broken("emission = 0.25", "emission = 0.25\nalbedo = 1.5");
        assert_field(&e, "medium.albedo", Some(9), "outside [0, 1]");
        let e = broken("generator = \"homogeneous\"", "generator = \"smoke\"");
        assert_field(&e, "medium.generator", Some(6), "unknown generator `smoke`");
        let e = broken("emission = 0.25", "emission = 0.25\nfile = \"x.vol\"");
        assert_field(&e, "medium.file", Some(9), "not both");
        // A missing .vol file.
        let text = GOOD.replacen(
            "generator = \"homogeneous\"\nparams = { n = 6, sigma_t = 2.0, albedo = 0.5 }",
            "file = \"missing.vol\"\nalbedo = 0.5",
            1,
        );
        let e = parse(&text).unwrap_err();
        assert_field(&e, "medium.file", Some(6), "cannot read");
        // Syntax errors carry line and column.
        let e = parse("format = 1\n[medium\n").unwrap_err();
        match &e {
            SceneFileError::Invalid { line, .. } => assert_eq!(*line, Some(2), "{e}"),
            other => panic!("{other}"),
        }
    }

    #[test]
    fn the_example_scenes_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
        let cloud = SceneFile::load(&dir.join("cloud_directional.toml")).unwrap();
        let s = &cloud.scene;
        assert_eq!(s.medium.grid.n, [64; 3]);
        assert!(s.medium.emission.iter().all(|&j| j == 0.0));
        assert!(matches!(s.lights[..], [Light::Directional { .. }]));
        assert_eq!(s.camera.map(|c| c.resolution), Some([64, 64]));
        let sphere = SceneFile::load(&dir.join("emissive_sphere.toml")).unwrap();
        let s = &sphere.scene;
        let Light::Sphere { center, radius, .. } = s.lights[0] else {
            panic!("{:?}", s.lights);
        };
        // The sphere lies inside the medium's box.
        let size = s.medium.grid.size();
        for a in 0..3 {
            assert!(center[a] - radius > s.medium.grid.origin[a]);
            assert!(center[a] + radius < s.medium.grid.origin[a] + size[a]);
        }
        assert_eq!(s.camera.map(|c| c.resolution), Some([64, 64]));
    }

    #[test]
    fn round_trip_through_toml_and_vol_files() {
        let dir =
            std::env::temp_dir().join(format!("scatterbench-scenefile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let text = GOOD
            .replacen(
                "generator = \"homogeneous\"",
                "generator = \"random_heterogeneous\"",
                1,
            )
            .replacen(
                "params = { n = 6, sigma_t = 2.0, albedo = 0.5 }",
                "params = { n = [6, 6, 6], seed = 4 }",
                1,
            );
        let a = parse(&text).unwrap();
        a.write(&dir.join("a.toml")).unwrap();
        let b = SceneFile::load(&dir.join("a.toml")).unwrap();
        // f32 rounding of the fields, nothing else.
        assert_eq!(b.scene.lights, a.scene.lights);
        assert_eq!(b.scene.camera, a.scene.camera);
        assert_eq!(b.scene.phase, a.scene.phase);
        assert_eq!(b.scene.sampler, a.scene.sampler);
        assert_eq!(b.outputs, a.outputs);
        assert_eq!(b.scene.medium.grid.n, a.scene.medium.grid.n);
        assert!((b.scene.medium.grid.dl - a.scene.medium.grid.dl).abs() < 1e-6);
        for (x, y) in a.scene.medium.sigma_t.iter().zip(&b.scene.medium.sigma_t) {
            assert_eq!(*y, f64::from(*x as f32));
        }
        assert_eq!(b.scene.medium.emission, vec![0.25; 216]);
        // A second round trip is exact.
        b.write(&dir.join("b.toml")).unwrap();
        let c = SceneFile::load(&dir.join("b.toml")).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        assert_eq!(c, b);
    }
}
