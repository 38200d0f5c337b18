//! The glTF loader: transforms, winding, materials, textures, cameras,
//! naming, the three container forms, and every kind of bad input.

use std::io::Cursor;
use std::path::Path;

use glam::DVec3;
use nusselt::Error;
use nusselt::load::{LoadOptions, load_scene, load_scene_from_slice};
use nusselt::scene::{LightKind, Scene, Shape, Side};
use serde_json::{Value, json};

/// Builds small glTF documents with one binary buffer (also used by the
/// bake's round-trip tests).
#[derive(Default)]
pub(crate) struct Gltf {
    pub(crate) bin: Vec<u8>,
    pub(crate) views: Vec<Value>,
    pub(crate) accessors: Vec<Value>,
    pub(crate) meshes: Vec<Value>,
    pub(crate) nodes: Vec<Value>,
    pub(crate) materials: Vec<Value>,
    pub(crate) textures: Vec<Value>,
    pub(crate) images: Vec<Value>,
    pub(crate) samplers: Vec<Value>,
    pub(crate) cameras: Vec<Value>,
    pub(crate) extensions_used: Vec<&'static str>,
    /// Scene root nodes; `None`: every node added with `root`.
    pub(crate) roots: Vec<usize>,
}

const QUAD: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
const QUAD_UV: [[f32; 2]; 4] = [[0., 1.], [1., 1.], [1., 0.], [0., 0.]];
const QUAD_INDICES: [u16; 6] = [0, 1, 2, 0, 2, 3];

