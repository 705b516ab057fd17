//! A bridge to Mitsuba 3: exports a [`Scene`] as a Mitsuba scene (`.vol` grids plus a scene
//! dictionary), renders it in K independent seeds with the Python package in
//! `.venv-mitsuba/` (made by `scripts/setup-mitsuba.sh`), and returns the per-pixel mean and
//! standard error with Mitsuba's version, variant and timings.
//!
//! The mapping, checked against Mitsuba 3's source (`src/volumes/grid.cpp`,
//! `include/mitsuba/render/volumegrid.h`, Dr.Jit's `texture.h`, `src/media/heterogeneous.cpp`,
//! `include/mitsuba/core/transform.h`, `include/mitsuba/render/sensor.h`,
//! `src/sensors/{orthographic,perspective}.cpp`, `src/phase/hg.cpp`):
//!
//! * **Medium**: a `cube` shape with a `null` BSDF spanning the grid's box, whose `interior`
//!   is a `heterogeneous` medium with `scale = 1`. σt (and albedo, unless constant) are
//!   `gridvolume`s read from `.vol` files with `use_grid_bbox = true` and
//!   `filter_type` the scene's interpolation (`"nearest"` by default, or `"trilinear"`:
//!   Dr.Jit's `eval_nonaccel` interpolates between texel centres (i + ½)/n and clamps at
//!   the outer half texel, as our `Interpolation::Trilinear`). With `use_grid_bbox` the volume's world-to-local transform
//!   maps the file's box onto the unit cube (`VolumeGrid::bbox_transform`), and the nearest
//!   filter reads texel ⌊u·n⌋ on each axis (Dr.Jit `Texture::eval_nonaccel`), so texel i
//!   covers [i, i+1)/n of the box: exactly our piecewise-constant voxel i. The texel order of
//!   the `.vol` file (x fastest) is ours. The medium's majorant is max σt (delta tracking).
//! * **Phase**: `isotropic`, or `hg` with the same `g`: Mitsuba evaluates
//!   HG(−wo·wi) with `wi` pointing back along the incoming ray, so g > 0 is forward
//!   scattering as in ours.
//! * **Lights**: `directional` (`direction`, `irradiance` on a plane perpendicular to the
//!   beam, as ours); `point` with `intensity = power/4π`; `constant` environment with
//!   `radiance`; a sphere light is a `sphere` shape with a black `diffuse` BSDF and an
//!   `area` emitter of the same `radiance` (emitting outward, one-sided).
//! * **Camera**: `to_world = look_at(eye, target, up)`, whose columns are
//!   (left = up × dir, dir × left, dir, eye). Mitsuba's projections map camera-space +x
//!   (left) to the image's left edge and +y to its top edge (`scale(−½, −½·aspect)` after
//!   the projection), so pixel (0, 0) is the top-left one looking along `dir` with `up` up,
//!   as in our camera. Orthographic: the film spans camera x ∈ [−1, 1], so `to_world` also
//!   scales x and y by `width/2`. Perspective: `fov` with `fov_axis = "y"`. `near_clip` is
//!   10⁻⁴ (the orthographic rays start that far in front of the image plane).
//! * **Film**: `hdrfilm`, RGB float32, `box` reconstruction filter (radius ½: each sample
//!   lands in exactly the pixel that contains it, so a pixel value is the unweighted mean
//!   over the pixel's area); `independent` sampler; `volpath` integrator with
//!   `max_depth = −1` (unlimited) unless a depth is given (our "at most k scatterings" is
//!   Mitsuba's `max_depth = k + 1`), `rr_depth` = [`RR_DEPTH`] (no Russian roulette: see
//!   below), and
//!   `hide_emitters = camera.hide_background` (volpath hides emitters hit at depth 0, i.e.
//!   seen through the null-BSDF cube and unscattered medium: exactly our order 0 from
//!   the lights).
//!   Grey inputs make the three channels equal; channel 0 is used and the largest channel
//!   difference is recorded.
//!
//! **Russian roulette at null collisions** (issue 14's dense-voxel cube). Mitsuba 3.9.1's
//! `volpath` plays Russian roulette at the top of *every* loop iteration once `depth >
//! rr_depth` (default 5), null collisions of delta tracking included, with survival
//! q = min(max throughput, 0.95) and throughput /= q (`src/integrators/volpath.cpp`). A null
//! collision leaves the throughput unchanged, so past depth 5 each one kills 5 % of the paths
//! and multiplies the survivors by 1/0.95: unbiased, but after m null collisions the weight
//! is 0.95⁻ᵐ with probability 0.95ᵐ. With one voxel of σt = 1000 in a σt = 4 cube (global
//! majorant 1000: ~250 null collisions per real one) the estimator is so heavy-tailed that
//! any affordable render sits low, with an error bar that does not cover it. Measured
//! against an independent analog light tracer (`reference/tests/cube_orders.rs`: exact
//! free paths, point detector; 2²³ photons, image mean of the 16×16 camera), 2-core EPYC:
//!
//! | cube | analog | ours (1024 spp) | Mitsuba rr_depth 5 | Mitsuba no RR |
//! |---|---|---|---|---|
//! | homogeneous σt 4 | 0.109758 ± 0.000049 | 0.109798 ± 0.000193 | 0.109727 ± 0.000098 (128 spp × 64) | 0.109754 ± 0.000091 (512 × 16) |
//! | centre σt 1000 | 0.109267 ± 0.000049 | 0.109328 ± 0.000193 | 0.103457 ± 0.000507 (64 spp × 8) | 0.109248 ± 0.000235 (64 × 8) |
//!
//! On the homogeneous cube (no null collisions) Russian roulette is harmless and both
//! renderers agree with the analog tracer; the coordinator's `mitsuba_compare` z = +4.0 there
//! (seed 4: ours 0.110146 ± 0.000188, Mitsuba 0.108875 ± 0.000252) was both estimates
//! fluctuating apart (+2.0 σ and −3.4 σ from the analog value, the latter with K − 1 = 7
//! degrees of freedom); seeds 5–8 give mean_z −1.27, +0.93, +0.76, +0.27. Exporting
//! `rr_depth` = [`RR_DEPTH`] removes the roulette: paths end by escaping, by `max_depth`
//! or with zero throughput, which in our bounded media with albedo < 1 always happens.
//!
//! Refused: volume emission (Mitsuba's `heterogeneous` medium has none; emissive
//! comparisons put a sphere light inside the medium) and scenes without a camera.

