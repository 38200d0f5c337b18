//! OpenEXR encoding and decoding: `solution.exr` (the per-vertex results) and
//! float RGB images. The only user of the `exr` crate.
//!
//! `solution.exr` layout (the user-facing contract):
//!
//! ```text
//! part "vertices"   width 1024, height max(1, ceil(n / 1024)), attribute vertexCount = n (int)
//!   float32 R G B (radiosity B), H.R H.G H.B (irradiance H; B = E + ρ H),
//!           P.X P.Y P.Z (position), N.X N.Y N.Z (unit normal)
//!   uint32  patch (input patch index)
//! part "triangles"  width 1024, height max(1, ceil(m / 1024)), attribute triangleCount = m (int)
//!   uint32  I0 I1 I2 (vertex indices, counter-clockwise seen from the front)
//!
//! item k (vertex or triangle) sits at x = k mod 1024, y = k div 1024:
//!   y=0  | 0    | 1    | ... | 1023 |
//!   y=1  | 1024 | 1025 | ... | 2047 |
//!   ...  | ...  | n-1  | 0 (unused, zero) ... |
//! ```
//!
//! Every file this module writes describes itself in its header: the
//! standard `software` ("nusselt <version>"), `comments` (the quantity and
//! its units in words) and `chromaticities` (linear Rec. 709 primaries, D65
//! white), and one `nusselt` string-vector attribute of `key=value` entries
//! naming each channel group's quantity and units, the scene and, where
//! they apply, the display exposure and the view ([`ImageInfo`]); an image
//! rendered from a view also carries the standard `worldToCamera`,
//! `fieldOfViewHorizontal` and `fieldOfViewVertical`. Each part's data
//! window is its own size; the display window, which OpenEXR requires to be
//! the same in every part of a file, covers both parts of `solution.exr`.
//! The custom entries share one attribute so that the header's bytes do not
//! depend on a hash map's order.
//!
//! Invariants: compression is lossless (ZIP, 16 lines per block), so
//! [`read_solution`] returns exactly the [`OutputMesh`] that
//! [`encode_solution`] was given, bit for bit; unused pixels are zero; the
//! readers check every count, channel, type and index before trusting it and
//! report problems as [`Error::Input`] naming the file.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

use ::exr::meta::attribute::Chromaticities;
use ::exr::prelude::*;
use glam::Vec3;

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;
use crate::render::frame::Frame;
use crate::render::view::View;

/// Width in pixels of both parts of `solution.exr`.
pub const ROW_WIDTH: usize = 1024;
/// Name of the per-vertex part.
pub const VERTICES_PART: &str = "vertices";
/// Name of the per-triangle part.
pub const TRIANGLES_PART: &str = "triangles";
/// Header attribute of the vertices part holding the vertex count.
pub const VERTEX_COUNT_ATTRIBUTE: &str = "vertexCount";
/// Header attribute of the triangles part holding the triangle count.
pub const TRIANGLE_COUNT_ATTRIBUTE: &str = "triangleCount";

/// What the solution encoder names in its errors.
const SOLUTION: &str = "the solution (OpenEXR)";
/// What the image encoder names in its errors.
const IMAGE: &str = "the image (OpenEXR)";

/// Name of the string-vector header attribute holding nusselt's
/// `key=value` description of the file.
pub const INFO_ATTRIBUTE: &str = "nusselt";

/// What the R, G, B channels of an image hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Radiance toward the camera, W/(m² sr): renders and references.
    Radiance,
    /// The standard error of a path-traced radiance estimate, W/(m² sr).
    RadianceStandardError,
    /// Test minus reference radiance, W/(m² sr) (`nusselt compare`).
    RadianceDifference,
    /// Radiosity B, W/m² (lightmaps).
    Radiosity,
    /// Irradiance H, W/m² (lightmaps).
    Irradiance,
}

impl Quantity {
    /// The quantity's name as the header gives it.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Radiance => "radiance",
            Quantity::RadianceStandardError => "standard error of radiance",
            Quantity::RadianceDifference => "radiance difference (test - reference)",
            Quantity::Radiosity => "radiosity",
            Quantity::Irradiance => "irradiance",
        }
    }

    /// Its units, in ASCII.
    pub fn units(self) -> &'static str {
        match self {
            Quantity::Radiosity | Quantity::Irradiance => "W/m^2",
            _ => "W/(m^2 sr)",
        }
    }
}

