//! Which light an image estimate keeps: the path tracer's side of the effect sets that the
//! grid pipeline plans with, so that a grid method and the reference are always compared on
//! exactly the same effects.
//!
//! The **order** of a contribution is the number of real scattering events between the
//! emitter and the camera:
//! * order 0: emission j seen directly (attenuated), a sphere light or the environment seen
//!   through the medium;
//! * order k ≥ 1: light (next-event estimation from a point, directional or sphere light, or
//!   the environment reached after the k-th scattering) or emission scattered k times.
//!
//! "Single scattering" of a grid method (FLD Eq 8's σs·p·L_ri term) is order 1 from lights;
//! its "multiple scattering" (the diffusion φ) is orders ≥ 2 from lights plus orders ≥ 1 from
//! emission; its emission term is order 0 from emission.

/// A set of contributions: an order range and which emitters count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Contributions {
    /// Fewest scattering events a counted contribution has.
    pub min_order: u32,
    /// Most scattering events a counted contribution has (`None`: unlimited, unbiased).
    pub max_order: Option<u32>,
    /// Light from the scene's lights (point, directional, sphere, environment).
    pub lights: bool,
    /// Light from the volume emission j.
    pub emission: bool,
}

impl Default for Contributions {
    fn default() -> Self {
        Self::all()
    }
}

impl Contributions {
    /// Everything: the full, unbiased radiance.
    pub const fn all() -> Self {
        Self {
            min_order: 0,
            max_order: None,
            lights: true,
            emission: true,
        }
    }

    /// Light that scattered at most `k` times, from every emitter (Mitsuba's
    /// `max_depth = k + 1`).
    pub const fn up_to(k: u32) -> Self {
        Self {
            max_order: Some(k),
            ..Self::all()
        }
    }

    /// Light from the lights scattered exactly once.
    pub const fn single_scattering() -> Self {
        Self {
            min_order: 1,
            max_order: Some(1),
            lights: true,
            emission: false,
        }
    }

    /// Light from the lights scattered at least twice.
    pub const fn multiple_scattering() -> Self {
        Self {
            min_order: 2,
            max_order: None,
            lights: true,
            emission: false,
        }
    }

    /// Emission seen directly (attenuated, never scattered).
    pub const fn emission_only() -> Self {
        Self {
            min_order: 0,
            max_order: Some(0),
            lights: false,
            emission: true,
        }
    }

    /// Light from the lights seen directly through the medium (order 0: the environment
    /// and sphere lights; the pipeline's `background`).
    pub const fn background() -> Self {
        Self {
            min_order: 0,
            max_order: Some(0),
            lights: true,
            emission: false,
        }
    }

    /// Emission scattered at least once.
    pub const fn scattered_emission() -> Self {
        Self {
            min_order: 1,
            max_order: None,
            lights: false,
            emission: true,
        }
    }

    /// Whether a contribution of `order` scatterings counts.
    #[inline]
    pub fn admits(&self, order: u32) -> bool {
        order >= self.min_order && self.max_order.is_none_or(|m| order <= m)
    }

    /// Whether light from the lights after `order` scatterings counts.
    #[inline]
    pub fn light(&self, order: u32) -> bool {
        self.lights && self.admits(order)
    }

    /// Whether emission after `order` scatterings counts.
    #[inline]
    pub fn emitted(&self, order: u32) -> bool {
        self.emission && self.admits(order)
    }

    /// Whether a path that has scattered `order` times can still contribute after scattering
    /// again (false once the order range or the emitters are exhausted).
    #[inline]
    pub fn continues_after(&self, order: u32) -> bool {
        (self.lights || self.emission) && self.max_order.is_none_or(|m| order < m)
    }

    /// Checks that the range is not empty.
    pub fn validate(&self) -> Result<(), crate::ReferenceError> {
        if self.max_order.is_some_and(|m| m < self.min_order) {
            return Err(crate::ReferenceError::BadParameter {
                name: "contributions.min_order",
                value: f64::from(self.min_order),
                reason: "exceeds max_order: the order range is empty",
            });
        }
        Ok(())
    }
}
