//! Services the image experiments share (`accuracy_cost`, `renderings`): loading a scene
//! file coarsened and re-framed, its path-traced reference with the reference's own noise,
//! and the image errors of a method against that reference.

use crate::common::{Ctx, parse_list, workspace_root};
use crate::images::{relative_noise, relative_rmse, relative_rmse_debiased};
use anyhow::{Context, Result, bail};
use reference::effects::{PtComponents, components_from_parts, render_components_part};
use reference::pathtracer::{Contributions, RenderSettings};
use solvers::pipeline::{self, ChannelImages, PipelineConfig};
use solvers::scene::{EffectSelection, Effects, Scene, SceneFile};
use std::path::PathBuf;

/// A scene prepared for comparison with its reference: its channels, effect set and reference.
#[derive(Debug)]
pub struct Prepared {
    /// File stem.
    pub name: String,
    /// Monochrome scene per colour channel (coarsened, resolution overridden).
    pub channels: Vec<Scene>,
    /// The file's `[effects]` restriction.
    pub selection: EffectSelection,
    /// The effects rendered.
    pub effects: Effects,
    /// Reference per channel.
    pub reference: Vec<PtComponents>,
    /// Seconds the reference took.
    pub reference_seconds: f64,
}

impl Prepared {
    /// The reference's own relative noise, √Σse²/√Σr² of the total image.
    pub fn noise(&self) -> f64 {
        let r: Vec<&[f64]> = self
            .reference
            .iter()
            .map(|c| c.total.mean.as_slice())
            .collect();
        let se: Vec<&[f64]> = self
            .reference
            .iter()
            .map(|c| c.total.stderr.as_slice())
            .collect();
        relative_noise(&se, &r)
    }
}

/// Scene files from a comma-separated list; relative paths that do not exist from the
/// current directory are taken from the workspace root.
pub fn scene_paths(list: &str) -> Result<Vec<PathBuf>> {
    let root = workspace_root();
    let v: Vec<PathBuf> = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            let p = PathBuf::from(s);
            if p.is_absolute() || p.exists() {
                p
            } else {
                root.join(p)
            }
        })
        .collect();
    if v.is_empty() {
        bail!("--scenes: no scene files given");
    }
    Ok(v)
}

/// Parses `W,H` (both > 0).
pub fn parse_resolution(s: &str) -> Result<[usize; 2]> {
    let v: Vec<usize> = parse_list("resolution", s)?;
    match v.as_slice() {
        [w, h] if *w > 0 && *h > 0 => {
            solvers::budget::check(
                format!("--resolution {w},{h}"),
                solvers::budget::image_bytes(*w, *h),
            )?;
            Ok([*w, *h])
        }
        _ => bail!("--resolution must be W,H with W, H > 0, got `{s}`"),
    }
}

/// Loads, coarsens and re-frames a scene file (no reference yet: [`render_reference`]).
pub fn load(
    path: &std::path::Path,
    coarsen: usize,
    resolution: Option<[usize; 2]>,
) -> Result<Prepared> {
    let file = SceneFile::load(path).with_context(|| format!("loading {}", path.display()))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let mut channels = file.channels();
    for ch in &mut channels {
        if coarsen > 1 {
            let q = ch.medium.emission.clone();
            ch.medium = pipeline::restrict::restrict(&ch.medium, &q, coarsen, 0)
                .with_context(|| format!("coarsening {name} by {coarsen}"))?;
        }
        if let (Some(res), Some(cam)) = (resolution, ch.camera.as_mut()) {
            cam.resolution = res;
        }
    }
    let config = PipelineConfig::default();
    let (_, effects) = pipeline::effects_of(&channels, &file.effects, &config)
        .with_context(|| format!("the effects of {name}"))?;
    Ok(Prepared {
        name,
        channels,
        selection: file.effects.clone(),
        effects,
        reference: Vec::new(),
        reference_seconds: 0.0,
    })
}

/// Renders the path-traced reference of every channel (`spp` ≥ 16 samples per pixel,
/// up to 32 batches), one [`Ctx::tally`] per channel. Returns whether the reference is
/// there: with `--shard` only this shard's batches are computed (for the merge) and it is
/// not. `reference_seconds` is the render time (summed over shards in a merge).
pub fn render_reference(ctx: &mut Ctx, scene: &mut Prepared, spp: u32, seed: u64) -> Result<bool> {
    let settings = RenderSettings {
        spp,
        seed,
        batches: 32.min(spp),
        contributions: Contributions::all(),
    };
    scene.reference.clear();
    scene.reference_seconds = 0.0;
    for (c, ch) in scene.channels.iter().enumerate() {
        let what = format!("path-traced reference of {}, channel {c}", scene.name);
        let tallied = ctx.tally(
            &what,
            |shard| {
                render_components_part(ch, &scene.effects, &settings, shard)
                    .with_context(|| what.clone())
            },
            |parts| {
                let seconds: f64 = parts.iter().map(|p| p.seconds).sum();
                Ok((components_from_parts(ch, &scene.effects, parts)?, seconds))
            },
        )?;
        if let Some((comp, seconds)) = tallied {
            scene.reference.push(comp);
            scene.reference_seconds += seconds;
        }
    }
    Ok(scene.reference.len() == scene.channels.len())
}

/// The errors of a run against the prepared reference: (total, debiased, single, multiple).
pub fn errors(scene: &Prepared, images: &[ChannelImages]) -> (f64, f64, f64, f64) {
    let pick = |f: fn(&ChannelImages) -> &Vec<f64>| -> Vec<&[f64]> {
        images.iter().map(|c| f(c).as_slice()).collect()
    };
    let refs = |f: fn(&PtComponents) -> &Vec<f64>| -> Vec<&[f64]> {
        scene.reference.iter().map(|c| f(c).as_slice()).collect()
    };
    let total = pick(|c| &c.total);
    let rt = refs(|c| &c.total.mean);
    let se = refs(|c| &c.total.stderr);
    (
        relative_rmse(&total, &rt),
        relative_rmse_debiased(&total, &rt, &se),
        relative_rmse(&pick(|c| &c.single), &refs(|c| &c.single.mean)),
        relative_rmse(&pick(|c| &c.multiple), &refs(|c| &c.multiple.mean)),
    )
}
