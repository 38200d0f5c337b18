//! The JSON Schemas under `src/schemas/`: each equals what the types
//! generate today, and what the subcommands write validates against it.
//!
//! Set `NUSSELT_UPDATE_SCHEMAS=1` to rewrite the committed files from the
//! types (then review the diff, and raise `report::SCHEMA_VERSION` when a
//! field was removed, renamed or changed meaning).

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::fixtures::{nusselt_ok, scene_arg};

fn schema_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src/schemas")
}

#[test]
fn committed_schemas_equal_the_generated_ones() {
    let update = std::env::var_os("NUSSELT_UPDATE_SCHEMAS").is_some();
    for (name, text) in nusselt::schema::schemas() {
        let path = schema_dir().join(name);
        if update {
            std::fs::create_dir_all(schema_dir()).unwrap();
            std::fs::write(&path, &text).unwrap();
        }
        let committed = std::fs::read_to_string(&path).unwrap_or_else(|e| {
            panic!(
                "{}: {e} (NUSSELT_UPDATE_SCHEMAS=1 writes it)",
                path.display()
            )
        });
        assert!(
            committed == text,
            "{name} differs from the types' schema: run the tests with NUSSELT_UPDATE_SCHEMAS=1"
        );
    }
}

/// The errors of `instance` against `src/schemas/<schema>`.
fn schema_errors(schema: &str, instance: &Value) -> Vec<String> {
    let schema: Value =
        serde_json::from_str(&std::fs::read_to_string(schema_dir().join(schema)).unwrap()).unwrap();
    let validator = jsonschema::validator_for(&schema).unwrap();
    validator
        .iter_errors(instance)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect()
}

/// Validates `file` against `src/schemas/<schema>`, failing with every
/// error found.
fn assert_valid(schema: &str, file: &Path) {
    let instance: Value = serde_json::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
    let errors = schema_errors(schema, &instance);
    assert!(errors.is_empty(), "{}: {errors:#?}", file.display());
}

#[test]
fn every_json_output_validates_against_its_schema() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let box_ = scene_arg("cornell-box.gltf");
    let solve = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        let mut args = vec!["solve", &box_, "-o", out.to_str().unwrap(), "--quiet"];
        args.extend_from_slice(extra);
        nusselt_ok(&args, d);
        out
    };
    let hierarchical = solve("h", &["--accuracy", "preview", "--lightmap", "64"]);
    let classic = solve("c", &["--method", "jacobi", "--element-size", "0.25"]);
    for out in [&hierarchical, &classic] {
        assert_valid("report.schema.json", &out.join("report.json"));
    }
    // What does not apply is null, not zero.
    let report = |out: &Path| -> Value {
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
    };
    let (h, c) = (report(&hierarchical), report(&classic));
    assert!(h["max_row_sum"].is_null() && c["max_row_sum"].as_f64().is_some());
    assert!(h["mean_row_error"].is_null() && h["max_form_factor_error"].is_null());
    assert!(h["times"]["form_factors"].is_null() && c["times"]["linking"].is_null());
    assert!(h["times"]["lightmap"].as_f64().is_some() && c["times"]["lightmap"].is_null());
    assert!(c["counts"]["clusters"].is_null() && h["counts"]["clusters"].as_u64().is_some());
    assert_eq!(h["schema_version"], nusselt::report::SCHEMA_VERSION);
    // The schema is strict enough to catch a wrong type or a missing field.
    let mut wrong = h.clone();
    wrong["counts"]["links"] = Value::from("many");
    assert!(!schema_errors("report.schema.json", &wrong).is_empty());
    let mut missing = h.clone();
    missing.as_object_mut().unwrap().remove("power");
    assert!(!schema_errors("report.schema.json", &missing).is_empty());

    let reference = d.join("ref.exr");
    nusselt_ok(
        &[
            "reference",
            &box_,
            "-o",
            reference.to_str().unwrap(),
            "--spp",
            "2",
            "--width",
            "32",
            "--height",
            "32",
            "--quiet",
        ],
        d,
    );
    assert_valid("reference.schema.json", &d.join("ref.json"));

    let render = d.join("render.exr");
    nusselt_ok(
        &[
            "render",
            hierarchical.join("solution.exr").to_str().unwrap(),
            "-o",
            render.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "32",
        ],
        d,
    );
    let compared = d.join("cmp");
    nusselt_ok(
        &[
            "compare",
            render.to_str().unwrap(),
            reference.to_str().unwrap(),
            "-o",
            compared.to_str().unwrap(),
        ],
        d,
    );
    assert_valid("metrics.schema.json", &compared.join("metrics.json"));
}
