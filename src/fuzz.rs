//! The bodies of the fuzz targets of `fuzz/` (loader, triangulation, the
//! whole pipeline on tiny random scenes), here so that `cargo test` replays
//! their corpora and regressions on stable (`tests/fuzz_corpus.rs`).
//!
//! Invariant: a harness never panics by itself; it returns an error when a
//! result breaks an invariant, and a panic inside the library is a finding.
//! Not part of the library's API.

use glam::DVec3;

use crate::hierarchical::Accuracy;
use crate::meshing::triangulate::{
    PatchInput, TriangulateOptions, triangulate_patches, validate_patch_mesh,
};
use crate::pipeline::{SolveSettings, solve};
use crate::scene::{InputTriangle, Material, Scene, Surface};
use crate::util::progress::Progress;

/// The body of the `load_gltf` fuzz target: bytes as a `.gltf` or `.glb`
/// file. Loading must return (a scene or an error), never panic.
pub fn fuzz_load(data: &[u8]) {
    let _ = crate::load::load_scene_from_slice(data, None, &Default::default());
}

/// Largest relative excess of absorbed over emitted power that
/// [`fuzz_pipeline`] accepts (per channel): preview accuracy on arbitrary
/// geometry (touching, penetrating, coplanar overlapping polygons).
pub const FUZZ_ENERGY_TOL: f64 = 0.05;

/// The body of the `pipeline` fuzz target: bytes become a tiny scene of one
/// to four parallelograms and up to three triangles (positions on a 1/32
/// grid of ±4, at a scale from 1 mm to 1 km, random reflectances, emissions
/// and sidedness, the first polygon always emitting), which is solved
/// hierarchically at preview accuracy and rendered at 12×8.
///
/// Returns an error when a result breaks an invariant: a non-finite or
/// negative radiosity or pixel, an output mesh that does not validate, or
/// absorbed power above the emitted power by more than [`FUZZ_ENERGY_TOL`].
/// A scene the library refuses (every polygon degenerate) is not an error.
/// It never panics by itself; a panic inside the library is a finding.
pub fn fuzz_pipeline(data: &[u8]) -> std::result::Result<(), String> {
    let mut bytes = data.iter().copied();
    let mut next = move || bytes.next().unwrap_or(0);
    let coord = |b: u8| f64::from(b) / 32.0 - 4.0;
    let scale = 10f64.powi(i32::from(next() % 7) - 3);
    let quads = 1 + usize::from(next() % 4);
    let triangles = usize::from(next() % 4);
    let mut input = Vec::new();
    let mut materials = Vec::new();
    let mut surfaces = Vec::new();
    for k in 0..quads + triangles {
        let mut point = || DVec3::new(coord(next()), coord(next()), coord(next())) * scale;
        let (o, a, b) = (point(), point(), point());
        let corners = if k < quads {
            vec![[o, o + a, o + a + b], [o, o + a + b, o + b]]
        } else {
            vec![[o, o + a, o + b]]
        };
        let flags = next();
        let reflectance = DVec3::new(
            f64::from(next()) / 256.0,
            f64::from(next()) / 256.0,
            f64::from(next()) / 256.0,
        );
        let emits = k == 0 || flags & 1 == 1;
        let emitted_radiance = if emits {
            DVec3::new(
                f64::from(next()) / 16.0 + 0.1,
                f64::from(next()) / 16.0 + 0.1,
                f64::from(next()) / 16.0 + 0.1,
            )
        } else {
            DVec3::ZERO
        };
        materials.push(Material {
            name: format!("m{k}"),
            reflectance,
            emitted_radiance,
            double_sided: flags & 2 == 2,
        });
        surfaces.push(Surface {
            name: format!("s{k}"),
            node: k,
        });
        for positions in corners {
            input.push(InputTriangle {
                positions,
                material: k as u32,
                surface: k as u32,
                reflectance,
                emitted_radiance,
                origin: Default::default(),
            });
        }
    }
    let Ok(scene) = Scene::build(input, materials, surfaces, Vec::new(), Vec::new()) else {
        return Ok(());
    };
    let mut settings = SolveSettings::default();
    settings.hierarchical.accuracy = Accuracy::preview();
    settings.view.width = Some(12);
    settings.view.height = Some(8);
    settings.render.samples_per_pixel = 1;
    let run = solve(&scene, &settings, &Progress::new(false)).map_err(|e| e.to_string())?;
    run.mesh.validate()?;
    if let Some(v) = run
        .mesh
        .radiosity
        .iter()
        .find(|b| !(b.is_finite() && b.min_element() >= 0.0))
    {
        return Err(format!("output radiosity {v}"));
    }
    if let Some(p) = run
        .frame
        .pixels
        .iter()
        .find(|p| !p.iter().all(|c| c.is_finite() && *c >= 0.0))
    {
        return Err(format!("pixel {p:?}"));
    }
    let power = &run.report.power;
    for c in 0..3 {
        let (e, a) = (power.emitted[c], power.absorbed[c]);
        if !(e.is_finite() && a.is_finite() && a >= 0.0 && a <= e * (1.0 + FUZZ_ENERGY_TOL)) {
            return Err(format!(
                "channel {c}: absorbed {a} W against emitted {e} W (tolerance {FUZZ_ENERGY_TOL})"
            ));
        }
    }
    Ok(())
}

