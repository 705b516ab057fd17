//! The mutated corpus of the fuzz property tests (`solvers/tests/fuzz_scene.rs`, and
//! `reference/tests/fuzz_render.rs` through `#[path]`): the example scene files of `scenes/`
//! shrunk to test size (generators at n = 12, cameras at 8×8, 16 spp), plus a scene reading a
//! `.vol` written by our own writer, and the mutations applied to them.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use solvers::scene::VolGrid;
use std::path::{Path, PathBuf};

/// The proptest configuration: `cases` cases from a fixed seed, no failure files.
pub fn config(cases: u32, seed: u64) -> Config {
    Config {
        cases,
        failure_persistence: None,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(seed),
        max_shrink_iters: 256,
        ..Config::default()
    }
}

/// The workspace's `scenes/` folder.
pub fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// The `.vol`-backed seed scene (σt from `density.vol` next to it).
pub const VOL_SCENE: &str = r#"format = 1
description = "sigma_t from a .vol written by VolGrid::write"

[medium]
file = "density.vol"
albedo = 0.7
emission = 0.05
density_scale = 2.0

[phase]
type = "hg"
g = 0.3

[[light]]
type = "point"
position = [0.5, 0.5, 1.5]
power = 4.0

[[light]]
type = "directional"
direction = [0.0, 0.3, -1.0]
irradiance = 1.0

[camera]
eye = [0.5, -1.5, 0.5]
target = [0.5, 0.5, 0.5]
up = [0.0, 0.0, 1.0]
projection = "perspective"
fov_y = 40.0
resolution = [8, 8]

[sampler]
spp = 16
seed = 3

[outputs]
write = ["image", "fluence"]

[effects]
exclude = ["anisotropy"]
"#;

/// The `.vol` of [`VOL_SCENE`]: 10³ voxels on the unit cube, a smooth blob, by our writer.
pub fn seed_vol() -> VolGrid {
    let n = 10;
    let mut data = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r2 = [i, j, k]
                    .map(|v| (v as f32 + 0.5) / n as f32 - 0.5)
                    .iter()
                    .map(|d| d * d)
                    .sum::<f32>();
                data.push(8.0 * (-12.0 * r2).exp());
            }
        }
    }
    VolGrid::new([n; 3], 1, [0.0; 3], [1.0; 3], data).unwrap()
}

/// The seed texts: every `scenes/*.toml`, shrunk, then [`VOL_SCENE`].
pub fn seeds() -> Vec<(String, String)> {
    let mut names: Vec<PathBuf> = std::fs::read_dir(scenes_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 5, "the example scenes are the corpus");
    let mut out: Vec<(String, String)> = names
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            let small = text
                .replace("n = 64", "n = 12")
                .replace("n = 32", "n = 12")
                .replace("resolution = [64, 64]", "resolution = [8, 8]")
                .replace("spp = 1024", "spp = 16")
                .replace("spp = 256", "spp = 16")
                .replace("spp = 64", "spp = 16");
            (p.file_name().unwrap().to_string_lossy().into_owned(), small)
        })
        .collect();
    out.push(("vol_scene.toml".into(), VOL_SCENE.into()));
    out
}

/// Values a mutation puts in place of a value: huge (100000 as a grid size or resolution is
/// refused by the size checks of `solvers::budget` before anything is allocated), negative,
/// non-finite, out of range for
/// every integer type, and of every other TOML type.
pub const VALUES: &[&str] = &[
    "0",
    "-1",
    "100000",
    "1e308",
    "-1e308",
    "1e39",
    "nan",
    "inf",
    "-inf",
    "9223372036854775808",
    "9223372036854775807",
    "2147483648",
    "4294967296",
    "1e-300",
    "0.5",
    "\"text\"",
    "true",
    "[]",
    "[1.0, 2.0, 3.0]",
    "[1e308, -1e308, nan]",
    "{}",
    "{ a = 1 }",
    "1979-05-27",
];

/// One mutation of a text.
#[derive(Debug, Clone)]
pub enum Mutation {
    /// XOR one byte with a non-zero mask.
    Flip(Index, u8),
    /// Keep only a prefix.
    Truncate(Index),
    /// Delete a line (a key, a header, …).
    DeleteLine(Index),
    /// Replace the value of a `key = value` line with one of [`VALUES`].
    SwapValue(Index, Index),
    /// Replace a number anywhere (also inside arrays and inline tables) with one of [`VALUES`].
    SwapNumber(Index, Index),
    /// Append a copy of a table (from a `[header]` line to the next header).
    DuplicateTable(Index),
    /// Insert a copy of a line after itself (duplicated key).
    DuplicateLine(Index),
}

