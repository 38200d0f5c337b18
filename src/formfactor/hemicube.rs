//! Hemicube form factors [CG85]: one row F(dA_x → polygon k) for all k at
//! once, with visibility resolved by a z-buffer on the five cube faces.
//!
//! Owns: [`Hemicube`] (the cell layout and its delta form factors) and the
//! per-receiver rasteriser. Pure geometry plus its own visibility: it knows
//! nothing of the BVH, the hierarchy or the solvers.
//!
//! Layout. The cube has unit height above the receiver x; in the receiver's
//! local frame (u, v, n), n the normal, the top face is z = 1 with
//! (x, y) ∈ [−1, 1]², the four side faces are x = ±1 or y = ±1 with the
//! other tangent coordinate in [−1, 1] and z ∈ [0, 1]. Every face is drawn
//! as a perspective image from x with image coordinates (s, t) and depth w
//! along the face's axis:
//!
//! ```text
//!            t = 1 ┌─────────────┐            top:  R × R cells,
//!                  │     top     │                  s, t ∈ [−1, 1]
//!                  │   (R × R)   │
//!           t = −1 └─────────────┘
//!   t = 1  ┌─────────────┐                    side: R × R/2 cells,
//!          │ side (R×R/2)│                          s ∈ [−1, 1], t ∈ [0, 1]
//!   t = 0  └─────────────┘  ← the receiver's tangent plane (z = 0)
//!       s = −1         s = 1
//! ```
//!
//! Cell (i, j) of a face has its centre at s = −1 + (i + ½)·2/R and
//! t = t₀ + (j + ½)·2/R (t₀ = −1 on top, 0 on the sides).
//!
//! Invariants:
//! - The delta form factor of a cell is its exact form factor from the
//!   receiver (the cell's quad through the analytic point-to-polygon
//!   kernel), not the cell-centre approximation, so the cells of a hemicube
//!   sum to 1 up to round-off at every resolution; the only errors left are
//!   the classic ones of [CG85]: aliasing (a cell counts whole or not at
//!   all, by its centre) and the differential receiver.
//! - A cell belongs to the nearest polygon whose front faces x, unless a
//!   back face (or a polygon seen from behind) is strictly nearer: back
//!   faces occlude but never receive a form factor. On a depth tie (the two
//!   sides of a double-sided surface) the front face wins.
//! - Every result is finite and in [0, 1]; the row sums to at most 1 (up to
//!   round-off), exactly the covered part of the hemisphere.
//! - The result depends only on the arguments (no randomness inside; the
//!   caller chooses the rotation).

use std::cell::RefCell;

use glam::DVec3;

use crate::formfactor::form_factor_point_polygon;

/// Largest resolution [`Hemicube::new`] builds: 3 · 2048² cells of delta
/// form factors take 100 MB.
pub const MAX_RESOLUTION: u32 = 2048;

/// Relative distance below which x counts as lying in a polygon's plane:
/// the polygon is then seen edge-on and draws nothing.
const EDGE_ON: f64 = 1e-10;

/// A depth tie within this relative margin goes to the front face.
const TIE: f64 = 1e-9;

/// Vertices per drawn piece; larger polygons are drawn as a fan of pieces.
const MAX_PIECE: usize = 8;

/// A piece clipped by the five planes of a face frustum has at most this
/// many vertices.
const CLIP_CAP: usize = MAX_PIECE + 5;

/// Cell owner for "no polygon" (empty, or hidden by a back face).
const NONE: u32 = u32::MAX;

/// A hemicube of resolution R: the top face has R × R cells, each side face
/// R × R/2, every cell with its precomputed delta form factor.
///
/// ```
/// use glam::DVec3;
/// use nusselt::formfactor::hemicube::Hemicube;
/// // A unit square 1 above the receiver, centred (closed form 0.2395).
/// let square: &[DVec3] = &[
///     DVec3::new(-0.5, -0.5, 1.0),
///     DVec3::new(-0.5, 0.5, 1.0),
///     DVec3::new(0.5, 0.5, 1.0),
///     DVec3::new(0.5, -0.5, 1.0),
/// ];
/// let hemicube = Hemicube::new(256);
/// let mut row = [0.0];
/// hemicube.row(DVec3::ZERO, DVec3::Z, &[square], None, 0.3, &mut row);
/// assert!((row[0] - 0.2395).abs() < 2e-3);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Hemicube {
    resolution: usize,
    /// Delta form factors of the top face, row-major: index j · R + i.
    top: Vec<f64>,
    /// Delta form factors of one side face (all four are equal), row-major:
    /// index j · R + i, j = 0 at the tangent plane.
    side: Vec<f64>,
}

/// The five faces: each maps local coordinates (x, y, z) to image
/// coordinates (a, b, f), f the depth axis; s = a / f, t = b / f.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Face {
    Top,
    PosX,
    NegX,
    PosY,
    NegY,
}

const FACES: [Face; 5] = [Face::Top, Face::PosX, Face::NegX, Face::PosY, Face::NegY];

impl Face {
    /// Local → face coordinates (a rotation, so dot products are kept).
    fn map(self, p: DVec3) -> DVec3 {
        match self {
            Face::Top => p,
            Face::PosX => DVec3::new(p.y, p.z, p.x),
            Face::NegX => DVec3::new(-p.y, p.z, -p.x),
            Face::PosY => DVec3::new(-p.x, p.z, p.y),
            Face::NegY => DVec3::new(p.x, p.z, -p.y),
        }
    }

