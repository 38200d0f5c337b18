//! Turns a [`SceneDef`] into a glTF 2.0 document (`gltf::json::Root`) and its
//! binary buffer.
//!
//! Invariants of the output: one buffer; per mesh one triangle primitive with
//! a welded `POSITION` accessor (with `min`/`max`) and `u32` indices, each in
//! its own 4-byte-aligned buffer view; positions rounded to the micrometre so
//! that the bytes do not depend on the platform's last-bit trigonometry;
//! materials with `metallicFactor` 0 and `roughnessFactor` 1; the
//! `KHR_materials_emissive_strength` extension listed in `extensionsUsed`
//! exactly when a material carries a strength; the scene's punctual lights
//! in the root's `KHR_lights_punctual.lights` (no `range`), each placed by a
//! node, and that extension listed in `extensionsUsed` (never in
//! `extensionsRequired`) exactly when there is a light.

use std::collections::{BTreeMap, HashMap};

use anyhow::{Result, bail};
use base64::Engine as _;
use glam::DVec3;
use gltf::json::{self, validation::Checked::Valid, validation::USize64};

use super::model::{BufferStorage, LightKind, SceneDef};

/// Rounds a length in metres to the micrometre and stores it as `f32`.
pub fn quantize(v: f64) -> f32 {
    let r = (v * 1e6).round() / 1e6;
    // Adding zero turns −0 into +0, so the bytes never hold a signed zero.
    (r + 0.0) as f32
}

fn quantize_vec(v: DVec3) -> [f32; 3] {
    [quantize(v.x), quantize(v.y), quantize(v.z)]
}

/// The welded vertices and the index list of one mesh.
pub struct IndexedMesh {
    pub positions: Vec<[f32; 3]>,
    pub indices: Vec<u32>,
}

/// Welds equal (quantized) positions in order of first use.
pub fn index_mesh(name: &str, triangles: &[[DVec3; 3]]) -> Result<IndexedMesh> {
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut lookup: HashMap<[u32; 3], u32> = HashMap::new();
    let mut indices = Vec::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        let mut ids = [0u32; 3];
        for (slot, corner) in ids.iter_mut().zip(tri) {
            let p = quantize_vec(*corner);
            let key = p.map(f32::to_bits);
            *slot = *lookup.entry(key).or_insert_with(|| {
                positions.push(p);
                (positions.len() - 1) as u32
            });
        }
        if ids[0] == ids[1] || ids[1] == ids[2] || ids[0] == ids[2] {
            bail!("mesh {name}: triangle {t} collapses to a line after rounding");
        }
        indices.extend_from_slice(&ids);
    }
    Ok(IndexedMesh { positions, indices })
}

fn pad_to_4(bytes: &mut Vec<u8>) {
    while !bytes.len().is_multiple_of(4) {
        bytes.push(0);
    }
}

fn push_view(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    data: &[u8],
    target: json::buffer::Target,
    name: String,
) -> json::Index<json::buffer::View> {
    pad_to_4(bin);
    let offset = bin.len();
    bin.extend_from_slice(data);
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64(data.len() as u64),
        byte_offset: Some(USize64(offset as u64)),
        byte_stride: None,
        name: Some(name),
        target: Some(Valid(target)),
        extensions: None,
        extras: Default::default(),
    })
}

/// The `KHR_lights_punctual` light objects of `scene`, checked against the
/// extension's ranges.
fn lights(scene: &SceneDef) -> Result<Vec<json::extensions::scene::khr_lights_punctual::Light>> {
    use json::extensions::scene::khr_lights_punctual::{Light, Spot, Type};
    scene
        .lights
        .iter()
        .enumerate()
        .map(|(k, l)| {
            if l.color.iter().any(|&c| !(0.0..=1.0).contains(&c)) {
                bail!("light {}: color must lie in [0, 1]", l.name);
            }
            if !(l.intensity.is_finite() && l.intensity >= 0.0) {
                bail!(
                    "light {}: intensity must be finite and non-negative",
                    l.name
                );
            }
            if !scene.nodes.iter().any(|n| n.light == Some(k)) {
                bail!("light {}: no node places it", l.name);
            }
            let (type_, spot) = match l.kind {
                LightKind::Point => (Type::Point, None),
                LightKind::Directional => (Type::Directional, None),
                LightKind::Spot {
                    inner_cone_angle,
                    outer_cone_angle,
                } => {
                    let ok = 0.0 <= inner_cone_angle
                        && inner_cone_angle < outer_cone_angle
                        && outer_cone_angle <= std::f64::consts::FRAC_PI_2;
                    if !ok {
                        bail!("light {}: need 0 ≤ inner < outer ≤ π/2 cone angles", l.name);
                    }
                    let spot = Spot {
                        inner_cone_angle: inner_cone_angle as f32,
                        outer_cone_angle: outer_cone_angle as f32,
                    };
                    (Type::Spot, Some(spot))
                }
            };
            Ok(Light {
                color: l.color.map(|c| c as f32),
                extensions: None,
                extras: Default::default(),
                intensity: l.intensity as f32,
                name: Some(l.name.to_owned()),
                range: None,
                spot,
                type_: Valid(type_),
            })
        })
        .collect()
}

