//! A real OpenVDB file (`scenes/test-data/density-8x6x4.vdb`, written by OpenVDB 10 through
//! Debian's python3-openvdb with `scripts/make-test-vdb.py`) loads through the scene-file path
//! (`[medium] vdb = …`, `grid = "density"`) to the same σt grid and box as the equivalent
//! `.vol`, written here from the script's formula.

#![cfg(feature = "vdb")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

use solvers::scene::{SceneFile, VolGrid, vdb};
use std::path::{Path, PathBuf};

const DIMS: [usize; 3] = [8, 6, 4];

/// The script's values: σ(a, b, c) = (1 + a + 8b + 64c)/64 at the voxel (a, b, c) of the box.
fn sigma(a: usize, b: usize, c: usize) -> f64 {
    (1 + a + 8 * b + 64 * c) as f64 / 64.0
}

fn expected() -> Vec<f64> {
    let mut v = Vec::new();
    for c in 0..DIMS[2] {
        for b in 0..DIMS[1] {
            for a in 0..DIMS[0] {
                v.push(sigma(a, b, c));
            }
        }
    }
    v
}

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/test-data")
}

fn parse(text: &str, dir: &Path) -> SceneFile {
    SceneFile::parse(text, dir, &dir.join("scene.toml")).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_real_vdb_file_reads_to_the_scripts_values() {
    let (dims, values) =
        vdb::read_float_grid(&data_dir().join("density-8x6x4.vdb"), "density").unwrap();
    assert_eq!(dims, DIMS);
    assert_eq!(values, expected());
    let e = vdb::read_float_grid(&data_dir().join("density-8x6x4.vdb"), "smoke").unwrap_err();
    assert!(e.to_string().contains("density"), "{e}");
}

#[test]
fn vdb_and_equivalent_vol_load_to_the_same_sigma_t_grid_and_box() {
    let dir = std::env::temp_dir().join(format!("scatterbench-vdb-file-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vdb_path = data_dir().join("density-8x6x4.vdb").canonicalize().unwrap();
    // The .vol on the box the VDB reader gives: the unit cube scaled by 1/longest axis.
    let dl = 1.0 / 8.0;
    let max = DIMS.map(|n| (n as f64 * dl) as f32);
    let values: Vec<f32> = expected().iter().map(|&v| v as f32).collect();
    VolGrid::new(DIMS, 1, [0.0; 3], max, values)
        .unwrap()
        .write(&dir.join("density.vol"))
        .unwrap();
    let from_vdb = parse(
        &format!(
            "format = 1\n[medium]\nvdb = {:?}\ngrid = \"density\"\nalbedo = 0.8\n",
            vdb_path.display().to_string()
        ),
        &dir,
    );
    let from_vol = parse(
        "format = 1\n[medium]\nfile = \"density.vol\"\nalbedo = 0.8\n",
        &dir,
    );
    let (a, b) = (&from_vdb.scene.medium, &from_vol.scene.medium);
    assert_eq!(a.grid, b.grid);
    assert_eq!(a.grid.n, DIMS);
    assert_eq!(a.grid.origin, [0.0; 3]);
    assert_eq!(a.grid.dl, dl);
    assert_eq!(a.sigma_t, b.sigma_t);
    assert_eq!(a.sigma_t, expected());
    assert_eq!(a.albedo, b.albedo);
    // An explicit box moves both alike.
    let boxed = "min = [-1.0, 0.0, 2.0]\nmax = [1.0, 1.5, 3.0]\n";
    let a = parse(
        &format!(
            "format = 1\n[medium]\nvdb = {:?}\nalbedo = 0.8\n{boxed}",
            vdb_path.display().to_string()
        ),
        &dir,
    );
    let b = parse(
        &format!("format = 1\n[medium]\nfile = \"density.vol\"\nalbedo = 0.8\n{boxed}"),
        &dir,
    );
    assert_eq!(a.scene.medium.grid, b.scene.medium.grid);
    assert_eq!(a.scene.medium.grid.origin, [-1.0, 0.0, 2.0]);
    assert_eq!(a.scene.medium.sigma_t, b.scene.medium.sigma_t);
    std::fs::remove_dir_all(&dir).ok();
}
