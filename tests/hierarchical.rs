//! The hierarchical solver [HSA91]: furnace and enclosure identities,
//! agreement with a fine uniform solution of the Cornell box, link growth,
//! shadows without leaks, thread independence, and the hierarchy's
//! validator after every solve.

use glam::DVec3;
use nusselt::classic::matrix::{FormFactorMatrix, Kernel, MatrixSettings};
use nusselt::classic::solve::{ClassicMethod, Convergence, System, solve};
use nusselt::classic::uniform::UniformMesh;
use nusselt::hierarchical::{
    Accuracy, HierarchicalSettings, HierarchicalSolution, solve_hierarchical,
};
use nusselt::meshing::leaf::{VertexValues, leaf_output_mesh, output_mesh};
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use crate::fixtures::{assert_light_adds_up, cornell, furnace_box, on_threads};

fn run(scene: &Scene, settings: &HierarchicalSettings) -> HierarchicalSolution {
    let bvh = TriangleBvh::of_scene(scene);
    let s = solve_hierarchical(scene, &bvh, settings, &Progress::hidden());
    s.hierarchy.validate(scene).unwrap();
    for (r, links) in s.links.iter().enumerate() {
        for l in links {
            assert!(
                l.source.index() < s.hierarchy.len(),
                "link of {r} to a dead element"
            );
            assert!((0.0..=1.0).contains(&l.form_factor) && (0.0..=1.0).contains(&l.visibility()));
        }
    }
    let mesh = leaf_output_mesh(scene, &s);
    mesh.validate().unwrap();
    // Each vertex's B and H are means of the same leaves: B = E + ρ H.
    assert_light_adds_up(scene, &mesh, "leaf mean");
    s
}

fn with(accuracy: Accuracy) -> HierarchicalSettings {
    HierarchicalSettings {
        accuracy,
        ..HierarchicalSettings::default()
    }
}

#[test]
fn furnace_within_the_stated_tolerance() {
    // Stated tolerances at ρ = 0.5 (default preset): the enclosure identity
    // Σ B·A = Φ / (1 − ρ) within 1 %; the leaves within 6 % area-weighted;
    // the output mesh's vertices (final gather over the links) within 6 %
    // on average and 45 % at worst. At ρ = 0.95 (preview preset: B = 20 E
    // makes every link bright, and the default preset's links explode):
    // 8 %, 9 %, 11 % and 80 % (measured 6.8 %, 7.4 %, 9.5 %, 70 %). KNOWN WEAKNESS: each link hands its whole receiver the mean
    // over it, so leaves next to the box's edges and corners carry their
    // ancestors' averages (measured: leaves 5.1 %, vertices 4.6 % mean,
    // 37 % worst, at a corner).
    for (rho, accuracy) in [(0.5, Accuracy::default()), (0.95, Accuracy::preview())] {
        let scene = furnace_box(DVec3::new(1.0, 0.8, 1.2), 1.0, rho);
        let settings = HierarchicalSettings {
            tolerance: 1e-9,
            ..with(accuracy)
        };
        let s = run(&scene, &settings);
        assert!(s.converged);
        let expected = std::f64::consts::PI / (1.0 - rho);
        let h = &s.hierarchy;
        let (mut leaf_err, mut area) = (0.0, 0.0);
        for id in h.leaves() {
            let e = h.get(id);
            leaf_err += (e.radiosity.x - expected).abs() / expected * e.area;
            area += e.area;
        }
        let leaf_err = leaf_err / area;
        let radiated: f64 = h
            .leaves()
            .map(|id| h.get(id).radiosity.x * h.get(id).area)
            .sum();
        let phi = scene.emitted_power().x;
        let enclosure = (radiated - phi / (1.0 - rho)).abs() / (phi / (1.0 - rho));
        let bvh = TriangleBvh::of_scene(&scene);
        let mesh = output_mesh(&scene, &bvh, &s, VertexValues::PointGather { seed: 1 });
        let vertex: Vec<f64> = mesh
            .radiosity
            .iter()
            .map(|b| (b.x as f64 - expected).abs() / expected)
            .collect();
        let mean = vertex.iter().sum::<f64>() / vertex.len() as f64;
        let worst = vertex.iter().cloned().fold(0.0, f64::max);
        eprintln!(
            "furnace ρ = {rho}: Σ B·A {enclosure:.2e}, leaves {leaf_err:.3}, vertices mean {mean:.3} worst {worst:.3}, {} links",
            s.link_count()
        );
        let (enclosure_tol, leaf_tol, mean_tol, worst_tol) = if rho < 0.9 {
            (0.01, 0.06, 0.06, 0.45)
        } else {
            (0.08, 0.09, 0.11, 0.8)
        };
        assert!(
            enclosure < enclosure_tol,
            "ρ = {rho}: Σ B·A off by {enclosure:e}"
        );
        assert!(leaf_err < leaf_tol, "ρ = {rho}: leaves off by {leaf_err:e}");
        assert!(
            mean < mean_tol && worst < worst_tol,
            "ρ = {rho}: vertices {mean} {worst}"
        );
    }
}