/// What an image's header says about it (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageInfo<'a> {
    /// What the pixels hold.
    pub quantity: Quantity,
    /// The scene file, as given; omitted when empty.
    pub scene: &'a str,
    /// The view the image was rendered from.
    pub view: Option<&'a View>,
    /// The exposure of the image's display PNG, where one was written.
    pub exposure: Option<f32>,
}

impl<'a> ImageInfo<'a> {
    /// An image of `quantity` with nothing else known.
    pub fn new(quantity: Quantity) -> ImageInfo<'a> {
        ImageInfo {
            quantity,
            scene: "",
            view: None,
            exposure: None,
        }
    }

    /// The same, of the scene file `scene`.
    pub fn scene(self, scene: &'a str) -> ImageInfo<'a> {
        ImageInfo { scene, ..self }
    }

    /// The same, rendered from `view`.
    pub fn view(self, view: Option<&'a View>) -> ImageInfo<'a> {
        ImageInfo { view, ..self }
    }

    /// The same, displayed at `exposure`.
    pub fn exposure(self, exposure: Option<f32>) -> ImageInfo<'a> {
        ImageInfo { exposure, ..self }
    }
}

/// Header text: OpenEXR strings are bytes, these are UTF-8.
fn text(s: &str) -> Text {
    Text::from_slice_unchecked(s.as_bytes())
}

/// Linear Rec. 709 primaries with a D65 white point.
fn rec709() -> Chromaticities {
    Chromaticities {
        red: Vec2(0.64, 0.33),
        green: Vec2(0.30, 0.60),
        blue: Vec2(0.15, 0.06),
        white: Vec2(0.3127, 0.3290),
    }
}

/// The attributes every part of a file shares: the chromaticities and the
/// `nusselt` entries.
fn shared_attributes(display: IntegerBounds, entries: &[String]) -> ImageAttributes {
    let mut shared = ImageAttributes::new(display);
    shared.chromaticities = Some(rec709());
    shared.other.insert(
        text(INFO_ATTRIBUTE),
        AttributeValue::TextVector(entries.iter().map(|e| text(e)).collect()),
    );
    shared
}

/// A part's own standard attributes: software and comments.
fn own_attributes(name: Option<&str>, comments: &str) -> LayerAttributes {
    let mut own = match name {
        Some(name) => LayerAttributes::named(name),
        None => LayerAttributes::default(),
    };
    own.software_name = Some(text(&format!("nusselt {}", env!("CARGO_PKG_VERSION"))));
    own.comments = Some(text(comments));
    own
}

/// `worldToCamera` of `view`: OpenEXR's camera space is left-handed, x
/// right, y up, z forward, and its matrices act on row vectors (the
/// translation in the last row).
fn world_to_camera(view: &View) -> [f32; 16] {
    let (r, u, f, e) = (view.right, view.up, view.forward, view.eye);
    let m = [
        [r.x, u.x, f.x, 0.0],
        [r.y, u.y, f.y, 0.0],
        [r.z, u.z, f.z, 0.0],
        [-r.dot(e), -u.dot(e), -f.dot(e), 1.0],
    ];
    std::array::from_fn(|k| m[k / 4][k % 4] as f32)
}

/// Rows needed for `count` items, at least one (OpenEXR has no empty parts).
fn rows_for(count: usize) -> usize {
    count.div_ceil(ROW_WIDTH).max(1)
}

/// The whole file in memory, with all parts, channels and attributes.
type FlatImage = Image<Layers<AnyChannels<FlatSamples>>>;
type FlatLayer = Layer<AnyChannels<FlatSamples>>;

/// Serialises an image into bytes.
fn write_bytes(image: &FlatImage, what: &'static str) -> Result<Vec<u8>> {
    let mut cursor = Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut cursor)
        .map_err(|e| Error::encode(what, e))?;
    Ok(cursor.into_inner())
}

