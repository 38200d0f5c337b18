//! The scale-up family (`tools/scenegen/scale.rs`): triangle counts near
//! their targets, the bundled 10⁴ member valid for the project's loader
//! (closed shells facing the rooms, furniture inside its room without
//! overlaps, downward-facing emitters, a camera in a lit room), and
//! on-demand members written byte for byte the same on every run.

use std::collections::BTreeMap;

use glam::DVec3;
use nusselt::load::{LoadOptions, load_scene};
use nusselt::visibility::TriangleBvh;

use crate::fixtures::scenegen::{readme::triangle_count, scale, write_scale};
use crate::fixtures::{
    Loaded, Tri, assert_closed_oriented, bundled_scene, radiance, read_gltf, sphere_directions,
};

const FILE: &str = "scale/office-10k.gltf";

fn is_shell(node: &str) -> bool {
    node.starts_with("room_") || node.starts_with("door_")
}

/// Piece name and room (i, j) of a furniture node `piece_i_j_k`.
fn furniture_node(node: &str) -> (&str, usize, usize) {
    let mut parts = node.rsplitn(4, '_');
    let _k = parts.next();
    let j = parts.next().and_then(|j| j.parse().ok());
    let i = parts.next().and_then(|i| i.parse().ok());
    let piece = parts.next();
    match (piece, i, j) {
        (Some(p), Some(i), Some(j)) => (p, i, j),
        _ => panic!("{node}: not a furniture node name"),
    }
}

#[test]
fn triangle_counts_land_within_15_percent_of_their_targets() {
    let mut last_rooms = 0;
    let mut last_detail = 0.0;
    for target in [10_000, 100_000, 1_000_000] {
        let plan = scale::Plan::for_target(target);
        let n = triangle_count(&scale::build(&plan));
        let ratio = n as f64 / target as f64;
        assert!(
            (0.85..=1.15).contains(&ratio),
            "target {target}: {n} triangles ({plan:?})"
        );
        assert!(
            plan.rooms() > last_rooms && plan.detail > last_detail,
            "{plan:?}"
        );
        let lit = plan.lit_rooms();
        assert!(lit >= 1 && lit < plan.rooms(), "{plan:?}: {lit} lit rooms");
        (last_rooms, last_detail) = (plan.rooms(), plan.detail);
    }
}

#[test]
fn bundled_office_loads_without_dropping_anything() {
    let scene = bundled_scene(FILE);
    let generated = triangle_count(&scale::scene(10_000));
    assert_eq!(scene.stats.input_triangles, generated);
    assert_eq!(scene.stats.degenerate_dropped, 0);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert!(
        scene.stats.merged_quads > generated / 5,
        "{:?}",
        scene.stats
    );
    let emitting: Vec<_> = scene
        .patches
        .iter()
        .filter(|p| p.emission.max_element() > 0.0)
        .collect();
    assert!(!emitting.is_empty());
    for p in emitting {
        assert!(
            p.normal.dot(DVec3::NEG_Y) > 0.999_999,
            "emitter faces {}",
            p.normal
        );
    }
    assert_eq!(scene.cameras.len(), 1);
    let bvh = TriangleBvh::of_scene(&scene);
    assert_eq!(bvh.len(), generated);
    // The camera's view ray meets the scene.
    let cam = &scene.cameras[0];
    assert!(bvh.closest_hit(cam.eye, cam.forward, 100.0).is_some());
}

#[test]
fn office_shells_are_closed_and_only_ceiling_panels_emit() {
    let Loaded { doc, tris, .. } = read_gltf(FILE);
    let shell: Vec<&Tri> = tris.iter().filter(|t| is_shell(&t.node)).collect();
    for t in &shell {
        assert!(
            t.normal().abs().max_element() > 1.0 - 1e-9,
            "{}: shell face not axis-aligned",
            t.node
        );
    }
    assert_closed_oriented(FILE, &shell);
    let mut lit_rooms = 0;
    for t in &tris {
        let emits = radiance(&doc, t.material).max_element() > 0.0;
        assert_eq!(emits, t.node.ends_with("_light"), "{}", t.node);
        if emits {
            assert!(t.normal().dot(DVec3::NEG_Y) > 0.999_999, "{}", t.node);
            assert!(t.p.iter().all(|p| (p.y - 2.6).abs() < 1e-6), "{}", t.node);
        }
    }
    for node in doc.nodes() {
        if node.name().is_some_and(|n| n.ends_with("_light")) {
            lit_rooms += 1;
        }
    }
    let plan = scale::Plan::for_target(10_000);
    assert_eq!(lit_rooms, plan.lit_rooms());
}

/// A furniture piece's name and world bounds.
type Bounds = (String, DVec3, DVec3);

