//! The procedural datasets of the rendering experiments (issue "Rendering pipeline",
//! FLD Section 6.2 analogs). Each is a [`Generator`] registered in
//! [`super::generators::GENERATORS`] and has a scene file in `scenes/` with its lights and
//! camera. All live on the unit cube with n³ voxels (default 64; raise `n` to scale up,
//! the fields are defined in world coordinates so the dataset only gets finer). Seeds drive
//! [`Perlin`] noise; the same parameters give the same fields bit for bit.
//!
//! | generator | what | paper |
//! |---|---|---|
//! | [`Nebula`] | noise-displaced implicit surface plus a small blob below it; coloured extinction comes from the scene file's `sigma_t_rgb` | Fig 1, 7 |
//! | [`EmissiveCloud`] | the Fig 4 sphere in vacuum with Perlin emission ([`crate::scenes::vacuum_cloud`]), with albedo, σt and emission scale as parameters | Fig 4 |
//! | [`ShellCore`] | a dense core inside a thin shell, vacuum between and outside | transitions dense → vacuum |
//! | [`Plume`] | a rising plume: density and temperature fields, blackbody emission per RGB channel | Fig 9 |

use super::generators::Generator;
use crate::noise::Perlin;
use crate::{Grid, Medium, SolverError};
use serde::Deserialize;

fn positive(name: &'static str, v: f64) -> Result<(), SolverError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SolverError::BadParameter {
            name,
            value: v,
            reason: "must be finite and > 0",
        })
    }
}

fn unit(name: &'static str, v: f64) -> Result<(), SolverError> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(SolverError::BadParameter {
            name,
            value: v,
            reason: "must lie in [0, 1]",
        })
    }
}

fn smoothstep(x: f64) -> f64 {
    let s = x.clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

fn dist(p: [f64; 3], c: [f64; 3]) -> f64 {
    ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt()
}

/// FLD Fig 1's "Nebulae": a noise-displaced implicit surface. With
/// f(p) = |p − c| − `radius` + `amplitude`·fbm(`frequency`·p, `octaves`) (c the centre of the
/// cube), σt = `sigma_max`·smoothstep(−f/`edge`): dense inside the displaced surface,
/// fading to vacuum over `edge`. A second, smaller blob (radius 0.1 at (0.5, 0.5, 0.14),
/// same noise) sits below it: it receives light mainly by scattering from the main body
/// (the "volume blob at the bottom" of FLD Section 6.2). Albedo `albedo` everywhere σt > 0;
/// no emission. Colour: the scene file scales σt per channel (`sigma_t_rgb`), as the paper
/// introduces colour "by a color-dependent scaling of the extinction field".
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Nebula {
    /// Voxels per axis (default 64).
    pub n: usize,
    /// Noise seed (default 1).
    pub seed: u64,
    /// Largest σt (default 60).
    pub sigma_max: f64,
    /// Albedo (default 0.9, the paper's).
    pub albedo: f64,
    /// Radius of the undisplaced surface (default 0.3).
    pub radius: f64,
    /// Displacement amplitude (default 0.15).
    pub amplitude: f64,
    /// Noise frequency (default 3).
    pub frequency: f64,
    /// Octaves (default 4).
    pub octaves: u32,
    /// Width of the soft edge (default 0.05).
    pub edge: f64,
}

impl Default for Nebula {
    fn default() -> Self {
        Self {
            n: 64,
            seed: 1,
            sigma_max: 60.0,
            albedo: 0.9,
            radius: 0.3,
            amplitude: 0.15,
            frequency: 3.0,
            octaves: 4,
            edge: 0.05,
        }
    }
}

impl Generator for Nebula {
    const NAME: &'static str = "nebula";
    const DESCRIPTION: &'static str = "FLD Fig 1: noise-displaced implicit surface plus a blob below (n, seed, sigma_max, albedo, radius, amplitude, frequency, octaves, edge)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        for (name, v) in [
            ("sigma_max", self.sigma_max),
            ("radius", self.radius),
            ("frequency", self.frequency),
            ("edge", self.edge),
        ] {
            positive(name, v)?;
        }
        unit("albedo", self.albedo)?;
        let grid = Grid::cube(self.n, 1.0)?;
        let noise = Perlin::new(self.seed);
        let sigma_t = grid.sample(|p| {
            let d = self.amplitude * noise.fbm(p.map(|x| self.frequency * x), self.octaves);
            let main = dist(p, [0.5, 0.5, 0.55]) - self.radius + d;
            let blob = dist(p, [0.5, 0.5, 0.14]) - 0.1 + 0.5 * d;
            self.sigma_max * smoothstep(-main.min(blob) / self.edge)
        });
        let albedo = sigma_t
            .iter()
            .map(|&s| if s > 0.0 { self.albedo } else { 0.0 })
            .collect();
        let n = grid.len();
        Medium::new(grid, sigma_t, albedo, vec![0.0; n])
    }
}

