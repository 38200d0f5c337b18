//! The bundled scenes in `scenes/`: up to date with their generator, and
//! well formed as the contract reads them.
//!
//! Files are read back with the `gltf` crate alone (no project loader), so
//! these tests check the files, not the loader. Geometry checks:
//! - names, counts, materials (ρ < 1, metallic 0, roughness 1, single-sided)
//!   and one perspective camera per scene;
//! - orientation: each surface of the simple scenes faces its expected
//!   direction; in the closed scenes every ray from a point of open space
//!   first meets a front face and never escapes;
//! - closure: the Goral box and the interior's room shells are closed,
//!   consistently oriented edge manifolds (every directed edge meets its
//!   reverse exactly once), which also rules out T-junctions there.

use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::Path;

use glam::DVec3;

use crate::fixtures::{
    Loaded, Tri, assert_closed_oriented, radiance, read_gltf, scene_path, scenegen,
    sphere_directions,
};

/// Möller–Trumbore; the distance along `dir` (unit) to the triangle, if hit.
fn ray_triangle(origin: DVec3, dir: DVec3, t: &Tri) -> Option<f64> {
    let (e1, e2) = (t.p[1] - t.p[0], t.p[2] - t.p[0]);
    let h = dir.cross(e2);
    let det = e1.dot(h);
    if det.abs() < 1e-14 {
        return None;
    }
    let s = origin - t.p[0];
    let u = s.dot(h) / det;
    let q = s.cross(e1);
    let v = dir.dot(q) / det;
    if !(0.0..=1.0).contains(&u) || v < 0.0 || u + v > 1.0 {
        return None;
    }
    let dist = e2.dot(q) / det;
    (dist > 1e-9).then_some(dist)
}

/// The nearest triangle along the ray, and whether the ray meets it from the
/// front. A back face only counts as first when it is nearer than every
/// front face by more than a rounding margin (rays through shared edges).
fn first_hit(tris: &[Tri], origin: DVec3, dir: DVec3) -> Option<(usize, bool)> {
    let mut front: Option<(usize, f64)> = None;
    let mut back: Option<(usize, f64)> = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(d) = ray_triangle(origin, dir, t) {
            let slot = if dir.dot(t.normal()) < 0.0 {
                &mut front
            } else {
                &mut back
            };
            if slot.is_none_or(|(_, best)| d < best) {
                *slot = Some((i, d));
            }
        }
    }
    match (front, back) {
        (Some((f, df)), Some((b, db))) => Some(if db < df - 1e-7 {
            (b, false)
        } else {
            (f, true)
        }),
        (Some((f, _)), None) => Some((f, true)),
        (None, Some((b, _))) => Some((b, false)),
        (None, None) => None,
    }
}

/// Shoots rays in all directions from `origin`; every ray that hits must hit
/// a front face first, and when `closed` every ray must hit. Returns the
/// number of hits per node.
fn check_rays_from(
    file: &str,
    tris: &[Tri],
    origin: DVec3,
    closed: bool,
) -> HashMap<String, usize> {
    let mut hits: HashMap<String, usize> = HashMap::new();
    for dir in sphere_directions(1500) {
        match first_hit(tris, origin, dir) {
            Some((i, true)) => *hits.entry(tris[i].node.clone()).or_default() += 1,
            Some((i, false)) => {
                panic!(
                    "{file}: ray from {origin} along {dir} meets the back of node {}",
                    tris[i].node
                )
            }
            None => assert!(!closed, "{file}: ray from {origin} along {dir} escapes"),
        }
    }
    hits
}

fn node_tris<'a>(tris: &'a [Tri], name: &str) -> Vec<&'a Tri> {
    let v: Vec<&Tri> = tris.iter().filter(|t| t.node == name).collect();
    assert!(!v.is_empty(), "no triangles in node {name}");
    v
}

fn assert_facing(file: &str, tris: &[Tri], name: &str, expected: DVec3) {
    for t in node_tris(tris, name) {
        let n = t.normal();
        assert!(
            n.dot(expected) > 0.99,
            "{file}: node {name} faces {n}, expected {expected}"
        );
    }
}

