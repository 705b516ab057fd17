//! Procedural media by name, for scene files (`[medium] generator = "…"` with its parameters
//! in `[medium.params]`).
//!
//! A generator is a parameter struct that implements [`Generator`] (its serde field names are
//! the parameter names, unknown ones are rejected); registering it is one line in
//! [`GENERATORS`]: `GeneratorEntry::of::<MyGenerator>(),`.

use crate::noise::Perlin;
use crate::{Grid, Medium, SolverError, scenes};
use serde::Deserialize;
use serde::de::DeserializeOwned;
use thiserror::Error;

/// A procedural medium with parameters read from a scene file.
pub trait Generator: DeserializeOwned {
    /// The name used in `generator = "…"`.
    const NAME: &'static str;
    /// One line for listings and error messages.
    const DESCRIPTION: &'static str;
    /// Builds the medium (on the generator's own box; a scene file may move and scale it).
    fn generate(&self) -> Result<Medium<f64>, SolverError>;
    /// Per-channel (R, G, B) media of a coloured dataset; `None` (the default) for a
    /// monochrome generator. The channels share [`Generator::generate`]'s grid.
    fn generate_channels(&self) -> Result<Option<[Medium<f64>; 3]>, SolverError> {
        Ok(None)
    }
}

type Channels = Option<[Medium<f64>; 3]>;

/// Why a generator could not build its medium.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GeneratorError {
    /// The parameters do not deserialise (unknown key, wrong type, missing value); the error
    /// carries the span in the document it was parsed from.
    #[error("{}", .0.message())]
    Params(toml::de::Error),
    /// The parameters parse but are out of range.
    #[error("{0}")]
    Solver(SolverError),
}

/// A registered generator: its name, description and builder.
#[derive(Debug, Clone, Copy)]
pub struct GeneratorEntry {
    /// The name used in `generator = "…"`.
    pub name: &'static str,
    /// One line of description.
    pub description: &'static str,
    build: fn(&str) -> Result<Medium<f64>, GeneratorError>,
    build_channels: fn(&str) -> Result<Channels, GeneratorError>,
}

impl GeneratorEntry {
    /// The entry of generator `G`.
    pub const fn of<G: Generator>() -> Self {
        Self {
            name: G::NAME,
            description: G::DESCRIPTION,
            build: build_from_document::<G>,
            build_channels: build_channels_from_document::<G>,
        }
    }

    /// The per-channel media of a coloured generator (`None` for a monochrome one), from
    /// the document's `[medium.params]`.
    pub fn build_channels_from_document(&self, document: &str) -> Result<Channels, GeneratorError> {
        (self.build_channels)(document)
    }

    /// Builds the medium from the `[medium.params]` table of the TOML document `document`
    /// (every other key of the document is ignored); parameter errors carry spans into it.
    pub fn build_from_document(&self, document: &str) -> Result<Medium<f64>, GeneratorError> {
        (self.build)(document)
    }

    /// Builds the medium from a parameter table.
    pub fn build(&self, params: &toml::Table) -> Result<Medium<f64>, GeneratorError> {
        let mut medium = toml::Table::new();
        medium.insert("params".into(), toml::Value::Table(params.clone()));
        let mut doc = toml::Table::new();
        doc.insert("medium".into(), toml::Value::Table(medium));
        // A table of TOML values always serialises.
        let text = toml::to_string(&doc).unwrap_or_default();
        (self.build)(&text)
    }
}

/// Every generator a scene file can name. Add new ones here, one line each.
pub const GENERATORS: &[GeneratorEntry] = &[
    GeneratorEntry::of::<VacuumCloud>(),
    GeneratorEntry::of::<Homogeneous>(),
    GeneratorEntry::of::<RandomHeterogeneous>(),
    GeneratorEntry::of::<DenseVoxel>(),
    GeneratorEntry::of::<Sphere>(),
    GeneratorEntry::of::<NoiseCloud>(),
    GeneratorEntry::of::<super::datasets::Nebula>(),
    GeneratorEntry::of::<super::datasets::EmissiveCloud>(),
    GeneratorEntry::of::<super::datasets::ShellCore>(),
    GeneratorEntry::of::<super::datasets::Plume>(),
];

