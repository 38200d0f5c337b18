//! `office-*`: the scale-up family, one office floor generated at any
//! triangle count (10⁴, 10⁵, 10⁶ and between), for clustering work and
//! benchmarks of how cost grows with scene size.
//!
//! The floor is a grid of `columns × rows` furnished rooms, every pair of
//! neighbouring rooms joined by a 1 m × 2.1 m door in the middle of their
//! shared wall. Column widths cycle through [`WIDTHS`], row depths through
//! [`DEPTHS`]; walls are 0.1 m thick and ceilings 2.6 m high. About a
//! third of the rooms (those with `(i + 2j) mod 3 = 0`, room (0, 0) among them) have
//! a 1 m × 1 m light panel in the middle of the ceiling; the others are lit
//! only through their doors. A [`Plan`] fixes the grid and a detail factor
//! `g` from the target: the wall grid step is 0.5 m / g (0.35 m / g
//! vertically) and furniture segment counts scale with g, while the number
//! of rooms makes up the rest, so the triangle count lands near the target.
//!
//! Invariants, by construction:
//! - The room shells come from one [`Lattice`], so they are closed,
//!   conforming (shared vertices, no T-junctions), axis-aligned and face
//!   into the rooms; light panels are ceiling cells, one-sided, facing down.
//! - Furniture stays inside the rooms, at least 5 cm from the walls (corner
//!   pieces end 1.1 m from their corner, doors start 1.3 m from it; centre
//!   pieces clear of both), rests on the floor or a table without bottom
//!   faces, and no two faces overlap: spheres float 1 mm above what carries
//!   them.
//! - Every piece of furniture is one mesh per scene, placed in each room by
//!   nodes (translation, and a half turn for pieces at the far wall).
//! - Generation is a pure function of the target: no randomness.

use std::f64::consts::PI;

use glam::{DQuat, DVec3};

use super::interior::{LIGHT_RADIANCE, books, bookshelf, chair, table};
use super::lattice::{Lattice, lines};
use super::model::triangle_count;
use super::model::{BufferStorage, Camera, Emission, Material, Node, SceneDef};
use super::shapes::{Side, Tri, cuboid_grid, cylinder, sphere};

/// Column widths (x), cycled. At least 3.6 m, so that corner pieces
/// (within 1.1 m of a corner) stay clear of the centred doors.
pub const WIDTHS: [f64; 3] = [4.0, 5.0, 3.6];
/// Row depths (z), cycled; at least 3.4 m, so that the table clears the
/// corner pieces.
pub const DEPTHS: [f64; 3] = [4.0, 3.4, 4.8];
const WALL: f64 = 0.1;
const HEIGHT: f64 = 2.6;
const DOOR_HEIGHT: f64 = 2.1;
/// Half the width of a door and of a light panel.
const HALF_DOOR: f64 = 0.5;
/// Target whose plan has detail 1.
const BASE_TARGET: f64 = 1e4;

/// The grid and tessellation chosen for a target triangle count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    pub target: usize,
    /// Rooms along x.
    pub columns: usize,
    /// Rooms along z.
    pub rows: usize,
    /// Tessellation factor g: (target / 10⁴)^(1/6), at least 0.5.
    pub detail: f64,
}

impl Plan {
    /// The plan for `target` triangles: the detail from the target, then
    /// as many rooms as make up the target at the mean per-room count of a
    /// 3 × 3 sample floor (one full cycle of widths, depths and kinds),
    /// laid out as a grid of one to two columns per row.
    pub fn for_target(target: usize) -> Plan {
        let detail = (target as f64 / BASE_TARGET).powf(1.0 / 6.0).max(0.5);
        let sample = Plan {
            target,
            columns: 3,
            rows: 3,
            detail,
        };
        let per_room = triangle_count(&build(&sample)) as f64 / 9.0;
        let rooms = (target as f64 / per_room).max(1.0);
        let (columns, rows) = grid_for(rooms);
        Plan {
            target,
            columns,
            rows,
            detail,
        }
    }

    pub fn rooms(&self) -> usize {
        self.columns * self.rows
    }