const FILES: [&str; 8] = [
    "cornell-box.gltf",
    "goral-box.gltf",
    "penumbra.gltf",
    "three-rooms.gltf",
    "two-squares.gltf",
    "spot-room.gltf",
    "courtyard.gltf",
    "scale/office-10k.gltf",
];

#[test]
fn bundled_scenes_are_up_to_date() {
    let first = scenegen::render_all().expect("generation succeeds");
    // A second run, through the example's own writer, gives the same bytes.
    let tmp = tempfile::tempdir().unwrap();
    let written = scenegen::write_all(tmp.path()).expect("writing succeeds");
    assert_eq!(written.len(), first.len());
    for (name, bytes) in &first {
        let again = std::fs::read(tmp.path().join(name)).unwrap();
        assert!(again == *bytes, "{name}: generation is not deterministic");
    }
    for (name, bytes) in &first {
        let path = scene_path(name);
        let on_disk = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            on_disk == *bytes,
            "{name} differs from the generator's output: run \
             `cargo run --release --example gen-scenes -- scenes/`"
        );
    }
    let generated: Vec<&str> = first.iter().map(|(n, _)| n.as_str()).collect();
    for f in FILES {
        assert!(generated.contains(&f), "{f} is not generated");
    }
}

#[test]
fn every_scene_is_well_formed() {
    for file in FILES {
        let Loaded { doc, tris, views } = read_gltf(file);
        assert_eq!(views.len(), 1, "{file}: one camera node");
        for node in doc.nodes() {
            assert!(
                node.name().is_some_and(|n| !n.is_empty()),
                "{file}: unnamed node"
            );
        }
        let uses_strength = doc.materials().any(|m| m.emissive_strength().is_some());
        let listed = doc
            .extensions_used()
            .any(|e| e == "KHR_materials_emissive_strength");
        assert_eq!(uses_strength, listed, "{file}: extensionsUsed");
        for m in doc.materials() {
            let name = m.name().unwrap_or("?");
            let pbr = m.pbr_metallic_roughness();
            assert!(
                pbr.base_color_factor()[..3]
                    .iter()
                    .all(|&c| (0.0..1.0).contains(&c)),
                "{file}: {name} ρ"
            );
            assert_eq!(pbr.metallic_factor(), 0.0, "{file}: {name}");
            assert_eq!(pbr.roughness_factor(), 1.0, "{file}: {name}");
            assert!(!m.double_sided(), "{file}: {name} is double-sided");
            assert!(
                m.emissive_factor()
                    .iter()
                    .all(|&c| (0.0..=1.0).contains(&c)),
                "{file}: {name}"
            );
        }
        let lights = doc.lights().map_or(0, |l| l.count());
        let lists_lights = doc.extensions_used().any(|e| e == "KHR_lights_punctual");
        assert_eq!(lights > 0, lists_lights, "{file}: extensionsUsed");
        assert!(
            lights > 0
                || tris
                    .iter()
                    .any(|t| radiance(&doc, t.material).max_element() > 0.0),
            "{file}: no light"
        );
        for t in &tris {
            assert!(t.area() > 1e-8, "{file}: degenerate triangle in {}", t.node);
        }
        // Buffers: the Goral box embeds its buffer, the others use <stem>.bin.
        let stem = Path::new(file)
            .file_stem()
            .and_then(|s| s.to_str())
            .expect("a file stem");
        for b in doc.buffers() {
            let gltf::buffer::Source::Uri(uri) = b.source() else {
                panic!("{file}: a .gltf buffer needs a uri");
            };
            if stem == "goral-box" {
                assert!(
                    uri.starts_with("data:application/octet-stream;base64,"),
                    "{file}"
                );
            } else {
                assert_eq!(uri, format!("{stem}.bin"), "{file}");
            }
        }
    }
}