use crate::compare::ImageEstimate;
use serde::Deserialize;
use serde_json::{Value, json};
use solvers::scene::{Camera, Light, Phase, Projection, Scene, VolError, VolGrid};
use solvers::vec3::{cross, normalize, sub};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};
use thiserror::Error;

/// Mitsuba's `volpath` `rr_depth` in every export: Russian roulette never starts (see the
/// module documentation, "Russian roulette at null collisions").
pub const RR_DEPTH: i64 = i32::MAX as i64;

/// The Python script that renders an exported job (shipped inside the binary).
pub const SCRIPT: &str = include_str!("../python/render_mitsuba.py");

/// Environment variable naming the Python interpreter that has `mitsuba` (overrides the
/// repository's `.venv-mitsuba/bin/python`).
pub const PYTHON_ENV: &str = "SCATTERBENCH_MITSUBA_PYTHON";

/// The message every "not installed" error ends with.
pub const SETUP_HINT: &str = "run scripts/setup-mitsuba.sh to install Mitsuba 3 into .venv-mitsuba/ (or point SCATTERBENCH_MITSUBA_PYTHON at a python that has it)";

/// Errors of the Mitsuba bridge.
#[derive(Debug, Error)]
pub enum MitsubaError {
    /// No Python with the `mitsuba` package.
    #[error("Mitsuba 3 not found ({python}): {reason}; {SETUP_HINT}")]
    NotInstalled {
        /// The interpreter tried.
        python: PathBuf,
        /// Why it is not usable.
        reason: String,
    },
    /// The scene uses something Mitsuba cannot represent the same way.
    #[error("scene cannot be rendered by Mitsuba: {0}")]
    Unsupported(String),
    /// A parameter of the render is invalid.
    #[error("invalid Mitsuba render settings: {0}")]
    Settings(String),
    /// The render script failed.
    #[error("Mitsuba render script failed ({status}); stderr ends with:\n{stderr_tail}")]
    ScriptFailed {
        /// Exit status.
        status: String,
        /// The last lines of its standard error.
        stderr_tail: String,
    },
    /// The render script ran past its time limit and was killed.
    #[error(
        "the Mitsuba render script ran past its time limit of {seconds} s and was killed \
         (raise it with --mitsuba-timeout or {TIMEOUT_ENV}, or lower the samples per pixel)"
    )]
    TimedOut {
        /// The limit, in seconds.
        seconds: f64,
    },
    /// The script's output is missing or inconsistent.
    #[error("unexpected output from the Mitsuba script: {0}")]
    Output(String),
    /// A file could not be written or read (the I/O error is the source).
    #[error("{}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// A grid could not be exported.
    #[error("exporting a grid")]
    Vol(#[from] VolError),
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> MitsubaError + '_ {
    move |source| MitsubaError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Which Python runs Mitsuba, and which variant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MitsubaConfig {
    /// The interpreter (with the `mitsuba` package).
    pub python: PathBuf,
    /// The Mitsuba variant, e.g. `scalar_rgb` or `llvm_ad_rgb`.
    pub variant: String,
}

impl MitsubaConfig {
    /// `$SCATTERBENCH_MITSUBA_PYTHON`, else `<workspace>/.venv-mitsuba/bin/python`.
    pub fn default_python() -> PathBuf {
        match std::env::var_os(PYTHON_ENV) {
            Some(p) if !p.is_empty() => PathBuf::from(p),
            _ => Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("..")
                .join(".venv-mitsuba")
                .join("bin")
                .join("python"),
        }
    }

    /// The default interpreter with `variant`.
    pub fn new(variant: &str) -> Self {
        Self {
            python: Self::default_python(),
            variant: variant.to_string(),
        }
    }

    /// For tests: the default interpreter with `variant` if it works; `Ok(None)` (after one
    /// line on standard error) if Mitsuba is not installed, unless
    /// `SCATTERBENCH_REQUIRE_MITSUBA=1`, which turns that into the error.
    pub fn available_or_skip(variant: &str) -> Result<Option<Self>, MitsubaError> {
        let cfg = Self::new(variant);
        match cfg.probe() {
            Ok(_) => Ok(Some(cfg)),
            Err(e @ MitsubaError::NotInstalled { .. }) => {
                if std::env::var("SCATTERBENCH_REQUIRE_MITSUBA").as_deref() == Ok("1") {
                    return Err(e);
                }
                // Written to the stream directly so that the test harness does not capture it.
                use std::io::Write;
                let _ = writeln!(
                    std::io::stderr(),
                    "skipped: Mitsuba not installed (run scripts/setup-mitsuba.sh)"
                );
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// Checks that the interpreter imports `mitsuba` and has the variant; returns Mitsuba's
    /// version.
    pub fn probe(&self) -> Result<String, MitsubaError> {
        self.probe_within(PROBE_TIMEOUT)
    }

    /// [`MitsubaConfig::probe`], killing the interpreter after `limit`.
    pub fn probe_within(&self, limit: Duration) -> Result<String, MitsubaError> {
        let not_installed = |reason: String| MitsubaError::NotInstalled {
            python: self.python.clone(),
            reason,
        };
        if !self.python.exists() {
            return Err(not_installed("no such interpreter".into()));
        }
        let code = "import sys, mitsuba as mi\nv = sys.argv[1]\nprint(mi.__version__)\nprint(v in mi.variants())";
        let dir = WorkDir::new(None)?;
        let out = run_limited(
            Command::new(&self.python).args(["-c", code, &self.variant]),
            &dir.path,
            "probe",
            limit,
        )
        .map_err(|e| not_installed(format!("cannot run it: {e}")))??;
        if !out.status.success() {
            return Err(not_installed(format!(
                "`import mitsuba` failed: {}",
                tail(&String::from_utf8_lossy(&out.stderr), 400)
            )));
        }
        let text = String::from_utf8_lossy(&out.stdout);
        let mut lines = text.lines();
        let version = lines.next().unwrap_or("unknown").trim().to_string();
        if lines.next().map(str::trim) != Some("True") {
            return Err(not_installed(format!(
                "mitsuba {version} has no variant `{}`",
                self.variant
            )));
        }
        Ok(version)
    }
}

/// Settings of a Mitsuba reference render.
#[derive(Debug, Clone, PartialEq)]
pub struct MitsubaSettings {
    /// Samples per pixel of each independent render.
    pub spp: u32,
    /// Number of independent renders K (≥ 2) for the per-pixel standard errors.
    pub renders: u32,
    /// Base seed; render k uses Mitsuba seed (seed · 65537 + k) mod 2³².
    pub seed: u64,
    /// Most scattering events per path in *our* convention (`pathtracer::RenderSettings`:
    /// light scattered at most k times), passed to Mitsuba as `max_depth = k + 1` (Mitsuba
    /// counts path segments: `max_depth = 1` is emitted light only); `None`: unlimited.
    pub max_depth: Option<u32>,
    /// Keep the exported files here instead of a temporary directory that is removed.
    pub keep_dir: Option<PathBuf>,
    /// Kill the render script after this long (`None`: [`default_timeout`]).
    pub timeout: Option<Duration>,
}

/// The environment variable with the default time limit of a Mitsuba child, in seconds.
pub const TIMEOUT_ENV: &str = "SCATTERBENCH_MITSUBA_TIMEOUT";

/// The time limit of a Mitsuba render script when the settings give none:
/// `SCATTERBENCH_MITSUBA_TIMEOUT` seconds, else one hour.
pub fn default_timeout() -> Duration {
    std::env::var(TIMEOUT_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0)
        .map_or(Duration::from_secs(3600), Duration::from_secs_f64)
}

/// The time limit of the import probe (`import mitsuba` takes a few seconds).
const PROBE_TIMEOUT: Duration = Duration::from_secs(120);

/// Runs `cmd` with its standard output and error captured in files under `dir` (no pipe can
/// fill) and kills it after `limit`.
fn run_limited(
    cmd: &mut Command,
    dir: &Path,
    tag: &str,
    limit: Duration,
) -> Result<Result<std::process::Output, MitsubaError>, std::io::Error> {
    let out_path = dir.join(format!("{tag}.stdout"));
    let err_path = dir.join(format!("{tag}.stderr"));
    let mut child = cmd
        .stdin(std::process::Stdio::null())
        .stdout(std::fs::File::create(&out_path)?)
        .stderr(std::fs::File::create(&err_path)?)
        .spawn()?;
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if start.elapsed() >= limit {
            let _ = child.kill();
            let _ = child.wait();
            return Ok(Err(MitsubaError::TimedOut {
                seconds: limit.as_secs_f64(),
            }));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stdout = std::fs::read(&out_path).unwrap_or_default();
    let stderr = std::fs::read(&err_path).unwrap_or_default();
    Ok(Ok(std::process::Output {
        status,
        stdout,
        stderr,
    }))
}

/// A Mitsuba render: per-pixel mean and standard error over K seeds, with provenance.
#[derive(Debug, Clone, PartialEq)]
pub struct MitsubaRender {
    /// The mean image and its standard errors (K − 1 degrees of freedom).
    pub image: ImageEstimate,
    /// Mitsuba's version.
    pub version: String,
    /// The variant used.
    pub variant: String,
    /// Samples per pixel of each render.
    pub spp: u32,
    /// Number of renders K.
    pub renders: u32,
    /// Seconds to load the scene in Mitsuba.
    pub load_seconds: f64,
    /// Wall seconds of each render (the first includes JIT compilation in LLVM variants).
    pub render_seconds: Vec<f64>,
    /// CPU seconds (all threads of the Python process) of each render.
    pub render_cpu_seconds: Vec<f64>,
    /// Wall seconds of the whole bridge call (export, Python start-up, load, renders).
    pub wall_seconds: f64,
    /// Largest |channel c − channel 0| over pixels, renders and channels (0 for grey scenes).
    pub max_channel_difference: f64,
}

impl MitsubaRender {
    /// Camera paths per second over all renders.
    pub fn paths_per_second(&self) -> f64 {
        let paths = self.paths_per_render() * self.renders as f64;
        paths / self.render_seconds.iter().sum::<f64>()
    }

    /// Camera paths per second over renders 2…K (excludes JIT compilation and warm-up).
    pub fn warm_paths_per_second(&self) -> f64 {
        if self.render_seconds.len() < 2 {
            return self.paths_per_second();
        }
        let rest = &self.render_seconds[1..];
        self.paths_per_render() * rest.len() as f64 / rest.iter().sum::<f64>()
    }

    /// Camera paths per CPU second (all threads) over all renders: the renderer's efficiency,
    /// less sensitive than wall time to other load on the machine.
    pub fn paths_per_cpu_second(&self) -> f64 {
        let paths = self.paths_per_render() * self.renders as f64;
        paths / self.render_cpu_seconds.iter().sum::<f64>()
    }

    fn paths_per_render(&self) -> f64 {
        (self.image.width * self.image.height) as f64 * f64::from(self.spp)
    }
}

/// A 4×4 row-major matrix as the script's transform marker.
fn transform(m: [[f64; 4]; 4]) -> Value {
    json!({ "__transform__": m })
}

/// Mitsuba's `look_at(eye, target, up)`: columns (left, up′, dir, eye) with
/// dir = normalise(target − eye), left = normalise(up × dir), up′ = dir × left.
pub fn look_at(eye: [f64; 3], target: [f64; 3], up: [f64; 3]) -> [[f64; 4]; 4] {
    let dir = normalize(sub(target, eye));
    let left = normalize(cross(up, dir));
    let new_up = cross(dir, left);
    let mut m = [[0.0; 4]; 4];
    for r in 0..3 {
        m[r] = [left[r], new_up[r], dir[r], eye[r]];
    }
    m[3] = [0.0, 0.0, 0.0, 1.0];
    m
}

/// The Mitsuba sensor `to_world` of our camera (see the module documentation).
pub fn sensor_to_world(camera: &Camera) -> [[f64; 4]; 4] {
    let mut m = look_at(camera.eye, camera.target, camera.up);
    if let Projection::Orthographic { width } = camera.projection {
        for row in m.iter_mut().take(3) {
            row[0] *= 0.5 * width;
            row[1] *= 0.5 * width;
        }
    }
    m
}

/// Where pixel position (`px`, `py`) (continuous, (0, 0) the top-left corner of the image,
/// x right, y down, in pixels) looks through an orthographic Mitsuba sensor with `to_world`,
/// following Mitsuba's sample-to-camera map; returns the ray origin on the image plane.
pub fn orthographic_pixel_origin(
    to_world: &[[f64; 4]; 4],
    resolution: [usize; 2],
    px: f64,
    py: f64,
) -> [f64; 3] {
    // Film sample (u, v) ∈ [0,1]²; camera x = 1 − 2u, y = (1 − 2v)/aspect (sensor.h).
    let aspect = resolution[0] as f64 / resolution[1] as f64;
    let (u, v) = (px / resolution[0] as f64, py / resolution[1] as f64);
    let local = [1.0 - 2.0 * u, (1.0 - 2.0 * v) / aspect, 0.0, 1.0];
    let mut out = [0.0; 3];
    for (r, o) in out.iter_mut().enumerate() {
        *o = (0..4).map(|c| to_world[r][c] * local[c]).sum();
    }
    out
}

/// Exports `scene` for Mitsuba (`max_depth` in Mitsuba's convention, `None` for −1): writes `sigma_t.vol` (and `albedo.vol` unless the albedo is
/// constant) into `dir` and returns the scene dictionary (transforms as `__transform__`
/// markers), with a `hdrfilm` of the camera's resolution and an `independent` sampler of
/// `spp` samples.
pub fn export_scene(
    scene: &Scene,
    dir: &Path,
    spp: u32,
    max_depth: Option<u32>,
) -> Result<Value, MitsubaError> {
    let m = &scene.medium;
    if let Some(i) = m.emission.iter().position(|&j| j != 0.0) {
        return Err(MitsubaError::Unsupported(format!(
            "the medium emits (emission {} in voxel {i}); Mitsuba's heterogeneous medium has no volume emission: compare emissive scenes with a sphere light inside the medium instead",
            m.emission[i]
        )));
    }
    let camera = scene.camera.ok_or_else(|| {
        MitsubaError::Unsupported("the scene has no camera to render an image with".into())
    })?;
    camera
        .validate()
        .map_err(|e| MitsubaError::Unsupported(e.to_string()))?;
    let grid = &m.grid;
    let sigma_path = dir.join("sigma_t.vol");
    VolGrid::from_field(grid, &m.sigma_t)?.write(&sigma_path)?;
    let grid_volume = |path: &Path| {
        json!({
            "type": "gridvolume",
            "filename": path.to_string_lossy(),
            "use_grid_bbox": true,
            "filter_type": scene.interpolation.name(),
        })
    };
    let albedo = if m.albedo.iter().all(|&a| a == m.albedo[0]) {
        json!(m.albedo[0])
    } else {
        let p = dir.join("albedo.vol");
        VolGrid::from_field(grid, &m.albedo)?.write(&p)?;
        grid_volume(&p)
    };
    let phase = match scene.phase {
        Phase::Isotropic => json!({"type": "isotropic"}),
        Phase::HenyeyGreenstein { g } => json!({"type": "hg", "g": g}),
    };
    let size = grid.size();
    let half = size.map(|s| 0.5 * s);
    let centre = [0, 1, 2].map(|a| grid.origin[a] + half[a]);
    let cube_to_world = [
        [half[0], 0.0, 0.0, centre[0]],
        [0.0, half[1], 0.0, centre[1]],
        [0.0, 0.0, half[2], centre[2]],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut dict = serde_json::Map::new();
    dict.insert("type".into(), json!("scene"));
    dict.insert(
        "integrator".into(),
        json!({
            "type": "volpath",
            "max_depth": max_depth.map_or(-1, i64::from),
            "rr_depth": RR_DEPTH,
            "hide_emitters": camera.hide_background,
        }),
    );
    let film = json!({
        "type": "hdrfilm",
        "width": camera.resolution[0],
        "height": camera.resolution[1],
        "rfilter": {"type": "box"},
        "pixel_format": "rgb",
        "component_format": "float32",
    });
    let mut sensor = json!({
        "to_world": transform(sensor_to_world(&camera)),
        "near_clip": 1e-4,
        "far_clip": 1e4,
        "film": film,
        "sampler": {"type": "independent", "sample_count": spp},
    });
    match camera.projection {
        Projection::Orthographic { .. } => sensor["type"] = json!("orthographic"),
        Projection::Perspective { fov_y_degrees } => {
            sensor["type"] = json!("perspective");
            sensor["fov"] = json!(fov_y_degrees);
            sensor["fov_axis"] = json!("y");
        }
    }
    dict.insert("sensor".into(), sensor);
    dict.insert(
        "medium_bounds".into(),
        json!({
            "type": "cube",
            "to_world": transform(cube_to_world),
            "bsdf": {"type": "null"},
            "interior": {
                "type": "heterogeneous",
                "sigma_t": grid_volume(&sigma_path),
                "albedo": albedo,
                "scale": 1.0,
                "phase": phase,
            },
        }),
    );
    for (i, light) in scene.lights.iter().enumerate() {
        let entry = match *light {
            Light::Point { position, power } => json!({
                "type": "point",
                "position": position,
                "intensity": power / (4.0 * std::f64::consts::PI),
            }),
            Light::Directional {
                direction,
                irradiance,
            } => json!({
                "type": "directional",
                "direction": direction,
                "irradiance": irradiance,
            }),
            Light::Sphere {
                center,
                radius,
                radiance,
            } => json!({
                "type": "sphere",
                "center": center,
                "radius": radius,
                "bsdf": {"type": "diffuse", "reflectance": 0.0},
                "emitter": {"type": "area", "radiance": radiance},
            }),
            Light::Environment { radiance } => json!({
                "type": "constant",
                "radiance": radiance,
            }),
        };
        dict.insert(format!("light_{i}"), entry);
    }
    Ok(Value::Object(dict))
}

#[derive(Deserialize)]
struct ScriptResult {
    version: String,
    variant: String,
    width: usize,
    height: usize,
    channels: usize,
    load_seconds: f64,
    render_seconds: Vec<f64>,
    render_cpu_seconds: Vec<f64>,
}

/// The last `max` bytes of `s` (on a character boundary).
fn tail(s: &str, max: usize) -> String {
    let start = s.len().saturating_sub(max);
    let start = (start..=s.len())
        .find(|&i| s.is_char_boundary(i))
        .unwrap_or(s.len());
    s[start..].trim().to_string()
}

/// A scratch directory, removed on drop unless kept.
struct WorkDir {
    path: PathBuf,
    keep: bool,
}

impl WorkDir {
    fn new(keep: Option<&Path>) -> Result<Self, MitsubaError> {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let (path, keep) = match keep {
            Some(p) => (p.to_path_buf(), true),
            None => (
                std::env::temp_dir().join(format!(
                    "scatterbench-mitsuba-{}-{}",
                    std::process::id(),
                    COUNTER.fetch_add(1, Ordering::Relaxed)
                )),
                false,
            ),
        };
        std::fs::create_dir_all(&path).map_err(io(&path))?;
        Ok(Self { path, keep })
    }
}

impl Drop for WorkDir {
    fn drop(&mut self) {
        if !self.keep {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

/// Renders `scene` with Mitsuba K = `settings.renders` times with independent seeds and
/// returns the per-pixel mean and standard error (K − 1 degrees of freedom).
pub fn render(
    scene: &Scene,
    settings: &MitsubaSettings,
    config: &MitsubaConfig,
) -> Result<MitsubaRender, MitsubaError> {
    let started = Instant::now();
    if settings.renders < 2 {
        return Err(MitsubaError::Settings(format!(
            "renders = {}: at least 2 independent renders are needed for standard errors",
            settings.renders
        )));
    }
    if settings.spp == 0 {
        return Err(MitsubaError::Settings("spp must be at least 1".into()));
    }
    let limit = settings.timeout.unwrap_or_else(default_timeout);
    config.probe_within(limit.min(PROBE_TIMEOUT))?;
    let work = WorkDir::new(settings.keep_dir.as_deref())?;
    let dir = &work.path;
    let scene_dict = export_scene(
        scene,
        dir,
        settings.spp,
        settings.max_depth.map(|k| k.saturating_add(1)),
    )?;
    let seeds: Vec<u32> = (0..settings.renders)
        .map(|k| {
            (settings.seed.wrapping_mul(65537).wrapping_add(u64::from(k)) & 0xffff_ffff) as u32
        })
        .collect();
    let job = json!({
        "variant": config.variant,
        "spp": settings.spp,
        "seeds": seeds,
        "scene": scene_dict,
        "output_dir": dir.to_string_lossy(),
    });
    let job_path = dir.join("job.json");
    let text = serde_json::to_string_pretty(&job)
        .map_err(|e| MitsubaError::Output(format!("serialising the job: {e}")))?;
    std::fs::write(&job_path, text).map_err(io(&job_path))?;
    let script_path = dir.join("render_mitsuba.py");
    std::fs::write(&script_path, SCRIPT).map_err(io(&script_path))?;
    let out = run_limited(
        Command::new(&config.python)
            .arg(&script_path)
            .arg(&job_path),
        dir,
        "render",
        limit,
    )
    .map_err(|e| MitsubaError::NotInstalled {
        python: config.python.clone(),
        reason: format!("cannot run it: {e}"),
    })??;
    if !out.status.success() {
        return Err(MitsubaError::ScriptFailed {
            status: out.status.to_string(),
            stderr_tail: tail(&String::from_utf8_lossy(&out.stderr), 2000),
        });
    }
    let result_path = dir.join("result.json");
    let result: ScriptResult =
        serde_json::from_str(&std::fs::read_to_string(&result_path).map_err(io(&result_path))?)
            .map_err(|e| MitsubaError::Output(format!("{}: {e}", result_path.display())))?;
    let camera = scene
        .camera
        .ok_or_else(|| MitsubaError::Unsupported("no camera".into()))?;
    if [result.width, result.height] != camera.resolution {
        return Err(MitsubaError::Output(format!(
            "image is {}x{}, the camera has {:?}",
            result.width, result.height, camera.resolution
        )));
    }
    if result.render_seconds.len() != seeds.len()
        || result.render_cpu_seconds.len() != seeds.len()
        || result.channels == 0
    {
        return Err(MitsubaError::Output(format!(
            "{} render times and {} channels for {} seeds",
            result.render_seconds.len(),
            result.channels,
            seeds.len()
        )));
    }
    let (w, h, c) = (result.width, result.height, result.channels);
    let n = w * h;
    let mut sum = vec![0.0; n];
    let mut sum_sq = vec![0.0; n];
    let mut max_channel_difference: f64 = 0.0;
    for k in 0..seeds.len() {
        let path = dir.join(format!("image_{k}.f32"));
        let bytes = std::fs::read(&path).map_err(io(&path))?;
        if bytes.len() != n * c * 4 {
            return Err(MitsubaError::Output(format!(
                "{} has {} bytes, expected {}",
                path.display(),
                bytes.len(),
                n * c * 4
            )));
        }
        let values: Vec<f64> = bytes
            .chunks_exact(4)
            .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect();
        for p in 0..n {
            let v0 = values[p * c];
            for ch in 1..c {
                max_channel_difference =
                    max_channel_difference.max((values[p * c + ch] - v0).abs());
            }
            sum[p] += v0;
            sum_sq[p] += v0 * v0;
        }
    }
    let kf = seeds.len() as f64;
    let mean: Vec<f64> = sum.iter().map(|s| s / kf).collect();
    let stderr: Vec<f64> = (0..n)
        .map(|p| {
            let var = ((sum_sq[p] - kf * mean[p] * mean[p]) / (kf - 1.0)).max(0.0);
            (var / kf).sqrt()
        })
        .collect();
    Ok(MitsubaRender {
        image: ImageEstimate {
            width: w,
            height: h,
            mean,
            stderr,
            dof: kf - 1.0,
        },
        version: result.version,
        variant: result.variant,
        spp: settings.spp,
        renders: settings.renders,
        load_seconds: result.load_seconds,
        render_seconds: result.render_seconds,
        render_cpu_seconds: result.render_cpu_seconds,
        wall_seconds: started.elapsed().as_secs_f64(),
        max_channel_difference,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use solvers::{Grid, Medium};

    fn camera(projection: Projection) -> Camera {
        Camera {
            hide_background: false,
            eye: [0.5, -1.0, 0.5],
            target: [0.5, 0.5, 0.5],
            up: [0.0, 0.0, 1.0],
            projection,
            resolution: [8, 4],
        }
    }

    #[test]
    fn orthographic_sensor_puts_pixel_zero_top_left_with_square_pixels() {
        // Looking along +y with z up: right is +x, so the image's top-left corner is at
        // (−w/2, ·, +h/2) relative to the eye, and pixels are w/8 = h/4 square.
        let cam = camera(Projection::Orthographic { width: 2.0 });
        let m = sensor_to_world(&cam);
        let tl = orthographic_pixel_origin(&m, cam.resolution, 0.0, 0.0);
        let br = orthographic_pixel_origin(&m, cam.resolution, 8.0, 4.0);
        let expect_tl = [0.5 - 1.0, -1.0, 0.5 + 0.5];
        let expect_br = [0.5 + 1.0, -1.0, 0.5 - 0.5];
        for a in 0..3 {
            assert!((tl[a] - expect_tl[a]).abs() < 1e-12, "{tl:?}");
            assert!((br[a] - expect_br[a]).abs() < 1e-12, "{br:?}");
        }
        // The view direction (third column) is +y.
        assert!((m[1][2] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn export_maps_grid_lights_and_camera_and_refuses_emission() {
        let grid = Grid::with_origin([4, 4, 4], 0.25, [1.0, 2.0, 3.0]).unwrap();
        let mut medium = Medium::homogeneous(grid, 2.0, 0.5).unwrap();
        medium.sigma_t[5] = 7.0;
        let mut scene = Scene {
            interpolation: Default::default(),
            medium,
            phase: Phase::HenyeyGreenstein { g: 0.3 },
            lights: vec![
                Light::Point {
                    position: [0.0; 3],
                    power: 4.0 * std::f64::consts::PI,
                },
                Light::Sphere {
                    center: [1.5, 2.5, 3.5],
                    radius: 0.1,
                    radiance: 2.0,
                },
            ],
            camera: Some(camera(Projection::Perspective {
                fov_y_degrees: 30.0,
            })),
            sampler: solvers::scene::Sampler { spp: 4, seed: 1 },
        };
        let dir =
            std::env::temp_dir().join(format!("scatterbench-mi-export-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let d = export_scene(&scene, &dir, 16, None).unwrap();
        let vol = VolGrid::read(&dir.join("sigma_t.vol")).unwrap();
        assert_eq!(vol.min, [1.0, 2.0, 3.0]);
        assert_eq!(vol.max, [2.0, 3.0, 4.0]);
        assert_eq!(vol.data[5], 7.0);
        let medium = &d["medium_bounds"]["interior"];
        assert_eq!(medium["albedo"], json!(0.5));
        assert_eq!(medium["sigma_t"]["filter_type"], json!("nearest"));
        assert_eq!(medium["phase"], json!({"type": "hg", "g": 0.3}));
        assert_eq!(
            d["medium_bounds"]["to_world"]["__transform__"][0],
            json!([0.5, 0.0, 0.0, 1.5])
        );
        assert_eq!(d["light_0"]["intensity"], json!(1.0));
        assert_eq!(d["light_1"]["emitter"]["radiance"], json!(2.0));
        assert_eq!(d["sensor"]["fov_axis"], json!("y"));
        assert_eq!(d["sensor"]["film"]["width"], json!(8));
        assert_eq!(d["sensor"]["film"]["rfilter"]["type"], json!("box"));
        assert_eq!(d["integrator"]["max_depth"], json!(-1));
        assert_eq!(d["integrator"]["rr_depth"], json!(i64::from(i32::MAX)));
        assert_eq!(d["integrator"]["hide_emitters"], json!(false));
        scene.interpolation = solvers::scene::Interpolation::Trilinear;
        if let Some(c) = scene.camera.as_mut() {
            c.hide_background = true;
        }
        let d = export_scene(&scene, &dir, 16, None).unwrap();
        let medium = &d["medium_bounds"]["interior"];
        assert_eq!(medium["sigma_t"]["filter_type"], json!("trilinear"));
        assert_eq!(d["integrator"]["hide_emitters"], json!(true));
        scene.medium.emission[3] = 1.0;
        let err = export_scene(&scene, &dir, 16, None).unwrap_err();
        assert!(err.to_string().contains("no volume emission"), "{err}");
        scene.medium.emission[3] = 0.0;
        scene.camera = None;
        assert!(matches!(
            export_scene(&scene, &dir, 16, None),
            Err(MitsubaError::Unsupported(_))
        ));
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_missing_interpreter_is_a_typed_error_that_says_how_to_install() {
        let cfg = MitsubaConfig {
            python: PathBuf::from("/nonexistent/python"),
            variant: "scalar_rgb".into(),
        };
        let err = cfg.probe().unwrap_err();
        assert!(matches!(err, MitsubaError::NotInstalled { .. }));
        assert!(
            err.to_string().contains("scripts/setup-mitsuba.sh"),
            "{err}"
        );
    }
}
