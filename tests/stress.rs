//! The stress scenes of `scenes/stress/` (see `scenes/README.md`): the
//! invariants every method must keep where methods fail.
//!
//! On a fast subset (the hierarchical solver at the `preview` and `default`
//! presets; the classic solvers on a uniform mesh with the point-polygon
//! kernel): no panic; every output vertex, pixel and power finite and
//! non-negative; the power absorbed never above the power emitted by more
//! than [`ENERGY_TOL`]; non-convergence reported (`converged: false` and a
//! warning) rather than hidden; the emitted power equal to the scene's; and
//! on `shared-edge`, the form factor of its closed form.
//!
//! Slow scenes (the hierarchical solver on `furnace-099` and
//! `many-emitters`) run only with `NUSSELT_SLOW_TESTS=1`; their known
//! energy excess is stated and bounded there.

use nusselt::classic::matrix::{FormFactorMatrix, Kernel, MatrixSettings};
use nusselt::classic::solve::{ClassicMethod, Convergence, System};
use nusselt::classic::uniform::UniformMesh;
use nusselt::formfactor::closed_form::c14;
use nusselt::hierarchical::{Accuracy, HierarchicalSettings, solve_hierarchical};
use nusselt::pipeline::{Method, SolveRun, SolveSettings, solve};
use nusselt::render::RenderSettings;
use nusselt::render::view::ViewOverrides;
use nusselt::report::Report;
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use crate::fixtures::{slow_tests, stress_scene};

/// Largest relative excess of absorbed over emitted power accepted in the
/// fast subset (per channel).
const ENERGY_TOL: f64 = 0.02;

/// [`ENERGY_TOL`] for `tiny-emitter` under the hierarchical solver, whose
/// links leave 2.1 % too much (measured at the preview preset; why: see
/// [`a_lamp_next_to_a_wall_delivers_its_power_to_the_closed_room`]).
const TINY_EMITTER_TOL: f64 = 0.03;

/// Stress scenes of the fast subset: every one but `furnace-099` and
/// `many-emitters`, whose hierarchical solves take minutes or tens of
/// seconds (see [`slow_scenes_keep_the_invariants`]).
const FAST: [&str; 9] = [
    "nearly-touching",
    "penetrating-box",
    "coplanar-overlap",
    "slivers",
    "tiny-emitter",
    "scale-range",
    "facing-away",
    "open-floor",
    "shared-edge",
];

const CLASSIC: [ClassicMethod; 4] = [
    ClassicMethod::Direct,
    ClassicMethod::Jacobi,
    ClassicMethod::GaussSeidel,
    ClassicMethod::Shooting,
];

/// Settings of a small, quick run: a 48 × 32 render at 1 sample per pixel.
fn quick(method: Method) -> SolveSettings {
    SolveSettings {
        method,
        render: RenderSettings::with_samples(1, 0),
        view: ViewOverrides {
            width: Some(48),
            height: Some(32),
            ..ViewOverrides::default()
        },
        ..SolveSettings::default()
    }
}

fn hierarchical(accuracy: Accuracy) -> SolveSettings {
    SolveSettings {
        hierarchical: HierarchicalSettings {
            accuracy,
            ..HierarchicalSettings::default()
        },
        ..quick(Method::Hierarchical)
    }
}

/// Runs `settings` on `scene` and checks the invariants of every run;
/// `energy_tol` bounds absorbed / emitted − 1.
fn run_checked(name: &str, scene: &Scene, settings: &SolveSettings, energy_tol: f64) -> SolveRun {
    let label = format!("{name} ({})", settings.method.name());
    let run = solve(scene, settings, &Progress::hidden())
        .unwrap_or_else(|e| panic!("{label}: solve failed: {e}"));
    run.mesh
        .validate()
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    assert!(run.mesh.vertex_count() > 0, "{label}: empty output mesh");
    for (k, b) in run.mesh.radiosity.iter().enumerate() {
        assert!(
            b.is_finite() && b.min_element() >= 0.0,
            "{label}: vertex {k} at {} has radiosity {b}",
            run.mesh.positions[k]
        );
    }
    for p in &run.frame.pixels {
        assert!(
            p.iter().all(|c| c.is_finite() && *c >= 0.0),
            "{label}: pixel {p:?}"
        );
    }
    check_report(&label, scene, &run.report, energy_tol);
    run
}

