//! The classic solvers and matrix kernels on closed boxes: the furnace and
//! enclosure identities, closure and reciprocity, and agreement between
//! solvers.

use glam::DVec3;
use nusselt::classic::matrix::{FormFactorMatrix, Kernel, MatrixSettings};
use nusselt::classic::solve::{ClassicMethod, Convergence, System, solve};
use nusselt::classic::uniform::UniformMesh;
use nusselt::formfactor::form_factor_polygon_polygon;
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use crate::fixtures::furnace_box;

const METHODS: [ClassicMethod; 4] = [
    ClassicMethod::Direct,
    ClassicMethod::Jacobi,
    ClassicMethod::GaussSeidel,
    ClassicMethod::Shooting,
];

fn bvh(scene: &Scene) -> TriangleBvh {
    nusselt::visibility::TriangleBvh::of_scene(scene)
}

/// The matrix of `mesh` by exact (unoccluded) polygon-to-polygon
/// quadrature: in a convex box nothing occludes.
fn exact_matrix(mesh: &UniformMesh) -> FormFactorMatrix {
    let n = mesh.elements.len();
    let mut v = vec![0f32; n * n];
    for i in 0..n {
        for j in 0..n {
            if mesh.elements[i].patch != mesh.elements[j].patch {
                v[i * n + j] = form_factor_polygon_polygon(
                    &mesh.elements[i].corners,
                    &mesh.elements[j].corners,
                    1e-7,
                )
                .value as f32;
            }
        }
    }
    FormFactorMatrix::from_values(n, v).unwrap()
}

fn system_vectors(scene: &Scene, mesh: &UniformMesh) -> (Vec<DVec3>, Vec<DVec3>, Vec<f64>) {
    mesh.element_values(scene)
}

#[test]
fn furnace_and_enclosure_identities_hold_for_every_solver() {
    for rho in [0.5, 0.95] {
        let le = 1.0 / std::f64::consts::PI; // E = 1
        let scene = furnace_box(DVec3::new(1.0, 0.7, 1.3), le, rho);
        let mesh = UniformMesh::new(&scene, 0.5);
        let matrix = exact_matrix(&mesh);
        let (r, e, a) = system_vectors(&scene, &mesh);
        let system = System {
            matrix: &matrix,
            reflectance: &r,
            emission: &e,
            area: &a,
        };
        let expected = 1.0 / (1.0 - rho);
        let phi: f64 = e.iter().zip(&a).map(|(e, a)| e.x * a).sum();
        for method in METHODS {
            let conv = Convergence {
                tolerance: 1e-9,
                max_iterations: 1_000_000,
            };
            let s = solve(&system, method, &conv, 1 << 30, &mut |_, _| {}).unwrap();
            assert!(s.converged, "{method:?} ρ {rho}");
            for b in &s.radiosity {
                assert!(
                    ((b.x - expected) / expected).abs() < 1e-4,
                    "{method:?} ρ {rho}: B = {} vs {expected}",
                    b.x
                );
            }
            let total: f64 = s.radiosity.iter().zip(&a).map(|(b, a)| b.x * a).sum();
            let identity = phi / (1.0 - rho);
            assert!(
                ((total - identity) / identity).abs() < 1e-4,
                "{method:?} ρ {rho}: Σ B A = {total} vs {identity}"
            );
        }
    }
}

/// The furnace identity with the matrix of adaptive area sampling (rays
/// through the scene's BVH): every row sums to 1 within the kernel's
/// stated errors, and every classic solver gives B = E / (1 − ρ) to within
/// what those row sums allow.
#[test]
fn furnace_identity_holds_for_every_solver_with_adaptive_sampling() {
    let rho = 0.5;
    let scene = furnace_box(DVec3::new(1.0, 0.7, 1.3), 1.0 / std::f64::consts::PI, rho);
    let mesh = UniformMesh::new(&scene, 0.5);
    let settings = MatrixSettings {
        kernel: Kernel::Sampling,
        sampling_tolerance: 1e-3,
        ..MatrixSettings::default()
    };
    let (matrix, stats, errors) =
        FormFactorMatrix::assemble_with_errors(&mesh, &bvh(&scene), &settings, &Progress::hidden())
            .unwrap();
    let n = mesh.elements.len();
    let mut worst: f64 = 0.0;
    for i in 0..n {
        let sum: f64 = matrix.row(i).iter().map(|&f| f as f64).sum();
        let stated: f64 = errors[i * n..(i + 1) * n].iter().map(|&e| e as f64).sum();
        assert!(
            (sum - 1.0).abs() <= 2.0 * stated + 1e-6,
            "row {i}: Σ F {sum}, stated error {stated}"
        );
        worst = worst.max((sum - 1.0).abs());
    }
    assert!(worst < 2e-3, "worst row sum off by {worst}");
    assert!(stats.mean_row_error.unwrap() < 2e-3, "{stats:?}");
    let (r, e, a) = system_vectors(&scene, &mesh);
    let system = System {
        matrix: &matrix,
        reflectance: &r,
        emission: &e,
        area: &a,
    };
    let expected = 1.0 / (1.0 - rho);
    for method in METHODS {
        let conv = Convergence {
            tolerance: 1e-9,
            max_iterations: 1_000_000,
        };
        let s = solve(&system, method, &conv, 1 << 30, &mut |_, _| {}).unwrap();
        assert!(s.converged, "{method:?}");
        for b in &s.radiosity {
            // A row sum off by δ moves B by about ρ δ / (1 − ρ)² · E.
            assert!(
                ((b.x - expected) / expected).abs() < 5e-3,
                "{method:?}: B = {} vs {expected}",
                b.x
            );
        }
    }
}

