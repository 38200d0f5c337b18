//! Output encoders, readers and atomic writing (`nusselt::output`).
//!
//! Set `NUSSELT_OUTPUT_DIR` to keep the sample output folder written by
//! `sample_output_folder_is_complete` (for `tools/check_outputs.py`).

use std::collections::BTreeMap;
use std::f32::consts::PI;
use std::fs;
use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, ImageAttributes,
    IntegerBounds, Layer, LayerAttributes, ReadChannels, ReadLayers, SmallVec, Text, WritableImage,
    f16,
};
use glam::Vec3;
use nusselt::Error;
use nusselt::mesh::OutputMesh;
use nusselt::output::{self, OutputSet, baked, exr as out_exr, png as out_png};
use nusselt::render::frame::Frame;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

// ---------------------------------------------------------------- helpers

/// A mesh with `n` vertices of arbitrary (not geometric) values and about
/// 2n triangles, from a fixed seed. Values include awkward bit patterns.
fn random_mesh(n: usize, seed: u64) -> OutputMesh {
    let mut rng = Pcg64::seed_from_u64(seed);
    let awkward = [0.0, 1.0 / 3.0, 1e-38, 1.0e-45, 65504.0, 3.0e38, 0.1, 7.0];
    let value = |rng: &mut Pcg64| {
        if rng.random_bool(0.1) {
            awkward[rng.random_range(0..awkward.len())]
        } else {
            rng.random_range(-1.0e3f32..1.0e3)
        }
    };
    let vec3 = |rng: &mut Pcg64| Vec3::new(value(rng), value(rng), value(rng));
    let positions: Vec<Vec3> = (0..n).map(|_| vec3(&mut rng)).collect();
    let normals: Vec<Vec3> = (0..n)
        .map(|_| Vec3::new(rng.random(), rng.random(), rng.random::<f32>() + 0.1).normalize())
        .collect();
    let radiosity: Vec<Vec3> = (0..n).map(|_| vec3(&mut rng).abs()).collect();
    let irradiance: Vec<Vec3> = (0..n).map(|_| vec3(&mut rng).abs()).collect();
    let patch: Vec<u32> = (0..n).map(|_| rng.random()).collect();
    let m = 2 * n + n % 7;
    let triangles = if n == 0 {
        Vec::new()
    } else {
        (0..m)
            .map(|_| {
                [
                    rng.random_range(0..n as u32),
                    rng.random_range(0..n as u32),
                    rng.random_range(0..n as u32),
                ]
            })
            .collect()
    };
    OutputMesh {
        positions,
        normals,
        patch,
        radiosity,
        irradiance,
        triangles,
    }
}

/// A closed box of 6 faces, each a `k`×`k` grid of quads, normals facing
/// inward (a room), radiosity varying smoothly: a geometrically valid mesh.
fn room_mesh(k: usize, size: Vec3) -> OutputMesh {
    let mut mesh = OutputMesh::default();
    // (normal axis, side): the face at coordinate `side` of axis `axis`.
    for (face, (axis, side)) in [(0, 0.0), (0, 1.0), (1, 0.0), (1, 1.0), (2, 0.0), (2, 1.0)]
        .into_iter()
        .enumerate()
    {
        let (u_axis, v_axis) = ((axis + 1) % 3, (axis + 2) % 3);
        let inward = if side == 0.0 { 1.0 } else { -1.0 };
        let mut normal = Vec3::ZERO;
        normal[axis] = inward;
        let base = mesh.positions.len() as u32;
        for j in 0..=k {
            for i in 0..=k {
                let mut unit = Vec3::ZERO;
                unit[axis] = side;
                unit[u_axis] = i as f32 / k as f32;
                unit[v_axis] = j as f32 / k as f32;
                mesh.positions.push(unit * size);
                mesh.normals.push(normal);
                mesh.patch.push(face as u32);
                let glow = if face == 3 { 20.0 } else { 0.0 };
                mesh.radiosity.push(Vec3::new(
                    glow + unit[u_axis] * 3.0,
                    glow + unit[v_axis] * 2.0,
                    glow + 0.5 + face as f32 * 0.1,
                ));
                mesh.irradiance
                    .push(Vec3::new(unit[u_axis] * 4.0, unit[v_axis], 0.7));
            }
        }
        let at = |i: usize, j: usize| base + (j * (k + 1) + i) as u32;
        for j in 0..k {
            for i in 0..k {
                let quad = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                // u × v points along +axis; flip the winding when the
                // normal points along -axis.
                let (a, b) = if inward > 0.0 {
                    ([quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]])
                } else {
                    ([quad[0], quad[2], quad[1]], [quad[0], quad[3], quad[2]])
                };
                mesh.triangles.push(a);
                mesh.triangles.push(b);
            }
        }
    }
    mesh.validate()
        .expect("the sample room is a valid output mesh");
    mesh
}

fn random_frame(width: u32, height: u32, seed: u64) -> Frame {
    let mut rng = Pcg64::seed_from_u64(seed);
    let pixels = (0..width * height)
        .map(|_| {
            [
                rng.random_range(0.0f32..50.0),
                rng.random::<f32>(),
                rng.random::<f32>() * 1e-3,
            ]
        })
        .collect();
    Frame {
        width,
        height,
        pixels,
    }
}

fn bits3(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter()
        .map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
        .collect()
}

fn assert_bit_exact(a: &OutputMesh, b: &OutputMesh) {
    assert_eq!(bits3(&a.positions), bits3(&b.positions));
    assert_eq!(bits3(&a.normals), bits3(&b.normals));
    assert_eq!(bits3(&a.radiosity), bits3(&b.radiosity));
    assert_eq!(a.patch, b.patch);
    assert_eq!(a.triangles, b.triangles);
}

/// The names of the files in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

type FlatLayer = Layer<AnyChannels<FlatSamples>>;
type FlatImage = Image<exr::prelude::Layers<AnyChannels<FlatSamples>>>;

/// What the image tests' frames hold.
fn radiance() -> out_exr::ImageInfo<'static> {
    out_exr::ImageInfo::new(out_exr::Quantity::Radiance)
}

/// Reads a whole file's shared attributes and its layers.
fn read_image(bytes: &[u8]) -> FlatImage {
    exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .unwrap()
}

