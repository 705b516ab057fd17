//! The rendering pipeline (issue "Rendering pipeline with effect-driven planning",
//! acceptance 1): planning, the zero-cost cases, the raymarch against closed forms, colour.
//! The emission-only comparison against the path tracer lives in
//! `reference/tests/pipeline_emission.rs`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use solvers::pipeline::{self, PipelineConfig, Shadows};
use solvers::scene::{
    Camera, EffectSelection, Light, Phase, Projection, Sampler, Scene, SceneFile,
};
use solvers::{Backend, Grid, Medium, Precision};
use std::f64::consts::PI;
use std::path::Path;

const CPU: Backend<'static> = Backend::Cpu(Precision::F64);

fn front_camera(res: usize, width: f64) -> Camera {
    Camera {
        hide_background: false,
        eye: [0.5, -2.0, 0.5],
        target: [0.5, 0.5, 0.5],
        up: [0.0, 0.0, 1.0],
        projection: Projection::Orthographic { width },
        resolution: [res, res],
    }
}

/// A 16³ cloud-like medium with emission, albedo `albedo`, one directional light.
fn cloud(albedo: f64, with_light: bool, with_emission: bool) -> Scene {
    let mut medium = solvers::scenes::vacuum_cloud::<f64>(16, 3).unwrap();
    for (a, s) in medium.albedo.iter_mut().zip(&medium.sigma_t) {
        *a = if *s > 0.0 { albedo } else { 0.0 };
    }
    if !with_emission {
        medium.emission.iter_mut().for_each(|j| *j = 0.0);
    }
    Scene {
        interpolation: Default::default(),
        medium,
        phase: Phase::HenyeyGreenstein { g: 0.4 },
        lights: if with_light {
            vec![Light::directional([0.3, 0.4, -1.0], 2.0).unwrap()]
        } else {
            vec![]
        },
        camera: Some(front_camera(12, 1.0)),
        sampler: Sampler { spp: 1, seed: 0 },
    }
}

/// FLD-LP with the solver's own defaults (ω = 1), R̄/j̄ < 10⁻⁵, at downsample 2.
fn quick_config() -> PipelineConfig {
    PipelineConfig {
        downsample: 2,
        method: solvers::MethodRef::new(Box::new(solvers::fld::FldMethod {
            config: solvers::fld::FldConfig::default(),
            solver: solvers::fld::Solver::Sor,
            anisotropy: solvers::method::AnisotropyScaling::Paper,
        })),
        tolerance: solvers::Tolerance {
            rel: 1e-5,
            max_steps: 100_000,
        },
        ..PipelineConfig::default()
    }
}

#[test]
fn albedo_zero_runs_no_diffusion_and_equals_the_raymarch_alone() {
    // Albedo 0: nothing scatters, so neither the light nor the diffusion solve is touched.
    let dark = cloud(0.0, true, true);
    let r = pipeline::render(&dark, &quick_config(), &CPU).unwrap();
    assert_eq!(r.plan.pass_names(), vec!["raymarch_emission"]);
    assert!(r.diffusion.is_empty());
    assert_eq!(
        r.passes_run
            .iter()
            .map(|p| p.name.as_str())
            .collect::<Vec<_>>(),
        vec!["raymarch_emission"]
    );
    let img = &r.channels[0];
    assert!(img.emission.iter().any(|&v| v > 0.0));
    assert_eq!(img.total, img.emission);
    assert!(img.single.iter().chain(&img.multiple).all(|&v| v == 0.0));
    // The same σt and j with albedo 0.6, restricted to emission: the identical image, bit for
    // bit (the emission raymarch depends on σt and j only).
    let lit = cloud(0.6, true, true);
    let cfg = PipelineConfig {
        effects: EffectSelection::only(&["emission"]).unwrap(),
        ..quick_config()
    };
    let e = pipeline::render(&lit, &cfg, &CPU).unwrap();
    assert_eq!(e.channels[0].total, img.total);

    // Scattering without multiple scattering: no diffusion solve; the image is the
    // single-scattering raymarch exactly, and that equals the single component of the full
    // render (components are integrated independently).
    let ss_scene = cloud(0.6, true, false);
    let cfg = PipelineConfig {
        effects: EffectSelection::exclude(&["multiple_scattering"]).unwrap(),
        ..quick_config()
    };
    let ss = pipeline::render(&ss_scene, &cfg, &CPU).unwrap();
    assert_eq!(
        ss.plan.pass_names(),
        vec!["bake_directional[0]", "raymarch_single"]
    );
    assert!(ss.diffusion.is_empty());
    assert_eq!(ss.channels[0].total, ss.channels[0].single);
    let full = pipeline::render(&ss_scene, &quick_config(), &CPU).unwrap();
    assert_eq!(
        full.plan.pass_names(),
        vec![
            "bake_directional[0]",
            "diffusion_solve",
            "raymarch_single",
            "raymarch_multiple"
        ]
    );
    assert_eq!(full.channels[0].single, ss.channels[0].single);
    assert!(full.channels[0].multiple.iter().any(|&v| v > 0.0));
    assert_eq!(full.diffusion.len(), 1);
    assert_eq!(full.diffusion[0].stop, solvers::Stop::Converged);
    // Restricted grid: 16/2 = 8 plus one vacuum layer on each side.
    assert_eq!(full.diffusion[0].grid, [10; 3]);
}

