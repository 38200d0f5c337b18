//! The wireframe overlay (`nusselt::render::wireframe`) and its compositing into
//! `render.png` (`output::png::encode_png_with_overlay`).

use glam::{DVec3, Vec3};
use nusselt::mesh::OutputMesh;
use nusselt::output::png::{Overlay, display_byte, encode_png, encode_png_with_overlay};
use nusselt::render::frame::Frame;
use nusselt::render::view::{View, ViewOverrides};
use nusselt::render::wireframe::wireframe_mask;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use crate::fixtures::on_threads;

/// Appends the rectangle [x0, x1] × [y0, y1] at height z, facing +z, as two
/// triangles whose shared diagonal runs from (x0, y0) to (x1, y1).
fn add_quad(mesh: &mut OutputMesh, (x0, x1): (f32, f32), (y0, y1): (f32, f32), z: f32) {
    let base = mesh.positions.len() as u32;
    let patch = mesh.patch.iter().max().map_or(0, |p| p + 1);
    for (x, y) in [(x0, y0), (x1, y0), (x1, y1), (x0, y1)] {
        mesh.positions.push(Vec3::new(x, y, z));
        mesh.normals.push(Vec3::Z);
        mesh.patch.push(patch);
        mesh.radiosity.push(Vec3::ONE);
        mesh.irradiance.push(Vec3::splat(2.0));
    }
    mesh.triangles.push([base, base + 1, base + 2]);
    mesh.triangles.push([base, base + 2, base + 3]);
}

/// Looking down −z from (0, 0, 4) with a 90° field of view: a point
/// (X, Y) at z = 0 lands at image x = (X / 4 + 1) · side / 2.
fn view(side: u32) -> View {
    let o = ViewOverrides {
        eye: Some(DVec3::new(0.0, 0.0, 4.0)),
        target: Some(DVec3::ZERO),
        fov_deg: Some(90.0),
        width: Some(side),
        height: Some(side),
        ..Default::default()
    };
    View::resolve(None, (DVec3::splat(-1.0), DVec3::ONE), &o).unwrap()
}

/// The unit quad's outline and diagonal in a 20 × 20 image: its corners land
/// on the centres of pixels 7 and 12 in each direction.
fn unit_quad_pixels() -> Vec<(u32, u32)> {
    let mut px = Vec::new();
    for k in 7..=12 {
        px.extend([(7, k), (12, k), (k, 7), (k, 12), (k, 19 - k)]);
    }
    px.sort_unstable();
    px.dedup();
    px
}

fn at(mask: &[f32], side: u32, (x, y): (u32, u32)) -> f32 {
    mask[(y * side + x) as usize]
}

#[test]
fn quad_head_on_shows_outline_and_diagonal_only() {
    let mut mesh = OutputMesh::default();
    add_quad(&mut mesh, (-1.0, 1.0), (-1.0, 1.0), 0.0);
    mesh.validate().unwrap();
    let mask = wireframe_mask(&mesh, &view(20));
    assert_eq!(mask.len(), 400);
    let lines = unit_quad_pixels();
    for y in 0..20 {
        for x in 0..20 {
            let c = at(&mask, 20, (x, y));
            if lines.contains(&(x, y)) {
                assert!(c > 0.99, "line pixel ({x}, {y}) has coverage {c}");
            } else {
                assert!(c < 0.01, "pixel ({x}, {y}) off the lines has coverage {c}");
            }
        }
    }
}

#[test]
fn edges_behind_a_nearer_quad_are_hidden() {
    let mut mesh = OutputMesh::default();
    add_quad(&mut mesh, (-1.0, 1.0), (-1.0, 1.0), 0.0);
    // At z = 1, image x = (X / 3 + 1) · 10: this quad covers image columns
    // 0 to 11 (its right edge on the boundary of pixels 10 and 11) and the
    // full height; its other edges and its diagonal stay away from the far
    // quad's left edge.
    add_quad(&mut mesh, (-3.0, 0.3), (-6.0, 6.0), 1.0);
    mesh.validate().unwrap();
    let mask = wireframe_mask(&mesh, &view(20));
    // The far quad's left edge and the hidden part of its diagonal.
    for y in 7..=12 {
        assert_eq!(at(&mask, 20, (7, y)), 0.0, "hidden pixel (7, {y})");
    }
    for x in 8..=9 {
        assert_eq!(at(&mask, 20, (x, 19 - x)), 0.0, "hidden diagonal ({x})");
    }
    // Its right edge and the uncovered end of the diagonal still show.
    for y in 7..=12 {
        assert!(at(&mask, 20, (12, y)) > 0.99, "visible pixel (12, {y})");
    }
    assert!(at(&mask, 20, (11, 8)) > 0.99);
    // The near quad's own right edge shows on its surface, split over the
    // two columns it separates (away from the far quad's lines).
    for y in (0..20).filter(|y| !(7..=12).contains(y)) {
        let (l, r) = (at(&mask, 20, (10, y)), at(&mask, 20, (11, y)));
        assert!(
            (l - 0.5).abs() < 0.01 && (r - 0.5).abs() < 0.01,
            "{y}: {l} {r}"
        );
    }
}

