//! The stress scenes of `scenes/stress/`: small scenes built to sit where
//! radiosity methods are known to fail (near contact, penetration, coplanar
//! overlap, slivers, extreme scales, reflectance near 1, lost or escaping
//! light, thousands of emitters, a singular kernel along a shared edge).
//!
//! Invariants: every scene is small (at most a few thousand triangles, most
//! a few dozen) so that the fast test subset solves them in seconds; every
//! scene has exactly the geometry its README section describes, one camera
//! and at least one emitter; each carries a note of what it stresses and
//! which method is expected to struggle, which the README prints.

use std::f64::consts::PI;

use glam::DVec3;

use super::model::{BufferStorage, Camera, Emission, Material, SceneDef};
use super::shapes::{Side, Tri, box_face, cuboid, grid, quad};

/// A stress scene and its README notes.
#[derive(Clone, Debug)]
pub struct StressScene {
    pub scene: SceneDef,
    /// What the scene stresses.
    pub stresses: &'static str,
    /// Which method is expected to struggle, and how.
    pub struggles: &'static str,
}

/// Every stress scene, in README order.
pub fn scenes() -> Vec<StressScene> {
    vec![
        nearly_touching(),
        penetrating_box(),
        coplanar_overlap(),
        slivers(),
        tiny_emitter(),
        scale_range(),
        furnace_099(),
        facing_away(),
        open_floor(),
        many_emitters(),
        shared_edge(),
    ]
}