/// The `nusselt` header entries of a file (the same in every part).
fn info_entries(image: &FlatImage) -> Vec<String> {
    let name = Text::from(out_exr::INFO_ATTRIBUTE);
    // Written among the attributes every part shares, read back per part.
    let all: Vec<_> = image
        .layer_data
        .iter()
        .map(|l| l.attributes.other.get(&name))
        .collect();
    assert!(
        all.windows(2).all(|w| w[0] == w[1]),
        "every part carries the same entries"
    );
    match all[0] {
        Some(AttributeValue::TextVector(v)) => v.iter().map(|t| t.to_string()).collect(),
        other => panic!("no {} string vector: {other:?}", out_exr::INFO_ATTRIBUTE),
    }
}

/// Reads every part of an EXR held in memory with the exr crate.
fn read_layers(bytes: &[u8]) -> Vec<FlatLayer> {
    read_image(bytes).layer_data.into_vec()
}

fn write_layers(layers: Vec<FlatLayer>) -> Vec<u8> {
    let bounds = IntegerBounds::from_dimensions(layers[0].size);
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_layers(ImageAttributes::new(bounds), layers)
        .write()
        .to_buffered(&mut out)
        .unwrap();
    out.into_inner()
}

fn layer(
    name: Option<&str>,
    size: (usize, usize),
    attributes: &[(&str, AttributeValue)],
    channels: Vec<AnyChannel<FlatSamples>>,
) -> FlatLayer {
    let mut attrs = name.map(LayerAttributes::named).unwrap_or_default();
    for (key, value) in attributes {
        attrs.other.insert(Text::from(*key), value.clone());
    }
    Layer::new(
        size,
        attrs,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    )
}

fn assert_input_error(result: nusselt::Result<impl std::fmt::Debug>, file: &Path, needle: &str) {
    match result {
        Err(Error::Input { path, message }) => {
            assert_eq!(path, file);
            assert!(
                message.contains(needle),
                "message {message:?} lacks {needle:?}"
            );
        }
        other => panic!("expected an input error mentioning {needle:?}, got {other:?}"),
    }
}

// ---------------------------------------------------------- solution.exr

#[test]
fn solution_round_trips_bit_exact() {
    for n in [0, 1, 1023, 1024, 1025, 3000] {
        let mesh = random_mesh(n, n as u64 + 1);
        let bytes = out_exr::encode_solution(&mesh, "").unwrap();
        let back = out_exr::decode_solution(&bytes, Path::new("mem.exr")).unwrap();
        assert_bit_exact(&mesh, &back);
    }
}

#[test]
fn solution_round_trips_through_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("solution.exr");
    let mesh = room_mesh(4, Vec3::new(2.0, 3.0, 4.0));
    output::write_atomic(&path, &out_exr::encode_solution(&mesh, "").unwrap()).unwrap();
    let back = out_exr::read_solution(&path).unwrap();
    assert_bit_exact(&mesh, &back);
    assert_eq!(mesh, back);
}

#[test]
fn solution_layout_matches_the_contract() {
    for n in [0usize, 1, 1023, 1024, 1025, 3000] {
        let mesh = random_mesh(n, 99 + n as u64);
        let m = mesh.triangles.len();
        let layers = read_layers(&out_exr::encode_solution(&mesh, "").unwrap());
        let names: Vec<String> = layers
            .iter()
            .map(|l| l.attributes.layer_name.as_ref().unwrap().to_string())
            .collect();
        assert_eq!(names, ["vertices", "triangles"]);
        let (vertices, triangles) = (&layers[0], &layers[1]);

        assert_eq!(vertices.size.width(), 1024);
        assert_eq!(vertices.size.height(), n.div_ceil(1024).max(1));
        assert_eq!(triangles.size.width(), 1024);
        assert_eq!(triangles.size.height(), m.div_ceil(1024).max(1));
        assert_eq!(
            vertices.attributes.other.get(&Text::from("vertexCount")),
            Some(&AttributeValue::I32(n as i32))
        );
        assert_eq!(
            triangles.attributes.other.get(&Text::from("triangleCount")),
            Some(&AttributeValue::I32(m as i32))
        );
        assert_eq!(
            vertices.encoding.compression,
            exr::prelude::Compression::ZIP16
        );

        let channels = |l: &FlatLayer| -> BTreeMap<String, FlatSamples> {
            l.channel_data
                .list
                .iter()
                .map(|c| (c.name.to_string(), c.sample_data.clone()))
                .collect()
        };
        let v = channels(vertices);
        let float_names = [
            "B", "G", "H.B", "H.G", "H.R", "N.X", "N.Y", "N.Z", "P.X", "P.Y", "P.Z", "R",
        ];
        let mut expected: Vec<&str> = float_names.to_vec();
        expected.push("patch");
        assert_eq!(v.keys().collect::<Vec<_>>(), expected);
        let float = |name: &str| match &v[name] {
            FlatSamples::F32(s) => s.clone(),
            other => panic!("channel {name} is not f32: {other:?}"),
        };
        for (name, source, axis) in [
            ("R", &mesh.radiosity, 0),
            ("G", &mesh.radiosity, 1),
            ("B", &mesh.radiosity, 2),
            ("H.R", &mesh.irradiance, 0),
            ("H.G", &mesh.irradiance, 1),
            ("H.B", &mesh.irradiance, 2),
            ("P.X", &mesh.positions, 0),
            ("P.Y", &mesh.positions, 1),
            ("P.Z", &mesh.positions, 2),
            ("N.X", &mesh.normals, 0),
            ("N.Y", &mesh.normals, 1),
            ("N.Z", &mesh.normals, 2),
        ] {
            let samples = float(name);
            assert_eq!(samples.len(), vertices.size.area());
            // vertex k at x = k mod 1024, y = k div 1024 (row-major).
            for (k, p) in source.iter().enumerate() {
                let (x, y) = (k % 1024, k / 1024);
                assert_eq!(samples[y * 1024 + x].to_bits(), p[axis].to_bits());
            }
            assert!(
                samples[n..].iter().all(|s| s.to_bits() == 0),
                "{name} padding"
            );
        }
        let FlatSamples::U32(patch) = &v["patch"] else {
            panic!("patch is not u32")
        };
        assert_eq!(&patch[..n], &mesh.patch[..]);
        assert!(patch[n..].iter().all(|&p| p == 0));

        let t = channels(triangles);
        assert_eq!(t.keys().collect::<Vec<_>>(), ["I0", "I1", "I2"]);
        for (c, name) in ["I0", "I1", "I2"].into_iter().enumerate() {
            let FlatSamples::U32(idx) = &t[name] else {
                panic!("{name} is not u32")
            };
            assert_eq!(idx.len(), triangles.size.area());
            let expected: Vec<u32> = mesh.triangles.iter().map(|t| t[c]).collect();
            assert_eq!(&idx[..m], &expected[..]);
            assert!(idx[m..].iter().all(|&i| i == 0));
        }
    }
}