#[test]
fn cornell_box_matches_the_published_data() {
    let file = "cornell-box.gltf";
    let Loaded { doc, tris, views } = read_gltf(file);
    assert_eq!(tris.len(), 38);
    let per_node = |n: &str| tris.iter().filter(|t| t.node == n).count();
    for (name, count) in [
        ("floor", 2),
        ("ceiling", 8),
        ("light", 2),
        ("back_wall", 2),
        ("left_wall", 2),
        ("right_wall", 2),
        ("short_block", 10),
        ("tall_block", 10),
    ] {
        assert_eq!(per_node(name), count, "{name}");
    }
    assert_facing(file, &tris, "floor", DVec3::Y);
    assert_facing(file, &tris, "ceiling", DVec3::NEG_Y);
    assert_facing(file, &tris, "light", DVec3::NEG_Y);
    assert_facing(file, &tris, "back_wall", DVec3::NEG_Z);
    assert_facing(file, &tris, "right_wall", DVec3::X);
    // The published red wall is slightly skewed: allow its small tilt.
    assert_facing(file, &tris, "left_wall", DVec3::NEG_X);
    for block in ["short_block", "tall_block"] {
        let ts = node_tris(&tris, block);
        let centre = ts.iter().map(|t| t.centroid()).sum::<DVec3>() / ts.len() as f64;
        for t in ts {
            assert!(
                t.normal().dot(t.centroid() - centre) > 0.0,
                "{block} faces inwards"
            );
        }
    }
    // Published corners, in metres.
    let has_vertex = |name: &str, p: DVec3| {
        tris.iter()
            .any(|t| t.node == name && t.p.iter().any(|q| q.distance(p) < 1e-6))
    };
    assert!(has_vertex("floor", DVec3::new(0.5528, 0.0, 0.0)));
    assert!(has_vertex("left_wall", DVec3::new(0.5496, 0.0, 0.5592)));
    assert!(has_vertex("tall_block", DVec3::new(0.423, 0.33, 0.247)));
    assert!(has_vertex("light", DVec3::new(0.343, 0.5488, 0.227)));
    // Ceiling and light tile the published ceiling rectangle.
    let area = |n: &str| node_tris(&tris, n).iter().map(|t| t.area()).sum::<f64>();
    assert!((area("ceiling") + area("light") - 0.556 * 0.5592).abs() < 1e-6);
    assert!((area("light") - 0.13 * 0.105).abs() < 1e-7);
    // The light: L_e = (17, 12, 4).
    let light = node_tris(&tris, "light")[0].material;
    assert!(radiance(&doc, light).distance(DVec3::new(17.0, 12.0, 4.0)) < 1e-4);
    // Only the light emits.
    for t in &tris {
        let emits = radiance(&doc, t.material).max_element() > 0.0;
        assert_eq!(emits, t.node == "light", "{}", t.node);
    }
    // The published camera.
    let v = views[0];
    assert!(v.eye.distance(DVec3::new(0.278, 0.273, -0.8)) < 1e-6);
    assert!(v.forward.distance(DVec3::Z) < 1e-6);
    assert!(v.up.distance(DVec3::Y) < 1e-6);
    assert!((v.yfov - 2.0 * (0.0125f64 / 0.035).atan()).abs() < 1e-6);
    assert_eq!(v.aspect, 1.0);
    // Red wall on the left of the image, green on the right.
    let hit = |u: f64| {
        first_hit(&tris, v.eye, v.ray(u, 0.5)).map(|(i, front)| (tris[i].node.clone(), front))
    };
    assert_eq!(hit(0.1), Some(("left_wall".to_owned(), true)));
    assert_eq!(hit(0.9), Some(("right_wall".to_owned(), true)));
    let left = doc
        .materials()
        .nth(node_tris(&tris, "left_wall")[0].material)
        .unwrap();
    let [r, g, b, _] = left.pbr_metallic_roughness().base_color_factor();
    assert!(r > 5.0 * g && r > 5.0 * b, "the left wall is red");
    // Orientation seen from inside the box and from the camera (the open
    // front lets rays escape).
    check_rays_from(file, &tris, DVec3::new(0.278, 0.45, 0.1), false);
    check_rays_from(file, &tris, v.eye, false);
}