/// A point of the plane y = `y` from (x, z).
fn xz(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// A rectangle x ∈ [x0, x1], z ∈ [z0, z1] in the plane y, facing +y.
fn rect_up(x0: f64, x1: f64, z0: f64, z1: f64, y: f64) -> Vec<Tri> {
    grid(
        xz(x0, y, z0),
        DVec3::Z * (z1 - z0),
        DVec3::X * (x1 - x0),
        1,
        1,
    )
}

/// The same rectangle facing −y.
fn rect_down(x0: f64, x1: f64, z0: f64, z1: f64, y: f64) -> Vec<Tri> {
    grid(
        xz(x0, y, z0),
        DVec3::X * (x1 - x0),
        DVec3::Z * (z1 - z0),
        1,
        1,
    )
}

/// The face of the box [min, max] on side `side`, wound to face into the box.
fn inner_face(min: DVec3, max: DVec3, side: Side) -> Vec<Tri> {
    let (o, u, v) = box_face(min, max, side);
    quad(o, o + v, o + u + v, o + u).to_vec()
}

/// The six inner faces of the room [0, size] in material `material`.
fn closed_room(s: &mut SceneDef, material: usize, size: DVec3) {
    for (name, side) in [
        ("floor", Side::NegY),
        ("ceiling", Side::PosY),
        ("left_wall", Side::NegX),
        ("right_wall", Side::PosX),
        ("back_wall", Side::NegZ),
        ("front_wall", Side::PosZ),
    ] {
        s.add_surface(name, material, inner_face(DVec3::ZERO, size, side));
    }
}

/// The triangle (a, b, c), reordered if needed so that its front faces
/// `facing`.
fn facing(a: DVec3, b: DVec3, c: DVec3, facing: DVec3) -> Tri {
    if (b - a).cross(c - a).dot(facing) >= 0.0 {
        [a, b, c]
    } else {
        [a, c, b]
    }
}

fn grey(s: &mut SceneDef, name: &'static str, rho: f64, note: &'static str) -> usize {
    s.add_material(Material {
        name,
        reflectance: [rho; 3],
        emission: None,
        note,
    })
}

/// A black emitter of radiance `le` (W·m⁻²·sr⁻¹, white).
fn black_light(s: &mut SceneDef, le: f64, note: &'static str) -> usize {
    s.add_material(Material {
        name: "light",
        reflectance: [0.0; 3],
        emission: Some(Emission::with_strength([le; 3])),
        note,
    })
}

fn camera(s: &mut SceneDef, eye: DVec3, target: DVec3, yfov_deg: f64, znear: f64) {
    s.add_camera(
        "camera",
        eye,
        target,
        DVec3::Y,
        Camera {
            yfov: yfov_deg.to_radians(),
            aspect_ratio: 1.5,
            znear,
        },
    );
}

/// Gaps of the nearly-touching plates, as fractions of the 1 m floor.
pub const PLATE_GAPS: [f64; 4] = [1e-3, 1e-4, 1e-5, 1e-6];

fn nearly_touching() -> StressScene {
    let mut s = SceneDef::new(
        "nearly-touching",
        "Nearly touching plates",
        BufferStorage::External,
    );
    s.about = "Four 0.3 m × 0.3 m × 0.02 m plates (closed boxes, faces outwards) hover over a \
1 m × 1 m `floor` (y = 0, facing up) with gaps of 1 mm, 100 µm, 10 µm and 1 µm under their \
bottom faces: 1e-3 to 1e-6 of the scene's 1 m size. A 0.4 m × 0.4 m `light` at y = 1 faces \
down over the middle; there are no walls. The floor under each plate and each plate's bottom \
face see each other across the gap and almost nothing else, so both should stay nearly black \
(light enters a gap only through its rim, which is as high as the gap)."
        .to_owned();
    let white = grey(&mut s, "white", 0.7, "matte white floor");
    let plate = grey(&mut s, "grey", 0.5, "mid grey plates");
    let light = black_light(&mut s, 10.0, "white L_e = 10; black");
    s.add_surface("floor", white, rect_up(0.0, 1.0, 0.0, 1.0, 0.0));
    let names = ["plate_1mm", "plate_100um", "plate_10um", "plate_1um"];
    for (k, (gap, name)) in PLATE_GAPS.iter().zip(names).enumerate() {
        let x0 = if k % 2 == 0 { 0.1 } else { 0.6 };
        let z0 = if k < 2 { 0.1 } else { 0.6 };
        s.add_surface(
            name,
            plate,
            cuboid(
                DVec3::new(x0, *gap, z0),
                DVec3::new(x0 + 0.3, gap + 0.02, z0 + 0.3),
                &[],
            ),
        );
    }
    s.add_surface("light", light, rect_down(0.3, 0.7, 0.3, 0.7, 1.0));
    camera(
        &mut s,
        DVec3::new(0.5, 0.45, -0.9),
        DVec3::new(0.5, 0.0, 0.5),
        50.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "contact and near contact: form factors between surfaces 1 µm apart are \
singular (point-to-area F → 1 per unit area), and ray-cast visibility needs an offset smaller \
than the gap, else rays start beyond the plate and light leaks under it.",
        struggles: "sampled visibility (rays from the floor under a plate pass through it when \
the ray offset exceeds the gap), the hemicube (its near plane clips the plate, so the floor \
under it sees the light) and point-polygon form factors at element centroids under the plate \
(F to the plate's bottom face ≈ 1). Coarse hierarchical leaves straddling a plate's edge \
average lit and shadowed floor.",
    }
}

fn penetrating_box() -> StressScene {
    let mut s = SceneDef::new(
        "penetrating-box",
        "Box penetrating the floor",
        BufferStorage::External,
    );
    s.about = "A 0.6 m × 0.6 m × 0.6 m `box` (all six faces, facing outwards) sunk 0.2 m \
into a 2 m × 2 m `floor` (y = 0, facing up): x, z ∈ [−0.3, 0.3], y ∈ [−0.2, 0.4]. The floor \
is one quad running through the box, and the box's sides run through the floor. A \
0.5 m × 0.5 m `light` at y = 1.5 (x, z ∈ [0.2, 0.7]) faces down; no walls. The floor inside \
the box and the box below the floor receive no light at all."
        .to_owned();
    let white = grey(&mut s, "white", 0.7, "matte white floor");
    let box_m = grey(&mut s, "grey", 0.5, "mid grey box");
    let light = black_light(&mut s, 10.0, "white L_e = 10; black");
    s.add_surface("floor", white, rect_up(-1.0, 1.0, -1.0, 1.0, 0.0));
    s.add_surface(
        "box",
        box_m,
        cuboid(DVec3::new(-0.3, -0.2, -0.3), DVec3::new(0.3, 0.4, 0.3), &[]),
    );
    s.add_surface("light", light, rect_down(0.2, 0.7, 0.2, 0.7, 1.5));
    camera(
        &mut s,
        DVec3::new(-1.2, 1.3, -1.8),
        DVec3::new(0.0, 0.1, 0.0),
        50.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "interpenetration: surfaces cross without a shared edge, so the lit floor \
and the dark floor inside the box meet along a line that no input edge marks, and parts of \
the box lie behind the floor.",
        struggles: "every mesh that does not follow the intersection line: uniform and \
quadtree elements straddling the box's footprint average the lit floor with the dark floor \
inside the box (a light leak under the box's walls, or a dark halo around it); \
point-sampled kernels whose sample lands inside the box.",
    }
}

fn coplanar_overlap() -> StressScene {
    let mut s = SceneDef::new(
        "coplanar-overlap",
        "Coplanar overlapping polygons",
        BufferStorage::External,
    );
    s.about = "A 2 m × 2 m `floor` (y = 0, facing up) with two squares lying exactly in its \
plane and overlapping each other: a red `rug` (x, z ∈ [−0.5, 0.3]) and a blue `tile` (x, z \
∈ [−0.1, 0.7]), both at y = 0 facing up. A `back_wall` (z = −1, facing +z, 2 m × 1.5 m) \
gives a second bounce, and a 0.6 m × 0.6 m `light` at y = 1.5 faces down. Where the \
polygons overlap, three surfaces claim the same points."
        .to_owned();
    let white = grey(&mut s, "white", 0.7, "matte white floor and wall");
    let red = s.add_material(Material {
        name: "red",
        reflectance: [0.7, 0.1, 0.1],
        emission: None,
        note: "red rug",
    });
    let blue = s.add_material(Material {
        name: "blue",
        reflectance: [0.1, 0.1, 0.7],
        emission: None,
        note: "blue tile",
    });
    let light = black_light(&mut s, 10.0, "white L_e = 10; black");
    s.add_surface("floor", white, rect_up(-1.0, 1.0, -1.0, 1.0, 0.0));
    s.add_surface("rug", red, rect_up(-0.5, 0.3, -0.5, 0.3, 0.0));
    s.add_surface("tile", blue, rect_up(-0.1, 0.7, -0.1, 0.7, 0.0));
    s.add_surface(
        "back_wall",
        white,
        grid(
            DVec3::new(-1.0, 0.0, -1.0),
            DVec3::X * 2.0,
            DVec3::Y * 1.5,
            1,
            1,
        ),
    );
    s.add_surface("light", light, rect_down(-0.3, 0.3, -0.3, 0.3, 1.5));
    camera(
        &mut s,
        DVec3::new(0.0, 1.6, 2.0),
        DVec3::new(0.0, 0.0, 0.0),
        50.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "coplanar overlap (z-fighting): a ray leaving one of the overlapping \
surfaces starts on the others, and which surface is seen there is decided by rounding.",
        struggles: "visibility without a robust self-intersection rule (rays from the rug \
hit the floor or the tile at t ≈ 0 and count as blocked, darkening the overlap), and the \
hemicube (its z-buffer flickers between the coplanar polygons). The energy bookkeeping stays \
valid: overlapping receivers each absorb what reaches them.",
    }
}

/// Height of the sliver triangles: aspect ratio 1 m / 0.1 mm = 1e4.
pub const SLIVER_HEIGHT: f64 = 1e-4;

fn slivers() -> StressScene {
    let mut s = SceneDef::new("slivers", "Slivers", BufferStorage::External);
    s.about = "A 1 m × 1 m `floor` (y = 0, facing up) triangulated with a sliver along each \
edge: the triangle of an edge and a point 0.1 mm inside its midpoint (aspect ratio 1e4), plus \
eight ordinary triangles fanning from the centre. Over it, at y = 0.5, five `slats` 1 m long \
and 0.1 mm wide (x ∈ [0, 1], facing up), each a quad of two slivers, cast hair-thin shadows; \
a 0.4 m × 0.4 m `light` at y = 1 faces down. No walls."
        .to_owned();
    let white = grey(&mut s, "white", 0.7, "matte white floor");
    let slat = grey(&mut s, "grey", 0.5, "mid grey slats");
    let light = black_light(&mut s, 10.0, "white L_e = 10; black");
    let h = SLIVER_HEIGHT;
    let p = |x: f64, z: f64| xz(x, 0.0, z);
    let (a, b, c, d) = (p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0));
    let (pb, pr, pt, pl) = (p(0.5, h), p(1.0 - h, 0.5), p(0.5, 1.0 - h), p(h, 0.5));
    let m = p(0.5, 0.5);
    let mut floor = vec![
        facing(a, b, pb, DVec3::Y),
        facing(b, c, pr, DVec3::Y),
        facing(c, d, pt, DVec3::Y),
        facing(d, a, pl, DVec3::Y),
    ];
    let ring = [a, pb, b, pr, c, pt, d, pl];
    for k in 0..ring.len() {
        floor.push(facing(m, ring[k], ring[(k + 1) % ring.len()], DVec3::Y));
    }
    s.add_surface("floor", white, floor);
    let slats: Vec<Tri> = [0.2, 0.35, 0.5, 0.65, 0.8]
        .iter()
        .flat_map(|&z| rect_up(0.0, 1.0, z, z + h, 0.5))
        .collect();
    s.add_surface("slats", slat, slats);
    s.add_surface("light", light, rect_down(0.3, 0.7, 0.3, 0.7, 1.0));
    camera(
        &mut s,
        DVec3::new(0.5, 1.1, -0.6),
        DVec3::new(0.5, 0.0, 0.5),
        55.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "slivers: triangles 1 m long and 0.1 mm high, whose centroids, normals and \
areas are computed from nearly collinear points, and whose subdivision gives ever thinner \
children.",
        struggles: "uniform meshing and quadtree subdivision (splitting a sliver keeps its \
aspect ratio, so elements stay slivers however small), point-polygon form factors taken at a \
sliver's centroid, and discontinuity meshing (constrained triangulation of 0.1 mm strips, \
shadow lines from 0.1 mm slats).",
    }
}

