//! Determinism of the whole `solve` command (issue 7): the same scene and
//! seed give bit-identical files on 1 and 2 threads and across repeated
//! runs, for the hierarchical method in each meshing mode (the classic
//! methods' thread independence is checked in tests/end_to_end.rs).
//! `report.json` is compared with its wall-clock and thread-count fields
//! removed.

use std::fs;
use std::path::Path;
use std::process::Command;

use serde_json::Value;

use crate::fixtures::scene_arg;

/// Runs `nusselt solve` on the bundled penumbra scene with
/// `RAYON_NUM_THREADS=threads`, writing to `dir/out`.
fn solve(dir: &Path, out: &str, threads: usize, mesh: &str) {
    let scene = scene_arg("penumbra.gltf");
    let result = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(["solve", &scene, "-q", "-o", out])
        .args(["--accuracy", "preview", "--mesh", mesh, "--seed", "7"])
        .args(["--width", "48", "--height", "32", "--spp", "4"])
        .env("RAYON_NUM_THREADS", threads.to_string())
        .current_dir(dir)
        .output()
        .expect("the nusselt binary runs");
    assert!(
        result.status.success(),
        "{out}: {}",
        String::from_utf8_lossy(&result.stderr)
    );
}

/// `report.json` without what legitimately varies: wall-clock times (the
/// phase times and every `*seconds` field) and the thread count.
fn stable_report(path: &Path) -> Value {
    fn strip(v: &mut Value) {
        match v {
            Value::Object(map) => {
                map.retain(|k, _| !(k == "times" || k == "threads" || k.ends_with("seconds")));
                map.values_mut().for_each(strip);
            }
            Value::Array(items) => items.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut report: Value = serde_json::from_slice(&fs::read(path).unwrap()).unwrap();
    strip(&mut report);
    report
}

#[test]
fn solve_outputs_are_bit_identical_across_threads_and_runs() {
    let dir = tempfile::tempdir().unwrap();
    for mesh in ["discontinuity", "quadtree", "uniform"] {
        let runs = [(1, "one"), (2, "two"), (2, "two-again")].map(|(threads, name)| {
            let out = format!("{mesh}-{name}");
            solve(dir.path(), &out, threads, mesh);
            dir.path().join(out)
        });
        for run in &runs[1..] {
            for file in ["solution.exr", "baked.gltf", "baked.bin", "render.exr"] {
                assert!(
                    fs::read(runs[0].join(file)).unwrap() == fs::read(run.join(file)).unwrap(),
                    "{mesh}: {file} differs between {} and {}",
                    runs[0].display(),
                    run.display()
                );
            }
            assert_eq!(
                stable_report(&runs[0].join("report.json")),
                stable_report(&run.join("report.json")),
                "{mesh}: report.json differs beyond times"
            );
        }
        // The comparison saw the thread counts it was meant to.
        let threads = |run: &Path| -> Value {
            serde_json::from_slice::<Value>(&fs::read(run.join("report.json")).unwrap()).unwrap()
                ["threads"]
                .clone()
        };
        assert_eq!(threads(&runs[0]), 1);
        assert_eq!(threads(&runs[1]), 2);
    }
}
