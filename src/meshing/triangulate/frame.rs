//! One patch seen in its own plane: the 2D frame, the polygon with its weld
//! radius, where a point lies on it, and the clipping of segments to it.
//!
//! Owns: [`Frame2`], [`Polygon`] (with [`Place`]), and [`LocalPatch`], a
//! patch's [`PatchInput`] classified in its frame before the global weld:
//! points at corners, on edges or inside, and clipped segments whose ends
//! refer to those points ([`End`]).
//!
//! Invariants:
//! - counter-clockwise in 2D is counter-clockwise seen from the patch front;
//! - a classified point lies inside the polygon or at most one weld radius
//!   outside it; points within [`CORNER`] weld radii of a corner are that
//!   corner, the others within one weld radius of an edge are on the nearest
//!   edge (by its world position, [`Polygon::edge_point`]);
//! - every clipped segment is longer than the weld radius and both its ends
//!   are classified points of the same [`LocalPatch`].

use glam::{DVec2, DVec3};

use super::{CORNER, PatchInput, THIN, WELD};
use crate::error::{Error, Result};
use crate::scene::Patch;

/// The weld radius of a patch: [`WELD`] times the scene diagonal, at most
/// [`THIN`] times the patch's width (its smallest extent across an edge).
fn patch_tolerance(diagonal: f64, patch: &Patch) -> f64 {
    let v = patch.vertices();
    let n = v.len();
    let mut width = f64::INFINITY;
    for k in 0..n {
        let (a, b) = (v[k], v[(k + 1) % n]);
        let d = (b - a).normalize_or_zero();
        let far = v
            .iter()
            .map(|&p| (p - a - d * (p - a).dot(d)).length())
            .fold(0.0, f64::max);
        width = width.min(far);
    }
    (WELD * diagonal).min(THIN * width)
}

/// An orthonormal frame in a patch plane; counter-clockwise in 2D is
/// counter-clockwise seen from the front.
#[derive(Clone, Copy, Debug)]
pub(super) struct Frame2 {
    origin: DVec3,
    u: DVec3,
    v: DVec3,
}

impl Frame2 {
    /// The frame at the patch's first corner, `u` along its first edge.
    fn of(patch: &Patch) -> Frame2 {
        let c = patch.vertices();
        let u = (c[1] - c[0]).normalize_or_zero();
        Frame2 {
            origin: c[0],
            u,
            v: patch.normal.cross(u),
        }
    }

    /// World point → frame coordinates (projected onto the plane).
    pub(super) fn project(&self, p: DVec3) -> DVec2 {
        let d = p - self.origin;
        DVec2::new(d.dot(self.u), d.dot(self.v))
    }

    /// Frame coordinates → world point in the plane.
    pub(super) fn lift(&self, q: DVec2) -> DVec3 {
        self.origin + q.x * self.u + q.y * self.v
    }
}

/// Where a classified point lies on the patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Place {
    Corner(usize),
    /// On edge k (from corner k to k + 1) at parameter t in (0, 1).
    Edge(usize, f64),
    Inside,
}

/// The patch polygon in its frame, with its weld radius.
#[derive(Clone, Debug)]
pub(super) struct Polygon {
    pub(super) frame: Frame2,
    /// World corners, counter-clockwise.
    pub(super) corners: Vec<DVec3>,
    /// The corners in the frame.
    pub(super) poly: Vec<DVec2>,
    /// The weld radius.
    pub(super) eps: f64,
}

impl Polygon {
    pub(super) fn new(patch: &Patch, diagonal: f64) -> Polygon {
        let frame = Frame2::of(patch);
        let corners = patch.vertices().to_vec();
        let poly = corners.iter().map(|&c| frame.project(c)).collect();
        Polygon {
            frame,
            corners,
            poly,
            eps: patch_tolerance(diagonal, patch),
        }
    }

    /// The number of corners (and edges).
    pub(super) fn n(&self) -> usize {
        self.poly.len()
    }

    /// Signed distance of q from edge k's line, positive inside.
    fn edge_distance(&self, k: usize, q: DVec2) -> f64 {
        let (a, b) = (self.poly[k], self.poly[(k + 1) % self.n()]);
        (b - a).normalize_or_zero().perp_dot(q - a)
    }

