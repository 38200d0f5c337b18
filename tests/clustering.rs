//! Clustering ([`nusselt::hierarchical::cluster`]): with and without clusters the
//! solutions agree, the enclosure and furnace identities hold with
//! clusters, and links and rays grow far slower than k².

use glam::DVec3;
use nusselt::hierarchical::cluster::{ClusterTree, Clusters, Node, Step};
use nusselt::hierarchical::hierarchy::Hierarchy;
use nusselt::hierarchical::link::Evaluator;
use nusselt::hierarchical::{
    Accuracy, Clustering, HierarchicalSettings, HierarchicalSolution, solve_hierarchical,
};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::meshing::point_gather::dark_emitters;
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use crate::fixtures::scenegen::{write_fan, write_scale};
use crate::fixtures::{LIT_ROOM, Room, on_threads, painted, room};

fn solve(scene: &Scene, clustering: Clustering, accuracy: Accuracy) -> HierarchicalSolution {
    let settings = HierarchicalSettings {
        accuracy,
        clustering,
        ..HierarchicalSettings::default()
    };
    let s = solve_hierarchical(
        scene,
        &TriangleBvh::of_scene(scene),
        &settings,
        &Progress::hidden(),
    );
    s.hierarchy.validate(scene).unwrap();
    assert_eq!(s.clusters.is_some(), clustering == Clustering::On);
    s
}

/// (absorbed / emitted, Σ B·A) over the leaves, first channel.
fn balance(scene: &Scene, s: &HierarchicalSolution) -> (f64, f64) {
    let h = &s.hierarchy;
    let (mut emitted, mut absorbed, mut radiated) = (0.0, 0.0, 0.0);
    for id in h.leaves() {
        let e = h.get(id);
        let p = &scene.patches[e.patch as usize];
        emitted += p.emission.x * e.area;
        absorbed += (1.0 - p.reflectance.x) * s.irradiance[id.index()].x * e.area;
        radiated += e.radiosity.x * e.area;
    }
    (absorbed / emitted, radiated)
}

/// Area-weighted mean relative difference of the patches' radiosities.
fn patch_difference(scene: &Scene, a: &HierarchicalSolution, b: &HierarchicalSolution) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, p) in scene.patches.iter().enumerate() {
        let (x, y) = (
            a.hierarchy.elements[i].radiosity.x,
            b.hierarchy.elements[i].radiosity.x,
        );
        num += p.area * (x - y).abs();
        den += p.area * y.abs();
    }
    num / den
}

#[test]
fn clusters_agree_with_patch_pairs_and_keep_the_enclosure_balance() {
    // Measured (preview): absorbed / emitted 0.990 without clusters, 0.989
    // with; patches differ by 0.4 % area-weighted. The cluster oracle
    // bounds each link's error, not their sum: stated tolerances 2 % on
    // the balance, 3 % on the patches.
    let scene = room(LIT_ROOM);
    let off = solve(&scene, Clustering::Off, Accuracy::preview());
    let on = solve(&scene, Clustering::On, Accuracy::preview());
    let (ratio_off, _) = balance(&scene, &off);
    let (ratio_on, _) = balance(&scene, &on);
    let diff = patch_difference(&scene, &on, &off);
    eprintln!(
        "{} patches: absorbed/emitted off {ratio_off:.4} ({} links), on {ratio_on:.4} ({} links, {} with clusters); patches differ {diff:.4}",
        scene.patches.len(),
        off.link_count(),
        on.link_count(),
        on.cluster_link_count()
    );
    let tree = &on.clusters.as_ref().unwrap().tree;
    tree.validate(&scene).unwrap();
    assert_eq!(tree.len(), scene.patches.len() - 1);
    assert!(on.cluster_link_count() > 0);
    assert!((ratio_on - 1.0).abs() < 0.02, "{ratio_on}");
    assert!(
        (ratio_on - ratio_off).abs() < 0.02,
        "{ratio_on} vs {ratio_off}"
    );
    assert!(diff < 0.03, "{diff}");
    // The final gather gets the cluster links' light per patch, of which
    // the emitters' part is a share.
    let lit: f64 = on.cluster_irradiance.iter().map(|h| h.x).sum();
    assert!(lit > 0.0);
    for (d, t) in on.cluster_direct.iter().zip(&on.cluster_irradiance) {
        assert!(d.x >= 0.0 && d.x <= t.x * (1.0 + 1e-9), "{d} of {t}");
    }
}