#[test]
fn goral_box_is_a_closed_unit_cube() {
    let file = "goral-box.gltf";
    let Loaded { doc, tris, views } = read_gltf(file);
    assert_eq!(tris.len(), 12);
    let centre = DVec3::splat(0.5);
    for name in [
        "floor",
        "ceiling",
        "back_wall",
        "front_wall",
        "left_wall",
        "right_wall",
    ] {
        let ts = node_tris(&tris, name);
        assert_eq!(ts.len(), 2, "{name} is one quad");
        let area: f64 = ts.iter().map(|t| t.area()).sum();
        assert!((area - 1.0).abs() < 1e-9, "{name}");
        for t in ts {
            let to_centre = (centre - t.centroid()).normalize();
            assert!(
                t.normal().dot(to_centre) > 0.7,
                "{name} faces away from the centre"
            );
        }
    }
    assert_closed_oriented(file, &tris.iter().collect::<Vec<_>>());
    // The whole ceiling emits E = 1.
    let ceiling = node_tris(&tris, "ceiling")[0].material;
    assert!((radiance(&doc, ceiling) * PI).distance(DVec3::ONE) < 1e-6);
    assert!(
        tris.iter()
            .filter(|t| t.node != "ceiling")
            .all(|t| radiance(&doc, t.material) == DVec3::ZERO)
    );
    let v = views[0];
    assert!(
        (0.0..1.0).contains(&v.eye.x)
            && (0.0..1.0).contains(&v.eye.y)
            && (0.5..1.0).contains(&v.eye.z)
    );
    // Looking at the back wall, with parts of the side walls in view.
    let hit = |u: f64, w: f64| {
        tris[first_hit(&tris, v.eye, v.ray(u, w)).unwrap().0]
            .node
            .clone()
    };
    assert_eq!(hit(0.5, 0.5), "back_wall");
    assert_eq!(hit(0.02, 0.5), "left_wall");
    assert_eq!(hit(0.98, 0.5), "right_wall");
    check_rays_from(file, &tris, centre, true);
    check_rays_from(file, &tris, v.eye, true);
}

#[test]
fn two_squares_face_each_other() {
    let file = "two-squares.gltf";
    let Loaded { doc, tris, views } = read_gltf(file);
    assert_eq!(tris.len(), 4);
    assert_facing(file, &tris, "emitter", DVec3::Y);
    assert_facing(file, &tris, "receiver", DVec3::NEG_Y);
    for (name, y) in [("emitter", 0.0), ("receiver", 1.0)] {
        let ts = node_tris(&tris, name);
        assert!((ts.iter().map(|t| t.area()).sum::<f64>() - 1.0).abs() < 1e-9);
        assert!(
            ts.iter()
                .flat_map(|t| t.p)
                .all(|p| p.y == y && (0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.z))
        );
    }
    let emitter = node_tris(&tris, "emitter")[0].material;
    assert!((radiance(&doc, emitter) * PI).distance(DVec3::ONE) < 1e-6);
    let black = doc
        .materials()
        .nth(emitter)
        .unwrap()
        .pbr_metallic_roughness()
        .base_color_factor();
    assert_eq!(&black[..3], &[0.0, 0.0, 0.0]);
    // The camera sees both fronts.
    let v = views[0];
    let hit = |w: f64| {
        first_hit(&tris, v.eye, v.ray(0.5, w)).map(|(i, front)| (tris[i].node.clone(), front))
    };
    assert_eq!(hit(0.05), Some(("receiver".to_owned(), true)));
    assert_eq!(hit(0.95), Some(("emitter".to_owned(), true)));
}

#[test]
fn penumbra_squares_are_stacked_as_documented() {
    let file = "penumbra.gltf";
    let Loaded { doc, tris, .. } = read_gltf(file);
    assert_eq!(tris.len(), 6);
    assert_facing(file, &tris, "floor", DVec3::Y);
    assert_facing(file, &tris, "occluder", DVec3::Y);
    assert_facing(file, &tris, "emitter", DVec3::NEG_Y);
    // (node, height, x range, z range)
    for (name, y, x, z) in [
        ("floor", 0.0, [-2.5, 2.5], [-2.5, 2.5]),
        ("occluder", 1.0, [-0.5, 0.5], [-0.5, 0.5]),
        ("emitter", 2.0, [-0.2, 0.8], [-0.35, 0.65]),
    ] {
        let ts = node_tris(&tris, name);
        let area = (x[1] - x[0]) * (z[1] - z[0]);
        assert!((ts.iter().map(|t| t.area()).sum::<f64>() - area).abs() < 1e-6);
        for p in ts.iter().flat_map(|t| t.p) {
            assert!((p.y - y).abs() < 1e-6, "{name}");
            assert!((x[0] - 1e-6..=x[1] + 1e-6).contains(&p.x), "{name}");
            assert!((z[0] - 1e-6..=z[1] + 1e-6).contains(&p.z), "{name}");
        }
    }
    // Only the emitter emits, and it is black.
    for t in &tris {
        let emits = radiance(&doc, t.material).max_element() > 0.0;
        assert_eq!(emits, t.node == "emitter", "{}", t.node);
    }
    let emitter = node_tris(&tris, "emitter")[0].material;
    let base = doc
        .materials()
        .nth(emitter)
        .unwrap()
        .pbr_metallic_roughness()
        .base_color_factor();
    assert_eq!(&base[..3], &[0.0, 0.0, 0.0]);
}

