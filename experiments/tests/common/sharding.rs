//! Helpers of the sharding tests (`tests/shard.rs`, `tests/slurm.rs`): CSVs compared without
//! their wall-clock columns, and the small atlas both run.

use std::path::Path;

/// The CSV at `path` without the columns `skip`: header and rows as strings.
pub fn csv_without(path: &Path, skip: &[&str]) -> Vec<Vec<String>> {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&i| !skip.contains(&header[i].as_str()))
        .collect();
    let mut out = vec![keep.iter().map(|&i| header[i].clone()).collect()];
    for row in r.records() {
        let row = row.unwrap();
        out.push(keep.iter().map(|&i| row[i].to_string()).collect());
    }
    out
}

/// Flags of a small `accuracy_cost` run: the emissive cloud at 12×12, the path tracer and
/// CDA, a 64-spp reference (5 tasks: the reference, 2 path-tracer points, the quick ladder's
/// CDA setting and CDA's multigrid twin `cda:mg`).
pub fn small_atlas() -> Vec<String> {
    let scene = super::spawn::workspace().join("scenes/emissive_cloud.toml");
    [
        "--quick",
        "--scenes",
        &scene.to_string_lossy(),
        "--methods",
        "pt,cda",
        "--reference-spp",
        "64",
        "--resolution",
        "12,12",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}
