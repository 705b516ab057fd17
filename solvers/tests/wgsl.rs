//! Every `.wgsl` file of the workspace parses and validates with naga, without any GPU. A file
//! whose lines include `// requires: a.wgsl` is validated with `a.wgsl` (a path relative to it)
//! prepended, as its host spec prepends it (`concat!` of both sources).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if path.is_dir() {
            if !name.starts_with('.') && name != "target" && name != "results" {
                wgsl_files(&path, out);
            }
        } else if name.ends_with(".wgsl") {
            out.push(path);
        }
    }
}

#[test]
fn every_wgsl_file_validates_with_naga() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let mut files = Vec::new();
    wgsl_files(root, &mut files);
    assert!(
        files.iter().any(|f| f.ends_with("fld/fld.wgsl")),
        "fld.wgsl not found under {}",
        root.display()
    );
    let mut failures = Vec::new();
    for file in &files {
        let own = std::fs::read_to_string(file).unwrap();
        let mut source = String::new();
        for line in own.lines() {
            if let Some(rest) = line.strip_prefix("// requires: ") {
                let name = rest.split_whitespace().next().unwrap();
                let dep = file.parent().unwrap().join(name);
                source.push_str(&std::fs::read_to_string(&dep).unwrap_or_else(|e| {
                    panic!("{} requires {}: {e}", file.display(), dep.display())
                }));
            }
        }
        source.push_str(&own);
        let module = match naga::front::wgsl::parse_str(&source) {
            Ok(m) => m,
            Err(e) => {
                failures.push(e.emit_to_string_with_path(&source, &file.display().to_string()));
                continue;
            }
        };
        let mut validator = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        );
        if let Err(e) = validator.validate(&module) {
            failures.push(format!("{}: {}", file.display(), e.emit_to_string(&source)));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    eprintln!("validated {} WGSL files", files.len());
}
