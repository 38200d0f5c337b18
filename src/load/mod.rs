//! The glTF 2.0 loader: the only module that knows the `gltf` crate.
//!
//! Owns: reading a `.gltf` (external or data-URI buffers) or `.glb` file and
//! mapping it, as the contract prescribes, onto the format-free scene model:
//! world-space triangles with their averaged material values, materials,
//! surfaces (one per node with a mesh) and perspective cameras, handed to
//! [`Scene::build`]; and the document's structure without its geometry
//! ([`SourceDocument`]: nodes, cameras, materials, the textures' images), with
//! each triangle's primitive and `TEXCOORD_0`/`TEXCOORD_1`, for the bake.
//!
//! Invariants:
//! - Untrusted input never panics and never drives an allocation: every
//!   accessor is checked against the bytes actually loaded
//!   (`accessor::check`) before it is read, node hierarchies are walked
//!   iteratively and each node at most once (cycles and shared children are
//!   errors), and the total triangle count is capped ([`MAX_TRIANGLES`]).
//!   Before any mesh is read, the triangles the node hierarchy instances are
//!   counted from the accessors' declared counts and checked against that
//!   cap and the memory budget ([`LOADED_TRIANGLE_BYTES`] each).
//! - Textures are decoded once per distinct image content (entries that
//!   share a file or bytes share one decode), each only after its header's
//!   width × height has been checked against the memory budget, and kept
//!   reduced (`texture`), so the textures held stay within the budget.
//!   External URIs must name regular files (a device or FIFO would be read
//!   without end) whose sizes are checked against the memory budget before
//!   they are read, and data URIs must carry the MIME type of their role.
//! - World-space positions lie within ±[`MAX_COORDINATE`] (the range the f32
//!   visibility structures handle), else the primitive is refused.
//! - Positions and transforms are f64 from the first multiplication on.
//! - Triangles leave counter-clockwise seen from their front in world space:
//!   a node whose world transform has a negative determinant gets its
//!   winding swapped.
//! - Nothing is welded, merged or dropped here; [`Scene::build`] does that.
//! - Errors are [`Error::Scene`] whose message names the mesh and primitive
//!   (or node, material, image) at fault.

mod accessor;
mod texture;

use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat4, DQuat, DVec2, DVec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use gltf::{Document, Semantic};
use rayon::prelude::*;

use crate::classic::uniform::human_bytes;
use crate::error::{Error, Result};
use crate::scene::{
    Camera, EnvironmentMap, InputTriangle, LightKind, Lights, MAX_COORDINATE, Material,
    PunctualLight, Scene, Sky, SourceDocument, Surface, TriangleOrigin,
};

use self::accessor::Expect;
use self::texture::{Sampler, Texture, UvTransform};

pub use crate::scene::MAX_TRIANGLES;

/// Bytes a loaded triangle takes until the scene is built: the
/// [`InputTriangle`] itself (about 190) and its share of the scene's
/// patches, welding tables and occluder BVH; an estimate, rounded up.
pub const LOADED_TRIANGLE_BYTES: u64 = 512;

/// Extensions whose effect the diffuse model ignores, when the file uses them.
const IGNORED_EXTENSIONS: &[&str] = &[
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_dispersion",
    "KHR_materials_ior",
    "KHR_materials_iridescence",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
];

/// Settings of the glTF mapping.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Reflectance components at or above this value are clamped to it (with
    /// a warning naming the material). Must lie in (0, 1); default 0.999.
    pub max_reflectance: f64,
    /// The sky around the scene, if any (`--sky`).
    pub sky: Option<Arc<Sky>>,
    /// Bytes the loader may allocate for sizes read from the file
    /// (`--memory-budget`): the triangles after instancing and the
    /// textures, each checked before it is allocated.
    pub memory_budget: u64,
}

impl LoadOptions {
    /// Checks the reflectance cap (in (0, 1)). The error names the
    /// command-line option.
    pub fn validate(&self) -> Result<()> {
        if !(self.max_reflectance > 0.0 && self.max_reflectance < 1.0) {
            return Err(Error::Setting("--max-reflectance must be in (0, 1)".into()));
        }
        Ok(())
    }
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            max_reflectance: 0.999,
            sky: None,
            memory_budget: crate::classic::matrix::DEFAULT_MEMORY_BUDGET,
        }
    }
}

/// The sky of `--sky`: three comma-separated radiances R,G,B (finite, not
/// negative, W·m⁻²·sr⁻¹) for a uniform sky, else the path of an
/// equirectangular OpenEXR environment (its first RGB layer; every texel
/// finite and not negative).
pub fn parse_sky(spec: &str) -> Result<Sky> {
    let parts: Vec<&str> = spec.split(',').collect();
    if parts.len() == 3
        && let Ok(v) = parts
            .iter()
            .map(|p| p.trim().parse::<f64>())
            .collect::<std::result::Result<Vec<f64>, _>>()
    {
        let l = DVec3::new(v[0], v[1], v[2]);
        if !(l.is_finite() && l.min_element() >= 0.0) {
            return Err(Error::Setting(format!(
                "--sky {spec}: the radiances must be finite and not negative"
            )));
        }
        return Ok(Sky::Uniform(l));
    }
    let path = Path::new(spec);
    let frame = crate::output::exr::read_image(path)?;
    if let Some(k) = frame
        .pixels
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite() && *c >= 0.0))
    {
        return Err(Error::input(
            path,
            format!(
                "texel {k} of the sky is {:?}: sky radiances must be finite and not negative",
                frame.pixels[k]
            ),
        ));
    }
    Ok(Sky::Map(EnvironmentMap {
        width: frame.width,
        height: frame.height,
        texels: frame.pixels,
    }))
}

/// Loads the default scene of a `.gltf` or `.glb` file. External buffers and
/// images are resolved against the file's folder.
pub fn load_scene(path: &Path, options: &LoadOptions) -> Result<Scene> {
    // A device or a pipe would be read without end, or block: only a
    // regular file, whose size bounds what is read.
    match std::fs::metadata(path) {
        Ok(meta) if !meta.is_file() => {
            return Err(Error::scene(path, "not a regular file"));
        }
        Err(e) => return Err(Error::scene(path, format!("cannot read the file: {e}"))),
        Ok(_) => {}
    }
    let bytes = std::fs::read(path)
        .map_err(|e| Error::scene(path, format!("cannot read the file: {e}")))?;
    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    load(&bytes, Some(base), path, options)
}

/// For fuzzing and tests: bytes of a .gltf or .glb; external URIs are
/// resolved against `base_dir`, and are an error when it is `None`. Errors
/// name the path `<memory>`.
pub fn load_scene_from_slice(
    bytes: &[u8],
    base_dir: Option<&Path>,
    options: &LoadOptions,
) -> Result<Scene> {
    load(bytes, base_dir, Path::new("<memory>"), options)
}

