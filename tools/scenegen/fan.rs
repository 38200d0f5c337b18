//! `fan-<n>`: a disc of n sliver triangles meeting at its centre under a
//! square light, the worst case for a BVH of boxes (every sliver's box
//! reaches the centre) and for per-triangle costs that should grow as
//! n log n. For benchmarks only (`gen-scenes --fan N DIR`); not bundled.
//!
//! Invariants: the disc (radius 1 m, y = 0, facing up, ρ = 0.5) shares its
//! centre and rim vertices; the light (0.6 m square at y = 1, facing down,
//! E = 1 W/m²) is one quad. Generation is a pure function of n.

use std::f64::consts::{PI, TAU};

use glam::DVec3;

use super::model::{BufferStorage, Camera, Emission, Material, SceneDef};
use super::shapes::grid;

pub fn scene(n: usize) -> SceneDef {
    let mut s = SceneDef::new(&format!("fan-{n}"), "Fan", BufferStorage::External);
    s.about = format!(
        "A 1 m disc of {n} slivers meeting at its centre, lit from 1 m above by a 0.6 m square \
         (E = 1 W/m²): a benchmark of costs against triangle count on the worst shape for boxes."
    );
    let light = s.add_material(Material {
        name: "light",
        reflectance: [0.0; 3],
        emission: Some(Emission {
            factor: [1.0 / PI; 3],
            strength: None,
        }),
        note: "L_e = 1/π",
    });
    let grey = s.add_diffuse("grey", [0.5; 3], "mid grey");
    // Faces −y: x × z = −y.
    s.add_surface(
        "light",
        light,
        grid(
            DVec3::new(-0.3, 1.0, -0.3),
            DVec3::X * 0.6,
            DVec3::Z * 0.6,
            1,
            1,
        ),
    );
    let rim = |k: usize| {
        let a = TAU * (k % n) as f64 / n as f64;
        DVec3::new(a.cos(), 0.0, a.sin())
    };
    // rim(k + 1) × rim(k) has y = sin(a_{k+1} − a_k) > 0: up.
    let slivers = (0..n).map(|k| [DVec3::ZERO, rim(k + 1), rim(k)]).collect();
    s.add_surface("disc", grey, slivers);
    s.add_camera(
        "camera",
        DVec3::new(0.0, 1.6, 1.6),
        DVec3::ZERO,
        DVec3::Y,
        Camera {
            yfov: 50f64.to_radians(),
            aspect_ratio: 1.0,
            znear: 0.01,
        },
    );
    s
}
