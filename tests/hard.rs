//! The hard interiors of `scenes/hard/`: energy closure per closed scene
//! and preset, no light through the sealed room's wall (at its elements
//! and at the output mesh's vertices), and the box under the table against
//! its committed path-traced point table, tighter at the finer preset.

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
    // The gallery (clusters) is not in this list yet: it closes to 0.95
    // at the default preset (issue 21).
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
    use nusselt::lab::points::{read_table, score};
    use nusselt::render::RenderSettings;
    use nusselt::render::view::ViewOverrides;
    use nusselt::{SolveSettings, solve};
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
        let settings = SolveSettings {
            hierarchical: HierarchicalSettings {
                accuracy,
                ..HierarchicalSettings::default()
            },
            render: RenderSettings {
                samples_per_pixel: 1,
                seed: 0,
            },
            view: ViewOverrides {
                width: Some(32),
                height: Some(24),
                ..ViewOverrides::default()
            },
            ..SolveSettings::default()
        };
        let run = solve(&scene, &settings, &Progress::hidden()).unwrap();
        let (s, _) = score(&run.mesh, &table).unwrap();
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
