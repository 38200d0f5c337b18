//! The hard interiors of `scenes/hard/`: energy closure per closed scene
//! and preset (and in a room whose floor is partly under boxes), no light
//! through the sealed room's wall (at its elements and at the output
//! mesh's vertices), the box under the table against its committed
//! path-traced point table, tighter at the finer preset, direct light
//! through a baffle by links against rays, a dim room resolved like a
//! bright one by the relative bf threshold, no steps in the vertex
//! values where the patches of a smoothly lit wall meet, and (slow) the
//! gallery hall's excess removed by the defect correction.

use glam::DVec3;
use nusselt::hierarchical::{
    Accuracy, HierarchicalSettings, HierarchicalSolution, solve_hierarchical,
};
use nusselt::meshing::leaf::{VertexValues, output_mesh};
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use crate::fixtures::{bundled_scene, slow_tests};

fn solve(scene: &Scene, bvh: &TriangleBvh, accuracy: Accuracy) -> HierarchicalSolution {
    let settings = HierarchicalSettings {
        accuracy,
        ..HierarchicalSettings::default()
    };
    solve_hierarchical(scene, bvh, &settings, &Progress::hidden())
}

/// The whole solve (output mesh included) with `hierarchical` and a small
/// cheap view, scored against a point table.
fn solve_and_score(
    scene: &Scene,
    hierarchical: HierarchicalSettings,
    table: &[nusselt::reference::ProbeValue],
) -> (nusselt::SolveRun, nusselt::lab::points::PointScore) {
    use nusselt::render::RenderSettings;
    use nusselt::render::view::ViewOverrides;
    use nusselt::{SolveSettings, solve};
    let settings = SolveSettings {
        hierarchical,
        render: RenderSettings::with_samples(1, 0),
        view: ViewOverrides {
            width: Some(32),
            height: Some(24),
            ..ViewOverrides::default()
        },
        ..SolveSettings::default()
    };
    let run = solve(scene, &settings, &Progress::hidden()).unwrap();
    let (s, _) = nusselt::lab::points::score(&run.mesh, table).unwrap();
    (run, s)
}

/// Absorbed over emitted power per channel, from the leaves' irradiance
/// (the report's `power`).
fn closure(scene: &Scene, s: &HierarchicalSolution) -> DVec3 {
    let (mut emitted, mut absorbed) = (DVec3::ZERO, DVec3::ZERO);
    for leaf in s.hierarchy.leaves() {
        let e = s.hierarchy.get(leaf);
        let patch = &scene.patches[e.patch as usize];
        emitted += patch.emission * e.area;
        absorbed += (DVec3::ONE - patch.reflectance) * s.irradiance[leaf.index()] * e.area;
    }
    absorbed / emitted
}

fn presets() -> Vec<(&'static str, Accuracy)> {
    let mut p = vec![
        ("preview", Accuracy::preview()),
        ("default", Accuracy::default()),
    ];
    if slow_tests("hard: energy closure at --accuracy high") {
        p.push(("high", Accuracy::high()));
    }
    p
}

#[test]
fn closed_hard_scenes_absorb_what_they_emit() {
    // The gallery is in its own test, slow.
    let mut failures = Vec::new();
    for name in ["sealed-rooms", "table-gap", "corridor"] {
        let scene = bundled_scene(&format!("hard/{name}.gltf"));
        let bvh = TriangleBvh::of_scene(&scene);
        for (preset, accuracy) in presets() {
            let ratio = closure(&scene, &solve(&scene, &bvh, accuracy));
            eprintln!("{name} {preset}: absorbed / emitted {ratio:.4}");
            if (ratio - DVec3::ONE).abs().max_element() > 0.005 {
                failures.push(format!("{name} {preset}: {ratio:.4}"));
            }
        }
    }
    assert!(failures.is_empty(), "off by more than 0.5 %: {failures:?}");
}

