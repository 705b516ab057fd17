//! Issue 12, item 2: the paper's isotropic σs against the similarity scaling in the grid
//! pipeline's multiple-scattering image (CDA, FLD-LP, LBM), both measured against the path tracer on the HG
//! `noise_cloud` and `shell_core` datasets (32³, 16×16 camera) at g ∈ {0.3, 0.7, 0.9, 0.99}.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use reference::effects::render_components;
use reference::pathtracer::{Contributions, RenderSettings};
use solvers::pipeline::{self, PipelineConfig};
use solvers::scene::{Phase, SceneFile};
use solvers::{Backend, Precision};
use std::path::Path;

const CLOUD: &str = r#"
format = 1
[medium]
generator = "noise_cloud"
params = { n = 32, seed = 7, sigma_max = 20.0, albedo = 0.9, radius = 0.4, frequency = 4.0, octaves = 4 }
[phase]
type = "hg"
g = 0.3
[[light]]
type = "directional"
direction = [0.4, 0.5, -1.0]
irradiance = 3.0
[camera]
eye = [0.5, -1.0, 0.5]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "orthographic"
width = 1.0
resolution = [16, 16]
"#;

const SHELL: &str = r#"
format = 1
[medium]
generator = "shell_core"
params = { n = 32 }
[phase]
type = "hg"
g = 0.3
[[light]]
type = "directional"
direction = [1.0, 0.3, -0.4]
irradiance = 3.0
[camera]
eye = [0.5, -1.6, 0.5]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "perspective"
fov_y = 36.0
resolution = [16, 16]
"#;

fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let n: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    (n / b.iter().map(|y| y * y).sum::<f64>()).sqrt()
}

/// Relative L2 distance over the pixels of the pipeline's multiple-scattering image (CDA,
/// FLD-LP and LBM, f32, downsample 4) to the path tracer's (256 spp). Measured on
/// `noise_cloud` 32³ / `shell_core` 32³ with the δ-scaled source (paper vs similarity):
/// g = 0.3: CDA 0.845/0.880, 0.951/0.957; FLD-LP 0.355/0.463, 0.540/0.622; LBM 0.213/0.261,
/// 0.392/0.432. g = 0.7: CDA 0.781/0.923, 0.929/0.957; FLD-LP 0.311/0.556, 0.497/0.700; LBM
/// 0.349/0.361, 0.481/0.505. g = 0.9: CDA 0.732/0.967, 0.929/0.980; FLD-LP 1.447/0.754,
/// 0.894/0.856; LBM 1.594/0.666, 1.033/0.762. g = 0.99: CDA 5.39/0.992, 5.50/0.937; FLD-LP
/// 21.5/0.982, 52.5/1.37; LBM 23.3/1.08, 65.4/2.82. The paper's variant is closer at
/// g ≤ 0.7 (all 12 cases), the similarity scaling at g = 0.99 (all 6) and at g = 0.9 for
/// FLD-LP and LBM (CDA stays closer with the paper's). Asserted at g = 0.3 and 0.99.
#[test]
fn similarity_scaling_is_closer_to_the_path_tracer_under_strong_anisotropy() {
    for (name, text) in [("noise_cloud", CLOUD), ("shell_core", SHELL)] {
        let mut file = SceneFile::parse(text, Path::new("."), Path::new("hg.toml")).unwrap();
        for g in [0.3, 0.7, 0.9, 0.99] {
            file.scene.phase = Phase::HenyeyGreenstein { g };
            let pt = render_components(
                &file.scene,
                &file.scene.implied_effects(),
                &RenderSettings {
                    spp: 256,
                    seed: 5,
                    batches: 16,
                    contributions: Contributions::all(),
                },
            )
            .unwrap();
            let pt_ms = &pt.multiple.mean;
            let pt_mean = pt_ms.iter().sum::<f64>() / pt_ms.len() as f64;
            for base in ["cda", "fld:lp", "lbm"] {
                let mut errs = Vec::new();
                for variant in ["paper", "similarity"] {
                    let cfg = PipelineConfig {
                        method: format!("{base}:{variant}").parse().unwrap(),
                        ..PipelineConfig::default()
                    };
                    let r =
                        pipeline::render(&file.scene, &cfg, &Backend::Cpu(Precision::F32)).unwrap();
                    let ms = &r.channels[0].multiple;
                    let mean = ms.iter().sum::<f64>() / ms.len() as f64;
                    let e = rel_l2(ms, pt_ms);
                    eprintln!(
                        "{name} g {g} {base}:{variant}: ms mean {mean:.4e} (pt {pt_mean:.4e}), rel L2 {e:.3}"
                    );
                    errs.push(e);
                }
                // The measured pattern behind the default (see the `fld` module docs): the
                // paper's variant is closer at g = 0.3, the similarity scaling at g = 0.99.
                let (paper, sim) = (errs[0], errs[1]);
                if g == 0.3 {
                    assert!(
                        paper < sim,
                        "{name} g {g} {base}: paper {paper} vs similarity {sim}"
                    );
                }
                if g == 0.99 {
                    assert!(
                        sim < paper,
                        "{name} g {g} {base}: similarity {sim} vs paper {paper}"
                    );
                }
            }
        }
    }
}
