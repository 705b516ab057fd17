//! Helpers shared by the experiments' tests: temporary output folders, CSV headers, and the
//! check of a run's promises (every promised file, every promised column in order).
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

pub mod sharding;
pub mod spawn;

use experiments::experiment::ExperimentEntry;
use std::path::{Path, PathBuf};

/// A fresh folder under the temp dir, unique to this test process.
pub fn tmp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("scatterbench-{name}-{}", std::process::id()))
}

/// The header row of a CSV file.
pub fn header(path: &Path) -> Vec<String> {
    experiments::common::csv_header(path).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()))
}

/// `cols` appear in the header of `path`, in this order (other columns may sit between).
pub fn assert_columns(path: &Path, cols: &[&str]) {
    if let Some(p) = missing_columns(path, cols) {
        panic!("{p}");
    }
}

/// The header of `path` is exactly `cols`.
pub fn assert_header(path: &Path, cols: &[&str]) {
    assert_eq!(header(path), cols, "{}", path.display());
}

fn missing_columns(path: &Path, cols: &[&str]) -> Option<String> {
    let h = match experiments::common::csv_header(path) {
        Ok(h) => h,
        Err(e) => return Some(format!("{}: {e:#}", path.display())),
    };
    let mut rest = h.iter();
    for c in cols {
        if !rest.any(|x| x == c) {
            return Some(format!(
                "{} lacks column `{c}` (or has it out of order): header {h:?}, promised {cols:?}",
                path.display()
            ));
        }
    }
    None
}

/// What is wrong with the files of a run of `entry` with flags `argv` in `dir`: each promised
/// file that is missing, each promised CSV column that is not in its header in order.
pub fn broken_promises(entry: &ExperimentEntry, argv: &[String], dir: &Path) -> Vec<String> {
    let promises = match entry.promises(argv) {
        Ok(p) => p,
        Err(e) => return vec![format!("{}: promises: {e:#}", entry.name)],
    };
    let mut problems = Vec::new();
    for p in promises {
        let path = dir.join(&p.file);
        if !path.is_file() {
            problems.push(format!(
                "{}: promised {} was not written",
                entry.name,
                path.display()
            ));
        } else if !p.columns.is_empty() {
            problems
                .extend(missing_columns(&path, &p.columns).map(|m| format!("{}: {m}", entry.name)));
        }
    }
    problems
}