fn load(bytes: &[u8], base: Option<&Path>, path: &Path, options: &LoadOptions) -> Result<Scene> {
    options.validate()?;
    let scene_error = |message: String| Error::scene(path, message);
    let (document, blob) = parse(bytes).map_err(scene_error)?;
    check_uris(&document, base, options.memory_budget).map_err(scene_error)?;
    let buffers = gltf::import_buffers(&document, base, blob)
        .map_err(|e| scene_error(format!("cannot load buffers: {}", describe(&e))))?;
    let mut loader = Loader {
        document: &document,
        buffers: &buffers,
        base,
        options,
        triangles: Vec::new(),
        materials: Vec::new(),
        material_ids: HashMap::new(),
        clamped: Vec::new(),
        ignored: BTreeMap::new(),
        surfaces: Vec::new(),
        cameras: Vec::new(),
        textures: HashMap::new(),
        decoded: HashMap::new(),
        decoded_files: HashMap::new(),
        texture_bytes: 0,
        world: vec![None; document.nodes().len()],
        punctual_lights: Vec::new(),
        warnings: Vec::new(),
        dropped_indices: 0,
    };
    loader.traverse().map_err(scene_error)?;
    // The images some texture uses, in index order: the bake embeds them;
    // the others are not read (an unused image may be missing).
    let mut used: Vec<usize> = document
        .as_json()
        .textures
        .iter()
        .map(|t| t.source.value())
        .collect();
    used.sort_unstable();
    used.dedup();
    // Each read within the budget, with the textures and the images
    // read before it.
    let mut images = Vec::with_capacity(used.len());
    let mut held = loader.texture_bytes;
    for &i in &used {
        let bytes = loader.image_bytes(i, held).map_err(scene_error)?;
        held = held.saturating_add(bytes.len() as u64);
        images.push(bytes);
    }
    let source = SourceDocument {
        json: without_geometry(&document, &used),
        images,
        world: std::mem::take(&mut loader.world),
        materials: loader.material_sources(),
    };
    let lights = Lights {
        punctual: std::mem::take(&mut loader.punctual_lights),
        sky: options.sky.as_deref().cloned(),
    };
    let warnings = loader.finish_warnings();
    let mut scene = Scene::build_lit(
        loader.triangles,
        loader.materials.into_iter().map(|m| m.material).collect(),
        loader.surfaces,
        loader.cameras,
        warnings,
        lights,
    )?;
    scene.source = Some(Arc::new(source));
    Ok(scene)
}

/// The document with its meshes, accessors, buffer views, buffers, skins
/// and animations removed, and the node fields that refer to them (mesh,
/// skin, morph weights) cleared; only the `used` images (ascending) stay,
/// renumbered in order with the textures pointing at them, and without
/// their source (the bake embeds their bytes).
fn without_geometry(document: &Document, used: &[usize]) -> gltf::json::Root {
    let mut json = document.as_json().clone();
    json.meshes.clear();
    json.accessors.clear();
    json.buffer_views.clear();
    json.buffers.clear();
    json.skins.clear();
    json.animations.clear();
    for node in &mut json.nodes {
        node.mesh = None;
        node.skin = None;
        node.weights = None;
        // Its light (KHR_lights_punctual), which the bake does not carry.
        node.extensions = None;
    }
    json.images = used
        .iter()
        .filter_map(|&i| json.images.get(i).cloned())
        .map(|mut image| {
            image.buffer_view = None;
            image.uri = None;
            image
        })
        .collect();
    for texture in &mut json.textures {
        if let Ok(k) = used.binary_search(&texture.source.value()) {
            texture.source = gltf::json::Index::new(k as u32);
        }
    }
    json
}

/// Splits GLB or reads JSON, then validates. Guards the `gltf` crate's own
/// panics: a GLB header length below 12, a POSITION index past the accessor
/// list (its validation indexes without checking), images without a source
/// or MIME type and cameras without their projection (its getters unwrap).
fn parse(bytes: &[u8]) -> Result<(Document, Option<Vec<u8>>), String> {
    if bytes.starts_with(b"glTF") {
        let Some(length) = bytes.get(8..12) else {
            return Err("truncated GLB header".into());
        };
        let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]);
        if length as usize != bytes.len() {
            return Err(format!(
                "GLB header declares length {length}, but the file has {} bytes",
                bytes.len()
            ));
        }
    }
    let gltf = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| format!("not a valid glTF file: {}", describe(&e)))?;
    let blob = gltf.blob;
    let root = gltf.document.into_json();
    let major = root.asset.version.split('.').next().unwrap_or("");
    if major != "2" {
        return Err(format!(
            "asset.version is '{}': only glTF 2.x is read",
            short(&root.asset.version)
        ));
    }
    for (i, node) in root.nodes.iter().enumerate() {
        let trs = node.translation.is_some() || node.rotation.is_some() || node.scale.is_some();
        if node.matrix.is_some() && trs {
            return Err(format!(
                "node {i} has both a matrix and translation/rotation/scale (the \
                 specification allows one or the other)"
            ));
        }
        if let Some(m) = &node.matrix
            && let Some(why) = not_decomposable(m)
        {
            return Err(format!(
                "node {i}: its matrix is not decomposable into translation, rotation \
                 and scale, as the specification requires ({why})"
            ));
        }
    }
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let position = primitive
                .attributes
                .get(&gltf::json::validation::Checked::Valid(Semantic::Positions));
            match position {
                Some(index) if index.value() >= root.accessors.len() => {
                    return Err(format!(
                        "mesh {m} primitive {p}: POSITION accessor {} does not exist",
                        index.value()
                    ));
                }
                _ => {}
            }
        }
    }
    // `gltf` unwraps these where its validation does not look.
    for (i, image) in root.images.iter().enumerate() {
        let complete = match (&image.buffer_view, &image.uri) {
            (Some(_), _) => image.mime_type.is_some(),
            (None, uri) => uri.is_some(),
        };
        if !complete {
            return Err(format!(
                "image {i} needs a uri, or a bufferView with a mimeType"
            ));
        }
    }
    for (i, camera) in root.cameras.iter().enumerate() {
        use gltf::json::camera::Type;
        use gltf::json::validation::Checked;
        let complete = match camera.type_ {
            Checked::Valid(Type::Perspective) => camera.perspective.is_some(),
            Checked::Valid(Type::Orthographic) => camera.orthographic.is_some(),
            Checked::Invalid => true, // reported by validation
        };
        if !complete {
            return Err(format!(
                "camera {i} lacks the block of its type ({:?})",
                camera.type_
            ));
        }
    }
    let document = Document::from_json(root)
        .map_err(|e| format!("not a valid glTF file: {}", describe(&e)))?;
    Ok((document, blob))
}

