//! Effect-driven planning: the minimal list of passes that renders an effect set.
//!
//! | pass | runs when |
//! |---|---|
//! | `bake_directional[i]` / `bake_point[i]` | single scattering of light i is in the set, or multiple scattering is (every light sources q_ri) |
//! | `diffusion_solve` | multiple scattering is in the set (source q_ri of the baked lights, plus j if emission is in the set) |
//! | `raymarch_single` | single scattering of at least one light is in the set (isotropic fast path unless anisotropy is) |
//! | `raymarch_multiple` | multiple scattering is in the set |
//! | `raymarch_emission` | emission is in the set |
//! | `raymarch_background` | background is in the set (an environment light seen through the medium, `[camera] hide_background` not set) |
//!
//! Nothing else runs: no baking without lights whose light is needed, no diffusion solve when
//! nothing scatters or multiple scattering is excluded, no emission pass without emission.
//! An empty plan renders a black image without running anything.

use super::PipelineError;
use crate::method::{LightInput, Method};
use crate::scene::{Effect, Effects, Light};
use serde::Serialize;
use std::fmt::Write;

/// One pass of the pipeline.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Pass {
    /// Deep shadow map and q_ri of directional light `light`.
    BakeDirectional {
        /// Light index.
        light: usize,
    },
    /// Deep shadow map (with 1/r²) and q_ri of point light `light`.
    BakePoint {
        /// Light index.
        light: usize,
    },
    /// The multiple-scattering solve for φ (FLD Eq 12 / Eq 20, or any other registered
    /// [`Method`]).
    DiffusionSolve {
        /// [`Method::name`], e.g. `cda`, `fld:lp`, `lbm`.
        method: String,
        /// Downsampling factor of the grid.
        downsample: usize,
        /// Whether j is part of the source (emission in the set).
        with_emission: bool,
        /// Lights whose q_ri is part of the source (or, for a method that takes lights
        /// itself, the lights it is given).
        lights: Vec<usize>,
        /// Whether the method sees the scene's phase function (its capability, and
        /// anisotropy in the effect set).
        anisotropic: bool,
    },
    /// Primary raymarch of single scattering.
    RaymarchSingle {
        /// Lights whose single scattering is rendered.
        lights: Vec<usize>,
        /// Isotropic fast path (g = 0 or anisotropy not in the set).
        isotropic: bool,
    },
    /// Primary raymarch of σs φ/4π.
    RaymarchMultiple,
    /// Primary raymarch of j/4π.
    RaymarchEmission,
    /// The environment seen through the medium: L_env·T along each camera ray (order 0).
    RaymarchBackground {
        /// Summed radiance of the environment lights.
        radiance: f64,
    },
}

impl Pass {
    /// Short name: `bake_directional[0]`, `diffusion_solve`, `raymarch_single`, …
    pub fn name(&self) -> String {
        match self {
            Pass::BakeDirectional { light } => format!("bake_directional[{light}]"),
            Pass::BakePoint { light } => format!("bake_point[{light}]"),
            Pass::DiffusionSolve { .. } => "diffusion_solve".into(),
            Pass::RaymarchSingle { .. } => "raymarch_single".into(),
            Pass::RaymarchMultiple => "raymarch_multiple".into(),
            Pass::RaymarchEmission => "raymarch_emission".into(),
            Pass::RaymarchBackground { .. } => "raymarch_background".into(),
        }
    }
}

/// A pass that runs, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Planned {
    /// The pass.
    pub pass: Pass,
    /// Why it runs.
    pub why: String,
    /// The effects whose light this pass computes (names as in `[effects]`). The image
    /// passes (`raymarch_*`) each render a disjoint set whose union is every rendered effect
    /// but `attenuation` and `anisotropy` (no effect counted twice, `every_effect_is_…`);
    /// `diffusion_solve` lists those its φ carries (rendered by `raymarch_multiple`); the
    /// bakes compute intermediate data only (empty).
    pub computes: Vec<String>,
}

/// A pass that does not run, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Skipped {
    /// The pass name.
    pub pass: String,
    /// Why it does not run.
    pub why: String,
}

/// The plan of a render.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plan {
    /// The effects the scene implies (union over colour channels).
    pub implied: Effects,
    /// The effects rendered (after `[effects]` and caller restrictions).
    pub effects: Effects,
    /// The passes, in execution order.
    pub passes: Vec<Planned>,
    /// The passes left out.
    pub skipped: Vec<Skipped>,
    /// Warnings about the plan (e.g. the paper's isotropic σs under |g| > 0.5).
    pub warnings: Vec<String>,
}

/// Light kind names for messages.
fn kind(l: &Light) -> &'static str {
    match l {
        Light::Point { .. } => "point",
        Light::Directional { .. } => "directional",
        Light::Sphere { .. } => "sphere",
        Light::Environment { .. } => "environment",
    }
}

