//! CDA and FLD behind the [`Method`] interface: the registry entries `cda` and `fld[:limiter]`.
//!
//! The method solves FLD Eq 20 (CDA: FLD Eq 12) with zero Dirichlet values on the solve grid's
//! outermost layer (FLD Section 5), source q = the problem's emission field, and stops when
//! R̄/j̄ (FLD Eq 37) < [`Tolerance::rel`]. Its defaults are the pipeline's: ω = 1.8 (measured
//! against 1.0 and 1.5 on `nebula` and `shell_core`, see
//! [`crate::pipeline::PipelineConfig::tolerance`]), θ = 0.5 and the other settings of
//! [`FldConfig::default`]. Parameters: `omega` (SOR factor ω, FLD Eq 36) and `theta` (the
//! under-relaxation of the D update, see the module docs of [`crate::fld`]).

use super::multigrid::MgConfig;
use super::{Boundary, FldConfig, FluxLimiter, Solver, VacuumFace};
use crate::method::{
    AnisotropyScaling, Capabilities, Fluence, LightInput, Method, MethodFamily, Params, Problem,
    Tolerance,
};
use crate::{Backend, Grid, Precision, SolverError};

/// CDA or FLD with one limiter and its solver settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FldMethod {
    /// The solver settings; `tolerance` and `max_iterations` are replaced by the
    /// [`Tolerance`] of each solve.
    pub config: FldConfig,
    /// How each solve runs: red-black SOR (the default), FAS multigrid ([`super::multigrid`],
    /// the variant `:mg`) or [`Solver::Auto`] (the variant `:auto`).
    pub solver: Solver,
    /// How σs is used under an anisotropic phase function (a spec suffix `:similarity`).
    pub anisotropy: AnisotropyScaling,
}

impl FldMethod {
    /// The method with the pipeline's defaults (ω = 1.8) and this limiter.
    pub fn new(limiter: FluxLimiter) -> Self {
        Self {
            config: FldConfig {
                limiter,
                ..FldConfig::default()
            }
            .with_omega(1.8),
            solver: Solver::Sor,
            anisotropy: AnisotropyScaling::default(),
        }
    }

    /// The same method solved by FAS multigrid with default cycle settings.
    pub fn multigrid(self) -> Self {
        self.with_solver(Solver::Multigrid(MgConfig::default()))
    }

    /// Builder: the solver ([`Solver::Auto`] is the variant `:auto`).
    pub fn with_solver(mut self, solver: Solver) -> Self {
        self.solver = solver;
        self
    }

    /// Builder: the face coefficient between medium and vacuum.
    pub fn with_vacuum_face(mut self, f: VacuumFace) -> Self {
        self.config.vacuum_face = f;
        self
    }

    /// Builder: the anisotropy scaling.
    pub fn with_anisotropy(mut self, a: AnisotropyScaling) -> Self {
        self.anisotropy = a;
        self
    }

    /// The solver settings of one solve.
    pub fn config_for(&self, tolerance: &Tolerance) -> FldConfig {
        FldConfig {
            tolerance: Some(tolerance.rel),
            max_iterations: tolerance.max_steps,
            ..self.config.clone()
        }
    }

    fn with_params(mut self, params: &Params) -> Result<Self, SolverError> {
        if let Some(w) = params.get("omega") {
            self.config.omega = w;
        }
        if let Some(t) = params.get("theta") {
            self.config.d_relaxation = t;
        }
        let (krylov, omega) = (params.get("krylov"), params.get("smoother_omega"));
        let (local, fmg) = (params.get("local_sweeps"), params.get("full_multigrid"));
        let named = [
            ("krylov", krylov),
            ("smoother_omega", omega),
            ("local_sweeps", local),
            ("full_multigrid", fmg),
        ];
        if let Some((name, value)) = named.into_iter().find_map(|(n, v)| Some((n, v?))) {
            let bad = |name, value, reason| SolverError::BadParameter {
                name,
                value,
                reason,
            };
            let (Solver::Multigrid(mg) | Solver::Auto(mg)) = &mut self.solver else {
                return Err(bad(name, value, "a multigrid setting (add :mg or :auto)"));
            };
            // A count: a finite non-negative integer (the cast is then exact up to the
            // bounds `MgConfig::validate` checks).
            let count = |name, v: f64, reason| {
                if v.is_finite() && v.fract() == 0.0 && v >= 0.0 {
                    Ok(v as usize)
                } else {
                    Err(bad(name, v, reason))
                }
            };
            if let Some(k) = krylov {
                mg.krylov = count("krylov", k, "the Krylov depth is a non-negative integer")?;
            }
            if let Some(w) = omega {
                mg.smoother_omega = w;
            }
            if let Some(l) = local {
                mg.local_sweeps = count(
                    "local_sweeps",
                    l,
                    "the local relaxation's sweeps are a non-negative integer",
                )?;
            }
            if let Some(f) = fmg {
                mg.full_multigrid = match f {
                    0.0 => false,
                    1.0 => true,
                    _ => return Err(bad("full_multigrid", f, "a switch: 0 or 1")),
                };
            }
            // The bounds are `MgConfig::validate`'s.
            mg.validate()?;
        }
        self.config.validate()?;
        Ok(self)
    }
}