/// Checks buffer and image URIs before `gltf` reads them: percent-escapes
/// must decode as UTF-8 (`gltf` unwraps the decoding), a data URI must name
/// a MIME type its role accepts, and an external file must be a relative
/// path that stays inside the scene's folder (no `file:` URI, no absolute
/// path, no `..` above the folder, no link out of it: an untrusted scene
/// reads nothing else) and a regular file, so that its size bounds what is
/// read; the external buffer files, which `gltf` reads whole, must fit
/// `memory_budget` together.
fn check_uris(document: &Document, base: Option<&Path>, memory_budget: u64) -> Result<(), String> {
    // `gltf` reads each external buffer file whole: their sizes, together,
    // must fit the memory budget.
    let mut buffer_bytes = 0u64;
    const BUFFER_TYPES: &[&str] = &["application/octet-stream", "application/gltf-buffer"];
    const IMAGE_TYPES: &[&str] = &["image/png", "image/jpeg"];
    let buffer_uris = document.buffers().filter_map(|b| match b.source() {
        gltf::buffer::Source::Uri(uri) => {
            Some((format!("buffer {}", b.index()), uri, BUFFER_TYPES))
        }
        gltf::buffer::Source::Bin => None,
    });
    let image_uris = document.images().filter_map(|i| match i.source() {
        gltf::image::Source::Uri { uri, .. } => {
            Some((format!("image {}", i.index()), uri, IMAGE_TYPES))
        }
        gltf::image::Source::View { .. } => None,
    });
    for (what, uri, types) in buffer_uris.chain(image_uris) {
        if let Some(rest) = uri.strip_prefix("data:") {
            let mime = rest.split([';', ',']).next().unwrap_or("");
            if !types.iter().any(|t| t.eq_ignore_ascii_case(mime)) {
                return Err(format!(
                    "{what}: data URI has MIME type '{}', expected one of {}",
                    short(mime),
                    types.join(", ")
                ));
            }
            if !rest.contains(";base64,") {
                return Err(format!("{what}: data URI is not base64-encoded"));
            }
            continue;
        }
        let path = if uri.starts_with("file:") {
            return Err(format!(
                "{what}: '{}' is a file: URI; a scene reads only files beside it, \
                 named by a relative path",
                short(uri)
            ));
        } else if uri.contains(':') {
            continue; // an unsupported scheme: `gltf` reports it
        } else {
            match urlencoding::decode(uri) {
                Ok(decoded) => Path::new(decoded.as_ref()).to_path_buf(),
                Err(_) => {
                    return Err(format!(
                        "{what}: URI '{}' has invalid percent-escapes",
                        short(uri)
                    ));
                }
            }
        };
        let Some(base) = base else { continue }; // `gltf` refuses it
        if let Err(why) = inside(base, &path) {
            return Err(format!("{what}: '{}' {why}", short(uri)));
        }
        let full = base.join(&path);
        let shown = short(&full.display().to_string());
        match std::fs::metadata(&full) {
            Ok(meta) if !meta.is_file() => {
                return Err(format!("{what}: '{shown}' is not a regular file"));
            }
            Ok(meta) if what.starts_with("buffer") => {
                buffer_bytes = buffer_bytes.saturating_add(meta.len());
                if buffer_bytes > memory_budget {
                    return Err(format!(
                        "{what}: '{shown}' has {}{}, over the memory budget of {} \
                         (raise --memory-budget)",
                        human_bytes(meta.len()),
                        match buffer_bytes - meta.len() {
                            0 => String::new(),
                            b =>
                                format!(" besides the {} of the buffers before it", human_bytes(b)),
                        },
                        human_bytes(memory_budget)
                    ));
                }
            }
            Ok(_) => {}
            // An image is read only when a material uses it.
            Err(e) if what.starts_with("buffer") => {
                return Err(format!("{what}: cannot read '{shown}': {e}"));
            }
            Err(_) => {}
        }
    }
    Ok(())
}

/// Whether `relative` names a file inside the folder `base` (or below it):
/// not absolute, no `..` that climbs above `base`, and, where the file
/// exists, not a link that leads out of it. The error says which.
fn inside(base: &Path, relative: &Path) -> Result<(), &'static str> {
    use std::path::Component;
    let mut depth = 0usize;
    for component in relative.components() {
        match component {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => {
                depth = depth
                    .checked_sub(1)
                    .ok_or("leads out of the scene's folder")?;
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err("is an absolute path; a scene reads only files beside it");
            }
        }
    }
    let full = base.join(relative);
    if let (Ok(file), Ok(folder)) = (full.canonicalize(), base.canonicalize())
        && !file.starts_with(&folder)
    {
        return Err("leads out of the scene's folder through a link");
    }
    Ok(())
}

/// One line for a `gltf` error, listing validation problems by JSON path.
fn describe(error: &gltf::Error) -> String {
    match error {
        gltf::Error::Validation(problems) => {
            let shown: Vec<String> = problems
                .iter()
                .take(3)
                .map(|(path, e)| format!("{path}: {e}"))
                .collect();
            let more = problems.len().saturating_sub(shown.len());
            if more > 0 {
                format!("{} (and {more} more)", shown.join("; "))
            } else {
                shown.join("; ")
            }
        }
        gltf::Error::ExternalReferenceInSliceImport => {
            "an external file is referenced but there is no folder to resolve it against".into()
        }
        other => other.to_string(),
    }
}

/// A texture slot of a material, resolved.
#[derive(Clone, Debug)]
struct TextureSlot {
    image: usize,
    tex_coord: u32,
    sampler: Sampler,
    transform: Option<UvTransform>,
    /// "baseColorTexture" or "emissiveTexture", for messages.
    role: &'static str,
}

/// A material as the loader needs it while reading primitives.
#[derive(Clone, Debug)]
struct LoadedMaterial {
    material: Material,
    /// baseColorFactor.rgb before clamping.
    base_factor: DVec3,
    base_texture: Option<TextureSlot>,
    /// emissiveFactor × emissive strength.
    emission: DVec3,
    emissive_texture: Option<TextureSlot>,
}