impl Gltf {
    pub(crate) fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    pub(crate) fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    pub(crate) fn positions(&mut self, p: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = p.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let lo = (0..3).map(|k| p.iter().map(|v| v[k]).fold(f32::INFINITY, f32::min));
        let hi = (0..3).map(|k| p.iter().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max));
        let finite = |x: f32| if x.is_finite() { x } else { 0.0 };
        self.accessor(json!({
            "bufferView": view, "componentType": 5126, "count": p.len(), "type": "VEC3",
            "min": lo.map(finite).collect::<Vec<_>>(), "max": hi.map(finite).collect::<Vec<_>>()
        }))
    }

    pub(crate) fn uvs(&mut self, uv: &[[f32; 2]]) -> usize {
        let bytes: Vec<u8> = uv.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessor(
            json!({"bufferView": view, "componentType": 5126, "count": uv.len(), "type": "VEC2"}),
        )
    }

    pub(crate) fn indices(&mut self, i: &[u16]) -> usize {
        let bytes: Vec<u8> = i.iter().flat_map(|c| c.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessor(
            json!({"bufferView": view, "componentType": 5123, "count": i.len(), "type": "SCALAR"}),
        )
    }

    pub(crate) fn material(&mut self, m: Value) -> usize {
        self.materials.push(m);
        self.materials.len() - 1
    }

    pub(crate) fn emitter(&mut self) -> usize {
        self.material(json!({"name": "Light", "emissiveFactor": [1.0, 1.0, 1.0],
            "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}}))
    }

    pub(crate) fn grey(&mut self) -> usize {
        self.material(json!({"name": "Grey",
            "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}}))
    }

    /// A mesh with one indexed quad primitive (with texture coordinates).
    pub(crate) fn quad_mesh(&mut self, name: Option<&str>, material: Option<usize>) -> usize {
        let pos = self.positions(&QUAD);
        let uv = self.uvs(&QUAD_UV);
        let idx = self.indices(&QUAD_INDICES);
        let mut prim = json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "indices": idx});
        if let Some(m) = material {
            prim["material"] = json!(m);
        }
        self.mesh(name, vec![prim])
    }

    pub(crate) fn mesh(&mut self, name: Option<&str>, primitives: Vec<Value>) -> usize {
        let mut mesh = json!({"primitives": primitives});
        if let Some(n) = name {
            mesh["name"] = json!(n);
        }
        self.meshes.push(mesh);
        self.meshes.len() - 1
    }

    pub(crate) fn node(&mut self, n: Value) -> usize {
        self.nodes.push(n);
        self.nodes.len() - 1
    }

    pub(crate) fn root(&mut self, n: Value) -> usize {
        let i = self.node(n);
        self.roots.push(i);
        i
    }

    /// An emitting quad far from everything else, so scenes are valid.
    pub(crate) fn light(&mut self) -> usize {
        let m = self.emitter();
        let mesh = self.quad_mesh(Some("LightMesh"), Some(m));
        self.root(
            json!({"name": "Light", "mesh": mesh, "translation": [0.0, 0.0, 50.0],
            "rotation": [1.0, 0.0, 0.0, 0.0]}),
        )
    }

    /// A material "Checker" whose base colour is a 2 × 2 texture of four
    /// colours.
    pub(crate) fn checker(&mut self) -> usize {
        let texels = [[250, 20, 20], [20, 250, 20], [20, 20, 250], [200, 200, 200]];
        let texture = self.png_texture(2, 2, &texels, None);
        self.material(json!({"name": "Checker", "pbrMetallicRoughness": {
            "baseColorFactor": [0.9, 0.9, 0.9, 1.0], "metallicFactor": 0.0,
            "baseColorTexture": {"index": texture}}}))
    }

    /// A PNG image (8-bit sRGB RGB) embedded through a buffer view.
    pub(crate) fn png_texture(
        &mut self,
        w: u32,
        h: u32,
        texels: &[[u8; 3]],
        sampler: Option<Value>,
    ) -> usize {
        let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb(texels[(y * w + x) as usize]));
        let mut png = Vec::new();
        img.write_to(&mut Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let view = self.view(&png);
        self.images
            .push(json!({"bufferView": view, "mimeType": "image/png", "name": "checker"}));
        let mut texture = json!({"source": self.images.len() - 1});
        if let Some(s) = sampler {
            self.samplers.push(s);
            texture["sampler"] = json!(self.samplers.len() - 1);
        }
        self.textures.push(texture);
        self.textures.len() - 1
    }

    pub(crate) fn json(&self, buffer: Value) -> Value {
        let mut root = json!({
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": self.roots}],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "buffers": [buffer],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        for (key, list) in [
            ("materials", &self.materials),
            ("textures", &self.textures),
            ("images", &self.images),
            ("samplers", &self.samplers),
            ("cameras", &self.cameras),
        ] {
            if !list.is_empty() {
                root[key] = json!(list);
            }
        }
        if !self.extensions_used.is_empty() {
            root["extensionsUsed"] = json!(self.extensions_used);
        }
        root
    }

    /// `.gltf` bytes with the buffer as a base64 data URI.
    pub(crate) fn embedded(&self) -> Vec<u8> {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::Engine::encode(&base64::engine::general_purpose::STANDARD, &self.bin)
        );
        serde_json::to_vec(&self.json(json!({"byteLength": self.bin.len(), "uri": uri}))).unwrap()
    }

    /// `.glb` bytes.
    pub(crate) fn glb(&self) -> Vec<u8> {
        let mut json =
            serde_json::to_vec(&self.json(json!({"byteLength": self.bin.len()}))).unwrap();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }

    pub(crate) fn load(&self) -> nusselt::Result<Scene> {
        load_scene_from_slice(&self.embedded(), None, &LoadOptions::default())
    }
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).length() <= tol
}

fn patches_of(scene: &Scene, surface: &str) -> Vec<nusselt::scene::Patch> {
    let s = scene
        .surfaces
        .iter()
        .position(|s| s.name == surface)
        .unwrap_or_else(|| panic!("no surface {surface}"));
    scene
        .patches
        .iter()
        .filter(|p| p.surface as usize == s)
        .cloned()
        .collect()
}

fn scene_error(result: nusselt::Result<Scene>) -> String {
    match result {
        Err(Error::Scene { message, .. }) => message,
        Err(other) => panic!("expected a scene error, got {other}"),
        Ok(_) => panic!("expected a scene error, got a scene"),
    }
}

#[test]
fn two_triangle_quad_merges_and_trs_applies() {
    let mut g = Gltf::default();
    g.light();
    let m = g.grey();
    let mesh = g.quad_mesh(Some("Q"), Some(m));
    let half = std::f32::consts::FRAC_1_SQRT_2;
    // Rotate 90° about X, scale 2, translate (1, 2, 3).
    g.root(
        json!({"name": "Floor", "mesh": mesh, "translation": [1.0, 2.0, 3.0],
        "rotation": [half, 0.0, 0.0, half], "scale": [2.0, 2.0, 2.0]}),
    );
    let scene = g.load().unwrap();
    let p = patches_of(&scene, "Floor");
    assert_eq!(p.len(), 1);
    assert_eq!(p[0].shape, Shape::Quad);
    assert!((p[0].area - 4.0).abs() < 1e-6);
    // R_x(90°) sends +Z to -Y.
    assert!(close(p[0].normal, DVec3::NEG_Y, 1e-6), "{}", p[0].normal);
    // (1,1,0) -> scale (2,2,0) -> rotate (2,0,2) -> translate (3,2,5).
    assert!(
        close(p[0].centroid(), DVec3::new(2.0, 2.0, 4.0), 1e-6),
        "{}",
        p[0].centroid()
    );
    assert!(
        p[0].vertices()
            .iter()
            .any(|v| close(*v, DVec3::new(3.0, 2.0, 5.0), 1e-6))
    );
    assert_eq!(scene.stats.merged_quads, 2);
}

#[test]
fn matrix_and_nested_parents_compose() {
    let mut g = Gltf::default();
    g.light();
    let m = g.grey();
    let mesh = g.quad_mesh(None, Some(m));
    let child = g.node(json!({"name": "Child", "mesh": mesh, "scale": [3.0, 3.0, 3.0]}));
    // Column-major translation by (10, 0, 0).
    g.root(json!({"name": "Parent", "children": [child],
        "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 10,0,0,1]}));
    let scene = g.load().unwrap();
    let p = patches_of(&scene, "Child");
    assert_eq!(p.len(), 1);
    assert!((p[0].area - 9.0).abs() < 1e-9);
    assert!(close(p[0].centroid(), DVec3::new(11.5, 1.5, 0.0), 1e-9));
    assert!(close(p[0].normal, DVec3::Z, 1e-12));
}

#[test]
fn mirrored_nodes_keep_the_front_face() {
    for (scale, normal) in [
        ([-1.0, 1.0, 1.0], DVec3::Z),
        ([1.0, 1.0, -1.0], DVec3::NEG_Z),
    ] {
        let mut g = Gltf::default();
        g.light();
        let m = g.grey();
        let mesh = g.quad_mesh(None, Some(m));
        g.root(json!({"name": "Mirror", "mesh": mesh, "scale": scale}));
        let scene = g.load().unwrap();
        let p = patches_of(&scene, "Mirror");
        assert_eq!(p.len(), 1);
        assert!(
            close(p[0].normal, normal, 1e-12),
            "scale {scale:?}: {}",
            p[0].normal
        );
        // The corners still run counter-clockwise around the normal.
        let (_, n) = nusselt::scene::polygon_area_normal(p[0].vertices());
        assert!(close(n, normal, 1e-12));
    }
}

#[test]
fn double_sided_materials_get_back_patches() {
    let mut g = Gltf::default();
    g.light();
    let m = g.material(json!({"name": "Card", "doubleSided": true,
        "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.3, 0.3, 1.0], "metallicFactor": 0.0}}));
    let mesh = g.quad_mesh(None, Some(m));
    g.root(json!({"name": "Card", "mesh": mesh}));
    let scene = g.load().unwrap();
    let p = patches_of(&scene, "Card");
    assert_eq!(p.len(), 2);
    assert_eq!(p.iter().filter(|p| p.side == Side::Back).count(), 1);
    assert_eq!(scene.stats.back_patches, 1);
    let material = scene.materials.iter().find(|m| m.name == "Card").unwrap();
    assert!(material.double_sided);
    let light = scene.materials.iter().find(|m| m.name == "Light").unwrap();
    assert!(!light.double_sided);
}

#[test]
fn emissive_strength_multiplies_the_factor() {
    let mut g = Gltf::default();
    g.extensions_used.push("KHR_materials_emissive_strength");
    let m = g.material(json!({"name": "Bright", "emissiveFactor": [1.0, 0.5, 0.25],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}},
        "pbrMetallicRoughness": {"metallicFactor": 0.0, "baseColorFactor": [0.2, 0.2, 0.2, 1.0]}}));
    let mesh = g.quad_mesh(None, Some(m));
    g.root(json!({"name": "Lamp", "mesh": mesh}));
    let scene = g.load().unwrap();
    assert_eq!(
        scene.materials[0].emitted_radiance,
        DVec3::new(4.0, 2.0, 1.0)
    );
    let p = patches_of(&scene, "Lamp");
    assert!(close(
        p[0].emission,
        std::f64::consts::PI * DVec3::new(4.0, 2.0, 1.0),
        1e-12
    ));
    assert!(close(p[0].reflectance, DVec3::splat(0.2), 1e-6));
}

fn srgb(c: u8) -> f64 {
    let c = f64::from(c) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn base_color_texture_mean_is_linear() {
    // 2×2 checker of known sRGB colours.
    let texels = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [128, 128, 128]];
    let mean = |k: usize| texels.iter().map(|t| srgb(t[k])).sum::<f64>() / 4.0;
    let expected = 0.5 * DVec3::new(mean(0), mean(1), mean(2));
    for sampler in [None, Some(json!({"magFilter": 9728, "minFilter": 9728}))] {
        let mut g = Gltf::default();
        g.light();
        let t = g.png_texture(2, 2, &texels, sampler.clone());
        let m = g.material(json!({"name": "Checker", "pbrMetallicRoughness": {
            "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0,
            "baseColorTexture": {"index": t}}}));
        let mesh = g.quad_mesh(None, Some(m));
        g.root(json!({"name": "Board", "mesh": mesh}));
        let scene = g.load().unwrap();
        let p = patches_of(&scene, "Board");
        assert!(
            close(p[0].reflectance, expected, 0.01),
            "sampler {sampler:?}: {} vs {expected}",
            p[0].reflectance
        );
        // The material keeps the factor alone.
        let material = scene
            .materials
            .iter()
            .find(|m| m.name == "Checker")
            .unwrap();
        assert_eq!(material.reflectance, DVec3::splat(0.5));
    }
}

#[test]
fn emissive_texture_is_srgb_decoded_and_wrap_modes_apply() {
    // Left column white, right column sRGB 128 grey. With CLAMP_TO_EDGE and
    // u in [1, 2], only the right column is seen; with REPEAT, both.
    let texels = [
        [255, 255, 255],
        [128, 128, 128],
        [255, 255, 255],
        [128, 128, 128],
    ];
    let grey = srgb(128);
    for (wrap, expected) in [
        (33071, grey),
        (10497, 0.5 * (1.0 + grey)),
        (33648, 0.5 * (1.0 + grey)),
    ] {
        let mut g = Gltf::default();
        let t = g.png_texture(2, 2, &texels, Some(json!({"wrapS": wrap, "wrapT": wrap})));
        let m = g.material(json!({"name": "Glow", "emissiveFactor": [2.0, 2.0, 2.0],
            "emissiveTexture": {"index": t}, "pbrMetallicRoughness": {"metallicFactor": 0.0}}));
        let pos = g.positions(&QUAD);
        let uv = g.uvs(&[[1., 1.], [2., 1.], [2., 0.], [1., 0.]]);
        let idx = g.indices(&QUAD_INDICES);
        let mesh = g.mesh(
            None,
            vec![json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv},
            "indices": idx, "material": m})],
        );
        g.root(json!({"name": "Panel", "mesh": mesh}));
        let scene = g.load().unwrap();
        let p = patches_of(&scene, "Panel");
        let want = std::f64::consts::PI * 2.0 * expected;
        assert!(
            (p[0].emission.x - want).abs() < 0.01 * want,
            "wrap {wrap}: {} vs {want}",
            p[0].emission.x
        );
    }
}

#[test]
fn texture_uses_the_named_texcoord_set() {
    let texels = [[255, 255, 255], [0, 0, 0], [255, 255, 255], [0, 0, 0]];
    let mut g = Gltf::default();
    g.light();
    let t = g.png_texture(2, 2, &texels, Some(json!({"magFilter": 9728})));
    let m = g.material(
        json!({"name": "M", "pbrMetallicRoughness": {"metallicFactor": 0.0,
        "baseColorTexture": {"index": t, "texCoord": 1}}}),
    );
    let pos = g.positions(&QUAD);
    let uv0 = g.uvs(&QUAD_UV);
    // Set 1 squeezes the whole quad into the left (white) column.
    let uv1 = g.uvs(&[[0.1, 0.9], [0.4, 0.9], [0.4, 0.1], [0.1, 0.1]]);
    let idx = g.indices(&QUAD_INDICES);
    let mesh = g.mesh(
        None,
        vec![json!({"attributes": {"POSITION": pos, "TEXCOORD_0": uv0,
        "TEXCOORD_1": uv1}, "indices": idx, "material": m})],
    );
    g.root(json!({"name": "S", "mesh": mesh}));
    let scene = g.load().unwrap();
    let p = patches_of(&scene, "S");
    // White texels and a white factor: clamped to the maximum, with a warning.
    assert!(
        close(p[0].reflectance, DVec3::splat(0.999), 1e-12),
        "{}",
        p[0].reflectance
    );
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("'M'") && w.contains("clamped"))
    );
}

#[test]
fn cameras_come_from_the_node_transform() {
    let mut g = Gltf::default();
    g.light();
    g.cameras.push(json!({"name": "Main", "type": "perspective",
        "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}}));
    g.cameras.push(json!({"type": "orthographic",
        "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}));
    let half = std::f32::consts::FRAC_1_SQRT_2;
    // 90° about +Y: -Z turns into -X.
    g.root(
        json!({"camera": 0, "translation": [1.0, 2.0, 3.0], "rotation": [0.0, half, 0.0, half]}),
    );
    g.root(json!({"camera": 1}));
    let scene = g.load().unwrap();
    assert_eq!(scene.cameras.len(), 1);
    let c = &scene.cameras[0];
    assert_eq!(c.name, "Main");
    assert!(close(c.eye, DVec3::new(1.0, 2.0, 3.0), 1e-6));
    assert!(close(c.forward, DVec3::NEG_X, 1e-6), "{}", c.forward);
    assert!(close(c.up, DVec3::Y, 1e-6));
    assert!((c.yfov - 0.8).abs() < 1e-6);
    assert!((c.aspect_ratio.unwrap() - 1.5).abs() < 1e-6);
    assert!(scene.warnings.iter().any(|w| w.contains("orthographic")));
}

#[test]
fn surfaces_are_named_by_node_then_mesh_then_index() {
    let mut g = Gltf::default();
    let light = g.light();
    let m = g.grey();
    let named = g.quad_mesh(Some("FloorMesh"), Some(m));
    let a = g.root(json!({"name": "Floor", "mesh": named}));
    let b = g.root(json!({"mesh": named, "translation": [0.0, 0.0, 5.0]}));
    let anonymous = g.quad_mesh(None, Some(m));
    let c = g.root(json!({"mesh": anonymous, "translation": [0.0, 0.0, 9.0]}));
    let scene = g.load().unwrap();
    let names: Vec<(&str, usize)> = scene
        .surfaces
        .iter()
        .map(|s| (s.name.as_str(), s.node))
        .collect();
    let node_c = format!("node{c}");
    assert_eq!(
        names,
        vec![
            ("Light", light),
            ("Floor", a),
            ("FloorMesh", b),
            (node_c.as_str(), c)
        ]
    );
}

#[test]
fn default_material_is_white_and_clamped_and_features_warn_once() {
    let mut g = Gltf::default();
    g.light();
    let metal =
        g.material(json!({"name": "Metal", "pbrMetallicRoughness": {"metallicFactor": 1.0}}));
    let bumpy = g.material(json!({"name": "Bumpy", "alphaMode": "BLEND",
        "normalTexture": {"index": 0}, "pbrMetallicRoughness": {"metallicFactor": 0.0}}));
    g.png_texture(1, 1, &[[128, 128, 255]], None);
    let plain = g.quad_mesh(None, None);
    let a = g.quad_mesh(None, Some(metal));
    let b = g.quad_mesh(None, Some(bumpy));
    for (i, mesh) in [plain, a, b].into_iter().enumerate() {
        g.root(json!({"mesh": mesh, "translation": [0.0, 0.0, 2.0 * i as f64]}));
    }
    let scene = g.load().unwrap();
    let default = scene
        .materials
        .iter()
        .find(|m| m.name == "default")
        .unwrap();
    assert_eq!(default.reflectance, DVec3::splat(0.999));
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("'default'") && w.contains("clamped"))
    );
    let ignored: Vec<_> = scene
        .warnings
        .iter()
        .filter(|w| w.contains("ignored by"))
        .collect();
    assert_eq!(ignored.len(), 1, "{:?}", scene.warnings);
    for word in [
        "metallic",
        "normal maps",
        "transparency",
        "'Metal'",
        "'Bumpy'",
    ] {
        assert!(
            ignored[0].contains(word),
            "{word} missing from {}",
            ignored[0]
        );
    }
    // The maximum is configurable.
    let options = LoadOptions {
        max_reflectance: 0.9,
        ..LoadOptions::default()
    };
    let scene = load_scene_from_slice(&g.embedded(), None, &options).unwrap();
    let default = scene
        .materials
        .iter()
        .find(|m| m.name == "default")
        .unwrap();
    assert_eq!(default.reflectance, DVec3::splat(0.9));
}

#[test]
fn strips_fans_and_unindexed_primitives_load() {
    let mut g = Gltf::default();
    let m = g.emitter();
    let pos = g.positions(&QUAD);
    let strip_idx = g.indices(&[0, 1, 3, 2]);
    let tri_pos = g.positions(&[[0., 0., 1.], [1., 0., 1.], [0., 1., 1.]]);
    let mesh = g.mesh(Some("Mixed"), vec![
        json!({"attributes": {"POSITION": pos}, "indices": strip_idx, "mode": 5, "material": m}),
        json!({"attributes": {"POSITION": pos}, "mode": 6, "material": m}),
        json!({"attributes": {"POSITION": tri_pos}, "material": m}),
    ]);
    g.root(json!({"mesh": mesh}));
    let scene = g.load().unwrap();
    assert_eq!(scene.stats.input_triangles, 5);
    // Every triangle faces +Z: strips and fans keep the winding.
    for p in &scene.patches {
        assert!(close(p.normal, DVec3::Z, 1e-12), "{}", p.normal);
    }
}

#[test]
fn glb_and_external_buffers_load_like_embedded_ones() {
    let mut g = Gltf::default();
    g.light();
    let m = g.grey();
    let mesh = g.quad_mesh(Some("Q"), Some(m));
    g.root(json!({"name": "Floor", "mesh": mesh}));
    let reference = g.load().unwrap();
    let glb = load_scene_from_slice(&g.glb(), None, &LoadOptions::default()).unwrap();
    assert_eq!(glb.patches, reference.patches);

    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene data.bin"), &g.bin).unwrap();
    let json = g.json(json!({"byteLength": g.bin.len(), "uri": "scene%20data.bin"}));
    let path = dir.path().join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let external = load_scene(&path, &LoadOptions::default()).unwrap();
    assert_eq!(external.patches, reference.patches);
    let glb_path = dir.path().join("scene.glb");
    std::fs::write(&glb_path, g.glb()).unwrap();
    assert_eq!(
        load_scene(&glb_path, &LoadOptions::default())
            .unwrap()
            .patches,
        reference.patches
    );

    // From memory without a folder, the external buffer cannot be found.
    let bytes = serde_json::to_vec(&json).unwrap();
    let message = scene_error(load_scene_from_slice(&bytes, None, &LoadOptions::default()));
    assert!(message.contains("external"), "{message}");
    // With the folder, it can.
    let scene = load_scene_from_slice(&bytes, Some(dir.path()), &LoadOptions::default()).unwrap();
    assert_eq!(scene.patches, reference.patches);
}

/// A valid one-quad scene whose JSON the caller may damage.
fn valid_json() -> (Gltf, Value) {
    let mut g = Gltf::default();
    let m = g.emitter();
    let mesh = g.quad_mesh(Some("Floor"), Some(m));
    g.root(json!({"name": "F", "mesh": mesh}));
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::Engine::encode(&base64::engine::general_purpose::STANDARD, &g.bin)
    );
    let json = g.json(json!({"byteLength": g.bin.len(), "uri": uri}));
    (g, json)
}

fn load_json(json: &Value) -> nusselt::Result<Scene> {
    load_scene_from_slice(
        &serde_json::to_vec(json).unwrap(),
        None,
        &LoadOptions::default(),
    )
}

#[test]
fn missing_file_malformed_json_and_truncated_glb_are_errors() {
    let path = Path::new("/nonexistent/dir/scene.gltf");
    match load_scene(path, &LoadOptions::default()) {
        Err(e @ Error::Scene { .. }) => {
            let line = e.to_string();
            assert!(
                line.contains("scene.gltf") && line.contains("cannot read"),
                "{line}"
            );
        }
        other => panic!("{other:?}"),
    }
    let message = scene_error(load_scene_from_slice(
        b"{\"asset\": ",
        None,
        &LoadOptions::default(),
    ));
    assert!(message.contains("not a valid glTF"), "{message}");
    let (g, _) = valid_json();
    let glb = g.glb();
    for cut in [3, 11, 20, glb.len() - 7] {
        let r = load_scene_from_slice(&glb[..cut], None, &LoadOptions::default());
        assert!(matches!(r, Err(Error::Scene { .. })), "cut at {cut}");
    }
    // A GLB header whose length is below the header size.
    let mut bad = glb.clone();
    bad[8..12].copy_from_slice(&3u32.to_le_bytes());
    scene_error(load_scene_from_slice(&bad, None, &LoadOptions::default()));
}

#[test]
fn non_finite_positions_name_mesh_and_primitive() {
    let mut g = Gltf::default();
    let m = g.emitter();
    let pos = g.positions(&[[0., 0., 0.], [1., f32::NAN, 0.], [0., 1., 0.]]);
    let mesh = g.mesh(
        Some("Broken"),
        vec![json!({"attributes": {"POSITION": pos}, "material": m})],
    );
    g.root(json!({"mesh": mesh}));
    let message = scene_error(g.load());
    assert!(
        message.contains("mesh 'Broken' primitive 0") && message.contains("non-finite"),
        "{message}"
    );
}

#[test]
fn out_of_range_index_names_mesh_and_primitive() {
    let mut g = Gltf::default();
    let m = g.emitter();
    let pos = g.positions(&QUAD);
    let ok = g.indices(&QUAD_INDICES);
    let bad = g.indices(&[0, 1, 17]);
    let mesh = g.mesh(
        Some("Floor"),
        vec![
            json!({"attributes": {"POSITION": pos}, "indices": ok, "material": m}),
            json!({"attributes": {"POSITION": pos}, "indices": bad, "material": m}),
        ],
    );
    g.root(json!({"mesh": mesh}));
    let message = scene_error(g.load());
    assert_eq!(
        message,
        "mesh 'Floor' primitive 1: index 17 out of range (4 vertices)"
    );
}

#[test]
fn line_primitives_are_refused() {
    let mut g = Gltf::default();
    let m = g.emitter();
    let pos = g.positions(&QUAD);
    let mesh = g.mesh(
        Some("Wire"),
        vec![json!({"attributes": {"POSITION": pos}, "mode": 1, "material": m})],
    );
    g.root(json!({"mesh": mesh}));
    let message = scene_error(g.load());
    assert!(
        message.starts_with("mesh 'Wire' primitive 0:") && message.contains("Lines"),
        "{message}"
    );
}

#[test]
fn a_scene_without_emitters_is_an_error() {
    let mut g = Gltf::default();
    let m = g.grey();
    let mesh = g.quad_mesh(None, Some(m));
    g.root(json!({"mesh": mesh}));
    assert!(matches!(g.load(), Err(Error::NoLight)));
}

#[test]
fn punctual_lights_are_read_in_world_space() {
    // A point light under a parent node translated by (1, 2, 3), a
    // directional light rotated 90° about x (its −z turns to −y, down),
    // a spot light with its cone.
    let (_, mut json) = valid_json();
    json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "name": "Bulb", "intensity": 10.0, "color": [1.0, 0.5, 0.25], "range": 4.0},
        {"type": "directional", "intensity": 3.0},
        {"type": "spot", "intensity": 2.0, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}}]}});
    let s = std::f64::consts::FRAC_1_SQRT_2;
    json["nodes"].as_array_mut().unwrap().extend([
        json!({"name": "Lamp", "translation": [1.0, 2.0, 3.0], "children": [2]}),
        json!({"name": "B", "translation": [0.5, 0.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}),
        json!({"name": "Sun", "rotation": [-s, 0.0, 0.0, s], "extensions": {"KHR_lights_punctual": {"light": 1}}}),
        json!({"name": "Spot", "extensions": {"KHR_lights_punctual": {"light": 2}}}),
    ]);
    json["scenes"][0]["nodes"] = json!([0, 1, 3, 4]);
    let scene = load_json(&json).unwrap();
    assert!(
        scene
            .warnings
            .iter()
            .all(|w| !w.contains("KHR_lights_punctual"))
    );
    let lights = &scene.lights.punctual;
    assert_eq!(lights.len(), 3);
    let bulb = &lights[0];
    assert_eq!(bulb.name, "Bulb");
    assert_eq!(bulb.kind, LightKind::Point);
    assert!((bulb.position - DVec3::new(1.5, 2.0, 3.0)).length() < 1e-12);
    assert_eq!(bulb.intensity, DVec3::new(10.0, 5.0, 2.5));
    assert_eq!(bulb.range, Some(4.0));
    assert_eq!(lights[1].kind, LightKind::Directional);
    assert_eq!(lights[1].name, "directional light 1");
    assert!(
        (lights[1].direction - DVec3::NEG_Y).length() < 1e-6,
        "{}",
        lights[1].direction
    );
    let LightKind::Spot {
        cos_inner,
        cos_outer,
    } = lights[2].kind
    else {
        panic!("{:?}", lights[2].kind)
    };
    assert!((cos_inner - 0.2f64.cos()).abs() < 1e-6 && (cos_outer - 0.5f64.cos()).abs() < 1e-6);
    assert!((lights[2].direction - DVec3::NEG_Z).length() < 1e-12);
    // The bake drops the lights, and with them the nodes' references.
    let source = scene.source.as_ref().unwrap();
    assert!(source.json.nodes.iter().all(|n| n.extensions.is_none()));

    // Lights alone light a scene.
    json["materials"][0]["emissiveFactor"] = json!([0.0, 0.0, 0.0]);
    assert!(scene.patches.iter().any(|p| p.is_emitter()));
    let unlit = load_json(&json).unwrap();
    assert!(unlit.patches.iter().all(|p| !p.is_emitter()) && unlit.lights.punctual.len() == 3);

    // What the spec forbids is an error naming the light.
    for (field, value, needle) in [
        (
            "spot",
            json!({"innerConeAngle": 0.6, "outerConeAngle": 0.5}),
            "cone angles",
        ),
        ("range", json!(0.0), "range"),
        ("intensity", json!(-1.0), "intensity"),
    ] {
        let mut bad = json.clone();
        bad["extensions"]["KHR_lights_punctual"]["lights"][2][field] = value;
        let message = scene_error(load_json(&bad));
        assert!(
            message.contains("light 2") && message.contains(needle),
            "{message}"
        );
    }
    let mut bad = json.clone();
    bad["nodes"][4]["extensions"]["KHR_lights_punctual"]["light"] = json!(7);
    let message = scene_error(load_json(&bad));
    assert!(
        message.contains("nodes[4]") && message.contains("light"),
        "{message}"
    );

    // With no light of any kind, the message says which kinds were looked for.
    let mut g = Gltf::default();
    let m = g.grey();
    let mesh = g.quad_mesh(None, Some(m));
    g.root(json!({"mesh": mesh}));
    let message = g.load().unwrap_err().to_string();
    assert!(
        message.contains("emissiveFactor")
            && message.contains("KHR_lights_punctual")
            && message.contains("--sky"),
        "{message}"
    );
}

