//! A Goral-1984-style empty box [GTGB84]: a closed 1 m cube, no occluders,
//! the whole ceiling a diffuse emitter, one red and one blue wall, the rest
//! white. Closed, so that enclosure identities (Σ_j F_ij = 1, total power
//! balance) can be checked on it. Each face is a single quad.
//!
//! ```text
//!   y                 back_wall at z = 0, front_wall at z = 1,
//!   │                 left_wall (red) at x = 0, right_wall (blue) at x = 1,
//!   └── x             floor at y = 0, ceiling (emitter) at y = 1;
//!  ╱                  the camera at z = 0.9 looks down −z at the back wall.
//! z
//! ```

use std::f64::consts::PI;

use glam::DVec3;

use super::model::{BufferStorage, Camera, Emission, Material, SceneDef};
use super::shapes::{Side, box_face, quad};

/// The cube's face looking in direction `facing`, wound to face inwards.
fn inner_face(facing: Side) -> Vec<super::shapes::Tri> {
    // The inward face looking along +n is the cube's outward face on the −n
    // side, wound the other way round.
    let outer = facing.opposite();
    let (o, u, v) = box_face(DVec3::ZERO, DVec3::ONE, outer);
    quad(o, o + v, o + u + v, o + u).to_vec()
}

pub fn scene() -> SceneDef {
    let mut s = SceneDef::new("goral-box", "Goral box", BufferStorage::Embedded);
    s.about = "An empty closed box in the manner of Goral, Torrance, Greenberg and Battaile \
(1984), the first radiosity paper [GTGB84]: a 1 m cube with no occluders, the whole ceiling \
a diffuse emitter of exitance E = 1 W/m², the left wall red, the right wall blue, the other \
faces white. Each face is one quad (two triangles). Because the box is closed, every row of \
form factors sums to 1 and all emitted power is eventually absorbed, which makes it the scene \
for enclosure and energy-balance checks. Its buffer is embedded in the `.gltf` as a base64 \
`data:` URI (the other scenes use an external `.bin`), so both loader paths are exercised; \
the emitter carries no `KHR_materials_emissive_strength` (its L_e = 1/π fits in \
`emissiveFactor`)."
        .to_owned();

    let white = s.add_material(Material {
        name: "white",
        reflectance: [0.75, 0.75, 0.75],
        emission: None,
        note: "neutral matte white",
    });
    let red = s.add_material(Material {
        name: "red",
        reflectance: [0.75, 0.1, 0.1],
        emission: None,
        note: "saturated red of the same peak reflectance as the white",
    });
    let blue = s.add_material(Material {
        name: "blue",
        reflectance: [0.1, 0.1, 0.75],
        emission: None,
        note: "saturated blue of the same peak reflectance as the white",
    });
    let light = s.add_material(Material {
        name: "ceiling_light",
        reflectance: [0.75, 0.75, 0.75],
        emission: Some(Emission {
            factor: [1.0 / PI; 3],
            strength: None,
        }),
        note: "white emitter, L_e = 1/π so that E = π L_e = 1 W/m²; it also reflects like \
the white walls",
    });

    s.add_surface("floor", white, inner_face(Side::PosY));
    s.add_surface("ceiling", light, inner_face(Side::NegY));
    s.add_surface("back_wall", white, inner_face(Side::PosZ));
    s.add_surface("front_wall", white, inner_face(Side::NegZ));
    s.add_surface("left_wall", red, inner_face(Side::PosX));
    s.add_surface("right_wall", blue, inner_face(Side::NegX));

    s.add_camera(
        "camera",
        DVec3::new(0.5, 0.5, 0.9),
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::Y,
        Camera {
            yfov: 70f64.to_radians(),
            aspect_ratio: 1.0,
            znear: 0.01,
        },
    );
    s
}
