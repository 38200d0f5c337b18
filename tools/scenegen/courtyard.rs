//! `courtyard`: an open-topped courtyard among four blocks of different
//! heights, lit by a directional sun (`KHR_lights_punctual`) and meant to
//! be solved with a uniform sky as well. No material emits.
//!
//! Plan (y up, metres; north is −z, east +x; block heights in brackets):
//!
//! ```text
//!  z=−10 ┌──────────────── street ───────────────┐
//!  z=−9  │ ┌──────── north [9] ──────────┬─────┐ │
//!  z=−6  │ ├─────┬───────────────────────┤     │ │
//!        │ │     │  ○     ○     ○     ○  │     │ │
//!        │ │west │              ┌─────┐  │ east│ │
//!        │ │[7.5]│    ground    │perg.│  │ [6] │ │
//!        │ │     │              └─────┘  │     │ │
//!        │ │     │                       │     │ │
//!  z=6   │ │     ├───────────────────────┴─────┤ │
//!  z=9   │ └─────┴────────── south [4] ────────┘ │
//!  z=10  └───────────────────────────────────────┘
//!      −10 −9    −6                      6     9 10
//! ```
//!
//! The blocks form a pinwheel (each one's end abuts the next one's side),
//! 3 m deep, around the 12 m × 12 m ground, with a 1 m street outside.
//! Invariants: blocks, ground and street come from one [`Lattice`] whose
//! open space is the courtyard, the street and the air over the roofs, so
//! every face looks into open space and neighbouring faces share vertices;
//! the lattice's own outer faces (its top and its four sides) are left
//! out, so the scene is open to the sky. The portico and the pergola rest
//! on the ground without bottom faces; faces that touch another part (a
//! column's top under a beam, a slat's end against a beam, the portico's
//! back against the north block) are left out.

use glam::DVec3;

use super::lattice::{Lattice, lines};
use super::model::{BufferStorage, Camera, Light, LightKind, SceneDef};
use super::shapes::{Side, Tri, cuboid};

/// Half the ground's side, the blocks' depth, the street's width.
const HALF: f64 = 6.0;
const DEPTH: f64 = 3.0;
const STREET: f64 = 1.0;
/// Top of the lattice: open air above the tallest roof.
const TOP: f64 = 10.0;

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// One block: its name, its footprint's corners (x, z) and its height.
struct Block {
    name: &'static str,
    min: [f64; 2],
    max: [f64; 2],
    height: f64,
}

impl Block {
    fn contains(&self, p: DVec3) -> bool {
        (self.min[0]..self.max[0]).contains(&p.x)
            && (0.0..self.height).contains(&p.y)
            && (self.min[1]..self.max[1]).contains(&p.z)
    }
}

/// The four blocks, pinwheeled around the ground.
fn blocks() -> [Block; 4] {
    let (h, o) = (HALF, HALF + DEPTH);
    [
        Block {
            name: "north",
            min: [-o, -o],
            max: [h, -h],
            height: 9.0,
        },
        Block {
            name: "east",
            min: [h, -o],
            max: [o, h],
            height: 6.0,
        },
        Block {
            name: "south",
            min: [-h, h],
            max: [o, o],
            height: 4.0,
        },
        Block {
            name: "west",
            min: [-o, -h],
            max: [-h, o],
            height: 7.5,
        },
    ]
}

/// Lattice lines along x or z: the street, the blocks' depth, the ground
/// in 1.5 m steps.
fn plan_lines() -> Vec<f64> {
    let (h, o, e) = (HALF, HALF + DEPTH, HALF + DEPTH + STREET);
    [vec![-e, -o], lines(-h, h, 1.5), vec![o, e]].concat()
}