impl Method for FldMethod {
    fn name(&self) -> String {
        let base = match self.config.limiter {
            FluxLimiter::Cda => "cda".to_string(),
            l => format!("fld:{l}"),
        };
        let base = match self.anisotropy {
            AnisotropyScaling::Paper => base,
            a => format!("{base}:{a}"),
        };
        let base = match self.config.vacuum_face {
            VacuumFace::Paper => base,
            VacuumFace::Marshak => format!("{base}:marshak"),
        };
        match self.solver {
            Solver::Sor => base,
            Solver::Multigrid(_) => format!("{base}:mg"),
            Solver::Auto(_) => format!("{base}:auto"),
        }
    }

    fn anisotropy(&self) -> Option<AnisotropyScaling> {
        Some(self.anisotropy)
    }

    fn vacuum_face(&self) -> VacuumFace {
        self.config.vacuum_face
    }

    fn capabilities(&self) -> Capabilities {
        Capabilities {
            gpu: self.config.vacuum_face == VacuumFace::Paper,
            f64: true,
            volume_source: true,
            anisotropic: false,
            lights: LightInput::Baked,
            conserves_energy: false,
            direct_points: false,
        }
    }

    fn solve(
        &self,
        backend: &Backend<'_>,
        problem: &Problem<'_>,
        tolerance: &Tolerance,
        observer: &mut dyn FnMut(usize, f64),
    ) -> Result<Fluence, SolverError> {
        tolerance.validate()?;
        let cfg = self.config_for(tolerance);
        let scaled = self.anisotropy.apply(problem.medium, problem.phase);
        let medium = scaled.as_ref().unwrap_or(problem.medium);
        super::solve_with(
            backend,
            medium,
            &Boundary::Zero,
            &cfg,
            &self.solver,
            observer,
        )
        .map(|s| s.erase())
        .map_err(|e| match e {
            SolverError::Unsupported(why) => {
                SolverError::Unsupported(format!("{}: {why}", self.name()))
            }
            e => e,
        })
    }

    /// Both solvers in the accuracy atlas (issue 15 item 4): the SOR method (the paper's, the
    /// family's default) has its multigrid twin (`cda:mg`, `fld:lp:mg`) as a setting of its
    /// own; the Marshak face has no multigrid, and the `:mg`/`:auto` variants none.
    fn param_settings(&self) -> Vec<crate::method::ParamSetting> {
        if self.solver != Solver::Sor || self.config.vacuum_face != VacuumFace::Paper {
            return Vec::new();
        }
        let m = self.clone().multigrid();
        vec![crate::method::ParamSetting {
            label: m.name(),
            method: Box::new(m),
            ordinate_set_only: false,
        }]
    }

    fn kernels(&self) -> &'static [&'static crate::gpu::kernel::KernelSpec] {
        &[&super::gpu::SPEC, &super::multigrid::gpu::SPEC]
    }

    fn bytes_per_step(&self, grid: &Grid, precision: Precision) -> usize {
        // Words per voxel and iteration as `CpuFld::bytes_per_iteration` counts them: 7 for
        // a constant limiter (CDA), 9 for FLD (the D update reads and writes more).
        let word = precision.bytes();
        let per_voxel = if self.config.limiter.is_constant() {
            7
        } else {
            9
        };
        grid.len() * per_voxel * word
    }
}

