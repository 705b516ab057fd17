//! The `[medium]` table: where the base medium comes from ([`MediumSource`], decided once),
//! one conversion per source, then the overrides of [`super::convert`] and the per-channel
//! RGB scales.

use super::SceneFileError;
use super::convert::Cx;
use super::schema::MediumDoc;
use crate::scene::generators::{self, GeneratorError};
use crate::scene::vdb;
use crate::{Grid, Medium, SolverError};

/// The per-channel (R, G, B) media of a coloured scene.
type Channels = [Medium<f64>; 3];

/// Where σt (and, for a generator, every field) of the base medium comes from: exactly one
/// of `generator`, `file` and `vdb`, each holding the value of its key.
#[derive(Debug, Clone, Copy)]
enum MediumSource<'a> {
    /// `generator = "…"`: a registered procedural medium, with `[medium.params]`.
    Generator(&'a str),
    /// `file = "….vol"`: σt from a Mitsuba `.vol` grid.
    Vol(&'a str),
    /// `vdb = "….vdb"`: σt from an OpenVDB float grid named by `grid`.
    Vdb(&'a str),
}

impl MediumSource<'_> {
    /// The field that errors about σt of this source name.
    fn density_field(self) -> &'static str {
        match self {
            MediumSource::Generator(_) => "medium.params",
            MediumSource::Vol(_) => "medium.file",
            MediumSource::Vdb(_) => "medium.vdb",
        }
    }
}

