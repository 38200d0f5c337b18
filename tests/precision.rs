//! The same scene at any scale: the Cornell box, wrapped in a root node
//! that scales it by 10⁻⁶ … 10⁶, gives the same energy balance, the same
//! output mesh (up to the scale) and the same image from its own camera.
//! Ray offsets, BVH epsilons, tolerances and the default view are all
//! relative to the scene, so nothing here may depend on the metre.

use std::path::Path;

use nusselt::output::exr::read_image;
use serde_json::{Value, json};

use crate::fixtures::{nusselt_ok, scene_path};

const SCALES: [&str; 5] = ["1e-6", "1e-3", "1", "1e3", "1e6"];

/// Writes the Cornell box scaled by `scale` as `dir/cb-SCALE.gltf` (beside
/// a copy of its buffer) and solves it at preview accuracy into
/// `dir/out-SCALE`.
fn solve_scaled(dir: &Path, scale: &str) -> Value {
    let mut g: Value =
        serde_json::from_slice(&std::fs::read(scene_path("cornell-box.gltf")).unwrap()).unwrap();
    let s: f64 = scale.parse().unwrap();
    let scene = g["scene"].as_u64().unwrap_or(0) as usize;
    let roots = g["scenes"][scene]["nodes"].take();
    let nodes = g["nodes"].as_array_mut().unwrap();
    nodes.push(json!({"name": "scale", "scale": [s, s, s], "children": roots}));
    g["scenes"][scene]["nodes"] = json!([nodes.len() - 1]);
    let file = dir.join(format!("cb-{scale}.gltf"));
    std::fs::write(&file, serde_json::to_vec(&g).unwrap()).unwrap();
    let out = dir.join(format!("out-{scale}"));
    nusselt_ok(
        &[
            "solve",
            file.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--accuracy",
            "preview",
            "--width",
            "48",
            "--height",
            "48",
            "--quiet",
        ],
        dir,
    );
    serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap()
}

#[test]
fn the_cornell_box_at_five_scales_gives_one_solution() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        scene_path("cornell-box.bin"),
        dir.path().join("cornell-box.bin"),
    )
    .unwrap();
    let reports: Vec<Value> = SCALES.iter().map(|s| solve_scaled(dir.path(), s)).collect();
    let images: Vec<_> = SCALES
        .iter()
        .map(|s| read_image(&dir.path().join(format!("out-{s}/render.exr"))).unwrap())
        .collect();
    const UNIT: usize = 2;
    let balance = |r: &Value| -> Vec<f64> {
        (0..3)
            .map(|c| {
                r["power"]["absorbed"][c].as_f64().unwrap()
                    / r["power"]["emitted"][c].as_f64().unwrap()
            })
            .collect()
    };
    let count = |r: &Value, k: &str| r["counts"][k].as_f64().unwrap();
    let mean = |f: &nusselt::render::frame::Frame| -> f64 {
        f.pixels.iter().map(|p| f64::from(p[1])).sum::<f64>() / f.pixels.len() as f64
    };
    for (k, scale) in SCALES.iter().enumerate() {
        let (r, one) = (&reports[k], &reports[UNIT]);
        // Emitted power goes with the area: W/m² times m².
        let s: f64 = scale.parse().unwrap();
        let emitted = r["power"]["emitted"][1].as_f64().unwrap();
        let expected = one["power"]["emitted"][1].as_f64().unwrap() * s * s;
        assert!(
            (emitted / expected - 1.0).abs() < 1e-5,
            "scale {scale}: emitted {emitted} W, expected {expected} W"
        );
        for (a, b) in balance(r).iter().zip(balance(one)) {
            assert!(
                (a - b).abs() < 2e-3,
                "scale {scale}: absorbed/emitted {a} against {b}"
            );
        }
        for key in ["patches", "leaves", "links", "output_vertices"] {
            let (a, b) = (count(r, key), count(one, key));
            assert!(
                (a / b - 1.0).abs() < 0.05,
                "scale {scale}: {key} {a} against {b} at scale 1"
            );
        }
        // The image from the scene's camera: the same to 0.5 % on the mean,
        // and pixel by pixel to 2 % (or 0.01 absolute, for the dark ones)
        // but for a handful on the light's edge, where one ray decides.
        let (f, g) = (&images[k], &images[UNIT]);
        assert_eq!((f.width, f.height), (g.width, g.height));
        assert!(mean(g) > 0.01, "the image at scale 1 is dark");
        assert!(
            (mean(f) / mean(g) - 1.0).abs() < 5e-3,
            "scale {scale}: image mean {} against {}",
            mean(f),
            mean(g)
        );
        let off = f
            .pixels
            .iter()
            .zip(&g.pixels)
            .filter(|(p, q)| {
                (0..3).any(|c| {
                    let (a, b) = (f64::from(p[c]), f64::from(q[c]));
                    (a - b).abs() > 0.02 * b.abs().max(0.5)
                })
            })
            .count();
        assert!(
            off <= f.pixels.len() / 200,
            "scale {scale}: {off} of {} pixels differ",
            f.pixels.len()
        );
    }
}