#[test]
fn interior_is_closed_furnished_and_lit_indirectly() {
    let file = "three-rooms.gltf";
    let Loaded { doc, tris, views } = read_gltf(file);
    assert!(
        (3000..=8000).contains(&tris.len()),
        "{} triangles",
        tris.len()
    );
    // Room shells: axis-aligned, closed and consistently oriented.
    let is_shell = |n: &str| n.starts_with("room_") || n.starts_with("doorway_") || n == "light";
    let shell: Vec<&Tri> = tris.iter().filter(|t| is_shell(&t.node)).collect();
    for t in &shell {
        let n = t.normal();
        assert!(
            n.abs().max_element() > 1.0 - 1e-9,
            "{}: shell face not axis-aligned",
            t.node
        );
    }
    assert_closed_oriented(file, &shell);
    for t in node_tris(&tris, "light") {
        assert!(t.normal().dot(DVec3::NEG_Y) > 0.999);
    }
    for name in [
        "table",
        "ball",
        "chair_1",
        "chair_2",
        "bookshelf",
        "books",
        "column_a",
        "column_b",
        "sphere_b",
        "sofa",
    ] {
        node_tris(&tris, name);
    }
    // Only the light emits.
    for t in &tris {
        assert_eq!(
            radiance(&doc, t.material).max_element() > 0.0,
            t.node == "light",
            "{}",
            t.node
        );
    }
    // From points of open space in each room, in the doorways and at the
    // camera, every ray meets a front face and none escapes.
    let v = views[0];
    let points = [
        DVec3::new(1.0, 1.5, 3.2),
        DVec3::new(6.0, 1.5, 1.0),
        DVec3::new(6.5, 1.5, 5.0),
        DVec3::new(5.05, 1.0, 1.0),
        DVec3::new(8.1, 1.0, 4.05),
        v.eye,
    ];
    for p in points {
        check_rays_from(file, &tris, p, true);
    }
    // No straight path from the light reaches room C: rays from points of
    // the light never land in room C's shell or furniture.
    let room_c = [
        "room_c_floor",
        "room_c_ceiling",
        "room_c_walls",
        "sofa",
        "stool",
        "sphere_c",
        "crate",
    ];
    for lp in [
        DVec3::new(2.0, 2.599, 2.0),
        DVec3::new(3.0, 2.599, 2.0),
        DVec3::new(2.5, 2.599, 2.5),
    ] {
        let hits = check_rays_from(file, &tris, lp, true);
        for n in room_c {
            assert!(!hits.contains_key(n), "light reaches {n} directly");
        }
    }
    // The camera shows the lit room and, through door AB, room B.
    let room_b = [
        "room_b_floor",
        "room_b_ceiling",
        "room_b_walls",
        "boxes",
        "cabinet",
        "sphere_b",
        "column_b",
    ];
    let (mut in_a, mut in_b, mut total) = (0, 0, 0);
    for j in 0..36 {
        for i in 0..64 {
            let dir = v.ray((i as f64 + 0.5) / 64.0, (j as f64 + 0.5) / 36.0);
            let (k, front) = first_hit(&tris, v.eye, dir).expect("the camera sees something");
            assert!(front);
            let node = tris[k].node.as_str();
            total += 1;
            if room_b.contains(&node) {
                in_b += 1;
            } else if node.starts_with("room_a") || node == "table" || node.starts_with("chair") {
                in_a += 1;
            }
        }
    }
    assert!(
        in_b * 50 > total,
        "room B fills only {in_b} of {total} pixels"
    );
    assert!(
        in_a * 4 > total,
        "room A fills only {in_a} of {total} pixels"
    );
}