fn f32s(v: &[f32]) -> serde_json::Value {
    serde_json::Value::from(v.iter().map(|&x| f64::from(x)).collect::<Vec<_>>())
}

/// The glTF document of `scene` and the bytes of its single buffer.
pub fn encode(scene: &SceneDef) -> Result<(json::Root, Vec<u8>)> {
    let mut root = json::Root {
        asset: json::Asset {
            generator: Some("nusselt gen-scenes (tools/gen_scenes.rs)".to_owned()),
            version: "2.0".to_owned(),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut bin = Vec::new();

    let mut uses_strength = false;
    for m in &scene.materials {
        if m.reflectance.iter().any(|&c| !(0.0..1.0).contains(&c)) {
            bail!("material {}: reflectance must lie in [0, 1)", m.name);
        }
        let rgb = m.reflectance.map(|c| c as f32);
        let mut material = json::Material {
            name: Some(m.name.to_owned()),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([
                    rgb[0], rgb[1], rgb[2], 1.0,
                ]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(1.0),
                ..Default::default()
            },
            double_sided: false,
            ..Default::default()
        };
        if let Some(e) = m.emission {
            if e.factor.iter().any(|&c| !(0.0..=1.0).contains(&c)) {
                bail!("material {}: emissiveFactor must lie in [0, 1]", m.name);
            }
            material.emissive_factor = json::material::EmissiveFactor(e.factor.map(|c| c as f32));
            if let Some(s) = e.strength {
                uses_strength = true;
                material.extensions = Some(json::extensions::material::Material {
                    emissive_strength: Some(json::extensions::material::EmissiveStrength {
                        emissive_strength: json::extensions::material::EmissiveStrengthFactor(
                            s as f32,
                        ),
                    }),
                    ..Default::default()
                });
            }
        }
        root.push(material);
    }
    if uses_strength {
        root.extensions_used
            .push("KHR_materials_emissive_strength".to_owned());
    }

    for mesh in &scene.meshes {
        if mesh.material >= scene.materials.len() {
            bail!("mesh {}: no material {}", mesh.name, mesh.material);
        }
        let indexed = index_mesh(&mesh.name, &mesh.triangles)?;
        let mut min = [f32::INFINITY; 3];
        let mut max = [f32::NEG_INFINITY; 3];
        for p in &indexed.positions {
            for a in 0..3 {
                min[a] = min[a].min(p[a]);
                max[a] = max[a].max(p[a]);
            }
        }
        let position_bytes: Vec<u8> = indexed
            .positions
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let index_bytes: Vec<u8> = indexed
            .indices
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let position_view = push_view(
            &mut root,
            &mut bin,
            &position_bytes,
            json::buffer::Target::ArrayBuffer,
            format!("{} positions", mesh.name),
        );
        let index_view = push_view(
            &mut root,
            &mut bin,
            &index_bytes,
            json::buffer::Target::ElementArrayBuffer,
            format!("{} indices", mesh.name),
        );
        let positions = root.push(json::Accessor {
            buffer_view: Some(position_view),
            byte_offset: Some(USize64(0)),
            count: USize64(indexed.positions.len() as u64),
            component_type: Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::F32,
            )),
            extensions: None,
            extras: Default::default(),
            type_: Valid(json::accessor::Type::Vec3),
            min: Some(f32s(&min)),
            max: Some(f32s(&max)),
            name: Some(format!("{} POSITION", mesh.name)),
            normalized: false,
            sparse: None,
        });
        let indices = root.push(json::Accessor {
            buffer_view: Some(index_view),
            byte_offset: Some(USize64(0)),
            count: USize64(indexed.indices.len() as u64),
            component_type: Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::U32,
            )),
            extensions: None,
            extras: Default::default(),
            type_: Valid(json::accessor::Type::Scalar),
            min: None,
            max: None,
            name: Some(format!("{} indices", mesh.name)),
            normalized: false,
            sparse: None,
        });
        let mut attributes = BTreeMap::new();
        attributes.insert(Valid(json::mesh::Semantic::Positions), positions);
        root.push(json::Mesh {
            name: Some(mesh.name.clone()),
            primitives: vec![json::mesh::Primitive {
                attributes,
                indices: Some(indices),
                material: Some(json::Index::new(mesh.material as u32)),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
                extensions: None,
                extras: Default::default(),
            }],
            weights: None,
            extensions: None,
            extras: Default::default(),
        });
    }

    for node in &scene.nodes {
        let camera = node.camera.map(|c| {
            root.push(json::Camera {
                name: Some(node.name.clone()),
                type_: Valid(json::camera::Type::Perspective),
                perspective: Some(json::camera::Perspective {
                    aspect_ratio: Some(c.aspect_ratio as f32),
                    yfov: c.yfov as f32,
                    zfar: None,
                    znear: c.znear as f32,
                    extensions: None,
                    extras: Default::default(),
                }),
                orthographic: None,
                extensions: None,
                extras: Default::default(),
            })
        });
        if let Some(m) = node.mesh.filter(|&m| m >= scene.meshes.len()) {
            bail!("node {}: no mesh {m}", node.name);
        }
        if let Some(&c) = node.children.iter().find(|&&c| c >= scene.nodes.len()) {
            bail!("node {}: no child node {c}", node.name);
        }
        if let Some(k) = node.light.filter(|&k| k >= scene.lights.len()) {
            bail!("node {}: no light {k}", node.name);
        }
        root.push(json::Node {
            name: Some(node.name.clone()),
            camera,
            mesh: node.mesh.map(|m| json::Index::new(m as u32)),
            translation: node.translation.map(quantize_vec),
            scale: node.scale.map(quantize_vec),
            rotation: node.rotation.map(|q| {
                // Rounded to 1e-9 (far below f32 precision near 1) so that
                // an exact 180° turn is written as (0, 1, 0, 0).
                let q = q.normalize().to_array();
                json::scene::UnitQuaternion(q.map(|c| ((c * 1e9).round() / 1e9 + 0.0) as f32))
            }),
            children: (!node.children.is_empty()).then(|| {
                node.children
                    .iter()
                    .map(|&c| json::Index::new(c as u32))
                    .collect()
            }),
            extensions: node.light.map(|k| json::extensions::scene::Node {
                khr_lights_punctual: Some(
                    json::extensions::scene::khr_lights_punctual::KhrLightsPunctual {
                        light: json::Index::new(k as u32),
                    },
                ),
            }),
            ..Default::default()
        });
    }

    if !scene.lights.is_empty() {
        root.extensions_used.push("KHR_lights_punctual".to_owned());
        root.extensions = Some(json::extensions::Root {
            khr_lights_punctual: Some(json::extensions::root::KhrLightsPunctual {
                lights: lights(scene)?,
            }),
        });
    }

    let scene_index = root.push(json::Scene {
        name: Some(scene.stem.clone()),
        nodes: scene
            .roots
            .iter()
            .map(|&n| json::Index::new(n as u32))
            .collect(),
        extensions: None,
        extras: Default::default(),
    });
    root.scene = Some(scene_index);

    pad_to_4(&mut bin);
    let uri = match scene.storage {
        BufferStorage::External => format!("{}.bin", scene.stem),
        BufferStorage::Embedded => format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&bin)
        ),
    };
    root.push(json::Buffer {
        byte_length: USize64(bin.len() as u64),
        name: Some(scene.stem.clone()),
        uri: Some(uri),
        extensions: None,
        extras: Default::default(),
    });
    Ok((root, bin))
}