/// Plans the passes that render `effects` (a restriction of `implied`) for a scene with
/// these `lights`; `method` (read through its [`Method::capabilities`]) and `downsample`
/// describe the multiple-scattering solve.
pub fn plan(
    lights: &[Light],
    implied: &Effects,
    effects: &Effects,
    method: &dyn Method,
    downsample: usize,
) -> Result<Plan, PipelineError> {
    let caps = method.capabilities();
    let ss = effects.single_scattering_lights();
    let ms = effects.contains(Effect::MultipleScattering);
    let emission = effects.contains(Effect::Emission);
    if ms && emission && !caps.volume_source {
        return Err(PipelineError::MethodCannot {
            method: method.name(),
            what: "multiply scatter volume emission (it takes no volume source); exclude `multiple` or `emission`, or choose another method",
        });
    }
    // Lights enter the multiple-scattering solve as baked q_ri unless the method takes them.
    let baked_for_ms = ms && caps.lights == LightInput::Baked;
    // A Direct method takes the lights itself (the contract of φ: `LightInput`): it refuses
    // sphere lights, and point lights unless it has `direct_points` (POP), and the single
    // scattering of an environment light is its.
    let direct = ms && caps.lights == LightInput::Direct;
    let mut by_solve = Vec::new();
    if direct {
        crate::method::direct_lights(&method.name(), lights, caps.direct_points)?;
        for (i, l) in lights.iter().enumerate() {
            if matches!(l, Light::Environment { .. }) {
                if ss.contains(&i) {
                    by_solve.push(i);
                } else if implied.contains(Effect::SingleScattering { light: i }) {
                    return Err(PipelineError::MethodCannot {
                        method: method.name(),
                        what: "exclude the single scattering of an environment light while rendering multiple scattering (its φ holds both); exclude both or neither",
                    });
                }
            }
        }
    }
    let ss: Vec<usize> = ss.into_iter().filter(|i| !by_solve.contains(i)).collect();
    let why_not = |e: Effect, what: &str| -> String {
        if implied.contains(e) {
            format!("{what} is excluded by the effect selection")
        } else {
            format!("the scene has no {what}")
        }
    };
    let mut passes = Vec::new();
    let mut skipped = Vec::new();
    let mut warnings = Vec::new();
    let mut carries = Vec::new();
    let mut baked = Vec::new();
    for (i, light) in lights.iter().enumerate() {
        let for_ss = ss.contains(&i);
        let name = format!("bake_{}[{i}]", kind(light));
        if !for_ss && !baked_for_ms {
            let why = if by_solve.contains(&i) {
                format!(
                    "{} takes light {i} itself and computes its single scattering",
                    method.name()
                )
            } else if !implied.contains(Effect::SingleScattering { light: i }) {
                "nothing scatters, so the light is never seen".to_string()
            } else {
                format!(
                    "neither single scattering of light {i} nor multiple scattering is rendered"
                )
            };
            skipped.push(Skipped { pass: name, why });
            continue;
        }
        let pass = match light {
            Light::Directional { .. } => Pass::BakeDirectional { light: i },
            Light::Point { .. } => Pass::BakePoint { light: i },
            other => {
                return Err(PipelineError::UnsupportedLight {
                    index: i,
                    kind: kind(other),
                });
            }
        };
        let why = match (for_ss, baked_for_ms) {
            (true, true) => format!(
                "single scattering of light {i} is rendered and its q_ri sources multiple scattering"
            ),
            (true, false) => format!("single scattering of light {i} is rendered"),
            _ => "its q_ri sources multiple scattering (its single scattering is not rendered)"
                .to_string(),
        };
        baked.push(i);
        passes.push(Planned {
            pass,
            why,
            computes: Vec::new(),
        });
    }
    if ms {
        let mut src = Vec::new();
        let direct: Vec<usize> = (0..lights.len()).collect();
        let ms_lights = if caps.lights == LightInput::Baked {
            if !baked.is_empty() {
                src.push(format!("q_ri of light(s) {baked:?}"));
            }
            baked.clone()
        } else {
            if !direct.is_empty() {
                src.push(format!(
                    "light(s) {direct:?} taken by the method itself (their uncollided light excluded, except an environment's: its single scattering is in φ)"
                ));
            }
            direct
        };
        carries = vec![Effect::MultipleScattering.to_string()];
        carries.extend(
            by_solve
                .iter()
                .map(|&light| Effect::SingleScattering { light }.to_string()),
        );
        if emission {
            src.push("the emission j".into());
        }
        let anisotropic = caps.anisotropic && effects.contains(Effect::Anisotropy);
        if !by_solve.is_empty() && effects.contains(Effect::Anisotropy) {
            warnings.push(format!(
                "the single scattering of environment light(s) {by_solve:?} is {}'s σs·φ/4π: isotropic in-scattering of the uncollided light, not the scene's phase function",
                method.name()
            ));
        }
        passes.push(Planned {
            computes: carries.clone(),
            pass: Pass::DiffusionSolve {
                method: method.name(),
                downsample,
                with_emission: emission,
                lights: ms_lights,
                anisotropic,
            },
            why: format!(
                "multiple scattering is rendered: φ from {} on a grid downsampled {downsample}x by {}, {}",
                src.join(" + "),
                method.name(),
                if anisotropic && method.anisotropy().is_some() {
                    "with the scene's phase function on the method's own kernel (the paper's variant `paper`)"
                } else if anisotropic {
                    "with the scene's phase function"
                } else if method.anisotropy() == Some(crate::method::AnisotropyScaling::Similarity) {
                    "scattering isotropically with the similarity scaling σs' = (1 − g)σs, σt' = σa + σs' (variant `similarity`)"
                } else if method.anisotropy().is_some() {
                    "scattering isotropically with σs as given (the paper's variant `paper`)"
                } else {
                    "scattering isotropically with σs as given"
                }
            ),
        });
    } else {
        skipped.push(Skipped {
            pass: "diffusion_solve".into(),
            why: why_not(Effect::MultipleScattering, "multiple scattering"),
        });
    }
    if ss.is_empty() {
        skipped.push(Skipped {
            pass: "raymarch_single".into(),
            why: if lights.is_empty() {
                "the scene has no lights".into()
            } else if implied.single_scattering_lights().is_empty() {
                "nothing scatters".into()
            } else {
                "single scattering is excluded by the effect selection".into()
            },
        });
    } else {
        let isotropic = !effects.contains(Effect::Anisotropy);
        passes.push(Planned {
            computes: ss
                .iter()
                .map(|&light| Effect::SingleScattering { light }.to_string())
                .collect(),
            pass: Pass::RaymarchSingle {
                lights: ss.clone(),
                isotropic,
            },
            why: format!(
                "single scattering of light(s) {ss:?}, {}",
                if isotropic {
                    "isotropic phase (fast path)"
                } else {
                    "with the scene's anisotropic phase function"
                }
            ),
        });
    }
    if ms {
        passes.push(Planned {
            pass: Pass::RaymarchMultiple,
            why: "σs·φ/4π of FLD Eq 8 (isotropic)".into(),
            computes: carries,
        });
    } else {
        skipped.push(Skipped {
            pass: "raymarch_multiple".into(),
            why: why_not(Effect::MultipleScattering, "multiple scattering"),
        });
    }
    if emission {
        passes.push(Planned {
            computes: vec![Effect::Emission.to_string()],
            pass: Pass::RaymarchEmission,
            why: "j/4π of FLD Eq 8 (unscattered emission)".into(),
        });
    } else {
        skipped.push(Skipped {
            pass: "raymarch_emission".into(),
            why: why_not(Effect::Emission, "emission"),
        });
    }
    if effects.contains(Effect::Background) {
        if let Some((index, light)) = lights
            .iter()
            .enumerate()
            .find(|(_, l)| matches!(l, Light::Sphere { .. }))
        {
            return Err(PipelineError::UnsupportedLight {
                index,
                kind: kind(light),
            });
        }
        let radiance: f64 = lights
            .iter()
            .map(|l| match l {
                Light::Environment { radiance } => *radiance,
                _ => 0.0,
            })
            .sum();
        passes.push(Planned {
            computes: vec![Effect::Background.to_string()],
            pass: Pass::RaymarchBackground { radiance },
            why: format!(
                "the environment (radiance {radiance}) seen through the medium: L_env·T, order 0 (hide it with [camera] hide_background = true)"
            ),
        });
    } else {
        skipped.push(Skipped {
            pass: "raymarch_background".into(),
            why: if implied.contains(Effect::Background) {
                "background is excluded by the effect selection".into()
            } else {
                "the camera sees no light directly (no environment or sphere light, or hide_background)".into()
            },
        });
    }
    Ok(Plan {
        implied: implied.clone(),
        effects: effects.clone(),
        passes,
        skipped,
        warnings,
    })
}

impl Plan {
    /// The pass names in order.
    pub fn pass_names(&self) -> Vec<String> {
        self.passes.iter().map(|p| p.pass.name()).collect()
    }

    /// Whether a pass of this name runs.
    pub fn runs(&self, name: &str) -> bool {
        self.passes.iter().any(|p| p.pass.name() == name)
    }

    /// The plan as text, for `--explain`.
    pub fn explain(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "implied effects:  {}", self.implied.names());
        let _ = writeln!(s, "rendered effects: {}", self.effects.names());
        if self.passes.is_empty() {
            let _ = writeln!(s, "passes: none (the image is black)");
        } else {
            let _ = writeln!(s, "passes:");
            for (k, p) in self.passes.iter().enumerate() {
                let _ = writeln!(s, "  {}. {:<22} {}", k + 1, p.pass.name(), p.why);
                if !p.computes.is_empty() {
                    let _ = writeln!(s, "     {:<22} computes: {}", "", p.computes.join(", "));
                }
            }
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        if !self.skipped.is_empty() {
            let _ = writeln!(s, "skipped:");
            for p in &self.skipped {
                let _ = writeln!(s, "  - {:<22} {}", p.pass, p.why);
            }
        }
        s
    }
}