/// FLD Fig 4's spherical cloud in vacuum with Perlin-noise emission
/// ([`crate::scenes::vacuum_cloud`]: radius 0.35, emission max(0, 0.5 + fbm(4p, 3))), with
/// σt, albedo and the emission scaled by parameters (defaults: the Fig 4 values 20, 0.9, 1).
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EmissiveCloud {
    /// Voxels per axis (default 64).
    pub n: usize,
    /// Noise seed (default 0).
    pub seed: u64,
    /// σt inside (default 20).
    pub sigma_t: f64,
    /// Albedo inside (default 0.9).
    pub albedo: f64,
    /// Emission multiplier (default 1).
    pub emission_scale: f64,
}

impl Default for EmissiveCloud {
    fn default() -> Self {
        Self {
            n: 64,
            seed: 0,
            sigma_t: 20.0,
            albedo: 0.9,
            emission_scale: 1.0,
        }
    }
}

impl Generator for EmissiveCloud {
    const NAME: &'static str = "emissive_cloud";
    const DESCRIPTION: &'static str = "FLD Fig 4 sphere in vacuum with Perlin emission, scalable (n, seed, sigma_t, albedo, emission_scale)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        positive("sigma_t", self.sigma_t)?;
        unit("albedo", self.albedo)?;
        if !(self.emission_scale.is_finite() && self.emission_scale >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "emission_scale",
                value: self.emission_scale,
                reason: "must be finite and >= 0",
            });
        }
        let mut m = crate::scenes::vacuum_cloud::<f64>(self.n, self.seed)?;
        for i in 0..m.grid.len() {
            if m.sigma_t[i] > 0.0 {
                m.sigma_t[i] = self.sigma_t;
                m.albedo[i] = self.albedo;
            }
            m.emission[i] *= self.emission_scale;
        }
        m.validate()?;
        Ok(m)
    }
}

/// A dense core inside a thin shell: σt = `core_sigma` within `core_radius` of the centre,
/// `shell_sigma` for `shell_radius` − `shell_thickness` ≤ r ≤ `shell_radius`, vacuum between
/// and outside; albedo `albedo` in both. Light reaches the core only through the shell, and
/// light scattered by the core crosses vacuum before the shell sees it: the dense-to-vacuum
/// transitions where FLD and CDA differ most.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShellCore {
    /// Voxels per axis (default 64).
    pub n: usize,
    /// Core radius (default 0.15).
    pub core_radius: f64,
    /// Core σt (default 100).
    pub core_sigma: f64,
    /// Outer shell radius (default 0.42).
    pub shell_radius: f64,
    /// Shell thickness (default 0.05).
    pub shell_thickness: f64,
    /// Shell σt (default 8).
    pub shell_sigma: f64,
    /// Albedo (default 0.95).
    pub albedo: f64,
}

impl Default for ShellCore {
    fn default() -> Self {
        Self {
            n: 64,
            core_radius: 0.15,
            core_sigma: 100.0,
            shell_radius: 0.42,
            shell_thickness: 0.05,
            shell_sigma: 8.0,
            albedo: 0.95,
        }
    }
}

impl Generator for ShellCore {
    const NAME: &'static str = "shell_core";
    const DESCRIPTION: &'static str = "dense core inside a thin shell, vacuum between (n, core_radius, core_sigma, shell_radius, shell_thickness, shell_sigma, albedo)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        for (name, v) in [
            ("core_radius", self.core_radius),
            ("core_sigma", self.core_sigma),
            ("shell_thickness", self.shell_thickness),
            ("shell_sigma", self.shell_sigma),
        ] {
            positive(name, v)?;
        }
        unit("albedo", self.albedo)?;
        if !(self.shell_radius - self.shell_thickness > self.core_radius
            && self.shell_radius <= 0.5)
        {
            return Err(SolverError::BadParameter {
                name: "shell_radius",
                value: self.shell_radius,
                reason: "the shell must lie outside the core (shell_radius - shell_thickness > core_radius) and inside the cube (<= 0.5)",
            });
        }
        let grid = Grid::cube(self.n, 1.0)?;
        let sigma_t = grid.sample(|p| {
            let r = dist(p, [0.5; 3]);
            if r <= self.core_radius {
                self.core_sigma
            } else if r >= self.shell_radius - self.shell_thickness && r <= self.shell_radius {
                self.shell_sigma
            } else {
                0.0
            }
        });
        let albedo = sigma_t
            .iter()
            .map(|&s| if s > 0.0 { self.albedo } else { 0.0 })
            .collect();
        let n = grid.len();
        Medium::new(grid, sigma_t, albedo, vec![0.0; n])
    }
}