/// The body of the `triangulate` fuzz target: bytes become points and
/// segments on the patches of a small fixed scene (an L-shaped floor with a
/// T-junction and a wall), snapped to a 1/128 grid of patch parameters so
/// that coincidences and collinearities are frequent. Returns an error when
/// triangulation fails or its result does not validate; it never panics.
pub fn fuzz_triangulate(data: &[u8]) -> std::result::Result<(), String> {
    let scene = fuzz_scene().map_err(|e| e.to_string())?;
    let Some((&first, rest)) = data.split_first() else {
        return Ok(());
    };
    let opts = TriangulateOptions {
        min_angle_deg: (first & 1 == 1).then(|| 15.0 + f64::from(first >> 1) % 16.0),
        max_added_vertices: 200,
    };
    let np = scene.patches.len();
    let mut inputs = vec![PatchInput::default(); np];
    let mut bytes = rest.iter().copied();
    for _ in 0..64 {
        let Some(tag) = bytes.next() else { break };
        let patch = &scene.patches[tag as usize % np];
        let c = patch.vertices();
        let jitter = if tag & 0x80 != 0 { 1e-12 } else { 0.0 };
        let mut point = || -> Option<DVec3> {
            let u = f64::from(bytes.next()?) / 128.0 - 0.5 + jitter;
            let v = f64::from(bytes.next()?) / 128.0 - 0.5;
            Some(c[0] + u * (c[1] - c[0]) + v * (c[c.len() - 1] - c[0]))
        };
        let input = &mut inputs[tag as usize % np];
        if (tag as usize / np).is_multiple_of(2) {
            let Some(p) = point() else { break };
            input.points.push(p);
        } else {
            let (Some(p), Some(q)) = (point(), point()) else {
                break;
            };
            input.segments.push([p, q]);
        }
    }
    let tris = triangulate_patches(&scene, &inputs, &opts).map_err(|e| e.to_string())?;
    validate_patch_mesh(&scene, &tris, &inputs)
}

/// The fixed scene of [`fuzz_triangulate`].
fn fuzz_scene() -> crate::error::Result<Scene> {
    let quad = |p: [[f64; 3]; 4], surface: u32, material: u32| {
        let p = p.map(DVec3::from_array);
        [[p[0], p[1], p[2]], [p[0], p[2], p[3]]].map(|positions| InputTriangle {
            positions,
            material,
            surface,
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::splat(f64::from(material)),
            origin: Default::default(),
        })
    };
    let mut tris = Vec::new();
    tris.extend(quad(
        [[0., 0., 0.], [2., 0., 0.], [2., 1., 0.], [0., 1., 0.]],
        0,
        0,
    ));
    tris.extend(quad(
        [[2., 0., 0.], [3., 0., 0.], [3., 0.5, 0.], [2., 0.5, 0.]],
        1,
        0,
    ));
    tris.extend(quad(
        [[2., 0.5, 0.], [3., 0.5, 0.], [3., 1., 0.], [2., 1., 0.]],
        2,
        0,
    ));
    tris.extend(quad(
        [[0., 0., 0.], [0., 0., 1.], [1.3, 0., 1.], [1.3, 0., 0.]],
        3,
        1,
    ));
    tris.push(InputTriangle {
        positions: [[1.3, 0., 0.], [1.3, 0., 1.], [3., 0., 0.]].map(DVec3::from_array),
        material: 0,
        surface: 4,
        reflectance: DVec3::splat(0.5),
        emitted_radiance: DVec3::ZERO,
        origin: Default::default(),
    });
    let materials = (0..2)
        .map(|m| Material {
            name: format!("m{m}"),
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::splat(f64::from(m)),
            double_sided: false,
        })
        .collect();
    let surfaces = (0..5)
        .map(|s| Surface {
            name: format!("s{s}"),
            node: s,
        })
        .collect();
    Scene::build(tris, materials, surfaces, Vec::new(), Vec::new())
}