#[test]
fn no_lights_and_no_emission_is_black_without_any_pass() {
    let s = cloud(0.9, false, false);
    let r = pipeline::render(&s, &quick_config(), &CPU).unwrap();
    assert!(r.plan.passes.is_empty(), "{}", r.plan.explain());
    assert!(r.passes_run.is_empty());
    assert!(r.plan.explain().contains("black"));
    let img = &r.channels[0];
    assert_eq!(img.total.len(), 144);
    assert!(img.total.iter().all(|&v| v == 0.0));
}

/// Worst relative error over the pixels of the single-scattering image against the closed
/// form (see the test below), on an n³ grid with raymarch sub-step `step`.
fn single_scattering_error(n: usize, step: f64, phase: Phase, shadows: Shadows) -> f64 {
    let (sigma, albedo, e) = (3.0, 0.7, 2.0);
    let grid = Grid::cube(n, 1.0).unwrap();
    let medium = Medium::homogeneous(grid, sigma, albedo).unwrap();
    let v: [f64; 3] = [0.0, 0.3, -1.0];
    let vlen = (0.09f64 + 1.0).sqrt();
    let scene = Scene {
        interpolation: Default::default(),
        medium,
        phase,
        lights: vec![Light::directional(v, e).unwrap()],
        camera: Some(front_camera(16, 0.9)),
        sampler: Sampler { spp: 1, seed: 0 },
    };
    let cfg = PipelineConfig {
        effects: EffectSelection::only(&["single_scattering"]).unwrap(),
        step,
        shadows,
        ..PipelineConfig::default()
    };
    let r = pipeline::render(&scene, &cfg, &CPU).unwrap();
    assert_eq!(
        r.plan.pass_names(),
        vec!["bake_directional[0]", "raymarch_single"]
    );
    let cos = -0.3 / vlen;
    let p = match phase {
        Phase::Isotropic => 1.0 / (4.0 * PI),
        Phase::HenyeyGreenstein { g } => {
            (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * cos).powf(1.5))
        }
    };
    let mut worst: f64 = 0.0;
    for py in 0..16 {
        // Orthographic: pixel row py at z = 0.5 + 0.9·(0.5 − (py + 0.5)/16).
        let z = 0.5 + 0.9 * (0.5 - (py as f64 + 0.5) / 16.0);
        let a = 1.0 - z;
        let yk = 0.3 * a;
        let c = vlen / 0.3;
        let i1 = (1.0 - (-sigma * (1.0 + c) * yk).exp()) / (sigma * (1.0 + c));
        let i2 = ((-sigma * yk).exp() - (-sigma).exp()) / sigma * (-sigma * vlen * a).exp();
        let exact = albedo * sigma * p * e * (i1 + i2);
        for px in 0..16 {
            let got = r.channels[0].total[py * 16 + px];
            worst = worst.max((got / exact - 1.0).abs());
        }
    }
    worst
}

