//! `three-rooms`: a three-room interior lit by one ceiling panel, for scenes
//! where most light arrives indirectly.
//!
//! Plan (y up, metres; walls 0.1 m thick, ceiling 2.6 m, doors 1 × 2.1 m):
//!
//! ```text
//!  z=7.1          ┌──────────────┐
//!                 │    room C    │   no straight path from the light
//!  z=4.1 ┌────────┴───┐    ┌─────┤   reaches room C (see below)
//!        │            │door│     │
//!  z=4.0 │  room A    ├ BC ┘     │
//!        │   [light]  │  room B  │
//!        │            door AB    │
//!  z=0   └────────────┴──────────┘
//!       x=0          5.0 5.1     9.1
//! ```
//!
//! Door AB spans z ∈ [0.5, 1.5] in the wall x ∈ [5.0, 5.1]; door BC spans
//! x ∈ [7.6, 8.6] in the wall z ∈ [4.0, 4.1]; the light covers
//! x, z ∈ [2, 3] on room A's ceiling. Every straight path from the light
//! into room B crosses door AB and so travels towards −z (the light lies at
//! z ≥ 2 > 1.5), and can never reach door BC at z = 4: room C is lit only
//! by interreflection.
//!
//! The room shells come from a [`Lattice`] (0.5 m × 0.35 m wall grid), so
//! walls, floors, ceilings and door reveals share vertices along every
//! edge. Furniture rests on the floor without bottom faces, and faces that
//! touch another part of the same piece are left out, so that no two faces
//! overlap.

use std::f64::consts::PI;

use glam::{DQuat, DVec3};

use super::lattice::{Lattice, lines};
use super::model::{BufferStorage, Camera, Emission, Material, Node, SceneDef};
use super::shapes::{Side, Tri, cuboid, cuboid_grid, cylinder, sphere};

const REGIONS: [&str; 5] = ["room_a", "room_b", "room_c", "doorway_ab", "doorway_bc"];
const HEIGHT: f64 = 2.6;
const DOOR_HEIGHT: f64 = 2.1;
/// The light panel on room A's ceiling, as (x, z) bounds.
const LIGHT_MIN: [f64; 2] = [2.0, 2.0];
const LIGHT_MAX: [f64; 2] = [3.0, 3.0];

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

fn lattice() -> Lattice {
    let xs = [lines(0.0, 5.0, 0.5), lines(5.1, 9.1, 0.5)].concat();
    let ys = [
        lines(0.0, DOOR_HEIGHT, 0.35),
        lines(DOOR_HEIGHT, HEIGHT, 0.25)[1..].to_vec(),
    ]
    .concat();
    let zs = [lines(0.0, 4.0, 0.5), lines(4.1, 7.1, 0.5)].concat();
    let mut l = Lattice::new(xs, ys, zs);
    l.open(v(0.0, 0.0, 0.0), v(5.0, HEIGHT, 4.0), 0);
    l.open(v(5.1, 0.0, 0.0), v(9.1, HEIGHT, 4.0), 1);
    l.open(v(5.1, 0.0, 4.1), v(9.1, HEIGHT, 7.1), 2);
    l.open(v(5.0, 0.0, 0.5), v(5.1, DOOR_HEIGHT, 1.5), 3);
    l.open(v(7.6, 0.0, 4.0), v(8.6, DOOR_HEIGHT, 4.1), 4);
    l
}

/// Names of the room-shell surfaces, in output order.
const SHELL_NAMES: [&str; 12] = [
    "room_a_floor",
    "room_a_ceiling",
    "light",
    "room_a_walls",
    "doorway_ab",
    "room_b_floor",
    "room_b_ceiling",
    "room_b_walls",
    "doorway_bc",
    "room_c_floor",
    "room_c_ceiling",
    "room_c_walls",
];

/// Room shells grouped into named surfaces, in [`SHELL_NAMES`] order.
fn shells() -> Vec<(String, Vec<Tri>)> {
    let mut groups: Vec<(String, Vec<Tri>)> = Vec::new();
    let mut push = |name: String, tris: [Tri; 2]| match groups.iter_mut().find(|g| g.0 == name) {
        Some(g) => g.1.extend(tris),
        None => groups.push((name, tris.to_vec())),
    };
    for face in lattice().boundary() {
        let room = REGIONS[face.region];
        let name = if room.starts_with("doorway") {
            room.to_owned()
        } else {
            match face.facing {
                Side::PosY => format!("{room}_floor"),
                Side::NegY => {
                    let c = (face.cell_min + face.cell_max) * 0.5;
                    let in_light = face.region == 0
                        && (LIGHT_MIN[0]..LIGHT_MAX[0]).contains(&c.x)
                        && (LIGHT_MIN[1]..LIGHT_MAX[1]).contains(&c.z);
                    if in_light {
                        "light".to_owned()
                    } else {
                        format!("{room}_ceiling")
                    }
                }
                _ => format!("{room}_walls"),
            }
        };
        push(name, face.triangles);
    }
    groups.sort_by_key(|g| SHELL_NAMES.iter().position(|&n| n == g.0));
    groups
}

