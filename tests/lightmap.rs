//! Lightmaps: the atlas read through its texture coordinates agrees with
//! the per-vertex solution, no texel a triangle's bilinear footprint reads
//! is empty, the input's `TEXCOORD_1` is used when present, and the bake
//! carries the atlas.

use glam::{Vec2, Vec3};
use nusselt::lightmap::{Lightmap, UvSource};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::mesh::OutputMesh;
use nusselt::scene::Scene;
use nusselt::{Progress, SolveRun};
use rand::{Rng, SeedableRng};
use serde_json::json;

use crate::fixtures::preview_settings;
use crate::loader::Gltf;

fn solve(scene: &Scene, lightmap: Option<u32>) -> SolveRun {
    nusselt::solve(scene, &preview_settings(lightmap), &Progress::hidden()).unwrap()
}

/// Relative differences between the atlas (bilinear, through the
/// interpolated texture coordinates) and the mesh's own linear
/// interpolation, at `n` random points uniform over the mesh's area (a
/// triangle picked by area: the many small triangles along a contact
/// line, narrower than a texel, count for their area); sorted.
fn differences(mesh: &OutputMesh, lightmap: &Lightmap, n: usize) -> Vec<f32> {
    let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
    let mut total = 0.0f64;
    let cumulative: Vec<f64> = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
            total += 0.5 * (b - a).cross(c - a).length();
            total
        })
        .collect();
    let scale = mesh
        .radiosity
        .iter()
        .map(|b| b.max_element())
        .fold(0.0f32, f32::max);
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let at = rng.random::<f64>() * total;
        let k = cumulative.partition_point(|&c| c <= at);
        let tri = mesh.triangles[k.min(mesh.triangles.len() - 1)];
        let (mut a, mut b): (f32, f32) = (rng.random(), rng.random());
        if a + b > 1.0 {
            (a, b) = (1.0 - a, 1.0 - b);
        }
        let w = [1.0 - a - b, a, b];
        let mix3 = |v: &[Vec3]| (0..3).map(|k| v[tri[k] as usize] * w[k]).sum::<Vec3>();
        let uv: Vec2 = (0..3).map(|k| lightmap.uv[tri[k] as usize] * w[k]).sum();
        let expected = mix3(&mesh.radiosity);
        let got = Lightmap::sample(&lightmap.radiosity, uv);
        // Relative to the point's own value, with a floor of 1 % of the
        // brightest vertex for dark points.
        let floor = expected.max_element().max(0.01 * scale);
        out.push((got - expected).abs().max_element() / floor);
    }
    out.sort_by(f32::total_cmp);
    out
}

/// Every texel that bilinear filtering reads at points of any triangle
/// (corners, edge points, inside) holds a value.
fn assert_footprints_written(mesh: &OutputMesh, lightmap: &Lightmap) {
    let side = lightmap.radiosity.width as usize;
    let steps = 6;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (a, b) = (i as f32 / steps as f32, j as f32 / steps as f32);
                let w = [1.0 - a - b, a, b];
                let uv: Vec2 = (0..3).map(|k| lightmap.uv[tri[k] as usize] * w[k]).sum();
                let (x, y) = (uv.x * side as f32 - 0.5, uv.y * side as f32 - 0.5);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let tx = (x.floor() as i64 + dx).clamp(0, side as i64 - 1) as usize;
                    let ty = (y.floor() as i64 + dy).clamp(0, side as i64 - 1) as usize;
                    assert!(
                        lightmap.written[ty * side + tx],
                        "triangle {t} reads the empty texel ({tx}, {ty}) at {uv}"
                    );
                }
            }
        }
    }
}

#[test]
fn the_cornell_atlas_agrees_with_the_mesh_and_leaves_no_hole() {
    let scene = crate::fixtures::cornell();
    let run = solve(&scene, None);
    for resolution in [256, 1024] {
        let lightmap = Lightmap::build(&scene, &run.mesh, resolution).unwrap();
        assert_eq!(lightmap.stats.uv_source, UvSource::Generated);
        assert!(
            lightmap
                .uv
                .iter()
                .all(|uv| uv.min_element() >= 0.0 && uv.max_element() <= 1.0)
        );
        assert_footprints_written(&run.mesh, &lightmap);
        let d = differences(&run.mesh, &lightmap, 20_000);
        let (median, p95) = (d[d.len() / 2], d[d.len() * 95 / 100]);
        eprintln!(
            "{resolution}²: {} charts, efficiency {:.3}, median {median:.4}, p95 {p95:.4}",
            lightmap.stats.charts, lightmap.stats.efficiency
        );
        // Bilinear filtering of a piecewise-linear field departs from it only
        // within a texel of its kinks (the output mesh's edges).
        // (Measured over the area: 256² median 10⁻⁴, p95 0.0037; 1024²
        // p95 0.0003.)
        let (median_bound, p95_bound) = if resolution == 256 {
            (0.002, 0.02)
        } else {
            (0.001, 0.003)
        };
        assert!(
            median <= median_bound && p95 <= p95_bound,
            "{resolution}²: median {median}, p95 {p95}"
        );
        // Coplanar patches of one wall share a chart: the Cornell box's
        // walls, floor, ceiling, light and block faces are few charts.
        assert!(
            lightmap.stats.charts <= 30,
            "{} charts",
            lightmap.stats.charts
        );
        assert!(
            lightmap.stats.efficiency > 0.3,
            "efficiency {}",
            lightmap.stats.efficiency
        );
    }
}