#[test]
fn furnace_identity_holds_with_clusters() {
    // Every front surface of a closed scene emits E and reflects ρ: B =
    // E / (1 − ρ) everywhere, whatever the form factors. Floating closed
    // boxes occlude without burying anything.
    let rho = 0.5;
    let scene = room(Room {
        floating: true,
        furnace: true,
        rho,
        ..LIT_ROOM
    });
    let s = solve(&scene, Clustering::On, Accuracy::preview());
    let exact = std::f64::consts::PI / (1.0 - rho);
    let (mut num, mut den, mut worst) = (0.0, 0.0, 0.0f64);
    for (i, p) in scene.patches.iter().enumerate() {
        let b = s.hierarchy.elements[i].radiosity.x;
        num += p.area * (b - exact).abs();
        den += p.area * exact;
        worst = worst.max((b - exact).abs() / exact);
    }
    let (_, radiated) = balance(&scene, &s);
    let total = radiated / (scene.total_area() * exact);
    eprintln!(
        "furnace with clusters: Σ B·A / exact {total:.4}, patches {:.4} mean, {worst:.4} worst ({} cluster links)",
        num / den,
        s.cluster_link_count()
    );
    assert!(s.cluster_link_count() > 0);
    // Measured: 1.005; patches 0.7 % mean, 3.6 % worst.
    assert!((total - 1.0).abs() < 0.02, "{total}");
    assert!(num / den < 0.03 && worst < 0.15, "{} {worst}", num / den);
}

#[test]
fn same_solution_for_one_and_two_threads_with_clusters() {
    let scene = room(LIT_ROOM);
    let run = || solve(&scene, Clustering::On, Accuracy::preview());
    let one = on_threads(1, run);
    let two = on_threads(2, run);
    assert_eq!(one.link_count(), two.link_count());
    assert_eq!(one.visibility_rays, two.visibility_rays);
    let b = |s: &HierarchicalSolution| -> Vec<[f64; 3]> {
        s.hierarchy
            .elements
            .iter()
            .map(|e| e.radiosity.to_array())
            .collect()
    };
    assert_eq!(b(&one), b(&two));
}

#[test]
fn links_and_rays_grow_far_slower_than_k_squared() {
    // The office family at 1,250 to 10,000 triangles, preview accuracy.
    let dir = std::env::temp_dir().join(format!("nusselt-cluster-growth-{}", std::process::id()));
    let mut rows = Vec::new();
    for target in [1_250, 2_500, 5_000, 10_000] {
        let (files, _) = write_scale(&dir, target).unwrap();
        let scene = load_scene(&files[0], &LoadOptions::default()).unwrap();
        let s = solve(&scene, Clustering::On, Accuracy::preview());
        let k = scene.patches.len() as f64;
        rows.push((k, s.link_count() as f64, s.visibility_rays as f64));
        eprintln!(
            "{target} triangles: {k} patches, {} links ({} with clusters), {} rays",
            s.link_count(),
            s.cluster_link_count(),
            s.visibility_rays
        );
    }
    std::fs::remove_dir_all(&dir).ok();
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    let slope = |a: f64, b: f64| (b / a).ln() / (last.0 / first.0).ln();
    let (links, rays) = (slope(first.1, last.1), slope(first.2, last.2));
    eprintln!("growth exponents against k: links {links:.2}, rays {rays:.2} (k² is 2)");
    assert!(links < 1.4 && rays < 1.4, "links {links}, rays {rays}");
    // Far below the k² pairs a start without clusters would evaluate.
    assert!(last.1 < 0.1 * last.0 * last.0, "{last:?}");
}

/// A 1 m² lamp 2 m above two floor tiles, with or without an opaque slab
/// between them; the cluster of the two tiles (receiver) and the lamp.
fn tiles_under_lamp(slab: bool) -> (Scene, Node, Node) {
    let p = DVec3::new;
    let mut quads = vec![
        (
            [
                p(0., 0., 0.),
                p(0., 0., 0.5),
                p(0.5, 0., 0.5),
                p(0.5, 0., 0.),
            ],
            1,
            false,
        ),
        (
            [
                p(0.5, 0., 0.),
                p(0.5, 0., 0.5),
                p(1., 0., 0.5),
                p(1., 0., 0.),
            ],
            1,
            false,
        ),
        (
            [p(0., 2., 0.), p(1., 2., 0.), p(1., 2., 1.), p(0., 2., 1.)],
            1,
            true,
        ),
    ];
    if slab {
        quads.push((
            [
                p(-2., 1., -2.),
                p(-2., 1., 3.),
                p(3., 1., 3.),
                p(3., 1., -2.),
            ],
            1,
            false,
        ));
    }
    let scene = painted(&quads, 0.5, 0.0);
    let tiles: Vec<u32> = (0..scene.patches.len() as u32)
        .filter(|&k| scene.patches[k as usize].corners[0].y == 0.0)
        .collect();
    let lamp = (0..scene.patches.len() as u32)
        .find(|&k| scene.patches[k as usize].is_emitter())
        .unwrap();
    let tree = ClusterTree::new(&scene);
    let pair = (0..tree.len() as u32)
        .find(|&c| {
            let c = &tree.clusters[c as usize];
            let mut run = tree.order[c.first as usize..(c.first + c.count) as usize].to_vec();
            run.sort_unstable();
            run == tiles
        })
        .expect("the two tiles form a cluster");
    (scene, Node::Cluster(pair), Node::Patch(lamp))
}