/// A rising plume with blackbody emission (FLD Fig 9 analog; the paper's fluid simulation
/// is not available, so the fields are procedural). With ρ the distance from the vertical
/// axis through (0.5, 0.5), h = (z − 0.1)/0.8 ∈ [0, 1] the height along the plume and
/// w(h) = 0.07 + 0.18·h its width:
/// * density σt = `sigma_max`·exp(−(ρ/w)²)·clamp(0.55 + 0.7·fbm(`frequency`·(x, y, z − h)), 0, 1)
///   for 0 ≤ h ≤ 1 (faded over the last 10 % at both ends), 0 elsewhere;
/// * temperature T = `t_ambient` + (`t_max` − `t_ambient`)·exp(−(ρ/(0.6 w))²)·(1 − 0.7h):
///   hottest in the core near the base, cooling upwards and outwards;
/// * emission j_c = `emission_scale`·(σt/`sigma_max`)·B(λ_c, T)/B(λ_G, `t_max`) per channel,
///   with Planck's law B(λ, T) = 2hc²/λ⁵ / (e^{hc/(λ k T)} − 1) at λ_R = 610 nm,
///   λ_G = 550 nm, λ_B = 465 nm. Emission follows density (soot) rather than Kirchhoff's
///   σa·B, since the paper's plume has albedo 1 (σa = 0) and still glows.
///
/// Albedo `albedo` (default 0.95; the paper uses 1.0, which this accepts). The monochrome
/// medium ([`Generator::generate`]) is the G channel.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Plume {
    /// Voxels per axis (default 64).
    pub n: usize,
    /// Noise seed (default 2).
    pub seed: u64,
    /// Largest σt (default 30).
    pub sigma_max: f64,
    /// Albedo (default 0.95).
    pub albedo: f64,
    /// Noise frequency (default 6).
    pub frequency: f64,
    /// Peak temperature in kelvin (default 1800).
    pub t_max: f64,
    /// Ambient temperature in kelvin (default 500).
    pub t_ambient: f64,
    /// Emission of the G channel at full density and `t_max` (default 200).
    pub emission_scale: f64,
}

impl Default for Plume {
    fn default() -> Self {
        Self {
            n: 64,
            seed: 2,
            sigma_max: 30.0,
            albedo: 0.95,
            frequency: 6.0,
            t_max: 1800.0,
            t_ambient: 500.0,
            emission_scale: 200.0,
        }
    }
}

/// Wavelengths of the R, G, B channels in metres.
pub const RGB_WAVELENGTHS: [f64; 3] = [610e-9, 550e-9, 465e-9];

/// Planck's spectral radiance B(λ, T) in W·sr⁻¹·m⁻³.
pub fn planck(lambda: f64, t: f64) -> f64 {
    const H: f64 = 6.626_070_15e-34;
    const C: f64 = 299_792_458.0;
    const K: f64 = 1.380_649e-23;
    if t <= 0.0 {
        return 0.0;
    }
    2.0 * H * C * C / lambda.powi(5) / (H * C / (lambda * K * t)).exp_m1()
}

impl Plume {
    fn fields(&self) -> Result<(Grid, Vec<f64>, Vec<f64>), SolverError> {
        for (name, v) in [
            ("sigma_max", self.sigma_max),
            ("frequency", self.frequency),
            ("t_max", self.t_max),
            ("t_ambient", self.t_ambient),
        ] {
            positive(name, v)?;
        }
        unit("albedo", self.albedo)?;
        if !(self.emission_scale.is_finite() && self.emission_scale >= 0.0) {
            return Err(SolverError::BadParameter {
                name: "emission_scale",
                value: self.emission_scale,
                reason: "must be finite and >= 0",
            });
        }
        let grid = Grid::cube(self.n, 1.0)?;
        let noise = Perlin::new(self.seed);
        let mut sigma = Vec::with_capacity(grid.len());
        let mut temp = Vec::with_capacity(grid.len());
        for p in grid.sample(|p| p) {
            let h = (p[2] - 0.1) / 0.8;
            let rho = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)).sqrt();
            let w = 0.07 + 0.18 * h.clamp(0.0, 1.0);
            let (s, t) = if (0.0..=1.0).contains(&h) {
                let ends = smoothstep(h / 0.1) * smoothstep((1.0 - h) / 0.1);
                let q = [p[0], p[1], p[2] - h].map(|x| self.frequency * x);
                let puff = (0.55 + 0.7 * noise.fbm(q, 4)).clamp(0.0, 1.0);
                let s = self.sigma_max * (-(rho / w).powi(2)).exp() * puff * ends;
                let t = self.t_ambient
                    + (self.t_max - self.t_ambient)
                        * (-(rho / (0.6 * w)).powi(2)).exp()
                        * (1.0 - 0.7 * h);
                (s, t)
            } else {
                (0.0, self.t_ambient)
            };
            sigma.push(s);
            temp.push(t);
        }
        Ok((grid, sigma, temp))
    }

    fn channel(
        &self,
        grid: Grid,
        sigma: &[f64],
        temp: &[f64],
        c: usize,
    ) -> Result<Medium<f64>, SolverError> {
        let norm = planck(RGB_WAVELENGTHS[1], self.t_max);
        let emission = sigma
            .iter()
            .zip(temp)
            .map(|(&s, &t)| {
                self.emission_scale * (s / self.sigma_max) * planck(RGB_WAVELENGTHS[c], t) / norm
            })
            .collect();
        let albedo = sigma
            .iter()
            .map(|&s| if s > 0.0 { self.albedo } else { 0.0 })
            .collect();
        Medium::new(grid, sigma.to_vec(), albedo, emission)
    }
}

