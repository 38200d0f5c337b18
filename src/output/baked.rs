//! `baked.gltf` + `baked.bin` (or, the same document and buffer in one
//! binary glTF, `baked.glb`): the output mesh with its radiosity baked into
//! vertex colours, laid out on the input scene's own nodes. The only writer
//! of glTF (through `gltf::json` and `gltf::Glb`).
//!
//! Layout ([`BakeLayout`] decides which output vertex goes where):
//!
//! ```text
//! nodes, scenes, cameras, textures, samplers: the input's, same indices
//!   (a node keeps its name, children, transform, camera and extras; its
//!   mesh is replaced by the bake's mesh for that node, one per node even
//!   when the input instanced a mesh, since each instance's light differs)
//! materials[0..M]   the input's materials as they were (textures included)
//! materials[M..]    one KHR_materials_unlit material per scene material,
//!                   white, single-sided, extras.source_material = its input
//!                   material's index (null for glTF's default material)
//! images            the input's, their bytes embedded as buffer views
//! mesh per node: one primitive per input primitive (and scene material)
//!   POSITION, NORMAL   f32 VEC3, in the node's own frame
//!   COLOR_0            f32 VEC3, clamp(B / π × exposure, 0, 1), linear
//!   _RADIOSITY         f32 VEC3, B (W/m², linear, unclamped)
//!   _IRRADIANCE        f32 VEC3, H (W/m², linear; B = E + ρ H)
//!   TEXCOORD_0         f32 VEC2, the input's, interpolated at the vertex
//!                      (when the input primitive has it; else, with a
//!                      lightmap, a copy of TEXCOORD_1: sets run from 0)
//!   TEXCOORD_1         f32 VEC2, with a lightmap: its atlas coordinates
//!                      (each baked material's emissiveTexture reads the
//!                      atlas's display PNG through it)
//!   indices            u32
//!   extras: source_primitive, and solution_vertices / solution_triangles:
//!           [start, count] runs into solution.exr's vertex and triangle
//!           order (the patch/node table)
//! baked.bin: one buffer, every view 4-byte aligned, no stride sharing
//! ```
//!
//! `asset.extras` records the exposure; `asset.generator` is "nusselt
//! VERSION". Without an input document (a scene built in code, or
//! [`BakeLayout::flat`]) each surface, or the whole mesh, is one node.
//!
//! Invariants: every output vertex and triangle appears in exactly one
//! primitive, so the vertex count over all primitives equals
//! `solution.exr`'s; a vertex's position through its node's world transform
//! is its `solution.exr` position (to f32 rounding); triangles are
//! counter-clockwise seen from the front once the node transform is
//! applied (the winding is swapped in nodes that mirror).

use std::collections::{BTreeMap, HashMap};
use std::f32::consts::PI;
use std::sync::Arc;

use glam::{DMat4, Vec2, Vec3};
use gltf::json;
use json::accessor::{ComponentType, GenericComponentType, Type};
use json::buffer::Target;
use json::mesh::{Mode, Semantic};
use json::validation::{Checked::Valid, USize64};

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;
use crate::scene::{Scene, SourceDocument, interpolate_on_patch};

/// What the encoder names in its errors.
const BAKED: &str = "the baked glTF";
/// The glTF extension that makes viewers show vertex colours unshaded.
const UNLIT: &str = "KHR_materials_unlit";
/// Extensions of the input that may remain in the copied materials,
/// textures and images (the loader's `gltf` build parses these; others are
/// dropped when it reads the file).
const KEPT_EXTENSIONS: &[&str] = &[
    UNLIT,
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
];
/// Name of the custom attribute holding the radiosity (without the `_`).
pub const RADIOSITY_ATTRIBUTE: &str = "RADIOSITY";
/// Name of the custom attribute holding the irradiance (without the `_`).
pub const IRRADIANCE_ATTRIBUTE: &str = "IRRADIANCE";

/// The displayed colour of a vertex of radiosity `b`: clamp(B / π ×
/// exposure, 0, 1) per channel.
pub fn display_color(b: Vec3, exposure: f32) -> Vec3 {
    (b / PI * exposure).clamp(Vec3::ZERO, Vec3::ONE)
}