/// The gallery (clusters, light that arrives after bounces off louvres)
/// closes too, at preview and default: measured 1.0028 and 1.0011
/// (0.963 at the default before the cluster links carried what their rays
/// reach and links carried fresh readings; `solve`, guided by the
/// discontinuities, 0.9959 and 1.0010). `high` is left out: on 2 GiB its
/// first linking is coarsened (1.0070 from `solve`, 430 s).
#[test]
fn the_gallery_absorbs_what_it_emits() {
    if !slow_tests("hard::the_gallery_absorbs_what_it_emits") {
        return;
    }
    let scene = bundled_scene("hard/gallery.gltf");
    let bvh = TriangleBvh::of_scene(&scene);
    let mut failures = Vec::new();
    for (preset, accuracy) in [
        ("preview", Accuracy::preview()),
        ("default", Accuracy::default()),
    ] {
        let ratio = closure(&scene, &solve(&scene, &bvh, accuracy));
        eprintln!("gallery {preset}: absorbed / emitted {ratio:.4}");
        if (ratio - DVec3::ONE).abs().max_element() > 0.005 {
            failures.push(format!("{preset}: {ratio:.4}"));
        }
    }
    assert!(failures.is_empty(), "off by more than 0.5 %: {failures:?}");
}

/// The gallery's hall (y ≤ 5 m, lit only after bounces off the louvres)
/// against its committed point table (137 of its 200 points), without the
/// defect correction and with it (two passes): measured power bias
/// +6.9 % and +3.1 %, median +7.0 % and +2.9 %; the second pass finds a
/// net residual of −0.1 %.
#[test]
fn the_defect_correction_brings_the_gallery_hall_to_its_point_table() {
    use nusselt::lab::points::read_table;
    if !slow_tests("hard::the_defect_correction_brings_the_gallery_hall_to_its_point_table") {
        return;
    }
    let table = read_table(&crate::fixtures::scene_path("hard/gallery.points.csv")).unwrap();
    let hall: Vec<_> = table
        .into_iter()
        .filter(|v| v.point.position.y <= 5.0)
        .collect();
    assert_eq!(hall.len(), 137);
    let scene = bundled_scene("hard/gallery.gltf");
    let mut bias = Vec::new();
    for passes in [0, 2] {
        let hierarchical = HierarchicalSettings {
            correction_passes: passes,
            ..HierarchicalSettings::default()
        };
        let (run, s) = solve_and_score(&scene, hierarchical, &hall);
        eprintln!(
            "gallery hall, {passes} correction passes: median {:.4}, power bias {:+.4}",
            s.median, s.power_bias
        );
        if passes > 0 {
            let c = run.report.correction.as_ref().expect("correction reported");
            assert_eq!(c.passes.len(), passes as usize);
            let last = c.passes.last().unwrap().residual;
            assert!(last.abs() < 0.005, "the last pass still finds {last}");
        }
        bias.push(s.power_bias);
    }
    assert!(
        bias[0] > 0.04,
        "the links alone: {:+.4} (the excess to correct)",
        bias[0]
    );
    assert!(bias[1].abs() < bias[0] / 2.0, "corrected: {:+.4}", bias[1]);
}

#[test]
fn light_on_partly_buried_floor_is_not_lost() {
    // Boxes stand on the floor of a closed room: the floor's elements
    // along their feet are partly under them. Their irradiance is a mean
    // over the whole element, and only the exposed part receives and
    // reflects it. Measured: 0.990 (preview) when the exposed part
    // reflected only the mean (0.992 at the default), 0.996 and 0.995
    // since; the bound is the 0.5 %.
    let scene = crate::fixtures::room(crate::fixtures::LIT_ROOM);
    let bvh = TriangleBvh::of_scene(&scene);
    let mut failures = Vec::new();
    for (preset, accuracy) in presets() {
        let ratio = closure(&scene, &solve(&scene, &bvh, accuracy));
        eprintln!("room with standing boxes, {preset}: absorbed / emitted {ratio:.4}");
        if (ratio - DVec3::ONE).abs().max_element() > 0.005 {
            failures.push(format!("{preset}: {ratio:.4}"));
        }
    }
    assert!(failures.is_empty(), "off by more than 0.5 %: {failures:?}");
}

/// Two closed rooms alike, 10 m apart, each lit by a 1 m² ceiling lamp
/// and holding a box on its floor; the second lamp is `dim` times the
/// first. Patches of the first room come first; returns the scene and the
/// patch count of one room.
fn twin_rooms(dim: f64) -> (Scene, usize) {
    use crate::fixtures::{box_faces, painted};
    let mut quads = Vec::new();
    for dx in [0.0, 10.0] {
        let o = DVec3::new(dx, 0.0, 0.0);
        for q in box_faces(o, o + DVec3::new(4.0, 3.0, 5.0)) {
            quads.push(([q[0], q[3], q[2], q[1]], 6, false));
        }
        let lamp = [(1.5, 2.0), (2.5, 2.0), (2.5, 3.0), (1.5, 3.0)]
            .map(|(x, z)| o + DVec3::new(x, 2.99, z));
        quads.push((lamp, 1, true));
        let lo = o + DVec3::new(1.0, 0.0, 1.5);
        for q in &box_faces(lo, lo + DVec3::new(1.2, 0.8, 1.0))[1..] {
            quads.push((*q, 3, false));
        }
    }
    let mut scene = painted(&quads, 0.5, 0.0);
    let half = scene.patches.len() / 2;
    for p in &mut scene.patches[half..] {
        p.emission *= dim;
    }
    (scene, half)
}

