//! Resource budgets of the hierarchical solver (issue 7): `max_links`,
//! `max_elements` and the memory budget stop refinement without exceeding
//! the limit, the solution stays physical, and `report.json` names the
//! budget (or says `null`); the command line checks the values.

use std::time::{Duration, Instant};

use nusselt::hierarchical::{
    Accuracy, Budget, BudgetHit, Clustering, HierarchicalSettings, memory_estimate,
    solve_hierarchical_guided,
};
use nusselt::pipeline::{SolveRun, SolveSettings, solve};
use nusselt::render::RenderSettings;
use nusselt::render::view::ViewOverrides;
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use crate::fixtures::{assert_user_error, bundled_scene, cornell, nusselt, on_threads, scene_path};

/// The default preset and output mesh (discontinuity: guided refinement
/// included), a tiny image.
fn settings(budget: impl FnOnce(&mut HierarchicalSettings)) -> SolveSettings {
    let mut s = SolveSettings {
        render: RenderSettings::with_samples(4, 0),
        view: ViewOverrides {
            width: Some(16),
            height: Some(16),
            ..ViewOverrides::default()
        },
        ..SolveSettings::default()
    };
    budget(&mut s.hierarchical);
    s
}

/// Solves and checks what every run must hold, budget or not: finite,
/// non-negative output, absorbed power at most the emitted (to 10⁻³), and the report
/// naming the budget exactly when a warning does.
fn run(scene: &Scene, settings: &SolveSettings) -> SolveRun {
    let run = solve(scene, settings, &Progress::hidden()).unwrap();
    run.mesh.validate().unwrap();
    for b in &run.mesh.radiosity {
        assert!(b.is_finite() && b.min_element() >= 0.0, "radiosity {b}");
    }
    let p = &run.report.power;
    for c in 0..3 {
        assert!(p.emitted[c] > 0.0 && p.absorbed[c].is_finite(), "{p:?}");
        // The defect correction's rays are unbiased, not exact: in these
        // closed scenes they leave the balance within 2·10⁻³ (the sealed
        // rooms at 16 MiB, seeds 0–3: 1.0013, 1.0004, 1.0009, 1.0013 of
        // the emitted; 0.9996 without the correction).
        assert!(p.absorbed[c] <= p.emitted[c] * (1.0 + 2e-3), "{p:?}");
    }
    let warned = run.report.warnings.iter().find(|w| w.contains("budget"));
    match &run.report.budget {
        Some(hit) => {
            let w = warned.expect("a budget warning");
            assert!(w.contains(hit.kind.option()), "{w}");
            assert!(!w.contains('\n'), "{w}");
        }
        None => assert!(warned.is_none(), "{warned:?}"),
    }
    run
}

fn hit(run: &SolveRun) -> BudgetHit {
    run.report.budget.expect("a budget is reported")
}

#[test]
fn element_budget_bounds_the_hierarchy() {
    let scene = cornell();
    let r = run(&scene, &settings(|h| h.accuracy.max_elements = Some(2_000)));
    let hit = hit(&r);
    let elements = r.report.counts.elements as u64;
    assert_eq!(hit.kind, Budget::Elements);
    assert_eq!((hit.limit, hit.reached), (2_000, elements));
    // A split adds four: the refused one came within four of the limit.
    assert!(elements <= 2_000 && elements + 4 > 2_000, "{elements}");
    let json = serde_json::to_value(&r.report).unwrap();
    assert_eq!(
        json["budget"],
        serde_json::json!({"kind": "elements", "limit": 2000, "reached": elements})
    );
}

/// A budget so small that the initial linking runs into it: the
/// discontinuity-guided splits that follow are refused too, and no
/// refinement round follows the first solve.
#[test]
fn tiny_element_budget_binds_linking_and_guided_splits() {
    let scene = cornell();
    let r = run(&scene, &settings(|h| h.accuracy.max_elements = Some(120)));
    assert_eq!(hit(&r).kind, Budget::Elements);
    assert!(r.report.counts.elements <= 120, "{:?}", r.report.counts);
    assert_eq!(
        r.report.convergence.rounds.len(),
        1,
        "no round after the hit"
    );
}

#[test]
fn memory_budget_bounds_the_estimate() {
    // The Cornell box's first linking does not fit 4 MiB: it starts again
    // with coarser thresholds, and the budget then stops refinement. The
    // sealed rooms' fits 16 MiB; with clusters the estimate counts the kept
    // cluster links at their own size: the count it was checked against is
    // the report's.
    let rooms = bundled_scene("hard/sealed-rooms.gltf");
    for (scene, clustering, budget) in [
        (cornell(), Clustering::Off, 4 << 20),
        (rooms, Clustering::On, 16 << 20),
    ] {
        let r = run(
            &scene,
            &settings(|h| {
                h.memory_budget = budget;
                h.clustering = clustering;
            }),
        );
        let hit = hit(&r);
        let c = &r.report.counts;
        let cluster_links = c.cluster_links.expect("hierarchical counts cluster links");
        assert_eq!(cluster_links > 0, clustering == Clustering::On, "{c:?}");
        assert_eq!(r.report.coarsened.is_some(), clustering == Clustering::Off);
        let estimate = memory_estimate(c.elements as u64, c.links, cluster_links);
        assert_eq!(hit.kind, Budget::Memory);
        assert_eq!((hit.limit, hit.reached), (budget, estimate));
        assert!(estimate <= budget, "{estimate} > {budget}");
        // The estimate bounds what the solution holds.
        assert!(
            c.memory_bytes <= estimate,
            "{} > {estimate}",
            c.memory_bytes
        );
        // Not refused far below the limit: a quarter of it at least.
        assert!(4 * estimate > budget, "{estimate}");
    }
}