fn check_report(label: &str, scene: &Scene, report: &Report, energy_tol: f64) {
    let power = &report.power;
    let phi = scene.emitted_power().to_array();
    for (c, phi) in phi.into_iter().enumerate() {
        let (e, a, r) = (power.emitted[c], power.absorbed[c], power.radiated[c]);
        assert!(
            e.is_finite() && a.is_finite() && r.is_finite(),
            "{label}: power {power:?}"
        );
        assert!(
            (e - phi).abs() <= 1e-9 * phi.max(1.0),
            "{label}: emitted {e} W, the scene emits {phi} W"
        );
        assert!(a >= 0.0, "{label}: absorbed {a} W");
        assert!(
            r >= e * (1.0 - 1e-9),
            "{label}: radiated {r} W below emitted {e} W"
        );
        assert!(
            a <= e * (1.0 + energy_tol),
            "{label}: absorbed {a} W exceeds emitted {e} W by more than {energy_tol}"
        );
    }
    let conv = &report.convergence;
    assert_eq!(conv.iterations, conv.history.len(), "{label}");
    assert!(
        conv.history.iter().all(|h| h.residual.is_finite()),
        "{label}: a residual is not finite"
    );
    let warned = report
        .warnings
        .iter()
        .any(|w| w.contains("did not reach the tolerance"));
    assert_eq!(
        warned, !conv.converged,
        "{label}: converged = {} but warnings {:?}",
        conv.converged, report.warnings
    );
}

#[test]
fn hierarchical_keeps_the_invariants_on_the_fast_subset() {
    for name in FAST {
        let scene = stress_scene(name);
        for accuracy in [Accuracy::preview(), Accuracy::default()] {
            let tol = if name == "tiny-emitter" {
                TINY_EMITTER_TOL
            } else {
                ENERGY_TOL
            };
            let run = run_checked(name, &scene, &hierarchical(accuracy), tol);
            assert!(run.report.convergence.converged, "{name}: not converged");
        }
    }
}

#[test]
fn classic_solvers_keep_the_invariants_on_the_fast_subset() {
    for name in FAST {
        let scene = stress_scene(name);
        for method in CLASSIC {
            let settings = SolveSettings {
                // A coarser mesh than the default keeps the dense matrices small.
                element_size: Some(scene.diagonal() / 15.0),
                ..quick(Method::Classic(method))
            };
            let run = run_checked(name, &scene, &settings, ENERGY_TOL);
            assert!(
                run.report.convergence.converged,
                "{name}: {} not converged",
                method.name()
            );
        }
    }
}

#[test]
fn receivers_of_emitters_facing_away_stay_black() {
    let scene = stress_scene("facing-away");
    for settings in [
        hierarchical(Accuracy::preview()),
        quick(Method::Classic(ClassicMethod::Jacobi)),
    ] {
        let run = run_checked("facing-away", &scene, &settings, ENERGY_TOL);
        assert_eq!(run.report.power.absorbed, [0.0; 3]);
        for (k, b) in run.mesh.radiosity.iter().enumerate() {
            let emitter = scene.patches[run.mesh.patch[k] as usize].is_emitter();
            if !emitter {
                assert_eq!(*b, glam::Vec3::ZERO, "vertex {k}");
            }
        }
    }
}

/// The ρ = 0.99 furnace on a coarse uniform mesh (6 × 25 elements).
fn coarse_furnace(method: ClassicMethod, max_iterations: usize) -> SolveSettings {
    SolveSettings {
        element_size: Some(0.2),
        convergence: Convergence {
            tolerance: 1e-6,
            max_iterations,
        },
        ..quick(Method::Classic(method))
    }
}

#[test]
fn jacobi_on_the_099_furnace_reports_that_it_did_not_converge() {
    let scene = stress_scene("furnace-099");
    // Jacobi's error falls by ρ = 0.99 per sweep: 20 sweeps are far from
    // 1e-6, and the report must say so.
    let run = run_checked(
        "furnace-099",
        &scene,
        &coarse_furnace(ClassicMethod::Jacobi, 20),
        ENERGY_TOL,
    );
    let conv = &run.report.convergence;
    assert!(!conv.converged);
    assert_eq!(conv.iterations, 20);
    assert!(conv.history.last().unwrap().residual > conv.tolerance);
    // Unconverged gathering has not yet delivered all the power.
    assert!(run.report.power.absorbed[0] < 0.9 * run.report.power.emitted[0]);

    // Solved to the end (direct), the closed box absorbs what it emits:
    // within ENERGY_TOL with the polygon-polygon kernel (measured 0.014 %).
    // KNOWN WEAKNESS: the point-polygon kernel's rows sum to 1 but are not
    // reciprocal, and ρ = 0.99 amplifies that by 1 / (1 − ρ) = 100: on
    // these 0.2 m elements the box absorbs 2.7 % more than it emits (0.9 %
    // on 0.1 m elements); bounded here at 4 %.
    for (kernel, tol) in [
        (Kernel::PolygonPolygon, ENERGY_TOL),
        (Kernel::PointPolygon, 0.04),
    ] {
        let settings = SolveSettings {
            matrix: MatrixSettings {
                kernel,
                ..MatrixSettings::default()
            },
            ..coarse_furnace(ClassicMethod::Direct, 1)
        };
        let run = run_checked("furnace-099", &scene, &settings, tol);
        assert!(run.report.convergence.converged);
        let p = &run.report.power;
        let balance = p.absorbed[0] / p.emitted[0];
        eprintln!(
            "furnace-099 direct, {}: absorbed / emitted {balance:.5}",
            kernel.name()
        );
        assert!(
            (balance - 1.0).abs() < tol,
            "{}: absorbed / emitted {balance}",
            kernel.name()
        );
    }
}