    /// Rooms with a light panel.
    pub fn lit_rooms(&self) -> usize {
        (0..self.rows)
            .flat_map(|j| (0..self.columns).map(move |i| (i, j)))
            .filter(|&(i, j)| is_lit(i, j))
            .count()
    }

    /// Horizontal spacing of the wall, floor and ceiling grid, metres.
    pub fn wall_step(&self) -> f64 {
        0.5 / self.detail
    }

    /// A segment count `base` at detail 1, scaled (at least 3).
    fn segments(&self, base: usize) -> usize {
        ((base as f64 * self.detail).round() as usize).max(3)
    }

    /// A grid count `base` at detail 1, scaled (at least 1).
    fn cells(&self, base: usize) -> usize {
        ((base as f64 * self.detail).round() as usize).max(1)
    }
}

/// The columns × rows grid closest to `rooms` rooms with columns between
/// rows and twice rows; ties go to the squarer grid.
fn grid_for(rooms: f64) -> (usize, usize) {
    let mut best = (1, 1);
    let mut best_err = f64::INFINITY;
    for rows in (1..=(rooms.sqrt().ceil() as usize + 1)).rev() {
        for columns in rows..=2 * rows {
            let err = ((columns * rows) as f64 - rooms).abs();
            if err < best_err - 1e-9 {
                best = (columns, rows);
                best_err = err;
            }
        }
    }
    best
}

fn is_lit(i: usize, j: usize) -> bool {
    (i + 2 * j).is_multiple_of(3)
}

/// File name stem for a target: `office-10k`, `office-1m`, `office-2500`.
pub fn stem(target: usize) -> String {
    if target >= 1_000_000 && target.is_multiple_of(1_000_000) {
        format!("office-{}m", target / 1_000_000)
    } else if target >= 1000 && target.is_multiple_of(1000) {
        format!("office-{}k", target / 1000)
    } else {
        format!("office-{target}")
    }
}

/// The scene for `target` triangles.
pub fn scene(target: usize) -> SceneDef {
    build(&Plan::for_target(target))
}

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// The open box of room (i, j): its floor corner nearest the origin and
/// its ceiling corner farthest from it.
pub fn room_box(i: usize, j: usize) -> (DVec3, DVec3) {
    let start =
        |n: usize, sizes: &[f64]| (0..n).map(|k| sizes[k % sizes.len()] + WALL).sum::<f64>();
    let min = v(start(i, &WIDTHS), 0.0, start(j, &DEPTHS));
    let size = v(WIDTHS[i % WIDTHS.len()], HEIGHT, DEPTHS[j % DEPTHS.len()]);
    (min, min + size)
}

/// Lattice lines along one axis across rooms spanning `ranges`: each room
/// cut at its door (and light) edges, then evenly at about `step`.
fn room_lines(ranges: impl Iterator<Item = (f64, f64)>, step: f64) -> Vec<f64> {
    let mut out = Vec::new();
    for (lo, hi) in ranges {
        let mid = (lo + hi) / 2.0;
        for (k, (a, b)) in [
            (lo, mid - HALF_DOOR),
            (mid - HALF_DOOR, mid + HALF_DOOR),
            (mid + HALF_DOOR, hi),
        ]
        .into_iter()
        .enumerate()
        {
            let l = lines(a, b, step);
            out.extend_from_slice(if k == 0 { &l } else { &l[1..] });
        }
    }
    out
}

/// What a shell face belongs to.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Part {
    Floor,
    Ceiling,
    Light,
    Walls,
}

