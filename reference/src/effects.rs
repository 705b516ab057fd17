//! The path tracer on exactly the effects the grid pipeline renders: maps a
//! [`solvers::scene::Effects`] set to the path-tracer renders ([`Contributions`] and, where
//! needed, a scene with fewer lights or an isotropic phase function) whose sum is each of the
//! pipeline's image components (`solvers::pipeline::ChannelImages`):
//!
//! | component | path-tracer renders |
//! |---|---|
//! | `single` | [`Contributions::single_scattering`] on the scene with only the lights whose single scattering is in the set |
//! | `multiple` | [`Contributions::multiple_scattering`] (if the scene has lights) + [`Contributions::scattered_emission`] (if emission is in the set) — only if multiple scattering is in the set |
//! | `emission` | [`Contributions::emission_only`] — if emission is in the set |
//! | `background` | [`Contributions::background`] (order 0 from the lights) — if background is in the set |
//!
//! Every render uses the phase function the effect set implies (isotropic unless
//! anisotropy is in the set). Each render gets its own seed (`seed + k` for the k-th render
//! of [`pt_passes`]), so the components are independent estimates and their standard errors
//! add in quadrature.

use crate::ReferenceError;
use crate::pathtracer::camera::render_image_part;
use crate::pathtracer::{BatchSums, Contributions, Image, RenderSettings, Shard, TraceOptions};
use solvers::scene::{Effect, Effects, Scene};

/// One of the pipeline's image components.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Component {
    /// Order 1 from lights.
    Single,
    /// Orders ≥ 2 from lights and ≥ 1 from emission.
    Multiple,
    /// Order-0 emission.
    Emission,
    /// Order 0 from the lights (the environment seen through the medium).
    Background,
}

/// One path-tracer render that contributes to a component.
#[derive(Debug, Clone)]
pub struct PtPass {
    /// The component it belongs to.
    pub component: Component,
    /// The scene to render (lights and phase function adjusted to the effect set).
    pub scene: Scene,
    /// What the render keeps.
    pub contributions: Contributions,
}

/// The path-tracer renders that reproduce the pipeline's components of `scene` under
/// `effects` (see the module table). Empty when nothing is rendered.
pub fn pt_passes(scene: &Scene, effects: &Effects) -> Vec<PtPass> {
    let mut base = scene.clone();
    base.phase = effects.apply_phase(scene.phase);
    let mut out = Vec::new();
    let ss = effects.single_scattering_lights();
    if !ss.is_empty() {
        let mut s = base.clone();
        s.lights = ss
            .iter()
            .filter_map(|&i| scene.lights.get(i).copied())
            .collect();
        out.push(PtPass {
            component: Component::Single,
            scene: s,
            contributions: Contributions::single_scattering(),
        });
    }
    let emission = effects.contains(Effect::Emission);
    if effects.contains(Effect::MultipleScattering) {
        if !scene.lights.is_empty() {
            out.push(PtPass {
                component: Component::Multiple,
                scene: base.clone(),
                contributions: Contributions::multiple_scattering(),
            });
        }
        if emission {
            out.push(PtPass {
                component: Component::Multiple,
                scene: base.clone(),
                contributions: Contributions::scattered_emission(),
            });
        }
    }
    if emission {
        out.push(PtPass {
            component: Component::Emission,
            scene: base.clone(),
            contributions: Contributions::emission_only(),
        });
    }
    if effects.contains(Effect::Background) {
        out.push(PtPass {
            component: Component::Background,
            scene: base,
            contributions: Contributions::background(),
        });
    }
    out
}

/// Path-traced images of the pipeline's components, each with standard errors (a component
/// that is not rendered is zero with zero error).
#[derive(Debug, Clone)]
pub struct PtComponents {
    /// single + multiple + emission + background.
    pub total: Image,
    /// Order 1 from lights.
    pub single: Image,
    /// Orders ≥ 2 from lights, ≥ 1 from emission.
    pub multiple: Image,
    /// Order-0 emission.
    pub emission: Image,
    /// Order 0 from the lights.
    pub background: Image,
    /// The renders that ran, with their seconds.
    pub renders: Vec<(Component, Contributions, f64)>,
}

impl PtComponents {
    /// All components zero (with zero error) on a `w` × `h` image, no renders.
    pub fn zeros(w: usize, h: usize) -> Self {
        Self {
            total: Image::zeros(w, h),
            single: Image::zeros(w, h),
            multiple: Image::zeros(w, h),
            emission: Image::zeros(w, h),
            background: Image::zeros(w, h),
            renders: Vec::new(),
        }
    }

    /// Adds the independent render `im` of `component` (made with `contributions` in
    /// `seconds`) to its component and to the total.
    pub fn add(
        &mut self,
        component: Component,
        contributions: Contributions,
        im: &Image,
        seconds: f64,
    ) {
        self.renders.push((component, contributions, seconds));
        let target = match component {
            Component::Single => &mut self.single,
            Component::Multiple => &mut self.multiple,
            Component::Emission => &mut self.emission,
            Component::Background => &mut self.background,
        };
        target.add_independent(im);
        self.total.add_independent(im);
    }