#[test]
fn hierarchical_on_the_099_furnace_reports_that_it_did_not_converge() {
    let scene = stress_scene("furnace-099");
    let settings = SolveSettings {
        hierarchical: HierarchicalSettings {
            accuracy: Accuracy {
                max_rounds: 1,
                ..Accuracy::preview()
            },
            max_iterations: 2,
            ..HierarchicalSettings::default()
        },
        ..quick(Method::Hierarchical)
    };
    let run = run_checked("furnace-099", &scene, &settings, ENERGY_TOL);
    // Every solve stops at the cap: the round's and each correction
    // pass's, so the history holds two per solve. (Two: Anderson mixing
    // settles a uniform furnace in four.)
    let conv = &run.report.convergence;
    assert!(!conv.converged);
    assert_eq!(conv.rounds[0].iterations, 2);
    let passes = run.report.correction.as_ref().map_or(0, |c| c.passes.len());
    assert_eq!(conv.iterations, 2 * (1 + passes));
}

/// Howell C-14 for the two unit squares of `shared-edge`.
fn shared_edge_form_factor() -> f64 {
    c14(1.0, 1.0, 1.0)
}

/// The receiver's share of the emitter's power, from the energy report:
/// the black emitter radiates E·A = 1 W; the receiver adds ρ F E A.
fn form_factor_from_report(report: &Report) -> f64 {
    (report.power.radiated[0] - report.power.emitted[0]) / 0.5
}

fn receiver_patch(scene: &Scene) -> u32 {
    let receiver = scene
        .patches
        .iter()
        .position(|p| !p.is_emitter())
        .expect("shared-edge has a receiver");
    receiver as u32
}

#[test]
fn shared_edge_form_factor_matches_its_closed_form() {
    let scene = stress_scene("shared-edge");
    let exact = shared_edge_form_factor();
    assert!((exact - 0.200044).abs() < 1e-6, "C-14 gives {exact}");
    let receiver = receiver_patch(&scene);
    assert_eq!(scene.patches.len(), 2);
    assert!(scene.patches[receiver as usize].area > 0.999);

    // The hierarchy: the flux onto the receiver's leaves, and the report.
    let bvh = TriangleBvh::of_scene(&scene);
    for (accuracy, tol) in [(Accuracy::preview(), 0.01), (Accuracy::default(), 0.005)] {
        let settings = HierarchicalSettings {
            accuracy,
            ..HierarchicalSettings::default()
        };
        let s = solve_hierarchical(&scene, &bvh, &settings, &Progress::hidden());
        let h = &s.hierarchy;
        let flux: f64 = h
            .leaves()
            .map(|id| id.index())
            .filter(|&i| h.elements[i].patch == receiver)
            .map(|i| s.irradiance[i].x * h.elements[i].area)
            .sum();
        let err = (flux - exact).abs() / exact;
        eprintln!("shared-edge hierarchical: F = {flux:.6} (exact {exact:.6}), error {err:.2e}");
        assert!(err < tol, "hierarchical F = {flux}, exact {exact}");
        let run = run_checked(
            "shared-edge",
            &scene,
            &SolveSettings {
                hierarchical: settings,
                ..quick(Method::Hierarchical)
            },
            ENERGY_TOL,
        );
        let f = form_factor_from_report(&run.report);
        assert!(
            (f - exact).abs() / exact < tol,
            "report: F = {f}, exact {exact}"
        );
    }

    // The classic kernels on a uniform mesh: the flux onto the receiver's
    // elements. Stated tolerances (the kernel's own error at the shared
    // edge, where the integrand is singular, on 0.125 m elements):
    // polygon-polygon 0.5 %, point-polygon 3 %, sampling 5 %, hemicube 5 %.
    let mesh = UniformMesh::new(&scene, 0.125);
    let (reflectance, emission, area) = mesh.element_values(&scene);
    for (kernel, tol) in [
        (Kernel::PolygonPolygon, 0.005),
        (Kernel::PointPolygon, 0.03),
        (Kernel::Sampling, 0.05),
        (Kernel::Hemicube, 0.05),
    ] {
        let settings = MatrixSettings {
            kernel,
            hemicube_resolution: 64,
            ..MatrixSettings::default()
        };
        let (matrix, _) =
            FormFactorMatrix::assemble(&mesh, &bvh, &settings, &Progress::hidden()).unwrap();
        let system = System {
            matrix: &matrix,
            reflectance: &reflectance,
            emission: &emission,
            area: &area,
        };
        let solution = nusselt::classic::solve::solve(
            &system,
            ClassicMethod::Direct,
            &Convergence::default(),
            settings.memory_budget,
            &mut |_, _| {},
        )
        .unwrap();
        let flux: f64 = (0..mesh.elements.len())
            .filter(|&i| mesh.elements[i].patch == receiver)
            .map(|i| solution.irradiance[i].x * area[i])
            .sum();
        let err = (flux - exact).abs() / exact;
        eprintln!(
            "shared-edge {}: F = {flux:.6} (exact {exact:.6}), error {err:.2e}",
            kernel.name()
        );
        assert!(err < tol, "{}: F = {flux}, exact {exact}", kernel.name());
    }
}

