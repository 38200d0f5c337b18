//! The bake keeps the scene: node names, parents, transforms, cameras,
//! materials and textures of the input survive, each instance gets its own
//! mesh, vertices sit in their node's frame (world positions equal the
//! solution's), `TEXCOORD_0` is carried over, and the patch table places
//! every output vertex and triangle once.

use std::path::{Path, PathBuf};

use glam::{DMat4, Vec3};
use nusselt::Progress;
use nusselt::load::{LoadOptions, load_scene};
use nusselt::mesh::OutputMesh;
use nusselt::output::baked::{self, BakeLayout};
use nusselt::scene::Scene;
use serde_json::json;

use crate::loader::Gltf;

/// An output mesh of `scene` without solving: each patch a fan around its
/// centroid, with radiosity and irradiance that differ per vertex.
fn fan_mesh(scene: &Scene) -> OutputMesh {
    let mut mesh = OutputMesh::default();
    for (i, patch) in scene.patches.iter().enumerate() {
        let base = mesh.positions.len() as u32;
        let corners = patch.vertices();
        for p in corners.iter().copied().chain([patch.centroid()]) {
            mesh.positions.push(p.as_vec3());
            mesh.normals.push(patch.normal.as_vec3());
            mesh.patch.push(i as u32);
            let h = Vec3::new(1.0, 2.0, 3.0) * (1.0 + (p.x.abs() + p.y.abs()) as f32);
            mesh.irradiance.push(h);
            mesh.radiosity
                .push(patch.emission.as_vec3() + patch.reflectance.as_vec3() * h);
        }
        let n = corners.len() as u32;
        for k in 0..n {
            mesh.triangles
                .push([base + k, base + (k + 1) % n, base + n]);
        }
    }
    mesh
}

/// The bake of `scene` (through `fan_mesh`) as a binary glTF, re-read.
fn bake(scene: &Scene) -> (OutputMesh, gltf::Document, Vec<gltf::buffer::Data>) {
    let mesh = fan_mesh(scene);
    let layout = BakeLayout::of_scene(scene, &mesh).unwrap();
    let glb = baked::encode_baked_glb(&mesh, &layout, 1.0).unwrap();
    let (doc, buffers, _) = gltf::import_slice(&glb).unwrap();
    (mesh, doc, buffers)
}