/// Single scattering in a homogeneous box lit by an oblique directional light, seen along
/// +y by an orthographic camera, against the closed form. With the light propagating along
/// v ∝ (0, 0.3, −1), the path to the light from (x, y, z) leaves through the top face when
/// y ≥ 0.3·(1 − z) and through the front face y = 0 otherwise, so along a camera ray
/// τ_l(y) = σ|v|·min(1 − z, y/0.3) (|v| the length of (0, 0.3, 1)) and
/// L = α σ p(cos θ) E [∫₀^{y_k} e^{−σy} e^{−σ|v|y/0.3} dy + e^{−σ|v|(1−z)} ∫_{y_k}^1 e^{−σy} dy],
/// y_k = 0.3(1 − z), cos θ = −0.3/|v|.
///
/// Exact shadow rays: each sub-step is integrated exactly for a depth linear along it, and a
/// sub-step holding the kink is bisected until the depth is linear within
/// `raymarch::TAU_LINEARITY` (10⁻²), so the error is set by that threshold, not by the grid
/// or the step (measured worst relative error over the pixels, isotropic and HG g = 0.6
/// alike: 2.2e-4 at 16³ and 32³, 1.2e-4 at 64³ with step 0.5, 3.7e-5 at 32³ with step 0.1;
/// 1.4e-8 everywhere at a threshold of 10⁻⁴; with the midpoint rule before, 6.4e-3, 1.6e-3,
/// 4.1e-4 and 6.7e-5). Deep shadow map: τ interpolated between centres, second order at the
/// kink (9.5e-3, 2.9e-3 at 16³, 32³). Asserted with margin, and the order of convergence of
/// the deep shadow map.
#[test]
fn single_scattering_matches_the_closed_form_in_a_homogeneous_box() {
    for phase in [Phase::Isotropic, Phase::HenyeyGreenstein { g: 0.6 }] {
        let err = |n, step| single_scattering_error(n, step, phase, Shadows::Exact);
        let (e16, e32, e64, e32_fine) = (err(16, 0.5), err(32, 0.5), err(64, 0.5), err(32, 0.1));
        eprintln!("{phase:?} exact: {e16:.2e} {e32:.2e} {e64:.2e}; step 0.1: {e32_fine:.2e}");
        for (what, e) in [
            ("16³", e16),
            ("32³", e32),
            ("64³", e64),
            ("32³ step 0.1", e32_fine),
        ] {
            assert!(e < 5e-4, "{phase:?} {what}: relative error {e}");
        }
        let dsm = |n| single_scattering_error(n, 0.5, phase, Shadows::DeepShadowMap);
        let (d16, d32) = (dsm(16), dsm(32));
        eprintln!("{phase:?} deep shadow map: {d16:.2e} {d32:.2e}");
        assert!(d32 < 4e-3 && d16 / d32 > 3.0, "{phase:?}: {d16} {d32}");
    }
}

/// Emission seen through an absorbing homogeneous box: L = j/(4π σ)(1 − e^{−σ·1}) for
/// every ray crossing the box along +y, exact whatever the step (piecewise-constant fields
/// are integrated exactly).
#[test]
fn emission_raymarch_is_exact_for_piecewise_constant_fields() {
    let grid = Grid::cube(8, 1.0).unwrap();
    let mut medium = Medium::homogeneous(grid, 2.5, 0.0).unwrap();
    medium.emission = vec![3.0; grid.len()];
    let scene = Scene {
        interpolation: Default::default(),
        medium,
        phase: Phase::Isotropic,
        lights: vec![],
        camera: Some(front_camera(8, 0.9)),
        sampler: Sampler { spp: 1, seed: 0 },
    };
    for step in [0.05, 0.5, 4.0] {
        let cfg = PipelineConfig {
            step,
            ..PipelineConfig::default()
        };
        let r = pipeline::render(&scene, &cfg, &CPU).unwrap();
        let exact = 3.0 / (4.0 * PI * 2.5) * (1.0 - (-2.5f64).exp());
        for v in &r.channels[0].total {
            assert!((v / exact - 1.0).abs() < 1e-12, "{v} vs {exact}");
        }
    }
}