/// The registered generator called `name`.
pub fn find(name: &str) -> Option<&'static GeneratorEntry> {
    GENERATORS.iter().find(|g| g.name == name)
}

/// The registered names, comma-separated (for error messages).
pub fn names() -> String {
    GENERATORS
        .iter()
        .map(|g| g.name)
        .collect::<Vec<_>>()
        .join(", ")
}

#[derive(Deserialize)]
struct ParamsDoc<G> {
    medium: ParamsMedium<G>,
}

#[derive(Deserialize)]
struct ParamsMedium<G> {
    /// Absent when the document has no `[medium.params]` (serde's rule for a missing
    /// `Option`; `#[serde(default)]` would demand `G: Default`).
    params: Option<G>,
}

fn params_of<G: Generator>(document: &str) -> Result<G, GeneratorError> {
    let doc: ParamsDoc<G> = toml::from_str(document).map_err(GeneratorError::Params)?;
    match doc.medium.params {
        Some(p) => Ok(p),
        None => toml::from_str::<G>("").map_err(GeneratorError::Params),
    }
}

fn build_from_document<G: Generator>(document: &str) -> Result<Medium<f64>, GeneratorError> {
    params_of::<G>(document)?
        .generate()
        .map_err(GeneratorError::Solver)
}

fn build_channels_from_document<G: Generator>(document: &str) -> Result<Channels, GeneratorError> {
    params_of::<G>(document)?
        .generate_channels()
        .map_err(GeneratorError::Solver)
}

/// [`scenes::vacuum_cloud`]: FLD Fig 4's spherical cloud with Perlin-noise emission, on the
/// unit cube.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VacuumCloud {
    /// Voxels per axis (default 64).
    pub n: usize,
    /// Noise seed (default 0).
    pub seed: u64,
}

impl Default for VacuumCloud {
    fn default() -> Self {
        Self { n: 64, seed: 0 }
    }
}

impl Generator for VacuumCloud {
    const NAME: &'static str = "vacuum_cloud";
    const DESCRIPTION: &'static str =
        "FLD Fig 4: sphere of radius 0.35, sigma_t 20, albedo 0.9, Perlin emission (n, seed)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        scenes::vacuum_cloud(self.n, self.seed)
    }
}

/// A homogeneous cube `[0, extent]³` without emission.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Homogeneous {
    /// Voxels per axis (default 32).
    #[serde(default = "Homogeneous::default_n")]
    pub n: usize,
    /// Edge length of the cube (default 1).
    #[serde(default = "Homogeneous::default_extent")]
    pub extent: f64,
    /// Extinction σt (required).
    pub sigma_t: f64,
    /// Single-scattering albedo (required).
    pub albedo: f64,
}

/// The defaults of the optional parameters. `Homogeneous` has required ones (`sigma_t`,
/// `albedo`), so it cannot be `#[serde(default)]` with a `Default` like the other generators.
impl Homogeneous {
    fn default_n() -> usize {
        32
    }
    fn default_extent() -> f64 {
        1.0
    }
}

impl Generator for Homogeneous {
    const NAME: &'static str = "homogeneous";
    const DESCRIPTION: &'static str = "homogeneous cube [0, extent]^3 (n, extent, sigma_t, albedo)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        if !(self.extent.is_finite() && self.extent > 0.0) {
            return Err(SolverError::BadParameter {
                name: "extent",
                value: self.extent,
                reason: "must be finite and > 0",
            });
        }
        Medium::homogeneous(Grid::cube(self.n, self.extent)?, self.sigma_t, self.albedo)
    }
}

/// Issue 14's dense-voxel cube: `n³` voxels of σt = `sigma_t` in the unit cube with the
/// voxel (n/2, n/2, n/2) of σt = `centre_sigma_t` (up to f64's range: a majorant test, the
/// path tracer's cost must not grow with it).
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DenseVoxel {
    /// Voxels per axis (default 8).
    pub n: usize,
    /// σt of every other voxel (default 4).
    pub sigma_t: f64,
    /// σt of the centre voxel (default 10⁶).
    pub centre_sigma_t: f64,
    /// Single-scattering albedo everywhere (default 0.9).
    pub albedo: f64,
}