/// Parses a whole OpenEXR file held in memory.
fn read_bytes(bytes: &[u8], source: &Path) -> Result<FlatImage> {
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| Error::input(source, format!("not a readable OpenEXR file: {e}")))
}

/// Reads a whole file into memory.
fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::input(path, e))
}

/// A float channel of `len` pixels holding `values` then zeros.
fn f32_channel(
    name: &str,
    len: usize,
    values: impl Iterator<Item = f32>,
) -> AnyChannel<FlatSamples> {
    let mut samples: Vec<f32> = values.collect();
    samples.resize(len, 0.0);
    AnyChannel::new(name, FlatSamples::F32(samples))
}

/// An unsigned integer channel of `len` pixels holding `values` then zeros.
fn u32_channel(
    name: &str,
    len: usize,
    values: impl Iterator<Item = u32>,
) -> AnyChannel<FlatSamples> {
    let mut samples: Vec<u32> = values.collect();
    samples.resize(len, 0);
    AnyChannel::new(name, FlatSamples::U32(samples))
}

/// Component `axis` of each vector.
fn component(values: &[Vec3], axis: usize) -> impl Iterator<Item = f32> + '_ {
    values.iter().map(move |v| v[axis])
}

/// A part of `solution.exr` with its name, comments and count attribute.
fn solution_part(
    name: &str,
    comments: &str,
    count_attribute: &str,
    count: usize,
    channels: Vec<AnyChannel<FlatSamples>>,
) -> Result<FlatLayer> {
    let count = i32::try_from(count).map_err(|_| {
        Error::encode(
            SOLUTION,
            format!("{count} items do not fit the {name} part"),
        )
    })?;
    let mut attributes = own_attributes(Some(name), comments);
    attributes
        .other
        .insert(Text::from(count_attribute), AttributeValue::I32(count));
    Ok(Layer::new(
        (ROW_WIDTH, rows_for(count as usize)),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    ))
}