/// One primitive of the bake: the output vertices and triangles of one
/// input primitive of one node (and one scene material).
#[derive(Clone, Debug)]
struct Group {
    node: usize,
    primitive: u32,
    material: u32,
    /// Output vertex indices, ascending.
    vertices: Vec<u32>,
    /// Output triangle indices, ascending.
    triangles: Vec<u32>,
}

/// Where each output vertex goes in the bake: which node, primitive and
/// material, and its interpolated `TEXCOORD_0`.
#[derive(Clone, Debug)]
pub struct BakeLayout {
    /// The document copied (its nodes, cameras, materials, textures,
    /// images).
    source: Arc<SourceDocument>,
    /// Names of the scene's materials, one baked material each.
    material_names: Vec<String>,
    groups: Vec<Group>,
    /// Per output vertex, when its input primitive has `TEXCOORD_0`.
    tex_coords: Vec<Option<Vec2>>,
    /// With a lightmap: its coordinates per output vertex and its display
    /// PNG.
    lightmap: Option<(Vec<Vec2>, Vec<u8>)>,
}

impl BakeLayout {
    /// The layout of `mesh`, an output mesh of `scene`, on the scene's
    /// input document (or, for a scene built in code, one node per
    /// surface). Fails when a vertex names a patch the scene lacks or a
    /// node the document did not place.
    pub fn of_scene(scene: &Scene, mesh: &OutputMesh) -> Result<BakeLayout> {
        if let Some(message) = mesh.length_mismatch() {
            return Err(Error::encode(BAKED, message));
        }
        let source = match &scene.source {
            Some(source) => source.clone(),
            None => Arc::new(synthetic_document(
                scene.surfaces.iter().map(|s| s.name.as_str()),
            )),
        };
        let node_of = |surface: u32| match &scene.source {
            Some(_) => scene.surfaces[surface as usize].node,
            None => surface as usize,
        };
        let mut keys: HashMap<(usize, u32, u32), usize> = HashMap::new();
        let mut groups: Vec<Group> = Vec::new();
        let mut vertex_group = Vec::with_capacity(mesh.vertex_count());
        let mut tex_coords = Vec::with_capacity(mesh.vertex_count());
        for (v, (&patch, &position)) in mesh.patch.iter().zip(&mesh.positions).enumerate() {
            let patch = scene.patches.get(patch as usize).ok_or_else(|| {
                Error::encode(
                    BAKED,
                    format!("vertex {v} names patch {patch}, which the scene lacks"),
                )
            })?;
            let first = &scene.triangles[patch.triangles[0] as usize];
            let key = (
                node_of(first.surface),
                first.origin.primitive,
                patch.material,
            );
            let g = *keys.entry(key).or_insert_with(|| {
                groups.push(Group {
                    node: key.0,
                    primitive: key.1,
                    material: key.2,
                    vertices: Vec::new(),
                    triangles: Vec::new(),
                });
                groups.len() - 1
            });
            groups[g].vertices.push(v as u32);
            vertex_group.push(g);
            let triangles = patch.triangles.iter().filter(|&&t| t != u32::MAX);
            tex_coords.push(interpolate_on_patch(
                triangles.map(|&t| &scene.triangles[t as usize]),
                position.as_dvec3(),
                |t| t.origin.tex_coords,
            ));
        }
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let g = vertex_group.get(tri[0] as usize).ok_or_else(|| {
                Error::encode(
                    BAKED,
                    format!("triangle {t} {tri:?} indexes beyond the vertices"),
                )
            })?;
            groups[*g].triangles.push(t as u32);
        }
        for g in &groups {
            if source.world.get(g.node).copied().flatten().is_none() {
                return Err(Error::encode(
                    BAKED,
                    format!("node {} has output vertices but no world transform", g.node),
                ));
            }
        }
        Ok(BakeLayout {
            source,
            material_names: scene.materials.iter().map(|m| m.name.clone()).collect(),
            groups,
            tex_coords,
            lightmap: None,
        })
    }

    /// Adds a lightmap: `uv` per output vertex (`TEXCOORD_1`) and the
    /// atlas's display image `png` (each baked material's emissive
    /// texture).
    pub fn set_lightmap(&mut self, uv: Vec<Vec2>, png: Vec<u8>) {
        self.lightmap = Some((uv, png));
    }

    /// The lightmap's display PNG, when there is one.
    pub fn lightmap_png(&self) -> Option<&[u8]> {
        self.lightmap.as_ref().map(|(_, png)| &png[..])
    }

    /// The whole mesh as one node "baked" and one primitive, in world
    /// space: for a mesh without a scene.
    pub fn flat(mesh: &OutputMesh) -> BakeLayout {
        BakeLayout {
            source: Arc::new(synthetic_document(["baked"])),
            material_names: vec!["baked radiosity".to_string()],
            groups: vec![Group {
                node: 0,
                primitive: 0,
                material: 0,
                vertices: (0..mesh.vertex_count() as u32).collect(),
                triangles: (0..mesh.triangles.len() as u32).collect(),
            }],
            tex_coords: vec![None; mesh.vertex_count()],
            lightmap: None,
        }
    }
}