#[test]
fn office_furniture_stays_in_its_room_without_overlaps() {
    let Loaded { tris, .. } = read_gltf(FILE);
    // World bounds of every furniture node, by room.
    let mut bounds: BTreeMap<(usize, usize), Vec<Bounds>> = BTreeMap::new();
    let mut per_node: BTreeMap<&str, (DVec3, DVec3)> = BTreeMap::new();
    for t in tris.iter().filter(|t| !is_shell(&t.node)) {
        let b = per_node
            .entry(&t.node)
            .or_insert((DVec3::INFINITY, DVec3::NEG_INFINITY));
        for p in t.p {
            *b = (b.0.min(p), b.1.max(p));
        }
    }
    for (node, (lo, hi)) in per_node {
        let (piece, i, j) = furniture_node(node);
        let (min, max) = scale::room_box(i, j);
        // Clear of the walls by 4 cm; on the floor, under the ceiling.
        let inner = DVec3::new(0.04, 0.0, 0.04);
        let eps = DVec3::splat(1e-5);
        assert!(
            lo.cmpge(min + inner - eps).all() && hi.cmple(max - inner + eps).all(),
            "{node} ({lo}..{hi}) leaves room ({i}, {j}) ({min}..{max})"
        );
        assert!(lo.y.abs() < 1e-5 || piece != "table", "{node} floats");
        bounds
            .entry((i, j))
            .or_default()
            .push((piece.to_owned(), lo, hi));
    }
    assert_eq!(bounds.len(), scale::Plan::for_target(10_000).rooms());
    for (room, pieces) in &bounds {
        assert!(
            pieces.len() >= 6,
            "room {room:?} has {} pieces",
            pieces.len()
        );
        for (a, (pa, la, ha)) in pieces.iter().enumerate() {
            for (pb, lb, hb) in &pieces[a + 1..] {
                let overlap = (ha.min(*hb) - la.max(*lb)).min_element();
                let mut pair = [pa.as_str(), pb.as_str()];
                pair.sort_unstable();
                let nested = pair == ["books", "bookshelf"];
                assert!(
                    overlap < 1e-6 || nested,
                    "room {room:?}: {pa} and {pb} overlap by {overlap} m"
                );
            }
        }
    }
}

#[test]
fn office_rays_from_open_space_meet_front_faces_and_the_camera_sees_a_lit_room() {
    let scene = bundled_scene(FILE);
    let bvh = TriangleBvh::of_scene(&scene);
    // The node a ray first meets, and whether it meets its front.
    let first = |origin: DVec3, dir: DVec3| {
        let hit = bvh
            .closest_hit(origin, dir, 1e3)
            .unwrap_or_else(|| panic!("ray from {origin} along {dir} escapes"));
        let t = &scene.triangles[hit.triangle as usize];
        let [a, b, c] = t.positions;
        let name = scene.surfaces[t.surface as usize].name.as_str();
        (name, (b - a).cross(c - a).dot(dir) < 0.0)
    };
    let plan = scale::Plan::for_target(10_000);
    let cam = &scene.cameras[0];
    let mut points = vec![cam.eye];
    for j in 0..plan.rows {
        for i in 0..plan.columns {
            let (min, max) = scale::room_box(i, j);
            // Above the furniture, below the ceiling, in the middle; and
            // in the middle of the doors.
            let mid = (min + max) / 2.0;
            points.push(DVec3::new(mid.x, 2.2, mid.z));
            if i + 1 < plan.columns {
                points.push(DVec3::new(max.x + 0.05, 1.0, mid.z));
            }
            if j + 1 < plan.rows {
                points.push(DVec3::new(mid.x, 1.0, max.z + 0.05));
            }
        }
    }
    for p in points {
        for dir in sphere_directions(4000) {
            let (name, front) = first(p, dir);
            assert!(front, "ray from {p} along {dir} meets the back of {name}");
        }
    }
    // The camera stands in lit room (0, 0) and sees mostly that room, and
    // room (1, 0) through the door.
    let (min, max) = scale::room_box(0, 0);
    assert!(cam.eye.cmpgt(min).all() && cam.eye.cmplt(max).all());
    assert!(scene.surfaces.iter().any(|s| s.name == "room_0_0_light"));
    let aspect = cam.aspect_ratio.expect("an aspect ratio");
    let right = cam.forward.cross(cam.up).normalize();
    let h = (cam.yfov / 2.0).tan();
    let (mut in_0, mut in_1, mut total) = (0, 0, 0);
    for j in 0..36 {
        for i in 0..64 {
            let (u, v) = ((i as f64 + 0.5) / 64.0, (j as f64 + 0.5) / 36.0);
            let dir =
                (cam.forward + (2.0 * u - 1.0) * h * aspect * right + (1.0 - 2.0 * v) * h * cam.up)
                    .normalize();
            let (name, front) = first(cam.eye, dir);
            assert!(front, "the camera sees the back of {name}");
            total += 1;
            let room = if is_shell(name) {
                name.strip_prefix("room_").map(|r| &r[..3])
            } else {
                let (_, i, j) = furniture_node(name);
                Some(if (i, j) == (0, 0) { "0_0" } else { "other" })
            };
            match room {
                Some("0_0") => in_0 += 1,
                Some("1_0") => in_1 += 1,
                _ => {}
            }
        }
    }
    assert!(
        in_0 * 2 > total,
        "room (0, 0) fills {in_0} of {total} pixels"
    );
    assert!(
        in_1 * 50 > total,
        "room (1, 0) fills {in_1} of {total} pixels"
    );
}

#[test]
fn on_demand_scale_scenes_are_byte_identical_across_runs() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (first, n) = write_scale(a.path(), 100_000).expect("writing succeeds");
    let (second, m) = write_scale(b.path(), 100_000).expect("writing succeeds");
    assert_eq!(n, m);
    let names: Vec<_> = first.iter().map(|p| p.file_name().unwrap()).collect();
    assert_eq!(names, ["office-100k.gltf", "office-100k.bin"]);
    for (p, q) in first.iter().zip(&second) {
        let (x, y) = (std::fs::read(p).unwrap(), std::fs::read(q).unwrap());
        assert!(x == y, "{}: generation is not deterministic", p.display());
    }
    // The written scene loads, with every triangle kept.
    let scene = load_scene(&first[0], &LoadOptions::default()).expect("the 10⁵ office loads");
    assert_eq!(scene.stats.input_triangles, n);
    assert_eq!(scene.stats.degenerate_dropped, 0);
}