fn tiny_emitter() -> StressScene {
    let mut s = SceneDef::new(
        "tiny-emitter",
        "Tiny emitter near a wall",
        BufferStorage::External,
    );
    s.about = "A closed 3 m × 2.5 m × 3 m room (six faces, facing inwards) lit only by a \
1 cm × 1 cm `light` 2 mm from the `left_wall` (x = 0.002, centred at y = 1.5, z = 1.5), facing \
the wall: a hot spot a few millimetres wide on the wall, and the rest of the room lit by what \
the wall reflects."
        .to_owned();
    let white = grey(&mut s, "white", 0.7, "matte white walls, floor and ceiling");
    let light = black_light(&mut s, 1e4, "white L_e = 10⁴ (3.14 W from 1 cm²); black");
    closed_room(&mut s, white, DVec3::new(3.0, 2.5, 3.0));
    // Faces −x: (u, v) = (z, y) gives z × y = −x.
    s.add_surface(
        "light",
        light,
        grid(
            DVec3::new(0.002, 1.495, 1.495),
            DVec3::Z * 0.01,
            DVec3::Y * 0.01,
            1,
            1,
        ),
    );
    camera(
        &mut s,
        DVec3::new(2.8, 1.6, 2.8),
        DVec3::new(0.0, 1.4, 1.2),
        60.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "a small emitter very close to a large receiver: the wall's irradiance \
varies from E/2 under the light to almost nothing a few centimetres away, and form factors \
from the wall's elements to the light are singular in the light's near field.",
        struggles: "point-polygon form factors and the hemicube at coarse wall elements (one \
centroid either sees the light at 2 mm, or the light falls between samples), area sampling \
(high variance), uniform meshes (the hot spot is far smaller than an element), and the \
hierarchical solver's relative thresholds (the light is 1e-5 of the scene's area).",
    }
}