#[test]
fn link_budget_is_reported() {
    let scene = cornell();
    let r = run(&scene, &settings(|h| h.accuracy.max_links = Some(2_000)));
    let hit = hit(&r);
    assert_eq!(hit.kind, Budget::Links);
    assert_eq!((hit.limit, hit.reached), (2_000, r.report.counts.links));
    assert!(hit.reached <= 2_000);
}

/// A time budget already spent when linking starts: no element is split
/// and no cluster pair opened unless its nodes touch (their error would
/// be unbounded); the links as they are get solved, and the report says
/// so.
#[test]
fn spent_time_budget_solves_the_first_links() {
    let scene = cornell();
    let free = run(&scene, &settings(|h| h.clustering = Clustering::On));
    assert!(free.report.budget.is_none());
    let mut spent = settings(|h| {
        h.clustering = Clustering::On;
        h.time_budget = Some(1e-9);
    });
    // More rows than a budgeted render always samples (16).
    spent.view.height = Some(48);
    let r = run(&scene, &spent);
    let hit = hit(&r);
    assert_eq!(hit.kind, Budget::Time);
    assert_eq!(hit.limit, 0);
    assert_eq!(
        r.report.convergence.rounds.len(),
        1,
        "no round after the hit"
    );
    let (c, f) = (&r.report.counts, &free.report.counts);
    assert_eq!(c.elements, c.patches, "nothing split");
    assert!(c.links < f.links / 10, "{} vs {}", c.links, f.links);
    assert!(c.cluster_links > Some(0), "{c:?}");
    // The budget covers the whole run: the output mesh's points after its
    // share took their leaves' values, the render one sample a pixel.
    let (late, free_mesh) = (
        r.report.mesh.as_ref().unwrap(),
        free.report.mesh.as_ref().unwrap(),
    );
    assert!(
        late.evaluations > 0 && late.late_evaluations == late.evaluations,
        "{late:?}"
    );
    assert_eq!(free_mesh.late_evaluations, 0);
    let said = |run: &SolveRun, what: &str| run.report.warnings.iter().any(|w| w.starts_with(what));
    assert!(
        said(&r, "output mesh:")
            && said(&r, "render:")
            && said(&r, "hierarchical: 0 of")
            && said(&r, "shadow lines:"),
        "{:?}",
        r.report.warnings
    );
    assert!(!said(&free, "output mesh:") && !said(&free, "render:"));
    // Rows begun after the budget took no sample and show their nearest
    // rendered row: none is left black.
    for what in ["got fewer samples", "got no sample"] {
        assert!(
            r.report.warnings.iter().any(|w| w.contains(what)),
            "{what}: {:?}",
            r.report.warnings
        );
    }
    let f = &r.frame;
    for row in f.pixels.chunks(f.width as usize) {
        assert!(
            row.iter().any(|p| p.iter().any(|&c| c > 0.0)),
            "a black row"
        );
    }
    assert!(!said(&free, "shadow lines:") && !said(&free, "hierarchical: 0 of"));
    // No correction pass began after the budget was spent.
    assert!(r.report.correction.is_none());
    assert!(free.report.correction.is_some_and(|c| !c.passes.is_empty()));
}

/// The budget's clock may start before the solve (`nusselt solve` starts
/// it with the command, so that loading counts): a budget spent by then
/// binds refinement and the output mesh as one spent during the solve.
#[test]
fn a_budget_spent_before_the_solve_binds_it() {
    let scene = cornell();
    let mut s = settings(|h| h.time_budget = Some(10.0));
    s.budget_start = Instant::now().checked_sub(Duration::from_secs(11));
    assert!(s.budget_start.is_some(), "the clock cannot go back 11 s");
    let r = run(&scene, &s);
    assert_eq!(hit(&r).kind, Budget::Time);
    assert_eq!(r.report.counts.elements, r.report.counts.patches);
    let m = r.report.mesh.as_ref().unwrap();
    assert!(
        m.evaluations > 0 && m.late_evaluations == m.evaluations,
        "{m:?}"
    );
}