struct Loader<'a> {
    document: &'a Document,
    buffers: &'a [gltf::buffer::Data],
    base: Option<&'a Path>,
    options: &'a LoadOptions,
    triangles: Vec<InputTriangle>,
    materials: Vec<LoadedMaterial>,
    /// glTF material index (`None`: the default material) → our index.
    material_ids: HashMap<Option<usize>, u32>,
    /// Per material: was some reflectance clamped?
    clamped: Vec<bool>,
    /// Ignored feature → names of the materials using it.
    ignored: BTreeMap<&'static str, Vec<String>>,
    surfaces: Vec<Surface>,
    cameras: Vec<Camera>,
    /// Decoded textures by image index.
    textures: HashMap<usize, Arc<Texture>>,
    /// Decoded textures by encoded content: image entries that share a
    /// file or bytes share one decode.
    decoded: HashMap<Vec<u8>, Arc<Texture>>,
    /// Decoded textures by canonical file path, so that a second entry
    /// naming a file is not checked again as if decoded anew.
    decoded_files: HashMap<PathBuf, Arc<Texture>>,
    /// Bytes the decoded textures keep, all together, with their encoded
    /// bytes (the keys of `decoded`).
    texture_bytes: u64,
    /// World transform of each node reached, by node index.
    world: Vec<Option<DMat4>>,
    /// The KHR_lights_punctual lights the reached nodes place, in node
    /// order.
    punctual_lights: Vec<PunctualLight>,
    warnings: Vec<String>,
    /// Trailing indices that did not form a whole triangle.
    dropped_indices: usize,
}

/// The nodes reached from `roots`, depth-first with children in file
/// order, each with its world transform; a node reached twice (a cycle or
/// a shared child) or a transform that is not finite is an error.
fn walk<'a>(
    document: &'a Document,
    roots: Vec<gltf::Node<'a>>,
) -> Result<Vec<(gltf::Node<'a>, DMat4)>, String> {
    let mut visited = vec![false; document.nodes().len()];
    let mut order = Vec::new();
    let mut stack: Vec<(gltf::Node<'_>, DMat4)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, DMat4::IDENTITY))
        .collect();
    while let Some((node, parent)) = stack.pop() {
        let index = node.index();
        if std::mem::replace(&mut visited[index], true) {
            return Err(format!(
                "node {} is reached twice: the node hierarchy has a cycle or a shared child",
                node_label(&node)
            ));
        }
        let world = parent * local_transform(&node)?;
        if !world.is_finite() {
            return Err(format!(
                "node {}: the world transform is not finite",
                node_label(&node)
            ));
        }
        let children: Vec<_> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, world)));
        order.push((node, world));
    }
    Ok(order)
}

/// Triangles a primitive declares, from its index (or position) accessor's
/// count alone: an upper bound of what it yields.
fn declared_triangles(primitive: &gltf::Primitive<'_>) -> u64 {
    let vertices = match primitive.indices() {
        Some(indices) => indices.count(),
        None => primitive.get(&Semantic::Positions).map_or(0, |p| p.count()),
    } as u64;
    match primitive.mode() {
        Mode::Triangles => vertices / 3,
        Mode::TriangleStrip | Mode::TriangleFan => vertices.saturating_sub(2),
        _ => 0,
    }
}