    /// Lowest t of the face.
    fn t0(self) -> f64 {
        if self == Face::Top { -1.0 } else { 0.0 }
    }
}

/// A convex piece of one input polygon, in the receiver's local frame.
#[derive(Clone, Copy, Debug)]
struct Piece {
    /// Row index of the polygon; drawn with an id only when `front`.
    id: u32,
    /// The front of the polygon faces the receiver.
    front: bool,
    len: usize,
    vertices: [DVec3; MAX_PIECE],
    /// Unit plane normal (local frame) and offset: the plane is
    /// {p : normal · p = offset}, offset ≠ 0.
    normal: DVec3,
    offset: f64,
}

/// Per-thread buffers reused across calls.
#[derive(Default)]
struct Scratch {
    pieces: Vec<Piece>,
    depth: Vec<f64>,
    owner: Vec<u32>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::default();
}

impl Hemicube {
    /// A hemicube whose top face has `resolution` × `resolution` cells.
    /// The resolution is rounded up to an even number and kept within
    /// [2, [`MAX_RESOLUTION`]]; [`Hemicube::resolution`] tells the one used.
    pub fn new(resolution: u32) -> Hemicube {
        let r = resolution.clamp(2, MAX_RESOLUTION).next_multiple_of(2) as usize;
        let h = 2.0 / r as f64;
        let edge = |k: usize| -1.0 + k as f64 * h;
        // The top face is symmetric under s → −s and t → −t: compute one
        // quadrant with the kernel and mirror it.
        let mut top = vec![0.0; r * r];
        for j in r / 2..r {
            for i in r / 2..r {
                let (s0, s1, t0, t1) = (edge(i), edge(i + 1), edge(j), edge(j + 1));
                let cell = [
                    DVec3::new(s0, t0, 1.0),
                    DVec3::new(s1, t0, 1.0),
                    DVec3::new(s1, t1, 1.0),
                    DVec3::new(s0, t1, 1.0),
                ];
                let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &cell);
                for (ii, jj) in [
                    (i, j),
                    (r - 1 - i, j),
                    (i, r - 1 - j),
                    (r - 1 - i, r - 1 - j),
                ] {
                    top[jj * r + ii] = f;
                }
            }
        }
        // A side face (x = 1, s along y, t along z) is symmetric in s.
        let mut side = vec![0.0; r * r / 2];
        for j in 0..r / 2 {
            for i in r / 2..r {
                let (s0, s1) = (edge(i), edge(i + 1));
                let (t0, t1) = (j as f64 * h, (j + 1) as f64 * h);
                let cell = [
                    DVec3::new(1.0, s0, t0),
                    DVec3::new(1.0, s1, t0),
                    DVec3::new(1.0, s1, t1),
                    DVec3::new(1.0, s0, t1),
                ];
                let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &cell);
                side[j * r + i] = f;
                side[j * r + (r - 1 - i)] = f;
            }
        }
        Hemicube {
            resolution: r,
            top,
            side,
        }
    }

    /// R: the top face has R × R cells, each side face R × R/2.
    pub fn resolution(&self) -> u32 {
        self.resolution as u32
    }

    /// Sum of the delta form factors of all cells of the hemicube: 1 up to
    /// round-off.
    pub fn total(&self) -> f64 {
        self.top.iter().sum::<f64>() + 4.0 * self.side.iter().sum::<f64>()
    }

    /// Form factors from the differential area at `x` with unit `normal` to
    /// every polygon in `polygons`, with visibility resolved by the z-buffer
    /// among those same polygons: `out[k]` = F(dA_x → polygon k).
    ///
    /// Polygons are convex and planar, counter-clockwise seen from their
    /// front (as [`crate::scene::Patch::vertices`] gives them); triangles and
    /// quads are the usual case, any vertex count works. A polygon whose
    /// front faces x is drawn with its index; one seen from behind only
    /// occludes and gets 0. Polygons with fewer than 3 vertices, zero area or
    /// non-finite vertices, and polygons whose plane passes through x (seen
    /// edge-on), draw nothing. `skip` is a polygon never drawn (the receiver
    /// itself). `rotation` turns the hemicube about the normal by that angle
    /// in radians (0 = a fixed frame built deterministically from the
    /// normal); callers pass a random angle per receiver against aliasing.
    ///
    /// With a zero or non-finite normal or a non-finite `x`, the row is 0.
    /// A polygon whose plane passes within 1e-10 of its own size of x counts
    /// as edge-on: x practically lies on it.
    ///
    /// Cost: O(polygons + covered cells) per face; the z-buffer lives in
    /// per-thread scratch, so a row allocates nothing once its thread's
    /// buffers have grown. Run rows for many receivers in parallel freely:
    /// a `Hemicube` is shared read-only.
    ///
    /// # Panics
    /// If `out.len() != polygons.len()` or there are `u32::MAX` or more
    /// polygons (caller bugs, never input data).
    pub fn row(
        &self,
        x: DVec3,
        normal: DVec3,
        polygons: &[&[DVec3]],
        skip: Option<usize>,
        rotation: f64,
        out: &mut [f64],
    ) {
        assert_eq!(
            out.len(),
            polygons.len(),
            "hemicube row: one output per polygon"
        );
        assert!(
            polygons.len() < NONE as usize,
            "hemicube row: too many polygons"
        );
        out.fill(0.0);
        let n = normal.normalize_or_zero();
        if n == DVec3::ZERO || !x.is_finite() {
            return;
        }
        let (u0, v0) = n.any_orthonormal_pair();
        let (sin, cos) = if rotation.is_finite() {
            rotation.sin_cos()
        } else {
            (0.0, 1.0)
        };
        let u = cos * u0 + sin * v0;
        let frame = [u, n.cross(u), n];
        SCRATCH.with(|scratch| {
            let scratch = &mut *scratch.borrow_mut();
            scratch.pieces.clear();
            for (k, polygon) in polygons.iter().enumerate() {
                if Some(k) != skip {
                    push_pieces(k as u32, x, &frame, polygon, &mut scratch.pieces);
                }
            }
            let r = self.resolution;
            scratch.depth.resize(r * r, 0.0);
            scratch.owner.resize(r * r, NONE);
            for face in FACES {
                let (weights, height) = match face {
                    Face::Top => (&self.top, r),
                    _ => (&self.side, r / 2),
                };
                let mut image = Image {
                    width: r,
                    height,
                    face,
                    depth: &mut scratch.depth[..r * height],
                    owner: &mut scratch.owner[..r * height],
                };
                image.depth.fill(0.0);
                image.owner.fill(NONE);
                // Front faces first, then back faces erase what they hide:
                // the order makes depth ties go to the front face.
                for pass_front in [true, false] {
                    for piece in scratch.pieces.iter().filter(|p| p.front == pass_front) {
                        image.draw(piece);
                    }
                }
                for (&owner, &w) in image.owner.iter().zip(weights) {
                    if owner != NONE {
                        out[owner as usize] += w;
                    }
                }
            }
        });
        for f in out.iter_mut() {
            *f = f.clamp(0.0, 1.0);
        }
    }
}

