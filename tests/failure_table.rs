//! The failure-mode table (`nusselt::lab::failures`): its yardsticks, its rows
//! and its Markdown, on small settings.
//!
//! The fast part runs the table on the two scenes whose answers are exact
//! (`facing-away`: nothing lit; `shared-edge`: the closed form) with one
//! method of each family. With `NUSSELT_SLOW_TESTS=1`, every method runs on
//! every stress scene (small images, few reference paths): no run may
//! panic or produce a non-finite value, and every row of the table is
//! written.

use nusselt::lab::failures::{
    self, Outcome, Quantity, SceneTable, TableMethod, TableSettings, closed_form,
};

use crate::fixtures::{scene_path, slow_tests, stress_scene};

fn small() -> TableSettings {
    TableSettings {
        width: 36,
        height: 24,
        reference_spp: 16,
        render_spp: 1,
        max_links: 200_000,
        ..TableSettings::default()
    }
}

fn run(name: &str, methods: &[TableMethod]) -> SceneTable {
    failures::scene_table(
        &stress_scene(name),
        name,
        &small(),
        methods,
        None,
        |_, _| {},
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn pick(labels: &[&str]) -> Vec<TableMethod> {
    let all = failures::table_methods(&small());
    let picked: Vec<TableMethod> = all
        .into_iter()
        .filter(|m| labels.contains(&m.label))
        .collect();
    assert_eq!(picked.len(), labels.len());
    picked
}

fn measured(table: &SceneTable, label: &str) -> failures::Measure {
    match &table.rows.iter().find(|(l, _)| *l == label).unwrap().1 {
        Outcome::Ran(m) => m.clone(),
        other => panic!("{}: {label}: {other:?}", table.name),
    }
}

#[test]
fn closed_forms_exist_where_the_scenes_promise_them() {
    for (name, quantity) in [
        ("tiny-emitter", Quantity::Absorbed),
        ("facing-away", Quantity::Absorbed),
        ("furnace-099", Quantity::Radiated),
        ("shared-edge", Quantity::Absorbed),
        ("open-floor", Quantity::Absorbed),
    ] {
        let c = closed_form(name, &stress_scene(name)).expect(name);
        assert_eq!(c.quantity, quantity, "{name}");
    }
    // ρ = 0.99 (as an f32), Φ = 0.04 W: Σ B A = Φ / (1 − ρ) = 4 W.
    let furnace = closed_form("furnace-099", &stress_scene("furnace-099")).unwrap();
    assert!((furnace.watts - 4.0).abs() < 1e-5, "{}", furnace.watts);
    assert!(closed_form("slivers", &stress_scene("slivers")).is_none());
    // A scene that is not what the name promises has no closed form.
    assert!(closed_form("shared-edge", &stress_scene("slivers")).is_none());
}

#[test]
fn the_table_measures_exact_scenes_exactly() {
    let labels = [
        "Gauss-Seidel, point-polygon",
        "Gauss-Seidel, hemicube",
        "hierarchical, discontinuity mesh",
    ];
    let methods = pick(&labels);
    let dark = run("facing-away", &methods);
    for (label, outcome) in &dark.rows {
        let m = measured(&dark, label);
        assert!(m.converged, "{label}");
        assert_eq!(m.power_error, Some(0.0), "{label}");
        assert_eq!(m.absorbed_ratio, 0.0, "{label}");
        assert_eq!(m.image_error, 0.0, "{label}");
        let symptoms = failures::symptoms(outcome, dark.fastest(), dark.reference_noise);
        assert!(symptoms.is_empty(), "{label}: {symptoms:?}");
    }
    let edge = run("shared-edge", &methods);
    // The classic solvers on the uniform mesh integrate the receiver's own
    // light back to the black emitter: within 1 % of the closed form.
    let gs = measured(&edge, "Gauss-Seidel, point-polygon");
    let e = gs.power_error.unwrap();
    assert!(e.abs() < 0.01, "power error {e}");
    // The reference is noisy at 16 paths per pixel, but a correct solve
    // lies within a few noise levels of it.
    assert!(
        gs.image_error < 3.0 * edge.reference_noise + 0.05,
        "image error {} against noise {}",
        gs.image_error,
        edge.reference_noise
    );
    let text = failures::markdown(&[dark, edge], &small(), "test");
    for label in labels {
        assert_eq!(text.matches(&format!("| {label} |")).count(), 2, "{label}");
    }
    assert!(text.contains("## facing-away") && text.contains("## shared-edge"));
}

#[test]
fn every_method_survives_every_stress_scene() {
    if !slow_tests("failure_table::every_method_survives_every_stress_scene") {
        return;
    }
    let dir = scene_path("stress");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "gltf").then(|| p.file_stem().unwrap().to_string_lossy().into())
        })
        .collect();
    names.sort();
    let methods = failures::table_methods(&small());
    let mut tables = Vec::new();
    for name in &names {
        let table = run(name, &methods);
        for (label, outcome) in &table.rows {
            match outcome {
                Outcome::Ran(m) => {
                    assert!(!m.non_finite, "{name}: {label}: non-finite output");
                    assert!(m.image_error.is_finite(), "{name}: {label}");
                }
                Outcome::Refused(_) => {}
                Outcome::Panicked(p) => panic!("{name}: {label} panicked: {p}"),
            }
        }
        tables.push(table);
    }
    let text = failures::markdown(&tables, &small(), "test");
    assert_eq!(
        text.lines()
            .filter(|l| l.starts_with("| ") && !l.starts_with("| method"))
            .count(),
        names.len() * methods.len()
    );
}