#[test]
fn solution_encoder_rejects_inconsistent_meshes() {
    let mut mesh = random_mesh(10, 5);
    mesh.normals.pop();
    assert!(matches!(
        out_exr::encode_solution(&mesh, ""),
        Err(Error::Encode { .. })
    ));
    let mut mesh = random_mesh(10, 5);
    mesh.triangles.push([0, 1, 10]);
    let err = out_exr::encode_solution(&mesh, "").unwrap_err();
    assert!(err.to_string().contains("triangle"), "{err}");
}

/// Parts of a small valid solution, to be broken one way at a time.
fn solution_parts(
    m: usize,
    index: u32,
) -> (Vec<AnyChannel<FlatSamples>>, Vec<AnyChannel<FlatSamples>>) {
    let f = |name: &str| AnyChannel::new(name, FlatSamples::F32(vec![0.5; 1024]));
    let mut vertices: Vec<_> = [
        "R", "G", "B", "H.R", "H.G", "H.B", "P.X", "P.Y", "P.Z", "N.X", "N.Y", "N.Z",
    ]
    .into_iter()
    .map(f)
    .collect();
    vertices.push(AnyChannel::new("patch", FlatSamples::U32(vec![0; 1024])));
    let mut idx = vec![0u32; 1024];
    idx[m.saturating_sub(1)] = index;
    let triangles = ["I0", "I1", "I2"]
        .into_iter()
        .map(|name| AnyChannel::new(name, FlatSamples::U32(idx.clone())))
        .collect();
    (vertices, triangles)
}

fn solution_file(
    n: i32,
    m: i32,
    vertices: Vec<AnyChannel<FlatSamples>>,
    triangles: Option<Vec<AnyChannel<FlatSamples>>>,
) -> Vec<u8> {
    let mut layers = vec![layer(
        Some("vertices"),
        (1024, 1),
        &[("vertexCount", AttributeValue::I32(n))],
        vertices,
    )];
    if let Some(triangles) = triangles {
        layers.push(layer(
            Some("triangles"),
            (1024, 1),
            &[("triangleCount", AttributeValue::I32(m))],
            triangles,
        ));
    }
    write_layers(layers)
}

#[test]
fn solution_reader_accepts_a_hand_made_file() {
    let (v, t) = solution_parts(2, 3);
    let mesh =
        out_exr::decode_solution(&solution_file(4, 2, v, Some(t)), Path::new("x.exr")).unwrap();
    assert_eq!(mesh.vertex_count(), 4);
    assert_eq!(mesh.triangles, [[0, 0, 0], [3, 3, 3]]);
    assert_eq!(mesh.positions[3], Vec3::splat(0.5));
}

#[test]
fn solution_reader_rejects_broken_files() {
    let file = Path::new("broken/solution.exr");
    let decode = |bytes: Vec<u8>| out_exr::decode_solution(&bytes, file);

    assert_input_error(decode(b"not an exr".to_vec()), file, "OpenEXR");

    let (v, _) = solution_parts(2, 3);
    assert_input_error(decode(solution_file(4, 2, v, None)), file, "triangles");

    let (v, t) = solution_parts(2, 4);
    assert_input_error(decode(solution_file(4, 2, v, Some(t))), file, "triangle 1");

    let (v, t) = solution_parts(2, 3);
    assert_input_error(
        decode(solution_file(1025, 2, v, Some(t))),
        file,
        "vertexCount",
    );

    let (v, t) = solution_parts(2, 3);
    assert_input_error(
        decode(solution_file(-1, 2, v, Some(t))),
        file,
        "vertexCount",
    );

    let (v, t) = solution_parts(2, 3);
    assert_input_error(
        decode(solution_file(4, 2000, v, Some(t))),
        file,
        "triangleCount",
    );

    let (mut v, t) = solution_parts(2, 3);
    v.retain(|c| !c.name.eq("N.Y"));
    assert_input_error(decode(solution_file(4, 2, v, Some(t))), file, "N.Y");

    let (mut v, t) = solution_parts(2, 3);
    v.retain(|c| !c.name.eq("H.G"));
    assert_input_error(decode(solution_file(4, 2, v, Some(t))), file, "H.G");

    let (mut v, t) = solution_parts(2, 3);
    for c in &mut v {
        if c.name.eq("patch") {
            c.sample_data = FlatSamples::F32(vec![0.0; 1024]);
        }
    }
    assert_input_error(decode(solution_file(4, 2, v, Some(t))), file, "uint32");

    let (mut v, t) = solution_parts(2, 3);
    for c in &mut v {
        if c.name.eq("P.X") {
            c.sample_data = FlatSamples::F32(vec![f32::NAN; 1024]);
        }
    }
    assert_input_error(decode(solution_file(4, 2, v, Some(t))), file, "non-finite");

    // Count attribute of the wrong type.
    let (v, t) = solution_parts(2, 3);
    let bytes = write_layers(vec![
        layer(
            Some("vertices"),
            (1024, 1),
            &[("vertexCount", AttributeValue::F32(4.0))],
            v,
        ),
        layer(
            Some("triangles"),
            (1024, 1),
            &[("triangleCount", AttributeValue::I32(2))],
            t,
        ),
    ]);
    assert_input_error(decode(bytes), file, "not an int");

    // Wrong width.
    let (_, t) = solution_parts(2, 3);
    let narrow: Vec<_> = [
        "R", "G", "B", "H.R", "H.G", "H.B", "P.X", "P.Y", "P.Z", "N.X", "N.Y", "N.Z",
    ]
    .into_iter()
    .map(|name| AnyChannel::new(name, FlatSamples::F32(vec![0.0; 512])))
    .chain([AnyChannel::new("patch", FlatSamples::U32(vec![0; 512]))])
    .collect();
    let bytes = write_layers(vec![
        layer(
            Some("vertices"),
            (512, 1),
            &[("vertexCount", AttributeValue::I32(4))],
            narrow,
        ),
        layer(
            Some("triangles"),
            (1024, 1),
            &[("triangleCount", AttributeValue::I32(2))],
            t,
        ),
    ]);
    assert_input_error(decode(bytes), file, "wide");

    // A missing file names the file.
    let missing = Path::new("/nonexistent/nusselt/solution.exr");
    assert_input_error(out_exr::read_solution(missing), missing, "");
}