impl Generator for Plume {
    const NAME: &'static str = "plume";
    const DESCRIPTION: &'static str = "FLD Fig 9 analog: rising plume, blackbody emission per RGB channel (n, seed, sigma_max, albedo, frequency, t_max, t_ambient, emission_scale)";
    fn generate(&self) -> Result<Medium<f64>, SolverError> {
        let (g, s, t) = self.fields()?;
        self.channel(g, &s, &t, 1)
    }
    fn generate_channels(&self) -> Result<Option<[Medium<f64>; 3]>, SolverError> {
        let (g, s, t) = self.fields()?;
        Ok(Some([
            self.channel(g, &s, &t, 0)?,
            self.channel(g, &s, &t, 1)?,
            self.channel(g, &s, &t, 2)?,
        ]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planck_peaks_where_wien_says_and_colours_a_flame_red() {
        // Wien: λ_max·T = 2.897771955e-3 m·K.
        let t = 5000.0;
        let lmax = 2.897_771_955e-3 / t;
        let b = |l: f64| planck(l, t);
        assert!(b(lmax) > b(0.98 * lmax) && b(lmax) > b(1.02 * lmax));
        // At plume temperatures R > G > B.
        let [r, g, bl] = RGB_WAVELENGTHS.map(|l| planck(l, 1500.0));
        assert!(r > g && g > bl, "{r} {g} {bl}");
        assert_eq!(planck(550e-9, 0.0), 0.0);
    }

    #[test]
    fn datasets_have_their_documented_structure() {
        let sc = ShellCore {
            n: 32,
            core_radius: 0.15,
            core_sigma: 100.0,
            shell_radius: 0.42,
            shell_thickness: 0.05,
            shell_sigma: 8.0,
            albedo: 0.95,
        }
        .generate()
        .unwrap();
        let g = sc.grid;
        let at = |m: &Medium<f64>, i, j, k| m.sigma_t[g.index(i, j, k)];
        assert_eq!(at(&sc, 16, 16, 16), 100.0);
        assert_eq!(at(&sc, 16, 16, 23), 0.0, "vacuum between core and shell");
        assert_eq!(at(&sc, 16, 16, 28), 8.0, "shell");
        assert_eq!(at(&sc, 0, 0, 0), 0.0);
        let p = Plume {
            n: 24,
            seed: 2,
            sigma_max: 30.0,
            albedo: 0.95,
            frequency: 6.0,
            t_max: 1800.0,
            t_ambient: 500.0,
            emission_scale: 20.0,
        };
        let ch = p.generate_channels().unwrap().unwrap();
        let tot = |m: &Medium<f64>| m.emission.iter().sum::<f64>();
        assert!(tot(&ch[0]) > tot(&ch[1]) && tot(&ch[1]) > tot(&ch[2]));
        assert_eq!(ch[1], p.generate().unwrap());
        assert_eq!(ch[0].sigma_t, ch[2].sigma_t);
        let neb = Nebula::deserialize(toml::Value::Table(toml::Table::new())).unwrap();
        let m = neb.generate().unwrap();
        let frac = m.sigma_t.iter().filter(|&&s| s > 0.0).count() as f64 / m.grid.len() as f64;
        assert!(frac > 0.05 && frac < 0.5, "occupied fraction {frac}");
        assert!(m.sigma_t.contains(&60.0));
        assert!(
            ShellCore::deserialize(toml::Value::Table(toml::Table::new()))
                .map(|mut s| {
                    s.shell_radius = 0.1;
                    s.generate().is_err()
                })
                .unwrap()
        );
    }
}