#[test]
fn a_dim_room_is_resolved_like_a_bright_one_with_the_relative_threshold() {
    // Radiosity is linear in the emission: the dim room's solution is the
    // bright room's times `dim`. An absolute threshold resolves the dim
    // room far more coarsely (its links' errors are small in W/m², large
    // against its radiosity); the relative one follows each receiver's
    // radiosity down to its floor. Measured: leaves dim / bright 0.055
    // absolute, 0.80 relative; the dim room's patch means against the
    // bright room's, scaled: 0.34 % absolute, 0.22 % relative
    // (area-weighted; patch means converge long before the leaves do).
    let dim = 1.0 / 16.0;
    let (scene, half) = twin_rooms(dim);
    let bvh = TriangleBvh::of_scene(&scene);
    let measure = |floor: f64| {
        let accuracy = Accuracy {
            bf_relative_floor: floor,
            ..Accuracy::default()
        };
        let s = solve(&scene, &bvh, accuracy);
        let h = &s.hierarchy;
        let mut leaves = [0usize; 2];
        for id in h.leaves() {
            leaves[usize::from(h.get(id).patch as usize >= half)] += 1;
        }
        let (mut num, mut den) = (0.0, 0.0);
        for p in 0..half {
            let (bright, faint) = (h.elements[p].radiosity.x, h.elements[p + half].radiosity.x);
            num += scene.patches[p].area * (faint / dim - bright).abs();
            den += scene.patches[p].area * bright;
        }
        (leaves[1] as f64 / leaves[0] as f64, num / den)
    };
    let (leaves_abs, diff_abs) = measure(1.0);
    let (leaves_rel, diff_rel) = measure(1.0 / 32.0);
    eprintln!(
        "leaves dim / bright: absolute {leaves_abs:.3}, relative {leaves_rel:.3}; \
         dim room × 16 against the bright room: absolute {diff_abs:.4}, relative {diff_rel:.4}"
    );
    assert!(leaves_abs < 0.2, "{leaves_abs}");
    assert!(leaves_rel > 0.6, "{leaves_rel}");
    assert!(
        diff_rel < diff_abs && diff_rel < 0.003,
        "{diff_rel} vs {diff_abs}"
    );
}

/// Area-weighted mean luminance-like value (channel mean) over the
/// patches of surface `name`, from `value(patch, area)`.
fn surface_mean(scene: &Scene, name: &str, value: impl Fn(usize) -> f64) -> f64 {
    let (mut sum, mut area) = (0.0, 0.0);
    for (p, patch) in scene.patches.iter().enumerate() {
        if scene.surfaces[patch.surface as usize].name == name {
            sum += value(p) * patch.area;
            area += patch.area;
        }
    }
    assert!(area > 0.0, "no surface {name}");
    sum / area
}

#[test]
fn the_sealed_room_gets_nothing_through_its_wall() {
    let scene = bundled_scene("hard/sealed-rooms.gltf");
    let bvh = TriangleBvh::of_scene(&scene);
    for (preset, accuracy) in presets() {
        let s = solve(&scene, &bvh, accuracy);
        // Per patch, the area-weighted mean of its leaves' radiosity.
        let mut sum = vec![(0.0, 0.0); scene.patches.len()];
        for leaf in s.hierarchy.leaves() {
            let e = s.hierarchy.get(leaf);
            let b = e.radiosity.element_sum() / 3.0;
            sum[e.patch as usize].0 += b * e.area;
            sum[e.patch as usize].1 += e.area;
        }
        let mean = |p: usize| sum[p].0 / sum[p].1;
        let lit = surface_mean(&scene, "lit_room", mean);
        let sealed = surface_mean(&scene, "sealed_room", mean);
        eprintln!("{preset}: lit room {lit:.4}, sealed room {sealed:.3e} (elements)");
        assert!(lit > 0.1, "{preset}: the lit room is dark ({lit})");
        assert!(
            sealed <= 1e-3 * lit,
            "{preset}: {sealed} leaks into the sealed room"
        );

        // The output mesh's vertices, each a point evaluation of every link.
        let mesh = output_mesh(&scene, &bvh, &s, VertexValues::PointGather { seed: 7 });
        let (mut worst, mut count) = (0.0f64, 0);
        for (v, &p) in mesh.patch.iter().enumerate() {
            if scene.surfaces[scene.patches[p as usize].surface as usize].name == "sealed_room" {
                worst = worst.max(f64::from(mesh.radiosity[v].max_element()));
                count += 1;
            }
        }
        eprintln!("{preset}: {count} sealed-room vertices, brightest {worst:.3e}");
        assert!(count > 0);
        assert!(
            worst <= 1e-3 * lit,
            "{preset}: a sealed-room vertex at {worst}"
        );
    }
}