/// Encodes `mesh`, solved from the scene file `scene` (as given; omitted
/// from the header when empty), as the bytes of `solution.exr` (layout in
/// the module doc).
///
/// Fails when the per-vertex arrays differ in length, a triangle indexes a
/// missing vertex, or a count exceeds what an EXR `int` attribute holds.
pub fn encode_solution(mesh: &OutputMesh, scene: &str) -> Result<Vec<u8>> {
    let n = mesh.positions.len();
    if let Some(message) = mesh.length_mismatch() {
        return Err(Error::encode(SOLUTION, message));
    }
    if let Some((t, tri)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
    {
        return Err(Error::encode(
            SOLUTION,
            format!("triangle {t} {tri:?} indexes beyond the {n} vertices"),
        ));
    }

    let v_len = ROW_WIDTH * rows_for(n);
    let vertices = solution_part(
        VERTICES_PART,
        "per output vertex: radiosity B in W/m^2 (R G B), irradiance H in W/m^2 \
         (H.R H.G H.B), position in m (P.X P.Y P.Z), unit normal (N.X N.Y N.Z), \
         input patch index (patch); linear Rec. 709 RGB",
        VERTEX_COUNT_ATTRIBUTE,
        n,
        vec![
            f32_channel("R", v_len, component(&mesh.radiosity, 0)),
            f32_channel("G", v_len, component(&mesh.radiosity, 1)),
            f32_channel("B", v_len, component(&mesh.radiosity, 2)),
            f32_channel("H.R", v_len, component(&mesh.irradiance, 0)),
            f32_channel("H.G", v_len, component(&mesh.irradiance, 1)),
            f32_channel("H.B", v_len, component(&mesh.irradiance, 2)),
            f32_channel("P.X", v_len, component(&mesh.positions, 0)),
            f32_channel("P.Y", v_len, component(&mesh.positions, 1)),
            f32_channel("P.Z", v_len, component(&mesh.positions, 2)),
            f32_channel("N.X", v_len, component(&mesh.normals, 0)),
            f32_channel("N.Y", v_len, component(&mesh.normals, 1)),
            f32_channel("N.Z", v_len, component(&mesh.normals, 2)),
            u32_channel("patch", v_len, mesh.patch.iter().copied()),
        ],
    )?;

    let m = mesh.triangles.len();
    let t_len = ROW_WIDTH * rows_for(m);
    let corner = |c: usize| mesh.triangles.iter().map(move |t| t[c]);
    let triangles = solution_part(
        TRIANGLES_PART,
        "per output triangle: indices of its vertices in the vertices part, \
         counter-clockwise seen from the front (I0 I1 I2)",
        TRIANGLE_COUNT_ATTRIBUTE,
        m,
        vec![
            u32_channel("I0", t_len, corner(0)),
            u32_channel("I1", t_len, corner(1)),
            u32_channel("I2", t_len, corner(2)),
        ],
    )?;

    // The display window covers both parts' data windows.
    let display = IntegerBounds::from_dimensions((
        ROW_WIDTH,
        vertices.size.height().max(triangles.size.height()),
    ));
    let mut entries = vec![
        "R G B=radiosity [W/m^2]".to_string(),
        "H.R H.G H.B=irradiance [W/m^2]".to_string(),
        "P.X P.Y P.Z=position [m]".to_string(),
        "N.X N.Y N.Z=unit normal".to_string(),
        "patch=input patch index".to_string(),
    ];
    if !scene.is_empty() {
        entries.push(format!("scene={scene}"));
    }
    let image = Image::from_layers(
        shared_attributes(display, &entries),
        vec![vertices, triangles],
    );
    write_bytes(&image, SOLUTION)
}

/// Reads `solution.exr` from `path` (see [`decode_solution`]).
pub fn read_solution(path: &Path) -> Result<OutputMesh> {
    decode_solution(&read_file(path)?, path)
}

/// Decodes the bytes of a `solution.exr`; `source` names the file in errors.
///
/// Checks the parts, their widths, the count attributes against the pixel
/// counts, every channel's presence and sample type, that values are finite
/// and that triangle indices are below the vertex count.
pub fn decode_solution(bytes: &[u8], source: &Path) -> Result<OutputMesh> {
    let image = read_bytes(bytes, source)?;
    let vertices = SolutionPart::find(&image, VERTICES_PART, VERTEX_COUNT_ATTRIBUTE, source)?;
    let triangles = SolutionPart::find(&image, TRIANGLES_PART, TRIANGLE_COUNT_ATTRIBUTE, source)?;

    let n = vertices.count;
    let vec3s = |names: [&str; 3], what: &str| -> Result<Vec<Vec3>> {
        let [x, y, z] = names.map(|name| vertices.f32s(name));
        let (x, y, z) = (x?, y?, z?);
        (0..n)
            .map(|k| {
                let v = Vec3::new(x[k], y[k], z[k]);
                if v.is_finite() {
                    Ok(v)
                } else {
                    Err(Error::input(
                        source,
                        format!("vertex {k} has a non-finite {what} {v}"),
                    ))
                }
            })
            .collect()
    };
    let radiosity = vec3s(["R", "G", "B"], "radiosity")?;
    let irradiance = vec3s(["H.R", "H.G", "H.B"], "irradiance")?;
    let positions = vec3s(["P.X", "P.Y", "P.Z"], "position")?;
    let normals = vec3s(["N.X", "N.Y", "N.Z"], "normal")?;
    let patch = vertices.u32s("patch")?[..n].to_vec();

    let [i0, i1, i2] = ["I0", "I1", "I2"].map(|name| triangles.u32s(name));
    let (i0, i1, i2) = (i0?, i1?, i2?);
    let triangles = (0..triangles.count)
        .map(|t| {
            let tri = [i0[t], i1[t], i2[t]];
            if tri.iter().any(|&i| i as usize >= n) {
                Err(Error::input(
                    source,
                    format!("triangle {t} {tri:?} indexes beyond the {n} vertices"),
                ))
            } else {
                Ok(tri)
            }
        })
        .collect::<Result<Vec<_>>>()?;

    Ok(OutputMesh {
        positions,
        normals,
        patch,
        radiosity,
        irradiance,
        triangles,
    })
}

/// One part of a `solution.exr` whose name, width and count were checked.
struct SolutionPart<'a> {
    layer: &'a FlatLayer,
    name: &'static str,
    count: usize,
    source: &'a Path,
}