// ---------------------------------------------------------------- images

#[test]
fn image_round_trips_bit_exact() {
    for (w, h) in [(1, 1), (7, 3), (64, 48), (1025, 2)] {
        let frame = random_frame(w, h, (w * 31 + h) as u64);
        let bytes = out_exr::encode_image(&frame, &radiance()).unwrap();
        let back = out_exr::decode_image(&bytes, Path::new("mem.exr")).unwrap();
        assert_eq!((back.width, back.height), (w, h));
        let bits =
            |f: &Frame| -> Vec<[u32; 3]> { f.pixels.iter().map(|p| p.map(f32::to_bits)).collect() };
        assert_eq!(bits(&frame), bits(&back));
    }
}

#[test]
fn image_is_single_part_float_rgb_with_row_zero_on_top() {
    let mut frame = Frame::new(3, 2);
    frame.pixels[0] = [1.0, 2.0, 3.0]; // (0, 0): top left
    frame.pixels[5] = [4.0, 5.0, 6.0]; // (2, 1): bottom right
    let layers = read_layers(&out_exr::encode_image(&frame, &radiance()).unwrap());
    assert_eq!(layers.len(), 1);
    let l = &layers[0];
    assert_eq!((l.size.width(), l.size.height()), (3, 2));
    let names: Vec<String> = l
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, ["B", "G", "R"]);
    let FlatSamples::F32(r) = &l.channel_data.list[2].sample_data else {
        panic!("R is not f32")
    };
    assert_eq!(r, &[1.0, 0.0, 0.0, 0.0, 0.0, 4.0]);
}

#[test]
fn image_reader_accepts_half_rgba_and_prefixed_layers() {
    let dir = tempfile::tempdir().unwrap();
    let values = [0.25f32, 1.5, 1000.0, 0.0];
    let half = |v: f32| f16::from_f32(v);
    let rgba = layer(
        None,
        (2, 2),
        &[],
        vec![
            AnyChannel::new("R", FlatSamples::F16(values.map(half).to_vec())),
            AnyChannel::new(
                "G",
                FlatSamples::F16(values.map(|v| half(v * 2.0)).to_vec()),
            ),
            AnyChannel::new(
                "B",
                FlatSamples::F16(values.map(|v| half(v * 0.5)).to_vec()),
            ),
            AnyChannel::new("A", FlatSamples::F16(vec![half(1.0); 4])),
        ],
    );
    let path = dir.path().join("half.exr");
    fs::write(&path, write_layers(vec![rgba])).unwrap();
    let frame = out_exr::read_image(&path).unwrap();
    assert_eq!((frame.width, frame.height), (2, 2));
    for (k, v) in values.iter().enumerate() {
        assert_eq!(frame.pixels[k], [*v, v * 2.0, v * 0.5]);
    }

    // Only a prefixed RGB layer (after a depth channel): it is found.
    let prefixed = layer(
        None,
        (1, 1),
        &[],
        vec![
            AnyChannel::new("Z", FlatSamples::F32(vec![9.0])),
            AnyChannel::new("beauty.R", FlatSamples::F32(vec![1.0])),
            AnyChannel::new("beauty.G", FlatSamples::F32(vec![2.0])),
            AnyChannel::new("beauty.B", FlatSamples::F32(vec![3.0])),
        ],
    );
    let frame = out_exr::decode_image(&write_layers(vec![prefixed]), &path).unwrap();
    assert_eq!(frame.pixels, [[1.0, 2.0, 3.0]]);
}

#[test]
fn image_reader_rejects_non_rgb_images() {
    let file = Path::new("depth.exr");
    let depth = layer(
        None,
        (2, 1),
        &[],
        vec![AnyChannel::new("Y", FlatSamples::F32(vec![1.0, 2.0]))],
    );
    assert_input_error(
        out_exr::decode_image(&write_layers(vec![depth]), file),
        file,
        "no RGB layer",
    );
    let ints = layer(
        None,
        (1, 1),
        &[],
        ["R", "G", "B"]
            .into_iter()
            .map(|n| AnyChannel::new(n, FlatSamples::U32(vec![1])))
            .collect(),
    );
    assert_input_error(
        out_exr::decode_image(&write_layers(vec![ints]), file),
        file,
        "integers",
    );
    assert_input_error(
        out_exr::decode_image(b"\x76\x2f\x31\x01garbage", file),
        file,
        "OpenEXR",
    );
}

#[test]
fn image_encoder_rejects_inconsistent_frames() {
    assert!(matches!(
        out_exr::encode_image(&Frame::new(0, 4), &radiance()),
        Err(Error::Encode { .. })
    ));
    let mut frame = Frame::new(2, 2);
    frame.pixels.pop();
    assert!(matches!(
        out_exr::encode_image(&frame, &radiance()),
        Err(Error::Encode { .. })
    ));
    assert!(matches!(
        out_png::encode_png(&frame, 1.0),
        Err(Error::Encode { .. })
    ));
}