/// The cluster oracle spends rays on a pair only when some visibility
/// would let it accept: a pair acceptable only when blocked is opened by
/// its first ray that gets through, and, when every ray is blocked, is
/// accepted with a value from fresh rays. Blocked pairs thus stop opening
/// at a coarser level than visible ones.
#[test]
fn cluster_oracle_accepts_blocked_pairs_early_and_opens_visible_ones_cheaply() {
    let examine = |slab: bool, eps: f64| {
        let (scene, r, s) = tiles_under_lamp(slab);
        let clusters = Clusters::new(&scene);
        let elements = Hierarchy::new(&scene).elements;
        let bvh = TriangleBvh::of_scene(&scene);
        let at = Evaluator {
            scene: &scene,
            elements: &elements,
            bvh: &bvh,
            seed: 7,
        };
        clusters.examine(&at, r, s, eps)
    };
    let (mut band, mut visible_from, mut blocked_from) = (0, f64::INFINITY, f64::INFINITY);
    for i in 0..60 {
        let eps = 1e-4 * 1.25f64.powi(i);
        let (open, blocked) = (examine(false, eps), examine(true, eps));
        match open {
            (Step::Accept(_), _) => visible_from = visible_from.min(eps),
            (Step::OpenReceiver, 0) => {}
            (Step::OpenReceiver, 1) => band += 1,
            other => panic!("visible pair at eps {eps}: {other:?}"),
        }
        match blocked {
            (Step::OpenReceiver, 0) => assert!(eps < visible_from),
            (Step::Accept(link), rays) => {
                blocked_from = blocked_from.min(eps);
                assert_eq!(link.transfer, 0.0);
                assert!(rays == 8 || rays == 16, "{rays} rays");
            }
            other => panic!("blocked pair at eps {eps}: {other:?}"),
        }
    }
    assert!(band > 0 && visible_from.is_finite());
    // The floor 1/8 of a blocked pair against 1/r² spread plus 1/8 of a
    // visible one: accepted at a threshold several times smaller.
    assert!(
        4.0 * blocked_from < visible_from,
        "{blocked_from} vs {visible_from}"
    );
}

/// Patches in one plane facing one way exchange no light, so the oracle
/// drops a flat cluster's self-link and a link between coplanar nodes
/// without a ray, while a flat cluster and the lamp above it are still
/// examined. (A fan of n slivers meeting at a point had every pair of its
/// touching clusters opened: O(n²) examinations, its linking 14× slower
/// at 10,000 slivers.)
#[test]
fn coplanar_nodes_exchange_nothing_and_are_dropped() {
    let (scene, tiles, lamp) = tiles_under_lamp(false);
    let clusters = Clusters::new(&scene);
    let tree = &clusters.tree;
    let Node::Cluster(c) = tiles else {
        unreachable!()
    };
    let (n, d) = tree.clusters[c as usize].plane.expect("the tiles are flat");
    assert!((n - DVec3::Y).length() < 1e-9 && d.abs() < 1e-9, "{n} {d}");
    assert!(
        tree.clusters[0].plane.is_none(),
        "tiles and lamp are not flat"
    );
    let elements = Hierarchy::new(&scene).elements;
    let bvh = TriangleBvh::of_scene(&scene);
    let at = Evaluator {
        scene: &scene,
        elements: &elements,
        bvh: &bvh,
        seed: 7,
    };
    assert!(matches!(
        clusters.examine(&at, tiles, tiles, 0.0),
        (Step::Drop, 0)
    ));
    let [a, b] = tree.clusters[c as usize].kids;
    assert!(matches!(
        clusters.examine(&at, tiles, a, 0.0),
        (Step::Drop, 0)
    ));
    assert!(matches!(
        clusters.examine(&at, a, tiles, 0.0),
        (Step::Drop, 0)
    ));
    assert!(matches!(
        clusters.examine(&at, a, b, 0.0),
        (Step::Patches, 0)
    ));
    let (step, _) = clusters.examine(&at, tiles, lamp, 0.0);
    assert!(!matches!(step, Step::Drop), "{step:?}");
    // The root (tiles and lamp) keeps its self-link.
    assert!(matches!(
        clusters.examine(&at, Node::Cluster(0), Node::Cluster(0), 0.0),
        (Step::SelfLink(0), 0)
    ));
}