/// Patch-average radiosity of a fine uniform mesh (point-polygon kernel,
/// 16 rays per pair, Jacobi to 1e-9).
fn uniform_reference(scene: &Scene, fraction: f64) -> Vec<DVec3> {
    let mesh = UniformMesh::new(scene, scene.diagonal() * fraction);
    let bvh = TriangleBvh::of_scene(scene);
    let settings = MatrixSettings {
        kernel: Kernel::PointPolygon,
        visibility_rays: 16,
        ..MatrixSettings::default()
    };
    let (matrix, _) =
        FormFactorMatrix::assemble(&mesh, &bvh, &settings, &Progress::hidden()).unwrap();
    let patch = |i: usize| &scene.patches[mesh.elements[i].patch as usize];
    let n = mesh.elements.len();
    let rho: Vec<DVec3> = (0..n).map(|i| patch(i).reflectance).collect();
    let e: Vec<DVec3> = (0..n).map(|i| patch(i).emission).collect();
    let a: Vec<f64> = mesh.elements.iter().map(|e| e.area).collect();
    let system = System {
        matrix: &matrix,
        reflectance: &rho,
        emission: &e,
        area: &a,
    };
    let conv = Convergence {
        tolerance: 1e-9,
        max_iterations: 100_000,
    };
    let sol = solve(
        &system,
        ClassicMethod::Jacobi,
        &conv,
        1 << 30,
        &mut |_, _| {},
    )
    .unwrap();
    let mut sum = vec![DVec3::ZERO; scene.patches.len()];
    for (i, el) in mesh.elements.iter().enumerate() {
        sum[el.patch as usize] += sol.radiosity[i] * el.area;
    }
    sum.iter()
        .zip(&scene.patches)
        .map(|(s, p)| *s / p.area)
        .collect()
}

/// Area-weighted relative L1 difference of patch averages (non-emitters).
fn patch_error(scene: &Scene, s: &HierarchicalSolution, reference: &[DVec3]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (p, patch) in scene.patches.iter().enumerate() {
        if patch.is_emitter() {
            continue;
        }
        let b = s.hierarchy.get(s.hierarchy.root(p)).radiosity;
        num += patch.area * (b - reference[p]).abs().element_sum();
        den += patch.area * reference[p].element_sum();
    }
    num / den
}

#[test]
fn cornell_box_agrees_with_a_fine_uniform_solution_and_improves_with_accuracy() {
    let scene = cornell();
    let reference = uniform_reference(&scene, 1.0 / 24.0);
    let errors: Vec<f64> = [Accuracy::preview(), Accuracy::default(), Accuracy::high()]
        .into_iter()
        .map(|a| patch_error(&scene, &run(&scene, &with(a)), &reference))
        .collect();
    eprintln!("patch-average errors (preview, default, high): {errors:?}");
    // Stated tolerance: 2 % area-weighted on patch averages at the default
    // (measured 1.2 %; preview 5.0 %, high 0.6 %). It was 3.1–3.6 % before
    // two fixes: links whose midpoint rule said F = 0 (a floor beside a
    // block face leaning away) get their quadrature, and links carry the
    // exposed part's radiosity (not the floor under the blocks).
    assert!(errors[1] < 0.02, "{errors:?}");
    assert!(
        errors[0] >= errors[1] && errors[1] >= errors[2] * 0.9,
        "{errors:?}"
    );
}