/// The surfaces of blocks, ground and street as (name, triangles), in a
/// fixed order: ground, street, then each block's walls and roof.
fn shells() -> Vec<(String, Vec<Tri>)> {
    let blocks = blocks();
    let ys = vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.5, 9.0, TOP];
    let mut l = Lattice::new(plan_lines(), ys, plan_lines());
    let e = HALF + DEPTH + STREET;
    // The courtyard, the street, and the air above each roof.
    l.open(v(-HALF, 0.0, -HALF), v(HALF, TOP, HALF), 0);
    let o = HALF + DEPTH;
    for (min, max) in [
        (v(-e, 0.0, -e), v(e, TOP, -o)),
        (v(-e, 0.0, o), v(e, TOP, e)),
        (v(-e, 0.0, -o), v(-o, TOP, o)),
        (v(o, 0.0, -o), v(e, TOP, o)),
    ] {
        l.open(min, max, 1);
    }
    for b in &blocks {
        l.open(
            v(b.min[0], b.height, b.min[1]),
            v(b.max[0], TOP, b.max[1]),
            2,
        );
    }

    let mut names: Vec<String> = vec!["ground".to_owned(), "street".to_owned()];
    for b in &blocks {
        names.push(format!("{}_walls", b.name));
        names.push(format!("{}_roof", b.name));
    }
    let mut groups: Vec<Vec<Tri>> = vec![Vec::new(); names.len()];
    for face in l.boundary() {
        let [a, b, c] = face.triangles[0];
        let d = face.triangles[1][2];
        let centre = (a + b + c + d) * 0.25;
        // The solid just behind the face: a block, or nothing (below the
        // ground, or outside the lattice).
        let behind = centre - face.facing.normal() * 0.01;
        let name = match blocks.iter().find(|b| b.contains(behind)) {
            Some(b) if face.facing == Side::PosY => format!("{}_roof", b.name),
            Some(b) => format!("{}_walls", b.name),
            None if face.facing == Side::PosY && centre.y == 0.0 => {
                let inside = centre.x.abs() < HALF && centre.z.abs() < HALF;
                if inside { "ground" } else { "street" }.to_owned()
            }
            // The lattice's top and outer sides: open sky and street.
            None => continue,
        };
        let slot = names.iter().position(|n| *n == name).expect("a known name");
        groups[slot].extend(face.triangles);
    }
    names.into_iter().zip(groups).collect()
}

/// A portico along the north block's courtyard face: a 1.2 m deep slab
/// 3 m up on four square columns; the slab's back against the wall and the
/// columns' tops and bottoms are left out.
fn portico() -> (Vec<Tri>, Vec<Tri>) {
    let slab = cuboid(
        v(-5.0, 3.0, -HALF),
        v(5.0, 3.25, -HALF + 1.2),
        &[Side::NegZ],
    );
    let mut columns = Vec::new();
    for x in [-4.5, -1.5, 1.5, 4.5] {
        columns.extend(cuboid(
            v(x - 0.15, 0.0, -5.25),
            v(x + 0.15, 3.0, -4.95),
            &[Side::NegY, Side::PosY],
        ));
    }
    (slab, columns)
}

/// A pergola in the east half: two beams along z on four posts, and ten
/// slats along x between the beams (their ends against the beams left
/// out), all 2.6–2.85 m up.
fn pergola() -> Vec<Tri> {
    let (y0, y1) = (2.6, 2.85);
    let (z0, z1) = (-2.5, 1.5);
    let mut t = Vec::new();
    for x in [1.5, 4.5] {
        t.extend(cuboid(v(x - 0.15, y0, z0), v(x + 0.15, y1, z1), &[]));
        for z in [z0 + 0.4, z1 - 0.4] {
            t.extend(cuboid(
                v(x - 0.1, 0.0, z - 0.1),
                v(x + 0.1, y0, z + 0.1),
                &[Side::NegY, Side::PosY],
            ));
        }
    }
    for k in 0..10 {
        let z = z0 + 0.15 + 0.4 * k as f64;
        t.extend(cuboid(
            v(1.65, y0, z),
            v(4.35, y1, z + 0.1),
            &[Side::NegX, Side::PosX],
        ));
    }
    t
}

/// Direction the sun's light travels: from the south-west, 45° above the
/// horizon, 30° round from south towards west.
pub fn sun_direction() -> DVec3 {
    let (elevation, azimuth) = (45f64.to_radians(), 30f64.to_radians());
    let horizontal = v(azimuth.sin(), 0.0, -azimuth.cos());
    (horizontal * elevation.cos() - DVec3::Y * elevation.sin()).normalize()
}