#[test]
fn table_gap_agrees_with_its_committed_point_table() {
    use nusselt::lab::points::read_table;
    // scenes/hard/table-gap.points.csv: `nusselt probe
    // scenes/hard/table-gap.gltf --random 60 --spp 100000 --seed 3`,
    // median standard error 0.25 %. Measured: preview median 0.90 %, p90
    // 4.1 %, mean bias −0.05 %; default 0.77 %, 2.1 %, −0.06 %.
    let table = read_table(&crate::fixtures::scene_path("hard/table-gap.points.csv")).unwrap();
    let scene = bundled_scene("hard/table-gap.gltf");
    let mut last = f64::INFINITY;
    for (preset, accuracy, median, p90) in [
        ("preview", Accuracy::preview(), 0.015, 0.06),
        ("default", Accuracy::default(), 0.012, 0.03),
    ] {
        let hierarchical = HierarchicalSettings {
            accuracy,
            ..HierarchicalSettings::default()
        };
        let (_, s) = solve_and_score(&scene, hierarchical, &table);
        eprintln!(
            "{preset}: median {:.4}, p90 {:.4}, mean bias {:+.4}",
            s.median, s.p90, s.mean_bias
        );
        assert_eq!(s.outside, 0);
        assert!(s.median <= median && s.p90 <= p90, "{preset}: {s:?}");
        assert!(s.mean_bias.abs() <= 0.005, "{preset}: bias {}", s.mean_bias);
        assert!(s.p90 < last, "{preset}: no better than the coarser preset");
        last = s.p90;
    }
}

/// The baffle scene: a 2 m × 2 m lamp at z = 2 facing down, a 4 m × 4 m
/// floor at z = 0 (surface `s1`), and between them eight slats 0.35 m wide
/// at 45°, 0.25 m apart, both faces (surfaces `s2`..), all of ρ 0.5.
fn baffle() -> (Scene, [DVec3; 4]) {
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let mut quads = vec![
        (
            [
                p(-1.0, -1.0, 2.0),
                p(-1.0, 1.0, 2.0),
                p(1.0, 1.0, 2.0),
                p(1.0, -1.0, 2.0),
            ],
            2,
            true,
        ),
        (
            [
                p(-2.0, -2.0, 0.0),
                p(2.0, -2.0, 0.0),
                p(2.0, 2.0, 0.0),
                p(-2.0, 2.0, 0.0),
            ],
            4,
            false,
        ),
    ];
    // Eight slats 0.35 m wide at 45°, 0.25 m apart, both faces.
    for k in 0..8 {
        let y = -1.0 + 0.25 * k as f64;
        let (a, b) = (p(-2.0, y, 1.0), p(-2.0, y + 0.25, 1.25));
        let (c, d) = (b + p(4.0, 0.0, 0.0), a + p(4.0, 0.0, 0.0));
        quads.push(([a, b, c, d], 1, false));
        quads.push(([a, d, c, b], 1, false));
    }
    (crate::fixtures::painted(&quads, 0.5, 0.0), quads[1].0)
}