#[test]
fn a_textured_scene_with_a_mirrored_instance_bakes_its_atlas_too() {
    // Textured tiles, one mirrored, under a tilted lamp: the atlas agrees
    // with the mesh as on the Cornell box, and no footprint reads a hole.
    let mut g = Gltf::default();
    g.light();
    let checker = g.checker();
    let tile = g.quad_mesh(Some("Tile"), Some(checker));
    g.root(json!({"name": "Plain", "mesh": tile, "scale": [3.0, 2.0, 1.0]}));
    g.root(json!({"name": "Mirror", "mesh": tile, "scale": [-3.0, 2.0, 1.0], "translation": [-0.5, 0.0, 0.0]}));
    let lamp = g.emitter();
    let lamp_mesh = g.quad_mesh(Some("Lamp"), Some(lamp));
    g.root(
        json!({"name": "Lamp", "mesh": lamp_mesh, "translation": [-1.0, 0.5, 2.0],
        "rotation": [1.0, 0.0, 0.0, 0.0]}),
    );
    let scene = g.load().unwrap();
    let run = solve(&scene, None);
    let lightmap = Lightmap::build(&scene, &run.mesh, 512).unwrap();
    assert_footprints_written(&run.mesh, &lightmap);
    let d = differences(&run.mesh, &lightmap, 5_000);
    let (median, p95) = (d[d.len() / 2], d[d.len() * 95 / 100]);
    assert!(median <= 0.01 && p95 <= 0.08, "median {median}, p95 {p95}");
}

#[test]
fn the_two_sides_of_a_seam_agree() {
    // One floor made of two nodes side by side under a lamp: the shared
    // edge is a seam between two charts. The vertices there (one position,
    // bit for bit, on each side) read the same light from either chart.
    let mut g = Gltf::default();
    let light = g.emitter();
    let lamp = g.quad_mesh(Some("Lamp"), Some(light));
    let half = std::f64::consts::FRAC_1_SQRT_2;
    g.root(
        json!({"name": "Lamp", "mesh": lamp, "translation": [-0.5, 1.5, 0.5],
        "rotation": [half, 0.0, 0.0, half]}),
    );
    let grey = g.grey();
    let tile = g.quad_mesh(Some("Tile"), Some(grey));
    for (name, x) in [("West", -1.0), ("East", 0.0)] {
        g.root(
            json!({"name": name, "mesh": tile, "translation": [x, 0.0, 0.0],
            "rotation": [-half, 0.0, 0.0, half]}),
        );
    }
    let scene = g.load().unwrap();
    let run = solve(&scene, None);
    let lightmap = Lightmap::build(&scene, &run.mesh, 512).unwrap();
    let mesh = &run.mesh;
    let mut seam: std::collections::HashMap<[u32; 3], Vec<usize>> = Default::default();
    for (v, p) in mesh.positions.iter().enumerate() {
        if p.x == 0.0 && mesh.normals[v].y > 0.99 {
            seam.entry(p.to_array().map(f32::to_bits))
                .or_default()
                .push(v);
        }
    }
    let pairs: Vec<_> = seam.values().filter(|vs| vs.len() == 2).collect();
    assert!(pairs.len() >= 3, "{} seam vertex pairs", pairs.len());
    for vs in pairs {
        let (a, b) = (vs[0], vs[1]);
        assert_ne!(lightmap.uv[a], lightmap.uv[b], "a seam joins two charts");
        let (sa, sb) = (
            Lightmap::sample(&lightmap.radiosity, lightmap.uv[a]),
            Lightmap::sample(&lightmap.radiosity, lightmap.uv[b]),
        );
        let scale = mesh.radiosity[a]
            .max_element()
            .max(mesh.radiosity[b].max_element());
        let vertex_gap = (mesh.radiosity[a] - mesh.radiosity[b]).abs().max_element() / scale;
        let atlas_gap = (sa - sb).abs().max_element() / scale;
        assert!(
            atlas_gap <= vertex_gap + 0.02,
            "at {}: atlas {sa} vs {sb}, vertices {} vs {}",
            mesh.positions[a],
            mesh.radiosity[a],
            mesh.radiosity[b]
        );
    }
}