#[test]
fn node_cycles_and_shared_children_are_errors() {
    let (_, mut json) = valid_json();
    // Node 0 (the quad) gets a parent 1 that is also its child.
    json["nodes"] =
        json!([{"name": "F", "mesh": 0, "children": [1]}, {"name": "Loop", "children": [0]}]);
    let message = scene_error(load_json(&json));
    assert!(message.contains("reached twice"), "{message}");
    // A self-loop.
    json["nodes"] = json!([{"name": "F", "mesh": 0, "children": [0]}]);
    assert!(scene_error(load_json(&json)).contains("reached twice"));
    // The same child under two parents would duplicate geometry.
    json["nodes"] = json!([{"mesh": 0}, {"children": [0]}, {"children": [0]}]);
    json["scenes"] = json!([{"nodes": [1, 2]}]);
    assert!(scene_error(load_json(&json)).contains("reached twice"));
}

#[test]
fn declared_counts_beyond_the_data_are_refused_without_allocating() {
    let (_, mut json) = valid_json();
    // POSITION claims four billion vertices in a 48-byte view.
    json["accessors"][0]["count"] = json!(4_000_000_000u64);
    let message = scene_error(load_json(&json));
    assert!(
        message.contains("mesh 'Floor' primitive 0") && message.contains("exceed"),
        "{message}"
    );
    // Indices claim more than their view holds.
    let (_, mut json) = valid_json();
    json["accessors"][2]["count"] = json!(usize::MAX / 2);
    assert!(scene_error(load_json(&json)).contains("exceed"));
    // A stride shorter than the element.
    let (_, mut json) = valid_json();
    json["bufferViews"][0]["byteStride"] = json!(4);
    assert!(scene_error(load_json(&json)).contains("stride"));
    // A buffer declaring more bytes than its data holds.
    let (_, mut json) = valid_json();
    json["buffers"][0]["byteLength"] = json!(1u64 << 40);
    scene_error(load_json(&json));
    // A sparse accessor without a view declaring billions of zeros.
    let (_, mut json) = valid_json();
    json["accessors"][0] = json!({"componentType": 5126, "count": 3_000_000_000u64, "type": "VEC3",
        "min": [0, 0, 0], "max": [1, 1, 0],
        "sparse": {"count": 1, "indices": {"bufferView": 2, "componentType": 5123},
            "values": {"bufferView": 0}}});
    assert!(scene_error(load_json(&json)).contains("without a buffer view"));
}