    /// None when q lies outside by more than the weld radius.
    pub(super) fn classify(&self, q: DVec2) -> Option<Place> {
        let n = self.n();
        if let Some(k) = (0..n).find(|&k| (q - self.poly[k]).length() <= CORNER * self.eps) {
            return Some(Place::Corner(k));
        }
        let mut best = (f64::INFINITY, 0);
        for k in 0..n {
            let d = self.edge_distance(k, q);
            if !(d >= -self.eps) {
                return None;
            }
            if d.abs() < best.0 {
                best = (d.abs(), k);
            }
        }
        if best.0 <= self.eps {
            let k = best.1;
            let (a, b) = (self.poly[k], self.poly[(k + 1) % n]);
            let t = ((q - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            return Some(if t <= 0.0 {
                Place::Corner(k)
            } else if t >= 1.0 {
                Place::Corner((k + 1) % n)
            } else {
                Place::Edge(k, t)
            });
        }
        Some(Place::Inside)
    }

    /// The world position of edge k at parameter t.
    pub(super) fn edge_point(&self, k: usize, t: f64) -> DVec3 {
        let (a, b) = (self.corners[k], self.corners[(k + 1) % self.n()]);
        a + t * (b - a)
    }

    /// The part of segment p–q inside the polygon (Cyrus–Beck), if longer
    /// than the weld radius. The ends may lie up to half a weld radius
    /// outside; [`Polygon::classify`] puts them on the boundary.
    pub(super) fn clip(&self, p: DVec2, q: DVec2) -> Option<(DVec2, DVec2)> {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let d = q - p;
        for k in 0..self.n() {
            // Against the polygon grown by half a weld radius, so that a
            // segment along an edge survives rounding.
            let fp = self.edge_distance(k, p) + 0.5 * self.eps;
            let fd = self.edge_distance(k, q) + 0.5 * self.eps - fp;
            if fd == 0.0 {
                if fp < 0.0 {
                    return None;
                }
            } else {
                let t = -fp / fd;
                if fd > 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
        if !(t1 > t0) || !((t1 - t0) * d.length() > self.eps) {
            return None;
        }
        Some((p + t0 * d, p + t1 * d))
    }
}

/// One end of a clipped segment, before the global weld: an index into the
/// patch's corners, [`LocalPatch::boundary`] or [`LocalPatch::interior`].
#[derive(Clone, Copy, Debug)]
pub(super) enum End {
    Corner(usize),
    Boundary(usize),
    Interior(usize),
}

/// A patch's input, classified in its own frame.
#[derive(Clone, Debug)]
pub(super) struct LocalPatch {
    pub(super) shape: Polygon,
    /// Points on an edge (edge index, world position), not at corners.
    pub(super) boundary: Vec<(usize, DVec3)>,
    /// Points inside, in the frame.
    pub(super) interior: Vec<DVec2>,
    /// Clipped segments by their ends.
    pub(super) segments: Vec<[End; 2]>,
}

impl LocalPatch {
    fn new(shape: Polygon) -> LocalPatch {
        LocalPatch {
            shape,
            boundary: Vec::new(),
            interior: Vec::new(),
            segments: Vec::new(),
        }
    }

    /// Adds a point; None when it lies outside.
    fn add_point(&mut self, q: DVec2) -> Option<End> {
        Some(match self.shape.classify(q)? {
            Place::Corner(k) => End::Corner(k),
            Place::Edge(k, t) => {
                self.boundary.push((k, self.shape.edge_point(k, t)));
                End::Boundary(self.boundary.len() - 1)
            }
            Place::Inside => {
                self.interior.push(q);
                End::Interior(self.interior.len() - 1)
            }
        })
    }

    /// Classifies the points of `input` in `shape`, then clips its segments
    /// and classifies their ends. Errors on non-finite input.
    pub(super) fn build(
        patch_index: usize,
        shape: Polygon,
        input: &PatchInput,
    ) -> Result<LocalPatch> {
        let mut local = LocalPatch::new(shape);
        for (i, &p) in input.points.iter().enumerate() {
            if !p.is_finite() {
                return Err(Error::Mesh(format!(
                    "patch {patch_index}: point {i} is not finite"
                )));
            }
            let q = local.shape.frame.project(p);
            local.add_point(q);
        }
        for (i, s) in input.segments.iter().enumerate() {
            if !s[0].is_finite() || !s[1].is_finite() {
                return Err(Error::Mesh(format!(
                    "patch {patch_index}: segment {i} is not finite"
                )));
            }
            let (p, q) = (
                local.shape.frame.project(s[0]),
                local.shape.frame.project(s[1]),
            );
            let Some((p, q)) = local.shape.clip(p, q) else {
                continue;
            };
            let (Some(a), Some(b)) = (local.add_point(p), local.add_point(q)) else {
                continue;
            };
            local.segments.push([a, b]);
        }
        Ok(local)
    }
}