/// Colour: RGB channels are independent monochrome problems; with `emission_rgb`
/// = [1, 2, 0] the emission image of G is twice R's and B is black.
#[test]
fn colour_channels_scale_independently() {
    let text = r#"
format = 1
[medium]
generator = "vacuum_cloud"
params = { n = 12, seed = 2 }
emission_rgb = [1.0, 2.0, 0.0]
sigma_t_rgb = [1.0, 1.0, 0.5]
[camera]
eye = [0.5, -2.0, 0.5]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "orthographic"
width = 1.0
resolution = [8, 8]
[effects]
only = ["emission"]
"#;
    let f = SceneFile::parse(text, Path::new("."), Path::new("rgb.toml")).unwrap();
    assert_eq!(f.channels().len(), 3);
    let r = pipeline::render_file(&f, &PipelineConfig::default(), &CPU).unwrap();
    assert_eq!(r.channels.len(), 3);
    assert_eq!(r.plan.pass_names(), vec!["raymarch_emission"]);
    assert_eq!(r.passes_run.len(), 3, "one emission pass per channel");
    let (red, green, blue) = (
        &r.channels[0].total,
        &r.channels[1].total,
        &r.channels[2].total,
    );
    assert!(red.iter().any(|&v| v > 0.0));
    for p in 0..64 {
        assert!((green[p] - 2.0 * red[p]).abs() <= 1e-14 * red[p].abs());
        assert_eq!(blue[p], 0.0);
    }
    // A bad effect name in the file is an error naming the field.
    let bad = text.replace("only = [\"emission\"]", "only = [\"bounce\"]");
    let e = SceneFile::parse(&bad, Path::new("."), Path::new("rgb.toml")).unwrap_err();
    assert_eq!(e.field(), Some("effects.only[0]"), "{e}");
    let bad = text.replace("only = [\"emission\"]", "exclude = [\"attenuation\"]");
    let e = SceneFile::parse(&bad, Path::new("."), Path::new("rgb.toml")).unwrap_err();
    assert_eq!(e.field(), Some("effects.exclude[0]"), "{e}");
    let bad = text.replace("only = [\"emission\"]", "only = [\"single_scattering[0]\"]");
    let e = SceneFile::parse(&bad, Path::new("."), Path::new("rgb.toml")).unwrap_err();
    assert!(e.to_string().contains("no light 0"), "{e}");
    let bad = text.replace(
        "sigma_t_rgb = [1.0, 1.0, 0.5]",
        "albedo_rgb = [1.0, 1.0, 2.0]",
    );
    let e = SceneFile::parse(&bad, Path::new("."), Path::new("rgb.toml")).unwrap_err();
    assert_eq!(e.field(), Some("medium.albedo_rgb"), "{e}");
}

#[test]
fn unsupported_lights_and_bad_settings_are_typed_errors() {
    let mut s = cloud(0.5, true, false);
    s.lights.push(Light::Environment { radiance: 1.0 });
    let e = pipeline::render(&s, &quick_config(), &CPU).unwrap_err();
    assert!(
        matches!(
            e,
            pipeline::PipelineError::UnsupportedLight {
                index: 1,
                kind: "environment"
            }
        ),
        "{e}"
    );
    // Excluding everything the environment light feeds makes the scene renderable; the
    // environment itself stays visible (background, order 0: L_env·T) unless hidden.
    let cfg = PipelineConfig {
        effects: EffectSelection::exclude(&["single_scattering[1]", "multiple_scattering"])
            .unwrap(),
        ..quick_config()
    };
    let r = pipeline::render(&s, &cfg, &CPU).unwrap();
    assert_eq!(
        r.plan.pass_names(),
        vec![
            "bake_directional[0]",
            "raymarch_single",
            "raymarch_background"
        ]
    );
    if let Some(c) = s.camera.as_mut() {
        c.hide_background = true;
    }
    let r = pipeline::render(&s, &cfg, &CPU).unwrap();
    assert_eq!(
        r.plan.pass_names(),
        vec!["bake_directional[0]", "raymarch_single"]
    );
    let mut no_cam = cloud(0.5, true, false);
    no_cam.camera = None;
    assert_eq!(
        pipeline::render(&no_cam, &quick_config(), &CPU).unwrap_err(),
        pipeline::PipelineError::NoCamera
    );
    let cfg = PipelineConfig {
        step: 0.0,
        ..quick_config()
    };
    assert!(pipeline::render(&s, &cfg, &CPU).is_err());
    assert!("fld:bogus".parse::<solvers::MethodRef>().is_err());
    assert_eq!(
        "fld:larsen2"
            .parse::<solvers::MethodRef>()
            .unwrap()
            .to_string(),
        "fld:larsen2"
    );
}

