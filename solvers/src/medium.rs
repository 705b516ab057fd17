//! Medium fields: extinction σt, single-scattering albedo α and emission j (FLD Table 1).

use crate::{Grid, Real, SolverError};

/// The voxelised inputs of a diffusion solve (FLD Section 5): extinction `sigma_t` [1/length],
/// albedo `albedo` ∈ [0, 1] and emission `emission` [power/volume] (the external-light
/// source q_ri is absorbed into `emission`, as the paper does).
#[derive(Debug, Clone, PartialEq)]
pub struct Medium<T> {
    /// The grid all fields live on.
    pub grid: Grid,
    /// Extinction coefficient σt per voxel, ≥ 0 (0 is vacuum).
    pub sigma_t: Vec<T>,
    /// Single-scattering albedo α = σs/σt per voxel, in [0, 1].
    pub albedo: Vec<T>,
    /// Emission j per voxel, ≥ 0.
    pub emission: Vec<T>,
}

impl<T: Real> Medium<T> {
    /// A homogeneous medium without emission.
    pub fn homogeneous(grid: Grid, sigma_t: f64, albedo: f64) -> Result<Self, SolverError> {
        let n = grid.len();
        let m = Self {
            grid,
            sigma_t: vec![T::c(sigma_t); n],
            albedo: vec![T::c(albedo); n],
            emission: vec![T::zero(); n],
        };
        m.validate()?;
        Ok(m)
    }

    /// Builds a medium from fields and validates it.
    pub fn new(
        grid: Grid,
        sigma_t: Vec<T>,
        albedo: Vec<T>,
        emission: Vec<T>,
    ) -> Result<Self, SolverError> {
        let m = Self {
            grid,
            sigma_t,
            albedo,
            emission,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks field sizes and ranges: σt ≥ 0 finite, α ∈ [0, 1], j ≥ 0 finite.
    pub fn validate(&self) -> Result<(), SolverError> {
        let n = self.grid.len();
        for (field, v) in [
            ("sigma_t", &self.sigma_t),
            ("albedo", &self.albedo),
            ("emission", &self.emission),
        ] {
            if v.len() != n {
                return Err(SolverError::FieldSize {
                    field,
                    expected: n,
                    got: v.len(),
                });
            }
        }
        let check =
            |field: &'static str, v: &[T], ok: &dyn Fn(f64) -> bool, range: &'static str| match v
                .iter()
                .position(|x| !ok(x.f()))
            {
                Some(index) => Err(SolverError::FieldValue {
                    field,
                    index,
                    value: v[index].f(),
                    range,
                }),
                None => Ok(()),
            };
        check(
            "sigma_t",
            &self.sigma_t,
            &|x| x.is_finite() && x >= 0.0,
            "[0, ∞)",
        )?;
        check(
            "albedo",
            &self.albedo,
            &|x| (0.0..=1.0).contains(&x),
            "[0, 1]",
        )?;
        check(
            "emission",
            &self.emission,
            &|x| x.is_finite() && x >= 0.0,
            "[0, ∞)",
        )?;
        Ok(())
    }

    /// Root-mean-square emission j̄ over all voxels (FLD Algorithm 1), in `f64`.
    pub fn rms_emission(&self) -> f64 {
        let s: f64 = self.emission.iter().map(|j| j.f() * j.f()).sum();
        (s / self.emission.len() as f64).sqrt()
    }

    /// The same medium converted to another precision.
    pub fn cast<U: Real>(&self) -> Medium<U> {
        let conv = |v: &[T]| v.iter().map(|x| U::c(x.f())).collect();
        Medium {
            grid: self.grid,
            sigma_t: conv(&self.sigma_t),
            albedo: conv(&self.albedo),
            emission: conv(&self.emission),
        }
    }
}