impl Loader<'_> {
    /// Walks the default scene depth-first, children in file order,
    /// after checking the triangles it instances against the budgets.
    fn traverse(&mut self) -> Result<(), String> {
        let document = self.document;
        let roots: Vec<gltf::Node<'_>> = match document
            .default_scene()
            .or_else(|| document.scenes().next())
        {
            Some(scene) => scene.nodes().collect(),
            None => {
                let mut is_child = vec![false; document.nodes().len()];
                for node in document.nodes() {
                    for child in node.children() {
                        is_child[child.index()] = true;
                    }
                }
                let roots: Vec<_> = document.nodes().filter(|n| !is_child[n.index()]).collect();
                if !roots.is_empty() {
                    self.warnings
                        .push("the file has no scene; using all root nodes".into());
                }
                roots
            }
        };
        let order = walk(document, roots)?;
        self.check_triangle_budget(&order)?;
        for (node, world) in order {
            let index = node.index();
            self.world[index] = Some(world);
            if let Some(mesh) = node.mesh() {
                self.add_mesh(&node, &mesh, &world)?;
            }
            if let Some(camera) = node.camera() {
                self.add_camera(&node, &camera, &world);
            }
            if let Some(light) = self.punctual_light(index, &world)? {
                self.punctual_lights.push(light);
            }
        }
        Ok(())
    }

    /// Counts the triangles the reached nodes instance, from the accessors'
    /// declared counts (nothing is read), and refuses them when they pass
    /// [`MAX_TRIANGLES`] or would need more than the memory budget at
    /// [`LOADED_TRIANGLE_BYTES`] each; the error names the mesh that
    /// contributes most. The counts are first checked against the data
    /// (`accessor::check`), so a count beyond its buffer is refused as such.
    fn check_triangle_budget(&self, order: &[(gltf::Node<'_>, DMat4)]) -> Result<(), String> {
        let mut instances = vec![0u64; self.document.meshes().len()];
        for (node, _) in order {
            if let Some(mesh) = node.mesh() {
                instances[mesh.index()] += 1;
            }
        }
        let mut total = 0u64;
        let mut largest: Option<(u64, gltf::Mesh<'_>, u64, u64)> = None;
        for mesh in self.document.meshes() {
            let k = instances[mesh.index()];
            if k == 0 {
                continue;
            }
            for p in mesh.primitives() {
                self.check_counted_accessors(&p).map_err(|e| {
                    format!("mesh {} primitive {}: {e}", mesh_label(&mesh), p.index())
                })?;
            }
            let per = mesh
                .primitives()
                .map(|p| declared_triangles(&p))
                .fold(0u64, u64::saturating_add);
            let all = per.saturating_mul(k);
            total = total.saturating_add(all);
            if largest.as_ref().is_none_or(|l| all > l.0) {
                largest = Some((all, mesh, per, k));
            }
        }
        let need = total.saturating_mul(LOADED_TRIANGLE_BYTES);
        let budget = self.options.memory_budget;
        if total <= MAX_TRIANGLES as u64 && need <= budget {
            return Ok(());
        }
        let most = largest.map_or_else(String::new, |(_, mesh, per, k)| {
            format!(
                ", most from mesh {} ({per} triangles × {k} nodes)",
                mesh_label(&mesh)
            )
        });
        Err(if total > MAX_TRIANGLES as u64 {
            format!(
                "the node hierarchy instances {total} triangles{most}, which need {} to load, \
                 more than the limit of {MAX_TRIANGLES} triangles",
                human_bytes(need)
            )
        } else {
            format!(
                "the node hierarchy instances {total} triangles{most}, which need {} to load, \
                 over the memory budget of {} (raise --memory-budget)",
                human_bytes(need),
                human_bytes(budget)
            )
        })
    }

    /// The accessors [`declared_triangles`] counts (indices, else
    /// positions) checked against the loaded data, as [`Self::add_primitive`]
    /// checks them.
    fn check_counted_accessors(&self, primitive: &gltf::Primitive<'_>) -> Result<(), String> {
        if let Some(positions) = primitive.get(&Semantic::Positions) {
            accessor::check(
                &positions,
                &Expect {
                    role: "POSITION".into(),
                    types: &[DataType::F32],
                    dimensions: Dimensions::Vec3,
                },
                self.buffers,
            )?;
        }
        if let Some(indices) = primitive.indices() {
            accessor::check(
                &indices,
                &Expect {
                    role: "indices".into(),
                    types: &[DataType::U8, DataType::U16, DataType::U32],
                    dimensions: Dimensions::Scalar,
                },
                self.buffers,
            )?;
        }
        Ok(())
    }

    fn add_mesh(
        &mut self,
        node: &gltf::Node<'_>,
        mesh: &gltf::Mesh<'_>,
        world: &DMat4,
    ) -> Result<(), String> {
        let name = node
            .name()
            .or(mesh.name())
            .map_or_else(|| format!("node{}", node.index()), str::to_string);
        let surface = self.surfaces.len() as u32;
        self.surfaces.push(Surface {
            name,
            node: node.index(),
        });
        let flip = world.determinant() < 0.0;
        for primitive in mesh.primitives() {
            let label = format!("mesh {} primitive {}", mesh_label(mesh), primitive.index());
            self.add_primitive(&primitive, world, flip, surface)
                .map_err(|e| format!("{label}: {e}"))?;
        }
        Ok(())
    }

    fn add_primitive(
        &mut self,
        primitive: &gltf::Primitive<'_>,
        world: &DMat4,
        flip: bool,
        surface: u32,
    ) -> Result<(), String> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Err(format!(
                "primitive mode {mode:?} is not supported (only triangles, strips and fans)"
            ));
        }
        let buffers = self.buffers;
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));

        let position_accessor = primitive
            .get(&Semantic::Positions)
            .ok_or("no POSITION attribute")?;
        accessor::check(
            &position_accessor,
            &Expect {
                role: "POSITION".into(),
                types: &[DataType::F32],
                dimensions: Dimensions::Vec3,
            },
            buffers,
        )?;
        let n_vertices = position_accessor.count();
        let mut positions = Vec::with_capacity(n_vertices);
        for (i, p) in reader
            .read_positions()
            .ok_or("POSITION data is unreadable")?
            .enumerate()
        {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(format!("vertex {i} has a non-finite position {p:?}"));
            }
            let world_p = world.transform_point3(DVec3::from_array(p.map(f64::from)));
            if !(world_p.abs().max_element() <= MAX_COORDINATE) {
                return Err(format!(
                    "vertex {i} lies at {world_p} in world space, beyond the supported \
                     ±{MAX_COORDINATE:e} m"
                ));
            }
            positions.push(world_p);
        }

        let indices: Vec<u32> = match primitive.indices() {
            Some(acc) => {
                accessor::check(
                    &acc,
                    &Expect {
                        role: "indices".into(),
                        types: &[DataType::U8, DataType::U16, DataType::U32],
                        dimensions: Dimensions::Scalar,
                    },
                    buffers,
                )?;
                let indices: Vec<u32> = reader
                    .read_indices()
                    .ok_or("index data is unreadable")?
                    .into_u32()
                    .collect();
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= n_vertices) {
                    return Err(format!("index {bad} out of range ({n_vertices} vertices)"));
                }
                indices
            }
            None => {
                let n = u32::try_from(n_vertices)
                    .map_err(|_| format!("{n_vertices} vertices are too many"))?;
                (0..n).collect()
            }
        };
        let corners = assemble(mode, &indices, flip, &mut self.dropped_indices);
        if self.triangles.len() + corners.len() > MAX_TRIANGLES {
            return Err(format!("the scene has more than {MAX_TRIANGLES} triangles"));
        }

        let material = self.material(primitive)?;
        let loaded = self.materials[material as usize].clone();
        let reflectance = self.slot_means(
            primitive,
            loaded
                .base_texture
                .as_ref()
                .filter(|_| loaded.base_factor != DVec3::ZERO),
            &corners,
            n_vertices,
        )?;
        let emission = self.slot_means(
            primitive,
            loaded
                .emissive_texture
                .as_ref()
                .filter(|_| loaded.emission != DVec3::ZERO),
            &corners,
            n_vertices,
        )?;
        let tex_coords = self.tex_coords(primitive, 0, n_vertices)?;
        let lightmap_coords = self.tex_coords(primitive, 1, n_vertices)?;
        let origin = |c: &[u32; 3]| TriangleOrigin {
            primitive: primitive.index() as u32,
            tex_coords: tex_coords.as_ref().map(|uv| c.map(|i| uv[i as usize])),
            lightmap_coords: lightmap_coords.as_ref().map(|uv| c.map(|i| uv[i as usize])),
        };
        let max = self.options.max_reflectance;
        self.triangles.reserve(corners.len());
        for (t, c) in corners.iter().enumerate() {
            let mut rho = loaded.base_factor * reflectance.as_ref().map_or(DVec3::ONE, |r| r[t]);
            if rho.max_element() >= max {
                self.clamped[material as usize] = true;
                rho = rho.min(DVec3::splat(max));
            }
            let emitted = loaded.emission * emission.as_ref().map_or(DVec3::ONE, |e| e[t]);
            self.triangles.push(InputTriangle {
                positions: c.map(|i| positions[i as usize]),
                material,
                surface,
                reflectance: rho,
                emitted_radiance: emitted,
                origin: origin(c),
            });
        }
        Ok(())
    }

    /// Per-triangle texture means of one material slot, or `None` without a
    /// texture (or when its factor is zero, so the texture cannot matter).
    fn slot_means(
        &mut self,
        primitive: &gltf::Primitive<'_>,
        slot: Option<&TextureSlot>,
        corners: &[[u32; 3]],
        n_vertices: usize,
    ) -> Result<Option<Vec<DVec3>>, String> {
        let Some(slot) = slot else {
            return Ok(None);
        };
        let set = slot.tex_coord;
        let Some(raw) = self.tex_coords(primitive, set, n_vertices)? else {
            return Err(format!(
                "the material's {} uses TEXCOORD_{set}, which the primitive lacks",
                slot.role
            ));
        };
        let uvs: Vec<DVec2> = raw
            .into_iter()
            .map(|[u, v]| {
                let uv = DVec2::new(u.into(), v.into());
                slot.transform.map_or(uv, |t| t.apply(uv))
            })
            .collect();
        let texture = self.texture(slot.image)?;
        let sampler = slot.sampler;
        Ok(Some(
            corners
                .par_iter()
                .map(|c| texture.triangle_mean(c.map(|i| uvs[i as usize]), &sampler))
                .collect(),
        ))
    }

    /// The decoded texture of image `index`, decoding it on first use of
    /// its content; the decode is checked against the memory budget, less
    /// what the textures decoded so far keep.
    fn texture(&mut self, index: usize) -> Result<Arc<Texture>, String> {
        if let Some(t) = self.textures.get(&index) {
            return Ok(t.clone());
        }
        // An external file: entries naming the same file share its decode;
        // its header and size are checked before it is read whole.
        let file = self.image_file(index).map(|path| {
            let key = std::fs::canonicalize(&path).unwrap_or_else(|_| path.clone());
            (path, key)
        });
        if let Some((path, key)) = &file {
            if let Some(t) = self.decoded_files.get(key) {
                let t = t.clone();
                self.textures.insert(index, t.clone());
                return Ok(t);
            }
            texture::check_file(path, self.options.memory_budget, self.texture_bytes).map_err(
                |e| {
                    let shown = short(&path.display().to_string());
                    format!("{}: '{shown}': {e}", self.image_label(index))
                },
            )?;
        }
        let bytes = self.image_bytes(index, self.texture_bytes)?;
        let texture = match self.decoded.get(&bytes) {
            Some(t) => t.clone(),
            None => {
                let texture = Arc::new(
                    Texture::decode(&bytes, self.options.memory_budget, self.texture_bytes)
                        .map_err(|e| format!("{}: cannot decode: {e}", self.image_label(index)))?,
                );
                // The encoded bytes stay too, as the key of the decode.
                self.texture_bytes += texture.bytes() + bytes.len() as u64;
                self.decoded.insert(bytes, texture.clone());
                texture
            }
        };
        if let Some((_, key)) = file {
            self.decoded_files.insert(key, texture.clone());
        }
        self.textures.insert(index, texture.clone());
        Ok(texture)
    }

    /// The file image `index` names by a relative URI, resolved against
    /// the scene's folder (`check_uris` has kept it inside), or `None`
    /// for an image in a buffer or a data URI.
    fn image_file(&self, index: usize) -> Option<PathBuf> {
        let image = self.document.images().nth(index)?;
        let gltf::image::Source::Uri { uri, .. } = image.source() else {
            return None;
        };
        if uri.contains(':') {
            return None;
        }
        let decoded = urlencoding::decode(uri).ok()?;
        Some(self.base?.join(decoded.as_ref()))
    }

    /// `image N ('name')`, for messages.
    fn image_label(&self, index: usize) -> String {
        match self.document.images().nth(index).and_then(|i| i.name()) {
            Some(name) => format!("image {index} ('{}')", short(name)),
            None => format!("image {index}"),
        }
    }

    /// The encoded bytes of image `index`, wherever the file keeps them.
    /// An external file is read only when its size, with the `in_use`
    /// bytes already held, fits the memory budget.
    fn image_bytes(&self, index: usize, in_use: u64) -> Result<Vec<u8>, String> {
        let image = self
            .document
            .images()
            .nth(index)
            .ok_or_else(|| format!("image {index} does not exist"))?;
        let label = self.image_label(index);
        Ok(match image.source() {
            gltf::image::Source::View { view, .. } => {
                let data = self
                    .buffers
                    .get(view.buffer().index())
                    .map_or(&[][..], |d| &d.0[..]);
                let range = view.offset()..view.offset().saturating_add(view.length());
                data.get(range)
                    .ok_or_else(|| {
                        format!("{label}: buffer view {} exceeds its buffer", view.index())
                    })?
                    .to_vec()
            }
            gltf::image::Source::Uri { .. } if let Some(path) = self.image_file(index) => {
                read_bounded(&path, self.options.memory_budget, in_use).map_err(|e| {
                    format!("{label}: '{}': {e}", short(&path.display().to_string()))
                })?
            }
            gltf::image::Source::Uri { uri, .. } => {
                gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), self.base)
                    .map_err(|e| {
                        format!("{label}: cannot read '{}': {}", short(uri), describe(&e))
                    })?
                    .0
            }
        })
    }

    /// The primitive's `TEXCOORD_<set>` as f32 pairs (normalized integers
    /// mapped to [0, 1]), or `None` when it has none.
    fn tex_coords(
        &self,
        primitive: &gltf::Primitive<'_>,
        set: u32,
        n_vertices: usize,
    ) -> Result<Option<Vec<[f32; 2]>>, String> {
        let Some(acc) = primitive.get(&Semantic::TexCoords(set)) else {
            return Ok(None);
        };
        let role = format!("TEXCOORD_{set}");
        accessor::check(
            &acc,
            &Expect {
                role: role.clone(),
                types: &[DataType::F32, DataType::U8, DataType::U16],
                dimensions: Dimensions::Vec2,
            },
            self.buffers,
        )?;
        if acc.data_type() != DataType::F32 && !acc.normalized() {
            return Err(format!(
                "{role} accessor {} holds integers that are not normalized",
                acc.index()
            ));
        }
        if acc.count() != n_vertices {
            return Err(format!(
                "{role} has {} elements but POSITION has {n_vertices}",
                acc.count()
            ));
        }
        let buffers = self.buffers;
        let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let uvs: Vec<[f32; 2]> = reader
            .read_tex_coords(set)
            .ok_or_else(|| format!("{role} data is unreadable"))?
            .into_f32()
            .collect();
        if let Some(i) = uvs.iter().position(|uv| !uv.iter().all(|c| c.is_finite())) {
            return Err(format!("vertex {i} has a non-finite {role} {:?}", uvs[i]));
        }
        Ok(Some(uvs))
    }

    /// The KHR_lights_punctual light node `index` places, in world space
    /// (read from the JSON without the `gltf` crate's getters, which
    /// unwrap). Position and direction (local −z) come from the node's
    /// world transform, whose scale does not change the light. Errors name
    /// the light: an index the file does not define, an unknown type, a
    /// negative or non-finite intensity or colour, a spot's cone angles
    /// outside 0 ≤ inner < outer ≤ π/2, a range that is not positive.
    fn punctual_light(&self, index: usize, world: &DMat4) -> Result<Option<PunctualLight>, String> {
        use gltf::json::extensions::scene::khr_lights_punctual::Type;
        use gltf::json::validation::Checked;
        let json = self.document.as_json();
        let Some(light) = json
            .nodes
            .get(index)
            .and_then(|n| n.extensions.as_ref()?.khr_lights_punctual.as_ref())
            .map(|l| l.light.value())
        else {
            return Ok(None);
        };
        let defined = json
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .and_then(|e| e.lights.get(light));
        let Some(def) = defined else {
            return Err(format!(
                "node {index} places KHR_lights_punctual light {light}, which the file does not \
                 define"
            ));
        };
        let label = match &def.name {
            Some(name) => format!("light {light} '{}'", short(name)),
            None => format!("light {light}"),
        };
        let colour = DVec3::from(def.color.map(f64::from));
        let intensity = f64::from(def.intensity);
        if !(colour.is_finite()
            && colour.min_element() >= 0.0
            && intensity.is_finite()
            && intensity >= 0.0)
        {
            return Err(format!(
                "{label}: colour {:?} and intensity {intensity} must be finite and not negative",
                def.color
            ));
        }
        let range = def.range.map(f64::from);
        if range.is_some_and(|r| !(r > 0.0 && r.is_finite())) {
            return Err(format!("{label}: range {range:?} must be positive"));
        }
        let kind = match def.type_ {
            Checked::Valid(Type::Point) => LightKind::Point,
            Checked::Valid(Type::Directional) => LightKind::Directional,
            Checked::Valid(Type::Spot) => {
                let (inner, outer) = def
                    .spot
                    .as_ref()
                    .map_or((0.0, std::f64::consts::FRAC_PI_4), |s| {
                        (f64::from(s.inner_cone_angle), f64::from(s.outer_cone_angle))
                    });
                if !(0.0 <= inner && inner < outer && outer <= std::f64::consts::FRAC_PI_2 + 1e-6) {
                    return Err(format!(
                        "{label}: spot cone angles inner {inner} and outer {outer} must satisfy \
                         0 <= inner < outer <= pi/2"
                    ));
                }
                LightKind::Spot {
                    cos_inner: inner.cos(),
                    cos_outer: outer.cos().max(0.0),
                }
            }
            Checked::Invalid => {
                return Err(format!(
                    "{label}: unknown light type (point, spot and directional are read)"
                ));
            }
        };
        let direction = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
        if direction == DVec3::ZERO && kind != LightKind::Point {
            return Err(format!(
                "{label}: the node's transform has no direction (zero scale)"
            ));
        }
        let mut placed = PunctualLight {
            name: String::new(),
            kind,
            position: world.transform_point3(DVec3::ZERO),
            direction,
            intensity: colour * intensity,
            range: if kind == LightKind::Directional {
                None
            } else {
                range
            },
        };
        placed.name = match &def.name {
            Some(name) => short(name),
            None => format!("{} light {light}", placed.kind_name()),
        };
        Ok(Some(placed))
    }

    /// The glTF material index behind each of our materials.
    fn material_sources(&self) -> Vec<Option<usize>> {
        let mut sources = vec![None; self.materials.len()];
        for (&gltf_index, &ours) in &self.material_ids {
            sources[ours as usize] = gltf_index;
        }
        sources
    }

    /// Our index of the primitive's material, converting it on first use.
    fn material(&mut self, primitive: &gltf::Primitive<'_>) -> Result<u32, String> {
        let material = primitive.material();
        let key = material.index();
        if let Some(&id) = self.material_ids.get(&key) {
            return Ok(id);
        }
        let loaded = self.convert_material(&material)?;
        let id = self.materials.len() as u32;
        self.clamped
            .push(loaded.material.reflectance != loaded.base_factor);
        self.materials.push(loaded);
        self.material_ids.insert(key, id);
        Ok(id)
    }

    fn convert_material(&mut self, m: &gltf::Material<'_>) -> Result<LoadedMaterial, String> {
        let name = match (m.name(), m.index()) {
            (Some(name), _) => name.to_string(),
            (None, Some(i)) => format!("material{i}"),
            (None, None) => "default".to_string(),
        };
        let label = format!("material '{name}'");
        let pbr = m.pbr_metallic_roughness();
        let [r, g, b, _] = pbr.base_color_factor();
        let base_factor = DVec3::new(r.into(), g.into(), b.into());
        if !(base_factor.is_finite() && base_factor.min_element() >= 0.0) {
            return Err(format!(
                "{label}: baseColorFactor {base_factor} is not a colour"
            ));
        }
        let strength = f64::from(m.emissive_strength().unwrap_or(1.0));
        let emission = DVec3::from_array(m.emissive_factor().map(f64::from)) * strength;
        if !(emission.is_finite() && emission.min_element() >= 0.0) {
            return Err(format!(
                "{label}: emissive factor × strength {emission} is negative or not finite"
            ));
        }
        let base_texture = pbr
            .base_color_texture()
            .map(|info| texture_slot(&info, "baseColorTexture"))
            .transpose()
            .map_err(|e| format!("{label}: {e}"))?;
        let emissive_texture = m
            .emissive_texture()
            .map(|info| texture_slot(&info, "emissiveTexture"))
            .transpose()
            .map_err(|e| format!("{label}: {e}"))?;

        let mut ignore = |feature: &'static str| {
            self.ignored.entry(feature).or_default().push(name.clone());
        };
        if pbr.metallic_factor() > 0.0 || pbr.metallic_roughness_texture().is_some() {
            ignore("metallic");
        }
        if pbr.roughness_factor() < 1.0 || pbr.metallic_roughness_texture().is_some() {
            ignore("roughness");
        }
        if m.normal_texture().is_some() {
            ignore("normal maps");
        }
        if m.occlusion_texture().is_some() {
            ignore("occlusion maps");
        }
        if m.alpha_mode() != gltf::material::AlphaMode::Opaque {
            ignore("transparency (alphaMode)");
        }
        if m.unlit() {
            ignore("KHR_materials_unlit");
        }

        let max = self.options.max_reflectance;
        Ok(LoadedMaterial {
            material: Material {
                name,
                reflectance: base_factor.min(DVec3::splat(max)),
                emitted_radiance: emission,
                double_sided: m.double_sided(),
            },
            base_factor,
            base_texture,
            emission,
            emissive_texture,
        })
    }

    fn add_camera(&mut self, node: &gltf::Node<'_>, camera: &gltf::Camera<'_>, world: &DMat4) {
        let name = camera
            .name()
            .or(node.name())
            .map_or_else(|| format!("camera{}", camera.index()), str::to_string);
        let perspective = match camera.projection() {
            gltf::camera::Projection::Perspective(p) => p,
            gltf::camera::Projection::Orthographic(_) => {
                self.warnings.push(format!(
                    "camera '{name}' is orthographic; only perspective cameras are used"
                ));
                return;
            }
        };
        let yfov = f64::from(perspective.yfov());
        let aspect_ratio = perspective.aspect_ratio().map(f64::from);
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
        let up = world.transform_vector3(DVec3::Y);
        let up = (up - up.dot(forward) * forward).normalize_or_zero();
        let valid_fov = yfov > 0.0 && yfov < std::f64::consts::PI;
        let valid_aspect = aspect_ratio.is_none_or(|a| a.is_finite() && a > 0.0);
        if forward == DVec3::ZERO || up == DVec3::ZERO || !valid_fov || !valid_aspect {
            self.warnings.push(format!(
                "camera '{name}' has a degenerate view (direction, up, yfov or aspect ratio); skipped"
            ));
            return;
        }
        self.cameras.push(Camera {
            name,
            eye,
            forward,
            up,
            yfov,
            aspect_ratio,
        });
    }

    /// Scene-wide warnings, appended after the per-item ones.
    fn finish_warnings(&mut self) -> Vec<String> {
        let mut warnings = std::mem::take(&mut self.warnings);
        if self.dropped_indices > 0 {
            warnings.push(format!(
                "ignored {} trailing index(es) that did not form a whole triangle",
                self.dropped_indices
            ));
        }
        for (m, clamped) in self.materials.iter().zip(&self.clamped) {
            if *clamped {
                warnings.push(format!(
                    "material '{}': reflectance clamped to {} (components at or above it)",
                    m.material.name, self.options.max_reflectance
                ));
            }
        }
        let mut ignored: Vec<String> = self
            .ignored
            .iter()
            .map(|(feature, names)| format!("{feature} ({})", quoted_list(names)))
            .collect();
        for ext in self.document.extensions_used() {
            if IGNORED_EXTENSIONS.contains(&ext) {
                ignored.push(ext.to_string());
            }
        }
        if !ignored.is_empty() {
            warnings.push(format!(
                "ignored by the diffuse model: {}",
                ignored.join("; ")
            ));
        }
        warnings
    }
}