/// The light the baffle's slats reflect onto the floor, by the solver's
/// links against cosine rays cast from the floor that take the radiosity
/// of the slat leaf they hit. The floor sees the slats through the gaps
/// between them, at their lower edges, which are darker than a slat's
/// mean. Measured with the absolute threshold: 0.972; 1.047 when a partly
/// hidden source handed every receiver its mean. (With the preset's
/// relative threshold, 0.954 and 0.978: the shares' noise, eight source
/// points over four quarters, costs more on its finer links; issue 21.)
#[test]
fn light_reflected_through_gaps_is_that_of_the_parts_in_sight() {
    use nusselt::sampling::{PolygonSampler, stream};
    use nusselt::util::geometry::outside_polygon;
    use rand::Rng;
    let (scene, floor) = baffle();
    let bvh = TriangleBvh::of_scene(&scene);
    let accuracy = Accuracy {
        bf_relative_floor: 1.0,
        ..Accuracy::default()
    };
    let s = solve(&scene, &bvh, accuracy);
    let h = &s.hierarchy;
    let name = |patch: u32| &scene.surfaces[scene.patches[patch as usize].surface as usize].name;
    let on_slat = |patch: u32| !matches!(name(patch).as_str(), "s0" | "s1");
    let from_slats = s.irradiance_from(on_slat);
    let by_links: f64 = h
        .leaves()
        .filter(|l| name(h.get(*l).patch) == "s1")
        .map(|l| from_slats[l.index()].x * h.get(l).area)
        .sum();
    // The leaf of `patch` that holds x.
    let leaf = |patch: u32, x: DVec3| {
        let n = scene.patches[patch as usize].normal;
        let mut id = h.root(patch as usize);
        while let Some(kids) = h.get(id).children() {
            let out = |k: &nusselt::hierarchical::hierarchy::ElementId| {
                outside_polygon(h.get(*k).vertices(), n, x)
            };
            id = *kids
                .iter()
                .min_by(|a, b| out(a).total_cmp(&out(b)))
                .unwrap();
        }
        h.get(id)
    };
    // Each slat face's patch and the other face's (one patch a face).
    let twin: Vec<u32> = (0..scene.patches.len())
        .map(|p| {
            let c = scene.patches[p].centroid();
            (0..scene.patches.len() as u32)
                .find(|&q| {
                    q as usize != p && scene.patches[q as usize].centroid().distance(c) < 1e-9
                })
                .unwrap_or(p as u32)
        })
        .collect();
    let sampler = PolygonSampler::new(&floor);
    let mut rng = stream(7, 0);
    let n = 400_000;
    let mut sum = 0.0;
    for _ in 0..n {
        let x = sampler.point(glam::DVec2::new(rng.random(), rng.random()));
        let (u, v): (f64, f64) = (rng.random(), rng.random());
        let (r, phi) = (u.sqrt(), std::f64::consts::TAU * v);
        let d = DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).max(0.0).sqrt());
        if let Some(hit) = bvh.closest_hit(x + 1e-6 * DVec3::Z, d, 10.0) {
            let patch = scene.triangles[hit.triangle as usize].front_patch;
            if !on_slat(patch) {
                continue;
            }
            // A slat's two faces are coincident quads: the hit may name
            // either; the face the ray meets is the one facing it.
            let facing = scene.patches[patch as usize].normal.dot(d) < 0.0;
            let face = if facing { patch } else { twin[patch as usize] };
            let y = x + 1e-6 * DVec3::Z + hit.t * d;
            sum += leaf(face, y).exposed_radiosity.x;
        }
    }
    let by_rays = 16.0 * sum / f64::from(n);
    let ratio = by_links / by_rays;
    eprintln!("slats onto the floor: links {by_links:.4} W, rays {by_rays:.4} W, ratio {ratio:.4}");
    assert!(
        (ratio - 1.0).abs() < 0.04,
        "links deliver {ratio:.4} × what rays see"
    );
}