/// The mutation strategy.
pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<Index>(), 1u8..=255).prop_map(|(i, m)| Mutation::Flip(i, m)),
        any::<Index>().prop_map(Mutation::Truncate),
        any::<Index>().prop_map(Mutation::DeleteLine),
        (any::<Index>(), any::<Index>()).prop_map(|(l, v)| Mutation::SwapValue(l, v)),
        (any::<Index>(), any::<Index>()).prop_map(|(l, v)| Mutation::SwapNumber(l, v)),
        any::<Index>().prop_map(Mutation::DuplicateTable),
        any::<Index>().prop_map(Mutation::DuplicateLine),
    ]
}

/// Byte ranges of the numbers of a text (runs of digits with sign, point, exponent).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'));
        if starts {
            let s = if i > 0 && b[i - 1] == b'-' { i - 1 } else { i };
            let mut e = i;
            while e < b.len()
                && (b[e].is_ascii_digit()
                    || b[e] == b'.'
                    || b[e] == b'e'
                    || ((b[e] == b'-' || b[e] == b'+') && b[e - 1] == b'e'))
            {
                e += 1;
            }
            out.push((s, e));
            i = e;
        } else {
            i += 1;
        }
    }
    out
}

/// Applies `m` to the bytes of `text`.
pub fn apply(text: &[u8], m: &Mutation) -> Vec<u8> {
    let s = String::from_utf8_lossy(text).into_owned();
    let lines: Vec<&str> = s.split_inclusive('\n').collect();
    match m {
        Mutation::Flip(i, mask) => {
            let mut b = text.to_vec();
            if !b.is_empty() {
                let at = i.index(b.len());
                b[at] ^= mask;
            }
            b
        }
        Mutation::Truncate(i) => text[..i.index(text.len() + 1)].to_vec(),
        Mutation::DeleteLine(i) if !lines.is_empty() => {
            let at = i.index(lines.len());
            let mut l = lines.clone();
            l.remove(at);
            l.concat().into_bytes()
        }
        Mutation::SwapValue(l, v) => {
            let keyed: Vec<usize> = (0..lines.len())
                .filter(|&k| lines[k].contains('=') && !lines[k].trim_start().starts_with('#'))
                .collect();
            if keyed.is_empty() {
                return text.to_vec();
            }
            let at = keyed[l.index(keyed.len())];
            let line = lines[at];
            let eq = line.find('=').unwrap_or(0);
            let mut out: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
            out[at] = format!("{}= {}\n", &line[..eq], VALUES[v.index(VALUES.len())]);
            out.concat().into_bytes()
        }
        Mutation::SwapNumber(l, v) => {
            let nums = numbers(&s);
            if nums.is_empty() {
                return text.to_vec();
            }
            let (a, b) = nums[l.index(nums.len())];
            format!("{}{}{}", &s[..a], VALUES[v.index(VALUES.len())], &s[b..]).into_bytes()
        }
        Mutation::DuplicateTable(i) => {
            let headers: Vec<usize> = (0..lines.len())
                .filter(|&k| lines[k].trim_start().starts_with('['))
                .collect();
            if headers.is_empty() {
                return text.to_vec();
            }
            let h = i.index(headers.len());
            let end = headers.get(h + 1).copied().unwrap_or(lines.len());
            let mut out = s.clone();
            if !out.ends_with('\n') {
                out.push('\n');
            }
            out.push_str(&lines[headers[h]..end].concat());
            out.into_bytes()
        }
        Mutation::DuplicateLine(i) if !lines.is_empty() => {
            let at = i.index(lines.len());
            let mut l: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
            let mut copy = l[at].clone();
            if !copy.ends_with('\n') {
                copy.push('\n');
                l[at].push('\n');
            }
            l.insert(at + 1, copy);
            l.concat().into_bytes()
        }
        _ => text.to_vec(),
    }
}

/// A seed index, then 1–3 mutations.
pub fn mutant() -> impl Strategy<Value = (Index, Vec<Mutation>)> {
    (any::<Index>(), proptest::collection::vec(mutation(), 1..=3))
}

/// A folder with `density.vol` (the seed `.vol`) for the scenes to read, unique per `tag`.
pub fn scene_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("scatterbench-fuzz-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    seed_vol().write(&dir.join("density.vol")).unwrap();
    dir
}

/// A seed index, then 1–2 mild mutations (mostly number swaps) so that most mutants parse and
/// reach the renderers.
pub fn render_mutant() -> impl Strategy<Value = (Index, Vec<Mutation>)> {
    let mild = prop_oneof![
        4 => (any::<Index>(), any::<Index>()).prop_map(|(l, v)| Mutation::SwapNumber(l, v)),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(l, v)| Mutation::SwapValue(l, v)),
        1 => any::<Index>().prop_map(Mutation::DeleteLine),
    ];
    (any::<Index>(), proptest::collection::vec(mild, 1..=2))
}