#[test]
fn exr_headers_describe_quantity_units_scene_colour_and_view() {
    let version = format!("nusselt {}", env!("CARGO_PKG_VERSION"));
    let rec709 = |image: &exr::prelude::Image<_>| {
        let c = image.attributes.chromaticities.expect("chromaticities");
        assert_eq!((c.red.x(), c.red.y()), (0.64, 0.33));
        assert_eq!((c.green.x(), c.green.y()), (0.30, 0.60));
        assert_eq!((c.blue.x(), c.blue.y()), (0.15, 0.06));
        assert_eq!((c.white.x(), c.white.y()), (0.3127, 0.3290));
    };

    // solution.exr: 3000 vertices (3 rows) and a different number of
    // triangles; each part's data window is its own, the display window
    // covers both.
    let mesh = random_mesh(3000, 5);
    let bytes = out_exr::encode_solution(&mesh, "scenes/räume.gltf").unwrap();
    assert_eq!(
        bytes,
        out_exr::encode_solution(&mesh, "scenes/räume.gltf").unwrap(),
        "deterministic"
    );
    let image = read_image(&bytes);
    rec709(&image);
    let entries = info_entries(&image);
    for e in [
        "R G B=radiosity [W/m^2]",
        "H.R H.G H.B=irradiance [W/m^2]",
        "P.X P.Y P.Z=position [m]",
    ] {
        assert!(entries.iter().any(|x| x == e), "{e} in {entries:?}");
    }
    assert!(
        entries.iter().any(|x| x.starts_with("scene=scenes/r")),
        "{entries:?}"
    );
    let heights: Vec<usize> = image.layer_data.iter().map(|l| l.size.height()).collect();
    assert_eq!(heights[0], 3);
    assert_eq!(heights[1], mesh.triangles.len().div_ceil(1024).max(1));
    assert_ne!(heights[0], heights[1]);
    assert_eq!(
        image.attributes.display_window.size.height(),
        heights[0].max(heights[1])
    );
    for layer in image.layer_data.iter() {
        assert_eq!(
            layer.attributes.software_name.as_ref().unwrap().to_string(),
            version
        );
        assert!(layer.attributes.comments.is_some());
    }

    // A render: radiance with its exposure and view; worldToCamera takes
    // the eye to the origin and the viewing direction to +z.
    let view = nusselt::render::view::View::resolve(
        None,
        (glam::DVec3::splat(-1.0), glam::DVec3::splat(1.0)),
        &nusselt::render::view::ViewOverrides {
            width: Some(40),
            height: Some(20),
            ..Default::default()
        },
    )
    .unwrap();
    let info = radiance()
        .scene("box.gltf")
        .view(Some(&view))
        .exposure(Some(2.5));
    let frame = random_frame(40, 20, 3);
    let bytes = out_exr::encode_image(&frame, &info).unwrap();
    assert_eq!(
        bytes,
        out_exr::encode_image(&frame, &info).unwrap(),
        "deterministic"
    );
    let image = read_image(&bytes);
    rec709(&image);
    let entries = info_entries(&image);
    for e in [
        "R G B=radiance [W/(m^2 sr)]",
        "scene=box.gltf",
        "displayExposure=2.5",
    ] {
        assert!(entries.iter().any(|x| x == e), "{e} in {entries:?}");
    }
    let own = &image.layer_data[0].attributes;
    let m = own.world_to_camera.expect("worldToCamera");
    let apply = |p: glam::DVec3| -> [f64; 3] {
        let p = [p.x, p.y, p.z, 1.0];
        std::array::from_fn(|c| (0..4).map(|r| p[r] * f64::from(m[r * 4 + c])).sum())
    };
    let at_eye = apply(view.eye);
    let ahead = apply(view.eye + view.forward);
    for k in 0..3 {
        assert!(at_eye[k].abs() < 1e-4, "{at_eye:?}");
        assert!((ahead[k] - [0.0, 0.0, 1.0][k]).abs() < 1e-4, "{ahead:?}");
    }
    let yfov = own.vertical_field_of_view.unwrap();
    assert!((f64::from(yfov) - view.yfov.to_degrees()).abs() < 1e-3);
    assert!(
        own.horizontal_field_of_view.unwrap() > yfov,
        "a 2:1 image is wider than tall"
    );
}

// ------------------------------------------------------------------- PNG

fn decode_png(bytes: &[u8]) -> image::RgbImage {
    let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).unwrap();
    assert_eq!(img.color(), image::ColorType::Rgb8);
    img.into_rgb8()
}

#[test]
fn png_applies_exposure_clamp_and_srgb() {
    // Linear value × exposure → sRGB byte, from the published sRGB curve:
    // 0.5 → 0.7354 → 188, 0.18 → 0.4613 → 118, 0.002 → 0.0258 → 7,
    // 0.0031308 → 0.04045 → 10, 0.8 → 0.9063 → 231.
    let cases: [(f32, f32, u8); 11] = [
        (0.0, 1.0, 0),
        (1.0, 1.0, 255),
        (0.5, 1.0, 188),
        (0.25, 2.0, 188),
        (0.18, 1.0, 118),
        (0.002, 1.0, 7),
        (0.003_130_8, 1.0, 10),
        (8.0, 0.1, 231),
        (3.0, 1.0, 255),
        (-1.0, 1.0, 0),
        (f32::NAN, 1.0, 0),
    ];
    for (linear, exposure, expected) in cases {
        let frame = Frame {
            width: 1,
            height: 1,
            pixels: vec![[linear, linear, linear]],
        };
        let png = decode_png(&out_png::encode_png(&frame, exposure).unwrap());
        assert_eq!(
            png.get_pixel(0, 0).0,
            [expected; 3],
            "linear {linear} exposure {exposure}"
        );
        assert_eq!(out_png::display_byte(linear, exposure), expected);
    }
    assert_eq!(out_png::display_byte(f32::INFINITY, 1.0), 255);
}

#[test]
fn png_keeps_row_zero_on_top_and_channels_apart() {
    let mut frame = Frame::new(2, 3);
    frame.pixels[0] = [1.0, 0.0, 0.0]; // top left red
    frame.pixels[1] = [0.0, 1.0, 0.0]; // top right green
    frame.pixels[5] = [0.0, 0.0, 1.0]; // bottom right blue
    let png = decode_png(&out_png::encode_png(&frame, 1.0).unwrap());
    assert_eq!(png.dimensions(), (2, 3));
    assert_eq!(png.get_pixel(0, 0).0, [255, 0, 0]);
    assert_eq!(png.get_pixel(1, 0).0, [0, 255, 0]);
    assert_eq!(png.get_pixel(1, 2).0, [0, 0, 255]);
    assert_eq!(png.get_pixel(0, 2).0, [0, 0, 0]);
}

