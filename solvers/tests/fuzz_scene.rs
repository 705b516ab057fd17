//! Property-based fuzzing of the scene-file parser and the `.vol` reader (issue 13, item 8).
//!
//! Corpus: the example scenes of `scenes/` (shrunk to test size, see `fuzz_corpus`) and a scene
//! reading a `.vol` written by our own writer; mutations: byte flips, truncation, line (key)
//! deletion, value swaps to huge / negative / non-finite numbers and other TOML types,
//! duplicated tables and keys; `.vol` files also get header fields set to hostile values.
//! Property: no panic; either an error that is located (a line or a field path, and the
//! file's name in the message) or a scene whose every channel passes `Scene::validate`.
//! Fixed seeds, no failure files: the same cases on every run.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::fuzz_corpus;

use fuzz_corpus::{Mutation, apply, config, mutant, scene_dir, seed_vol, seeds};
use proptest::prelude::*;
use proptest::sample::Index;
use solvers::scene::{SceneFile, SceneFileError, VolGrid};
use std::path::Path;

/// The property for one parse: a located error, or a scene that validates.
fn check_parse(
    result: Result<SceneFile, SceneFileError>,
    file: &Path,
) -> Result<(), TestCaseError> {
    match result {
        Ok(f) => {
            for (c, s) in f.channels().iter().enumerate() {
                prop_assert!(s.validate().is_ok(), "channel {c}: {:?}", s.validate());
            }
            prop_assert!(f.scene.validate().is_ok());
        }
        Err(e) => {
            let msg = e.to_string();
            let name = file.file_name().unwrap().to_string_lossy().into_owned();
            prop_assert!(msg.contains(&name), "error does not name the file: {msg}");
            match &e {
                SceneFileError::Invalid { field, line, .. } => prop_assert!(
                    line.is_some() || !field.is_empty(),
                    "error without line or field: {msg}"
                ),
                SceneFileError::Io { .. } => {}
            }
        }
    }
    Ok(())
}

/// Parses `text` as the file `dir/scene.toml`.
fn parse(text: &[u8], dir: &Path) -> (Result<SceneFile, SceneFileError>, std::path::PathBuf) {
    let file = dir.join("scene.toml");
    let text = String::from_utf8_lossy(text);
    (SceneFile::parse(&text, dir, &file), file)
}

/// Cases per property: 5000 scene mutants and 3000 `.vol` mutants took 2.5 s together on a
/// shared 2-core machine in release (with `reference/tests/fuzz_render.rs`, 3000 mutants in
/// 5.4 s, about 8 s for the whole fuzz corpus).
const SCENE_CASES: u32 = 5000;
const VOL_CASES: u32 = 3000;

proptest! {
    #![proptest_config(config(SCENE_CASES, 0x5eed_0001))]

    #[test]
    fn mutated_scene_files_give_located_errors_or_valid_scenes((seed, muts) in mutant()) {
        let dir = scene_dir("scene");
        let corpus = seeds();
        let (_, text) = &corpus[seed.index(corpus.len())];
        let mut bytes = text.clone().into_bytes();
        for m in &muts {
            bytes = apply(&bytes, m);
        }
        let (r, file) = parse(&bytes, &dir);
        check_parse(r, &file)?;
    }
}

/// A mutation of a `.vol` file.
#[derive(Debug, Clone)]
enum VolMutation {
    /// One of the text mutations that act on bytes (flip, truncate).
    Bytes(Mutation),
    /// Set an i32 header field (encoding, dims, channels) to a hostile value.
    HeaderInt(Index, i32),
    /// Set an f32 of the bounding box to a hostile value.
    HeaderFloat(Index, f32),
    /// Append bytes.
    Append(usize),
}

fn vol_mutation() -> impl Strategy<Value = VolMutation> {
    let ints = prop_oneof![
        Just(0),
        Just(-1),
        Just(1),
        Just(2),
        Just(3),
        Just(6),
        Just(9),
        Just(1000),
        Just(i32::MAX),
        Just(i32::MIN),
        Just(1 << 20)
    ];
    let floats = prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(0.0),
        Just(-1.0),
        Just(1e38),
        Just(1e-38),
        Just(0.5),
        Just(2.0)
    ];
    prop_oneof![
        (any::<Index>(), 1u8..=255).prop_map(|(i, m)| VolMutation::Bytes(Mutation::Flip(i, m))),
        any::<Index>().prop_map(|i| VolMutation::Bytes(Mutation::Truncate(i))),
        (any::<Index>(), ints).prop_map(|(i, v)| VolMutation::HeaderInt(i, v)),
        (any::<Index>(), floats).prop_map(|(i, v)| VolMutation::HeaderFloat(i, v)),
        (1usize..16).prop_map(VolMutation::Append),
    ]
}

fn apply_vol(bytes: &mut Vec<u8>, m: &VolMutation) {
    match m {
        VolMutation::Bytes(m) => *bytes = apply(bytes, m),
        VolMutation::HeaderInt(i, v) => {
            let at = [4, 8, 12, 16, 20][i.index(5)];
            if bytes.len() >= at + 4 {
                bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
        }
        VolMutation::HeaderFloat(i, v) => {
            let at = 24 + 4 * i.index(6);
            if bytes.len() >= at + 4 {
                bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
        }
        VolMutation::Append(n) => bytes.extend(std::iter::repeat_n(0x3f, *n)),
    }
}

proptest! {
    #![proptest_config(config(VOL_CASES, 0x5eed_0002))]

    #[test]
    fn mutated_vol_files_give_typed_errors_or_consistent_grids(
        muts in proptest::collection::vec(vol_mutation(), 1..=3)
    ) {
        let dir = scene_dir("vol");
        let mut bytes = seed_vol().to_bytes();
        for m in &muts {
            apply_vol(&mut bytes, m);
        }
        // The reader alone: a typed error or a grid consistent with its header.
        if let Ok(v) = VolGrid::from_bytes(&bytes) {
            prop_assert_eq!(v.data.len(), v.cells() * v.channels);
            prop_assert_eq!(&VolGrid::from_bytes(&v.to_bytes()).unwrap(), &v);
            if let Ok(g) = v.grid() {
                prop_assert_eq!(g.n, v.dims);
            }
        }
        // Through the scene file: a located error (`medium.file`) or a valid scene.
        std::fs::write(dir.join("density.vol"), &bytes).unwrap();
        let (r, file) = parse(fuzz_corpus::VOL_SCENE.as_bytes(), &dir);
        if let Err(e) = &r {
            prop_assert_eq!(e.field(), Some("medium.file"), "{}", e);
        }
        check_parse(r, &file)?;
    }
}

#[test]
fn every_seed_parses_to_a_valid_scene() {
    let dir = scene_dir("seeds");
    for (name, text) in seeds() {
        let (r, _) = parse(text.as_bytes(), &dir);
        let f = r.unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(f.scene.validate().is_ok(), "{name}");
        assert!(
            f.scene.medium.grid.len() <= 16 * 16 * 16,
            "{name}: test-sized"
        );
    }
}

#[test]
fn invalid_utf8_through_load_is_an_io_error_naming_the_file() {
    let dir = scene_dir("utf8");
    let path = dir.join("bad.toml");
    std::fs::write(&path, b"format = 1\n[medium]\ngenerator = \"\xff\xfe\"\n").unwrap();
    let e = SceneFile::load(&path).unwrap_err();
    assert!(matches!(e, SceneFileError::Io { .. }), "{e}");
    assert!(e.to_string().contains("bad.toml"), "{e}");
}