fn scale_range() -> StressScene {
    let mut s = SceneDef::new(
        "scale-range",
        "Millimetres to kilometres",
        BufferStorage::External,
    );
    s.about = "A 2 km × 2 km `ground` (y = 0, facing up) lit by a 200 m × 200 m `sky_panel` \
500 m up (facing down). On the ground, cubes of 10 m (`house`), 1 m (`crate`), 1 cm (`die`) \
and 1 mm (`grain`) without bottom faces, near the origin: six orders of magnitude of length \
in one scene."
        .to_owned();
    let ground = grey(&mut s, "ground", 0.3, "dark grey ground");
    let white = grey(&mut s, "white", 0.7, "matte white cubes");
    let light = black_light(&mut s, 1.0, "white L_e = 1; black");
    s.add_surface(
        "ground",
        ground,
        rect_up(-1000.0, 1000.0, -1000.0, 1000.0, 0.0),
    );
    for (name, x0, size) in [
        ("house", 20.0, 10.0),
        ("crate", 2.0, 1.0),
        ("die", 0.5, 0.01),
        ("grain", 0.1, 0.001),
    ] {
        s.add_surface(
            name,
            white,
            cuboid(
                DVec3::new(x0, 0.0, 0.0),
                DVec3::new(x0 + size, size, size),
                &[Side::NegY],
            ),
        );
    }
    s.add_surface(
        "sky_panel",
        light,
        rect_down(-100.0, 100.0, -100.0, 100.0, 500.0),
    );
    camera(
        &mut s,
        DVec3::new(-2.0, 1.5, 5.0),
        DVec3::new(2.0, 0.3, 0.0),
        50.0,
        0.001,
    );
    StressScene {
        scene: s,
        stresses: "a scale range of 10⁶: every tolerance set relative to the scene size (ray \
offsets, minimum element area, degenerate-triangle height, element size) is either far too \
coarse for the millimetre cube or far too fine for the ground.",
        struggles: "every method with tolerances relative to the scene diagonal: ray offsets of \
1e-6 × 2.8 km = 3 mm swallow the grain, the minimum element area stops refinement long \
before the die is resolved, and a uniform mesh sized to the scene (about 110 m elements) \
gives each small cube one element per face. The hemicube's near plane is far larger than the \
grain.",
    }
}

