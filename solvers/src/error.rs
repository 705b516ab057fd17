//! Typed errors for everything a user can get wrong when setting up a solve, and the
//! helpers their messages share: [`Compact`] numbers, [`indefinite`] articles and
//! [`chain`] for an error with its causes in one line.

use std::fmt;
use thiserror::Error;

/// A float as messages print it: the shortest digits that round-trip, in positional
/// notation for 10⁻⁴ ≤ |x| < 10⁶ (and 0), otherwise in whichever of positional and
/// exponent notation is shorter (ties: positional). So `1e300` stays `1e300` rather than
/// 301 digits, `1e-7` is `1e-7`, `1234567` is `1234567` and `0.5` is `0.5`; `inf`, `-inf`
/// and `NaN` print as Rust prints them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compact(pub f64);

impl fmt::Display for Compact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        let plain = format!("{x}");
        if !x.is_finite() || x == 0.0 || (1e-4..1e6).contains(&x.abs()) {
            return f.write_str(&plain);
        }
        let exp = format!("{x:e}");
        f.write_str(if exp.len() < plain.len() {
            &exp
        } else {
            &plain
        })
    }
}

/// `word` with its indefinite article: "an environment", "a point" (by the first letter:
/// "an" before a vowel).
pub fn indefinite(word: &str) -> String {
    let vowel = word
        .chars()
        .next()
        .is_some_and(|c| "aeiouAEIOU".contains(c));
    format!("{} {word}", if vowel { "an" } else { "a" })
}

/// An error and its causes ([`std::error::Error::source`]) in one line, joined by `: `, for
/// messages that embed another error as text (an error type that keeps its cause as
/// `source` does not repeat it in its own `Display`).
pub fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cause = c.source();
    }
    s
}

/// Errors returned by the solvers. Every variant says which input is wrong and why.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SolverError {
    /// A grid needs at least 3 voxels per axis: one interior voxel between two boundary layers.
    #[error(
        "grid dimension {axis} = {n} is too small: at least 3 voxels are needed (one interior voxel between the two Dirichlet boundary layers)"
    )]
    GridTooSmall {
        /// Axis name, `x`, `y` or `z`.
        axis: char,
        /// The offending size.
        n: usize,
    },
    /// The voxel size must be finite and positive.
    #[error("voxel size must be finite and > 0, got {}", Compact(*.0))]
    BadVoxelSize(f64),
    /// The grid has more voxels than fit in memory addressing.
    #[error("grid {nx}x{ny}x{nz} has too many voxels")]
    GridTooLarge {
        /// Voxels along x.
        nx: usize,
        /// Voxels along y.
        ny: usize,
        /// Voxels along z.
        nz: usize,
    },
    /// A field has the wrong number of values for its grid.
    #[error("field `{field}` has {got} values but the grid has {expected} voxels")]
    FieldSize {
        /// Field name.
        field: &'static str,
        /// Expected number of values (voxels).
        expected: usize,
        /// Actual number of values.
        got: usize,
    },
    /// A field value is outside its physical range (negative extinction, albedo above 1, NaN …).
    #[error("field `{field}` at voxel {index} is {}, which is outside {range}", Compact(*.value))]
    FieldValue {
        /// Field name.
        field: &'static str,
        /// Linear voxel index (x fastest).
        index: usize,
        /// The offending value.
        value: f64,
        /// The allowed range, in words.
        range: &'static str,
    },
    /// A solver parameter is out of range.
    #[error("parameter `{name}` = {} is invalid: {reason}", Compact(*.value))]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// An explicit time step above the stability bound it is checked against (the RDE's
    /// fixed r above the Gershgorin bound, or above thesis Eq 4.9 in the strict mode).
    #[error("parameter `{name}` = {value} exceeds {criterion} = {bound}")]
    StepAboveBound {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The bound it exceeds.
        bound: f64,
        /// Which bound, in words.
        criterion: &'static str,
    },
    /// The flux limiter name could not be parsed.
    #[error(
        "unknown flux limiter `{0}`; expected one of cda, sum, max, kershaw, larsen<n> (e.g. larsen2), lp"
    )]
    UnknownLimiter(String),
    /// A name (method, method parameter, precision …) that is not one of those that exist.
    #[error("unknown {what} `{got}`; known: {known}")]
    UnknownName {
        /// What kind of name.
        what: &'static str,
        /// The name given.
        got: String,
        /// The names that exist.
        known: String,
    },
    /// A GPU backend failure (no adapter, grid too large for the device, device lost …).
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// A run would need more memory than the budget allows ([`crate::budget`]).
    #[error(transparent)]
    TooLarge(#[from] crate::budget::TooLarge),
    /// The requested combination of backend and precision does not exist.
    #[error("{0}")]
    Unsupported(String),
    /// A method that takes the lights itself ([`crate::method::LightInput::Direct`]) was
    /// given a light of a kind it does not take.
    #[error(
        "method {method} takes directional and environment lights only; light {index} is {} light (exclude its effects, or use a method that takes baked lights)",
        crate::error::indefinite(kind)
    )]
    LightKind {
        /// The method's name.
        method: String,
        /// Index of the light in [`crate::method::Problem::lights`].
        index: usize,
        /// Its kind (`point`, `sphere`).
        kind: &'static str,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compact_numbers_are_short_and_round_trip() {
        let cases = [
            (1e300, "1e300"),
            (-1e300, "-1e300"),
            (1e12, "1e12"),
            (1e-7, "1e-7"),
            (2.5e-9, "2.5e-9"),
            (1234567.0, "1234567"),
            (123456.75, "123456.75"),
            (0.5, "0.5"),
            (0.0001, "0.0001"),
            (0.0, "0"),
            (3.0, "3"),
            (f64::INFINITY, "inf"),
            (f64::NEG_INFINITY, "-inf"),
            (f64::NAN, "NaN"),
            (f64::MAX, "1.7976931348623157e308"),
            (f64::MIN_POSITIVE, "2.2250738585072014e-308"),
        ];
        for (x, want) in cases {
            let got = Compact(x).to_string();
            assert_eq!(got, want, "{x:?}");
            if x.is_finite() {
                assert_eq!(
                    got.parse::<f64>().ok(),
                    Some(x),
                    "{got} does not round-trip"
                );
            }
        }
        let e = SolverError::BadParameter {
            name: "tau",
            value: 1e300,
            reason: "must be small",
        };
        assert_eq!(
            e.to_string(),
            "parameter `tau` = 1e300 is invalid: must be small"
        );
    }

    #[test]
    fn articles_follow_the_first_letter() {
        assert_eq!(indefinite("environment"), "an environment");
        assert_eq!(indefinite("sphere"), "a sphere");
        assert_eq!(indefinite("Orthographic"), "an Orthographic");
        assert_eq!(indefinite(""), "a ");
        let e = crate::pipeline::PipelineError::UnsupportedLight {
            index: 1,
            kind: "environment",
        };
        assert!(
            e.to_string()
                .starts_with("light 1 is an environment light,"),
            "{e}"
        );
    }

    #[test]
    fn chain_joins_the_causes_once() {
        #[derive(Debug, Error)]
        #[error("reading x.vol")]
        struct Outer(#[source] std::io::Error);
        let e = Outer(std::io::Error::new(std::io::ErrorKind::NotFound, "gone"));
        assert_eq!(chain(&e), "reading x.vol: gone");
    }
}