/// Transforms `polygon` into the local frame around `x` and appends it as
/// one or more convex pieces of at most [`MAX_PIECE`] vertices; appends
/// nothing for a polygon that cannot cover any cell.
fn push_pieces(id: u32, x: DVec3, frame: &[DVec3; 3], polygon: &[DVec3], pieces: &mut Vec<Piece>) {
    let m = polygon.len();
    if m < 3 || polygon.iter().any(|p| !p.is_finite()) {
        return;
    }
    let local = |p: DVec3| {
        let d = p - x;
        DVec3::new(d.dot(frame[0]), d.dot(frame[1]), d.dot(frame[2]))
    };
    // Wholly behind the tangent plane: outside every face.
    if polygon.iter().all(|&p| (p - x).dot(frame[2]) <= 0.0) {
        return;
    }
    // Newell-style area vector of the fan from the first vertex.
    let p0 = local(polygon[0]);
    let mut area = DVec3::ZERO;
    let mut reach = p0.length();
    for i in 1..m - 1 {
        let (a, b) = (local(polygon[i]), local(polygon[i + 1]));
        area += (a - p0).cross(b - p0);
        reach = reach.max(b.length());
    }
    let normal = area.normalize_or_zero();
    if normal == DVec3::ZERO {
        return;
    }
    let offset = polygon.iter().map(|&p| normal.dot(local(p))).sum::<f64>() / m as f64;
    if !offset.is_finite() || !reach.is_finite() || offset.abs() <= EDGE_ON * reach {
        return;
    }
    // Fan pieces sharing the first vertex, each of at most MAX_PIECE.
    let mut start = 1;
    while start + 1 < m {
        let end = (start + MAX_PIECE - 1).min(m);
        let mut piece = Piece {
            id,
            front: offset < 0.0,
            len: 0,
            vertices: [DVec3::ZERO; MAX_PIECE],
            normal,
            offset,
        };
        piece.vertices[0] = p0;
        for (slot, &p) in piece.vertices[1..].iter_mut().zip(&polygon[start..end]) {
            *slot = local(p);
        }
        piece.len = end - start + 1;
        pieces.push(piece);
        start = end - 1;
    }
}

/// One face's z-buffer: depth holds 1/w of the nearest surface so far
/// (0 = nothing), owner its polygon id or [`NONE`].
struct Image<'a> {
    width: usize,
    height: usize,
    face: Face,
    depth: &'a mut [f64],
    owner: &'a mut [u32],
}