/// The room shells as named surfaces, in a fixed order: each room's
/// floor, ceiling, light (if lit) and walls, then the doorways.
fn shells(plan: &Plan) -> Vec<(String, Part, Vec<Tri>)> {
    let (nx, nz) = (plan.columns, plan.rows);
    let ys = [
        lines(0.0, DOOR_HEIGHT, 0.35 / plan.detail),
        lines(DOOR_HEIGHT, HEIGHT, 0.25 / plan.detail)[1..].to_vec(),
    ]
    .concat();
    let mut lattice = Lattice::new(
        room_lines(
            (0..nx).map(|i| room_box(i, 0)).map(|(a, b)| (a.x, b.x)),
            plan.wall_step(),
        ),
        ys,
        room_lines(
            (0..nz).map(|j| room_box(0, j)).map(|(a, b)| (a.z, b.z)),
            plan.wall_step(),
        ),
    );
    // Regions: rooms first (row by row), then the doors.
    let mut doors = Vec::new();
    for j in 0..nz {
        for i in 0..nx {
            let (min, max) = room_box(i, j);
            lattice.open(min, max, i + nx * j);
        }
    }
    for j in 0..nz {
        for i in 0..nx {
            let (min, max) = room_box(i, j);
            let mid = (min + max) / 2.0;
            if i + 1 < nx {
                doors.push((
                    format!("door_{i}_{j}_east"),
                    v(max.x, 0.0, mid.z - HALF_DOOR),
                    v(max.x + WALL, DOOR_HEIGHT, mid.z + HALF_DOOR),
                ));
            }
            if j + 1 < nz {
                doors.push((
                    format!("door_{i}_{j}_north"),
                    v(mid.x - HALF_DOOR, 0.0, max.z),
                    v(mid.x + HALF_DOOR, DOOR_HEIGHT, max.z + WALL),
                ));
            }
        }
    }
    let rooms = nx * nz;
    for (k, (_, min, max)) in doors.iter().enumerate() {
        lattice.open(*min, *max, rooms + k);
    }

    const PARTS: [(Part, &str); 4] = [
        (Part::Floor, "floor"),
        (Part::Ceiling, "ceiling"),
        (Part::Light, "light"),
        (Part::Walls, "walls"),
    ];
    let mut room_parts: Vec<[Vec<Tri>; 4]> = vec![Default::default(); rooms];
    let mut door_tris: Vec<Vec<Tri>> = vec![Vec::new(); doors.len()];
    for face in lattice.boundary() {
        if face.region >= rooms {
            door_tris[face.region - rooms].extend(face.triangles);
            continue;
        }
        let (i, j) = (face.region % nx, face.region / nx);
        let part = match face.facing {
            Side::PosY => Part::Floor,
            Side::NegY => {
                let (min, max) = room_box(i, j);
                let c = (face.cell_min + face.cell_max) - (min + max);
                let (dx, dz) = (c.x / 2.0, c.z / 2.0);
                if is_lit(i, j) && dx.abs() < HALF_DOOR && dz.abs() < HALF_DOOR {
                    Part::Light
                } else {
                    Part::Ceiling
                }
            }
            _ => Part::Walls,
        };
        let slot = PARTS.iter().position(|p| p.0 == part).unwrap_or(3);
        room_parts[face.region][slot].extend(face.triangles);
    }
    let mut out = Vec::new();
    for (r, parts) in room_parts.into_iter().enumerate() {
        for ((part, name), tris) in PARTS.iter().zip(parts) {
            if !tris.is_empty() {
                out.push((format!("room_{}_{}_{name}", r % nx, r / nx), *part, tris));
            }
        }
    }
    for ((name, _, _), tris) in doors.into_iter().zip(door_tris) {
        out.push((name, Part::Walls, tris));
    }
    out
}

/// A lamp standing on the floor at `base`: a thin open pole and a closed
/// shade on it.
fn lamp(
    plan: &Plan,
    base: DVec3,
    pole_height: f64,
    shade_radius: f64,
    shade_height: f64,
) -> Vec<Tri> {
    let mut t = cylinder(base, 0.015, pole_height, plan.segments(6), 1, false, false);
    t.extend(cylinder(
        base + v(0.0, pole_height, 0.0),
        shade_radius,
        shade_height,
        plan.segments(20),
        plan.cells(2),
        true,
        true,
    ));
    t
}