/// The planner's output for each dataset's scene file (acceptance 1).
#[test]
fn planner_output_for_each_dataset() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let cases: [(&str, usize, &[&str], &str); 4] = [
        (
            "nebula.toml",
            3,
            &[
                "bake_directional[0]",
                "diffusion_solve",
                "raymarch_single",
                "raymarch_multiple",
            ],
            "attenuation, single_scattering[0], multiple_scattering",
        ),
        (
            "emissive_cloud.toml",
            1,
            &["diffusion_solve", "raymarch_multiple", "raymarch_emission"],
            "attenuation, multiple_scattering, emission",
        ),
        (
            "shell_core.toml",
            1,
            &[
                "bake_directional[0]",
                "diffusion_solve",
                "raymarch_single",
                "raymarch_multiple",
            ],
            "attenuation, single_scattering[0], multiple_scattering, anisotropy",
        ),
        (
            "plume.toml",
            3,
            &[
                "bake_directional[0]",
                "bake_point[1]",
                "diffusion_solve",
                "raymarch_single",
                "raymarch_multiple",
                "raymarch_emission",
            ],
            "attenuation, single_scattering[0], single_scattering[1], multiple_scattering, emission",
        ),
    ];
    for (file, channels, passes, effects) in cases {
        let f = SceneFile::load(&dir.join(file)).unwrap();
        let ch = f.channels();
        assert_eq!(ch.len(), channels, "{file}");
        let plan = pipeline::plan_channels(&ch, &f.effects, &PipelineConfig::default()).unwrap();
        assert_eq!(plan.pass_names(), passes, "{file}:\n{}", plan.explain());
        assert_eq!(plan.effects.names(), effects, "{file}");
        // Restrictions change the plan exactly as the effect set says.
        let only_emission = PipelineConfig {
            effects: EffectSelection::only(&["emission"]).unwrap(),
            ..PipelineConfig::default()
        };
        let p = pipeline::plan_channels(&ch, &f.effects, &only_emission).unwrap();
        let expect: &[&str] = if effects.contains("emission") {
            &["raymarch_emission"]
        } else {
            &[]
        };
        assert_eq!(p.pass_names(), expect, "{file}: emission only");
        let no_ms = PipelineConfig {
            effects: EffectSelection::exclude(&["multiple_scattering"]).unwrap(),
            ..PipelineConfig::default()
        };
        let p = pipeline::plan_channels(&ch, &f.effects, &no_ms).unwrap();
        assert!(!p.runs("diffusion_solve"), "{file}");
        assert!(
            p.explain().contains("multiple scattering is excluded"),
            "{file}"
        );
    }
    // The plume's channels glow red more than blue (blackbody at < 1800 K).
    let plume = SceneFile::load(&dir.join("plume.toml")).unwrap().channels();
    let glow = |s: &Scene| s.medium.emission.iter().sum::<f64>();
    assert!(glow(&plume[0]) > glow(&plume[1]) && glow(&plume[1]) > glow(&plume[2]));
}

/// OpenVDB input through scene files: the error paths (no `.vdb` file can be produced
/// offline here, so reading real data is not exercised by the tests).
#[test]
fn vdb_scene_files_report_typed_errors_naming_the_field() {
    let base = "format = 1\n[medium]\nalbedo = 0.5\n";
    let parse = |extra: &str| {
        SceneFile::parse(
            &format!("{base}{extra}"),
            Path::new("/nonexistent-dir"),
            Path::new("v.toml"),
        )
        .unwrap_err()
    };
    let e = parse("vdb = \"cloud.vdb\"\n");
    assert_eq!(e.field(), Some("medium.vdb"), "{e}");
    assert!(e.to_string().contains("cloud.vdb"), "{e}");
    let e = parse("vdb = \"cloud.vdb\"\ngenerator = \"homogeneous\"\n");
    assert_eq!(e.field(), Some("medium.vdb"), "{e}");
    assert!(e.to_string().contains("not both"), "{e}");
    let e = parse("generator = \"homogeneous\"\ngrid = \"density\"\n");
    assert_eq!(e.field(), Some("medium.grid"), "{e}");
}