const PARAMS: &[(&str, &str)] = &[
    ("omega", "SOR factor ω ∈ (0, 2) (FLD Eq 36); default 1.8"),
    (
        "theta",
        "under-relaxation θ ∈ (0, 1] of the D update; default 0.5, 1 = FLD Algorithm 1 verbatim",
    ),
    (
        "krylov",
        "multigrid (:mg, :auto) only: depth 0–16 of the Krylov acceleration of the cycles; \
         default 3, 0 = plain cycles",
    ),
    (
        "smoother_omega",
        "multigrid (:mg, :auto) only: ω ∈ (0, 2) of the red-black smoother on every level; \
         default 1.2, 1 = Gauss–Seidel",
    ),
    (
        "local_sweeps",
        "multigrid (:mg, :auto, CPU) only: extra red-black sweeps 0–64, twice per cycle, in a \
         box around each point-like source; default 8, 0 = none",
    ),
    (
        "full_multigrid",
        "multigrid (:mg, :auto, CPU) only: 1 starts from a full-multigrid (nested-iteration) \
         guess, 0 from phi = 0; default 1",
    ),
];

/// Classical diffusion: FLD's solver with the constant limiter 1/3 (FLD Eq 12, Section 6.1).
pub const CDA: MethodFamily = MethodFamily {
    name: "cda",
    title: "classical diffusion (CDA), red-black SOR",
    paper: "Koerner et al., Flux-Limited Diffusion (FLD Eqs 11–12, 26–27, 30–37, Algorithm 1)",
    variants: "[paper|similarity][:marshak][:mg|:auto]",
    params: PARAMS,
    build: |variant, params| {
        let (_, a, face, solver) = options(variant, false)?;
        let m = FldMethod::new(FluxLimiter::Cda)
            .with_anisotropy(a)
            .with_vacuum_face(face)
            .with_solver(solver);
        Ok(Box::new(m.with_params(params)?))
    },
};

/// Flux-limited diffusion with one of the five limiters of FLD Table 2 (default
/// Levermore–Pomraning, the paper's choice).
pub const FLD: MethodFamily = MethodFamily {
    name: "fld",
    title: "flux-limited diffusion (FLD), red-black SOR",
    paper: "Koerner et al., Flux-Limited Diffusion (FLD Eqs 15–20, Table 2, Algorithm 1)",
    variants: "lp|sum|max|kershaw|larsen<n>[:paper|similarity][:marshak][:mg|:auto]",
    params: PARAMS,
    build: |variant, params| {
        let (limiter, a, face, solver) = options(variant, true)?;
        let limiter = match limiter {
            None => FluxLimiter::LevermorePomraning,
            Some(v) => v.trim().parse()?,
        };
        let m = FldMethod::new(limiter)
            .with_anisotropy(a)
            .with_vacuum_face(face)
            .with_solver(solver);
        Ok(Box::new(m.with_params(params)?))
    },
};

