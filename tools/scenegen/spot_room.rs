//! `spot-room`: a closed, furnished room lit only by two punctual lights
//! (`KHR_lights_punctual`): a point light hanging over the table and a
//! warm spot light high on the right wall, aimed at the floor beside the
//! table. No material emits.
//!
//! Plan (y up, metres; ceiling 2.8 m; the camera stands at the front wall,
//! z = 4, looking towards −z, so +x is to its right):
//!
//! ```text
//!  z=0  ┌──────── back wall (blue) ────────┐
//!       │                     [box_b]      │
//!       │                     [box_a]      │
//!  left │        ┌─table──┐                │ right
//!  wall │        │   ●    │ ○              │ wall: spot at (4.85, 2.45, 2.8)
//!       │        └────────┘           spot◄│
//!       │  [box_c]                         │
//!  z=4  └──────────── front wall ──────────┘
//!      x=0                                x=5
//! ```
//!
//! Invariants: the shell comes from a one-region [`Lattice`], so it is
//! closed and its faces share vertices along every edge, all facing into
//! the room; the furniture rests on the floor without bottom faces, and
//! faces that touch another part of the same piece are left out.

use glam::DVec3;

use super::lattice::{Lattice, lines};
use super::model::{BufferStorage, Camera, Light, LightKind, Node, SceneDef};
use super::shapes::{Side, Tri, cuboid};

const WIDTH: f64 = 5.0;
const HEIGHT: f64 = 2.8;
const DEPTH: f64 = 4.0;

/// Where the table's node puts its centre on the floor.
const TABLE_AT: DVec3 = DVec3::new(2.0, 0.0, 1.8);

/// The point of the floor on the spot light's axis.
const SPOT_AIM: DVec3 = DVec3::new(3.0, 0.0, 1.3);

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// Names of the shell's surfaces, by the direction they face, in output
/// order.
const SHELL: [(&str, Side); 6] = [
    ("floor", Side::PosY),
    ("ceiling", Side::NegY),
    ("back_wall", Side::PosZ),
    ("front_wall", Side::NegZ),
    ("left_wall", Side::PosX),
    ("right_wall", Side::NegX),
];

/// The room's six surfaces, in [`SHELL`] order, on a grid of about
/// 1 m × 0.7 m.
fn shell() -> Vec<(&'static str, Vec<Tri>)> {
    let mut l = Lattice::new(
        lines(0.0, WIDTH, 1.0),
        lines(0.0, HEIGHT, 0.7),
        lines(0.0, DEPTH, 1.0),
    );
    l.open(DVec3::ZERO, v(WIDTH, HEIGHT, DEPTH), 0);
    let faces = l.boundary();
    SHELL
        .iter()
        .map(|&(name, side)| {
            let tris = faces
                .iter()
                .filter(|f| f.facing == side)
                .flat_map(|f| f.triangles)
                .collect();
            (name, tris)
        })
        .collect()
}

/// A 1.4 m × 0.8 m table centred on the origin: a 4 cm top 0.76 m high on
/// four 5 cm square legs, the legs without top or bottom faces.
fn table() -> Vec<Tri> {
    let mut t = cuboid(v(-0.7, 0.72, -0.4), v(0.7, 0.76, 0.4), &[]);
    for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let c = v(0.6 * sx, 0.0, 0.3 * sz);
        t.extend(cuboid(
            c + v(-0.025, 0.0, -0.025),
            c + v(0.025, 0.72, 0.025),
            &[Side::NegY, Side::PosY],
        ));
    }
    t
}