    /// Camera paths traced: one per pixel sample of each render that ran, at `spp` samples
    /// per pixel (what `paths_per_second` counts in the atlas and `mitsuba_compare`).
    pub fn paths(&self, spp: u32) -> u64 {
        let pixels = (self.total.width * self.total.height) as u64;
        self.renders.len() as u64 * pixels * u64::from(spp)
    }
}

/// Renders the components of `scene` under `effects` with the path tracer (`settings`'
/// contributions are replaced per render, and its seed offset by the render's index).
pub fn render_components(
    scene: &Scene,
    effects: &Effects,
    settings: &RenderSettings,
) -> Result<PtComponents, ReferenceError> {
    let parts = render_components_part(scene, effects, settings, Shard::WHOLE)?;
    components_from_parts(scene, effects, &parts)
}

/// One pass of [`render_components_part`]: its per-batch sums and the seconds it took.
#[derive(Debug, Clone, PartialEq)]
pub struct PassSums {
    /// Per-batch pixel sums ([`render_image_part`]).
    pub sums: BatchSums,
    /// Wall-clock seconds of this part (summed over shards once joined).
    pub seconds: f64,
}

/// [`render_components`] for `shard`'s batches: one [`PassSums`] per pass of
/// [`pt_passes`], in order.
pub fn render_components_part(
    scene: &Scene,
    effects: &Effects,
    settings: &RenderSettings,
    shard: Shard,
) -> Result<Vec<PassSums>, ReferenceError> {
    pt_passes(scene, effects)
        .into_iter()
        .enumerate()
        .map(|(k, pass)| {
            let s = RenderSettings {
                contributions: pass.contributions,
                seed: settings.seed.wrapping_add(k as u64),
                ..*settings
            };
            let t0 = std::time::Instant::now();
            let sums = render_image_part(&pass.scene, &s, &TraceOptions::of(&pass.scene), shard)?;
            Ok(PassSums {
                sums,
                seconds: t0.elapsed().as_secs_f64(),
            })
        })
        .collect()
}

/// The components of a whole render from its passes' joined sums
/// ([`render_components_part`] of the same scene and effects).
pub fn components_from_parts(
    scene: &Scene,
    effects: &Effects,
    parts: &[PassSums],
) -> Result<PtComponents, ReferenceError> {
    let camera = scene.camera.ok_or(ReferenceError::NoCamera)?;
    let [w, h] = camera.resolution;
    let passes = pt_passes(scene, effects);
    if passes.len() != parts.len() {
        return Err(ReferenceError::ShardMismatch {
            what: format!(
                "the scene's effects need {} path-traced passes, the sums hold {}",
                passes.len(),
                parts.len()
            ),
        });
    }
    let mut out = PtComponents::zeros(w, h);
    for (pass, part) in passes.into_iter().zip(parts) {
        let im = Image::from_sums(w, h, &part.sums)?;
        out.add(pass.component, pass.contributions, &im, part.seconds);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use solvers::scene::{EffectSelection, Light, Phase, Sampler};
    use solvers::{Grid, Medium};

    #[test]
    fn passes_follow_the_effect_set() {
        let grid = Grid::cube(4, 1.0).unwrap();
        let mut medium = Medium::homogeneous(grid, 2.0, 0.5).unwrap();
        medium.emission = vec![1.0; grid.len()];
        let scene = Scene {
            interpolation: Default::default(),
            medium,
            phase: Phase::HenyeyGreenstein { g: 0.5 },
            lights: vec![
                Light::directional([0.0, 0.0, -1.0], 1.0).unwrap(),
                Light::Point {
                    position: [0.5, 0.5, 2.0],
                    power: 1.0,
                },
            ],
            camera: None,
            sampler: Sampler { spp: 1, seed: 0 },
        };
        let all = scene.implied_effects();
        let p = pt_passes(&scene, &all);
        let kinds: Vec<_> = p.iter().map(|p| (p.component, p.contributions)).collect();
        assert_eq!(
            kinds,
            vec![
                (Component::Single, Contributions::single_scattering()),
                (Component::Multiple, Contributions::multiple_scattering()),
                (Component::Multiple, Contributions::scattered_emission()),
                (Component::Emission, Contributions::emission_only()),
            ]
        );
        assert_eq!(p[0].scene.phase, Phase::HenyeyGreenstein { g: 0.5 });
        let sel =
            EffectSelection::exclude(&["single_scattering[1]", "emission", "anisotropy"]).unwrap();
        let e = all.restrict(&sel, 2).unwrap();
        let p = pt_passes(&scene, &e);
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].scene.lights, vec![scene.lights[0]]);
        assert_eq!(p[0].scene.phase, Phase::Isotropic);
        assert_eq!(p[1].contributions, Contributions::multiple_scattering());
        assert_eq!(p[1].scene.lights.len(), 2);
        let only = EffectSelection::only(&["emission"]).unwrap();
        let p = pt_passes(&scene, &all.restrict(&only, 2).unwrap());
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].contributions, Contributions::emission_only());
    }
}