#[test]
fn solvers_agree_on_the_same_matrix() {
    let mut scene = furnace_box(DVec3::ONE, 1.0, 0.7);
    // One emitting face only, as in a lit room.
    for p in scene.patches.iter_mut().skip(1) {
        p.emission = DVec3::ZERO;
    }
    scene.patches[0].emission = DVec3::new(3.0, 2.0, 1.0);
    let mesh = UniformMesh::new(&scene, 0.34);
    let matrix = exact_matrix(&mesh);
    let (r, e, a) = system_vectors(&scene, &mesh);
    let system = System {
        matrix: &matrix,
        reflectance: &r,
        emission: &e,
        area: &a,
    };
    let conv = Convergence {
        tolerance: 1e-12,
        max_iterations: 10_000_000,
    };
    let reference = solve(
        &system,
        ClassicMethod::Direct,
        &conv,
        1 << 30,
        &mut |_, _| {},
    )
    .unwrap();
    for method in METHODS {
        let s = solve(&system, method, &conv, 1 << 30, &mut |_, _| {}).unwrap();
        for (x, y) in s.radiosity.iter().zip(&reference.radiosity) {
            assert!(
                (*x - *y).abs().max_element() <= 1e-6 * y.max_element(),
                "{method:?}: {x} vs {y}"
            );
        }
    }
}

/// Row sums (closure) and reciprocity of each kernel's matrix in a closed
/// box, against the exact matrix.
#[test]
fn kernels_close_the_box_and_keep_reciprocity() {
    let scene = furnace_box(DVec3::new(1.0, 0.8, 1.2), 1.0, 0.5);
    let mesh = UniformMesh::new(&scene, 0.4);
    let bvh = bvh(&scene);
    let exact = exact_matrix(&mesh);
    let n = mesh.elements.len();
    // (kernel, closure tolerance, row L1 tolerance, reciprocity tolerance):
    // the centroid-based kernels (point-polygon, hemicube) are not
    // reciprocal for neighbouring elements, by construction; adaptive area
    // sampling is held to its tolerance (10⁻³ here) at the shared edges.
    for (kernel, closure_tol, entry_tol, reciprocity_tol) in [
        (Kernel::PolygonPolygon, 2e-3, 2e-3, 2e-3),
        (Kernel::PointPolygon, 0.05, 0.2, 0.1),
        (Kernel::Sampling, 2e-3, 2e-3, 2e-3),
        (Kernel::Hemicube, 0.05, 0.2, 0.1),
    ] {
        let settings = MatrixSettings {
            kernel,
            sampling_tolerance: 1e-3,
            hemicube_resolution: 256,
            quadrature_tolerance: 1e-5,
            ..MatrixSettings::default()
        };
        let (m, stats) =
            FormFactorMatrix::assemble(&mesh, &bvh, &settings, &Progress::hidden()).unwrap();
        assert!(
            (stats.mean_row_sum - 1.0).abs() < closure_tol,
            "{kernel:?}: mean row sum {}",
            stats.mean_row_sum
        );
        // Entry-wise against the exact matrix, in the metric of the total
        // transfer (sum of absolute errors per row).
        let worst = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| (m.get(i, j) - exact.get(i, j)).abs() as f64)
                    .sum::<f64>()
            })
            .fold(0.0, f64::max);
        assert!(worst < entry_tol, "{kernel:?}: worst row L1 error {worst}");
        // Reciprocity A_i F_ij = A_j F_ji, summed over pairs.
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            for j in 0..n {
                let (ai, aj) = (mesh.elements[i].area, mesh.elements[j].area);
                num += (ai * m.get(i, j) as f64 - aj * m.get(j, i) as f64).abs();
                den += ai * m.get(i, j) as f64;
            }
        }
        assert!(
            num / den < reciprocity_tol,
            "{kernel:?}: reciprocity error {}",
            num / den
        );
        eprintln!(
            "{kernel:?}: mean row sum {:.5}, worst row L1 error {worst:.5}, reciprocity error {:.5}",
            stats.mean_row_sum,
            num / den
        );
    }
}