impl Default for DenseVoxel {
    fn default() -> Self {
        Self {
            n: 8,
            sigma_t: 4.0,
            centre_sigma_t: 1e6,
            albedo: 0.9,
        }
    }
}

impl Generator for DenseVoxel {
    const NAME: &'static str = "dense_voxel";
    const DESCRIPTION: &'static str =
        "unit cube of sigma_t with one dense centre voxel (n, sigma_t, centre_sigma_t, albedo)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        let grid = Grid::cube(self.n, 1.0)?;
        let mut sigma = vec![self.sigma_t; grid.len()];
        let c = self.n / 2;
        sigma[grid.index(c, c, c)] = self.centre_sigma_t;
        let n = grid.len();
        Medium::new(grid, sigma, vec![self.albedo; n], vec![0.0; n])
    }
}

/// A homogeneous sphere of radius `radius` centred in the unit cube, vacuum around it
/// (voxels whose centre lies inside are filled).
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sphere {
    /// Voxels per axis (default 16).
    pub n: usize,
    /// Radius (default 0.35; in (0, 0.5]).
    pub radius: f64,
    /// σt inside (default 20).
    pub sigma_t: f64,
    /// Single-scattering albedo inside (default 0.9).
    pub albedo: f64,
}

impl Default for Sphere {
    fn default() -> Self {
        Self {
            n: 16,
            radius: 0.35,
            sigma_t: 20.0,
            albedo: 0.9,
        }
    }
}

impl Generator for Sphere {
    const NAME: &'static str = "sphere";
    const DESCRIPTION: &'static str =
        "homogeneous sphere centred in the unit cube, vacuum around (n, radius, sigma_t, albedo)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        if !(self.radius > 0.0 && self.radius <= 0.5) {
            return Err(SolverError::BadParameter {
                name: "radius",
                value: self.radius,
                reason: "must be in (0, 0.5] (the sphere lies in the unit cube)",
            });
        }
        let grid = Grid::cube(self.n, 1.0)?;
        let r2 = self.radius * self.radius;
        let inside = |p: [f64; 3]| (0..3).map(|a| (p[a] - 0.5) * (p[a] - 0.5)).sum::<f64>() < r2;
        let sigma = grid.sample(|p| if inside(p) { self.sigma_t } else { 0.0 });
        let n = grid.len();
        Medium::new(grid, sigma, vec![self.albedo; n], vec![0.0; n])
    }
}

/// [`scenes::random_heterogeneous`]: random per-voxel σt, albedo and sparse emission.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RandomHeterogeneous {
    /// Voxels along x, y, z (default 16³).
    pub n: [usize; 3],
    /// Seed (default 0).
    pub seed: u64,
    /// Probability of a vacuum voxel (default 0).
    pub vacuum_fraction: f64,
}

impl Default for RandomHeterogeneous {
    fn default() -> Self {
        Self {
            n: [16; 3],
            seed: 0,
            vacuum_fraction: 0.0,
        }
    }
}

impl Generator for RandomHeterogeneous {
    const NAME: &'static str = "random_heterogeneous";
    const DESCRIPTION: &'static str = "random per-voxel sigma_t, albedo and sparse emission (n = [nx, ny, nz], seed, vacuum_fraction)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        if !(0.0..=1.0).contains(&self.vacuum_fraction) {
            return Err(SolverError::BadParameter {
                name: "vacuum_fraction",
                value: self.vacuum_fraction,
                reason: "must lie in [0, 1]",
            });
        }
        scenes::random_heterogeneous(self.n, self.seed, self.vacuum_fraction)
    }
}