impl<'a> SolutionPart<'a> {
    fn find(
        image: &'a FlatImage,
        name: &'static str,
        count_attribute: &str,
        source: &'a Path,
    ) -> Result<SolutionPart<'a>> {
        let layer = image
            .layer_data
            .iter()
            .find(|l| l.attributes.layer_name.as_ref().is_some_and(|n| n.eq(name)))
            .ok_or_else(|| {
                Error::input(
                    source,
                    format!("no part named {name:?}; not a nusselt solution"),
                )
            })?;
        if layer.size.width() != ROW_WIDTH {
            return Err(Error::input(
                source,
                format!(
                    "part {name:?} is {} pixels wide, expected {ROW_WIDTH}",
                    layer.size.width()
                ),
            ));
        }
        let count = match layer.attributes.other.get(&Text::from(count_attribute)) {
            Some(AttributeValue::I32(c)) => *c,
            Some(_) => {
                return Err(Error::input(
                    source,
                    format!("attribute {count_attribute:?} of part {name:?} is not an int"),
                ));
            }
            None => {
                return Err(Error::input(
                    source,
                    format!("part {name:?} lacks the attribute {count_attribute:?}"),
                ));
            }
        };
        let pixels = layer.size.area();
        let count = usize::try_from(count)
            .ok()
            .filter(|&c| c <= pixels)
            .ok_or_else(|| {
                Error::input(
                    source,
                    format!(
                        "{count_attribute} = {count} in part {name:?} does not fit its {pixels} pixels"
                    ),
                )
            })?;
        Ok(SolutionPart {
            layer,
            name,
            count,
            source,
        })
    }

    /// The samples of channel `channel`, which must hold `count` values.
    fn samples(&self, channel: &str) -> Result<&'a FlatSamples> {
        let found = self
            .layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.eq(channel))
            .ok_or_else(|| {
                Error::input(
                    self.source,
                    format!("part {:?} lacks the channel {channel:?}", self.name),
                )
            })?;
        if found.sample_data.len() < self.count {
            return Err(Error::input(
                self.source,
                format!("channel {channel:?} of part {:?} is subsampled", self.name),
            ));
        }
        Ok(&found.sample_data)
    }

    fn wrong_type(&self, channel: &str, expected: &str) -> Error {
        Error::input(
            self.source,
            format!(
                "channel {channel:?} of part {:?} is not {expected}",
                self.name
            ),
        )
    }

    fn f32s(&self, channel: &str) -> Result<&'a [f32]> {
        match self.samples(channel)? {
            FlatSamples::F32(v) => Ok(v),
            _ => Err(self.wrong_type(channel, "float32")),
        }
    }

    fn u32s(&self, channel: &str) -> Result<&'a [u32]> {
        match self.samples(channel)? {
            FlatSamples::U32(v) => Ok(v),
            _ => Err(self.wrong_type(channel, "uint32")),
        }
    }
}