/// What the specification forbids is refused, naming what is wrong.
#[test]
fn specification_violations_are_refused() {
    // A sparse index at or above the accessor's count: the index view read
    // as 32-bit indices holds 0x00010000 and up.
    let (_, mut json) = valid_json();
    let view = json["accessors"][2]["bufferView"].clone();
    json["accessors"][0]["sparse"] = json!({"count": 1,
        "indices": {"bufferView": view, "componentType": 5125},
        "values": {"bufferView": json["accessors"][0]["bufferView"].clone()}});
    let message = scene_error(load_json(&json));
    assert!(
        message.contains("sparse indices must increase and stay below"),
        "{message}"
    );
    // A buffer view beyond its buffer's declared byteLength (the data
    // itself is long enough).
    let (_, mut json) = valid_json();
    let shorter = json["buffers"][0]["byteLength"].as_u64().unwrap() - 4;
    json["buffers"][0]["byteLength"] = json!(shorter);
    let message = scene_error(load_json(&json));
    assert!(message.contains("exceeds buffer 0"), "{message}");
    // A major version other than 2.
    let (_, mut json) = valid_json();
    json["asset"]["version"] = json!("3.0");
    assert!(scene_error(load_json(&json)).contains("asset.version is '3.0'"));
    // A matrix beside translation/rotation/scale.
    let (_, mut json) = valid_json();
    json["nodes"][0]["matrix"] = json!([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
    json["nodes"][0]["translation"] = json!([0, 1, 0]);
    assert!(scene_error(load_json(&json)).contains("both a matrix and"));
    // Matrices that no translation, rotation and scale make: a projective
    // last row (m33 = -1 flipped a receiver, and the run reported success),
    // and a shear. A mirror (negative scale) is decomposable.
    for (matrix, why) in [
        (
            json!([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1]),
            "a projection",
        ),
        (
            json!([1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
            "a projection",
        ),
        (
            json!([1, 0, 0, 0, 0.5, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
            "a shear",
        ),
    ] {
        let (_, mut json) = valid_json();
        json["nodes"][0]["matrix"] = matrix;
        let message = scene_error(load_json(&json));
        assert!(
            message.contains("not decomposable") && message.contains(why),
            "{message}"
        );
    }
    let (_, mut json) = valid_json();
    json["nodes"][0]["matrix"] = json!([-2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
    load_json(&json).expect("a mirror is a negative scale");
    // A GLB whose header length is not the file's.
    let (g, _) = valid_json();
    let mut longer = g.glb();
    longer.extend_from_slice(&[0; 4]);
    let message = scene_error(load_scene_from_slice(
        &longer,
        None,
        &LoadOptions::default(),
    ));
    assert!(message.contains("GLB header declares length"), "{message}");
}

#[test]
fn dangling_references_are_errors_not_panics() {
    let (_, mut json) = valid_json();
    json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99);
    assert!(scene_error(load_json(&json)).contains("POSITION accessor 99"));
    let (_, mut json) = valid_json();
    json["nodes"][0]["mesh"] = json!(7);
    assert!(scene_error(load_json(&json)).contains("not a valid glTF"));
    // Found by fuzzing: an image with neither uri nor bufferView, and one
    // with a bufferView but no mimeType, made `gltf` unwrap None.
    for image in [json!({"name": "nothing"}), json!({"bufferView": 0})] {
        let (_, mut json) = valid_json();
        json["images"] = json!([image]);
        assert!(scene_error(load_json(&json)).contains("image 0 needs"));
    }
    // A camera whose type names a missing block.
    let (_, mut json) = valid_json();
    json["cameras"] = json!([{"type": "perspective", "orthographic":
        {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}]);
    assert!(scene_error(load_json(&json)).contains("camera 0 lacks"));
    let (_, mut json) = valid_json();
    json["buffers"][0]["uri"] = json!("%ff%fe.bin");
    scene_error(load_scene_from_slice(
        &serde_json::to_vec(&json).unwrap(),
        Some(Path::new(".")),
        &LoadOptions::default(),
    ));
}

#[test]
fn undecodable_texture_names_the_image() {
    let mut g = Gltf::default();
    let view = g.view(b"definitely not a png");
    g.images
        .push(json!({"bufferView": view, "mimeType": "image/png", "name": "brick"}));
    g.textures.push(json!({"source": 0}));
    let m = g.material(json!({"name": "Wall", "emissiveFactor": [1, 1, 1],
        "pbrMetallicRoughness": {"metallicFactor": 0.0, "baseColorTexture": {"index": 0}}}));
    let mesh = g.quad_mesh(Some("WallMesh"), Some(m));
    g.root(json!({"mesh": mesh}));
    let message = scene_error(g.load());
    assert!(
        message.contains("image 0 ('brick')") && message.contains("decode"),
        "{message}"
    );
}

// The hostile-input suite, library level (issue 7). The command-line side,
// one `error:` line and exit code 1, is in tests/cli.rs.

/// A scene of one emitting quad at `quad` (mesh 'Far') under a node with
/// `node` fields.
fn scene_with_positions(quad: [[f32; 3]; 4], node: Value) -> Gltf {
    let mut g = Gltf::default();
    let m = g.emitter();
    let pos = g.positions(&quad);
    let idx = g.indices(&QUAD_INDICES);
    let mesh = g.mesh(
        Some("Far"),
        vec![json!({"attributes": {"POSITION": pos}, "indices": idx, "material": m})],
    );
    let mut node = node;
    node["mesh"] = json!(mesh);
    g.root(node);
    g
}

#[test]
fn hostile_huge_finite_coordinates_are_refused_before_the_bvh() {
    // Finite but near f32::MAX: obvhs panicked building the BVH.
    let huge = QUAD.map(|p| p.map(|c| c * 3e38));
    let message = scene_error(scene_with_positions(huge, json!({})).load());
    assert!(
        message.starts_with("mesh 'Far' primitive 0: vertex 1")
            && message.contains("beyond the supported"),
        "{message}"
    );
    // Moderate positions that a node scale carries past the bound.
    let scaled = scene_with_positions(QUAD, json!({"scale": [1e13, 1e13, 1e13]}));
    assert!(scene_error(scaled.load()).contains("mesh 'Far' primitive 0"));
    // Just inside the bound: loads, and the BVH and a solve survive it.
    let big = scene_with_positions(QUAD, json!({"scale": [9e11, 9e11, 9e11]}));
    let scene = big.load().expect("coordinates within the bound load");
    let mut settings = nusselt::pipeline::SolveSettings::default();
    settings.hierarchical.accuracy = nusselt::hierarchical::Accuracy::preview();
    settings.view.width = Some(8);
    settings.view.height = Some(8);
    let run = nusselt::pipeline::solve(
        &scene,
        &settings,
        &nusselt::util::progress::Progress::new(false),
    )
    .expect("a 9e11 m scene solves");
    assert!(run.frame.pixels.iter().flatten().all(|c| c.is_finite()));
    // The scene model refuses such coordinates too, naming the surface.
    let mut tris: Vec<nusselt::scene::InputTriangle> = Vec::new();
    for (k, corner) in [[0usize, 1, 2], [0, 2, 3]].iter().enumerate() {
        tris.push(nusselt::scene::InputTriangle {
            positions: corner.map(|i| DVec3::from_array(QUAD[i].map(f64::from)) * 3e38),
            material: 0,
            surface: 0,
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::splat(k as f64),
            origin: Default::default(),
        });
    }
    let material = nusselt::scene::Material {
        name: "m".into(),
        reflectance: DVec3::splat(0.5),
        emitted_radiance: DVec3::ONE,
        double_sided: false,
    };
    let surface = nusselt::scene::Surface {
        name: "Giant".into(),
        node: 0,
    };
    match Scene::build(tris, vec![material], vec![surface], vec![], vec![]) {
        Err(e) => assert!(e.to_string().contains("surface 'Giant'"), "{e}"),
        Ok(_) => panic!("3e38 m coordinates were accepted"),
    }
}

#[test]
fn hostile_wrong_accessor_types_name_the_primitive() {
    // (accessor to damage, field changes, expected words)
    // `gltf`'s validation refuses POSITION that is not a 3-vector (by its
    // min/max) and names it by JSON path; the loader refuses the rest.
    let by_gltf = r#"not a valid glTF file: meshes[0].primitives[0].attributes["POSITION"]"#;
    let cases: [(usize, Value, &str); 5] = [
        (
            0,
            json!({"type": "VEC2", "min": [0, 0], "max": [1, 1]}),
            by_gltf,
        ),
        (
            0,
            json!({"type": "SCALAR", "min": [0], "max": [1]}),
            by_gltf,
        ),
        (
            0,
            json!({"componentType": 5121}),
            "mesh 'Floor' primitive 0: POSITION accessor 0 has type Vec3 U8",
        ),
        (
            2,
            json!({"componentType": 5126}),
            "mesh 'Floor' primitive 0: indices accessor 2 has type Scalar F32",
        ),
        (
            2,
            json!({"type": "VEC2"}),
            "mesh 'Floor' primitive 0: indices accessor 2 has type Vec2",
        ),
    ];
    for (accessor, change, needle) in cases {
        let (_, mut json) = valid_json();
        for (k, v) in change.as_object().unwrap() {
            json["accessors"][accessor][k] = v.clone();
        }
        let message = scene_error(load_json(&json));
        assert!(message.contains(needle), "{needle}: {message}");
    }
}

#[test]
fn hostile_very_deep_node_graph_loads_without_recursion() {
    const DEPTH: usize = 100_000;
    let (_, mut json) = valid_json();
    // Node k has child k + 1; the quad hangs at the bottom, each level
    // shifted by 1 µm along z.
    let mut nodes: Vec<Value> = (0..DEPTH)
        .map(|k| json!({"children": [k + 1], "translation": [0.0, 0.0, 1e-6]}))
        .collect();
    nodes.push(json!({"name": "Bottom", "mesh": 0}));
    json["nodes"] = json!(nodes);
    json["scenes"] = json!([{"nodes": [0]}]);
    let scene = load_json(&json).expect("a deep but acyclic hierarchy loads");
    assert_eq!(scene.surfaces.len(), 1);
    assert_eq!(scene.surfaces[0].name, "Bottom");
    let z = scene.patches[0].corners[0].z;
    assert!((z - DEPTH as f64 * 1e-6).abs() < 1e-9, "z = {z}");
    // The same depth closed into a cycle is found without recursion too.
    let mut cyclic = json.clone();
    cyclic["nodes"][DEPTH]["children"] = json!([0]);
    assert!(scene_error(load_json(&cyclic)).contains("reached twice"));
}

/// The valid one-quad scene with its buffer in an external file
/// `scene.bin` of `bin` bytes, declared `byte_length` long.
fn external_buffer_scene(dir: &Path, bin: &[u8], byte_length: u64) -> std::path::PathBuf {
    let (_, mut json) = valid_json();
    std::fs::write(dir.join("scene.bin"), bin).unwrap();
    json["buffers"][0] = json!({"uri": "scene.bin", "byteLength": byte_length});
    let path = dir.join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    path
}

#[test]
fn hostile_missing_short_oversized_and_special_buffers() {
    let dir = tempfile::tempdir().unwrap();
    let (g, _) = valid_json();
    let bin = g.bin.clone();
    let path = external_buffer_scene(dir.path(), &bin, bin.len() as u64);
    load_scene(&path, &LoadOptions::default()).expect("the intact external buffer loads");
    let load = |path: &Path| scene_error(load_scene(path, &LoadOptions::default()));

    // Missing file: named.
    std::fs::remove_file(dir.path().join("scene.bin")).unwrap();
    let message = load(&path);
    assert!(
        message.contains("buffer 0") && message.contains("scene.bin"),
        "{message}"
    );
    // Shorter than declared.
    let path = external_buffer_scene(dir.path(), &bin[..bin.len() - 8], bin.len() as u64);
    assert!(load(&path).contains("cannot load buffers"));
    // A declared length of a petabyte is not trusted (nor allocated).
    let path = external_buffer_scene(dir.path(), &bin, 1_000_000_000_000_000);
    assert!(load(&path).contains("cannot load buffers"));
    // A device instead of a file would be read without end.
    let (_, mut json) = valid_json();
    let device = dir.path().join("zero");
    std::os::unix::fs::symlink("/dev/zero", &device).unwrap();
    let from_slice = |json: &serde_json::Value, base: &Path| {
        scene_error(load_scene_from_slice(
            &serde_json::to_vec(json).unwrap(),
            Some(base),
            &LoadOptions::default(),
        ))
    };
    // Through a link inside the folder: refused as leading out of it.
    json["buffers"][0]["uri"] = json!("zero");
    let message = from_slice(&json, dir.path());
    assert!(message.contains("through a link"), "{message}");
    // From a folder where it is a device node itself: not a regular file.
    json["buffers"][0]["uri"] = json!("zero");
    let message = from_slice(&json, Path::new("/dev"));
    assert!(message.contains("not a regular file"), "{message}");
    // Untrusted scenes read nothing outside their folder, and say so
    // without showing what is there.
    let secret = dir.path().join("secret.bin");
    std::fs::write(&secret, b"root:x:0:0:root:/root:/bin/bash\n").unwrap();
    let inner = dir.path().join("scene");
    std::fs::create_dir(&inner).unwrap();
    for (uri, needle) in [
        ("../secret.bin", "leads out of the scene's folder"),
        ("a/../../secret.bin", "leads out of the scene's folder"),
        ("%2E%2E/secret.bin", "leads out of the scene's folder"),
        (secret.to_str().unwrap(), "absolute path"),
        ("file:///etc/passwd", "file: URI"),
        ("file:../secret.bin", "file: URI"),
    ] {
        json["buffers"][0]["uri"] = json!(uri);
        let message = from_slice(&json, &inner);
        assert!(message.contains(needle), "{uri}: {message}");
        assert!(!message.contains("root"), "{uri}: {message}");
    }
    // So would a folder.
    json["buffers"][0]["uri"] = json!(".");
    let message = from_slice(&json, dir.path());
    assert!(message.contains("not a regular file"), "{message}");
}

#[test]
fn hostile_bad_data_uris_are_errors() {
    let (g, _) = valid_json();
    let encoded = base64::Engine::encode(&base64::engine::general_purpose::STANDARD, &g.bin);
    let len = g.bin.len();
    let with_uri = |uri: String| {
        let (_, mut json) = valid_json();
        json["buffers"][0] = json!({"uri": uri, "byteLength": len});
        scene_error(load_json(&json))
    };
    let bad_base64 = with_uri(format!(
        "data:application/octet-stream;base64,{}",
        encoded.replace(['A', 'g'], "*")
    ));
    assert!(bad_base64.contains("buffer"), "{bad_base64}");
    let wrong_mime = with_uri(format!("data:text/plain;base64,{encoded}"));
    assert!(
        wrong_mime.contains("buffer 0") && wrong_mime.contains("'text/plain'"),
        "{wrong_mime}"
    );
    let not_base64 = with_uri("data:application/octet-stream,abc".into());
    assert!(not_base64.contains("not base64"), "{not_base64}");
    // The accepted alternative MIME type of the specification loads.
    let (_, mut json) = valid_json();
    json["buffers"][0]["uri"] = json!(format!("data:application/gltf-buffer;base64,{encoded}"));
    load_json(&json).expect("application/gltf-buffer is a buffer MIME type");
    // MIME types are case-insensitive.
    json["buffers"][0]["uri"] = json!(format!("data:Application/Octet-Stream;base64,{encoded}"));
    load_json(&json).expect("MIME types ignore case");
    // An image data URI that claims to be HTML.
    let (_, mut json) = valid_json();
    json["images"] = json!([{"uri": "data:text/html;base64,PGh0bWw+"}]);
    let message = scene_error(load_json(&json));
    assert!(message.contains("image 0"), "{message}");
}

#[test]
fn hostile_giant_declared_texture_is_refused_from_its_header() {
    // A PNG whose header claims 100 000 × 100 000 texels (30 GB decoded)
    // followed by no pixel data: refused before any pixel buffer exists.
    let mut png_bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut png_bytes, 100_000, 100_000);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().unwrap();
        // The header is read up to the first data chunk: give it one.
        writer.write_chunk(png::chunk::IDAT, &[0x78, 0x9c]).unwrap();
        drop(writer);
    }
    let mut g = Gltf::default();
    let view = g.view(&png_bytes);
    g.images
        .push(json!({"bufferView": view, "mimeType": "image/png", "name": "giant"}));
    g.textures.push(json!({"source": 0}));
    let m = g.material(json!({"name": "Wall", "emissiveFactor": [1, 1, 1],
        "pbrMetallicRoughness": {"metallicFactor": 0.0, "baseColorTexture": {"index": 0}}}));
    let mesh = g.quad_mesh(Some("WallMesh"), Some(m));
    g.root(json!({"mesh": mesh}));
    let started = std::time::Instant::now();
    let message = scene_error(g.load());
    eprintln!(
        "giant texture refused in {:.3} s",
        started.elapsed().as_secs_f64()
    );
    assert!(
        message.contains("image 0 ('giant')") && message.contains("100000×100000"),
        "{message}"
    );
    // No decoding happened: the message is the header check's own (the
    // declared texel count against the limit), which runs before any
    // pixel is decoded.
    assert!(message.contains("texels exceed the limit"), "{message}");
}