#[test]
fn edge_through_the_eye_plane_is_clipped_not_lost() {
    // A degenerate triangle (two equal indices) whose one real edge runs
    // along the floor from far in front of the eye to behind it.
    let mut mesh = OutputMesh::default();
    for z in [-10.0, 10.0] {
        mesh.positions.push(Vec3::new(0.0, -1.0, z));
        mesh.normals.push(Vec3::Y);
        mesh.patch.push(0);
        mesh.radiosity.push(Vec3::ZERO);
        mesh.irradiance.push(Vec3::ZERO);
    }
    mesh.triangles.push([0, 1, 1]);
    let mask = wireframe_mask(&mesh, &view(21));
    // It projects to column 10 from its far end (y = 11.25) down to the
    // bottom of the image: rows 11 to 20.
    for y in 11..21 {
        assert!(at(&mask, 21, (10, y)) > 0.99, "row {y}");
    }
    let elsewhere: f32 = (0..21 * 21)
        .filter(|i| i % 21 != 10)
        .map(|i| mask[i as usize])
        .sum();
    assert!(elsewhere < 0.01, "{elsewhere}");
    assert!((0..11).all(|y| at(&mask, 21, (10, y)) == 0.0));
}

#[test]
fn degenerate_input_does_not_panic() {
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let positions = vec![
        p(0.0, 0.0, 4.0), // the eye itself
        p(0.0, 0.0, 0.0),
        p(0.0, 0.0, 0.0), // duplicate of 1
        p(1.0, 1.0, 1.0),
        p(f32::NAN, 0.0, 0.0),
        p(f32::INFINITY, 1.0, 0.0),
        p(0.0, 0.0, 100.0), // behind the eye
        p(3.0e38, -3.0e38, 1.0),
        p(0.0, 0.0, 4.0 - 1e-7), // just in front of the eye
    ];
    let n = positions.len();
    let mesh = OutputMesh {
        positions,
        normals: vec![Vec3::Z; n],
        patch: vec![0; n],
        radiosity: vec![Vec3::ZERO; n],
        irradiance: vec![Vec3::ZERO; n],
        triangles: vec![
            [1, 1, 1],
            [1, 2, 3],
            [0, 1, 3],
            [4, 5, 1],
            [4, 1, 3],
            [6, 1, 3],
            [0, 6, 8],
            [7, 1, 3],
            [1, 3, 99],
            [u32::MAX, 0, 1],
        ],
    };
    for side in [1, 2, 20] {
        let mask = wireframe_mask(&mesh, &view(side));
        assert_eq!(mask.len(), (side * side) as usize);
        assert!(mask.iter().all(|c| (0.0..=1.0).contains(c)));
    }
    assert!(
        wireframe_mask(&OutputMesh::default(), &view(4))
            .iter()
            .all(|c| *c == 0.0)
    );
}

#[test]
fn same_mask_for_one_and_two_threads() {
    let mut rng = Pcg64::seed_from_u64(6);
    let mut mesh = OutputMesh::default();
    for _ in 0..300 {
        let x = rng.random_range(-1.5f32..1.3);
        let y = rng.random_range(-1.5f32..1.3);
        let z = rng.random_range(-1.0f32..1.0);
        let (dx, dy) = (
            rng.random_range(0.05f32..0.5),
            rng.random_range(0.05f32..0.5),
        );
        add_quad(&mut mesh, (x, x + dx), (y, y + dy), z);
    }
    let o = ViewOverrides {
        eye: Some(DVec3::new(1.0, 2.0, 5.0)),
        target: Some(DVec3::ZERO),
        fov_deg: Some(60.0),
        width: Some(96),
        height: Some(64),
        ..Default::default()
    };
    let view = View::resolve(None, (DVec3::splat(-2.0), DVec3::splat(2.0)), &o).unwrap();
    let masks: Vec<Vec<f32>> = [1, 2]
        .map(|threads| on_threads(threads, || wireframe_mask(&mesh, &view)))
        .into();
    assert_eq!(masks[0], masks[1]);
    let lit = masks[0].iter().filter(|c| **c > 0.5).count();
    assert!(lit > 500 && lit < 96 * 64 / 2, "{lit} line pixels");
}

#[test]
fn overlay_blends_in_linear_light_and_leaves_zero_coverage_alone() {
    let frame = Frame {
        width: 3,
        height: 1,
        pixels: vec![[0.2, 0.4, 0.1], [0.0; 3], [5.0, 0.3, 0.0]],
    };
    let overlay = Overlay {
        coverage: &[0.0, 0.5, 1.0],
        color: [1.0, 0.0, 0.25],
    };
    let decode = |bytes: &[u8]| {
        image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
            .unwrap()
            .to_rgb8()
    };
    let with = decode(&encode_png_with_overlay(&frame, 2.0, &overlay).unwrap());
    let without = decode(&encode_png(&frame, 2.0).unwrap());
    assert_eq!(with.get_pixel(0, 0), without.get_pixel(0, 0));
    // Half coverage of red over black: display value 0.5 in red.
    assert_eq!(
        with.get_pixel(1, 0).0,
        [display_byte(0.5, 1.0), 0, display_byte(0.125, 1.0)]
    );
    assert_eq!(with.get_pixel(2, 0).0, [255, 0, display_byte(0.25, 1.0)]);
    let short = Overlay {
        coverage: &[1.0],
        color: [1.0; 3],
    };
    let err = encode_png_with_overlay(&frame, 2.0, &short).unwrap_err();
    assert!(err.to_string().contains("overlay"), "{err}");
}