/// Every registered method as the multiple-scattering pass: only that pass changes (single
/// scattering and emission are bitwise those of the FLD render), the solve converges, its
/// image is finite and non-negative, and it estimates the same order of magnitude as FLD
/// (mean multiple-scattering radiance within a factor of 10 of FLD-LP's: these methods differ
/// by up to ~5x on this small cloud surrounded by vacuum; measured CDA 0.217, LBM 1.31).
#[test]
fn every_registered_method_replaces_only_the_multiple_scattering_pass() {
    let with_emission = cloud(0.9, true, true);
    let fld_with = pipeline::render(&with_emission, &quick_config(), &CPU).unwrap();
    // A method without a volume source (none at present; POP takes emission since its
    // emission ordinates) would be compared on the scene without emission.
    let lights_only = cloud(0.9, true, false);
    let fld_without = pipeline::render(&lights_only, &quick_config(), &CPU).unwrap();
    for family in solvers::method::METHODS {
        let method = (family.build)(None, &solvers::method::Params::none()).unwrap();
        let name = method.name();
        let (scene, fld) = if method.capabilities().volume_source {
            (&with_emission, &fld_with)
        } else {
            (&lights_only, &fld_without)
        };
        let cfg = PipelineConfig {
            method: solvers::MethodRef::new(method),
            ..quick_config()
        };
        let other = pipeline::render(scene, &cfg, &CPU).unwrap();
        assert!(other.plan.runs("diffusion_solve"), "{name}");
        assert_eq!(other.diffusion.len(), 1, "{name}");
        assert_eq!(other.diffusion[0].method, name);
        assert_eq!(
            other.diffusion[0].stop,
            solvers::Stop::Converged,
            "{name}: {:?}",
            other.diffusion[0]
        );
        let (a, b) = (&fld.channels[0], &other.channels[0]);
        assert_eq!(a.single, b.single, "{name}");
        assert_eq!(a.emission, b.emission, "{name}");
        assert!(
            b.multiple.iter().all(|v| v.is_finite() && *v >= 0.0),
            "{name}"
        );
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let ratio = mean(&b.multiple) / mean(&a.multiple);
        eprintln!("{name} / FLD-LP multiple scattering = {ratio}");
        assert!(
            (0.1..10.0).contains(&ratio),
            "{name} / FLD multiple scattering = {ratio}"
        );
    }
}

/// Issue 12, item 2: the plan names the anisotropy variant that runs, and warns when the
/// paper's isotropic σs runs under |g| > 0.5 (not at g = 0.4, not for `:similarity`).
#[test]
fn the_plan_names_the_anisotropy_variant_and_warns_on_strong_anisotropy() {
    let with = |spec: &str, g: f64| {
        let mut s = cloud(0.9, true, false);
        s.phase = Phase::HenyeyGreenstein { g };
        let cfg = PipelineConfig {
            method: spec.parse().unwrap(),
            ..PipelineConfig::default()
        };
        pipeline::plan_channels(&[s], &EffectSelection::default(), &cfg).unwrap()
    };
    let p = with("cda", 0.9);
    assert_eq!(p.warnings.len(), 1, "{}", p.explain());
    assert!(p.explain().contains("warning") && p.explain().contains("`paper`"));
    assert!(with("cda", 0.4).warnings.is_empty());
    let s = with("fld:lp:similarity", 0.9);
    assert!(s.warnings.is_empty(), "{}", s.explain());
    assert!(
        s.explain().contains("fld:lp:similarity") && s.explain().contains("similarity scaling")
    );
    // LBM: its paper variant scatters with the lattice HG kernel, warned about the same way.
    let l = with("lbm", 0.9);
    assert_eq!(l.warnings.len(), 1, "{}", l.explain());
    assert!(l.explain().contains("lattice") && l.explain().contains("`paper`"));
    assert!(with("lbm", 0.4).warnings.is_empty());
    let ls = with("lbm:similarity", 0.9);
    assert!(ls.warnings.is_empty(), "{}", ls.explain());
    assert!(ls.explain().contains("lbm:similarity") && ls.explain().contains("similarity scaling"));
}