/// The hierarchical solver on the slow stress scenes, with the energy
/// excess each is known to have (KNOWN WEAKNESS, measured at `preview`):
/// `furnace-099` absorbed 23.5 % more than it emits when this was written
/// (every form-factor error is amplified by 1 / (1 − ρ) = 100; 2.2 M links
/// in about 160 s), 0.9936 of it with the defect correction (2026-12-03);
/// `many-emitters` (2 304 emitter patches) absorbed 1.141 of its power
/// from 5f8bece until 2026-12-04: `sharpen` let dim links keep an error of
/// 5 % of the oracle's threshold each, and a wall's 2 304 links to the
/// emitters added theirs up. With that tolerance capped at a tenth of F
/// it is 0.997 without the correction and 1.018 with it (default preset
/// 1.018).
#[test]
fn slow_scenes_keep_the_invariants() {
    if !slow_tests("stress::slow_scenes_keep_the_invariants") {
        return;
    }
    for (name, energy_tol) in [("furnace-099", 0.3), ("many-emitters", 0.03)] {
        let scene = stress_scene(name);
        let run = run_checked(name, &scene, &hierarchical(Accuracy::preview()), energy_tol);
        let p = &run.report.power;
        eprintln!(
            "{name}: {} elements, {} links, absorbed / emitted {:.4}, converged {}",
            run.report.counts.elements,
            run.report.counts.links,
            p.absorbed[0] / p.emitted[0],
            run.report.convergence.converged
        );
    }
    let scene = stress_scene("many-emitters");
    for method in CLASSIC {
        run_checked(
            "many-emitters",
            &scene,
            &SolveSettings {
                element_size: Some(scene.diagonal() / 15.0),
                ..quick(Method::Classic(method))
            },
            ENERGY_TOL,
        );
    }
}

#[test]
fn a_lamp_next_to_a_wall_delivers_its_power_to_the_closed_room() {
    // A 1 cm² emitter 2 mm from a wall: the wall's own sample points are all
    // far from the hot spot, and the form factor estimated from them alone
    // is about 10⁵ times too small (measured before the reciprocal check:
    // 0.001 % of the power absorbed). The room is closed: absorbed = emitted.
    let scene = stress_scene("tiny-emitter");
    for (name, accuracy) in [
        ("preview", Accuracy::preview()),
        ("default", Accuracy::default()),
    ] {
        // KNOWN WEAKNESS, bounded here: the lamp is black, so it absorbs
        // what the hot spot under it sends back, and that light is not
        // taken from what the wall sends elsewhere (the wall's links carry
        // its mean radiosity, and their visibility rays rarely meet the
        // 1 cm² lamp). Measured (2026-12-03): absorbed / emitted 1.021
        // (preview), 1.014 (default); with the walls black, 1.000 and
        // 0.998, so the direct light is right.
        let run = run_checked(
            "tiny-emitter",
            &scene,
            &hierarchical(accuracy),
            TINY_EMITTER_TOL,
        );
        let (e, a) = (run.report.power.emitted[0], run.report.power.absorbed[0]);
        assert!(a > 0.95 * e, "{name}: absorbed {a} W of {e} W");
    }
}
