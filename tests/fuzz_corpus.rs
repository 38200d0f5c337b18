//! Replays the fuzz corpus and any recorded crash inputs through the fuzz
//! target's body on stable Rust: no input may panic the loader.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use nusselt::load::{LoadOptions, load_scene_from_slice};

use crate::fixtures::slow_tests;

/// The body of `fuzz/fuzz_targets/load_gltf.rs`.
fn fuzz_body(data: &[u8]) {
    let _ = load_scene_from_slice(data, None, &LoadOptions::default());
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .map(|e| e.expect("readable directory entry").path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

#[test]
fn corpus_and_regressions_never_panic() {
    let corpus = files_in(&fuzz_dir().join("corpus/load_gltf"));
    assert!(corpus.len() >= 10, "the seed corpus is missing");
    let regressions = files_in(&fuzz_dir().join("regressions"));
    let mut panicked = Vec::new();
    for file in corpus.iter().chain(&regressions) {
        let data = std::fs::read(file).expect("readable corpus file");
        if catch_unwind(AssertUnwindSafe(|| fuzz_body(&data))).is_err() {
            panicked.push(file.display().to_string());
        }
    }
    assert!(panicked.is_empty(), "the loader panicked on: {panicked:?}");
}

#[test]
fn seed_corpus_covers_valid_and_broken_inputs() {
    let dir = fuzz_dir().join("corpus/load_gltf");
    let load = |name: &str| {
        let data = std::fs::read(dir.join(name)).expect("seed file");
        load_scene_from_slice(&data, None, &LoadOptions::default())
    };
    for name in [
        "quad.gltf",
        "quad.glb",
        "textured.gltf",
        "textured.glb",
        "sparse.gltf",
    ] {
        if let Err(e) = load(name) {
            panic!("{name} should load: {e}");
        }
    }
    let textured = load("textured.gltf").unwrap();
    assert_eq!(textured.cameras.len(), 1);
    assert!(textured.stats.back_patches > 0);
    for (name, needle) in [
        ("nan.gltf", "mesh 'NaN' primitive 0"),
        ("bad_index.gltf", "mesh 'BadIndex' primitive 0: index 17"),
        ("lines.gltf", "mesh 'Lines' primitive 0"),
        ("cycle.gltf", "reached twice"),
        ("huge_count.gltf", "exceed"),
        ("truncated.glb", "GLB header declares length"),
        ("malformed.gltf", "not a valid glTF"),
        ("no_emitters.glb", "no light in the scene"),
    ] {
        match load(name) {
            Ok(_) => panic!("{name} should fail"),
            Err(e) => assert!(e.to_string().contains(needle), "{name}: {e}"),
        }
    }
}

/// The single-file inputs of issue 26 in the seed corpus, each with the
/// outcome the loader must give: `Ok`, or an error containing the text.
/// Loaded with the corpus folder as the scene's folder, so that external
/// URIs meet the folder check (the fuzz body, without a folder, refuses
/// them earlier).
const ISSUE_26_SEEDS: [(&str, Option<&str>); 13] = [
    (
        "projective_matrix.gltf",
        Some("not [0, 0, 0, 1]: a projection"),
    ),
    (
        "shear_matrix.gltf",
        Some("columns 0 and 1 are not orthogonal: a shear"),
    ),
    (
        "matrix_and_trs.gltf",
        Some("has both a matrix and translation/rotation/scale"),
    ),
    (
        "sparse_index_past_count.gltf",
        Some("sparse index 0 is 7: sparse indices must increase and stay below"),
    ),
    ("view_past_buffer.gltf", Some("exceeds buffer 0")),
    ("glb_length_short.glb", Some("GLB header declares length")),
    ("version_3.gltf", Some("asset.version is '3.0'")),
    ("uri_parent.gltf", Some("leads out of the scene's folder")),
    ("uri_absolute.gltf", Some("is an absolute path")),
    ("uri_file_scheme.gltf", Some("is a file: URI")),
    ("control_names.gltf", Some("Red Mesh' primitive 0")),
    (
        "instancing_bomb.glb",
        Some("instances 8388610 triangles, most from mesh 'Tiles' (32768 triangles × 256 nodes)"),
    ),
    ("shared_image_source.gltf", None),
];

#[test]
fn issue_26_seeds_are_refused_or_accepted_as_the_loader_should() {
    let dir = fuzz_dir().join("corpus/load_gltf");
    for (name, expected) in ISSUE_26_SEEDS {
        let data = std::fs::read(dir.join(name)).expect("seed file (fuzz/make_seeds.py)");
        let result = catch_unwind(AssertUnwindSafe(|| {
            load_scene_from_slice(&data, Some(&dir), &LoadOptions::default())
        }))
        .unwrap_or_else(|_| panic!("{name}: the loader panicked"));
        match (result, expected) {
            (Ok(_), None) => {}
            (Ok(_), Some(needle)) => panic!("{name} should fail with '{needle}'"),
            (Err(e), None) => panic!("{name} should load: {e}"),
            (Err(e), Some(needle)) => {
                let message = e.to_string();
                assert!(message.contains(needle), "{name}: {message}");
                // No control character reaches the terminal, and no
                // file outside the folder is echoed.
                assert!(
                    !message.chars().any(char::is_control),
                    "{name}: {message:?}"
                );
                assert!(!message.contains("root:"), "{name}: {message}");
            }
        }
    }
}

/// The `triangulate` fuzz target: its seed corpus and recorded crashes
/// triangulate without panicking and the result validates.
#[test]
fn triangulate_corpus_and_regressions_validate() {
    let corpus = files_in(&fuzz_dir().join("corpus/triangulate"));
    assert!(corpus.len() >= 10, "the triangulate seed corpus is missing");
    let regressions = files_in(&fuzz_dir().join("regressions/triangulate"));
    let mut failed = Vec::new();
    for file in corpus.iter().chain(&regressions) {
        let data = std::fs::read(file).expect("readable corpus file");
        match catch_unwind(AssertUnwindSafe(|| nusselt::fuzz::fuzz_triangulate(&data))) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => failed.push(format!("{}: {e}", file.display())),
            Err(_) => failed.push(format!("{}: panicked", file.display())),
        }
    }
    assert!(failed.is_empty(), "triangulation failed on: {failed:?}");
}

/// Runs the `pipeline` fuzz target's body on `data`: a panic or a broken
/// invariant becomes an `Err` naming it.
fn pipeline_body(data: &[u8]) -> Result<(), String> {
    match catch_unwind(AssertUnwindSafe(|| nusselt::fuzz::fuzz_pipeline(data))) {
        Ok(result) => result,
        Err(_) => Err("panicked".into()),
    }
}

/// The `pipeline` fuzz target: its seed corpus and recorded crashes solve
/// without panicking, with finite non-negative results and no energy
/// created.
#[test]
fn pipeline_corpus_and_regressions_keep_the_invariants() {
    let corpus = files_in(&fuzz_dir().join("corpus/pipeline"));
    assert!(corpus.len() >= 10, "the pipeline seed corpus is missing");
    let regressions = files_in(&fuzz_dir().join("regressions/pipeline"));
    let mut failed = Vec::new();
    for file in corpus.iter().chain(&regressions) {
        let data = std::fs::read(file).expect("readable corpus file");
        if let Err(e) = pipeline_body(&data) {
            failed.push(format!("{}: {e}", file.display()));
        }
    }
    assert!(failed.is_empty(), "the pipeline failed on: {failed:?}");
}

/// Without a fuzzer: the bodies of all three targets over a few thousand
/// deterministic pseudo-random inputs (random bytes, and mutations of the
/// seeds). Slow; runs with NUSSELT_SLOW_TESTS=1.
#[test]
fn fuzz_bodies_survive_pseudo_random_inputs() {
    use rand::{Rng, SeedableRng};
    if !slow_tests("fuzz_corpus::fuzz_bodies_survive_pseudo_random_inputs") {
        return;
    }
    let mut rng = rand_pcg::Pcg32::seed_from_u64(0x6675_7a7a);
    let seeds = |dir: &str| -> Vec<Vec<u8>> {
        files_in(&fuzz_dir().join(dir))
            .iter()
            .map(|f| std::fs::read(f).unwrap())
            .collect()
    };
    let input = |rng: &mut rand_pcg::Pcg32, seeds: &[Vec<u8>]| -> Vec<u8> {
        if rng.random_bool(0.5) || seeds.is_empty() {
            let n = rng.random_range(0..200);
            (0..n).map(|_| rng.random()).collect()
        } else {
            let mut data = seeds[rng.random_range(0..seeds.len())].clone();
            for _ in 0..rng.random_range(1..8) {
                if data.is_empty() {
                    break;
                }
                let at = rng.random_range(0..data.len());
                data[at] = rng.random();
            }
            data
        }
    };
    let mut failed = Vec::new();
    let gltf_seeds = seeds("corpus/load_gltf");
    for k in 0..2000 {
        let data = input(&mut rng, &gltf_seeds);
        if catch_unwind(AssertUnwindSafe(|| fuzz_body(&data))).is_err() {
            failed.push(format!("load_gltf #{k}: panicked on {data:?}"));
        }
    }
    let tri_seeds = seeds("corpus/triangulate");
    for k in 0..2000 {
        let data = input(&mut rng, &tri_seeds);
        match catch_unwind(AssertUnwindSafe(|| nusselt::fuzz::fuzz_triangulate(&data))) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => failed.push(format!("triangulate #{k}: {e} on {data:?}")),
            Err(_) => failed.push(format!("triangulate #{k}: panicked on {data:?}")),
        }
    }
    let pipeline_seeds = seeds("corpus/pipeline");
    for k in 0..1000 {
        let data = input(&mut rng, &pipeline_seeds);
        if let Err(e) = pipeline_body(&data) {
            failed.push(format!("pipeline #{k}: {e} on {data:?}"));
        }
    }
    assert!(failed.is_empty(), "{} failures: {failed:#?}", failed.len());
}