/// Issue 12, item 2: at g = 0 the similarity variant of CDA, FLD-LP and LBM renders exactly
/// the paper variant's images (no rescaled medium, no re-baked source); at g = 0.9 its
/// multiple-scattering image differs (the δ-scaled source and medium are used).
#[test]
fn the_similarity_variant_is_the_paper_variant_at_g_zero() {
    for base in ["cda", "fld:lp", "lbm"] {
        let render = |variant: &str, g: f64| {
            let mut s = cloud(0.9, true, true);
            s.phase = Phase::HenyeyGreenstein { g };
            let cfg = PipelineConfig {
                method: format!("{base}:{variant}").parse().unwrap(),
                downsample: 2,
                ..PipelineConfig::default()
            };
            pipeline::render(&s, &cfg, &Backend::Cpu(Precision::F64))
                .unwrap()
                .channels
                .remove(0)
        };
        let (p, s) = (render("paper", 0.0), render("similarity", 0.0));
        assert_eq!(p.multiple, s.multiple, "{base}");
        assert_eq!(p.total, s.total, "{base}");
        let (p, s) = (render("paper", 0.9), render("similarity", 0.9));
        let d: f64 = p
            .multiple
            .iter()
            .zip(&s.multiple)
            .map(|(a, b)| (a - b).abs())
            .sum();
        let n: f64 = p.multiple.iter().map(|a| a.abs()).sum();
        assert!(
            d > 0.01 * n,
            "{base}: g = 0.9 variants differ by {d} of {n}"
        );
        assert_eq!(
            p.single, s.single,
            "{base}: single scattering is the same pass"
        );
    }
}