/// A document of one root node per name, in world space, without
/// materials or cameras.
fn synthetic_document<'a>(names: impl IntoIterator<Item = &'a str>) -> SourceDocument {
    let mut json = json::Root::default();
    let nodes: Vec<_> = names
        .into_iter()
        .map(|name| {
            json.push(json::Node {
                name: Some(name.to_string()),
                ..Default::default()
            })
        })
        .collect();
    let count = nodes.len();
    let scene = json.push(json::Scene {
        extensions: None,
        extras: None,
        name: None,
        nodes,
    });
    json.scene = Some(scene);
    SourceDocument {
        json,
        images: Vec::new(),
        world: vec![Some(DMat4::IDENTITY); count],
        materials: Vec::new(),
    }
}

/// Encodes `mesh`, laid out by `layout`, as (`baked.gltf` JSON bytes,
/// `baked.bin` bytes); the JSON refers to the binary buffer by the relative
/// URI `bin_name`.
///
/// Fails on an empty mesh (glTF has no empty accessors), arrays of unequal
/// length, out-of-range indices, non-finite values, a negative or non-finite
/// exposure, a layout of another mesh, an image of unknown format, or a
/// `bin_name` that is not a plain file name.
pub fn encode_baked_gltf(
    mesh: &OutputMesh,
    layout: &BakeLayout,
    exposure: f32,
    bin_name: &str,
) -> Result<(Vec<u8>, Vec<u8>)> {
    check(mesh, layout, exposure, bin_name)?;
    let (root, bin) = baked_root(mesh, layout, exposure, Some(bin_name))?;
    let mut gltf_bytes = root.to_vec_pretty().map_err(|e| Error::encode(BAKED, e))?;
    gltf_bytes.push(b'\n');
    Ok((gltf_bytes, bin))
}

/// Encodes `mesh` as one binary glTF (`baked.glb`): the same document as
/// [`encode_baked_gltf`]'s, its buffer the GLB's binary chunk. Fails as
/// that does.
pub fn encode_baked_glb(mesh: &OutputMesh, layout: &BakeLayout, exposure: f32) -> Result<Vec<u8>> {
    check(mesh, layout, exposure, "baked.bin")?;
    let (root, bin) = baked_root(mesh, layout, exposure, None)?;
    let json = root.to_vec().map_err(|e| Error::encode(BAKED, e))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // computed by the writer
        },
        json: json.into(),
        bin: Some(bin.into()),
    };
    glb.to_vec().map_err(|e| Error::encode(BAKED, e))
}

/// `[start, count]` runs of consecutive values in an ascending list.
fn runs(values: &[u32]) -> Vec<[u32; 2]> {
    let mut out: Vec<[u32; 2]> = Vec::new();
    for &v in values {
        match out.last_mut() {
            Some([start, count]) if *start + *count == v => *count += 1,
            _ => out.push([v, 1]),
        }
    }
    out
}

