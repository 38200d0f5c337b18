//! Triangle-list builders for the bundled scenes.
//!
//! Every builder returns triangles counter-clockwise seen from the side its
//! doc names as the front. Quads are split along the a–c diagonal:
//!
//! ```text
//!   d ───── c      front normal = (b − a) × (d − a)
//!   │     ╱ │      triangles (a, b, c) and (a, c, d)
//!   │   ╱   │
//!   a ───── b
//! ```

use std::f64::consts::TAU;

use glam::DVec3;

pub type Tri = [DVec3; 3];

/// The two triangles of the quad a, b, c, d (counter-clockwise from the front).
pub fn quad(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> [Tri; 2] {
    [[a, b, c], [a, c, d]]
}

/// Scales millimetre coordinates to metres.
pub fn mm(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z) / 1000.0
}

/// The parallelogram `origin + s·u + t·v`, s, t ∈ [0, 1], cut into `nu × nv`
/// quads; its front faces `u × v`.
pub fn grid(origin: DVec3, u: DVec3, v: DVec3, nu: usize, nv: usize) -> Vec<Tri> {
    let at = |i: usize, j: usize| origin + u * (i as f64 / nu as f64) + v * (j as f64 / nv as f64);
    let mut tris = Vec::with_capacity(2 * nu * nv);
    for j in 0..nv {
        for i in 0..nu {
            tris.extend(quad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)));
        }
    }
    tris
}

/// One face of an axis-aligned box, named by its outward normal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    NegX,
    PosX,
    NegY,
    PosY,
    NegZ,
    PosZ,
}

impl Side {
    pub const ALL: [Side; 6] = [
        Side::NegX,
        Side::PosX,
        Side::NegY,
        Side::PosY,
        Side::NegZ,
        Side::PosZ,
    ];

    /// The face on the other side of the box.
    pub fn opposite(self) -> Side {
        match self {
            Side::NegX => Side::PosX,
            Side::PosX => Side::NegX,
            Side::NegY => Side::PosY,
            Side::PosY => Side::NegY,
            Side::NegZ => Side::PosZ,
            Side::PosZ => Side::NegZ,
        }
    }

    /// The outward unit normal.
    pub fn normal(self) -> DVec3 {
        match self {
            Side::NegX => DVec3::NEG_X,
            Side::PosX => DVec3::X,
            Side::NegY => DVec3::NEG_Y,
            Side::PosY => DVec3::Y,
            Side::NegZ => DVec3::NEG_Z,
            Side::PosZ => DVec3::Z,
        }
    }
}

/// The corner and edge vectors (u × v outward) of face `side` of the box.
pub fn box_face(min: DVec3, max: DVec3, side: Side) -> (DVec3, DVec3, DVec3) {
    let d = max - min;
    let (dx, dy, dz) = (DVec3::X * d.x, DVec3::Y * d.y, DVec3::Z * d.z);
    match side {
        Side::PosX => (DVec3::new(max.x, min.y, min.z), dy, dz),
        Side::NegX => (min, dz, dy),
        Side::PosY => (DVec3::new(min.x, max.y, min.z), dz, dx),
        Side::NegY => (min, dx, dz),
        Side::PosZ => (DVec3::new(min.x, min.y, max.z), dx, dy),
        Side::NegZ => (min, dy, dx),
    }
}

/// An axis-aligned box facing outwards, without the faces in `omit` (faces
/// that rest on or touch another surface, which would otherwise overlap it).
pub fn cuboid(min: DVec3, max: DVec3, omit: &[Side]) -> Vec<Tri> {
    Side::ALL
        .iter()
        .filter(|s| !omit.contains(s))
        .flat_map(|&s| {
            let (o, u, v) = box_face(min, max, s);
            quad(o, o + u, o + u + v, o + v)
        })
        .collect()
}

/// The same box, `n` quads along each of its edges, facing outwards.
pub fn cuboid_grid(min: DVec3, max: DVec3, n: usize, omit: &[Side]) -> Vec<Tri> {
    Side::ALL
        .iter()
        .filter(|s| !omit.contains(s))
        .flat_map(|&s| {
            let (o, u, v) = box_face(min, max, s);
            grid(o, u, v, n, n)
        })
        .collect()
}

/// A point on the circle of radius `r` about the vertical axis through `c`.
fn rim(c: DVec3, r: f64, k: usize, n: usize) -> DVec3 {
    let a = TAU * k as f64 / n as f64;
    c + DVec3::new(r * a.cos(), 0.0, r * a.sin())
}

/// A vertical cylinder standing on `base` (centre of its bottom circle),
/// `segments` around and `rings` quads high, facing outwards; caps are fans.
pub fn cylinder(
    base: DVec3,
    radius: f64,
    height: f64,
    segments: usize,
    rings: usize,
    bottom_cap: bool,
    top_cap: bool,
) -> Vec<Tri> {
    let up = DVec3::Y * height;
    let mut tris = Vec::new();
    for j in 0..rings {
        let y0 = base + up * (j as f64 / rings as f64);
        let y1 = base + up * ((j + 1) as f64 / rings as f64);
        for k in 0..segments {
            let (a, b) = (rim(y0, radius, k, segments), rim(y1, radius, k, segments));
            let (c, d) = (
                rim(y1, radius, k + 1, segments),
                rim(y0, radius, k + 1, segments),
            );
            tris.extend(quad(a, b, c, d));
        }
    }
    for k in 0..segments {
        if bottom_cap {
            tris.push([
                base,
                rim(base, radius, k, segments),
                rim(base, radius, k + 1, segments),
            ]);
        }
        if top_cap {
            let top = base + up;
            tris.push([
                top,
                rim(top, radius, k + 1, segments),
                rim(top, radius, k, segments),
            ]);
        }
    }
    tris
}

/// A latitude–longitude sphere facing outwards: `segments` around, `rings`
/// from pole to pole, single triangles at the poles.
pub fn sphere(center: DVec3, radius: f64, segments: usize, rings: usize) -> Vec<Tri> {
    let at = |k: usize, j: usize| {
        let theta = TAU * k as f64 / segments as f64;
        let phi = std::f64::consts::PI * j as f64 / rings as f64;
        if j == 0 {
            center + DVec3::Y * radius
        } else if j == rings {
            center - DVec3::Y * radius
        } else {
            center
                + radius * DVec3::new(phi.sin() * theta.cos(), phi.cos(), phi.sin() * theta.sin())
        }
    };
    let mut tris = Vec::new();
    for j in 0..rings {
        for k in 0..segments {
            let (a, b, c, d) = (at(k, j), at(k + 1, j), at(k + 1, j + 1), at(k, j + 1));
            if j > 0 {
                tris.push([a, b, c]);
            }
            if j + 1 < rings {
                tris.push([a, c, d]);
            }
        }
    }
    tris
}