/// Under a time budget that is never spent, refinement rounds settle their
/// links in batches (reading the clock between them): the hierarchy, the
/// balance and the vertex values come out as without a budget. (Settling
/// part of a round early changes which element is split first, and so the
/// order of the later decisions: on the Cornell box 0.3 % fewer elements
/// and 3.7 % fewer links.)
#[test]
fn an_unspent_time_budget_solves_as_without_one() {
    let scene = cornell();
    let free = run(&scene, &settings(|_| {}));
    let timed = run(&scene, &settings(|h| h.time_budget = Some(1e6)));
    assert!(timed.report.budget.is_none() && timed.report.warnings.is_empty());
    let (a, b) = (&free.report.counts, &timed.report.counts);
    let near = |x: u64, y: u64, tol: f64| (x as f64 / y as f64 - 1.0).abs() <= tol;
    assert!(
        near(a.elements as u64, b.elements as u64, 0.01),
        "{a:?} vs {b:?}"
    );
    assert!(near(a.links, b.links, 0.05), "{a:?} vs {b:?}");
    let mean = |r: &SolveRun| {
        r.mesh
            .radiosity
            .iter()
            .map(|b| b.as_dvec3())
            .sum::<glam::DVec3>()
            / r.mesh.radiosity.len() as f64
    };
    let (m0, m1) = (mean(&free), mean(&timed));
    assert!((m1 / m0 - 1.0).abs().max_element() < 0.01, "{m0} vs {m1}");
    for c in 0..3 {
        let ratio = |r: &SolveRun| r.report.power.absorbed[c] / r.report.power.emitted[c];
        let (f, t) = (ratio(&free), ratio(&timed));
        assert!((f - t).abs() < 2e-3, "absorbed / emitted {f} vs {t}");
    }
}

/// Cluster openings count against the link budget like splits.
#[test]
fn link_budget_binds_cluster_openings() {
    let scene = cornell();
    let r = run(
        &scene,
        &settings(|h| {
            h.clustering = Clustering::On;
            h.accuracy.max_links = Some(40);
        }),
    );
    let hit = hit(&r);
    assert_eq!(hit.kind, Budget::Links);
    assert!(hit.reached <= 40 && r.report.counts.links <= 40, "{hit:?}");
}

/// The first budget to refuse a split is the one reported; the others
/// still hold.
#[test]
fn several_budgets_each_hold() {
    let scene = cornell();
    let r = run(
        &scene,
        &settings(|h| {
            h.accuracy.max_links = Some(3_000);
            h.accuracy.max_elements = Some(1_500);
        }),
    );
    let c = &r.report.counts;
    assert!(c.links <= 3_000 && c.elements <= 1_500, "{c:?}");
    assert!(r.report.budget.is_some());
}

#[test]
fn no_budget_reached_reports_null() {
    let scene = cornell();
    let r = run(
        &scene,
        &settings(|h| {
            h.accuracy = Accuracy::preview();
            h.accuracy.max_elements = Some(1_000_000);
            h.accuracy.max_links = Some(1_000_000);
        }),
    );
    assert_eq!(r.report.budget, None);
    let json = serde_json::to_value(&r.report).unwrap();
    assert!(json["budget"].is_null(), "{}", json["budget"]);
}

#[test]
fn budgeted_solve_is_thread_independent() {
    let scene = cornell();
    let bvh = TriangleBvh::of_scene(&scene);
    let hs = HierarchicalSettings {
        accuracy: Accuracy {
            max_elements: Some(600),
            ..Accuracy::default()
        },
        ..HierarchicalSettings::default()
    };
    let solve_on = |threads| {
        on_threads(threads, || {
            solve_hierarchical_guided(&scene, &bvh, &hs, &[], &Progress::hidden())
        })
    };
    let (one, two) = (solve_on(1), solve_on(2));
    assert_eq!(one.budget, two.budget);
    assert_eq!(one.hierarchy.elements, two.hierarchy.elements);
    assert_eq!(one.links, two.links);
}

#[test]
fn cli_max_elements_writes_the_budget_to_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_path("cornell-box.gltf");
    let out = nusselt(
        &[
            "solve",
            scene.to_str().unwrap(),
            "-q",
            "-o",
            "res",
            "--max-elements",
            "500",
            "--width",
            "16",
            "--height",
            "16",
        ],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("raise --max-elements"), "{stderr}");
    let text = std::fs::read_to_string(dir.path().join("res/report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    let budget = &report["budget"];
    assert_eq!(budget["kind"], "elements", "{budget}");
    assert_eq!(budget["limit"], 500, "{budget}");
    let reached = budget["reached"].as_u64().unwrap();
    assert!(
        reached <= 500 && reached == report["counts"]["elements"],
        "{budget}"
    );
}

#[test]
fn cli_refuses_bad_budgets() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_path("cornell-box.gltf");
    let scene = scene.to_str().unwrap();
    for (flag, value) in [
        ("--max-elements", "0"),
        ("--max-elements", "-3"),
        ("--max-elements", "NaN"),
        ("--max-elements", "2.5"),
        ("--max-links", "0"),
        ("--max-links", "inf"),
        ("--memory-budget", "0"),
        ("--memory-budget", "-1"),
        ("--memory-budget", "NaN"),
        ("--time-budget", "0"),
        ("--time-budget", "-2"),
        ("--cluster-eps", "0"),
    ] {
        let arg = format!("{flag}={value}");
        let out = nusselt(&["solve", scene, "-q", &arg], dir.path());
        assert_user_error(&out, flag);
    }
    assert!(!dir.path().join("out").exists(), "nothing written");
}