/// The MIME type of an encoded image, from its first bytes.
fn sniff_mime(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xff, 0xd8, 0xff]) {
        Some("image/jpeg")
    } else if bytes.starts_with(b"RIFF") && bytes.get(8..12) == Some(b"WEBP") {
        Some("image/webp")
    } else if bytes.starts_with(b"\xabKTX 20\xbb") {
        Some("image/ktx2")
    } else {
        None
    }
}

/// The bake's document and buffer; the buffer is the file `bin_name`, or
/// with `None` the GLB's binary chunk.
fn baked_root(
    mesh: &OutputMesh,
    layout: &BakeLayout,
    exposure: f32,
    bin_name: Option<&str>,
) -> Result<(json::Root, Vec<u8>)> {
    let source = &layout.source;
    let mut root = source.json.clone();
    root.extensions = None;
    root.extensions_used
        .retain(|e| KEPT_EXTENSIONS.contains(&e.as_str()));
    root.extensions_required
        .retain(|e| KEPT_EXTENSIONS.contains(&e.as_str()));
    if !root.extensions_used.iter().any(|e| e == UNLIT) {
        root.extensions_used.push(UNLIT.to_string());
    }
    let mut packer = Packer::new(root, bin_name);

    for (i, bytes) in source.images.iter().enumerate() {
        let mime = match packer.root.images[i].mime_type.as_ref() {
            Some(m) => m.0.clone(),
            None => sniff_mime(bytes)
                .ok_or_else(|| {
                    Error::encode(BAKED, format!("image {i} is in a format it cannot name"))
                })?
                .to_string(),
        };
        let view = packer.view(bytes, None, &format!("image {i}"));
        let image = &mut packer.root.images[i];
        image.buffer_view = Some(view);
        image.mime_type = Some(json::image::MimeType(mime));
    }

    // The lightmap's display image: one more image, texture and sampler
    // (bilinear, clamped, as the atlas's padding expects).
    let lightmap_texture = match &layout.lightmap {
        Some((_, png)) => {
            let view = packer.view(png, None, "lightmap");
            let source = packer.root.push(json::Image {
                buffer_view: Some(view),
                mime_type: Some(json::image::MimeType("image/png".to_string())),
                name: Some("lightmap".to_string()),
                uri: None,
                extensions: None,
                extras: None,
            });
            let clamp = Valid(json::texture::WrappingMode::ClampToEdge);
            let sampler = packer.root.push(json::texture::Sampler {
                mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
                min_filter: Some(Valid(json::texture::MinFilter::Linear)),
                wrap_s: clamp,
                wrap_t: clamp,
                name: Some("lightmap".to_string()),
                extensions: None,
                extras: None,
            });
            Some(packer.root.push(json::Texture {
                name: Some("lightmap".to_string()),
                sampler: Some(sampler),
                source,
                extensions: None,
                extras: None,
            }))
        }
        None => None,
    };

    let first_baked = packer.root.materials.len();
    for (k, name) in layout.material_names.iter().enumerate() {
        let source_material = source.materials.get(k).copied().flatten();
        let extras = serde_json::json!({ "source_material": source_material });
        packer.root.push(json::Material {
            name: Some(format!("{name} (baked, unlit)")),
            double_sided: false,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(1.0),
                ..Default::default()
            },
            extensions: Some(json::extensions::material::Material {
                unlit: Some(json::extensions::material::Unlit {}),
                ..Default::default()
            }),
            emissive_texture: lightmap_texture.map(|index| json::texture::Info {
                index,
                tex_coord: 1,
                extensions: None,
                extras: None,
            }),
            emissive_factor: json::material::EmissiveFactor(match lightmap_texture {
                Some(_) => [1.0; 3],
                None => [0.0; 3],
            }),
            extras: Some(raw(&extras)?),
            ..Default::default()
        });
    }

    let colors: Vec<Vec3> = mesh
        .radiosity
        .iter()
        .map(|&b| display_color(b, exposure))
        .collect();
    let mut primitives: BTreeMap<usize, Vec<json::mesh::Primitive>> = BTreeMap::new();
    for group in &layout.groups {
        let world = source.world[group.node].unwrap_or(DMat4::IDENTITY);
        let primitive = packer.primitive(
            mesh,
            &colors,
            layout,
            group,
            world,
            json::Index::new((first_baked + group.material as usize) as u32),
        )?;
        primitives.entry(group.node).or_default().push(primitive);
    }
    for (node, primitives) in primitives {
        let name = packer.root.nodes[node]
            .name
            .clone()
            .unwrap_or_else(|| format!("node{node}"));
        let mesh_index = packer.root.push(json::Mesh {
            extensions: None,
            extras: None,
            name: Some(name),
            primitives,
            weights: None,
        });
        packer.root.nodes[node].mesh = Some(mesh_index);
    }

    let extras = serde_json::json!({
        "exposure": exposure,
        "generator": "nusselt",
        "version": env!("CARGO_PKG_VERSION"),
        "COLOR_0": "clamp(B / pi * exposure, 0, 1), linear",
        "_RADIOSITY": "radiosity B, linear, unclamped, W/m^2",
        "_IRRADIANCE": "irradiance H, linear, W/m^2; B = E + albedo * H",
        "baked_materials": first_baked,
    });
    let (mut root, bin) = packer.finish();
    root.asset = json::Asset {
        generator: Some(format!("nusselt {}", env!("CARGO_PKG_VERSION"))),
        extras: Some(raw(&extras)?),
        ..Default::default()
    };
    Ok((root, bin))
}