/// A 1.4 m × 0.8 m table centred on the origin, its top 0.76 m high, on
/// four round legs of `leg_segments` sides.
pub fn table(leg_segments: usize) -> Vec<Tri> {
    let mut t = cuboid(v(-0.7, 0.72, -0.4), v(0.7, 0.76, 0.4), &[]);
    for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        t.extend(cylinder(
            v(0.62 * sx, 0.0, 0.32 * sz),
            0.03,
            0.72,
            leg_segments,
            1,
            false,
            false,
        ));
    }
    t
}

/// A chair centred on the origin, its back on the +z side.
pub fn chair() -> Vec<Tri> {
    let mut t = cuboid(v(-0.22, 0.42, -0.22), v(0.22, 0.46, 0.22), &[]);
    for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let c = v(0.19 * sx, 0.0, 0.19 * sz);
        t.extend(cuboid(
            c + v(-0.02, 0.0, -0.02),
            c + v(0.02, 0.42, 0.02),
            &[Side::NegY, Side::PosY],
        ));
    }
    t.extend(cuboid(
        v(-0.22, 0.46, 0.18),
        v(0.22, 0.95, 0.22),
        &[Side::NegY],
    ));
    t
}

/// Side panels and boards of a 1 m × 1.8 m × 0.3 m open bookshelf.
pub fn bookshelf() -> Vec<Tri> {
    let mut t = cuboid(v(0.0, 0.0, 0.0), v(0.02, 1.8, 0.3), &[Side::NegY]);
    t.extend(cuboid(v(0.98, 0.0, 0.0), v(1.0, 1.8, 0.3), &[Side::NegY]));
    for (i, y) in SHELF_LEVELS.iter().enumerate() {
        let mut omit = vec![Side::NegX, Side::PosX];
        if i == 0 {
            omit.push(Side::NegY);
        }
        t.extend(cuboid(v(0.02, *y, 0.0), v(0.98, y + 0.02, 0.3), &omit));
    }
    t
}

const SHELF_LEVELS: [f64; 5] = [0.0, 0.45, 0.9, 1.35, 1.78];

/// Books standing on the three lower boards, 1 cm apart, sizes from a
/// fixed table.
pub fn books() -> Vec<Tri> {
    const SIZES: [(f64, f64); 6] = [
        (0.05, 0.28),
        (0.04, 0.24),
        (0.06, 0.3),
        (0.035, 0.22),
        (0.05, 0.26),
        (0.045, 0.31),
    ];
    let mut t = Vec::new();
    for (shelf, y) in SHELF_LEVELS[..3].iter().enumerate() {
        let mut x = 0.06 + 0.1 * shelf as f64;
        for k in 0..(4 + shelf) {
            let (w, h) = SIZES[(k + 2 * shelf) % SIZES.len()];
            let base = y + 0.02;
            t.extend(cuboid(
                v(x, base, 0.06),
                v(x + w, base + h, 0.26),
                &[Side::NegY],
            ));
            x += w + 0.01;
        }
    }
    t
}

fn sofa() -> Vec<Tri> {
    let mut t = cuboid_grid(
        v(0.0, 0.0, 0.0),
        v(1.8, 0.42, 0.65),
        2,
        &[Side::NegY, Side::PosZ],
    );
    t.extend(cuboid_grid(
        v(0.0, 0.0, 0.65),
        v(1.8, 0.85, 0.8),
        2,
        &[Side::NegY],
    ));
    t
}

