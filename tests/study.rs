//! `nusselt study` on a tiny scene: the CSV has the expected rows, the
//! charts are valid SVG and PNG, the reference is cached and reused.

use crate::fixtures::{assert_user_error, nusselt, scene_arg};
use std::fs;

#[test]
fn tiny_study_writes_rows_charts_and_contact_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let config = r#"{"width": 16, "height": 16, "reference_spp": 16, "render_spp": 1,
        "runs": [
          {"label": "jacobi", "method": "jacobi", "element_fractions": [0.4, 0.25]},
          {"label": "gs hemicube", "method": "gauss-seidel", "kernel": "hemicube", "element_fractions": [0.4]},
          {"label": "hierarchical", "method": "hierarchical", "accuracy": ["preview"]}
        ]}"#;
    fs::write(dir.path().join("study.json"), config).unwrap();
    let scene = scene_arg("goral-box.gltf");
    let args = ["study", &scene, "-o", "s", "--config", "study.json", "-q"];
    let out = nusselt(&args, dir.path());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = dir.path().join("s");
    let csv = fs::read_to_string(s.join("results.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("label,method,setting,elements"));
    assert_eq!(lines.len(), 1 + 4, "{csv}");
    // Labels are quoted only when they need it (RFC 4180).
    assert!(lines[1].starts_with("jacobi,jacobi,0.4,"));
    assert!(lines[3].starts_with("gs hemicube,gauss-seidel,0.4,"));
    for line in &lines[1..] {
        let rel: f64 = line.split(',').nth(10).unwrap().parse().unwrap();
        assert!(rel.is_finite() && rel > 0.0 && rel < 1.0, "{line}");
    }
    for stem in ["error-time", "error-elements", "links-elements"] {
        let svg = fs::read_to_string(s.join(format!("{stem}.svg"))).unwrap();
        roxmltree::Document::parse(&svg).unwrap_or_else(|e| panic!("{stem}.svg: {e}"));
        assert!(
            svg.contains("jacobi") && svg.contains("hierarchical"),
            "{stem}: legend"
        );
        let png = image::open(s.join(format!("{stem}.png"))).unwrap();
        assert!(png.width() > 100 && png.height() > 100);
    }
    let sheet = image::open(s.join("contact-sheet.png")).unwrap();
    assert!(sheet.width() >= 6 * 16 && sheet.height() >= 3 * 16);
    // The reference is cached: a second run reuses it byte for byte.
    let before = fs::read(s.join("reference.exr")).unwrap();
    let out = nusselt(&args, dir.path());
    assert!(out.status.success());
    assert_eq!(fs::read(s.join("reference.exr")).unwrap(), before);
    // A bad configuration is one clean error.
    fs::write(
        dir.path().join("bad.json"),
        r#"{"runs": [{"label": "x", "method": "magic"}]}"#,
    )
    .unwrap();
    let out = nusselt(
        &["study", &scene, "-o", "t", "--config", "bad.json", "-q"],
        dir.path(),
    );
    assert_user_error(&out, "unknown method 'magic'");
}

/// The radiosity solutions and the independent path tracer agree on the
/// Cornell box. Stated tolerances: image means per channel within 3 % for
/// Jacobi on a uniform mesh (h = 0.03 diagonal) and within 5 % for the
/// default hierarchical solver (measured: 2.4–3.5 % darker; its links hand
/// each receiver the mean over it, which misplaces light next to edges),
/// and a mean relative error under 15 %; the rest is discretisation and
/// the reference's noise at 256 spp. (RMSE itself is dominated by the
/// light's edge pixels, where 16 stratified samples and the reference's
/// random ones cover the light differently.)
#[test]
fn cornell_radiosity_agrees_with_the_path_tracer() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("cornell-box.gltf");
    let size = ["--width", "32", "--height", "32"];
    let mut reference = vec!["reference", &scene, "-q", "-o", "ref.exr", "--spp", "256"];
    reference.extend(size);
    assert!(nusselt(&reference, dir.path()).status.success());
    let configs: [(&[&str], f64); 2] = [
        (&["--method", "jacobi", "--element-size", "0.03"], 0.03),
        (&["--method", "hierarchical"], 0.05),
    ];
    for (method, tolerance) in configs {
        let mut solve = vec!["solve", &scene, "-q", "-o", "sol", "--spp", "16"];
        solve.extend(method);
        solve.extend(size);
        assert!(nusselt(&solve, dir.path()).status.success());
        let out = nusselt(&["compare", "sol/render.exr", "ref.exr"], dir.path());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let m: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        for c in ["R", "G", "B"] {
            let ch = &m["channels"][c];
            let ratio = ch["mean_test"].as_f64().unwrap() / ch["mean_reference"].as_f64().unwrap();
            assert!(
                (ratio - 1.0).abs() < tolerance,
                "{method:?} {c}: mean ratio {ratio}"
            );
        }
        let mre = m["overall"]["mean_relative_error"].as_f64().unwrap();
        assert!(mre < 0.15, "{method:?}: mean relative error {mre}");
    }
}