impl Cx<'_> {
    /// The monochrome medium and, for a coloured scene, the three channel media.
    pub(super) fn medium(
        &self,
        m: &MediumDoc,
    ) -> Result<(Medium<f64>, Option<Box<Channels>>), SceneFileError> {
        let source = self.medium_source(m)?;
        let (base, base_channels) = match source {
            MediumSource::Generator(name) => self.generator_medium(m, name)?,
            MediumSource::Vdb(rel) => (self.vdb_medium(m, rel)?, None),
            MediumSource::Vol(rel) => (self.vol_medium(m, rel)?, None),
        };
        let density_field = source.density_field();
        let mono = self.overrides(m, base, density_field)?;
        let channels = match base_channels {
            Some([r, g, b]) => Some([
                self.overrides(m, r, density_field)?,
                self.overrides(m, g, density_field)?,
                self.overrides(m, b, density_field)?,
            ]),
            None => None,
        };
        let channels = self.colour_scales(m, &mono, channels)?;
        Ok((mono, channels.map(Box::new)))
    }

    /// Which of `generator`, `file` and `vdb` the table gives (exactly one, else an error).
    fn medium_source<'m>(&self, m: &'m MediumDoc) -> Result<MediumSource<'m>, SceneFileError> {
        let loc = self.loc;
        if m.vdb.is_none() && m.grid.is_some() {
            return Err(loc.err("medium.grid", "`grid` names a grid of a `vdb` file"));
        }
        match (&m.generator, &m.file, &m.vdb) {
            (Some(name), None, None) => Ok(MediumSource::Generator(name)),
            (None, Some(rel), None) => Ok(MediumSource::Vol(rel)),
            (None, None, Some(rel)) => Ok(MediumSource::Vdb(rel)),
            (None, None, None) => Err(loc.err(
                "medium",
                format!(
                    "needs `generator = \"…\"` (one of {}) or `file = \"….vol\"`",
                    generators::names()
                ),
            )),
            (_, _, vdb) => {
                let field = if vdb.is_some() {
                    "medium.vdb"
                } else {
                    "medium.file"
                };
                Err(loc.err(field, "give one of `generator`, `file` or `vdb`, not both"))
            }
        }
    }

    /// The medium of generator `name` from `[medium.params]`, and its channels if coloured.
    fn generator_medium(
        &self,
        m: &MediumDoc,
        name: &str,
    ) -> Result<(Medium<f64>, Option<Channels>), SceneFileError> {
        let loc = self.loc;
        let entry = generators::find(name).ok_or_else(|| {
            loc.err(
                "medium.generator",
                format!("unknown generator `{name}`; known: {}", generators::names()),
            )
        })?;
        if let Some(n) = m.params.as_ref().and_then(|p| p.get("n")) {
            let dims: Vec<usize> = match n {
                toml::Value::Integer(k) => vec![usize::try_from(*k).unwrap_or(0); 3],
                toml::Value::Array(a) => a
                    .iter()
                    .map(|v| {
                        v.as_integer()
                            .and_then(|k| usize::try_from(k).ok())
                            .unwrap_or(0)
                    })
                    .collect(),
                _ => Vec::new(),
            };
            if !dims.is_empty() {
                let bytes = crate::budget::bytes(&dims, crate::budget::MEDIUM_BYTES_PER_VOXEL);
                crate::budget::check(format!("medium.params.n = {n}"), bytes)
                    .map_err(|e| loc.err("medium.params.n", e.to_string()))?;
            }
        }
        let medium = entry.build_from_document(self.text).map_err(|e| match e {
            GeneratorError::Params(e) => loc.toml_err(&e, "medium.params"),
            GeneratorError::Solver(SolverError::BadParameter {
                name,
                value,
                reason,
            }) if m.params.as_ref().is_some_and(|p| p.contains_key(name)) => loc.err(
                &format!("medium.params.{name}"),
                format!("{} is invalid: {reason}", crate::error::Compact(value)),
            ),
            GeneratorError::Solver(e) => {
                loc.err("medium.params", format!("generator `{name}`: {e}"))
            }
        })?;
        let channels = entry
            .build_channels_from_document(self.text)
            .map_err(|e| loc.err("medium.params", format!("generator `{name}`: {e}")))?;
        Ok((medium, channels))
    }

    /// σt from the OpenVDB float grid `grid` (default "density") of `rel`, on the unit box
    /// of its longest axis; albedo and emission come from the overrides.
    fn vdb_medium(&self, m: &MediumDoc, rel: &str) -> Result<Medium<f64>, SceneFileError> {
        let loc = self.loc;
        if m.params.is_some() {
            return Err(loc.err(
                "medium.params",
                "parameters belong to a `generator`; this medium reads `vdb`",
            ));
        }
        let grid_name = m.grid.as_deref().unwrap_or("density");
        let path = self.dir.join(rel);
        let (dims, sigma_t) = vdb::read_float_grid(&path, grid_name)
            .map_err(|e| loc.err("medium.vdb", crate::error::chain(&e)))?;
        let grid = Grid::new(dims, 1.0 / dims.into_iter().max().unwrap_or(1) as f64)
            .map_err(|e| loc.err("medium.vdb", format!("`{rel}`: {e}")))?;
        if m.albedo.is_none() {
            return Err(loc.err(
                "medium.albedo",
                "required with `vdb`: a number in [0, 1] or a .vol path",
            ));
        }
        Ok(unlit(grid, sigma_t))
    }

    /// σt from the one-channel `.vol` grid `rel`, on its own box unless `min`/`max` give
    /// one; albedo and emission come from the overrides.
    fn vol_medium(&self, m: &MediumDoc, rel: &str) -> Result<Medium<f64>, SceneFileError> {
        let loc = self.loc;
        if m.params.is_some() {
            return Err(loc.err(
                "medium.params",
                "parameters belong to a `generator`; this medium reads `file`",
            ));
        }
        let vol = self.read_vol("medium.file", rel)?;
        let sigma_t = self.single_channel("medium.file", rel, &vol)?;
        let grid = if m.min.is_some() || m.max.is_some() {
            // Replaced by the explicit box in the overrides; only the dimensions matter here.
            Grid::new(vol.dims, 1.0).map_err(|e| loc.err("medium.file", format!("`{rel}`: {e}")))?
        } else {
            vol.grid().map_err(|e| {
                loc.err(
                    "medium.file",
                    format!("`{rel}`: {}", crate::error::chain(&e)),
                )
            })?
        };
        if m.albedo.is_none() {
            return Err(loc.err(
                "medium.albedo",
                "required with `file`: a number in [0, 1] or a .vol path",
            ));
        }
        Ok(unlit(grid, sigma_t))
    }

    /// Applies `sigma_t_rgb`, `albedo_rgb` and `emission_rgb`: with any of them, every
    /// channel (the generator's, else three copies of `mono`) is scaled by its entry.
    /// Without them, `channels` is returned as it is.
    fn colour_scales(
        &self,
        m: &MediumDoc,
        mono: &Medium<f64>,
        channels: Option<Channels>,
    ) -> Result<Option<Channels>, SceneFileError> {
        let loc = self.loc;
        let scales = [
            ("medium.sigma_t_rgb", m.sigma_t_rgb),
            ("medium.albedo_rgb", m.albedo_rgb),
            ("medium.emission_rgb", m.emission_rgb),
        ];
        if scales.iter().all(|(_, v)| v.is_none()) {
            return Ok(channels);
        }
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
        Ok(Some(ch))
    }
}

/// A medium with σt only (albedo and emission 0, to be set by the overrides).
fn unlit(grid: Grid, sigma_t: Vec<f64>) -> Medium<f64> {
    let n = grid.len();
    Medium {
        grid,
        sigma_t,
        albedo: vec![0.0; n],
        emission: vec![0.0; n],
    }
}