/// A JSON value as glTF `extras`.
fn raw(value: &serde_json::Value) -> Result<Box<json::extras::RawValue>> {
    json::extras::RawValue::from_string(value.to_string()).map_err(|e| Error::encode(BAKED, e))
}

/// Builds the JSON root and the binary buffer together: each accessor gets
/// its own buffer view, appended to the single buffer.
struct Packer {
    root: json::Root,
    bin: Vec<u8>,
    buffer: json::Index<json::Buffer>,
}

impl Packer {
    /// Adds the one buffer to `root`.
    fn new(mut root: json::Root, bin_name: Option<&str>) -> Packer {
        let buffer = root.push(json::Buffer {
            byte_length: USize64(0), // set by `finish`
            name: None,
            uri: bin_name.map(str::to_string),
            extensions: None,
            extras: None,
        });
        Packer {
            root,
            bin: Vec::new(),
            buffer,
        }
    }

    /// Appends `bytes` as a new buffer view. Every element written here is
    /// 4 bytes wide, so every view starts 4-byte aligned.
    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<Target>,
        name: &str,
    ) -> json::Index<json::buffer::View> {
        let view = self.root.push(json::buffer::View {
            buffer: self.buffer,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(self.bin.len())),
            byte_stride: None,
            name: Some(name.to_string()),
            target: target.map(Valid),
            extensions: None,
            extras: None,
        });
        self.bin.extend_from_slice(bytes);
        // Images may have any length; the next view starts 4-byte aligned.
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        view
    }

    /// One primitive: `group`'s vertices in `world`'s local frame, with
    /// their colours, layers and texture coordinates, and its triangles.
    fn primitive(
        &mut self,
        mesh: &OutputMesh,
        colors: &[Vec3],
        layout: &BakeLayout,
        group: &Group,
        world: DMat4,
        material: json::Index<json::Material>,
    ) -> Result<json::mesh::Primitive> {
        let to_local = world.inverse();
        let linear = glam::DMat3::from_mat4(world);
        let mirrored = linear.determinant() < 0.0;
        let pick = |values: &[Vec3]| -> Vec<Vec3> {
            group.vertices.iter().map(|&v| values[v as usize]).collect()
        };
        let positions: Vec<Vec3> = group
            .vertices
            .iter()
            .map(|&v| {
                to_local
                    .transform_point3(mesh.positions[v as usize].as_dvec3())
                    .as_vec3()
            })
            .collect();
        let normals: Vec<Vec3> = group
            .vertices
            .iter()
            .map(|&v| {
                (linear.transpose() * mesh.normals[v as usize].as_dvec3())
                    .normalize()
                    .as_vec3()
            })
            .collect();
        if !positions.iter().chain(&normals).all(|p| p.is_finite()) {
            return Err(Error::encode(
                BAKED,
                format!("node {}: its transform cannot be inverted", group.node),
            ));
        }
        let mut local: HashMap<u32, u32> = HashMap::with_capacity(group.vertices.len());
        for (i, &v) in group.vertices.iter().enumerate() {
            local.insert(v, i as u32);
        }
        let mut indices = Vec::with_capacity(group.triangles.len() * 3);
        for &t in &group.triangles {
            let mut tri = mesh.triangles[t as usize].map(|v| local[&v]);
            if mirrored {
                tri.swap(1, 2);
            }
            indices.extend(tri);
        }

        let mut attributes = BTreeMap::from([
            (
                Valid(Semantic::Positions),
                self.vec3_accessor(&positions, "POSITION", true),
            ),
            (
                Valid(Semantic::Normals),
                self.vec3_accessor(&normals, "NORMAL", false),
            ),
            (
                Valid(Semantic::Colors(0)),
                self.vec3_accessor(&pick(colors), "COLOR_0", false),
            ),
            (
                Valid(Semantic::Extras(RADIOSITY_ATTRIBUTE.to_string())),
                self.vec3_accessor(&pick(&mesh.radiosity), "_RADIOSITY", false),
            ),
            (
                Valid(Semantic::Extras(IRRADIANCE_ATTRIBUTE.to_string())),
                self.vec3_accessor(&pick(&mesh.irradiance), "_IRRADIANCE", false),
            ),
        ]);
        let uvs: Option<Vec<Vec2>> = group
            .vertices
            .iter()
            .map(|&v| layout.tex_coords[v as usize])
            .collect();
        let lightmap_uvs: Option<Vec<Vec2>> = layout
            .lightmap
            .as_ref()
            .map(|(uv, _)| group.vertices.iter().map(|&v| uv[v as usize]).collect());
        // glTF's texture coordinate sets run from 0 without gaps: without
        // the input's TEXCOORD_0, the lightmap's coordinates are set 0 too.
        if let Some(uvs) = uvs.as_ref().or(lightmap_uvs.as_ref()) {
            attributes.insert(
                Valid(Semantic::TexCoords(0)),
                self.vec2_accessor(uvs, "TEXCOORD_0"),
            );
        }
        if let Some(uvs) = &lightmap_uvs {
            attributes.insert(
                Valid(Semantic::TexCoords(1)),
                self.vec2_accessor(uvs, "TEXCOORD_1"),
            );
        }
        let extras = serde_json::json!({
            "source_primitive": group.primitive,
            "solution_vertices": runs(&group.vertices),
            "solution_triangles": runs(&group.triangles),
        });
        Ok(json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Some(raw(&extras)?),
            indices: Some(self.index_accessor(&indices)),
            material: Some(material),
            mode: Valid(Mode::Triangles),
            targets: None,
        })
    }

    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        (type_, component): (Type, ComponentType),
        bounds: Option<(serde_json::Value, serde_json::Value)>,
        name: &str,
    ) -> json::Index<json::Accessor> {
        let (min, max) = bounds.unzip();
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Valid(type_),
            min,
            max,
            name: Some(name.to_string()),
            normalized: false,
            sparse: None,
        })
    }

    /// A vertex-attribute view of little-endian f32s.
    fn float_view(
        &mut self,
        floats: impl Iterator<Item = f32>,
        name: &str,
    ) -> json::Index<json::buffer::View> {
        let bytes: Vec<u8> = floats.flat_map(f32::to_le_bytes).collect();
        self.view(&bytes, Some(Target::ArrayBuffer), name)
    }

    /// A float VEC3 vertex attribute; with `bounded`, its exact per-axis
    /// minimum and maximum (required for POSITION).
    fn vec3_accessor(
        &mut self,
        values: &[Vec3],
        name: &str,
        bounded: bool,
    ) -> json::Index<json::Accessor> {
        let view = self.float_view(values.iter().flat_map(|v| v.to_array()), name);
        let bounds = bounded.then(|| {
            let (lo, hi) = values.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), &p| (lo.min(p), hi.max(p)),
            );
            (
                serde_json::json!(lo.to_array()),
                serde_json::json!(hi.to_array()),
            )
        });
        self.accessor(
            view,
            values.len(),
            (Type::Vec3, ComponentType::F32),
            bounds,
            name,
        )
    }

    /// A float VEC2 vertex attribute.
    fn vec2_accessor(&mut self, values: &[Vec2], name: &str) -> json::Index<json::Accessor> {
        let view = self.float_view(values.iter().flat_map(|v| v.to_array()), name);
        self.accessor(
            view,
            values.len(),
            (Type::Vec2, ComponentType::F32),
            None,
            name,
        )
    }

    /// The uint32 triangle indices.
    fn index_accessor(&mut self, indices: &[u32]) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(Target::ElementArrayBuffer), "indices");
        self.accessor(
            view,
            indices.len(),
            (Type::Scalar, ComponentType::U32),
            None,
            "indices",
        )
    }

    fn finish(mut self) -> (json::Root, Vec<u8>) {
        self.root.buffers[self.buffer.value()].byte_length = USize64::from(self.bin.len());
        (self.root, self.bin)
    }
}