/// Resolves a textureInfo: image, texture coordinate set, sampler, transform.
fn texture_slot(info: &gltf::texture::Info<'_>, role: &'static str) -> Result<TextureSlot, String> {
    let texture = info.texture();
    let mut tex_coord = info.tex_coord();
    let transform = match info.texture_transform() {
        Some(t) => {
            if let Some(set) = t.tex_coord() {
                tex_coord = set;
            }
            let [ox, oy] = t.offset();
            let [sx, sy] = t.scale();
            let transform = UvTransform {
                offset: DVec2::new(ox.into(), oy.into()),
                rotation: t.rotation().into(),
                scale: DVec2::new(sx.into(), sy.into()),
            };
            if !(transform.offset.is_finite()
                && transform.scale.is_finite()
                && transform.rotation.is_finite())
            {
                return Err(format!("{role}: KHR_texture_transform is not finite"));
            }
            Some(transform)
        }
        None => None,
    };
    Ok(TextureSlot {
        image: texture.source().index(),
        tex_coord,
        sampler: Sampler::from_gltf(&texture.sampler()),
        transform,
        role,
    })
}

/// Triangles (vertex indices, counter-clockwise in world space) of a
/// triangle-list, strip or fan index sequence.
fn assemble(mode: Mode, indices: &[u32], flip: bool, dropped: &mut usize) -> Vec<[u32; 3]> {
    let mut tris: Vec<[u32; 3]> = match mode {
        Mode::Triangles => {
            *dropped += indices.len() % 3;
            indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        }
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[0], w[2], w[1]]
                }
            })
            .collect(),
        Mode::TriangleFan => indices
            .windows(2)
            .skip(1)
            .map(|w| [w[0], w[1], indices[0]])
            .collect(),
        _ => Vec::new(),
    };
    if flip {
        for t in &mut tris {
            t.swap(1, 2);
        }
    }
    tris
}

