//! What renders an image in the experiments: the path tracer, or the grid pipeline with any
//! method of [`solvers::method::METHODS`]. `render --method`, `renderings --methods` and the
//! atlas parse their method names here, so a newly registered method is available to all of
//! them, with its name in every help text and error.

use anyhow::{Result, anyhow};
use solvers::method::{self, MethodRef, Params};
use solvers::{Backend, Precision};

/// The path tracer's name in `--method` lists.
pub const PATH_TRACER: &str = "pt";

/// A renderer of camera images.
#[derive(Debug, Clone, PartialEq)]
pub enum Renderer {
    /// `reference::pathtracer` on exactly the effects the pipeline would render.
    PathTracer,
    /// `solvers::pipeline` with this multiple-scattering method.
    Pipeline(MethodRef),
}

impl Renderer {
    /// `pt`, or a registered method's name (case-insensitive), with named parameters for
    /// the method (`omega=1.5`; an error for the path tracer).
    pub fn parse_with(spec: &str, params: &Params) -> Result<Self> {
        if spec.trim().eq_ignore_ascii_case(PATH_TRACER) {
            if *params != Params::none() {
                return Err(anyhow!("the path tracer takes no method parameters"));
            }
            return Ok(Renderer::PathTracer);
        }
        method::parse_with(spec, params)
            .map(|m| Renderer::Pipeline(MethodRef::new(m)))
            .map_err(|e| anyhow!("{e}; or `{PATH_TRACER}` (the path tracer)"))
    }

    /// As [`Renderer::parse_with`] without parameters.
    pub fn parse(spec: &str) -> Result<Self> {
        Self::parse_with(spec, &Params::none())
    }

    /// Its canonical name (`pt`, `cda`, `fld:lp`, `lbm`, …).
    pub fn name(&self) -> String {
        match self {
            Renderer::PathTracer => PATH_TRACER.into(),
            Renderer::Pipeline(m) => m.name(),
        }
    }

    /// The path tracer and every registered family with its defaults, in registry order.
    pub fn all() -> Vec<Renderer> {
        let mut v = vec![Renderer::PathTracer];
        for fam in method::METHODS {
            if let Ok(m) = (fam.build)(None, &Params::none()) {
                v.push(Renderer::Pipeline(MethodRef::new(m)));
            }
        }
        v
    }

    /// Whether it runs on `backend` (the path tracer: CPU only; a grid method: its
    /// capabilities, and the GPU computes in f32 only).
    pub fn supports(&self, backend: &Backend<'_>, precision: Precision) -> bool {
        match (self, backend) {
            (Renderer::PathTracer, Backend::Gpu(_)) => false,
            (Renderer::PathTracer, Backend::Cpu(_)) => true,
            (Renderer::Pipeline(_), Backend::Gpu(_)) if precision == Precision::F64 => false,
            (Renderer::Pipeline(m), b) => m.capabilities().supports(b),
        }
    }
}

/// Parses a list of renderer names (comma-separated flags are split by clap).
pub fn parse_list(names: &[String]) -> Result<Vec<Renderer>> {
    if names.is_empty() {
        return Err(anyhow!("the method list is empty; {}", help()));
    }
    names.iter().map(|n| Renderer::parse(n)).collect()
}

/// One line for `--method` help texts: every registered method and `pt`.
pub fn help() -> String {
    format!(
        "methods (case-insensitive): {PATH_TRACER} (path tracer), {}",
        method::names()
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn every_registered_family_and_pt_parse_and_appear_in_help() {
        let h = help();
        for r in Renderer::all() {
            let again = Renderer::parse(&r.name().to_uppercase()).unwrap();
            assert_eq!(again, r);
            let family = r.name();
            let family = family.split(':').next().unwrap();
            assert!(h.contains(family), "{h} lacks {family}");
        }
        let e = Renderer::parse("nope").unwrap_err().to_string();
        assert!(
            e.contains("fld") && e.contains("lbm") && e.contains("pt"),
            "{e}"
        );
        assert!(parse_list(&[]).is_err());
    }
}
