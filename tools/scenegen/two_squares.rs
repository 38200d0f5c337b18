//! Two directly opposed unit squares 1 m apart, for closed-form checks.
//!
//! The form factor between two parallel, directly opposed unit squares at
//! distance 1 is 0.199825 (the closed form for parallel directly opposed
//! rectangles, found in any table of view factors).
//! The lower square emits E = 1 W/m² (L_e = 1/π) and reflects nothing; the
//! upper one reflects ρ = 0.5 and emits nothing, so its irradiance is
//! H = F · E and its radiosity B = ρ F E exactly (nothing else is in the
//! scene, so light escapes after at most one bounce off the receiver: the
//! black emitter absorbs what comes back).

use std::f64::consts::PI;

use glam::DVec3;

use super::model::{BufferStorage, Camera, Emission, Material, SceneDef};
use super::shapes::grid;

pub fn scene() -> SceneDef {
    let mut s = SceneDef::new("two-squares", "Two squares", BufferStorage::External);
    s.about = "Two parallel, directly opposed 1 m × 1 m squares 1 m apart: the lower one \
(`emitter`, at y = 0, facing up) emits E = 1 W/m² and reflects nothing; the upper one \
(`receiver`, at y = 1, facing down) reflects ρ = 0.5. The form factor between them is \
F = 0.199825, so the receiver's mean irradiance is H = F · E = 0.199825 W/m² and its mean \
radiosity B = ρ H = 0.0999125 W/m², with no further bounces (the emitter is black). A \
closed-form check of form factors and of the whole pipeline."
        .to_owned();

    let black_emitter = s.add_material(Material {
        name: "emitter",
        reflectance: [0.0, 0.0, 0.0],
        emission: Some(Emission {
            factor: [1.0 / PI; 3],
            strength: None,
        }),
        note: "L_e = 1/π, E = 1 W/m²; black, so it reflects nothing",
    });
    let grey = s.add_material(Material {
        name: "grey",
        reflectance: [0.5, 0.5, 0.5],
        emission: None,
        note: "mid grey",
    });

    // Emitter faces +y: u × v = z × x = +y.
    s.add_surface(
        "emitter",
        black_emitter,
        grid(DVec3::ZERO, DVec3::Z, DVec3::X, 1, 1),
    );
    // Receiver faces −y: x × z = −y.
    s.add_surface("receiver", grey, grid(DVec3::Y, DVec3::X, DVec3::Z, 1, 1));

    s.add_camera(
        "camera",
        DVec3::new(0.5, 0.5, 1.8),
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::Y,
        Camera {
            yfov: 50f64.to_radians(),
            aspect_ratio: 1.0,
            znear: 0.01,
        },
    );
    s
}