/// Why a node's column-major `matrix` is not T·R·S, or `None` when it is:
/// its last row must be (0, 0, 0, 1) (no projection) and its first three
/// columns must be mutually orthogonal (no shear), to a relative 10⁻⁴ as
/// float data allows. A zero column is a zero scale, which is allowed.
fn not_decomposable(m: &[f32; 16]) -> Option<String> {
    let m = m.map(f64::from);
    if m.iter().any(|v| !v.is_finite()) {
        return Some("it has a non-finite entry".into());
    }
    let column = |j: usize| DVec3::new(m[4 * j], m[4 * j + 1], m[4 * j + 2]);
    let size = (0..4).map(|j| column(j).length()).fold(1.0, f64::max);
    let row = [m[3], m[7], m[11], m[15]];
    let tol = 1e-4;
    if row[..3].iter().any(|v| v.abs() > tol * size) || (row[3] - 1.0).abs() > tol {
        return Some(format!(
            "its last row is {row:?}, not [0, 0, 0, 1]: a projection"
        ));
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let (u, v) = (column(a), column(b));
        if u.dot(v).abs() > tol * u.length() * v.length() {
            return Some(format!("columns {a} and {b} are not orthogonal: a shear"));
        }
    }
    None
}

/// The node's local transform in f64 (matrix, or T·R·S).
fn local_transform(node: &gltf::Node<'_>) -> Result<DMat4, String> {
    match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => {
            Ok(DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from))))
        }
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => {
            let q = DQuat::from_array(rotation.map(f64::from));
            let len = q.length();
            if !(len.is_finite() && len > 0.0) {
                return Err(format!(
                    "node {}: rotation {rotation:?} is not a quaternion",
                    node_label(node)
                ));
            }
            Ok(DMat4::from_scale_rotation_translation(
                DVec3::from_array(scale.map(f64::from)),
                q / len,
                DVec3::from_array(translation.map(f64::from)),
            ))
        }
    }
}