/// A mesh named `name`: a 2 m square at y = 0 facing +y (or −y when
/// `down`), with `uv1` as TEXCOORD_1 (and `uv0` as TEXCOORD_0) at its
/// corners, which run from (−1, +1) in x, z anticlockwise seen from the
/// front.
fn square(
    g: &mut Gltf,
    name: &str,
    material: usize,
    down: bool,
    uv1: [[f32; 2]; 4],
    uv0: Option<[[f32; 2]; 4]>,
) -> usize {
    let up = [
        [-1.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 0.0, -1.0],
        [-1.0, 0.0, -1.0],
    ];
    let down_corners = [
        [-1.0, 0.0, -1.0],
        [1.0, 0.0, -1.0],
        [1.0, 0.0, 1.0],
        [-1.0, 0.0, 1.0],
    ];
    let pos = g.positions(if down { &down_corners } else { &up });
    let mut attributes = json!({"POSITION": pos, "TEXCOORD_1": g.uvs(&uv1)});
    if let Some(uv0) = uv0 {
        attributes["TEXCOORD_0"] = json!(g.uvs(&uv0));
    }
    let idx = g.indices(&[0, 1, 2, 0, 2, 3]);
    g.mesh(
        Some(name),
        vec![json!({"attributes": attributes, "indices": idx, "material": material})],
    )
}

#[test]
fn the_input_s_texcoord_1_is_used_and_the_bake_carries_the_atlas() {
    let mut g = Gltf::default();
    g.light();
    let grey = g.grey();
    // A 2 m square floor whose TEXCOORD_1 maps it onto the atlas's left half.
    let floor = square(
        &mut g,
        "Floor",
        grey,
        false,
        [[0.05, 0.95], [0.45, 0.95], [0.45, 0.05], [0.05, 0.05]],
        Some([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]),
    );
    g.root(json!({"name": "Floor", "mesh": floor, "translation": [0.0, 45.0, 0.0]}));
    // The light (from `light`) lacks TEXCOORD_1: the input's coordinates
    // are used only when every triangle has them.
    let scene = g.load().unwrap();
    let run = solve(&scene, Some(128));
    let lightmap = run.lightmap.as_ref().unwrap();
    assert_eq!(lightmap.stats.uv_source, UvSource::Generated);

    // Without the light's triangles lacking it: give the light TEXCOORD_1.
    let mut g = Gltf::default();
    let light = g.emitter();
    let lamp = square(
        &mut g,
        "Lamp",
        light,
        true,
        [[0.55, 0.05], [0.95, 0.05], [0.95, 0.45], [0.55, 0.45]],
        None,
    );
    g.root(json!({"name": "Lamp", "mesh": lamp, "translation": [0.0, 1.0, 0.0]}));
    let grey = g.grey();
    let floor = square(
        &mut g,
        "Floor",
        grey,
        false,
        [[0.05, 0.95], [0.45, 0.95], [0.45, 0.55], [0.05, 0.55]],
        None,
    );
    g.root(json!({"name": "Floor", "mesh": floor}));
    let scene = g.load().unwrap();
    let mut run = solve(&scene, Some(128));
    let lightmap = run.lightmap.clone().unwrap();
    assert_eq!(lightmap.stats.uv_source, UvSource::Input);
    // Each floor vertex at (x, 0, z) sits at u = 0.25 + 0.2 x, v = 0.75 + 0.2 z.
    for (v, p) in run.mesh.positions.iter().enumerate() {
        if p.y.abs() < 1e-6 {
            let expected = Vec2::new(0.25 + 0.2 * p.x, 0.75 + 0.2 * p.z);
            assert!(
                (lightmap.uv[v] - expected).abs().max_element() < 1e-5,
                "{} vs {expected}",
                lightmap.uv[v]
            );
        }
    }
    assert_footprints_written(&run.mesh, &lightmap);

    // The bake: TEXCOORD_1 on every primitive, and each baked material's
    // emissive texture is the atlas through it; the files are written.
    let dir = tempfile::tempdir().unwrap();
    nusselt::write_outputs(dir.path(), &mut run).unwrap();
    for f in ["lightmap-B.exr", "lightmap-H.exr", "lightmap.png"] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    let atlas = nusselt::output::exr::read_image(&dir.path().join("lightmap-B.exr")).unwrap();
    assert_eq!(atlas, lightmap.radiosity);
    let (doc, _, images) = gltf::import(dir.path().join("baked.gltf")).unwrap();
    for prim in doc
        .meshes()
        .flat_map(|m| m.primitives().collect::<Vec<_>>())
    {
        assert!(prim.get(&gltf::Semantic::TexCoords(1)).is_some());
        let emissive = prim.material().emissive_texture().expect("the atlas");
        assert_eq!(emissive.tex_coord(), 1);
        let image = &images[emissive.texture().source().index()];
        assert_eq!((image.width, image.height), (128, 128));
    }
    assert_eq!(run.report.lightmap.as_ref().unwrap().resolution, 128);
}

#[test]
fn an_out_of_range_lightmap_is_refused() {
    let scene = load_scene(
        &crate::fixtures::scene_path("cornell-box.gltf"),
        &LoadOptions::default(),
    )
    .unwrap();
    for bad in [0, 8, 100_000] {
        let err =
            nusselt::solve(&scene, &preview_settings(Some(bad)), &Progress::hidden()).unwrap_err();
        assert!(err.to_string().contains("--lightmap"), "{err}");
    }
}
