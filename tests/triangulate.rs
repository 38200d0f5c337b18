//! Patch triangulation: crack-free meshes of whole scenes with arbitrary
//! points and constraint segments, checked by `validate_patch_mesh`.

use std::sync::OnceLock;
use std::time::Instant;

use glam::DVec3;
use nusselt::Error;
use nusselt::meshing::triangulate::{
    PatchInput, PatchTriangulation, TriangulateOptions, triangulate_patches, validate_patch_mesh,
};
use nusselt::scene::{Patch, Scene, Shape};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use crate::fixtures::bundled_scene;

/// The Cornell box, loaded once for the module.
fn cornell() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(crate::fixtures::cornell)
}

/// The point at patch parameters (u, v), extended linearly beyond [0, 1].
fn at(p: &Patch, u: f64, v: f64) -> DVec3 {
    let c = p.vertices();
    c[0] + u * (c[1] - c[0]) + v * (c[c.len() - 1] - c[0])
}

fn empty_inputs(scene: &Scene) -> Vec<PatchInput> {
    vec![PatchInput::default(); scene.patches.len()]
}

fn triangulate_and_validate(
    scene: &Scene,
    inputs: &[PatchInput],
    opts: &TriangulateOptions,
) -> Vec<PatchTriangulation> {
    let tris = triangulate_patches(scene, inputs, opts).expect("triangulation succeeds");
    if let Err(e) = validate_patch_mesh(scene, &tris, inputs) {
        panic!("invalid patch mesh: {e}");
    }
    tris
}

/// Random points and segments reaching past every patch, so that they cross
/// each other and the boundary.
fn random_inputs(scene: &Scene, seed: u64, points: usize, segments: usize) -> Vec<PatchInput> {
    let mut rng = Pcg64::seed_from_u64(seed);
    scene
        .patches
        .iter()
        .map(|p| {
            let mut r = || rng.random_range(-0.3..1.3);
            PatchInput {
                points: (0..points).map(|_| at(p, r(), r())).collect(),
                segments: (0..segments)
                    .map(|_| [at(p, r(), r()), at(p, r(), r())])
                    .collect(),
            }
        })
        .collect()
}

fn vertex_count(tris: &[PatchTriangulation]) -> usize {
    tris.iter().map(|t| t.positions.len()).sum()
}

#[test]
fn cornell_box_with_random_points_and_crossing_segments() {
    let scene = cornell();
    let inputs = random_inputs(scene, 7, 12, 8);
    let start = Instant::now();
    let plain = triangulate_and_validate(scene, &inputs, &TriangulateOptions::default());
    let plain_time = start.elapsed();
    let start = Instant::now();
    let refined = triangulate_and_validate(scene, &inputs, &TriangulateOptions::refined());
    let refined_time = start.elapsed();
    eprintln!(
        "cornell: {} patches, plain {:.1} ms ({} vertices), refined {:.1} ms ({} vertices)",
        scene.patches.len(),
        plain_time.as_secs_f64() * 1e3,
        vertex_count(&plain),
        refined_time.as_secs_f64() * 1e3,
        vertex_count(&refined),
    );
    assert!(plain.iter().all(|t| !t.constrained_edges.is_empty()));
    assert!(vertex_count(&refined) > vertex_count(&plain));
    // Refinement leaves fewer small angles.
    let skinny = |tris: &[PatchTriangulation]| {
        let (mut bad, mut all) = (0usize, 0usize);
        for t in tris {
            for tri in &t.triangles {
                all += 1;
                if min_angle_deg(tri.map(|i| t.positions[i as usize])) < 20.0 {
                    bad += 1;
                }
            }
        }
        bad as f64 / all as f64
    };
    assert!(
        skinny(&refined) < 0.5 * skinny(&plain),
        "refined {} plain {}",
        skinny(&refined),
        skinny(&plain)
    );
}

fn min_angle_deg(p: [DVec3; 3]) -> f64 {
    (0..3)
        .map(|k| {
            let (a, b, c) = (p[k], p[(k + 1) % 3], p[(k + 2) % 3]);
            (b - a).angle_between(c - a).to_degrees()
        })
        .fold(180.0, f64::min)
}