#[test]
fn png_rejects_bad_exposure() {
    let frame = Frame::new(1, 1);
    for exposure in [f32::NAN, f32::INFINITY, -1.0] {
        assert!(matches!(
            out_png::encode_png(&frame, exposure),
            Err(Error::Setting(_))
        ));
    }
}

#[test]
fn luminance_uses_rec709_weights() {
    assert!((out_png::luminance([1.0, 1.0, 1.0]) - 1.0).abs() < 1e-6);
    assert!((out_png::luminance([1.0, 0.0, 0.0]) - 0.2126).abs() < 1e-7);
    assert!((out_png::luminance([0.0, 1.0, 0.0]) - 0.7152).abs() < 1e-7);
    assert!((out_png::luminance([0.0, 0.0, 1.0]) - 0.0722).abs() < 1e-7);
}

#[test]
fn auto_exposure_clips_a_small_emitter_only() {
    assert_eq!(out_png::auto_exposure(std::iter::empty()), 1.0);
    assert_eq!(
        out_png::auto_exposure([0.0, -1.0, f32::NAN].into_iter()),
        1.0
    );

    // 0.5 % of the pixels are a bright emitter: the rest sets the exposure.
    let mut rng = Pcg64::seed_from_u64(3);
    let mut lum: Vec<f32> = (0..1000).map(|_| rng.random_range(0.1f32..2.0)).collect();
    let scene_max = lum.iter().copied().fold(0.0, f32::max);
    lum[..5].fill(500.0);
    lum.push(f32::INFINITY);
    lum.push(f32::NAN);
    let e = out_png::auto_exposure(lum.iter().copied());
    assert!(e * 500.0 > 1.0, "the emitter clips");
    assert!(e * scene_max <= 1.0 + 1e-6, "the lit scene does not clip");
    assert!(e * scene_max > 0.8, "the lit scene fills the range");

    // Independent of order.
    lum.reverse();
    assert_eq!(out_png::auto_exposure(lum.iter().copied()), e);

    // A uniform image lands at 0.9.
    let e = out_png::auto_exposure(std::iter::repeat_n(4.0, 100));
    assert!((e * 4.0 - 0.9).abs() < 1e-6);
}

// ------------------------------------------------------------- baked.gltf

/// The values of a float VEC3 accessor, read with the gltf crate.
fn vec3_values(accessor: gltf::Accessor<'_>, buffers: &[gltf::buffer::Data]) -> Vec<Vec3> {
    gltf::accessor::Iter::<[f32; 3]>::new(accessor, |b| Some(&buffers[b.index()][..]))
        .unwrap()
        .map(Vec3::from_array)
        .collect()
}

#[test]
fn baked_gltf_reparses_with_the_mesh_values() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = room_mesh(5, Vec3::new(5.0, 2.5, 3.0));
    let exposure = 0.37;
    let (json, bin) = baked::encode_baked_gltf(
        &mesh,
        &baked::BakeLayout::flat(&mesh),
        exposure,
        "baked.bin",
    )
    .unwrap();
    let mut set = OutputSet::create(dir.path()).unwrap();
    set.stage("baked.gltf", &json).unwrap();
    set.stage("baked.bin", &bin).unwrap();
    set.commit().unwrap();

    let gltf = gltf::Gltf::from_slice(&json).unwrap();
    assert_eq!(
        gltf.extensions_used().collect::<Vec<_>>(),
        ["KHR_materials_unlit"]
    );
    let (doc, buffers, _) = gltf::import(dir.path().join("baked.gltf")).unwrap();
    assert_eq!(buffers.len(), 1);
    assert_eq!(buffers[0].len(), bin.len());

    let meshes: Vec<_> = doc.meshes().collect();
    assert_eq!(meshes.len(), 1);
    assert_eq!(doc.nodes().count(), 1);
    assert_eq!(doc.scenes().count(), 1);
    assert_eq!(doc.default_scene().unwrap().nodes().count(), 1);
    let prims: Vec<_> = meshes[0].primitives().collect();
    assert_eq!(prims.len(), 1);
    let prim = &prims[0];
    assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);

    let reader = prim.reader(|b| Some(&buffers[b.index()][..]));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .unwrap()
        .map(Vec3::from_array)
        .collect();
    let normals: Vec<Vec3> = reader
        .read_normals()
        .unwrap()
        .map(Vec3::from_array)
        .collect();
    let colors: Vec<Vec3> = reader
        .read_colors(0)
        .unwrap()
        .into_rgb_f32()
        .map(Vec3::from_array)
        .collect();
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    let radiosity = vec3_values(
        prim.get(&gltf::Semantic::Extras("RADIOSITY".into()))
            .unwrap(),
        &buffers,
    );
    assert_eq!(bits3(&positions), bits3(&mesh.positions));
    assert_eq!(bits3(&normals), bits3(&mesh.normals));
    assert_eq!(bits3(&radiosity), bits3(&mesh.radiosity));
    let flat: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    assert_eq!(indices, flat);
    for (c, b) in colors.iter().zip(&mesh.radiosity) {
        let expected = (*b / PI * exposure).clamp(Vec3::ZERO, Vec3::ONE);
        assert!(
            (*c - expected).abs().max_element() < 1e-6,
            "{c} vs {expected}"
        );
        assert!(c.min_element() >= 0.0 && c.max_element() <= 1.0);
    }
    // The emitter face (B ≈ 20) clips, the rest does not.
    assert!(colors.iter().any(|c| c.x == 1.0));

    // POSITION bounds, index type, material.
    let pos = prim.get(&gltf::Semantic::Positions).unwrap();
    let lo = mesh.positions.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
    let hi = mesh
        .positions
        .iter()
        .fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
    assert_eq!(pos.min().unwrap(), serde_json::json!(lo.to_array()));
    assert_eq!(pos.max().unwrap(), serde_json::json!(hi.to_array()));
    assert_eq!(
        prim.indices().unwrap().data_type(),
        gltf::accessor::DataType::U32
    );
    let material = prim.material();
    assert!(material.unlit());
    assert!(!material.double_sided());
}