/// Splits a `cda`/`fld` variant into (limiter, anisotropy scaling, vacuum face, solver):
/// tokens separated by `:`, where `mg` selects multigrid, `auto` [`Solver::Auto`],
/// `paper`/`similarity` the scaling, `marshak` the Marshak vacuum face, and (for `fld`,
/// first) any other token the limiter. `marshak` with `mg` is an error (multigrid has the
/// paper's face only; `marshak:auto` solves by SOR), and so are `mg` and `auto` together.
fn options(
    variant: Option<&str>,
    has_limiter: bool,
) -> Result<(Option<String>, AnisotropyScaling, VacuumFace, Solver), SolverError> {
    let mut limiter = None;
    let mut scaling = AnisotropyScaling::default();
    let mut face = VacuumFace::Paper;
    let (mut mg, mut auto) = (false, false);
    for (k, tok) in variant.unwrap_or("").split(':').enumerate() {
        let t = tok.trim();
        if t.is_empty() && variant.is_none() {
            continue;
        }
        if t.eq_ignore_ascii_case("mg") {
            mg = true;
        } else if t.eq_ignore_ascii_case("auto") {
            auto = true;
        } else if t.eq_ignore_ascii_case("marshak") {
            face = VacuumFace::Marshak;
        } else if let Some(a) = AnisotropyScaling::parse(t) {
            scaling = a;
        } else if has_limiter && k == 0 {
            limiter = Some(t.to_string());
        } else {
            return Err(SolverError::UnknownName {
                what: if has_limiter {
                    "variant of fld (after the limiter: paper, similarity, marshak, mg, auto)"
                } else {
                    "variant of cda"
                },
                got: t.to_string(),
                known: if has_limiter {
                    "lp, sum, max, kershaw, larsen<n>, then paper|similarity, marshak and/or \
                     mg|auto"
                        .into()
                } else {
                    "paper, similarity, marshak, mg, auto".into()
                },
            });
        }
    }
    if mg && face == VacuumFace::Marshak {
        return Err(SolverError::UnknownName {
            what: "variant combination (multigrid has the paper's vacuum face only)",
            got: "marshak:mg".into(),
            known: "marshak without mg, or mg without marshak".into(),
        });
    }
    if mg && auto {
        return Err(SolverError::UnknownName {
            what: "variant combination (one solver: mg or auto)",
            got: "mg:auto".into(),
            known: "mg, auto, or neither (SOR)".into(),
        });
    }
    let solver = if mg {
        Solver::Multigrid(MgConfig::default())
    } else if auto {
        Solver::Auto(MgConfig::default())
    } else {
        Solver::Sor
    };
    Ok((limiter, scaling, face, solver))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::method::{self, Problem};
    use crate::scene::Phase;
    use crate::{Grid, Medium};

    #[test]
    fn the_scaling_variant_parses_and_round_trips() {
        for (spec, name) in [
            ("cda", "cda"),
            ("cda:paper", "cda"),
            ("CDA:Similarity", "cda:similarity"),
            ("fld:lp:similarity", "fld:lp:similarity"),
            ("fld:kershaw:paper", "fld:kershaw"),
        ] {
            let m = method::parse(spec).unwrap();
            assert_eq!(m.name(), name, "{spec}");
            assert_eq!(method::parse(&m.name()).unwrap().name(), name);
        }
        assert!(method::parse("cda:bogus").is_err());
        assert!(method::parse("fld:lp:bogus").is_err());
    }

    /// `:marshak` selects the Marshak vacuum face, round-trips, runs on the CPU only and not
    /// with multigrid (a typed error, not a panic).
    #[test]
    fn the_marshak_variant_parses_and_says_where_it_runs() {
        for (spec, name) in [
            ("cda:marshak", "cda:marshak"),
            ("FLD:LP:Marshak", "fld:lp:marshak"),
            (
                "fld:kershaw:similarity:marshak",
                "fld:kershaw:similarity:marshak",
            ),
        ] {
            let m = method::parse(spec).unwrap();
            assert_eq!(m.name(), name);
            assert_eq!(method::parse(&m.name()).unwrap().name(), name);
            assert_eq!(m.vacuum_face(), VacuumFace::Marshak);
            assert!(!m.capabilities().gpu);
        }
        assert_eq!(
            method::parse("cda").unwrap().vacuum_face(),
            VacuumFace::Paper
        );
        assert!(method::parse("cda:marshak:mg").is_err());
        assert!(method::parse("fld:lp:mg:marshak").is_err());
    }

    /// The similarity variant solves the scaled medium: at albedo 1 and g = 0.9, σt' = σt/10;
    /// its φ equals the paper variant's φ on a medium with σt/10 (same arithmetic), and
    /// differs from the paper variant on the original medium.
    #[test]
    fn similarity_solves_the_transport_scaled_medium() {
        let grid = Grid::new([12; 3], 0.1).unwrap();
        let mut m = Medium::<f64>::homogeneous(grid, 20.0, 1.0).unwrap();
        m.emission = vec![1.0; grid.len()];
        let mut scaled = m.clone();
        scaled.sigma_t.iter_mut().for_each(|s| *s *= 0.1);
        let hg = Phase::HenyeyGreenstein { g: 0.9 };
        let tol = Tolerance::rel(1e-8);
        let be = Backend::Cpu(Precision::F64);
        let run = |spec: &str, med: &Medium<f64>| {
            let p = Problem {
                medium: med,
                lights: &[],
                phase: hg,
            };
            method::parse(spec)
                .unwrap()
                .solve(&be, &p, &tol, &mut |_, _| {})
                .unwrap()
        };
        let sim = run("cda:similarity", &m);
        let paper_scaled = run("cda", &scaled);
        let paper = run("cda", &m);
        let rel = |a: &[f64], b: &[f64]| {
            let n: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
            (n / b.iter().map(|y| y * y).sum::<f64>()).sqrt()
        };
        assert!(rel(&sim.phi, &paper_scaled.phi) < 1e-12);
        // A tenth of σt: D is 10× larger and φ about 10× smaller than the paper variant's.
        assert!(rel(&sim.phi, &paper.phi) > 0.1);
    }
}
