//! The output mesh of a hierarchical solution in its three modes: the mesh
//! validator (closed surfaces, no cracks or T-vertices, constraint segments
//! present), split vertices on contact lines, output adaptivity, the
//! hierarchy following the discontinuities, and thread independence.

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use nusselt::discontinuity::{DiscontinuitySettings, Segment, SegmentKind, discontinuity_segments};
use nusselt::hierarchical::{
    Accuracy, CONTACT_AREA_FRACTION, HierarchicalSettings, HierarchicalSolution,
    solve_hierarchical, solve_hierarchical_guided,
};
use nusselt::mesh::OutputMesh;
use nusselt::meshing::point_gather::{LinkRays, PointEvaluator};
use nusselt::meshing::{MeshMode, MeshSettings, MeshStats, build_mesh};
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use crate::fixtures::{cornell, on_threads};

fn preview() -> HierarchicalSettings {
    HierarchicalSettings {
        accuracy: Accuracy::preview(),
        ..HierarchicalSettings::default()
    }
}

struct Solved {
    pub scene: Scene,
    pub bvh: TriangleBvh,
    pub guide: Vec<Vec<Segment>>,
    pub solution: HierarchicalSolution,
}

fn solved_cornell(guided: bool) -> Solved {
    solved_cornell_with(guided, &preview())
}

fn solved_cornell_with(guided: bool, settings: &HierarchicalSettings) -> Solved {
    let scene = cornell();
    let bvh = TriangleBvh::of_scene(&scene);
    let guide = discontinuity_segments(&scene, &bvh, &DiscontinuitySettings::default())
        .by_patch(scene.patches.len());
    let solution = if guided {
        solve_hierarchical_guided(&scene, &bvh, settings, &guide, &Progress::hidden())
    } else {
        solve_hierarchical(&scene, &bvh, settings, &Progress::hidden())
    };
    Solved {
        scene,
        bvh,
        guide,
        solution,
    }
}

fn mesh(s: &Solved, mode: MeshMode) -> (OutputMesh, MeshStats) {
    let settings = MeshSettings {
        mode,
        ..MeshSettings::default()
    };
    build_mesh(
        &s.scene,
        &s.bvh,
        &s.solution,
        &s.guide,
        &settings,
        &Progress::hidden(),
    )
    .unwrap()
}

fn key(p: Vec3) -> [u32; 3] {
    p.to_array().map(f32::to_bits)
}