/// Reflectance of every surface of the furnace.
pub const FURNACE_RHO: f64 = 0.99;

fn furnace_099() -> StressScene {
    let mut s = SceneDef::new(
        "furnace-099",
        "Furnace at ρ = 0.99",
        BufferStorage::External,
    );
    s.about = "A closed 1 m cube (faces inwards), every surface of reflectance ρ = 0.99, lit \
by one 0.2 m × 0.2 m `light` in the middle of the ceiling (the ceiling is cut around it into \
eight quads, so nothing overlaps). It emits E = 1 W/m²; since nothing escapes, all of Φ = \
0.04 W is eventually absorbed, after about 1 / (1 − ρ) = 100 bounces."
        .to_owned();
    let white = s.add_material(Material {
        name: "white",
        reflectance: [FURNACE_RHO; 3],
        emission: None,
        note: "ρ = 0.99 everywhere",
    });
    let light = s.add_material(Material {
        name: "light",
        reflectance: [FURNACE_RHO; 3],
        emission: Some(Emission {
            factor: [1.0 / PI; 3],
            strength: None,
        }),
        note: "L_e = 1/π, E = 1 W/m²; it reflects like the walls",
    });
    let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
    for (name, side) in [
        ("floor", Side::NegY),
        ("left_wall", Side::NegX),
        ("right_wall", Side::PosX),
        ("back_wall", Side::NegZ),
        ("front_wall", Side::PosZ),
    ] {
        s.add_surface(name, white, inner_face(lo, hi, side));
    }
    let cuts = [0.0, 0.4, 0.6, 1.0];
    let mut ceiling = Vec::new();
    for i in 0..3 {
        for k in 0..3 {
            if (i, k) != (1, 1) {
                ceiling.extend(rect_down(cuts[i], cuts[i + 1], cuts[k], cuts[k + 1], 1.0));
            }
        }
    }
    s.add_surface("ceiling", white, ceiling);
    s.add_surface("light", light, rect_down(0.4, 0.6, 0.4, 0.6, 1.0));
    camera(
        &mut s,
        DVec3::new(0.5, 0.5, 0.95),
        DVec3::new(0.5, 0.45, 0.0),
        70.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "reflectance near 1 in a closed scene: the spectral radius of ρF is 0.99, so \
iterative solvers need hundreds of sweeps, and any form-factor row summing above 1 makes \
the system create energy.",
        struggles: "Jacobi (error falls by only 1 % per sweep: about 1 400 sweeps for 1e-6), \
Gauss-Seidel and shooting less so; the hierarchical solver's gathering iterations; and every \
kernel whose rows over-sum (sampling, the hemicube), where the absorbed power then exceeds \
the emitted.",
    }
}