pub fn scene() -> SceneDef {
    let mut s = SceneDef::new(
        "three-rooms",
        "Three furnished rooms",
        BufferStorage::External,
    );
    s.about = "A furnished interior of three rooms joined by doorways, for light that \
arrives mostly indirectly. Room A (5 m × 4 m) has the only light, a 1 m × 1 m ceiling panel; \
room B (4 m × 4 m) opens off it through door AB and receives a little direct light through \
that door; room C (4 m × 3 m) opens off room B through door BC and receives no direct light \
at all (every straight path from the light through door AB heads away from door BC), only \
interreflected light. Walls, floors and ceilings are a conforming grid of 0.5 m × 0.35 m \
quads that share vertices along every edge, including the door reveals; the furniture \
(a table with a ball on it, two chairs that are instances of one mesh, a bookshelf with \
books, tessellated columns, boxes, spheres, a sofa, a stool) rests on the floor without \
bottom faces, so that no faces overlap. Node hierarchy and transforms are exercised: the \
ball is a child of the table, the chairs are one mesh placed by two rotated nodes, and room \
C's furniture hangs under a translated group node. The camera stands in room A and looks \
through door AB into room B.

Plan (seen from above; walls 0.1 m thick, ceilings 2.6 m, doors 1 m × 2.1 m; the light \
covers x, z ∈ [2, 3] on room A's ceiling):

```text
 z=7.1          ┌──────────────┐
                │    room C    │
 z=4.1 ┌────────┴───┐    ┌─────┤
       │            │door│     │   door BC: x ∈ [7.6, 8.6]
 z=4.0 │  room A    ├ BC ┘     │
       │   [light]  │  room B  │
       │            door AB    │   door AB: z ∈ [0.5, 1.5]
 z=0   └────────────┴──────────┘
      x=0          5.0 5.1     9.1
```"
    .to_owned();

    let paint_a = s.add_diffuse("paint_white", [0.78, 0.76, 0.72], "warm white wall paint");
    let paint_b = s.add_diffuse("paint_sage", [0.55, 0.62, 0.5], "sage green wall paint");
    let paint_c = s.add_diffuse("paint_blue", [0.55, 0.6, 0.7], "pale blue wall paint");
    let ceiling = s.add_diffuse("ceiling_white", [0.8, 0.8, 0.8], "white ceiling paint");
    let oak = s.add_diffuse("oak_floor", [0.5, 0.35, 0.22], "light oak boards");
    let carpet = s.add_diffuse("carpet", [0.35, 0.33, 0.3], "grey-beige carpet");
    let trim = s.add_diffuse("door_trim", [0.7, 0.7, 0.68], "off-white door reveals");
    let walnut = s.add_diffuse("walnut", [0.4, 0.25, 0.15], "dark wood (table, stool)");
    let fabric = s.add_diffuse("blue_fabric", [0.15, 0.3, 0.6], "chair upholstery");
    let pine = s.add_diffuse("pine", [0.6, 0.46, 0.32], "light wood (bookshelf)");
    let cloth = s.add_diffuse("book_cloth", [0.55, 0.15, 0.12], "red book covers");
    let concrete = s.add_diffuse("concrete", [0.55, 0.55, 0.52], "columns");
    let orange = s.add_diffuse("orange", [0.75, 0.3, 0.08], "ball on the table");
    let yellow = s.add_diffuse("yellow", [0.7, 0.6, 0.15], "sphere in room B");
    let teal = s.add_diffuse("teal", [0.15, 0.5, 0.55], "sphere in room C");
    let cardboard = s.add_diffuse("cardboard", [0.55, 0.42, 0.28], "boxes");
    let lacquer = s.add_diffuse("white_lacquer", [0.7, 0.7, 0.68], "cabinet");
    let velvet = s.add_diffuse("red_velvet", [0.5, 0.12, 0.12], "sofa");
    let light = s.add_material(Material {
        name: "light",
        reflectance: [0.8, 0.8, 0.8],
        emission: Some(Emission::with_strength(LIGHT_RADIANCE)),
        note: "warm white ceiling panel; its reflectance is the ceiling's",
    });

    for (name, tris) in shells() {
        let material = match name.as_str() {
            "light" => light,
            "room_a_floor" => oak,
            "room_b_floor" | "room_c_floor" => carpet,
            "room_a_walls" => paint_a,
            "room_b_walls" => paint_b,
            "room_c_walls" => paint_c,
            n if n.ends_with("_ceiling") => ceiling,
            _ => trim,
        };
        s.add_surface(&name, material, tris);
    }

    // Room A: furniture under one group node (identity transform).
    let table_mesh = s.add_mesh("table", walnut, table(12));
    let ball_mesh = s.add_mesh("ball", orange, sphere(v(0.0, 0.12, 0.0), 0.12, 24, 16));
    let chair_mesh = s.add_mesh("chair", fabric, chair());
    let shelf_mesh = s.add_mesh("bookshelf", pine, bookshelf());
    let books_mesh = s.add_mesh("books", cloth, books());
    let column_a_mesh = s.add_mesh(
        "column_a",
        concrete,
        cylinder(v(4.0, 0.0, 3.2), 0.15, HEIGHT, 24, 6, false, false),
    );
    let ball = s.add_node(Node {
        name: "ball".to_owned(),
        mesh: Some(ball_mesh),
        translation: Some(v(0.3, 0.76, 0.1)),
        ..Node::default()
    });
    let table = s.add_node(Node {
        name: "table".to_owned(),
        mesh: Some(table_mesh),
        translation: Some(v(2.5, 0.0, 2.3)),
        children: vec![ball],
        ..Node::default()
    });
    let chair_1 = s.add_node(Node {
        name: "chair_1".to_owned(),
        mesh: Some(chair_mesh),
        translation: Some(v(2.3, 0.0, 1.55)),
        rotation: Some(DQuat::from_rotation_y(PI)),
        ..Node::default()
    });
    let chair_2 = s.add_node(Node {
        name: "chair_2".to_owned(),
        mesh: Some(chair_mesh),
        translation: Some(v(2.7, 0.0, 3.05)),
        ..Node::default()
    });
    let books = s.add_node(Node {
        name: "books".to_owned(),
        mesh: Some(books_mesh),
        ..Node::default()
    });
    let shelf = s.add_node(Node {
        name: "bookshelf".to_owned(),
        mesh: Some(shelf_mesh),
        translation: Some(v(0.4, 0.0, 0.05)),
        children: vec![books],
        ..Node::default()
    });
    let column_a = s.add_node(Node {
        name: "column_a".to_owned(),
        mesh: Some(column_a_mesh),
        ..Node::default()
    });
    let group_a = s.add_node(Node {
        name: "room_a_furniture".to_owned(),
        children: vec![table, chair_1, chair_2, shelf, column_a],
        ..Node::default()
    });
    s.roots.push(group_a);

    // Room B: world-space meshes as root nodes.
    let mut boxes = cuboid_grid(v(7.5, 0.0, 0.3), v(8.3, 0.6, 1.1), 4, &[Side::NegY]);
    boxes.extend(cuboid_grid(
        v(7.7, 0.6, 0.5),
        v(8.1, 0.9, 0.9),
        2,
        &[Side::NegY],
    ));
    s.add_surface("boxes", cardboard, boxes);
    s.add_surface(
        "cabinet",
        lacquer,
        cuboid_grid(v(8.6, 0.0, 1.6), v(9.0, 0.9, 3.0), 3, &[Side::NegY]),
    );
    s.add_surface("sphere_b", yellow, sphere(v(6.4, 0.3, 2.6), 0.3, 32, 16));
    s.add_surface(
        "column_b",
        concrete,
        cylinder(v(7.0, 0.0, 3.0), 0.2, HEIGHT, 24, 8, false, false),
    );

    // Room C: meshes in the room's own frame under a translated group node.
    let origin_c = v(5.1, 0.0, 4.1);
    let sofa_mesh = s.add_mesh("sofa", velvet, sofa());
    let stool_mesh = s.add_mesh(
        "stool",
        walnut,
        cylinder(v(3.2, 0.0, 1.9), 0.2, 0.45, 20, 2, false, true),
    );
    let sphere_c_mesh = s.add_mesh("sphere_c", teal, sphere(v(1.3, 0.2, 0.9), 0.2, 16, 12));
    let crate_mesh = s.add_mesh(
        "crate",
        cardboard,
        cuboid_grid(v(3.1, 0.0, 0.7), v(3.7, 0.5, 1.3), 2, &[Side::NegY]),
    );
    let children_c = [
        ("sofa", sofa_mesh, v(0.4, 0.0, 2.15)),
        ("stool", stool_mesh, DVec3::ZERO),
        ("sphere_c", sphere_c_mesh, DVec3::ZERO),
        ("crate", crate_mesh, DVec3::ZERO),
    ]
    .into_iter()
    .map(|(name, mesh, t)| {
        s.add_node(Node {
            name: name.to_owned(),
            mesh: Some(mesh),
            translation: (t != DVec3::ZERO).then_some(t),
            ..Node::default()
        })
    })
    .collect();
    let group_c = s.add_node(Node {
        name: "room_c_furniture".to_owned(),
        translation: Some(origin_c),
        children: children_c,
        ..Node::default()
    });
    s.roots.push(group_c);

    s.add_camera(
        "camera",
        v(0.5, 1.5, 1.9),
        v(8.0, 0.7, 0.6),
        DVec3::Y,
        Camera {
            yfov: 60f64.to_radians(),
            aspect_ratio: 16.0 / 9.0,
            znear: 0.05,
        },
    );
    s
}

/// Emitted radiance of the ceiling panel, W·m⁻²·sr⁻¹ per RGB channel.
pub const LIGHT_RADIANCE: [f64; 3] = [10.0, 9.2, 8.0];