/// The preconditions of [`encode_baked_gltf`].
fn check(mesh: &OutputMesh, layout: &BakeLayout, exposure: f32, bin_name: &str) -> Result<()> {
    let fail = |message: String| Err(Error::encode(BAKED, message));
    if !exposure.is_finite() || exposure < 0.0 {
        return Err(Error::Setting(format!(
            "exposure {exposure} must be finite and non-negative"
        )));
    }
    let plain = !bin_name.is_empty()
        && bin_name != "."
        && bin_name != ".."
        && bin_name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'));
    if !plain {
        return fail(format!(
            "buffer name {bin_name:?} is not a plain file name (letters, digits, '.', '_', '-')"
        ));
    }
    let n = mesh.positions.len();
    if let Some(message) = mesh.length_mismatch() {
        return fail(message);
    }
    if n == 0 || mesh.triangles.is_empty() {
        return fail(format!(
            "the mesh is empty ({n} vertices, {} triangles)",
            mesh.triangles.len()
        ));
    }
    // Accessor counts and offsets must fit the u32 indices and JSON numbers.
    if u32::try_from(n).is_err() || u32::try_from(mesh.triangles.len() * 3).is_err() {
        return fail(format!("the mesh is too large ({n} vertices)"));
    }
    for k in 0..n {
        let values = [
            mesh.positions[k],
            mesh.normals[k],
            mesh.radiosity[k],
            mesh.irradiance[k],
        ];
        if !values.iter().all(|v| v.is_finite()) {
            return fail(format!(
                "vertex {k} has a non-finite position, normal, radiosity or irradiance"
            ));
        }
    }
    if let Some((t, tri)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
    {
        return fail(format!(
            "triangle {t} {tri:?} indexes beyond the {n} vertices"
        ));
    }
    // The layout must be this mesh's: every vertex and triangle in one
    // group, each triangle's vertices in its group.
    let mut vertex_group = vec![usize::MAX; n];
    for (g, group) in layout.groups.iter().enumerate() {
        for &v in &group.vertices {
            match vertex_group.get_mut(v as usize) {
                Some(slot) if *slot == usize::MAX => *slot = g,
                _ => {
                    return fail(format!(
                        "the layout places vertex {v} twice or beyond the mesh"
                    ));
                }
            }
        }
    }
    let placed: usize = layout.groups.iter().map(|g| g.triangles.len()).sum();
    let consistent = layout.tex_coords.len() == n
        && !vertex_group.contains(&usize::MAX)
        && placed == mesh.triangles.len()
        && layout.groups.iter().enumerate().all(|(g, group)| {
            group.triangles.iter().all(|&t| {
                mesh.triangles
                    .get(t as usize)
                    .is_some_and(|tri| tri.iter().all(|&v| vertex_group[v as usize] == g))
            })
        });
    if !consistent {
        return fail("the layout is not this mesh's".to_string());
    }
    Ok(())
}