#[test]
fn triangulation_is_deterministic() {
    let scene = cornell();
    let inputs = random_inputs(scene, 11, 6, 6);
    let opts = TriangulateOptions::refined();
    let a = triangulate_patches(scene, &inputs, &opts).unwrap();
    let b = triangulate_patches(scene, &inputs, &opts).unwrap();
    assert_eq!(a, b);
}

#[test]
fn three_rooms_boundaries_have_twins() {
    let scene = bundled_scene("three-rooms.gltf");
    let inputs = empty_inputs(&scene);
    let start = Instant::now();
    let tris = triangulate_and_validate(&scene, &inputs, &TriangulateOptions::default());
    let elapsed = start.elapsed();
    let corners: usize = scene.patches.iter().map(|p| p.vertices().len()).sum();
    eprintln!(
        "three-rooms: {} patches, {:.1} ms, {} vertices ({} corners)",
        scene.patches.len(),
        elapsed.as_secs_f64() * 1e3,
        vertex_count(&tris),
        corners
    );
    // Small furniture meets big walls and floors: their corners must have
    // been inserted into the big patches' edges.
    let split = tris
        .iter()
        .zip(&scene.patches)
        .filter(|(t, p)| t.positions.len() > p.vertices().len())
        .count();
    assert!(split > 0, "no patch edge received a neighbour's vertex");
}

#[test]
fn constraints_touching_and_coinciding_with_the_boundary() {
    let scene = cornell();
    let mut inputs = empty_inputs(scene);
    // Bilinear parameters, quads only: (1, v) lies on the edge p1–p2.
    let quads: Vec<usize> = (0..scene.patches.len())
        .filter(|&i| scene.patches[i].shape == Shape::Quad)
        .take(6)
        .collect();
    assert!(!quads.is_empty());
    for &i in &quads {
        let p = &scene.patches[i];
        inputs[i].segments = vec![
            // Along an edge, extending past both corners.
            [p.point(-0.5, 0.0), p.point(1.5, 0.0)],
            // Part of another edge.
            [p.point(1.0, 0.2), p.point(1.0, 0.7)],
            // Corner to corner, and corner to an edge's middle.
            [p.point(0.0, 0.0), p.point(1.0, 1.0)],
            [p.point(1.0, 0.0), p.point(0.0, 0.5)],
            // Ends on the diagonal (a T) and on the other segment's end.
            [p.point(0.25, 0.0), p.point(0.5, 0.5)],
            [p.point(0.0, 0.5), p.point(0.25, 0.9)],
            // Collinear overlap with the diagonal.
            [p.point(0.4, 0.4), p.point(0.8, 0.8)],
            // Outside altogether, and touching the boundary from outside
            // (nothing of either is inside).
            [p.point(1.2, 0.1), p.point(1.5, 0.9)],
            [p.point(1.5, 0.5), p.point(1.0, 0.5)],
        ];
        inputs[i].points = vec![p.point(0.0, 0.3), p.point(0.5, 0.5), p.point(1.0, 1.0)];
    }
    let tris = triangulate_and_validate(scene, &inputs, &TriangulateOptions::default());
    for &i in &quads {
        let t = &tris[i];
        let p = &scene.patches[i];
        let tol = 1e-9 * scene.diagonal();
        let has_vertex = |x: DVec3| t.positions.iter().any(|&v| (v - x).length() < tol);
        for (u, v) in [(0.0, 0.5), (0.25, 0.0), (1.0, 0.2), (1.0, 0.7), (0.5, 0.5)] {
            assert!(
                has_vertex(p.point(u, v)),
                "patch {i}: no vertex at ({u}, {v})"
            );
        }
    }
}

#[test]
fn duplicate_and_reversed_segments_change_nothing() {
    let scene = cornell();
    let base = random_inputs(scene, 3, 4, 5);
    let mut doubled = base.clone();
    for input in &mut doubled {
        let extra: Vec<[DVec3; 2]> = input
            .segments
            .iter()
            .flat_map(|&[a, b]| [[b, a], [a, b], [b, a]])
            .collect();
        input.segments.extend(extra);
        input.points.extend(input.points.clone());
    }
    let opts = TriangulateOptions::default();
    let once = triangulate_and_validate(scene, &base, &opts);
    let many = triangulate_and_validate(scene, &doubled, &opts);
    assert_eq!(once, many);
}