/// A heterogeneous cloud without emission, for rendering and Monte Carlo comparisons: on the
/// unit cube, inside a sphere of `radius` about the centre,
/// σt = `sigma_max` · clamp(0.5 + fbm(`frequency`·p, `octaves`), 0, 1) · s(r), where the
/// edge factor s(r) = smoothstep of (radius − r)/(0.3·radius) fades the density to 0 at the
/// sphere; σt = 0 outside; albedo `albedo` everywhere, no emission.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NoiseCloud {
    /// Voxels per axis (default 64).
    pub n: usize,
    /// Noise seed (default 0).
    pub seed: u64,
    /// Largest σt (default 20).
    pub sigma_max: f64,
    /// Albedo of every voxel (default 0.9).
    pub albedo: f64,
    /// Cloud radius (default 0.4).
    pub radius: f64,
    /// Noise frequency (default 4).
    pub frequency: f64,
    /// Noise octaves (default 4).
    pub octaves: u32,
}

impl Default for NoiseCloud {
    fn default() -> Self {
        Self {
            n: 64,
            seed: 0,
            sigma_max: 20.0,
            albedo: 0.9,
            radius: 0.4,
            frequency: 4.0,
            octaves: 4,
        }
    }
}

impl Generator for NoiseCloud {
    const NAME: &'static str = "noise_cloud";
    const DESCRIPTION: &'static str = "fbm-density sphere without emission (n, seed, sigma_max, albedo, radius, frequency, octaves)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        for (name, v) in [
            ("sigma_max", self.sigma_max),
            ("radius", self.radius),
            ("frequency", self.frequency),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(SolverError::BadParameter {
                    name,
                    value: v,
                    reason: "must be finite and > 0",
                });
            }
        }
        let grid = Grid::cube(self.n, 1.0)?;
        let noise = Perlin::new(self.seed);
        let sigma_t = grid.sample(|p| {
            let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2)).sqrt();
            let t = ((self.radius - r) / (0.3 * self.radius)).clamp(0.0, 1.0);
            let edge = t * t * (3.0 - 2.0 * t);
            let d = (0.5 + noise.fbm(p.map(|x| self.frequency * x), self.octaves)).clamp(0.0, 1.0);
            self.sigma_max * d * edge
        });
        let n = grid.len();
        Medium::new(grid, sigma_t, vec![self.albedo; n], vec![0.0; n])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registry_names_are_unique_and_build_with_defaults_or_params() {
        let mut names: Vec<_> = GENERATORS.iter().map(|g| g.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), GENERATORS.len());
        let cloud = find("vacuum_cloud")
            .unwrap()
            .build(&toml::Table::new())
            .unwrap();
        assert_eq!(cloud, scenes::vacuum_cloud::<f64>(64, 0).unwrap());
        let params: toml::Table = toml::from_str("n = 8\nsigma_t = 3.0\nalbedo = 0.5").unwrap();
        let h = find("homogeneous").unwrap().build(&params).unwrap();
        assert_eq!(h.grid.n, [8; 3]);
        assert!(h.sigma_t.iter().all(|&s| s == 3.0));
        // Missing required parameter, unknown parameter, out-of-range value.
        let err = find("homogeneous")
            .unwrap()
            .build(&toml::Table::new())
            .unwrap_err();
        assert!(err.to_string().contains("sigma_t"), "{err}");
        let bad: toml::Table = toml::from_str("n = 8\nsigma = 3.0").unwrap();
        let err = find("vacuum_cloud").unwrap().build(&bad).unwrap_err();
        assert!(err.to_string().contains("sigma"), "{err}");
        let bad: toml::Table = toml::from_str("vacuum_fraction = 2.0").unwrap();
        let err = find("random_heterogeneous")
            .unwrap()
            .build(&bad)
            .unwrap_err();
        assert!(matches!(err, GeneratorError::Solver(_)), "{err}");
        assert!(find("nope").is_none());
    }

    /// `Default` is the one place of the defaults: a generator built from an empty
    /// `[medium.params]` (or none) is the one its `Default` builds, and `Homogeneous` (no
    /// `Default`: it has required parameters) still demands them.
    #[test]
    fn empty_params_build_the_default_generator() {
        use super::super::datasets::{EmissiveCloud, Nebula, Plume, ShellCore};
        fn check<G: Generator + Default>() {
            let entry = find(G::NAME).unwrap();
            let want = G::default().generate().unwrap();
            assert_eq!(
                entry.build(&toml::Table::new()).unwrap(),
                want,
                "{}",
                G::NAME
            );
            let bare = "[medium]\ngenerator = \"x\"\n";
            assert_eq!(
                entry.build_from_document(bare).unwrap(),
                want,
                "{}",
                G::NAME
            );
            assert_eq!(
                entry.build_channels_from_document(bare).unwrap(),
                G::default().generate_channels().unwrap(),
                "{}",
                G::NAME
            );
        }
        check::<VacuumCloud>();
        check::<RandomHeterogeneous>();
        check::<NoiseCloud>();
        check::<Nebula>();
        check::<EmissiveCloud>();
        check::<ShellCore>();
        check::<Plume>();
        check::<DenseVoxel>();
        check::<Sphere>();
        let h: Homogeneous = toml::from_str("sigma_t = 1.0\nalbedo = 0.5").unwrap();
        assert_eq!((h.n, h.extent), (32, 1.0));
        let err = find("homogeneous")
            .unwrap()
            .build_from_document("[medium]\n")
            .unwrap_err();
        assert!(err.to_string().contains("missing field `sigma_t`"), "{err}");
    }

    /// The dense voxel sits at the centre with its value (σt = 3·10³⁸ is a valid σt); the
    /// sphere's filled voxels are those whose centre lies inside, and a radius outside
    /// (0, 0.5] is a typed error naming it.
    #[test]
    fn dense_voxel_and_sphere_generators() {
        let p: toml::Table = toml::from_str(
            "n = 8
centre_sigma_t = 3e38",
        )
        .unwrap();
        let m = find("dense_voxel").unwrap().build(&p).unwrap();
        let c = m.grid.index(4, 4, 4);
        assert_eq!(m.sigma_t[c], 3e38);
        assert_eq!(m.sigma_t.iter().filter(|&&s| s == 4.0).count(), 511);
        let s = Sphere {
            n: 20,
            radius: 0.3,
            ..Sphere::default()
        }
        .generate()
        .unwrap();
        let filled = s.sigma_t.iter().filter(|&&x| x == 20.0).count() as f64;
        let want = 4.0 / 3.0 * std::f64::consts::PI * 0.3f64.powi(3) * 8000.0;
        assert!((filled / want - 1.0).abs() < 0.05, "{filled} vs {want}");
        assert!(s.sigma_t.iter().all(|&x| x == 0.0 || x == 20.0));
        let bad: toml::Table = toml::from_str("radius = 0.7").unwrap();
        let err = find("sphere").unwrap().build(&bad).unwrap_err();
        assert!(err.to_string().contains("radius"), "{err}");
    }

    #[test]
    fn noise_cloud_is_heterogeneous_bounded_and_vanishes_outside_its_sphere() {
        let g = NoiseCloud {
            n: 24,
            seed: 3,
            sigma_max: 10.0,
            albedo: 0.8,
            radius: 0.4,
            frequency: 4.0,
            octaves: 3,
        };
        let m = g.generate().unwrap();
        let (lo, hi) = m
            .sigma_t
            .iter()
            .fold((f64::MAX, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
        assert_eq!(lo, 0.0);
        assert!(hi <= 10.0 && hi > 3.0, "max sigma_t {hi}");
        for (idx, &s) in m.sigma_t.iter().enumerate() {
            let [i, j, k] = m.grid.coords(idx);
            let p = m.grid.center(i, j, k);
            let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2)).sqrt();
            if r >= 0.4 {
                assert_eq!(s, 0.0);
            }
        }
        // Heterogeneous: the inner voxels' σt is far from constant.
        let inner: Vec<f64> = m.sigma_t.iter().copied().filter(|&s| s > 0.0).collect();
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        let var = inner.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / inner.len() as f64;
        assert!(var.sqrt() > 0.2 * mean, "std {} mean {mean}", var.sqrt());
        assert!(m.emission.iter().all(|&e| e == 0.0));
    }
}