#[test]
fn links_grow_far_slower_than_elements_squared() {
    let scene = cornell();
    let mut rows = Vec::new();
    for a in [Accuracy::preview(), Accuracy::default(), Accuracy::high()] {
        let s = run(&scene, &with(a));
        rows.push((
            s.hierarchy.len() as f64,
            s.link_count() as f64,
            s.memory_bytes(),
        ));
    }
    eprintln!("(elements, links, bytes): {rows:?}");
    for &(n, links, bytes) in &rows {
        assert!(links < 0.1 * n * n, "{rows:?}");
        assert!(links / n < 30.0, "links per element unbounded: {rows:?}");
        // The target holds from the default preset on; at the preview the
        // element arena outweighs its few links.
        assert!(
            (bytes as f64) / links <= 100.0 || n == rows[0].0,
            "bytes per link: {rows:?}"
        );
    }
    let (n0, l0, _) = rows[0];
    let (n2, l2, _) = rows[2];
    let exponent = (l2 / l0).ln() / (n2 / n0).ln();
    // Measured 1.50 with every link at 32 rays, 1.51 since links accepted
    // whatever their visibility take 4 (their one-ray-per-quarter spreads
    // add a few shadow splits at the preview), 1.62 since the presets'
    // thresholds follow each receiver's radiosity (the dim ceiling is
    // resolved like the lit floor at the finer presets).
    assert!(exponent < 1.7, "links ~ elements^{exponent}: {rows:?}");
}

/// True when (x, z) lies inside the floor footprint of a convex polygon.
fn inside(poly: &[DVec3], x: f64, z: f64, inset: f64) -> bool {
    let n = poly.len();
    let c: DVec3 = poly.iter().sum::<DVec3>() / n as f64;
    let mut sign = 0.0;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let cross = |px: f64, pz: f64| (b.x - a.x) * (pz - a.z) - (b.z - a.z) * (px - a.x);
        if sign == 0.0 {
            sign = cross(c.x, c.z).signum();
        }
        let len = ((b.x - a.x).powi(2) + (b.z - a.z).powi(2)).sqrt();
        if cross(x, z) * sign < inset * len {
            return false;
        }
    }
    true
}

#[test]
fn no_light_leaks_under_the_blocks() {
    let scene = cornell();
    let s = run(&scene, &with(Accuracy::default()));
    let h = &s.hierarchy;
    let from_light = s.irradiance_from(|p| scene.patches[p as usize].is_emitter());
    let floor_y = scene.bounds.0.y;
    let top_y = scene.bounds.1.y;
    let is_floor = |p: u32| {
        let patch = &scene.patches[p as usize];
        patch.normal.y > 0.99 && (patch.corners[0].y - floor_y).abs() < 1e-6
    };
    // Block tops: upward faces strictly between floor and ceiling; the
    // blocks are vertical prisms, so their tops outline their footprints.
    let tops: Vec<Vec<DVec3>> = scene
        .patches
        .iter()
        .filter(|p| {
            p.normal.y > 0.99 && p.corners[0].y > floor_y + 0.01 && p.corners[0].y < top_y - 0.01
        })
        .map(|p| p.vertices().to_vec())
        .collect();
    assert_eq!(tops.len(), 2, "the Cornell box has two blocks");
    let lit_max = h
        .leaves()
        .filter(|id| is_floor(h.get(*id).patch))
        .map(|id| from_light[id.index()].max_element())
        .fold(0.0, f64::max);
    assert!(lit_max > 0.0);
    let (mut under, mut straddling, mut leaking) = (0, 0, 0);
    for id in h.leaves() {
        let e = h.get(id);
        if !is_floor(e.patch) {
            continue;
        }
        let irr = from_light[id.index()].max_element();
        for top in &tops {
            if e.vertices().iter().all(|v| inside(top, v.x, v.z, 0.0)) {
                under += 1;
                if irr > 0.02 * lit_max {
                    leaking += 1;
                }
            } else if inside(top, e.centroid().x, e.centroid().z, 0.0) {
                // Leaves straddling a block's base are lit by their part
                // outside the footprint; only counted here (the
                // discontinuity mesher puts an edge along the base).
                straddling += 1;
            }
        }
    }
    // Partly visible links whose visibility varies over their receiver
    // split the receiver, and the shadow errors of all links from one
    // source patch are summed before a receiver is accepted, so a light
    // split into many small pieces cannot leak through the sum.
    eprintln!("{under} leaves under the blocks, {leaking} lit; {straddling} along the bases");
    assert!(
        under > 0 && straddling > 0,
        "{under} under, {straddling} along"
    );
    assert!(
        leaking as f64 <= 0.05 * under as f64,
        "{leaking} of {under} leaves under the blocks are lit"
    );
}