#[test]
fn bad_inputs_are_errors() {
    let scene = cornell();
    let mut inputs = empty_inputs(scene);
    inputs[0]
        .segments
        .push([DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 0.0)]);
    let err = triangulate_patches(scene, &inputs, &TriangulateOptions::default()).unwrap_err();
    assert!(
        matches!(&err, Error::Mesh(m) if m.contains("patch 0: segment 0")),
        "{err}"
    );
    let err = triangulate_patches(scene, &inputs[1..], &TriangulateOptions::default());
    assert!(matches!(err, Err(Error::Mesh(_))));
    let opts = TriangulateOptions {
        min_angle_deg: Some(60.0),
        max_added_vertices: 10,
    };
    let err = triangulate_patches(scene, &empty_inputs(scene), &opts);
    assert!(matches!(err, Err(Error::Setting(_))));
}

#[test]
fn the_validator_finds_cracks() {
    let scene = cornell();
    let inputs = random_inputs(scene, 5, 3, 3);
    let good = triangulate_and_validate(scene, &inputs, &TriangulateOptions::default());
    // A neighbour's boundary vertex moved: its edges lose their twins.
    let mut bad = good.clone();
    let t = &mut bad[0];
    let [u, _] = t.boundary_edges[0];
    t.positions[u as usize] += DVec3::splat(1e-12);
    assert!(validate_patch_mesh(scene, &bad, &inputs).is_err());
    // A missing triangle leaves a hole.
    let mut bad = good.clone();
    bad[1].triangles.pop();
    assert!(validate_patch_mesh(scene, &bad, &inputs).is_err());
    // A flipped triangle.
    let mut bad = good;
    bad[2].triangles[0].swap(0, 1);
    assert!(validate_patch_mesh(scene, &bad, &inputs).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Arbitrary segments and points on two neighbouring Cornell patches.
    #[test]
    fn arbitrary_segments_on_cornell_patches(
        segs in prop::collection::vec((-0.5f64..1.5, -0.5f64..1.5, -0.5f64..1.5, -0.5f64..1.5), 0..12),
        pts in prop::collection::vec((-0.2f64..1.2, -0.2f64..1.2), 0..12),
        snap in any::<bool>(),
        refine in any::<bool>(),
    ) {
        let scene = cornell();
        let mut inputs = empty_inputs(scene);
        // Snapping to a coarse grid makes coincidences and collinearity likely.
        let s = |x: f64| if snap { (x * 8.0).round() / 8.0 } else { x };
        for patch in [0usize, 1] {
            let p = &scene.patches[patch];
            inputs[patch].segments = segs
                .iter()
                .map(|&(a, b, c, d)| [at(p, s(a), s(b)), at(p, s(c), s(d))])
                .collect();
            inputs[patch].points = pts.iter().map(|&(u, v)| at(p, s(u), s(v))).collect();
        }
        let opts = if refine { TriangulateOptions::refined() } else { TriangulateOptions::default() };
        let tris = triangulate_patches(scene, &inputs, &opts);
        prop_assert!(tris.is_ok(), "{:?}", tris.err());
        let check = validate_patch_mesh(scene, &tris.unwrap(), &inputs);
        prop_assert!(check.is_ok(), "{:?}", check.err());
    }
}

/// Regression: a clipped segment end 1.35e-7 from a corner of the Cornell
/// box's right wall lay within reach of both edges through that corner and
/// was put on both, leaving a degenerate triangle and a T-vertex.
#[test]
fn point_near_a_corner_goes_on_one_edge_only() {
    let scene = cornell();
    let mut inputs = empty_inputs(scene);
    for patch in [0usize, 1] {
        let p = &scene.patches[patch];
        inputs[patch].segments = vec![[at(p, 0.75, -0.375), at(p, 1.25, 0.375)]];
    }
    triangulate_and_validate(scene, &inputs, &TriangulateOptions::default());
}

/// Random byte strings through the fuzz target's body; set
/// `NUSSELT_STRESS=<cases>` for a longer run.
#[test]
fn random_fuzz_inputs_validate() {
    let cases: usize = std::env::var("NUSSELT_STRESS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    let mut rng = Pcg64::seed_from_u64(99);
    for case in 0..cases {
        let len = rng.random_range(1..200);
        let data: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        if let Err(e) = nusselt::fuzz::fuzz_triangulate(&data) {
            panic!("case {case} ({data:?}): {e}");
        }
    }
}