pub fn scene() -> SceneDef {
    let mut s = SceneDef::new(
        "spot-room",
        "Room under a spot and a point light",
        BufferStorage::External,
    );
    s.about = "A closed 5 m × 2.8 m × 4 m room lit only by two `KHR_lights_punctual` lights, \
for the solver's punctual-light path: no material emits. A point light hangs 0.6 m below the \
ceiling over a table (top and four square legs), which shades the floor beneath it; a warm \
spot light high on the right wall is aimed at the floor just past the table's right end, so \
that the table and the two stacked boxes further back cast shadows inside its pool (the grey \
crate by the left wall lies outside its outer cone). The walls are white except the \
blue back wall and the terracotta left wall, both in the camera's view, which bleed their \
colour onto the floor and the furniture. The shell is a conforming grid of about \
1 m × 0.7 m quads, closed and facing inwards; the table is one mesh placed by a translated \
node; the boxes rest on the floor (one on another) without bottom faces. The camera stands \
at the front wall and sees the table and both pools of light (the lights themselves are \
points and invisible).

Plan (seen from above; the camera looks from z = 4 towards −z):

```text
 z=0  ┌──────── back wall (blue) ────────┐
      │                     [box_b]      │
      │                     [box_a]      │
 left │        ┌─table──┐                │ right
 wall │        │   ●    │ ○              │ wall
      │        └────────┘           spot◄│
      │  [box_c]                         │
 z=4  └──────────── front wall ──────────┘
     x=0                                x=5
```

● the point light, 2.2 m up over the table's centre; ◄ the spot light, 2.45 m up and \
0.15 m off the right wall; ○ where the spot's axis meets the floor."
        .to_owned();

    let white = s.add_diffuse(
        "paint_white",
        [0.72, 0.7, 0.67],
        "warm white wall paint (front and right walls)",
    );
    let blue = s.add_diffuse(
        "paint_blue",
        [0.38, 0.48, 0.62],
        "muted blue wall paint (back wall)",
    );
    let terracotta = s.add_diffuse(
        "paint_terracotta",
        [0.66, 0.34, 0.24],
        "terracotta wall paint (left wall)",
    );
    let ceiling = s.add_diffuse("ceiling_white", [0.78, 0.78, 0.76], "white ceiling paint");
    let oak = s.add_diffuse("oak_floor", [0.5, 0.36, 0.24], "light oak boards");
    let walnut = s.add_diffuse("walnut", [0.4, 0.25, 0.15], "dark wood (table)");
    let cardboard = s.add_diffuse("cardboard", [0.55, 0.42, 0.28], "boxes");
    let grey = s.add_diffuse("grey_crate", [0.45, 0.45, 0.45], "grey crate");

    for (name, tris) in shell() {
        let material = match name {
            "floor" => oak,
            "ceiling" => ceiling,
            "back_wall" => blue,
            "left_wall" => terracotta,
            _ => white,
        };
        s.add_surface(name, material, tris);
    }

    let table_mesh = s.add_mesh("table", walnut, table());
    let table = s.add_node(Node {
        name: "table".to_owned(),
        mesh: Some(table_mesh),
        translation: Some(TABLE_AT),
        ..Node::default()
    });
    s.roots.push(table);
    s.add_surface(
        "box_a",
        cardboard,
        cuboid(v(3.3, 0.0, 0.5), v(3.9, 0.5, 1.1), &[Side::NegY]),
    );
    s.add_surface(
        "box_b",
        cardboard,
        cuboid(v(3.42, 0.5, 0.62), v(3.78, 0.8, 0.98), &[Side::NegY]),
    );
    s.add_surface(
        "box_c",
        grey,
        cuboid(v(0.45, 0.0, 2.7), v(0.95, 0.7, 3.2), &[Side::NegY]),
    );

    // The lamp hangs 0.6 m below the ceiling over the table's centre.
    s.add_light(
        Light {
            name: "ceiling_lamp",
            kind: LightKind::Point,
            color: [1.0, 0.96, 0.9],
            intensity: 20.0,
        },
        TABLE_AT + v(0.0, HEIGHT - 0.6, 0.0),
        DVec3::NEG_Z,
    );
    // High on the right wall, aimed at the floor just past the table's
    // right end (its axis clears the table).
    let spot_at = v(WIDTH - 0.15, 2.45, 2.8);
    s.add_light(
        Light {
            name: "wall_spot",
            kind: LightKind::Spot {
                inner_cone_angle: 0.35,
                outer_cone_angle: 0.6,
            },
            color: [1.0, 0.78, 0.5],
            intensity: 60.0,
        },
        spot_at,
        SPOT_AIM - spot_at,
    );

    s.add_camera(
        "camera",
        v(2.5, 2.0, 3.9),
        v(2.2, 0.5, 1.4),
        DVec3::Y,
        Camera {
            yfov: 60f64.to_radians(),
            aspect_ratio: 16.0 / 9.0,
            znear: 0.05,
        },
    );
    s
}
