//! Hemicube form factors \[CG85\]: one row F(dA_x → polygon k) for all k at
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
//!   the classic ones of \[CG85\]: aliasing (a cell counts whole or not at
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
mod tests;
