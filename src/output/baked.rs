//! `baked.gltf` + `baked.bin` (or, the same document and buffer in one
//! binary glTF, `baked.glb`): the output mesh with its radiosity baked into
//! vertex colours. The only writer of glTF (through `gltf::json` and
//! `gltf::Glb`).
//!
//! Layout:
//!
//! ```text
//! scene 0 ─ node "baked" ─ mesh "baked" ─ one triangle primitive, material 0
//! material 0: KHR_materials_unlit (listed in extensionsUsed), single-sided,
//!             base colour white, so a viewer shows COLOR_0 as it is
//! baked.bin (one buffer, every view 4-byte aligned, no stride sharing):
//!   view 0  POSITION    float VEC3  n × 12 bytes  ARRAY_BUFFER  (min/max set)
//!   view 1  NORMAL      float VEC3  n × 12 bytes  ARRAY_BUFFER
//!   view 2  COLOR_0     float VEC3  n × 12 bytes  ARRAY_BUFFER
//!   view 3  _RADIOSITY  float VEC3  n × 12 bytes  ARRAY_BUFFER
//!   view 4  _IRRADIANCE float VEC3  n × 12 bytes  ARRAY_BUFFER
//!   view 5  indices     uint32 SCALAR 3m × 4 bytes ELEMENT_ARRAY_BUFFER
//! ```
//!
//! `COLOR_0` = clamp(B / π × exposure, 0, 1) per channel (linear display
//! radiance), `_RADIOSITY` = B (linear, unclamped, W/m²), `_IRRADIANCE` =
//! H (the light arriving, linear, W/m²: an engine multiplies it with its
//! own albedo, B = E + ρ H). `asset.extras`
//! records the exposure; `asset.generator` is "nusselt VERSION".
//!
//! Invariant: the vertices and triangles are those of the [`OutputMesh`] in
//! order, so `baked.gltf` and `solution.exr` describe the same mesh.

use std::collections::BTreeMap;
use std::f32::consts::PI;

use glam::Vec3;
use gltf::json;
use json::accessor::{ComponentType, GenericComponentType, Type};
use json::buffer::Target;
use json::mesh::{Mode, Semantic};
use json::validation::{Checked::Valid, USize64};

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;

/// What the encoder names in its errors.
const BAKED: &str = "the baked glTF";
/// The glTF extension that makes viewers show vertex colours unshaded.
const UNLIT: &str = "KHR_materials_unlit";
/// Name of the custom attribute holding the radiosity (without the `_`).
pub const RADIOSITY_ATTRIBUTE: &str = "RADIOSITY";
/// Name of the custom attribute holding the irradiance (without the `_`).
pub const IRRADIANCE_ATTRIBUTE: &str = "IRRADIANCE";

/// The displayed colour of a vertex of radiosity `b`: clamp(B / π ×
/// exposure, 0, 1) per channel.
pub fn display_color(b: Vec3, exposure: f32) -> Vec3 {
    (b / PI * exposure).clamp(Vec3::ZERO, Vec3::ONE)
}

/// Encodes `mesh` as (`baked.gltf` JSON bytes, `baked.bin` bytes); the JSON
/// refers to the binary buffer by the relative URI `bin_name`.
///
/// Fails on an empty mesh (glTF has no empty accessors), arrays of unequal
/// length, out-of-range indices, non-finite values, a negative or non-finite
/// exposure, or a `bin_name` that is not a plain file name.
pub fn encode_baked_gltf(
    mesh: &OutputMesh,
    exposure: f32,
    bin_name: &str,
) -> Result<(Vec<u8>, Vec<u8>)> {
    check(mesh, exposure, bin_name)?;
    let (root, bin) = baked_root(mesh, exposure, Some(bin_name))?;
    let mut gltf_bytes = root.to_vec_pretty().map_err(|e| Error::encode(BAKED, e))?;
    gltf_bytes.push(b'\n');
    Ok((gltf_bytes, bin))
}