#[test]
fn baked_gltf_json_records_views_and_exposure() {
    let mesh = room_mesh(2, Vec3::ONE);
    let (json, bin) =
        baked::encode_baked_gltf(&mesh, &baked::BakeLayout::flat(&mesh), 1.25, "my-bake.bin")
            .unwrap();
    let root: serde_json::Value = serde_json::from_slice(&json).unwrap();
    assert_eq!(root["asset"]["version"], "2.0");
    assert_eq!(
        root["asset"]["generator"],
        format!("nusselt {}", env!("CARGO_PKG_VERSION"))
    );
    assert_eq!(root["asset"]["extras"]["exposure"], 1.25);
    assert_eq!(root["buffers"][0]["uri"], "my-bake.bin");
    assert_eq!(root["buffers"][0]["byteLength"], bin.len());
    let views = root["bufferViews"].as_array().unwrap();
    assert_eq!(views.len(), 6);
    let mut end = 0;
    for view in views {
        let offset = view["byteOffset"].as_u64().unwrap();
        let length = view["byteLength"].as_u64().unwrap();
        assert_eq!(offset % 4, 0);
        assert_eq!(offset, end, "views are packed in order");
        end = offset + length;
        let target = view["target"].as_u64().unwrap();
        assert!(target == 34962 || target == 34963);
    }
    assert_eq!(end as usize, bin.len());
    assert_eq!(views[5]["target"], 34963);
    let attrs = &root["meshes"][0]["primitives"][0]["attributes"];
    for name in ["POSITION", "NORMAL", "COLOR_0", "_RADIOSITY", "_IRRADIANCE"] {
        let a = &root["accessors"][attrs[name].as_u64().unwrap() as usize];
        assert_eq!(a["type"], "VEC3");
        assert_eq!(a["componentType"], 5126);
        assert_eq!(a["count"], mesh.vertex_count());
    }
    assert!(root["materials"][0]["extensions"]["KHR_materials_unlit"].is_object());
}

#[test]
fn baked_gltf_rejects_what_it_cannot_write() {
    let empty = OutputMesh::default();
    let err = baked::encode_baked_gltf(&empty, &baked::BakeLayout::flat(&empty), 1.0, "baked.bin")
        .unwrap_err();
    assert!(matches!(err, Error::Encode { .. }));
    assert!(err.to_string().contains("empty"), "{err}");

    let mesh = room_mesh(1, Vec3::ONE);
    for bad in ["", "../baked.bin", "a b.bin", "x/y.bin"] {
        assert!(
            baked::encode_baked_gltf(&mesh, &baked::BakeLayout::flat(&mesh), 1.0, bad).is_err(),
            "{bad:?}"
        );
    }
    assert!(matches!(
        baked::encode_baked_gltf(
            &mesh,
            &baked::BakeLayout::flat(&mesh),
            f32::NAN,
            "baked.bin"
        ),
        Err(Error::Setting(_))
    ));
    let mut broken = mesh.clone();
    broken.radiosity[0].x = f32::INFINITY;
    assert!(
        baked::encode_baked_gltf(&broken, &baked::BakeLayout::flat(&broken), 1.0, "baked.bin")
            .is_err()
    );
    let mut broken = mesh.clone();
    broken.triangles[0][1] = 10_000;
    assert!(
        baked::encode_baked_gltf(&broken, &baked::BakeLayout::flat(&broken), 1.0, "baked.bin")
            .is_err()
    );
}

// -------------------------------------------------------- atomic writing

#[test]
fn write_atomic_replaces_and_leaves_no_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sub").join("report.json");
    output::write_atomic(&path, b"first").unwrap();
    output::write_atomic(&path, b"second").unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"second");
    assert_eq!(listing(&dir.path().join("sub")), ["report.json"]);
}

#[test]
fn failed_write_keeps_the_earlier_file() {
    let dir = tempfile::tempdir().unwrap();
    // A folder where a file should go: the rename fails after the
    // temporary file was written.
    let blocked = dir.path().join("render.exr");
    fs::create_dir(&blocked).unwrap();
    fs::write(blocked.join("keep"), b"x").unwrap();
    let err = output::write_atomic(&blocked, b"new").unwrap_err();
    assert!(
        matches!(err, Error::Output { ref path, .. } if path == &blocked),
        "{err}"
    );
    assert_eq!(listing(dir.path()), ["render.exr"]);
    assert_eq!(listing(&blocked), ["keep"]);

    // In a set, a failing rename keeps the earlier files not yet renamed.
    fs::write(dir.path().join("solution.exr"), b"earlier result").unwrap();
    let mut set = OutputSet::create(dir.path()).unwrap();
    set.stage("render.exr", b"new render").unwrap();
    set.stage("solution.exr", b"new solution").unwrap();
    assert!(matches!(set.commit(), Err(Error::Output { .. })));
    assert_eq!(
        fs::read(dir.path().join("solution.exr")).unwrap(),
        b"earlier result"
    );
    assert_eq!(listing(dir.path()), ["render.exr", "solution.exr"]);
}

#[test]
fn uncommitted_set_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("baked.gltf"), b"earlier").unwrap();
    {
        let mut set = OutputSet::create(dir.path()).unwrap();
        set.stage("solution.exr", b"abc").unwrap();
        set.stage("baked.gltf", b"new").unwrap();
        // Staged files are not visible under their names yet.
        assert!(!dir.path().join("solution.exr").exists());
        assert_eq!(fs::read(dir.path().join("baked.gltf")).unwrap(), b"earlier");
        assert_eq!(listing(dir.path()).len(), 2, "one staging folder");
        // A later step fails: the set is dropped.
    }
    assert_eq!(listing(dir.path()), ["baked.gltf"]);
    assert_eq!(fs::read(dir.path().join("baked.gltf")).unwrap(), b"earlier");
}

#[test]
fn committed_set_writes_every_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out").join("cornell");
    let mut set = OutputSet::create(&out).unwrap();
    assert_eq!(set.dir(), out);
    set.stage("a.txt", b"alpha").unwrap();
    set.stage("b.txt", b"").unwrap();
    let written = set.commit().unwrap();
    assert_eq!(written, [out.join("a.txt"), out.join("b.txt")]);
    assert_eq!(fs::read(out.join("a.txt")).unwrap(), b"alpha");
    assert_eq!(fs::read(out.join("b.txt")).unwrap(), b"");
    assert_eq!(listing(&out), ["a.txt", "b.txt"]);
}