/// Encodes `frame` as a single-part OpenEXR image with float32 channels
/// R, G, B (linear Rec. 709), row 0 at the top, losslessly compressed, its
/// header describing it as `info` says (module doc).
pub fn encode_image(frame: &Frame, info: &ImageInfo) -> Result<Vec<u8>> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    if w == 0 || h == 0 {
        return Err(Error::encode(IMAGE, format!("the image is {w}×{h} pixels")));
    }
    if frame.pixels.len() != w * h {
        return Err(Error::encode(
            IMAGE,
            format!("{} pixels for a {w}×{h} image", frame.pixels.len()),
        ));
    }
    let channel =
        |name: &str, c: usize| f32_channel(name, w * h, frame.pixels.iter().map(|p| p[c]));
    let quantity = format!("{} [{}]", info.quantity.name(), info.quantity.units());
    let mut entries = vec![format!("R G B={quantity}")];
    let mut comments = format!("{quantity}, linear Rec. 709 RGB");
    if !info.scene.is_empty() {
        entries.push(format!("scene={}", info.scene));
        comments.push_str(&format!(", of {}", info.scene));
    }
    if let Some(exposure) = info.exposure {
        entries.push(format!("displayExposure={exposure}"));
    }
    let mut attributes = own_attributes(None, &comments);
    if let Some(view) = info.view {
        let yfov = view.yfov;
        let xfov =
            2.0 * ((yfov / 2.0).tan() * f64::from(view.width) / f64::from(view.height)).atan();
        attributes.world_to_camera = Some(world_to_camera(view));
        attributes.vertical_field_of_view = Some(yfov.to_degrees() as f32);
        attributes.horizontal_field_of_view = Some(xfov.to_degrees() as f32);
        entries.push(format!(
            "view=eye {:?} forward {:?} up {:?} yfov {:.6} rad",
            view.eye.to_array(),
            view.forward.to_array(),
            view.up.to_array(),
            yfov
        ));
    }
    let layer = Layer::new(
        (w, h),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![
            channel("R", 0),
            channel("G", 1),
            channel("B", 2),
        ])),
    );
    let display = IntegerBounds::from_dimensions(layer.size);
    write_bytes(
        &Image::from_layers(shared_attributes(display, &entries), vec![layer]),
        IMAGE,
    )
}

/// Reads an RGB image from `path` (see [`decode_image`]).
pub fn read_image(path: &Path) -> Result<Frame> {
    decode_image(&read_file(path)?, path)
}

/// Decodes an OpenEXR image; `source` names the file in errors.
///
/// Takes the first RGB layer: the parts in file order, and within a part
/// the plain channels `R`, `G`, `B` first, then layers named by a prefix
/// (`diffuse.R`, …) in alphabetical order. Half and float samples are
/// accepted, alpha and other channels ignored. An image without such a
/// layer, or whose RGB channels hold integers or are subsampled, is an error.
pub fn decode_image(bytes: &[u8], source: &Path) -> Result<Frame> {
    let image = read_bytes(bytes, source)?;
    for layer in &image.layer_data {
        // prefix → [R, G, B] channels of that prefix.
        let mut groups: BTreeMap<String, [Option<&FlatSamples>; 3]> = BTreeMap::new();
        for channel in &layer.channel_data.list {
            let name = channel.name.to_string();
            let (prefix, base) = match name.rsplit_once('.') {
                Some((prefix, base)) => (prefix.to_string(), base.to_string()),
                None => (String::new(), name.clone()),
            };
            let slot = match base.as_str() {
                "R" => 0,
                "G" => 1,
                "B" => 2,
                _ => continue,
            };
            groups.entry(prefix).or_default()[slot] = Some(&channel.sample_data);
        }
        let Some((prefix, [Some(r), Some(g), Some(b)])) = groups
            .into_iter()
            .find(|(_, rgb)| rgb.iter().all(Option::is_some))
        else {
            continue;
        };
        let (w, h) = (layer.size.width(), layer.size.height());
        let (width, height) = match (u32::try_from(w), u32::try_from(h)) {
            (Ok(width), Ok(height)) => (width, height),
            _ => {
                return Err(Error::input(
                    source,
                    format!("the image is too large ({w}×{h})"),
                ));
            }
        };
        let layer_name = if prefix.is_empty() {
            "RGB".to_string()
        } else {
            format!("{prefix}.RGB")
        };
        let mut planes: Vec<Vec<f32>> = Vec::with_capacity(3);
        for samples in [r, g, b] {
            if samples.len() != w * h {
                return Err(Error::input(
                    source,
                    format!("the {layer_name} channels are subsampled"),
                ));
            }
            if let FlatSamples::U32(_) = samples {
                return Err(Error::input(
                    source,
                    format!("the {layer_name} channels hold integers, not colours"),
                ));
            }
            planes.push(samples.values_as_f32().collect());
        }
        // Every plane holds exactly w × h values (checked above).
        let pixels = (0..w * h)
            .map(|i| [planes[0][i], planes[1][i], planes[2][i]])
            .collect();
        return Ok(Frame {
            width,
            height,
            pixels,
        });
    }
    Err(Error::input(
        source,
        "no RGB layer (channels R, G and B) in the image",
    ))
}