fn node_label(node: &gltf::Node<'_>) -> String {
    match node.name() {
        Some(name) => format!("'{}' ({})", short(name), node.index()),
        None => node.index().to_string(),
    }
}

fn mesh_label(mesh: &gltf::Mesh<'_>) -> String {
    match mesh.name() {
        Some(name) => format!("'{}'", short(name)),
        None => mesh.index().to_string(),
    }
}

/// A name or URI cut to a length that keeps messages on one line.
/// The whole file at `path`, refused unread when its size, with `in_use`
/// bytes already held, is over `memory_budget`; at most that many bytes
/// are read even if the file grows meanwhile.
fn read_bounded(path: &Path, memory_budget: u64, in_use: u64) -> Result<Vec<u8>, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read the file: {e}"))?;
    let len = file
        .metadata()
        .map_err(|e| format!("cannot read the file: {e}"))?
        .len();
    texture::check_file_size(len, memory_budget, in_use)?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(len)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read the file: {e}"))?;
    Ok(bytes)
}

fn short(s: &str) -> String {
    const MAX: usize = 80;
    let one_line: String = s
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    if one_line.chars().count() > MAX {
        format!("{}…", one_line.chars().take(MAX).collect::<String>())
    } else {
        one_line
    }
}

fn quoted_list(names: &[String]) -> String {
    names
        .iter()
        .map(|n| format!("'{}'", short(n)))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_keep_the_winding() {
        let mut dropped = 0;
        let strip = assemble(Mode::TriangleStrip, &[0, 1, 2, 3], false, &mut dropped);
        assert_eq!(strip, vec![[0, 1, 2], [1, 3, 2]]);
        let fan = assemble(Mode::TriangleFan, &[0, 1, 2, 3], false, &mut dropped);
        assert_eq!(fan, vec![[1, 2, 0], [2, 3, 0]]);
        let list = assemble(Mode::Triangles, &[0, 1, 2, 3], true, &mut dropped);
        assert_eq!(list, vec![[0, 2, 1]]);
        assert_eq!(dropped, 1);
    }
}