/// Encodes `mesh` as one binary glTF (`baked.glb`): the same document as
/// [`encode_baked_gltf`]'s, its buffer the GLB's binary chunk. Fails as
/// that does.
pub fn encode_baked_glb(mesh: &OutputMesh, exposure: f32) -> Result<Vec<u8>> {
    check(mesh, exposure, "baked.bin")?;
    let (root, bin) = baked_root(mesh, exposure, None)?;
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

/// The bake's document and buffer; the buffer is the file `bin_name`, or
/// with `None` the GLB's binary chunk.
fn baked_root(
    mesh: &OutputMesh,
    exposure: f32,
    bin_name: Option<&str>,
) -> Result<(json::Root, Vec<u8>)> {
    let colors: Vec<Vec3> = mesh
        .radiosity
        .iter()
        .map(|&b| display_color(b, exposure))
        .collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();

    let mut packer = Packer::new(bin_name);
    let position = packer.vec3_accessor(&mesh.positions, "POSITION", true);
    let normal = packer.vec3_accessor(&mesh.normals, "NORMAL", false);
    let color = packer.vec3_accessor(&colors, "COLOR_0", false);
    let radiosity = packer.vec3_accessor(&mesh.radiosity, "_RADIOSITY", false);
    let irradiance = packer.vec3_accessor(&mesh.irradiance, "_IRRADIANCE", false);
    let index_accessor = packer.index_accessor(&indices);
    let (mut root, bin) = packer.finish();

    let material = root.push(json::Material {
        name: Some("baked radiosity (unlit)".to_string()),
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
        ..Default::default()
    });
    root.extensions_used.push(UNLIT.to_string());

    let attributes = BTreeMap::from([
        (Valid(Semantic::Positions), position),
        (Valid(Semantic::Normals), normal),
        (Valid(Semantic::Colors(0)), color),
        (
            Valid(Semantic::Extras(RADIOSITY_ATTRIBUTE.to_string())),
            radiosity,
        ),
        (
            Valid(Semantic::Extras(IRRADIANCE_ATTRIBUTE.to_string())),
            irradiance,
        ),
    ]);
    let mesh_index = root.push(json::Mesh {
        extensions: None,
        extras: None,
        name: Some("baked".to_string()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: None,
            indices: Some(index_accessor),
            material: Some(material),
            mode: Valid(Mode::Triangles),
            targets: None,
        }],
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh_index),
        name: Some("baked".to_string()),
        ..Default::default()
    });
    let scene = root.push(json::Scene {
        extensions: None,
        extras: None,
        name: Some("baked".to_string()),
        nodes: vec![node],
    });
    root.scene = Some(scene);

    let extras = serde_json::json!({
        "exposure": exposure,
        "generator": "nusselt",
        "version": env!("CARGO_PKG_VERSION"),
        "COLOR_0": "clamp(B / pi * exposure, 0, 1), linear",
        "_RADIOSITY": "radiosity B, linear, unclamped, W/m^2",
        "_IRRADIANCE": "irradiance H, linear, W/m^2; B = E + albedo * H",
    });
    root.asset = json::Asset {
        generator: Some(format!("nusselt {}", env!("CARGO_PKG_VERSION"))),
        extras: Some(
            json::extras::RawValue::from_string(extras.to_string())
                .map_err(|e| Error::encode(BAKED, e))?,
        ),
        ..Default::default()
    };

    Ok((root, bin))
}

/// Builds the JSON root and the binary buffer together: each accessor gets
/// its own buffer view, appended to the single buffer.
struct Packer {
    root: json::Root,
    bin: Vec<u8>,
    buffer: json::Index<json::Buffer>,
}

impl Packer {
    fn new(bin_name: Option<&str>) -> Packer {
        let mut root = json::Root::default();
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
        target: Target,
        name: &str,
    ) -> json::Index<json::buffer::View> {
        let view = self.root.push(json::buffer::View {
            buffer: self.buffer,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(self.bin.len())),
            byte_stride: None,
            name: Some(name.to_string()),
            target: Some(Valid(target)),
            extensions: None,
            extras: None,
        });
        self.bin.extend_from_slice(bytes);
        view
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

    /// A float VEC3 vertex attribute; with `bounded`, its exact per-axis
    /// minimum and maximum (required for POSITION).
    fn vec3_accessor(
        &mut self,
        values: &[Vec3],
        name: &str,
        bounded: bool,
    ) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = values
            .iter()
            .flat_map(|v| v.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let view = self.view(&bytes, Target::ArrayBuffer, name);
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

    /// The uint32 triangle indices.
    fn index_accessor(&mut self, indices: &[u32]) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Target::ElementArrayBuffer, "indices");
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
fn check(mesh: &OutputMesh, exposure: f32, bin_name: &str) -> Result<()> {
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
    Ok(())
}