/// Distance from `x` to segment `ab`, and the segment parameter.
fn to_segment(x: DVec3, a: DVec3, b: DVec3) -> (f64, f64) {
    let d = b - a;
    let t = ((x - a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
    ((a + t * d - x).length(), t)
}

/// The validator on an output mesh: no degenerate triangles; per
/// patch, every edge (by position) in one or two triangles, those in one on
/// the patch boundary or on a contact line, where the vertex is split; no
/// vertex of any patch strictly inside another patch's boundary edge (no
/// T-vertices, so no cracks); every segment a union of mesh edges.
fn validate(scene: &Scene, mesh: &OutputMesh, segments: &[Vec<Segment>]) {
    mesh.validate().unwrap();
    let tol = 1e-5 * scene.diagonal();
    let pos = |i: u32| mesh.positions[i as usize].as_dvec3();
    let mut edges: Vec<HashMap<[[u32; 3]; 2], usize>> = vec![HashMap::new(); scene.patches.len()];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(pos);
        assert!(
            (b - a).cross(c - a).length() > 1e-12 * scene.diagonal().powi(2),
            "degenerate triangle {t:?}"
        );
        let p = mesh.patch[t[0] as usize] as usize;
        for k in 0..3 {
            let (u, v) = (
                key(mesh.positions[t[k] as usize]),
                key(mesh.positions[t[(k + 1) % 3] as usize]),
            );
            *edges[p].entry([u.min(v), u.max(v)]).or_default() += 1;
        }
    }
    let on_boundary = |p: usize, x: DVec3| {
        let vs = scene.patches[p].vertices();
        (0..vs.len()).any(|i| to_segment(x, vs[i], vs[(i + 1) % vs.len()]).0 < tol)
    };
    let on_contact = |p: usize, x: DVec3| {
        segments.get(p).is_some_and(|s| {
            s.iter().any(|s| {
                s.kind == nusselt::discontinuity::SegmentKind::Contact
                    && to_segment(x, s.a, s.b).0 < tol
            })
        })
    };
    let as_d = |k: [u32; 3]| DVec3::from_array(k.map(|b| f32::from_bits(b) as f64));
    let mut boundary = Vec::new();
    for (p, es) in edges.iter().enumerate() {
        for (&[u, v], &n) in es {
            assert!(n <= 2, "patch {p}: edge in {n} triangles");
            if n == 1 {
                let (a, b) = (as_d(u), as_d(v));
                let mid = 0.5 * (a + b);
                assert!(
                    on_boundary(p, mid) || on_contact(p, mid),
                    "patch {p}: open edge {a}–{b} inside the patch"
                );
                boundary.push((p, a, b));
            }
        }
    }
    // No T-vertices: no vertex of another patch strictly inside an open
    // edge (a patch boundary or a contact line).

    // Only vertices on their own patch's boundary or contact lines count:
    // without segments (uniform, quadtree), a floor vertex may lie by
    // chance on the base edge of a box standing in the floor's interior.
    for &(p, a, b) in &boundary {
        for (k, x) in mesh.positions.iter().enumerate() {
            let q = mesh.patch[k] as usize;
            let y = x.as_dvec3();
            if q == p || !(on_boundary(q, y) || on_contact(q, y)) {
                continue;
            }
            let (d, t) = to_segment(x.as_dvec3(), a, b);
            let len = (b - a).length();
            assert!(
                !(d < tol && t * len > tol && (1.0 - t) * len > tol),
                "T-vertex: vertex {x} of patch {} inside edge {a}–{b} of patch {p}",
                mesh.patch[k]
            );
        }
    }
    // Every segment lies on mesh edges: points along it are on an edge.
    for (p, segs) in segments.iter().enumerate() {
        for s in segs {
            for f in [0.3, 0.5, 0.7] {
                let x = s.a + f * (s.b - s.a);
                let on_edge = edges[p]
                    .keys()
                    .any(|&[u, v]| to_segment(x, as_d(u), as_d(v)).0 < tol);
                assert!(
                    on_edge,
                    "patch {p}: segment {}–{} is not a mesh edge at {f}",
                    s.a, s.b
                );
            }
        }
    }
}

#[test]
fn every_mode_gives_a_valid_crack_free_mesh() {
    let s = solved_cornell(true);
    let (leaves, mut last) = (s.solution.hierarchy.leaf_count(), 0);
    for mode in [
        MeshMode::Uniform,
        MeshMode::Quadtree,
        MeshMode::Discontinuity,
    ] {
        let (m, stats) = mesh(&s, mode);
        let segments: &[Vec<Segment>] = if mode == MeshMode::Discontinuity {
            &s.guide
        } else {
            &[]
        };
        validate(&s.scene, &m, segments);
        eprintln!(
            "{mode:?}: {} vertices, {} triangles, {stats:?}",
            m.vertex_count(),
            m.triangles.len()
        );
        // Uniform aims at as many vertices as there are leaves.
        if mode == MeshMode::Uniform {
            let n = m.vertex_count() as f64;
            assert!(
                n > 0.5 * leaves as f64 && n < 2.5 * leaves as f64,
                "{n} vertices for {leaves} leaves"
            );
        }
        if mode == MeshMode::Discontinuity {
            assert!(stats.segments > 0 && stats.constrained_edges >= stats.segments);
            assert!(
                m.vertex_count() > last,
                "constraints and adaptivity add vertices"
            );
        }
        last = m.vertex_count();
    }
}

#[test]
fn contact_lines_split_vertices_into_a_dark_and_a_lit_side() {
    let s = solved_cornell(true);
    let (m, stats) = mesh(&s, MeshMode::Discontinuity);
    assert!(stats.split_vertices > 0);
    // Group the floor's vertices by position: a split vertex on a block's
    // base has a copy under the block (no light reaches it) and one outside.
    let mut by_pos: HashMap<(u32, [u32; 3]), Vec<f32>> = HashMap::new();
    for k in 0..m.vertex_count() {
        by_pos
            .entry((m.patch[k], key(m.positions[k])))
            .or_default()
            .push(m.radiosity[k].max_element());
    }
    let split: Vec<&Vec<f32>> = by_pos.values().filter(|v| v.len() > 1).collect();
    assert_eq!(
        split.iter().map(|v| v.len() - 1).sum::<usize>(),
        stats.split_vertices
    );
    let sharp = split
        .iter()
        .filter(|v| {
            let (lo, hi) = v
                .iter()
                .fold((f32::INFINITY, 0f32), |(a, b), &x| (a.min(x), b.max(x)));
            lo < 0.1 * hi
        })
        .count();
    assert!(
        2 * sharp >= split.len(),
        "only {sharp} of {} split vertices have a dark side",
        split.len()
    );
}

#[test]
fn adaptivity_reduces_interpolation_error() {
    // The absolute brightness threshold: on the coarser mesh it leaves,
    // adaptivity has more to do (with the preset's relative one, the mean
    // error falls 7 %, from 0.0056).
    let mut settings = preview();
    settings.accuracy.bf_relative_floor = 1.0;
    let s = solved_cornell_with(true, &settings);
    let error = |tol: f64| {
        let settings = MeshSettings {
            adapt_tol: tol,
            ..MeshSettings::default()
        };
        let (m, stats) = build_mesh(
            &s.scene,
            &s.bvh,
            &s.solution,
            &s.guide,
            &settings,
            &Progress::hidden(),
        )
        .unwrap();
        // Independent check at points that are never vertices (three per
        // triangle, off the centroid): the area-weighted mean difference
        // between the interpolation and a point evaluation with other rays.
        let (mut diff, mut area) = (0.0, 0.0);
        let points = PointEvaluator::new(&s.scene, &s.bvh, &s.solution, 99);
        for t in &m.triangles {
            let p = m.patch[t[0] as usize] as usize;
            let x = t.map(|i| m.positions[i as usize].as_dvec3());
            let b = t.map(|i| m.radiosity[i as usize].as_dvec3());
            let a = 0.5 * (x[1] - x[0]).cross(x[2] - x[0]).length();
            for w in [[0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.2, 0.6]] {
                let at = w[0] * x[0] + w[1] * x[1] + w[2] * x[2];
                let interp = w[0] * b[0] + w[1] * b[1] + w[2] * b[2];
                let exact = points.value(p, at, LinkRays::Bright).radiosity;
                diff += a / 3.0 * (exact - interp).abs().max_element();
            }
            area += a;
        }
        (diff / area, stats.adaptive_vertices, m.vertex_count())
    };
    let (off, added_off, n_off) = error(0.0);
    let (on, added_on, n_on) = error(0.05);
    eprintln!(
        "mean |interpolated − point value|: {off:.5} with {n_off} vertices (no adaptivity), {on:.5} with {n_on} ({added_on} added)"
    );
    assert_eq!(added_off, 0);
    assert!(added_on > 0);
    assert!(on < 0.9 * off, "adaptivity: {off} → {on}");
}

#[test]
fn the_hierarchy_follows_the_discontinuities() {
    let plain = solved_cornell(false);
    let guided = solved_cornell(true);
    guided.solution.hierarchy.validate(&guided.scene).unwrap();
    let min_area = guided.solution.thresholds.min_area;
    let h = &guided.solution.hierarchy;
    // A point of a segment strictly inside a leaf: that leaf is crossed by
    // the segment, so it is at most the bound.
    let tol = 1e-6 * guided.scene.diagonal();
    let (mut checked, mut contacts) = (0, 0);
    let crossed_area = |sol: &HierarchicalSolution| {
        let mut sum = 0.0;
        for id in sol.hierarchy.leaves() {
            let e = sol.hierarchy.get(id);
            let normal = guided.scene.patches[e.patch as usize].normal;
            let vs = e.vertices();
            for seg in &guided.guide[e.patch as usize] {
                let inside = [0.25, 0.5, 0.75].iter().any(|f| {
                    let x = seg.a + f * (seg.b - seg.a);
                    (0..vs.len()).all(|i| {
                        let edge = vs[(i + 1) % vs.len()] - vs[i];
                        normal.cross(edge).normalize().dot(x - vs[i]) > tol
                    })
                });
                if inside {
                    sum += e.area;
                    break;
                }
            }
        }
        sum
    };
    for id in h.leaves() {
        let e = h.get(id);
        let normal = guided.scene.patches[e.patch as usize].normal;
        let vs = e.vertices();
        for seg in &guided.guide[e.patch as usize] {
            let x = 0.5 * (seg.a + seg.b);
            let inside = (0..vs.len()).all(|i| {
                let edge = vs[(i + 1) % vs.len()] - vs[i];
                normal.cross(edge).normalize().dot(x - vs[i]) > tol
            });
            if inside {
                // Contact lines go finer than shadow lines.
                let bound = match seg.kind {
                    SegmentKind::Contact => {
                        contacts += 1;
                        CONTACT_AREA_FRACTION * min_area
                    }
                    _ => 4.0 * min_area,
                } * (1.0 + 1e-9);
                checked += 1;
                assert!(
                    e.area <= bound,
                    "leaf {id:?} crossed by a {:?} segment has area {} > {bound}",
                    seg.kind,
                    e.area
                );
            }
        }
    }
    assert!(checked > contacts && contacts > 0, "{checked} {contacts}");
    let (a_plain, a_guided) = (
        crossed_area(&plain.solution),
        crossed_area(&guided.solution),
    );
    eprintln!("area of leaves crossed by segments: {a_plain:.3} plain, {a_guided:.3} guided");
    assert!(a_guided < 0.5 * a_plain);
}

#[test]
fn same_mesh_for_one_and_two_threads() {
    let build = |threads: usize| {
        on_threads(threads, || {
            let s = solved_cornell(true);
            mesh(&s, MeshMode::Discontinuity).0
        })
    };
    assert_eq!(build(1), build(2));
}
