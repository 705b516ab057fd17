//! The host↔WGSL contract of every GPU kernel, checked with naga on the CPU (no GPU needed):
//! each [`KernelSpec`] of `solvers::gpu::kernel::specs()` against the WGSL it carries.
//!
//! * every declared binding is a WGSL global of that name at `@group(0) @binding(i)` (i its
//!   position in the spec) with the declared access, and no WGSL binding is undeclared;
//! * every declared entry point is a compute entry point, every declared override exists;
//! * every uniform's WGSL struct has the Rust `#[repr(C)]` struct's size, and the same
//!   members (by name, in order) at the same offsets (`naga::proc::Layouter`).
//!
//! A reordered field or binding on either side fails here instead of giving wrong numbers on
//! the GPU only.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use naga::{AddressSpace, StorageAccess, TypeInner};
use solvers::gpu::kernel::{Access, KernelSpec, StructLayout, specs};

/// Every mismatch between `spec` and its WGSL, one line each.
fn mismatches(spec: &KernelSpec) -> Vec<String> {
    let module = match naga::front::wgsl::parse_str(spec.source) {
        Ok(m) => m,
        Err(e) => return vec![e.emit_to_string(spec.source)],
    };
    let mut layouter = naga::proc::Layouter::default();
    if let Err(e) = layouter.update(module.to_ctx()) {
        return vec![format!("layout: {e}")];
    }
    let mut out = Vec::new();
    let globals: Vec<_> = module
        .global_variables
        .iter()
        .filter_map(|(_, g)| g.binding.as_ref().map(|b| (g, b)))
        .collect();
    for (index, (name, access)) in spec.bindings.iter().enumerate() {
        let Some((global, binding)) = globals
            .iter()
            .find(|(g, _)| g.name.as_deref() == Some(*name))
        else {
            out.push(format!(
                "binding {index} `{name}` ({access:?}) is declared but the WGSL has no binding \
                 named `{name}`"
            ));
            continue;
        };
        if (binding.group, binding.binding) != (0, index as u32) {
            out.push(format!(
                "`{name}` is binding {index} in the spec but @group({}) @binding({}) in the WGSL",
                binding.group, binding.binding
            ));
        }
        let wgsl = match global.space {
            AddressSpace::Uniform => Some(Access::Uniform),
            AddressSpace::Storage { access } if access == StorageAccess::LOAD => Some(Access::Read),
            AddressSpace::Storage { access }
                if access.contains(StorageAccess::LOAD | StorageAccess::STORE) =>
            {
                Some(Access::ReadWrite)
            }
            _ => None,
        };
        if wgsl != Some(*access) {
            out.push(format!(
                "`{name}` is declared {access:?} but the WGSL has var<{:?}>",
                global.space
            ));
        }
        if *access == Access::Uniform {
            match spec.uniforms.iter().find(|(n, _)| n == name) {
                Some((_, rust)) => {
                    out.extend(struct_mismatches(name, rust, &module, &layouter, global.ty))
                }
                None => out.push(format!(
                    "uniform `{name}` has no Rust struct layout in the spec's `uniforms`"
                )),
            }
        }
    }
    for (global, binding) in &globals {
        let name = global.name.as_deref().unwrap_or("?");
        if !spec.bindings.iter().any(|(n, _)| *n == name) {
            out.push(format!(
                "the WGSL binds `{name}` at @group({}) @binding({}) but the spec does not \
                 declare it",
                binding.group, binding.binding
            ));
        }
    }
    for (name, _) in spec.uniforms {
        if !spec
            .bindings
            .iter()
            .any(|(n, a)| n == name && *a == Access::Uniform)
        {
            out.push(format!(
                "`uniforms` lists `{name}`, which is not a uniform binding"
            ));
        }
    }
    for entry in spec.entries {
        let found = module
            .entry_points
            .iter()
            .any(|e| e.name == *entry && e.stage == naga::ShaderStage::Compute);
        if !found {
            out.push(format!(
                "entry point `{entry}` is not a @compute fn of the WGSL"
            ));
        }
    }
    for constant in spec.constants {
        if !module
            .overrides
            .iter()
            .any(|(_, o)| o.name.as_deref() == Some(*constant))
        {
            out.push(format!("override constant `{constant}` is not in the WGSL"));
        }
    }
    out
}