/// Direct light through a baffle of tilted slats (the lecture's museum in
/// small): the floor's irradiance from the lamp by the solver's links
/// against cosine rays cast from the floor. Most lamp–floor pairs are in
/// penumbra here, where links accepted on the readings of the rays that
/// decided them lose the light of every pair whose rays happened to be
/// all blocked.
#[test]
fn light_through_a_baffle_is_what_rays_see() {
    use nusselt::sampling::{PolygonSampler, stream};
    use rand::Rng;
    let (scene, floor) = baffle();
    let bvh = TriangleBvh::of_scene(&scene);
    let s = solve(&scene, &bvh, Accuracy::default());
    let is_lamp = |patch: u32| scene.patches[patch as usize].is_emitter();
    let direct = s.irradiance_from(is_lamp);
    let on_floor =
        |patch: u32| scene.surfaces[scene.patches[patch as usize].surface as usize].name == "s1";
    let by_links: f64 = s
        .hierarchy
        .leaves()
        .filter(|l| on_floor(s.hierarchy.get(*l).patch))
        .map(|l| direct[l.index()].x * s.hierarchy.get(l).area)
        .sum::<f64>()
        + (0..scene.patches.len() as u32)
            .filter(|&p| on_floor(p))
            .map(|p| {
                s.cluster_direct.get(p as usize).map_or(0.0, |c| c.x)
                    * scene.patches[p as usize].area
            })
            .sum::<f64>();
    // Cosine rays from uniform floor points: the fraction that reaches the
    // lamp's front, times its exitance π.
    let sampler = PolygonSampler::new(&floor);
    let mut rng = stream(5, 0);
    let n = 400_000;
    let mut hits = 0u32;
    for _ in 0..n {
        let x = sampler.point(glam::DVec2::new(rng.random(), rng.random()));
        let (u, v): (f64, f64) = (rng.random(), rng.random());
        let (r, phi) = (u.sqrt(), std::f64::consts::TAU * v);
        let d = DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).max(0.0).sqrt());
        let reaches_lamp = bvh
            .closest_hit(x + 1e-6 * DVec3::Z, d, 10.0)
            .is_some_and(|hit| {
                let t = &scene.triangles[hit.triangle as usize];
                is_lamp(t.front_patch)
                    && (t.positions[1] - t.positions[0])
                        .cross(t.positions[2] - t.positions[0])
                        .dot(d)
                        < 0.0
            });
        hits += u32::from(reaches_lamp);
    }
    let fraction = f64::from(hits) / f64::from(n);
    let floor_area = 16.0;
    let by_rays = std::f64::consts::PI * fraction * floor_area;
    let se = (fraction * (1.0 - fraction) / f64::from(n)).sqrt() / fraction;
    let ratio = by_links / by_rays;
    eprintln!("baffle: links {by_links:.4} W, rays {by_rays:.4} W (± {se:.4}), ratio {ratio:.4}");
    // Measured: 0.983 (0.959 when the rays that decided a link's
    // acceptance also set its visibility of 0).
    assert!(
        (ratio - 1.0).abs() < 0.025,
        "links deliver {ratio:.4} × what rays see"
    );
}

#[test]
fn a_smoothly_lit_wall_has_no_steps_at_its_patch_edges() {
    // A closed room whose faces are 8 × 8 grids of patches, clusters on (so
    // that cluster links carry part of every patch's light), lit by a
    // ceiling panel. Where two patches of one wall meet, their shared
    // vertices are separate gathers of one irradiance: they must agree
    // (`meshing::seams`, the report's `estimated_error`). The leaves' own
    // means, which step from patch to patch, show that the measure sees a
    // checkerboard when there is one.
    use crate::fixtures::{Room, room};
    use nusselt::hierarchical::Clustering;
    use nusselt::meshing::seams::seam_steps;
    use nusselt::pipeline::{SolveSettings, solve as solve_scene};
    use nusselt::render::view::ViewOverrides;

    let scene = room(Room {
        n: 8,
        blocks: 0,
        floating: false,
        rho: 0.6,
        furnace: false,
    });
    // Bounds (p90, median) of the relative steps; measured 4.9 %, 1.6 %
    // (preview) and 0.77 %, 0.19 % (default); the leaves' means 22–24 %,
    // 8–10 %.
    for (preset, accuracy, bound) in [
        ("preview", Accuracy::preview(), (0.07, 0.025)),
        ("default", Accuracy::default(), (0.015, 0.005)),
    ] {
        let mut settings = SolveSettings::default();
        settings.hierarchical.accuracy = accuracy.clone();
        settings.hierarchical.clustering = Clustering::On;
        settings.view = ViewOverrides {
            width: Some(32),
            height: Some(24),
            ..ViewOverrides::default()
        };
        let run = solve_scene(&scene, &settings, &Progress::hidden()).unwrap();
        let steps = run.report.estimated_error.expect("the walls have seams");
        eprintln!("{preset}: {steps:?}");
        assert!(steps.pairs > 500, "{preset}: {} seam pairs", steps.pairs);
        assert!(
            steps.p90 <= bound.0 && steps.median <= bound.1,
            "{preset}: vertices across patch edges disagree: {steps:?}"
        );

        let bvh = TriangleBvh::of_scene(&scene);
        let hs = HierarchicalSettings {
            accuracy,
            clustering: Clustering::On,
            ..HierarchicalSettings::default()
        };
        let s = solve_hierarchical(&scene, &bvh, &hs, &Progress::hidden());
        let leaf_means = seam_steps(
            &scene,
            &output_mesh(&scene, &bvh, &s, VertexValues::LeafMean),
        )
        .expect("the walls have seams");
        eprintln!("{preset}, leaf means: {leaf_means:?}");
        assert!(
            leaf_means.p90 > 2.0 * steps.p90,
            "{preset}: leaf means {leaf_means:?} against {steps:?}"
        );
    }
}

