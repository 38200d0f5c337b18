//! The Cornell box from the Cornell Program of Computer Graphics'
//! "Cornell Box Data" page (<https://www.graphics.cornell.edu/online/box/data.html>).
//!
//! Vertex coordinates are the published ones (millimetres, converted to
//! metres), in the published order, which is already counter-clockwise seen
//! from inside the box. The published ceiling is one quad that the light
//! overlaps; here the ceiling is cut around the light (four trapezoids whose
//! inner corners are the light's corners), so that no two faces overlap and
//! the light is flush with the ceiling, sharing its edges.

use glam::DVec3;

use super::model::{BufferStorage, Camera, Emission, Material, SceneDef};
use super::shapes::{Tri, mm, quad};

/// Quads of the published data, each given as its four corners in mm.
fn quads(corners: &[[f64; 3]]) -> Vec<Tri> {
    corners
        .chunks_exact(4)
        .flat_map(|q| {
            let [a, b, c, d] = [q[0], q[1], q[2], q[3]].map(|p| mm(p[0], p[1], p[2]));
            quad(a, b, c, d)
        })
        .collect()
}

const FLOOR: [[f64; 3]; 4] = [
    [552.8, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 559.2],
    [549.6, 0.0, 559.2],
];
const LIGHT: [[f64; 3]; 4] = [
    [343.0, 548.8, 227.0],
    [343.0, 548.8, 332.0],
    [213.0, 548.8, 332.0],
    [213.0, 548.8, 227.0],
];
/// The published ceiling corners, in the published order; corner i lies
/// on the same side as light corner i.
const CEILING: [[f64; 3]; 4] = [
    [556.0, 548.8, 0.0],
    [556.0, 548.8, 559.2],
    [0.0, 548.8, 559.2],
    [0.0, 548.8, 0.0],
];
const BACK_WALL: [[f64; 3]; 4] = [
    [549.6, 0.0, 559.2],
    [0.0, 0.0, 559.2],
    [0.0, 548.8, 559.2],
    [556.0, 548.8, 559.2],
];
const RIGHT_WALL: [[f64; 3]; 4] = [
    [0.0, 0.0, 559.2],
    [0.0, 0.0, 0.0],
    [0.0, 548.8, 0.0],
    [0.0, 548.8, 559.2],
];
const LEFT_WALL: [[f64; 3]; 4] = [
    [552.8, 0.0, 0.0],
    [549.6, 0.0, 559.2],
    [556.0, 548.8, 559.2],
    [556.0, 548.8, 0.0],
];
const SHORT_BLOCK: [[f64; 3]; 20] = [
    [130.0, 165.0, 65.0],
    [82.0, 165.0, 225.0],
    [240.0, 165.0, 272.0],
    [290.0, 165.0, 114.0],
    //
    [290.0, 0.0, 114.0],
    [290.0, 165.0, 114.0],
    [240.0, 165.0, 272.0],
    [240.0, 0.0, 272.0],
    //
    [130.0, 0.0, 65.0],
    [130.0, 165.0, 65.0],
    [290.0, 165.0, 114.0],
    [290.0, 0.0, 114.0],
    //
    [82.0, 0.0, 225.0],
    [82.0, 165.0, 225.0],
    [130.0, 165.0, 65.0],
    [130.0, 0.0, 65.0],
    //
    [240.0, 0.0, 272.0],
    [240.0, 165.0, 272.0],
    [82.0, 165.0, 225.0],
    [82.0, 0.0, 225.0],
];
const TALL_BLOCK: [[f64; 3]; 20] = [
    [423.0, 330.0, 247.0],
    [265.0, 330.0, 296.0],
    [314.0, 330.0, 456.0],
    [472.0, 330.0, 406.0],
    //
    [423.0, 0.0, 247.0],
    [423.0, 330.0, 247.0],
    [472.0, 330.0, 406.0],
    [472.0, 0.0, 406.0],
    //
    [472.0, 0.0, 406.0],
    [472.0, 330.0, 406.0],
    [314.0, 330.0, 456.0],
    [314.0, 0.0, 456.0],
    //
    [314.0, 0.0, 456.0],
    [314.0, 330.0, 456.0],
    [265.0, 330.0, 296.0],
    [265.0, 0.0, 296.0],
    //
    [265.0, 0.0, 296.0],
    [265.0, 330.0, 296.0],
    [423.0, 330.0, 247.0],
    [423.0, 0.0, 247.0],
];

