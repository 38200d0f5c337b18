//! A square light over a square occluder over a floor: a penumbra with a
//! closed form.
//!
//! Geometry (metres, +y up), every square axis-aligned:
//!
//! ```text
//!   y = 2   emitter   x ∈ [−0.2, 0.8], z ∈ [−0.35, 0.65], facing down
//!   y = 1   occluder  x, z ∈ [−0.5, 0.5], facing up (its back faces the floor)
//!   y = 0   floor     x, z ∈ [−2.5, 2.5], facing up
//! ```
//!
//! A floor point f is hidden from an emitter point e when the midpoint of
//! e–f lies on the occluder, so the occluder's shadow from e is the square
//! 2·occluder − e. Over the emitter (centre c = (0.3, 0.15) in x, z) that
//! gives the umbra [−0.5 − c, 0.5 − c] and the penumbra out to
//! [−1.5 − c, 1.5 − c] per axis, both inside the floor, which is fully lit
//! beyond.
//!
//! The floor's radiosity is purely direct, B = ρ E F(x → visible part of the
//! emitter): the emitter is black, so nothing comes back from it; the
//! occluder's lit top faces away from the floor and its back (towards the
//! floor) is not a radiosity surface; the floor cannot see itself.

use glam::DVec3;

use super::model::{BufferStorage, Camera, Emission, Material, SceneDef};
use super::shapes::grid;

pub fn scene() -> SceneDef {
    let mut s = SceneDef::new("penumbra", "Penumbra", BufferStorage::External);
    s.about = "A closed-form soft shadow: a 1 m × 1 m `emitter` at y = 2 (facing down, \
x ∈ [−0.2, 0.8], z ∈ [−0.35, 0.65]), a 1 m × 1 m `occluder` at y = 1 (facing up, x, z ∈ \
[−0.5, 0.5]) and a 5 m × 5 m `floor` at y = 0 (facing up, x, z ∈ [−2.5, 2.5]). The emitter \
is offset from the occluder's centre, so the umbra (x ∈ [−0.8, 0.2], z ∈ [−0.65, 0.35]) and \
the penumbra around it (out to x ∈ [−1.8, 1.2], z ∈ [−1.65, 1.35]) are off-centre, with fully \
lit floor beyond. The emitter is black and the occluder's lit top faces away from the floor, \
so the floor's radiosity is purely direct: B(x) = ρ E F(x → the part of the emitter visible \
from x), where by additivity of Lambert's contour integral F(visible part) = F(emitter) − \
F(emitter ∩ the occluder projected from x onto the emitter's plane). A closed-form check of \
shadow meshing and of vertex values in a penumbra."
        .to_owned();

    let emitter = s.add_material(Material {
        name: "emitter",
        reflectance: [0.0, 0.0, 0.0],
        emission: Some(Emission::with_strength([10.0; 3])),
        note: "white L_e = 10, E = 10π W/m²; black, so it reflects nothing back to the floor",
    });
    let grey = s.add_material(Material {
        name: "grey",
        reflectance: [0.5, 0.5, 0.5],
        emission: None,
        note: "mid grey (floor and occluder)",
    });

    // Floor and occluder face +y: u × v = z × x = +y.
    s.add_surface(
        "floor",
        grey,
        grid(
            DVec3::new(-2.5, 0.0, -2.5),
            DVec3::Z * 5.0,
            DVec3::X * 5.0,
            1,
            1,
        ),
    );
    s.add_surface(
        "occluder",
        grey,
        grid(DVec3::new(-0.5, 1.0, -0.5), DVec3::Z, DVec3::X, 1, 1),
    );
    // Emitter faces −y: x × z = −y.
    s.add_surface(
        "emitter",
        emitter,
        grid(DVec3::new(-0.2, 2.0, -0.35), DVec3::X, DVec3::Z, 1, 1),
    );

    // From the shadow's side, between the occluder and the emitter, so that it
    // sees the emitter's front, the occluder's top and the floor.
    s.add_camera(
        "camera",
        DVec3::new(-1.6, 1.8, -4.2),
        DVec3::new(-0.2, 0.4, 0.0),
        DVec3::Y,
        Camera {
            yfov: 60f64.to_radians(),
            aspect_ratio: 1.5,
            znear: 0.01,
        },
    );
    s
}