/// The furniture meshes of one plan: (name, material name, triangles).
/// Centre pieces are centred on their origin; corner pieces (see
/// [`CORNER_SETS`]) start at it.
fn pieces(plan: &Plan) -> Vec<(&'static str, &'static str, Vec<Tri>)> {
    let p = |name, material, triangles| (name, material, triangles);
    let mut crates = cuboid_grid(
        v(0.0, 0.0, 0.0),
        v(0.7, 0.5, 0.7),
        plan.cells(3),
        &[Side::NegY],
    );
    crates.extend(cuboid_grid(
        v(0.15, 0.5, 0.15),
        v(0.55, 0.8, 0.55),
        plan.cells(2),
        &[Side::NegY],
    ));
    let pot_height = 0.35;
    vec![
        p("table", "walnut", table(plan.segments(12))),
        p(
            "ball",
            "orange",
            sphere(
                v(0.0, 0.121, 0.0),
                0.12,
                plan.segments(20),
                plan.segments(12),
            ),
        ),
        p("chair", "blue_fabric", chair()),
        p("bookshelf", "pine", bookshelf()),
        p("books", "book_cloth", books()),
        p(
            "cabinet",
            "white_lacquer",
            cuboid_grid(
                v(0.0, 0.0, 0.0),
                v(0.8, 0.9, 0.45),
                plan.cells(3),
                &[Side::NegY],
            ),
        ),
        p(
            "floor_lamp",
            "linen",
            lamp(plan, v(0.4, 0.0, 0.4), 1.5, 0.2, 0.3),
        ),
        p(
            "desk_lamp",
            "linen",
            lamp(plan, DVec3::ZERO, 0.3, 0.1, 0.12),
        ),
        p(
            "column",
            "concrete",
            cylinder(
                v(0.35, 0.0, 0.35),
                0.15,
                HEIGHT,
                plan.segments(20),
                plan.cells(6),
                false,
                false,
            ),
        ),
        p("crates", "cardboard", crates),
        p(
            "pot",
            "terracotta",
            cylinder(
                v(0.4, 0.0, 0.4),
                0.15,
                pot_height,
                plan.segments(16),
                plan.cells(2),
                false,
                true,
            ),
        ),
        p(
            "plant",
            "leaf_green",
            sphere(
                v(0.4, pot_height + 0.281, 0.4),
                0.28,
                plan.segments(20),
                plan.segments(12),
            ),
        ),
        p(
            "big_sphere",
            "teal",
            sphere(
                v(0.0, 0.351, 0.0),
                0.35,
                plan.segments(28),
                plan.segments(16),
            ),
        ),
        p(
            "stool",
            "walnut",
            cylinder(
                v(0.0, 0.0, 0.0),
                0.2,
                0.45,
                plan.segments(16),
                plan.cells(2),
                false,
                true,
            ),
        ),
    ]
}

/// Corner pieces: (meshes, extent along x). Their footprints start at the
/// piece's origin and reach at most 1 m along x and 0.8 m along z, so that
/// placed 0.1 m from the side wall a piece ends 1.1 m from the corner,
/// short of the doors (at least 1.3 m from it).
const CORNER_SETS: [(&[&str], f64); 6] = [
    (&["bookshelf", "books"], 1.0),
    (&["cabinet"], 0.8),
    (&["floor_lamp"], 0.8),
    (&["column"], 0.7),
    (&["crates"], 0.7),
    (&["pot", "plant"], 0.8),
];