#[test]
fn same_radiosities_for_one_and_two_threads() {
    let scene = cornell();
    let settings = with(Accuracy::preview());
    let solve_on = |threads: usize| on_threads(threads, || run(&scene, &settings));
    let (one, two) = (solve_on(1), solve_on(2));
    assert_eq!(one.hierarchy.elements, two.hierarchy.elements);
    assert_eq!(one.links, two.links);
}

/// The floor of the Cornell box and a face of the tall block that leans
/// away from the floor's middle: every quarter centroid of the floor lies
/// behind the face's plane (the midpoint rule says F = 0), while the floor
/// in front of it does see it. The link must carry the exact front-side
/// form factor, not drop the pair.
#[test]
fn a_source_behind_the_receivers_sample_points_keeps_its_form_factor() {
    use nusselt::formfactor::form_factor_polygon_polygon_with;
    use nusselt::hierarchical::hierarchy::Hierarchy;
    use nusselt::hierarchical::link::{Evaluator, Inherited};

    let scene = cornell();
    let bvh = TriangleBvh::of_scene(&scene);
    let h = Hierarchy::new(&scene);
    let floor = h.root(0);
    let face = h.root(17);
    let (fe, se) = (h.get(floor), h.get(face));
    let n_s = scene.patches[17].normal;
    let quarters_behind = nusselt::hierarchical::hierarchy::split_corners(fe.shape, &fe.corners)
        .iter()
        .all(|q| (nusselt::scene::polygon_centroid(q) - se.corners[0]).dot(n_s) < 0.0);
    assert!(quarters_behind, "the case this test is about");
    let exact =
        form_factor_polygon_polygon_with(fe.vertices(), se.vertices(), 1e-6, 1 << 16, |x| {
            f64::from(u8::from((x - se.corners[0]).dot(n_s) > 0.0))
        })
        .value;
    let evaluator = Evaluator {
        scene: &scene,
        elements: &h.elements,
        bvh: &bvh,
        seed: 0,
    };
    let (link, _) = evaluator.evaluate(floor, face, Inherited::Nothing, |_| 32);
    let f = f64::from(link.form_factor);
    assert!(exact > 1e-3, "{exact}");
    assert!((f - exact).abs() < 0.05 * exact, "F {f} against {exact}");
    assert!(
        link.visibility() > 0.5,
        "the floor in front of the face sees it"
    );
}

/// A slat 6 m long that cuts into a wall, and a 0.5 m patch of that wall
/// under the slat's middle (the gallery's louvres and light well): only
/// the wall's 8 cm strip above the joint is in front of the slat's face,
/// and the light it sends there lands within centimetres of the joint,
/// between the slat's quarter centroids and out of sight of the wall
/// patch's own. The link must carry the form factor of that strip, not
/// the midpoint rules' near-zero (1.5 % of it when the source's points
/// were tried only for a source of smaller area).
#[test]
fn a_slat_that_cuts_into_a_wall_keeps_the_light_of_the_wall_beside_it() {
    use nusselt::formfactor::form_factor_polygon_polygon_with;
    use nusselt::hierarchical::hierarchy::Hierarchy;
    use nusselt::hierarchical::link::{Evaluator, Inherited};

    let p = DVec3::new;
    let (s, c) = (45f64.to_radians().sin(), 45f64.to_radians().cos());
    let (joint, width) = (p(0.0, 5.92, 3.4985), 0.27);
    let up = p(0.0, c, s) * width;
    let slat = [
        joint,
        joint + up,
        joint + p(6.0, 0.0, 0.0) + up,
        joint + p(6.0, 0.0, 0.0),
    ];
    let wall = [
        p(3.5, 6.0, 3.5),
        p(3.0, 6.0, 3.5),
        p(3.0, 5.5, 3.5),
        p(3.5, 5.5, 3.5),
    ];
    let scene = crate::fixtures::painted(&[(slat, 1, false), (wall, 1, true)], 0.5, 0.0);
    let n_r = scene.patches[0].normal;
    assert!(
        (n_r - p(0.0, c, -s)).length() < 1e-9,
        "the slat faces up and toward the wall"
    );
    let bvh = TriangleBvh::of_scene(&scene);
    let h = Hierarchy::new(&scene);
    let (r, w) = (h.root(0), h.root(1));
    let (re, we) = (h.get(r), h.get(w));
    let exact =
        form_factor_polygon_polygon_with(we.vertices(), re.vertices(), 1e-7, 1 << 18, |x| {
            f64::from(u8::from((x - re.corners[0]).dot(n_r) > 0.0))
        })
        .value
            * we.area
            / re.area;
    let evaluator = Evaluator {
        scene: &scene,
        elements: &h.elements,
        bvh: &bvh,
        seed: 0,
    };
    let (link, _) = evaluator.evaluate(r, w, Inherited::Nothing, |_| 32);
    let f = f64::from(link.form_factor);
    eprintln!("slat ← wall: F {f:.3e} against {exact:.3e}");
    assert!(exact > 1e-3, "{exact}");
    assert!((f - exact).abs() < 0.05 * exact, "F {f} against {exact}");
}