/// A disc of 2,048 slivers meeting at its centre (`gen-scenes --fan`)
/// takes the light of the square above it as one of 256 does: the
/// clusters its slivers make are flat, their links dropped, and the disc
/// still gets all the light (Σ B·A of the disc, clustered, to 0.5 %).
#[test]
fn a_fan_of_slivers_gets_the_light_of_a_coarse_disc() {
    let dir = tempfile::tempdir().unwrap();
    let radiated = |n: usize| {
        let files = write_fan(dir.path(), n).unwrap();
        let scene = load_scene(&files[0], &LoadOptions::default()).unwrap();
        let s = solve(&scene, Clustering::On, Accuracy::preview());
        let h = &s.hierarchy;
        h.leaves()
            .map(|id| h.get(id))
            .filter(|e| !scene.patches[e.patch as usize].is_emitter())
            .map(|e| e.radiosity.x * e.area)
            .sum::<f64>()
    };
    let (coarse, fine) = (radiated(256), radiated(2048));
    eprintln!("disc: {coarse} W at 256 slivers, {fine} W at 2048");
    assert!((fine / coarse - 1.0).abs() < 5e-3, "{fine} vs {coarse}");
}

/// A 10 × 10 m ground of 100 patches under a 1 m² lamp 40 m up, with an
/// opaque 3 × 3 m slab 1 m over one corner of it.
fn ground_under_far_lamp() -> Scene {
    let p = DVec3::new;
    painted(
        &[
            (
                [
                    p(0., 0., 0.),
                    p(0., 0., 10.),
                    p(10., 0., 10.),
                    p(10., 0., 0.),
                ],
                10,
                false,
            ),
            (
                [
                    p(4., 40., 4.),
                    p(5., 40., 4.),
                    p(5., 40., 5.),
                    p(4., 40., 5.),
                ],
                1,
                true,
            ),
            (
                [
                    p(-0.5, 1., -0.5),
                    p(-0.5, 1., 3.),
                    p(3., 1., 3.),
                    p(3., 1., -0.5),
                ],
                1,
                false,
            ),
        ],
        0.5,
        0.0,
    )
}

/// The emitters the point gather may confirm with a few rays: those from
/// which no link carrying light reaches any part of a patch. Checked
/// against the solution's own gather: no element link brings a dark
/// emitter's light to the patch, and no cluster link either. With
/// clusters, ground patches far from the lamp get its light through
/// cluster links only.
#[test]
fn emitters_hidden_from_whole_patches_are_marked_dark() {
    let scene = ground_under_far_lamp();
    let lamp = scene.patches.iter().position(|p| p.is_emitter()).unwrap() as u32;
    for clustering in [Clustering::Off, Clustering::On] {
        let s = solve(&scene, clustering, Accuracy::preview());
        let dark = dark_emitters(&scene, &s, &[lamp]);
        let by_links = s.irradiance_from(|p| p == lamp);
        let mut from_links = vec![false; scene.patches.len()];
        for id in s.hierarchy.leaves() {
            let e = s.hierarchy.get(id);
            from_links[e.patch as usize] |= by_links[id.index()].x > 0.0;
        }
        let from_clusters = |p: usize| s.cluster_direct.get(p).is_some_and(|d| d.x > 0.0);
        let (mut n_dark, mut clusters_only) = (0, 0);
        for p in 0..scene.patches.len() {
            if dark[p] == 1 {
                n_dark += 1;
                assert!(
                    !from_links[p] && !from_clusters(p),
                    "{clustering:?}: patch {p}"
                );
            } else if !from_links[p] && from_clusters(p) {
                clusters_only += 1;
            }
        }
        eprintln!(
            "{clustering:?}: {n_dark} dark patches, {clusters_only} lit through clusters only"
        );
        // Without clusters: the lamp itself and the ground under the slab
        // (9 patches). With them, the cluster links that light the ground
        // also cover the patches under the slab (a cluster shares its
        // light among its members by direction): only the lamp is dark.
        if clustering == Clustering::On {
            assert!(
                n_dark >= 1 && clusters_only > 0,
                "{n_dark}, {clusters_only}"
            );
        } else {
            assert!(n_dark >= 10 && clusters_only == 0, "{n_dark}");
        }
    }
}