/// Materials: (name, ρ, note).
const MATERIALS: [(&str, [f64; 3], &str); 21] = [
    ("paint_white", [0.78, 0.76, 0.72], "warm white wall paint"),
    ("paint_sage", [0.55, 0.62, 0.5], "sage green wall paint"),
    ("paint_blue", [0.55, 0.6, 0.7], "pale blue wall paint"),
    ("ceiling_white", [0.8, 0.8, 0.8], "white ceiling paint"),
    ("oak_floor", [0.5, 0.35, 0.22], "light oak boards"),
    ("carpet", [0.35, 0.33, 0.3], "grey-beige carpet"),
    ("tiles", [0.62, 0.6, 0.58], "pale floor tiles"),
    ("door_trim", [0.7, 0.7, 0.68], "off-white door reveals"),
    ("walnut", [0.4, 0.25, 0.15], "dark wood (tables, stools)"),
    ("blue_fabric", [0.15, 0.3, 0.6], "chair upholstery"),
    ("pine", [0.6, 0.46, 0.32], "light wood (bookshelves)"),
    ("book_cloth", [0.55, 0.15, 0.12], "red book covers"),
    ("white_lacquer", [0.7, 0.7, 0.68], "cabinets"),
    ("linen", [0.75, 0.72, 0.62], "lamps (not emitting)"),
    ("concrete", [0.55, 0.55, 0.52], "columns"),
    ("cardboard", [0.55, 0.42, 0.28], "crates"),
    ("terracotta", [0.6, 0.32, 0.2], "plant pots"),
    ("leaf_green", [0.12, 0.35, 0.1], "plants"),
    ("orange", [0.75, 0.3, 0.08], "balls on the tables"),
    ("teal", [0.15, 0.5, 0.55], "large spheres"),
    ("light", [0.8, 0.8, 0.8], "ceiling panels"),
];

/// Builds the floor of `plan`.
pub fn build(plan: &Plan) -> SceneDef {
    let stem = stem(plan.target);
    let title = format!("Office floor, {} triangles targeted", plan.target);
    let mut s = SceneDef::new(&stem, &title, BufferStorage::External);
    s.about = about(plan);
    for (name, reflectance, note) in MATERIALS {
        s.add_material(Material {
            name,
            reflectance,
            emission: (name == "light").then(|| Emission::with_strength(LIGHT_RADIANCE)),
            note: if name == "light" {
                "warm white ceiling panels (as in three-rooms); reflectance of the ceiling"
            } else {
                note
            },
        });
    }
    let material = |name: &str| {
        MATERIALS
            .iter()
            .position(|m| m.0 == name)
            .unwrap_or_else(|| panic!("no material {name}"))
    };

    for (name, part, tris) in shells(plan) {
        let (i, j) = room_of(&name);
        let m = match part {
            Part::Floor => ["oak_floor", "carpet", "tiles"][kind(i, j)],
            Part::Ceiling => "ceiling_white",
            Part::Light => "light",
            Part::Walls if name.starts_with("door_") => "door_trim",
            Part::Walls => ["paint_white", "paint_sage", "paint_blue"][j % 3],
        };
        s.add_surface(&name, material(m), tris);
    }

    let meshes: Vec<(&str, usize)> = pieces(plan)
        .into_iter()
        .map(|(name, m, tris)| (name, s.add_mesh(name, material(m), tris)))
        .collect();
    let mesh = |name: &str| {
        meshes
            .iter()
            .find(|m| m.0 == name)
            .map(|m| m.1)
            .unwrap_or_else(|| panic!("no mesh {name}"))
    };

    for j in 0..plan.rows {
        for i in 0..plan.columns {
            let (min, max) = room_box(i, j);
            let (w, d) = (max.x - min.x, max.z - min.z);
            let mut children = Vec::new();
            let mut place = |s: &mut SceneDef, name: &str, at: DVec3, turned: bool| {
                let id = s.add_node(Node {
                    name: format!("{name}_{i}_{j}_{}", children.len()),
                    mesh: Some(mesh(name)),
                    translation: (at != DVec3::ZERO).then_some(at),
                    rotation: turned.then(|| DQuat::from_rotation_y(PI)),
                    ..Node::default()
                });
                children.push(id);
            };
            let (mx, mz) = (w / 2.0, d / 2.0);
            match kind(i, j) {
                0 => {
                    place(&mut s, "table", v(mx, 0.0, mz), false);
                    place(&mut s, "ball", v(mx + 0.3, 0.76, mz + 0.1), false);
                    place(&mut s, "chair", v(mx - 0.2, 0.0, mz - 0.75), true);
                    place(&mut s, "chair", v(mx + 0.2, 0.0, mz + 0.75), false);
                }
                1 => {
                    place(&mut s, "big_sphere", v(mx, 0.0, mz), false);
                    place(&mut s, "stool", v(mx, 0.0, mz - 0.85), false);
                }
                _ => {
                    place(&mut s, "table", v(mx, 0.0, mz), false);
                    place(&mut s, "desk_lamp", v(mx - 0.45, 0.76, mz + 0.2), false);
                    place(&mut s, "chair", v(mx + 0.1, 0.0, mz - 0.75), true);
                }
            }
            // Four corners, each with a piece from the cycled corner sets,
            // 0.1 m from the side wall and 0.05 m from the end wall; pieces
            // at the far (+z) wall are turned half round.
            for (c, (at_x, at_z)) in [(false, false), (true, false), (false, true), (true, true)]
                .into_iter()
                .enumerate()
            {
                let (names, ex) = CORNER_SETS[(3 * i + 5 * j + c) % CORNER_SETS.len()];
                let at = match (at_x, at_z) {
                    (false, false) => v(0.1, 0.0, 0.05),
                    (true, false) => v(w - 0.1 - ex, 0.0, 0.05),
                    (false, true) => v(0.1 + ex, 0.0, d - 0.05),
                    (true, true) => v(w - 0.1, 0.0, d - 0.05),
                };
                for name in names {
                    place(&mut s, name, at, at_z);
                }
            }
            let group = s.add_node(Node {
                name: format!("room_{i}_{j}_furniture"),
                translation: Some(min),
                children,
                ..Node::default()
            });
            s.roots.push(group);
        }
    }

    let (_, max) = room_box(0, 0);
    let (w, d) = (max.x, max.z);
    s.add_camera(
        "camera",
        v(0.3, 1.7, d / 2.0 - 0.3),
        v(w, 1.0, d / 2.0),
        DVec3::Y,
        Camera {
            yfov: 65f64.to_radians(),
            aspect_ratio: 16.0 / 9.0,
            znear: 0.05,
        },
    );
    s
}