impl Image<'_> {
    /// Scan-converts `piece` with cell-centre sampling and a depth test.
    fn draw(&mut self, piece: &Piece) {
        let face = self.face;
        // Clip in face coordinates against the frustum and a near plane at
        // half the plane's distance: no point of the polygon is nearer than
        // |offset|, and frustum points with f < |offset| / 2 are closer than
        // |offset| to x, so this removes nothing but guards the division.
        let near = 0.5 * piece.offset.abs();
        let lower = if face == Face::Top {
            (DVec3::new(0.0, 1.0, 1.0), 0.0)
        } else {
            (DVec3::new(0.0, 1.0, 0.0), 0.0)
        };
        let planes = [
            (DVec3::Z, -near),
            (DVec3::new(-1.0, 0.0, 1.0), 0.0),
            (DVec3::new(1.0, 0.0, 1.0), 0.0),
            (DVec3::new(0.0, -1.0, 1.0), 0.0),
            lower,
        ];
        let mut a = [DVec3::ZERO; CLIP_CAP];
        let mut b = [DVec3::ZERO; CLIP_CAP];
        let mut len = piece.len;
        // Outcodes: bit k set when a vertex is outside plane k.
        let (mut all_out, mut any_out) = (u8::MAX, 0u8);
        for (slot, &p) in a.iter_mut().zip(&piece.vertices[..len]) {
            let q = face.map(p);
            *slot = q;
            let mut code = 0;
            for (bit, (k, c)) in planes.iter().enumerate() {
                if k.dot(q) + c < 0.0 {
                    code |= 1 << bit;
                }
            }
            all_out &= code;
            any_out |= code;
        }
        if all_out != 0 {
            return;
        }
        for (bit, (k, c)) in planes.into_iter().enumerate() {
            if any_out & (1 << bit) == 0 {
                continue;
            }
            len = clip(&a[..len], k, c, &mut b);
            if len < 3 {
                return;
            }
            std::mem::swap(&mut a, &mut b);
        }
        // Project to cell units: X = (s + 1) / h, Y = (t − t₀) / h.
        let h = 2.0 / self.width as f64;
        let t0 = face.t0();
        let mut pts = [(0.0, 0.0); CLIP_CAP];
        for (q, p) in pts.iter_mut().zip(&a[..len]) {
            *q = ((p.x / p.z + 1.0) / h, (p.y / p.z - t0) / h);
        }
        let pts = &pts[..len];
        // Depth 1/w = (n · (s, t, 1)) / offset is affine in the image.
        let nf = face.map(piece.normal) / piece.offset;
        let (y_min, y_max) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.1), hi.max(p.1))
            });
        let j0 = cell_index(y_min, self.height);
        let j1 = cell_index(y_max, self.height);
        for j in j0..j1 {
            let yc = j as f64 + 0.5;
            let (mut xl, mut xr) = (f64::INFINITY, f64::NEG_INFINITY);
            for (e, &(px, py)) in pts.iter().enumerate() {
                let (qx, qy) = pts[(e + 1) % len];
                if (py <= yc) != (qy <= yc) {
                    let xc = px + (yc - py) * (qx - px) / (qy - py);
                    xl = xl.min(xc);
                    xr = xr.max(xc);
                }
            }
            if xl >= xr {
                continue;
            }
            let i0 = cell_index(xl, self.width);
            let i1 = cell_index(xr, self.width);
            let t = t0 + yc * h;
            let row = j * self.width;
            for i in i0..i1 {
                let s = -1.0 + (i as f64 + 0.5) * h;
                let q = nf.x * s + nf.y * t + nf.z;
                let c = row + i;
                if piece.front {
                    if q > self.depth[c] {
                        self.depth[c] = q;
                        self.owner[c] = piece.id;
                    }
                } else if self.owner[c] != NONE && q > self.depth[c] * (1.0 + TIE) {
                    self.depth[c] = q;
                    self.owner[c] = NONE;
                }
            }
        }
    }
}

/// The first cell whose centre is at or beyond `x` (cell units), clamped
/// to [0, n]: cells i with centre i + ½ ∈ [a, b) are `index(a)..index(b)`.
fn cell_index(x: f64, n: usize) -> usize {
    let i = (x - 0.5).ceil();
    if i <= 0.0 {
        0
    } else if i >= n as f64 {
        n
    } else {
        i as usize
    }
}

