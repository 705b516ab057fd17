use super::*;
use crate::scene::{Interpolation, Light, Phase};

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
    let e = broken("emission = 0.25", "emission = 0.25\nvdb = \"x.vdb\"");
    assert_field(&e, "medium.vdb", Some(9), "not both");
    let e = broken("emission = 0.25", "emission = 0.25\ngrid = \"density\"");
    assert_field(&e, "medium.grid", Some(9), "names a grid of a `vdb` file");
    let e = broken(
        "generator = \"homogeneous\"\nparams = { n = 6, sigma_t = 2.0, albedo = 0.5 }",
        "",
    );
    assert_field(&e, "medium", Some(5), "needs `generator");
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
fn a_missing_or_empty_sampler_table_gives_the_documented_defaults() {
    let without = GOOD.replacen("[sampler]\nspp = 4\nseed = 9\n", "", 1);
    let empty = GOOD.replacen("spp = 4\nseed = 9\n", "", 1);
    let only_seed = GOOD.replacen("spp = 4\n", "", 1);
    assert_ne!(without, GOOD);
    assert_ne!(empty, GOOD);
    for (text, want) in [
        (without, Sampler { spp: 16, seed: 0 }),
        (empty, Sampler { spp: 16, seed: 0 }),
        (only_seed, Sampler { spp: 16, seed: 9 }),
    ] {
        assert_eq!(parse(&text).unwrap().scene.sampler, want);
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
    let dir = std::env::temp_dir().join(format!("scatterbench-scenefile-{}", std::process::id()));
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

/// Issue 13: a missing `[medium]` table is named as such (it used to be blamed on
/// `format`, the first key), and an unclosed `[medium` header is a TOML syntax error at the
/// header's line and column (it used to be blamed on the next table, `light`).
#[test]
fn a_missing_medium_and_a_broken_header_point_at_the_real_problem() {
    let light =
        "[[light]]\ntype = \"directional\"\ndirection = [0.0, 0.0, -1.0]\nirradiance = 1.0\n";
    let e = parse(&format!("format = 1\n\n{light}")).unwrap_err();
    assert_eq!(e.field(), Some("medium"), "{e}");
    assert_eq!(
        e.to_string(),
        "test.toml: `medium`: missing: a scene file needs a [medium] table (with `generator`, `file` or `vdb`)"
    );
    let e = parse(&format!(
        "format = 1\n[medium\ngenerator = \"homogeneous\"\n{light}"
    ))
    .unwrap_err();
    assert_eq!(e.field(), Some(""), "{e}");
    assert_eq!(
        e.to_string(),
        "test.toml:2:8: TOML syntax error: unclosed table, expected `]`"
    );
    // Broken headers of other tables, and a broken value, are syntax errors at their line.
    for (from, to, line) in [
        ("[camera]", "[camera", 36),
        (
            "[[light]]\ntype = \"sphere\"",
            "[[light]\ntype = \"sphere\"",
            21,
        ),
        ("fov_y = 30.0", "fov_y = ", 41),
    ] {
        let e = broken(from, to);
        assert_eq!(e.field(), Some(""), "{e}");
        match &e {
            SceneFileError::Invalid { line: l, .. } => assert_eq!(*l, Some(line), "{e}"),
            other => panic!("{other}"),
        }
        assert!(e.to_string().contains("TOML syntax error"), "{e}");
    }
    // A missing key of a sub-table still names the table.
    let e = broken("eye = [0.5, -3.0, 0.5]\n", "");
    assert_eq!(e.field(), Some("camera"), "{e}");
    assert!(e.to_string().contains("missing field `eye`"), "{e}");
}

/// Issue 13: messages about a light put "an" before a vowel.
#[test]
fn light_messages_use_the_right_article() {
    let e = broken("radiance = 0.5", "radiance = 0.5\npower = 1.0");
    assert_field(
        &e,
        "light[3].power",
        None,
        "not a parameter of an environment light",
    );
    let e = broken(
        "type = \"environment\"\nradiance = 0.5",
        "type = \"environment\"",
    );
    assert_field(
        &e,
        "light[3]",
        None,
        "an environment light needs `radiance`",
    );
    let e = broken("power = 2.0", "power = 2.0\nradius = 1.0");
    assert_field(
        &e,
        "light[2].radius",
        None,
        "not a parameter of a point light",
    );
}

/// Issue 13: values in field messages print compactly (`1e300`, not 301 digits).
#[test]
fn field_values_print_compactly() {
    let e = broken("fov_y = 30.0", "fov_y = 1e300");
    assert_field(&e, "camera.fov_y", Some(41), "1e300 is invalid");
    let e = broken("radius = 0.1", "radius = -1e300");
    assert_field(&e, "light[1].radius", Some(24), "-1e300 is invalid");
    assert!(!e.to_string().contains("0000000000"), "{e}");
}

/// Issue 12: `[medium] interpolation` and `[camera] hide_background` parse (defaults:
/// nearest, visible), survive a write/load round trip, and an unknown interpolation is an
/// error naming the field.
#[test]
fn interpolation_and_hide_background_parse_round_trip_and_are_checked() {
    let f = parse(GOOD).unwrap();
    assert_eq!(f.scene.interpolation, Interpolation::Nearest);
    assert!(!f.scene.camera.unwrap().hide_background);
    let text = GOOD
        .replacen(
            "emission = 0.25",
            "emission = 0.25\ninterpolation = \"trilinear\"",
            1,
        )
        .replacen(
            "resolution = [16, 8]",
            "resolution = [16, 8]\nhide_background = true",
            1,
        );
    let a = parse(&text).unwrap();
    assert_eq!(a.scene.interpolation, Interpolation::Trilinear);
    assert!(a.scene.camera.unwrap().hide_background);
    let dir = std::env::temp_dir().join(format!("scatterbench-interp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    a.write(&dir.join("a.toml")).unwrap();
    let b = SceneFile::load(&dir.join("a.toml")).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(b.scene.interpolation, Interpolation::Trilinear);
    assert_eq!(b.scene.camera, a.scene.camera);
    let e = broken(
        "emission = 0.25",
        "emission = 0.25\ninterpolation = \"cubic\"",
    );
    assert_field(&e, "medium.interpolation", None, "unknown interpolation");
}