/// The furnishing of room (i, j): 0 meeting room, 1 lounge, 2 office.
fn kind(i: usize, j: usize) -> usize {
    (2 * i + j) % 3
}

/// Room (i, j) of a surface named `room_i_j_…` or `door_i_j_…`.
fn room_of(name: &str) -> (usize, usize) {
    let mut it = name.split('_').skip(1).map(|n| n.parse().unwrap_or(0));
    (it.next().unwrap_or(0), it.next().unwrap_or(0))
}

fn about(plan: &Plan) -> String {
    format!(
        "One member of the scale-up family (`tools/scenegen/scale.rs`): an office floor of \
{c} × {r} = {rooms} furnished rooms (x × z), generated for a target of {target} triangles. \
Room widths cycle through 4, 5 and 3.6 m along x, depths through 4, 3.4 and 4.8 m along z; \
walls are 0.1 m thick, ceilings 2.6 m high, and every two neighbouring rooms share a \
1 m × 2.1 m door in the middle of their wall. {lit} of the rooms (room (i, j) with \
(i + 2j) mod 3 = 0) have a 1 m × 1 m light panel in the middle of the ceiling; the others \
are lit through their doors only. Detail factor g = {g:.3}: walls, floors and ceilings are \
one conforming lattice of {step:.3} m × {vstep:.3} m cells (shared vertices everywhere, \
door reveals included), and furniture segment counts are g times those at 10⁴. Each room \
has a centre group (meeting: table, ball and two chairs; lounge: large sphere and stool; \
office: desk, desk lamp and chair) and one piece in each corner (bookshelf with books, \
cabinet, floor lamp, floor-to-ceiling column, crates, potted plant), all instances of one \
mesh per piece placed by nodes under a `room_i_j_furniture` group; nothing rests on a \
bottom face and no faces overlap. The camera stands in the lit room (0, 0) and looks \
across it towards the door into room (1, 0).",
        c = plan.columns,
        r = plan.rows,
        rooms = plan.rooms(),
        target = plan.target,
        lit = plan.lit_rooms(),
        g = plan.detail,
        step = plan.wall_step(),
        vstep = 0.35 / plan.detail,
    )
}