/// Sutherland–Hodgman clip of a convex polygon to {p : k · p + c ≥ 0};
/// returns the vertex count written to `out` (at most one more than the
/// input's).
fn clip(input: &[DVec3], k: DVec3, c: f64, out: &mut [DVec3; CLIP_CAP]) -> usize {
    let mut n = 0;
    let m = input.len();
    for i in 0..m {
        let p = input[i];
        let q = input[(i + 1) % m];
        let dp = k.dot(p) + c;
        let dq = k.dot(q) + c;
        if dp >= 0.0 && n < CLIP_CAP {
            out[n] = p;
            n += 1;
        }
        if (dp >= 0.0) != (dq >= 0.0) && n < CLIP_CAP {
            out[n] = p + (dp / (dp - dq)) * (q - p);
            n += 1;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::stream;
    use rand::Rng;

    /// The polygon oriented so that its front faces `x`.
    fn facing(mut poly: Vec<DVec3>, x: DVec3) -> Vec<DVec3> {
        let n = (poly[1] - poly[0]).cross(poly[2] - poly[0]);
        if n.dot(x - poly[0]) < 0.0 {
            poly.reverse();
        }
        poly
    }

    /// A `size` × `size` square at height z centred over (cx, cy), front
    /// facing down (towards the origin's side).
    fn square(cx: f64, cy: f64, z: f64, size: f64) -> Vec<DVec3> {
        let r = 0.5 * size;
        vec![
            DVec3::new(cx - r, cy - r, z),
            DVec3::new(cx - r, cy + r, z),
            DVec3::new(cx + r, cy + r, z),
            DVec3::new(cx + r, cy - r, z),
        ]
    }

    fn row(hc: &Hemicube, x: DVec3, n: DVec3, polys: &[Vec<DVec3>], rot: f64) -> Vec<f64> {
        let refs: Vec<&[DVec3]> = polys.iter().map(|p| p.as_slice()).collect();
        let mut out = vec![f64::NAN; polys.len()];
        hc.row(x, n, &refs, None, rot, &mut out);
        out
    }

    fn exact(x: DVec3, n: DVec3, poly: &[DVec3]) -> f64 {
        form_factor_point_polygon(x, n, poly)
    }

    /// Named configurations with their exact answer for polygon 0.
    struct Config {
        name: &'static str,
        x: DVec3,
        normal: DVec3,
        polys: Vec<Vec<DVec3>>,
        exact: f64,
    }

    fn configs() -> Vec<Config> {
        let x = DVec3::ZERO;
        let wall = |z0: f64| {
            facing(
                vec![
                    DVec3::new(-1.0, 1.0, z0),
                    DVec3::new(1.0, 1.0, z0),
                    DVec3::new(1.0, 1.0, 1.0),
                    DVec3::new(-1.0, 1.0, 1.0),
                ],
                x,
            )
        };
        let big = square(0.0, 0.0, 2.0, 2.0);
        let small = square(0.0, 0.0, 1.0, 0.5);
        let tilted_n = DVec3::new(0.3, -0.2, 1.0).normalize();
        let tilted = facing(
            vec![
                DVec3::new(0.2, 0.1, 0.7),
                DVec3::new(1.1, 0.3, 0.9),
                DVec3::new(0.6, 1.2, 1.4),
            ],
            x,
        );
        vec![
            Config {
                name: "square, offset",
                x,
                normal: DVec3::Z,
                polys: vec![square(0.5, 0.3, 1.0, 1.0)],
                exact: exact(x, DVec3::Z, &square(0.5, 0.3, 1.0, 1.0)),
            },
            Config {
                name: "perpendicular wall",
                x,
                normal: DVec3::Z,
                polys: vec![wall(0.0)],
                exact: exact(x, DVec3::Z, &wall(0.0)),
            },
            Config {
                name: "wall half below",
                x,
                normal: DVec3::Z,
                polys: vec![wall(-1.0)],
                exact: exact(x, DVec3::Z, &wall(-1.0)),
            },
            Config {
                name: "occluded square",
                x,
                normal: DVec3::Z,
                exact: exact(x, DVec3::Z, &big) - exact(x, DVec3::Z, &small),
                polys: vec![big, small],
            },
            Config {
                name: "tilted triangle",
                x,
                normal: tilted_n,
                exact: exact(x, tilted_n, &tilted),
                polys: vec![tilted],
            },
        ]
    }

    #[test]
    fn cells_sum_to_one_at_every_resolution() {
        println!("   R   sum of exact cells   sum of cell-centre ΔF [CG85]");
        for r in [2u32, 4, 8, 16, 32, 64, 128, 256, 512, 1024] {
            let hc = Hemicube::new(r);
            assert_eq!(hc.resolution(), r);
            let total = hc.total();
            assert!((total - 1.0).abs() < 1e-10, "R = {r}: {total}");
            // The classic cell-centre delta form factors, for comparison:
            // they converge to the exact cells as R grows.
            let h = 2.0 / r as f64;
            let (mut midpoint, mut worst) = (0.0, 0.0f64);
            let ru = r as usize;
            for j in 0..ru {
                for i in 0..ru {
                    let (s, t) = (-1.0 + (i as f64 + 0.5) * h, -1.0 + (j as f64 + 0.5) * h);
                    let f = h * h / (std::f64::consts::PI * (1.0 + s * s + t * t).powi(2));
                    midpoint += f;
                    worst = worst.max((f / hc.top[j * ru + i] - 1.0).abs());
                    if j < ru / 2 {
                        let t = (j as f64 + 0.5) * h;
                        let f = t * h * h / (std::f64::consts::PI * (1.0 + s * s + t * t).powi(2));
                        midpoint += 4.0 * f;
                        worst = worst.max((f / hc.side[j * ru + i] - 1.0).abs());
                    }
                }
            }
            println!("{r:>4}   {total:.15}   {midpoint:.9} (worst cell off by {worst:.2e})");
            // The cell-centre rule is second order: the exact cells are in
            // the right places with the right sizes.
            // (The worst relative error times R² tends to 8/3.)
            assert!(worst * (r * r) as f64 <= 2.7, "R = {r}: {worst}");
        }
        // Odd and out-of-range resolutions are adjusted, not refused.
        assert_eq!(Hemicube::new(0).resolution(), 2);
        assert_eq!(Hemicube::new(7).resolution(), 8);
        assert_eq!(Hemicube::new(u32::MAX).resolution(), MAX_RESOLUTION);
    }

    #[test]
    fn parallel_square_at_several_offsets() {
        let hc = Hemicube::new(256);
        for z in [0.25, 0.5, 1.0, 2.0] {
            for (cx, cy) in [(0.0, 0.0), (0.5, 0.5), (1.2, -0.3), (-3.0, 0.4)] {
                let sq = square(cx, cy, z, 1.0);
                let want = exact(DVec3::ZERO, DVec3::Z, &sq);
                for rot in [0.0, 0.37] {
                    let got = row(&hc, DVec3::ZERO, DVec3::Z, std::slice::from_ref(&sq), rot)[0];
                    assert!(
                        (got - want).abs() < 2e-3,
                        "z {z}, centre ({cx}, {cy}), rotation {rot}: {got} vs {want}"
                    );
                }
            }
        }
        // The closed form of the doc example (centred unit square, height 1).
        let got = row(
            &hc,
            DVec3::ZERO,
            DVec3::Z,
            &[square(0.0, 0.0, 1.0, 1.0)],
            0.3,
        )[0];
        assert!((got - 0.239_5).abs() < 2e-3, "{got}");
    }

    #[test]
    fn walls_and_clipping_match_the_exact_kernel() {
        let hc = Hemicube::new(256);
        for c in configs() {
            if c.polys.len() != 1 {
                continue;
            }
            let got = row(&hc, c.x, c.normal, &c.polys, 0.21)[0];
            assert!(
                got > 0.0 && (got - c.exact).abs() < 2e-3,
                "{}: {got} vs {}",
                c.name,
                c.exact
            );
        }
        // A wall entirely below the tangent plane is not seen at all.
        let below = facing(
            vec![
                DVec3::new(-1.0, 1.0, -2.0),
                DVec3::new(1.0, 1.0, -2.0),
                DVec3::new(1.0, 1.0, -0.01),
                DVec3::new(-1.0, 1.0, -0.01),
            ],
            DVec3::ZERO,
        );
        assert_eq!(row(&hc, DVec3::ZERO, DVec3::Z, &[below], 0.0)[0], 0.0);
        // A receiver looking sideways sees the same wall as a parallel one.
        let wall = facing(square(0.0, 0.0, 1.0, 1.0), DVec3::ZERO);
        let normal = DVec3::new(0.0, 0.6, 0.8);
        let got = row(&hc, DVec3::ZERO, normal, std::slice::from_ref(&wall), 1.0)[0];
        let want = exact(DVec3::ZERO, normal, &wall);
        assert!((got - want).abs() < 2e-3, "{got} vs {want}");
    }

    #[test]
    fn nearer_square_occludes_farther_one() {
        let hc = Hemicube::new(256);
        let big = square(0.0, 0.0, 2.0, 2.0);
        let small = square(0.0, 0.0, 1.0, 0.5);
        let (fb, fs) = (
            exact(DVec3::ZERO, DVec3::Z, &big),
            exact(DVec3::ZERO, DVec3::Z, &small),
        );
        // The small square's shadow on the big one is exactly its own
        // projection, so the big one loses exactly the small one's F.
        let alone = row(&hc, DVec3::ZERO, DVec3::Z, std::slice::from_ref(&big), 0.4)[0];
        for polys in [
            vec![big.clone(), small.clone()],
            vec![small.clone(), big.clone()],
        ] {
            let out = row(&hc, DVec3::ZERO, DVec3::Z, &polys, 0.4);
            let (gb, gs) = if polys[0] == big {
                (out[0], out[1])
            } else {
                (out[1], out[0])
            };
            assert!((gs - fs).abs() < 2e-3, "small {gs} vs {fs}");
            assert!((gb - (fb - fs)).abs() < 2e-3, "big {gb} vs {}", fb - fs);
            assert!(
                (gb + gs - alone).abs() < 1e-12,
                "covered cells are shared, not lost"
            );
        }
        // Seen from behind, the small square still shadows but gets nothing.
        let mut back = small.clone();
        back.reverse();
        let out = row(
            &hc,
            DVec3::ZERO,
            DVec3::Z,
            &[big.clone(), back.clone()],
            0.4,
        );
        assert_eq!(out[1], 0.0);
        assert!(
            (out[0] - (fb - fs)).abs() < 2e-3,
            "{} vs {}",
            out[0],
            fb - fs
        );
        // Both sides (a double-sided surface): the front side wins the tie,
        // whatever the drawing order.
        for polys in [
            vec![big.clone(), small.clone(), back.clone()],
            vec![big.clone(), back, small.clone()],
        ] {
            let out = row(&hc, DVec3::ZERO, DVec3::Z, &polys, 0.4);
            let (gs, gback) = if polys[1] == square(0.0, 0.0, 1.0, 0.5) {
                (out[1], out[2])
            } else {
                (out[2], out[1])
            };
            assert_eq!(gback, 0.0);
            assert!((gs - fs).abs() < 2e-3, "{gs} vs {fs}");
            assert!((out[0] - (fb - fs)).abs() < 2e-3);
        }
        // A farther polygon does not hide a nearer one.
        let far_small = square(0.0, 0.0, 3.0, 0.5);
        let out = row(&hc, DVec3::ZERO, DVec3::Z, &[big.clone(), far_small], 0.4);
        assert!((out[0] - fb).abs() < 2e-3 && out[1] == 0.0, "{out:?}");
        // `skip` removes a polygon entirely, as occluder too.
        let refs: Vec<&[DVec3]> = vec![&big, &small];
        let mut out = [0.0; 2];
        hc.row(DVec3::ZERO, DVec3::Z, &refs, Some(1), 0.4, &mut out);
        assert!(out[1] == 0.0 && (out[0] - fb).abs() < 2e-3, "{out:?}");
    }

    #[test]
    fn rotation_changes_results_only_within_aliasing() {
        let hc = Hemicube::new(128);
        let mut rng = stream(7, 0);
        for c in configs() {
            let values: Vec<f64> = (0..16)
                .map(|_| {
                    let rot = rng.random::<f64>() * std::f64::consts::TAU;
                    row(&hc, c.x, c.normal, &c.polys, rot)[0]
                })
                .collect();
            let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            assert!(hi > lo, "{}: rotation must move the cells", c.name);
            assert!(hi - lo < 4e-3, "{}: spread {}", c.name, hi - lo);
            for v in values {
                assert!((v - c.exact).abs() < 3e-3, "{}: {v} vs {}", c.name, c.exact);
            }
        }
        // Turning by a full turn is the same hemicube.
        let c = &configs()[0];
        let a = row(&hc, c.x, c.normal, &c.polys, 0.3)[0];
        let b = row(&hc, c.x, c.normal, &c.polys, 0.3 + std::f64::consts::TAU)[0];
        assert!((a - b).abs() < 1e-12);
    }

    #[test]
    fn error_falls_as_resolution_grows() {
        const ROTATIONS: usize = 8;
        let resolutions = [16u32, 32, 64, 128, 256];
        let configs = configs();
        let mut table = vec![vec![0.0; resolutions.len()]; configs.len()];
        for (ri, &r) in resolutions.iter().enumerate() {
            let hc = Hemicube::new(r);
            for (ci, c) in configs.iter().enumerate() {
                let mut rng = stream(11, ci as u64);
                let mean: f64 = (0..ROTATIONS)
                    .map(|_| {
                        let rot = rng.random::<f64>() * std::f64::consts::TAU;
                        (row(&hc, c.x, c.normal, &c.polys, rot)[0] - c.exact).abs()
                    })
                    .sum::<f64>()
                    / ROTATIONS as f64;
                table[ci][ri] = mean;
            }
        }
        println!("mean |F_hemicube − F_exact| over {ROTATIONS} random rotations");
        print!("{:<20} {:>9}", "configuration", "F_exact");
        for r in resolutions {
            print!(" {:>9}", format!("R={r}"));
        }
        println!();
        for (c, errors) in configs.iter().zip(&table) {
            print!("{:<20} {:>9.6}", c.name, c.exact);
            for e in errors {
                print!(" {e:>9.2e}");
            }
            println!();
            // A clear trend: 16× the resolution cuts the error by 16× at
            // least, and no doubling makes it more than a little worse.
            let (first, last) = (errors[0], errors[errors.len() - 1]);
            assert!(last < first / 16.0, "{}: {errors:?}", c.name);
            for w in errors.windows(2) {
                assert!(w[1] < 1.5 * w[0], "{}: {errors:?}", c.name);
            }
        }
    }

    /// A unit cube around the receiver, each face facing inwards; the floor
    /// (z = 0) first.
    fn cube() -> Vec<Vec<DVec3>> {
        let c = DVec3::splat(0.5);
        let corners = |axis: usize, side: f64| {
            let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
            [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
                .map(|(a, b)| {
                    let mut p = DVec3::ZERO;
                    p[axis] = side;
                    p[i] = a;
                    p[j] = b;
                    p
                })
                .to_vec()
        };
        let mut faces = Vec::new();
        for axis in [2, 0, 1] {
            for side in [0.0, 1.0] {
                faces.push(facing(corners(axis, side), c));
            }
        }
        faces
    }

    #[test]
    fn closed_cube_rows_sum_to_one() {
        let hc = Hemicube::new(128);
        let faces = cube();
        let refs: Vec<&[DVec3]> = faces.iter().map(|p| p.as_slice()).collect();
        for x in [
            DVec3::new(0.5, 0.5, 0.0),
            DVec3::new(0.1, 0.8, 0.0),
            DVec3::new(1e-6, 0.5, 0.0),
            DVec3::new(1e-6, 1e-6, 0.0),
        ] {
            let mut out = [f64::NAN; 6];
            hc.row(x, DVec3::Z, &refs, Some(0), 0.7, &mut out);
            let sum: f64 = out.iter().sum();
            assert!((sum - 1.0).abs() < 1e-9, "{x}: {sum} {out:?}");
            assert_eq!(out[0], 0.0);
            for (k, f) in out.iter().enumerate().skip(1) {
                let want = exact(x, DVec3::Z, &faces[k]);
                assert!((f - want).abs() < 5e-3, "{x}, face {k}: {f} vs {want}");
            }
        }
        // At a corner of the floor the two walls through x are seen
        // edge-on; the rest is finite and matches the exact kernel.
        let x = DVec3::ZERO;
        let mut out = [f64::NAN; 6];
        hc.row(x, DVec3::Z, &refs, Some(0), 0.7, &mut out);
        for (k, f) in out.iter().enumerate().skip(1) {
            let want = exact(x, DVec3::Z, &faces[k]);
            assert!((f - want).abs() < 5e-3, "corner, face {k}: {f} vs {want}");
        }
    }

    #[test]
    fn touching_and_degenerate_polygons_stay_in_range() {
        let hc = Hemicube::new(128);
        let x = DVec3::ZERO;
        let check = |polys: &[Vec<DVec3>], n: DVec3| {
            let out = row(&hc, x, n, polys, 0.9);
            for f in &out {
                assert!(f.is_finite() && (0.0..=1.0).contains(f), "{out:?}");
            }
            assert!(out.iter().sum::<f64>() <= 1.0 + 1e-12);
            out
        };
        // A wall standing on the tangent plane, sharing its bottom edge
        // with it.
        let wall = facing(
            vec![
                DVec3::new(-1.0, 0.5, 0.0),
                DVec3::new(1.0, 0.5, 0.0),
                DVec3::new(1.0, 0.5, 1.0),
                DVec3::new(-1.0, 0.5, 1.0),
            ],
            x,
        );
        let f = check(std::slice::from_ref(&wall), DVec3::Z)[0];
        assert!((f - exact(x, DVec3::Z, &wall)).abs() < 3e-3, "{f}");
        // A wall through x: seen edge-on.
        let through = facing(
            vec![
                DVec3::new(-1.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(-1.0, 0.0, 1.0),
            ],
            DVec3::Y,
        );
        assert_eq!(check(&[through], DVec3::Z)[0], 0.0);
        // Squares 1e-6 above x: centred (almost the whole hemisphere) and
        // with x under a corner (almost a quarter).
        for sq in [square(0.0, 0.0, 1e-6, 1.0), square(0.5, 0.5, 1e-6, 1.0)] {
            let f = check(std::slice::from_ref(&sq), DVec3::Z)[0];
            let want = exact(x, DVec3::Z, &sq);
            assert!((f - want).abs() < 3e-3, "{f} vs {want}");
        }
        // Coplanar with the receiver: nothing.
        let floor = facing(square(2.0, 0.0, 0.0, 1.0), DVec3::Z);
        assert_eq!(check(&[floor], DVec3::Z)[0], 0.0);
        // Degenerate input draws nothing and harms no other polygon.
        let sq = square(0.0, 0.0, 1.0, 1.0);
        let want = exact(x, DVec3::Z, &sq);
        let junk = vec![
            vec![
                DVec3::new(0.0, 0.0, 0.5),
                DVec3::new(1.0, 0.0, 0.5),
                DVec3::new(2.0, 0.0, 0.5),
            ],
            vec![DVec3::new(0.0, 0.0, 0.5), DVec3::new(1.0, 0.0, 0.5)],
            vec![
                DVec3::new(f64::NAN, 0.0, 0.5),
                DVec3::new(1.0, 0.0, 0.5),
                DVec3::Z,
            ],
            vec![DVec3::splat(f64::INFINITY); 4],
            vec![],
            sq,
        ];
        let out = check(&junk, DVec3::Z);
        assert_eq!(&out[..5], &[0.0; 5]);
        assert!((out[5] - want).abs() < 3e-3);
        // A degenerate receiver gets a zero row.
        let refs: Vec<&[DVec3]> = junk.iter().map(|p| p.as_slice()).collect();
        for (x, n) in [
            (DVec3::ZERO, DVec3::ZERO),
            (DVec3::NAN, DVec3::Z),
            (x, DVec3::NAN),
        ] {
            let mut out = [1.0; 6];
            hc.row(x, n, &refs, None, f64::NAN, &mut out);
            assert_eq!(out, [0.0; 6]);
        }
    }

    #[test]
    fn polygons_of_many_vertices_are_drawn_whole() {
        let hc = Hemicube::new(256);
        for m in [5usize, 8, 9, 12, 40] {
            let poly: Vec<DVec3> = (0..m)
                .map(|k| {
                    let a = -(k as f64) * std::f64::consts::TAU / m as f64;
                    DVec3::new(0.3 + a.cos(), a.sin(), 1.0)
                })
                .collect();
            let poly = facing(poly, DVec3::ZERO);
            // The exact kernel takes at most 15 vertices: sum over a fan.
            let want: f64 = (1..m - 1)
                .map(|k| exact(DVec3::ZERO, DVec3::Z, &[poly[0], poly[k], poly[k + 1]]))
                .sum();
            let got = row(&hc, DVec3::ZERO, DVec3::Z, &[poly], 0.5)[0];
            assert!((got - want).abs() < 2e-3, "{m} vertices: {got} vs {want}");
        }
    }

    #[test]
    fn random_scenes_give_bounded_deterministic_rows() {
        let hc = Hemicube::new(32);
        let mut rng = stream(3, 1);
        for _ in 0..100 {
            let polys: Vec<Vec<DVec3>> = (0..20)
                .map(|_| {
                    let c = DVec3::new(
                        rng.random_range(-2.0..2.0),
                        rng.random_range(-2.0..2.0),
                        rng.random_range(-1.0..2.0),
                    );
                    let m = if rng.random::<bool>() { 3 } else { 4 };
                    let (e1, e2) = DVec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    )
                    .normalize()
                    .any_orthonormal_pair();
                    let size = rng.random_range(0.01..2.0);
                    (0..m)
                        .map(|k| {
                            let a = k as f64 * std::f64::consts::TAU / m as f64;
                            c + size * (a.cos() * e1 + a.sin() * e2)
                        })
                        .collect()
                })
                .collect();
            let n = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let rot = rng.random_range(0.0..7.0);
            let a = row(&hc, DVec3::ZERO, n, &polys, rot);
            let b = row(&hc, DVec3::ZERO, n, &polys, rot);
            assert_eq!(a, b);
            assert!(
                a.iter().all(|f| f.is_finite() && (0.0..=1.0).contains(f)),
                "{a:?}"
            );
            assert!(a.iter().sum::<f64>() <= 1.0 + 1e-12);
        }
    }
}