fn facing_away() -> StressScene {
    let mut s = SceneDef::new(
        "facing-away",
        "Emitters facing away from everything",
        BufferStorage::External,
    );
    s.about = "A 2 m × 2 m `floor` (y = 0, facing up) with a 0.5 m `block` on it (no bottom \
face) and two 0.4 m × 0.4 m emitters 1 m up, `light_left` and `light_right`, facing up \
(+y), away from everything: all emitted power escapes to the sky, and every receiver's \
radiosity is exactly zero."
        .to_owned();
    let white = grey(&mut s, "white", 0.7, "matte white floor and block");
    let light = s.add_material(Material {
        name: "light",
        reflectance: [0.5; 3],
        emission: Some(Emission::with_strength([10.0; 3])),
        note: "white L_e = 10; mid grey, though nothing reaches it",
    });
    s.add_surface("floor", white, rect_up(-1.0, 1.0, -1.0, 1.0, 0.0));
    s.add_surface(
        "block",
        white,
        cuboid(
            DVec3::new(-0.25, 0.0, -0.25),
            DVec3::new(0.25, 0.5, 0.25),
            &[Side::NegY],
        ),
    );
    s.add_surface("light_left", light, rect_up(-0.9, -0.5, -0.2, 0.2, 1.0));
    s.add_surface("light_right", light, rect_up(0.5, 0.9, -0.2, 0.2, 1.0));
    camera(
        &mut s,
        DVec3::new(0.0, 1.8, 2.5),
        DVec3::new(0.0, 0.4, 0.0),
        50.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "zero received light: every form factor from an emitter is zero, so any \
quantity normalised by received light, by the largest non-emitter radiosity or by a \
gradient is 0/0.",
        struggles: "no method should struggle; this checks that normalisations, convergence \
tests, refinement oracles and the display exposure survive a scene whose receivers are all \
black (no NaN, no division by zero, convergence reported immediately).",
    }
}

fn open_floor() -> StressScene {
    let mut s = SceneDef::new("open-floor", "Open scene", BufferStorage::External);
    s.about = "A 4 m × 4 m `floor` (y = 0, facing up) under a 1 m × 1 m `light` at y = 2 \
(facing down), and nothing else: no walls, so most light escapes after one bounce. The \
floor's radiosity is purely direct, B(x) = ρ E F(x → light), a closed form at every point."
        .to_owned();
    let white = grey(&mut s, "white", 0.7, "matte white floor");
    let light = black_light(&mut s, 10.0, "white L_e = 10; black");
    s.add_surface("floor", white, rect_up(-2.0, 2.0, -2.0, 2.0, 0.0));
    s.add_surface("light", light, rect_down(-0.5, 0.5, -0.5, 0.5, 2.0));
    camera(
        &mut s,
        DVec3::new(0.0, 2.5, 4.0),
        DVec3::new(0.0, 0.0, 0.0),
        55.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "an open scene: form-factor rows sum far below 1, most power escapes, and \
the floor's irradiance falls off smoothly to its rim, so enclosure identities do not hold.",
        struggles: "mostly a control; methods that assume closure (ambient terms, row-sum \
normalisation) over-light the floor. The absorbed power is only a fraction of the emitted.",
    }
}

/// Emitting triangles of the many-emitters scene, per side of their grid.
pub const EMITTER_GRID: usize = 48;