/// A homogeneous 16³ unit cube (σt = 4, albedo `albedo`, phase `phase`) lit along −z, seen
/// from the front.
fn lit_cube(albedo: f64, phase: Phase, lights: Vec<Light>) -> Scene {
    let grid = Grid::cube(16, 1.0).unwrap();
    Scene {
        interpolation: Default::default(),
        medium: Medium::homogeneous(grid, 4.0, albedo).unwrap(),
        phase,
        lights,
        camera: Some(front_camera(12, 1.2)),
        sampler: Sampler { spp: 1, seed: 0 },
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Issue 17 item 6 / issue 16 item 6: a method that takes the lights itself (`lpm`) renders
/// single + multiple with no effect counted twice. Its multiple-scattering image agrees with
/// the same solver on the baked source (`lpm:baked`, q = σs·L_ri at the voxel centres) —
/// both exact enough on an axis-aligned light, whose direction is an LPM cell centre — while
/// counting the single scattering twice would add the single image, ≥ 0.4 of the multiple
/// image's mean here, and fail the bound.
#[test]
fn direct_lpm_counts_every_effect_once() {
    let scene = lit_cube(
        0.9,
        Phase::Isotropic,
        vec![Light::directional([0.0, 0.0, -1.0], 2.0).unwrap()],
    );
    let cfg = |spec: &str| PipelineConfig {
        downsample: 1,
        method: spec.parse().unwrap(),
        tolerance: solvers::Tolerance::rel(1e-5),
        ..PipelineConfig::default()
    };
    let direct = pipeline::render(&scene, &cfg("lpm"), &CPU).unwrap();
    let baked = pipeline::render(&scene, &cfg("lpm:baked"), &CPU).unwrap();
    let (d, b) = (&direct.channels[0], &baked.channels[0]);
    assert_eq!(
        d.single, b.single,
        "the single-scattering raymarch is shared"
    );
    let (md, mb, s) = (mean(&d.multiple), mean(&b.multiple), mean(&d.single));
    let rel = (md - mb).abs() / mb;
    eprintln!("multiple: direct {md:.6e}, baked {mb:.6e} (rel {rel:.3e}); single {s:.6e}");
    assert!(
        s > 0.4 * mb,
        "the test needs a visible single image: {s} vs {mb}"
    );
    assert!(rel < 0.05, "direct vs baked multiple scattering: {rel:.3e}");
    let total = |c: &pipeline::ChannelImages| mean(&c.total);
    assert!((total(d) - total(b)).abs() < 0.05 * total(b));
    // The plan says who computed what: the light is baked for the raymarch only.
    let bake = &direct.plan.passes[0];
    assert_eq!(bake.pass.name(), "bake_directional[0]");
    assert!(
        bake.why
            .contains("single scattering of light 0 is rendered"),
        "{}",
        bake.why
    );
    assert!(!bake.why.contains("q_ri"), "{}", bake.why);
}

/// The plan's image passes compute disjoint effect sets whose union is every rendered effect
/// but attenuation and anisotropy, for a baked method and for the two that take the lights
/// themselves, on a scene with a directional and an environment light (the environment's
/// single scattering is the Direct method's φ); with a point light added, LPM refuses it and
/// POP leaves its single scattering to the raymarch.
#[test]
fn every_effect_is_computed_by_exactly_one_image_pass() {
    let scene = lit_cube(
        0.9,
        Phase::HenyeyGreenstein { g: 0.6 },
        vec![
            Light::directional([0.0, 0.3, -1.0], 2.0).unwrap(),
            Light::Environment { radiance: 0.5 },
        ],
    );
    for spec in ["fld:lp", "lpm", "pop"] {
        let cfg = PipelineConfig {
            method: spec.parse().unwrap(),
            ..PipelineConfig::default()
        };
        let planned =
            pipeline::plan_channels(std::slice::from_ref(&scene), &EffectSelection::all(), &cfg);
        if spec == "fld:lp" {
            // Baked methods cannot take an environment light's single scattering.
            assert!(matches!(
                planned,
                Err(pipeline::PipelineError::UnsupportedLight { index: 1, .. })
            ));
            continue;
        }
        let plan = planned.unwrap();
        let mut seen: Vec<String> = Vec::new();
        for p in plan
            .passes
            .iter()
            .filter(|p| p.pass.name().starts_with("raymarch"))
        {
            for e in &p.computes {
                assert!(
                    !seen.contains(e),
                    "{spec}: {e} computed twice: {:#?}",
                    plan.passes
                );
                seen.push(e.clone());
            }
        }
        seen.sort();
        let mut want: Vec<String> = plan
            .effects
            .names()
            .split(", ")
            .filter(|n| !["attenuation", "anisotropy"].contains(n))
            .map(String::from)
            .collect();
        want.sort();
        assert_eq!(seen, want, "{spec}: {}", plan.explain());
        assert!(
            plan.explain()
                .contains("computes: multiple_scattering, single_scattering[1]")
        );
        assert!(
            plan.warnings
                .iter()
                .any(|w| w.contains("environment light(s) [1]"))
        );
        // Excluding the environment's single scattering alone cannot be honoured.
        let cfg = PipelineConfig {
            effects: EffectSelection::exclude(&["single_scattering[1]"]).unwrap(),
            ..cfg
        };
        assert!(matches!(
            pipeline::plan_channels(std::slice::from_ref(&scene), &EffectSelection::all(), &cfg),
            Err(pipeline::PipelineError::MethodCannot { .. })
        ));
        // A point light: LPM refuses it by name; POP takes it (its radial grids) and its
        // single scattering stays the raymarch's, like a directional light's.
        let mut point = scene.clone();
        point.lights.push(Light::Point {
            position: [0.5, 0.5, 2.0],
            power: 1.0,
        });
        let planned = pipeline::plan_channels(
            std::slice::from_ref(&point),
            &EffectSelection::all(),
            &PipelineConfig {
                method: spec.parse().unwrap(),
                ..PipelineConfig::default()
            },
        );
        if spec == "lpm" {
            let e = planned.unwrap_err();
            assert!(e.to_string().contains("light 2 is a point light"), "{e}");
        } else {
            let plan = planned.unwrap();
            let explained = plan.explain();
            assert!(
                explained.contains("computes: single_scattering[0], single_scattering[2]"),
                "{explained}"
            );
            assert!(
                explained.contains("computes: multiple_scattering, single_scattering[1]"),
                "{explained}"
            );
        }
    }
}