/// Mismatches between the Rust layout `rust` and the WGSL struct type `ty` of binding `name`.
fn struct_mismatches(
    name: &str,
    rust: &StructLayout,
    module: &naga::Module,
    layouter: &naga::proc::Layouter,
    ty: naga::Handle<naga::Type>,
) -> Vec<String> {
    let wgsl_name = module.types[ty].name.as_deref().unwrap_or("?");
    let TypeInner::Struct { members, .. } = &module.types[ty].inner else {
        return vec![format!("uniform `{name}` is not a struct in the WGSL")];
    };
    let mut out = Vec::new();
    let size = layouter[ty].size as usize;
    if size != rust.size {
        out.push(format!(
            "`{name}`: WGSL struct {wgsl_name} is {size} bytes but Rust {} is {}",
            rust.rust, rust.size
        ));
    }
    let wgsl: Vec<(&str, usize)> = members
        .iter()
        .map(|m| (m.name.as_deref().unwrap_or("?"), m.offset as usize))
        .collect();
    for (i, (field, offset)) in rust.members.iter().enumerate() {
        match wgsl.iter().position(|(n, _)| n == field) {
            None => out.push(format!(
                "`{name}`: Rust {}.{field} (offset {offset}) has no member in WGSL {wgsl_name}",
                rust.rust
            )),
            Some(j) if wgsl[j].1 != *offset || j != i => out.push(format!(
                "`{name}`: {field} is member {i} at offset {offset} in Rust {} but member {j} \
                 at offset {} in WGSL {wgsl_name}",
                rust.rust, wgsl[j].1
            )),
            Some(_) => {}
        }
    }
    for (field, offset) in &wgsl {
        if !rust.members.iter().any(|(n, _)| n == field) {
            out.push(format!(
                "`{name}`: WGSL {wgsl_name}.{field} (offset {offset}) has no field in Rust {}",
                rust.rust
            ));
        }
    }
    out
}

#[test]
fn every_kernel_spec_matches_its_wgsl() {
    let specs = specs();
    let labels: Vec<&str> = specs.iter().map(|s| s.label).collect();
    // Every shader in the crate is declared by some spec (a method's through
    // `Method::kernels`), so a new kernel cannot skip the contract. A file without an entry
    // point is a library (`limiter.wgsl`): some spec's source must contain it verbatim.
    fn wgsl_files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                wgsl_files(&p, out);
            } else if p.extension().is_some_and(|x| x == "wgsl") {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    wgsl_files(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
        &mut files,
    );
    assert!(files.len() >= 3, "{files:?}");
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(path).unwrap();
        if !text.contains("@compute") {
            assert!(
                specs.iter().any(|s| s.source.contains(&text)),
                "{name} (no entry point) is prepended to no KernelSpec's source"
            );
            continue;
        }
        assert!(
            labels.contains(&name.as_str()),
            "{name} has no KernelSpec in gpu::kernel::specs() ({labels:?}); declare it in the method's `kernels()`"
        );
    }
    for expected in ["fld.wgsl", "lbm.wgsl", "copy.wgsl", "multigrid.wgsl"] {
        assert!(labels.contains(&expected), "{expected}: {labels:?}");
    }
    let mut failures = Vec::new();
    for spec in specs {
        assert!(!spec.bindings.is_empty() && !spec.entries.is_empty());
        for m in mismatches(spec) {
            failures.push(format!("{}: {m}", spec.label));
        }
    }
    assert!(
        failures.is_empty(),
        "host and WGSL disagree:\n{}",
        failures.join("\n")
    );
}

/// Every uniform struct has at least one member checked, and the checker does catch a
/// reordered member and a swapped binding (on a copy of the FLD shader, edited here).
#[test]
fn the_checker_catches_a_reordered_member_and_a_swapped_binding() {
    let fld = specs().into_iter().find(|s| s.label == "fld.wgsl").unwrap();
    let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };

    let members = fld.source.replacen(
        "    omega: f32,\n    one_minus_omega: f32,",
        "    one_minus_omega: f32,\n    omega: f32,",
        1,
    );
    assert_ne!(members, fld.source, "the edit must apply");
    let spec = KernelSpec {
        source: leak(members),
        ..*fld
    };
    let found = mismatches(&spec);
    assert!(
        found.iter().any(|m| m.contains("omega is member")),
        "{found:?}"
    );

    let swapped = fld
        .source
        .replacen(
            "@binding(3) var<storage, read> sig",
            "@binding(4) var<storage, read> sig",
            1,
        )
        .replacen(
            "@binding(4) var<storage, read> absorb",
            "@binding(3) var<storage, read> absorb",
            1,
        );
    assert_ne!(swapped, fld.source, "the edit must apply");
    let spec = KernelSpec {
        source: leak(swapped),
        ..*fld
    };
    let found = mismatches(&spec);
    assert!(
        found.iter().any(|m| m.contains("`sig` is binding 3")),
        "{found:?}"
    );
}