/// World transforms of the nodes reached from the default scene.
fn worlds(doc: &gltf::Document) -> Vec<Option<DMat4>> {
    let mut world = vec![None; doc.nodes().len()];
    let mut stack: Vec<(gltf::Node<'_>, DMat4)> = doc
        .default_scene()
        .unwrap()
        .nodes()
        .map(|n| (n, DMat4::IDENTITY))
        .collect();
    while let Some((node, parent)) = stack.pop() {
        let m = node.transform().matrix().map(|c| c.map(f64::from));
        let w = parent * DMat4::from_cols_array_2d(&m);
        world[node.index()] = Some(w);
        stack.extend(node.children().map(|c| (c, w)));
    }
    world
}

fn runs(value: &serde_json::Value) -> Vec<usize> {
    let mut out = Vec::new();
    for run in value.as_array().unwrap() {
        let (start, count) = (run[0].as_u64().unwrap(), run[1].as_u64().unwrap());
        out.extend((start..start + count).map(|i| i as usize));
    }
    out
}

/// What a node says about itself, apart from its mesh.
fn node_facts(node: &gltf::Node<'_>) -> (Option<String>, Vec<usize>, [[f32; 4]; 4], Option<usize>) {
    (
        node.name().map(str::to_string),
        node.children().map(|c| c.index()).collect(),
        node.transform().matrix(),
        node.camera().map(|c| c.index()),
    )
}

/// Checks the bake `doc` of `input` against the input document and `mesh`:
/// the structure is the input's, every vertex and triangle is placed once
/// and lands on its world position and winding. Returns, per baked vertex
/// in solution order, its (node, local position, TEXCOORD_0).
#[allow(clippy::type_complexity)]
fn check_bake(
    what: &str,
    input: &gltf::Document,
    mesh: &OutputMesh,
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
) -> Vec<Option<(usize, Vec3, Option<[f32; 2]>)>> {
    // Structure: nodes, cameras, scenes, textures, materials.
    assert_eq!(doc.nodes().len(), input.nodes().len(), "{what}: nodes");
    for (a, b) in input.nodes().zip(doc.nodes()) {
        assert_eq!(node_facts(&a), node_facts(&b), "{what}: node {}", b.index());
    }
    let scene_roots = |d: &gltf::Document| -> Vec<usize> {
        d.default_scene()
            .unwrap()
            .nodes()
            .map(|n| n.index())
            .collect()
    };
    assert_eq!(scene_roots(input), scene_roots(doc), "{what}: scene roots");
    assert_eq!(
        doc.cameras().len(),
        input.cameras().len(),
        "{what}: cameras"
    );
    for (a, b) in input.cameras().zip(doc.cameras()) {
        assert_eq!(a.name(), b.name());
        match (a.projection(), b.projection()) {
            (
                gltf::camera::Projection::Perspective(p),
                gltf::camera::Projection::Perspective(q),
            ) => {
                assert_eq!(
                    (p.yfov(), p.aspect_ratio(), p.znear(), p.zfar()),
                    (q.yfov(), q.aspect_ratio(), q.znear(), q.zfar())
                );
            }
            (
                gltf::camera::Projection::Orthographic(_),
                gltf::camera::Projection::Orthographic(_),
            ) => {}
            _ => panic!("{what}: camera {} changed its projection", a.index()),
        }
    }
    assert_eq!(
        doc.textures().len(),
        input.textures().len(),
        "{what}: textures"
    );
    for (a, b) in input.textures().zip(doc.textures()) {
        assert_eq!(a.source().name(), b.source().name());
        assert_eq!(a.sampler().index(), b.sampler().index());
    }
    // The images some texture uses, and only those.
    let mut used: Vec<usize> = input.textures().map(|t| t.source().index()).collect();
    used.sort_unstable();
    used.dedup();
    assert_eq!(doc.images().len(), used.len(), "{what}: images");
    let m = input.materials().len();
    for (a, b) in input.materials().zip(doc.materials()) {
        let (pa, pb) = (a.pbr_metallic_roughness(), b.pbr_metallic_roughness());
        assert_eq!(a.name(), b.name());
        assert_eq!(pa.base_color_factor(), pb.base_color_factor());
        let slot =
            |t: Option<gltf::texture::Info<'_>>| t.map(|t| (t.texture().index(), t.tex_coord()));
        assert_eq!(slot(pa.base_color_texture()), slot(pb.base_color_texture()));
        assert_eq!(a.emissive_factor(), b.emissive_factor());
    }

    // Geometry: every vertex and triangle once, in its node's frame.
    let world = worlds(doc);
    let scale = mesh
        .positions
        .iter()
        .fold(1.0f32, |a, p| a.max(p.abs().max_element()));
    let mut placed = vec![None; mesh.vertex_count()];
    let mut triangles_seen = vec![0u32; mesh.triangles.len()];
    let mut meshes_used = Vec::new();
    for node in doc.nodes() {
        let Some(node_mesh) = node.mesh() else {
            continue;
        };
        assert!(
            !meshes_used.contains(&node_mesh.index()),
            "{what}: a mesh is shared"
        );
        meshes_used.push(node_mesh.index());
        let w = world[node.index()].expect("a baked node is in the scene");
        let mirrored = w.determinant() < 0.0;
        for prim in node_mesh.primitives() {
            let material = prim.material().index().unwrap();
            assert!(material >= m, "{what}: a primitive uses an input material");
            assert!(prim.material().unlit());
            let extras: serde_json::Value =
                serde_json::from_str(prim.extras().as_ref().unwrap().get()).unwrap();
            let vertices = runs(&extras["solution_vertices"]);
            let triangles = runs(&extras["solution_triangles"]);
            let reader = prim.reader(|b| Some(&buffers[b.index()][..]));
            let positions: Vec<Vec3> = reader.read_positions().unwrap().map(Vec3::from).collect();
            let uvs: Option<Vec<[f32; 2]>> =
                reader.read_tex_coords(0).map(|t| t.into_f32().collect());
            let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            assert_eq!(
                positions.len(),
                vertices.len(),
                "{what}: patch table vertices"
            );
            assert_eq!(
                indices.len(),
                3 * triangles.len(),
                "{what}: patch table triangles"
            );
            for (k, (&v, p)) in vertices.iter().zip(&positions).enumerate() {
                assert!(placed[v].is_none(), "{what}: vertex {v} placed twice");
                let world_p = w.transform_point3(p.as_dvec3()).as_vec3();
                assert!(
                    (world_p - mesh.positions[v]).abs().max_element() <= 1e-5 * scale,
                    "{what}: vertex {v} lands at {world_p}, not {}",
                    mesh.positions[v]
                );
                placed[v] = Some((node.index(), *p, uvs.as_ref().map(|u| u[k])));
            }
            for (tri, &t) in indices.chunks(3).zip(&triangles) {
                triangles_seen[t] += 1;
                let mut solution: Vec<usize> = tri.iter().map(|&i| vertices[i as usize]).collect();
                if mirrored {
                    solution.swap(1, 2);
                }
                let expected: Vec<usize> = mesh.triangles[t].iter().map(|&i| i as usize).collect();
                assert_eq!(solution, expected, "{what}: triangle {t}");
            }
        }
    }
    assert!(
        placed.iter().all(Option::is_some),
        "{what}: a vertex is not baked"
    );
    assert!(
        triangles_seen.iter().all(|&c| c == 1),
        "{what}: a triangle is not baked once"
    );
    placed
}

fn bundled_scenes() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut files = Vec::new();
    for dir in [
        root.clone(),
        root.join("hard"),
        root.join("stress"),
        root.join("scale"),
    ] {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "gltf") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

#[test]
fn every_bundled_scene_keeps_its_structure_in_the_bake() {
    let files = bundled_scenes();
    assert!(files.len() >= 15, "{} bundled scenes", files.len());
    for file in files {
        let what = file.display().to_string();
        let scene = load_scene(&file, &LoadOptions::default()).unwrap();
        let (input, _, _) = gltf::import(&file).unwrap();
        let (mesh, doc, buffers) = bake(&scene);
        check_bake(&what, &input, &mesh, &doc, &buffers);
    }
}

#[test]
fn textured_instances_and_a_mirror_keep_their_frames_and_texture_coordinates() {
    let mut g = Gltf::default();
    g.light();
    let checker = g.checker();
    let quad = g.quad_mesh(Some("Tile"), Some(checker));
    // A parent that rotates and scales unevenly, its two instances of the
    // tile (one mirrored), and a camera child.
    let camera = g.cameras.len();
    g.cameras.push(json!({"type": "perspective", "name": "Eye",
        "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.05}}));
    let plain = g.node(json!({"name": "Plain", "mesh": quad, "translation": [1.0, 2.0, 0.5]}));
    let mirror = g.node(
        json!({"name": "Mirror", "mesh": quad, "scale": [-1.0, 1.0, 1.0],
        "translation": [-1.0, 0.0, 0.0]}),
    );
    let eye = g.node(json!({"name": "EyeNode", "camera": camera, "translation": [0.0, 0.0, 5.0]}));
    g.root(json!({"name": "Group", "children": [plain, mirror, eye],
        "rotation": [0.0, 0.2588190451, 0.0, 0.9659258263], "scale": [2.0, 1.0, 0.5]}));

    let bytes = g.embedded();
    let scene =
        nusselt::load::load_scene_from_slice(&bytes, None, &LoadOptions::default()).unwrap();
    let input = gltf::Gltf::from_slice(&bytes).unwrap().document;
    let (mesh, doc, buffers) = bake(&scene);
    let placed = check_bake("textured", &input, &mesh, &doc, &buffers);

    // The input quad maps (x, y) to uv (x, 1 - y); every vertex of a tile,
    // corners and centroids, carries that in its node's frame.
    let mut tiles = 0;
    for (node, local, uv) in placed.into_iter().flatten() {
        if node == plain || node == mirror {
            tiles += 1;
            let uv = uv.expect("the tile's vertices carry TEXCOORD_0");
            assert!(local.z.abs() < 1e-6 && local.x >= -1e-6 && local.x <= 1.0 + 1e-6);
            assert!(
                (uv[0] - local.x).abs() < 1e-5 && (uv[1] - (1.0 - local.y)).abs() < 1e-5,
                "{local} {uv:?}"
            );
        }
    }
    assert_eq!(
        tiles,
        2 * 5,
        "two tiles of one quad patch, 4 corners and a centroid each"
    );

    // The texture and its image bytes came along; the camera stays a child.
    let image = doc.images().next().unwrap();
    let gltf::image::Source::View { view, mime_type } = image.source() else {
        panic!("the image is not embedded");
    };
    assert_eq!(mime_type, "image/png");
    let png = &buffers[view.buffer().index()][view.offset()..view.offset() + view.length()];
    assert!(png.starts_with(b"\x89PNG"));
    let eye_node = doc.nodes().nth(eye).unwrap();
    assert_eq!(eye_node.camera().unwrap().name(), Some("Eye"));
    // Each baked material names its input material.
    for material in doc.materials().skip(input.materials().len()) {
        let extras: serde_json::Value =
            serde_json::from_str(material.extras().as_ref().unwrap().get()).unwrap();
        let source = extras["source_material"].as_u64().unwrap() as usize;
        let name = input.materials().nth(source).unwrap().name().unwrap();
        assert!(
            material.name().unwrap().starts_with(name),
            "{:?}",
            material.name()
        );
    }
}

#[test]
fn a_real_solve_bakes_onto_the_nodes() {
    // The whole pipeline on the Cornell box: the bake written by
    // `write_outputs` re-reads with its world positions on the solution's.
    let file = crate::fixtures::scene_path("cornell-box.gltf");
    let scene = load_scene(&file, &LoadOptions::default()).unwrap();
    let settings = crate::fixtures::preview_settings(None);
    let mut run = nusselt::solve(&scene, &settings, &Progress::hidden()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    nusselt::write_outputs(dir.path(), &mut run).unwrap();
    let (doc, buffers, _) = gltf::import(dir.path().join("baked.gltf")).unwrap();
    let (input, _, _) = gltf::import(&file).unwrap();
    let named: Vec<_> = doc
        .nodes()
        .filter(|n| n.mesh().is_some())
        .filter_map(|n| n.name())
        .collect();
    assert!(
        named.contains(&"tall_block") && named.contains(&"light"),
        "{named:?}"
    );
    check_bake("cornell solve", &input, &run.mesh, &doc, &buffers);
}

/// The bake's vertices back in `solution.exr`'s order, through the patch
/// table: world positions (f32, through the node transforms), `_RADIOSITY`,
/// `_IRRADIANCE`; and the triangles as solution vertex indices, in
/// solution order.
pub(crate) struct Reassembled {
    pub positions: Vec<Vec3>,
    pub radiosity: Vec<Vec3>,
    pub irradiance: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

pub(crate) fn reassemble(doc: &gltf::Document, buffers: &[gltf::buffer::Data]) -> Reassembled {
    let world = worlds(doc);
    let mut parts: Vec<(usize, Vec3, Vec3, Vec3)> = Vec::new();
    let mut triangles: Vec<(usize, [u32; 3])> = Vec::new();
    for node in doc.nodes() {
        let Some(node_mesh) = node.mesh() else {
            continue;
        };
        let w = world[node.index()].unwrap();
        for prim in node_mesh.primitives() {
            let extras: serde_json::Value =
                serde_json::from_str(prim.extras().as_ref().unwrap().get()).unwrap();
            let vertices = runs(&extras["solution_vertices"]);
            let reader = prim.reader(|b| Some(&buffers[b.index()][..]));
            let attribute = |name: &str| {
                let accessor = prim
                    .attributes()
                    .find(|(s, _)| *s == gltf::Semantic::Extras(name.into()))
                    .unwrap()
                    .1;
                gltf::accessor::Iter::<[f32; 3]>::new(accessor, |b| Some(&buffers[b.index()][..]))
                    .unwrap()
                    .map(Vec3::from)
                    .collect::<Vec<_>>()
            };
            let (b, h) = (attribute("RADIOSITY"), attribute("IRRADIANCE"));
            for (k, p) in reader.read_positions().unwrap().enumerate() {
                let p = w.transform_point3(Vec3::from(p).as_dvec3()).as_vec3();
                parts.push((vertices[k], p, b[k], h[k]));
            }
            let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            for (tri, t) in indices.chunks(3).zip(runs(&extras["solution_triangles"])) {
                let mut solution = [tri[0], tri[1], tri[2]].map(|i| vertices[i as usize] as u32);
                if w.determinant() < 0.0 {
                    solution.swap(1, 2);
                }
                triangles.push((t, solution));
            }
        }
    }
    parts.sort_by_key(|p| p.0);
    triangles.sort_by_key(|t| t.0);
    Reassembled {
        positions: parts.iter().map(|p| p.1).collect(),
        radiosity: parts.iter().map(|p| p.2).collect(),
        irradiance: parts.iter().map(|p| p.3).collect(),
        triangles: triangles.into_iter().map(|t| t.1).collect(),
    }
}

#[test]
fn an_image_no_texture_uses_may_be_missing_and_is_left_out() {
    // Image 0 names a file that does not exist and no texture uses it; the
    // texture uses image 1. The scene loads, and the bake keeps image 1
    // only, as its image 0.
    let mut g = Gltf::default();
    g.light();
    g.images.push(json!({"uri": "missing.png"}));
    let texture = g.png_texture(1, 1, &[[200, 100, 50]], None);
    let m = g.material(json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": texture}}}));
    let tile = g.quad_mesh(Some("Tile"), Some(m));
    g.root(json!({"name": "Tile", "mesh": tile}));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("scene.gltf");
    std::fs::write(&file, g.embedded()).unwrap();
    let scene = load_scene(&file, &LoadOptions::default()).unwrap();
    let (_, doc, _) = bake(&scene);
    let images: Vec<_> = doc.images().collect();
    assert_eq!(images.len(), 1);
    assert_eq!(images[0].name(), Some("checker"));
    assert_eq!(doc.textures().next().unwrap().source().index(), 0);
}