/// The floor under the Cornell box's blocks is inside closed solids: its
/// leaves are measured unexposed, the rest of the floor exposed, and what
/// the floor's links carry (the exposed mean) is brighter than its area
/// mean, which the dark footprints pull down.
#[test]
fn buried_floor_under_the_blocks_is_not_averaged_into_links() {
    let scene = cornell();
    let s = run(&scene, &HierarchicalSettings::default());
    let h = &s.hierarchy;
    // Top faces of the two blocks (facing up, above the floor).
    let tops: Vec<&[DVec3]> = scene
        .patches
        .iter()
        .filter(|p| p.normal.y > 0.99 && p.centroid().y > 0.01)
        .map(|p| p.vertices())
        .collect();
    assert_eq!(tops.len(), 2);
    // Inside the footprint (xz) of a convex top face, by `margin` metres.
    let inside = |x: DVec3, poly: &[DVec3], margin: f64| {
        let n = poly.len();
        let signs: Vec<f64> = (0..n)
            .map(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % n]);
                let e = glam::DVec2::new(b.x - a.x, b.z - a.z);
                let d = glam::DVec2::new(x.x - a.x, x.z - a.z);
                e.perp_dot(d) / e.length()
            })
            .collect();
        signs.iter().all(|&s| s > margin) || signs.iter().all(|&s| s < -margin)
    };
    let (mut under, mut open) = (0, 0);
    for id in h.leaves() {
        let e = h.get(id);
        if e.patch != 0 {
            continue;
        }
        let reach = e
            .vertices()
            .iter()
            .map(|v| v.distance(e.centroid()))
            .fold(0.0, f64::max);
        let c = e.centroid();
        if tops.iter().any(|t| inside(c, t, reach)) {
            under += 1;
            assert_eq!(e.exposure, 0.0, "leaf under a block at {c}");
        } else if tops.iter().all(|t| !inside(c, t, -reach)) {
            open += 1;
            assert_eq!(e.exposure, 1.0, "open floor leaf at {c}");
        }
    }
    assert!(under > 10 && open > 100, "{under} {open}");
    let floor = h.get(h.root(0));
    assert!(
        floor.exposure > 0.7 && floor.exposure < 0.9,
        "{}",
        floor.exposure
    );
    assert!(floor.exposed_radiosity.y > floor.radiosity.y * 1.1);
}