/// Emitted radiance of the light, W·m⁻²·sr⁻¹ per RGB channel.
pub const LIGHT_RADIANCE: [f64; 3] = [17.0, 12.0, 4.0];

/// The ceiling with the light's rectangle cut out: corner i of the outer
/// rectangle joins corner i of the light, giving four trapezoids.
fn ceiling_around_light() -> Vec<Tri> {
    let outer: Vec<Tri> = quads(&CEILING);
    let inner: Vec<Tri> = quads(&LIGHT);
    let o = [outer[0][0], outer[0][1], outer[0][2], outer[1][2]];
    let l = [inner[0][0], inner[0][1], inner[0][2], inner[1][2]];
    (0..4)
        .flat_map(|i| {
            let j = (i + 1) % 4;
            quad(o[i], o[j], l[j], l[i])
        })
        .collect()
}

pub fn scene() -> SceneDef {
    let mut s = SceneDef::new("cornell-box", "Cornell box", BufferStorage::External);
    s.about = "The Cornell box as published by the Cornell Program of Computer Graphics \
(\"Cornell Box Data\", <https://www.graphics.cornell.edu/online/box/data.html>): the \
published vertex coordinates (millimetres, converted to metres; the box is not perfectly \
rectangular and the red wall is slightly skewed, as measured), open at the front, with the \
published camera. The only change to the published geometry: the ceiling is cut around the \
light (four trapezoids meeting the light's corners) instead of being one quad under it, so \
that no faces overlap and the light is flush with the ceiling. The red wall is on the left \
of the camera's image, as in the Cornell photographs."
        .to_owned();

    let white = s.add_material(Material {
        name: "white",
        reflectance: [0.725, 0.71, 0.68],
        emission: None,
        note: "RGB summary of the published white spectrum (about 0.75 above 450 nm, \
falling to 0.34 at 400 nm); the values most renderers use (e.g. Tungsten, Mitsuba scenes)",
    });
    let red = s.add_material(Material {
        name: "red",
        reflectance: [0.63, 0.065, 0.05],
        emission: None,
        note: "RGB summary of the published red spectrum (about 0.05 below 580 nm, rising \
to about 0.63 in the red)",
    });
    let green = s.add_material(Material {
        name: "green",
        reflectance: [0.14, 0.45, 0.091],
        emission: None,
        note: "RGB summary of the published green spectrum (peak about 0.45 near 530 nm)",
    });
    let light = s.add_material(Material {
        name: "light",
        reflectance: [0.78, 0.78, 0.78],
        emission: Some(Emission::with_strength(LIGHT_RADIANCE)),
        note: "a warm white of L_e = (17, 12, 4), the usual RGB stand-in for the published \
light spectrum; the published light reflectance is 0.78",
    });

    s.add_surface("floor", white, quads(&FLOOR));
    s.add_surface("ceiling", white, ceiling_around_light());
    s.add_surface("light", light, quads(&LIGHT));
    s.add_surface("back_wall", white, quads(&BACK_WALL));
    s.add_surface("right_wall", green, quads(&RIGHT_WALL));
    s.add_surface("left_wall", red, quads(&LEFT_WALL));
    s.add_surface("short_block", white, quads(&SHORT_BLOCK));
    s.add_surface("tall_block", white, quads(&TALL_BLOCK));

    // Published camera: at (278, 273, −800) mm, looking along +z, +y up,
    // focal length 35 mm on a 25 mm × 25 mm film.
    let eye = mm(278.0, 273.0, -800.0);
    s.add_camera(
        "camera",
        eye,
        eye + DVec3::Z,
        DVec3::Y,
        Camera {
            yfov: 2.0 * (0.0125f64 / 0.035).atan(),
            aspect_ratio: 1.0,
            znear: 0.01,
        },
    );
    s
}