#[test]
fn stage_rejects_paths_and_duplicates() {
    let dir = tempfile::tempdir().unwrap();
    let mut set = OutputSet::create(dir.path()).unwrap();
    for bad in ["", ".", "..", "../escape.txt", "a/b.txt", "/abs.txt"] {
        assert!(
            matches!(set.stage(bad, b"x"), Err(Error::Output { .. })),
            "{bad:?}"
        );
    }
    set.stage("x.txt", b"1").unwrap();
    assert!(matches!(
        set.stage("x.txt", b"2"),
        Err(Error::Output { .. })
    ));
    drop(set);
    assert!(listing(dir.path()).is_empty());
    assert!(!dir.path().parent().unwrap().join("escape.txt").exists());
}

#[test]
fn output_set_refuses_unusable_folders() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("plain-file");
    fs::write(&file, b"x").unwrap();
    // The folder is a file.
    let err = OutputSet::create(&file).unwrap_err();
    assert!(
        matches!(err, Error::Output { ref path, .. } if path == &file),
        "{err}"
    );
    // The folder's parent is a file: it cannot be created.
    let under: PathBuf = file.join("out");
    let err = OutputSet::create(&under).unwrap_err();
    assert!(
        matches!(err, Error::Output { ref path, .. } if path == &under),
        "{err}"
    );
    assert!(err.to_string().starts_with("cannot write"), "{err}");
    // So is writing a single file there.
    assert!(matches!(
        output::write_atomic(&under.join("x.exr"), b"x"),
        Err(Error::Output { .. })
    ));
    assert_eq!(fs::read(&file).unwrap(), b"x");
}

#[test]
fn json_is_pretty_and_non_finite_becomes_null() {
    #[derive(serde::Serialize)]
    struct Report {
        rmse: f64,
        bad: f64,
        count: u32,
    }
    let bytes = output::write_json(&Report {
        rmse: 0.25,
        bad: f64::NAN,
        count: 3,
    })
    .unwrap();
    let text = String::from_utf8(bytes).unwrap();
    assert!(text.ends_with("}\n"));
    assert!(text.contains("\n  \"rmse\": 0.25"));
    let parsed: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(parsed["bad"], serde_json::Value::Null);
    assert_eq!(parsed["count"], 3);
}

// -------------------------------------------------- a complete output folder

/// Writes a sample run's files (as `solve` would) and re-reads them. With
/// `NUSSELT_OUTPUT_DIR` set, the folder is kept there for
/// `tools/check_outputs.py`.
#[test]
fn sample_output_folder_is_complete() {
    let temp = tempfile::tempdir().unwrap();
    let dir = match std::env::var_os("NUSSELT_OUTPUT_DIR") {
        Some(d) => PathBuf::from(d),
        None => temp.path().join("out"),
    };
    // Enough vertices for several rows of both parts.
    let mesh = room_mesh(24, Vec3::new(5.5, 5.5, 5.5));
    assert!(mesh.vertex_count() > 2048 && mesh.triangles.len() > 4096);
    let exposure = out_png::auto_exposure(
        mesh.radiosity
            .iter()
            .map(|b| out_png::luminance((*b / PI).to_array())),
    );
    let frame = random_frame(64, 40, 11);
    let (gltf, bin) = baked::encode_baked_gltf(
        &mesh,
        &baked::BakeLayout::flat(&mesh),
        exposure,
        "baked.bin",
    )
    .unwrap();

    let mut set = OutputSet::create(&dir).unwrap();
    set.stage(
        "solution.exr",
        &out_exr::encode_solution(&mesh, "").unwrap(),
    )
    .unwrap();
    set.stage("baked.gltf", &gltf).unwrap();
    set.stage("baked.bin", &bin).unwrap();
    set.stage(
        "render.exr",
        &out_exr::encode_image(&frame, &radiance()).unwrap(),
    )
    .unwrap();
    set.stage("render.png", &out_png::encode_png(&frame, 0.05).unwrap())
        .unwrap();
    set.commit().unwrap();

    assert_eq!(
        out_exr::read_solution(&dir.join("solution.exr")).unwrap(),
        mesh
    );
    assert_eq!(out_exr::read_image(&dir.join("render.exr")).unwrap(), frame);
    let (doc, _, _) = gltf::import(dir.join("baked.gltf")).unwrap();
    assert_eq!(doc.accessors().count(), 6);
    let names = listing(&dir);
    for f in [
        "baked.bin",
        "baked.gltf",
        "render.exr",
        "render.png",
        "solution.exr",
    ] {
        assert!(names.contains(&f.to_string()), "{f} missing");
    }
    assert!(
        names.iter().all(|n| !n.starts_with('.')),
        "temporary files left: {names:?}"
    );
}

#[test]
fn solution_exposure_is_the_area_weighted_log_average() {
    // Two squares, the second four times the area and four times brighter
    // in luminance: log-average = exp((1 ln 1 + 4 ln 4) / 5) of B/π = 1.
    let square = |mesh: &mut OutputMesh, x: f32, side: f32, b: f32| {
        let base = mesh.positions.len() as u32;
        for (u, v) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            mesh.positions.push(Vec3::new(x + u * side, v * side, 0.0));
            mesh.normals.push(Vec3::Z);
            mesh.patch.push(0);
            mesh.radiosity.push(Vec3::splat(b * PI));
            mesh.irradiance.push(Vec3::splat(2.0 * b * PI));
        }
        mesh.triangles.push([base, base + 1, base + 2]);
        mesh.triangles.push([base, base + 2, base + 3]);
    };
    let mut mesh = OutputMesh::default();
    square(&mut mesh, 0.0, 1.0, 1.0);
    square(&mut mesh, 5.0, 2.0, 4.0);
    let mean = (4.0f64.ln() * 4.0 / 5.0).exp() as f32;
    let e = out_png::solution_exposure(&mesh);
    assert!((e * mean - out_png::SOLUTION_KEY).abs() < 1e-5, "{e}");
    // Unlit vertices do not count; a dark or empty solution gets 1.
    square(&mut mesh, 20.0, 3.0, 0.0);
    assert!((out_png::solution_exposure(&mesh) - e).abs() < 1e-6);
    assert_eq!(out_png::solution_exposure(&OutputMesh::default()), 1.0);
    let mut dark = OutputMesh::default();
    square(&mut dark, 0.0, 1.0, 0.0);
    assert_eq!(out_png::solution_exposure(&dark), 1.0);
}