/// A link's visibility rays follow what its acceptance hangs on: a dim
/// source's link, accepted whatever its visibility, gets the few rays;
/// a bright one the full count; and a cheap link whose source has since
/// brightened is sampled again rather than split or kept.
#[test]
fn visibility_rays_follow_what_the_decision_needs() {
    use nusselt::hierarchical::hierarchy::{Hierarchy, SourceState};
    use nusselt::hierarchical::link::{Evaluator, Inherited};
    use nusselt::hierarchical::oracle::{
        Decision, Ends, FEW_RAYS, Oracle, Thresholds, decide, rays_needed,
    };

    let scene = cornell();
    let bvh = TriangleBvh::of_scene(&scene);
    let h = Hierarchy::new(&scene);
    let light = scene.patches.iter().position(|p| p.is_emitter()).unwrap();
    let (floor, source) = (h.root(0), h.root(light));
    let (re, se) = (h.get(floor), h.get(source));
    let t = Thresholds {
        oracle: Oracle::Bf,
        ff_eps: 0.0,
        bf_eps: 0.01,
        bf_relative: None,
        power_eps: 0.0,
        cluster_eps: 0.0,
        min_area: 0.0,
        rays: 32,
    };
    let rho = scene.patches[0].reflectance;
    let state = |b: f64| SourceState {
        radiosity: DVec3::splat(b),
        unevenness: DVec3::ZERO,
    };
    let ends = |state: SourceState| Ends {
        receiver: re,
        reflectance: rho,
        source: se,
        state,
    };
    let (dim, bright) = (ends(state(1e-6)), ends(state(1e3)));
    let evaluator = Evaluator {
        scene: &scene,
        elements: &h.elements,
        bvh: &bvh,
        seed: 0,
    };
    let evaluate = |ends: &Ends| {
        let plan = move |l: &nusselt::hierarchical::link::Link| rays_needed(&t, l, ends);
        evaluator.evaluate(floor, source, Inherited::Nothing, plan)
    };
    let (cheap, cast) = evaluate(&dim);
    assert_eq!((cheap.rays(), cast), (FEW_RAYS, FEW_RAYS as u64));
    assert!(cheap.form_factor > 0.0);
    assert_eq!(decide(&t, &cheap, &dim), Decision::Accept);
    let (full, cast) = evaluate(&bright);
    assert_eq!((full.rays(), cast), (32, 32));
    // The cheap link, now that its source is bright: resampled first.
    assert_eq!(decide(&t, &cheap, &bright), Decision::Resample);
    assert_ne!(decide(&t, &full, &bright), Decision::Resample);
}

#[test]
fn the_defect_correction_closes_a_furnace_of_many_bounces() {
    // At ρ = 0.95 light goes round the box twenty times, and the preset's
    // small closure errors of the links add up in Σ B·A (the test above
    // allows 8 %). The ray gather of the solution itself has no such error:
    // two passes of defect correction must bring the enclosure identity
    // to within 1 %, and the patches' means with it, on any thread count.
    let rho = 0.95;
    let scene = furnace_box(DVec3::new(1.0, 0.8, 1.2), 1.0, rho);
    let expected = std::f64::consts::PI / (1.0 - rho);
    let measure = |passes: u32, threads: usize| {
        let settings = HierarchicalSettings {
            tolerance: 1e-9,
            correction_passes: passes,
            ..with(Accuracy::preview())
        };
        let s = on_threads(threads, || run(&scene, &settings));
        let h = &s.hierarchy;
        let radiated: f64 = h
            .leaves()
            .map(|id| h.get(id).radiosity.x * h.get(id).area)
            .sum();
        let total: f64 = h.leaves().map(|id| h.get(id).area).sum();
        let enclosure = (radiated / total - expected).abs() / expected;
        let mut patch = vec![(0.0, 0.0); scene.patches.len()];
        for id in h.leaves() {
            let e = h.get(id);
            patch[e.patch as usize].0 += e.radiosity.x * e.area;
            patch[e.patch as usize].1 += e.area;
        }
        let worst_patch = patch
            .iter()
            .map(|(b, a)| (b / a - expected).abs() / expected)
            .fold(0.0, f64::max);
        (enclosure, worst_patch, s.correction)
    };
    let (before, before_patch, _) = measure(0, 2);
    let (after, after_patch, correction) = measure(2, 2);
    eprintln!(
        "furnace ρ = 0.95: Σ B·A off by {before:.4} → {after:.4}, worst patch {before_patch:.4} → {after_patch:.4}"
    );
    assert!(after < 0.01, "corrected: Σ B·A off by {after:.4}");
    assert!(
        after_patch < 0.02,
        "corrected: a patch off by {after_patch:.4}"
    );
    assert!(after < before / 2.0, "{before:.4} → {after:.4}");
    let (_, _, one_thread) = measure(2, 1);
    assert_eq!(
        correction, one_thread,
        "the correction depends on the thread count"
    );
}