pub fn scene() -> SceneDef {
    let mut s = SceneDef::new(
        "courtyard",
        "Courtyard under sun and sky",
        BufferStorage::External,
    );
    s.about = "An open-topped courtyard for outdoor light: a 12 m × 12 m paved ground among four \
blocks of different heights (north 9 m, west 7.5 m, east 6 m, south 4 m), 3 m deep and \
pinwheeled so that each one's end abuts the next one's side, with a 1 m street round the \
outside. A portico (a slab on four columns) runs along the north block's sunlit face, and a \
pergola of ten slats on two beams and four posts stands in the east half, so that the sun \
draws the slats' stripes and the columns' shadows on the ground, next to the shadows of the \
west and south blocks. The only light is a directional sun (`KHR_lights_punctual`) from the \
south-west, 45° above the horizon; no material emits. The scene is meant to be solved with a \
sky as well, e.g. `nusselt solve scenes/courtyard.gltf --sky 0.25,0.32,0.45` (a uniform sky \
radiance, W·m⁻²·sr⁻¹, per channel); without `--sky` it is lit by the sun alone. Blocks, \
ground and street are one conforming grid (1.5 m on the ground, up to 1.5 m on the walls), \
every face looking into open air; the portico and the pergola rest on the ground without \
bottom faces. The camera stands high in the south-west corner and looks across the ground to \
the sunlit north and east faces.

Plan (seen from above; north is −z, east +x; block heights in brackets):

```text
 z=−10 ┌──────────────── street ───────────────┐
 z=−9  │ ┌──────── north [9] ──────────┬─────┐ │
 z=−6  │ ├─────┬───────────────────────┤     │ │
       │ │     │  ○     ○     ○     ○  │     │ │
       │ │west │              ┌─────┐  │ east│ │
       │ │[7.5]│    ground    │perg.│  │ [6] │ │
       │ │     │              └─────┘  │     │ │
       │ │     │                       │     │ │
 z=6   │ │     ├───────────────────────┴─────┤ │
 z=9   │ └─────┴────────── south [4] ────────┘ │
 z=10  └───────────────────────────────────────┘
     −10 −9    −6                      6     9 10
```

○ the portico's columns, under a slab over x ∈ [−5, 5], z ∈ [−6, −4.8], 3–3.25 m up; \
perg. the pergola, over x ∈ [1.35, 4.65], z ∈ [−2.5, 1.5], 2.6–2.85 m up. The sun's light \
travels along (0.354, −0.707, −0.612): the west and south blocks shade the ground's west and \
south edges, and the courtyard faces of the north and east blocks are sunlit."
        .to_owned();

    let paving = s.add_diffuse("paving", [0.5, 0.47, 0.42], "sandstone paving (ground)");
    let asphalt = s.add_diffuse("asphalt", [0.15, 0.15, 0.15], "street");
    let ochre = s.add_diffuse(
        "plaster_ochre",
        [0.7, 0.55, 0.35],
        "ochre plaster (north block)",
    );
    let white = s.add_diffuse(
        "plaster_white",
        [0.75, 0.73, 0.68],
        "white plaster (east block)",
    );
    let brick = s.add_diffuse("brick", [0.45, 0.22, 0.16], "red brick (south block)");
    let stone = s.add_diffuse(
        "stone",
        [0.55, 0.52, 0.46],
        "grey limestone (west block, portico)",
    );
    let tiles = s.add_diffuse("roof_tiles", [0.5, 0.24, 0.16], "terracotta roofs");
    let wood = s.add_diffuse("weathered_wood", [0.4, 0.33, 0.25], "pergola timber");

    for (name, tris) in shells() {
        let material = match name.as_str() {
            "ground" => paving,
            "street" => asphalt,
            n if n.ends_with("_roof") => tiles,
            "north_walls" => ochre,
            "east_walls" => white,
            "south_walls" => brick,
            _ => stone,
        };
        s.add_surface(&name, material, tris);
    }
    let (slab, columns) = portico();
    s.add_surface("portico_roof", stone, slab);
    s.add_surface("portico_columns", stone, columns);
    s.add_surface("pergola", wood, pergola());

    // The node's position only marks where the sunlight comes from.
    let sun = sun_direction();
    s.add_light(
        Light {
            name: "sun",
            kind: LightKind::Directional,
            color: [1.0, 0.96, 0.88],
            intensity: 3.0,
        },
        -sun * 12.0,
        sun,
    );

    s.add_camera(
        "camera",
        v(-5.2, 7.0, 5.2),
        v(1.5, 2.5, -2.5),
        DVec3::Y,
        Camera {
            yfov: 60f64.to_radians(),
            aspect_ratio: 16.0 / 9.0,
            znear: 0.05,
        },
    );
    s
}