fn many_emitters() -> StressScene {
    let mut s = SceneDef::new(
        "many-emitters",
        "Thousands of tiny emitters",
        BufferStorage::External,
    );
    s.about = format!(
        "A closed 3 m × 2.5 m × 3 m room (six faces, facing inwards) whose light is {} tiny \
emitting triangles (`leds`, legs of 3 cm, one per 5 cm cell of a {n} × {n} grid over x, z \
∈ [0.3, 2.7]) hanging 1 cm below the ceiling and facing down. No two of them share an edge, \
so each is its own patch.",
        EMITTER_GRID * EMITTER_GRID,
        n = EMITTER_GRID
    );
    let white = grey(&mut s, "white", 0.7, "matte white walls, floor and ceiling");
    let light = black_light(&mut s, 2.0, "white L_e = 2; black");
    closed_room(&mut s, white, DVec3::new(3.0, 2.5, 3.0));
    let mut leds = Vec::with_capacity(EMITTER_GRID * EMITTER_GRID);
    for i in 0..EMITTER_GRID {
        for k in 0..EMITTER_GRID {
            let (x, z) = (0.3 + 0.05 * i as f64, 0.3 + 0.05 * k as f64);
            let o = DVec3::new(x + 0.01, 2.49, z + 0.01);
            leds.push(facing(
                o,
                o + DVec3::X * 0.03,
                o + DVec3::Z * 0.03,
                DVec3::NEG_Y,
            ));
        }
    }
    s.add_surface("leds", light, leds);
    camera(
        &mut s,
        DVec3::new(1.5, 1.0, 2.9),
        DVec3::new(1.5, 1.6, 0.0),
        65.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "thousands of emitter patches: the initial linking is quadratic in the \
number of patches, and each emitter is a separate small source for shadows and \
discontinuities.",
        struggles: "the hierarchical solver's initial patch-to-patch linking (millions of \
pairs before any refinement) and discontinuity meshing (thousands of light sources, each \
casting its own shadow lines); the classic methods are not hurt beyond their matrix size.",
    }
}

/// Side of the shared-edge squares (m).
pub const SHARED_EDGE_SIDE: f64 = 1.0;

fn shared_edge() -> StressScene {
    let mut s = SceneDef::new(
        "shared-edge",
        "One emitter, one receiver, sharing an edge",
        BufferStorage::External,
    );
    s.about = "Two 1 m × 1 m squares at right angles sharing the edge x ∈ [0, 1] along the \
x axis: the `emitter` (y = 0, z ∈ [0, 1], facing +y) emits E = 1 W/m² and reflects nothing; \
the `receiver` (z = 0, y ∈ [0, 1], facing +z) reflects ρ = 0.5. The form factor between \
them is F = 0.200044 (perpendicular rectangles with a common edge, Howell C-14), so the \
receiver's mean irradiance is H = F · E = 0.200044 W/m² and its mean radiosity \
B = ρ H = 0.100022 W/m²; nothing else is in the scene."
        .to_owned();
    let emitter = s.add_material(Material {
        name: "emitter",
        reflectance: [0.0; 3],
        emission: Some(Emission {
            factor: [1.0 / PI; 3],
            strength: None,
        }),
        note: "L_e = 1/π, E = 1 W/m²; black, so it reflects nothing",
    });
    let grey_m = grey(&mut s, "grey", 0.5, "mid grey");
    let a = SHARED_EDGE_SIDE;
    s.add_surface("emitter", emitter, rect_up(0.0, a, 0.0, a, 0.0));
    // Faces +z: x × y = +z.
    s.add_surface(
        "receiver",
        grey_m,
        grid(DVec3::ZERO, DVec3::X * a, DVec3::Y * a, 1, 1),
    );
    camera(
        &mut s,
        DVec3::new(1.6, 1.2, 1.8),
        DVec3::new(0.4, 0.3, 0.3),
        55.0,
        0.01,
    );
    StressScene {
        scene: s,
        stresses: "a singular kernel: a single emitter–receiver pair with a closed-form \
answer, whose kernel is singular along the shared edge (the point-to-area form factor tends to 1/2 there, and its \
integrand to infinity).",
        struggles: "point-polygon form factors and the hemicube on elements along the edge \
(centroid estimates miss the singular corner), and area sampling (infinite variance near the \
edge); adaptive polygon-polygon quadrature and the hierarchical solver's subdivision handle \
it.",
    }
}