#[test]
fn the_floor_under_a_pedestal_stays_dark() {
    // A closed room lit by a ceiling panel, clusters on, with a closed
    // pedestal (a box turned 30° about the vertical, its bottom face on the
    // floor) standing across four floor patches. The floor under it is
    // sealed off: at its leaves and at the output mesh's vertices inside
    // the footprint the radiosity must be nil, direct and indirect.
    use crate::fixtures::{box_faces, painted};
    use nusselt::hierarchical::Clustering;

    let turn = glam::DQuat::from_rotation_y(30f64.to_radians());
    let centre = DVec3::new(2.0, 0.0, 2.5);
    let place = |p: DVec3| centre + turn * (p - DVec3::new(0.35, 0.0, 0.35));
    let mut quads = Vec::new();
    for q in box_faces(DVec3::ZERO, DVec3::new(4.0, 3.0, 5.0)) {
        quads.push(([q[0], q[3], q[2], q[1]], 4, false));
    }
    let lamp =
        [(1.5, 2.0), (2.5, 2.0), (2.5, 3.0), (1.5, 3.0)].map(|(x, z)| DVec3::new(x, 2.99, z));
    quads.push((lamp, 1, true));
    let faces = box_faces(DVec3::ZERO, DVec3::new(0.7, 1.1, 0.7));
    for q in &faces {
        quads.push((q.map(place), 3, false));
    }
    let scene = painted(&quads, 0.6, 0.0);
    let footprint: Vec<DVec3> = faces[0].iter().map(|&p| place(p)).collect();
    let under = |p: DVec3, inset: f64| {
        // The footprint is convex; its corners run one way round.
        (0..4).all(|i| {
            let (a, b) = (footprint[i], footprint[(i + 1) % 4]);
            let side = (b - a).cross(p - a).y / (b - a).length();
            side.abs() >= inset && side.signum() == (b - a).cross(centre - a).y.signum()
        })
    };
    let bvh = TriangleBvh::of_scene(&scene);
    for (preset, accuracy) in [
        ("preview", Accuracy::preview()),
        ("default", Accuracy::default()),
    ] {
        let hs = HierarchicalSettings {
            accuracy,
            clustering: Clustering::On,
            ..HierarchicalSettings::default()
        };
        let s = solve_hierarchical(&scene, &bvh, &hs, &Progress::hidden());
        let on_floor = |p: u32| {
            scene.patches[p as usize].normal.y > 0.99
                && scene.patches[p as usize].corners[0].y.abs() < 1e-9
        };
        let (mut lit, mut area, mut worst_leaf, mut buried) = (0.0, 0.0, 0.0f64, 0);
        for leaf in s.hierarchy.leaves() {
            let e = s.hierarchy.get(leaf);
            if !on_floor(e.patch) {
                continue;
            }
            let b = e.radiosity.element_sum() / 3.0;
            if e.vertices().iter().all(|&v| under(v, 0.0)) {
                worst_leaf = worst_leaf.max(b);
                buried += 1;
            } else {
                lit += b * e.area;
                area += e.area;
            }
        }
        let lit = lit / area;
        let mesh = output_mesh(&scene, &bvh, &s, VertexValues::PointGather { seed: 3 });
        let (mut worst_vertex, mut inside) = (0.0f64, 0);
        for (v, &p) in mesh.patch.iter().enumerate() {
            if on_floor(p) && under(mesh.positions[v].as_dvec3(), 0.02) {
                worst_vertex = worst_vertex.max(f64::from(mesh.radiosity[v].max_element()));
                inside += 1;
            }
        }
        eprintln!(
            "{preset}: floor {lit:.4}; {buried} leaves under the pedestal, brightest {worst_leaf:.2e}; {inside} vertices, brightest {worst_vertex:.2e}"
        );
        assert!(
            buried > 0 && inside > 0,
            "{preset}: nothing under the pedestal"
        );
        assert!(
            worst_leaf <= 1e-3 * lit,
            "{preset}: a leaf under the pedestal at {worst_leaf}"
        );
        assert!(
            worst_vertex <= 1e-3 * lit,
            "{preset}: a vertex under the pedestal at {worst_vertex}"
        );
    }
}

/// A closed hall, 10 m long, with a lit panel at one end hidden from the
/// hall behind a second panel that faces the same way (the lamp between
/// them lights the first): seen from the hall, a cluster holding both has
/// the mean of a bright and a dim face, while only the dim one is in
/// sight. At cluster thresholds coarse enough for such clusters to stand
/// for their members, a cluster link must carry what its rays reach, not
/// that mean. Measured: 0.9946 and 0.9982 at cluster_eps 0.3 and 3; with
/// the clusters' mean, 1.0129 and 1.0499.
#[test]
fn a_cluster_link_carries_what_its_rays_reach_not_its_clusters_mean() {
    use crate::fixtures::{box_faces, painted};
    use nusselt::hierarchical::Clustering;
    let p = DVec3::new;
    let mut quads = Vec::new();
    for q in box_faces(DVec3::ZERO, p(10.0, 3.0, 3.0)) {
        quads.push(([q[0], q[3], q[2], q[1]], 4, false));
    }
    // Facing +x (counter-clockwise seen from +x), or −x.
    let panel = |x: f64, lo: f64, hi: f64, toward_plus: bool| {
        let q = [p(x, lo, lo), p(x, hi, lo), p(x, hi, hi), p(x, lo, hi)];
        if toward_plus {
            q
        } else {
            [q[0], q[3], q[2], q[1]]
        }
    };
    // Every face has a back, so that the hall stays closed.
    for (x, lo, hi) in [(0.5, 0.5, 2.5), (1.1, 0.5, 2.5)] {
        quads.push((panel(x, lo, hi, true), 2, false));
        quads.push((panel(x, lo, hi, false), 2, false));
    }
    quads.push((panel(0.8, 1.0, 2.0, false), 1, true));
    quads.push((panel(0.8, 1.0, 2.0, true), 1, false));
    let scene = painted(&quads, 0.7, 0.0);
    let bvh = TriangleBvh::of_scene(&scene);
    let mut failures = Vec::new();
    for cluster_eps in [0.3, 3.0] {
        let settings = HierarchicalSettings {
            accuracy: Accuracy {
                cluster_eps,
                ..Accuracy::default()
            },
            clustering: Clustering::On,
            ..HierarchicalSettings::default()
        };
        let s = solve_hierarchical(&scene, &bvh, &settings, &Progress::hidden());
        let ratio = closure(&scene, &s).x;
        eprintln!("hidden lit panel, cluster_eps {cluster_eps}: absorbed / emitted {ratio:.4}");
        if (ratio - 1.0).abs() > 0.01 {
            failures.push(format!("{cluster_eps}: {ratio:.4}"));
        }
    }
    assert!(failures.is_empty(), "off by more than 1 %: {failures:?}");
}

/// A black lamp 0.3 m in front of the panel it lights, in a closed hall
/// of 0.7 paint: the lamp reflects nothing, yet what it absorbs of the
/// panel's light has to add up. Measured: 1.0117 (the remaining excess:
/// links from the panel's coarse elements to the walls beside it, a few
/// tenths of a percent per bounce, tripled by the paint); with a second
/// panel closing the lamp in, 0.857 when links into a black receiver were
/// never split (they carried the panel's mean radiosity, well below what
/// its bright middle sends the lamp), 0.9952 since.
#[test]
fn a_black_lamp_absorbs_what_reaches_it() {
    use crate::fixtures::{box_faces, painted};
    let p = DVec3::new;
    let mut quads = Vec::new();
    for q in box_faces(DVec3::ZERO, p(10.0, 3.0, 3.0)) {
        quads.push(([q[0], q[3], q[2], q[1]], 4, false));
    }
    let panel = |x: f64, lo: f64, hi: f64, toward_plus: bool| {
        let q = [p(x, lo, lo), p(x, hi, lo), p(x, hi, hi), p(x, lo, hi)];
        if toward_plus {
            q
        } else {
            [q[0], q[3], q[2], q[1]]
        }
    };
    quads.push((panel(0.5, 0.5, 2.5, true), 2, false));
    quads.push((panel(0.5, 0.5, 2.5, false), 2, false));
    quads.push((panel(0.8, 1.0, 2.0, false), 1, true));
    quads.push((panel(0.8, 1.0, 2.0, true), 1, false));
    let scene = painted(&quads, 0.7, 0.0);
    let bvh = TriangleBvh::of_scene(&scene);
    let ratio = closure(&scene, &solve(&scene, &bvh, Accuracy::default())).x;
    eprintln!("black lamp before a panel: absorbed / emitted {ratio:.4}");
    assert!((ratio - 1.0).abs() < 0.02, "{ratio:.4}");
}
