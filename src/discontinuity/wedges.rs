//! D1 discontinuities: the critical VE and EV wedges of a job.
//!
//! Owns: [`Wedge`] (its plane, bounding half-planes, generating features,
//! box and visibility test), [`Traced`] and [`Context::run_job`], which
//! keeps the critical wedges of a job and traces each (see `trace`).
//!
//! A wedge is a planar region in which a visibility event between an emitter
//! and an occluder happens:
//!
//! ```text
//!   VE: emitter vertex v, occluder edge ab       EV: emitter edge w0w1, occluder vertex p
//!          v                                         w0 ------ w1
//!         / \                                           \    /
//!        a---b     <- occluder edge                      \  /
//!       /     \                                           p        <- occluder vertex
//!      /wedge  \   <- beyond ab, away from v             / \
//!                                                       /wedge
//! ```
//!
//! A wedge is kept only when it is critical: the emitter lies entirely on one
//! side of its plane (for VE, the emitter's other vertices; for EV, always
//! true of a convex emitter's edge) and the occluder is tangent to it (for VE,
//! every triangle on the edge lies on one side; for EV, every triangle
//! touching the vertex does). Such a wedge bounds the region where a part of
//! the emitter starts or stops being hidden: a gradient (D1) discontinuity of
//! the direct light, or the umbra/penumbra boundary. EEE events are not
//! traced.
//!
//! Invariants: a wedge's normal is a unit vector; a degenerate plane (its
//! generating points nearly collinear) makes no wedge; a job's wedges are
//! tried in the order of the luminaire's vertices (VE) or edges (EV).

use glam::DVec3;

use super::clip::Bounds;
use super::context::Context;
use super::luminaires::Luminaire;
use super::occluders::third;
use super::silhouettes::Job;
use super::{Segment, SegmentKind};
use crate::visibility::TriangleBvh;

/// A wedge plane is degenerate, and skipped, when the cross product of its
/// two generating directions is at most this fraction of the product of
/// their lengths.
const DEGENERATE: f64 = 1e-12;

/// What one job produced.
#[derive(Debug, Default)]
pub(super) struct Traced {
    /// The segments, in the order traced.
    pub(super) segments: Vec<Segment>,
    /// Critical wedges traced.
    pub(super) wedges: usize,
    /// Visibility rays cast.
    pub(super) rays: usize,
}

/// A critical wedge: its plane, the in-plane half-planes bounding it, and
/// the features that generate it.
pub(super) struct Wedge {
    pub(super) kind: SegmentKind,
    /// Unit normal of the plane.
    pub(super) normal: DVec3,
    /// The plane is `normal · x = offset`.
    pub(super) offset: f64,
    /// (point, in-plane normal): the region is k · (x − o) ≥ 0 for each.
    pub(super) half_planes: [(DVec3, DVec3); 3],
    /// How many of `half_planes` are used.
    pub(super) n_half_planes: usize,
    /// Occluder feature: the edge (VE) or the vertex twice (EV).
    pub(super) base: [DVec3; 2],
    /// Emitter feature: the vertex twice (VE) or the edge (EV).
    pub(super) source: [DVec3; 2],
    /// Directions from `base` outward along the wedge's two side rays.
    pub(super) directions: [DVec3; 2],
}

impl Wedge {
    /// The VE wedge of emitter vertex `v` and occluder edge (a, b), in the
    /// plane with unit normal `m`.
    fn ve(v: DVec3, a: DVec3, b: DVec3, m: DVec3) -> Wedge {
        let toward = |k: DVec3, o: DVec3, inside: DVec3| {
            if k.dot(inside - o) < 0.0 { -k } else { k }
        };
        let k1 = toward(m.cross(a - v), v, b);
        let k2 = toward(m.cross(b - v), v, a);
        let k3 = -toward(m.cross(b - a), a, v);
        Wedge {
            kind: SegmentKind::Ve,
            normal: m,
            offset: m.dot(v),
            half_planes: [(v, k1), (v, k2), (a, k3)],
            n_half_planes: 3,
            base: [a, b],
            source: [v, v],
            directions: [a - v, b - v],
        }
    }

    /// The EV wedge of emitter edge (w0, w1) and occluder vertex `p`, in the
    /// plane with unit normal `m`.
    fn ev(w0: DVec3, w1: DVec3, p: DVec3, m: DVec3) -> Wedge {
        let (d0, d1) = (p - w0, p - w1);
        let orient = |k: DVec3, d: DVec3| if k.dot(d) < 0.0 { -k } else { k };
        let k1 = orient(m.cross(d0), d1);
        let k2 = orient(m.cross(d1), d0);
        Wedge {
            kind: SegmentKind::Ev,
            normal: m,
            offset: m.dot(p),
            half_planes: [(p, k1), (p, k2), (p, DVec3::ZERO)],
            n_half_planes: 2,
            base: [p, p],
            source: [w0, w1],
            directions: [d0, d1],
        }
    }

    /// A box holding the wedge's part inside the scene box `scene`: along
    /// each axis the wedge is unbounded wherever a side ray heads.
    pub(super) fn bounds(&self, scene: &Bounds) -> Bounds {
        let (lo, hi) = (scene.lo, scene.hi);
        let mut wlo = self.base[0].min(self.base[1]);
        let mut whi = self.base[0].max(self.base[1]);
        for d in self.directions {
            for k in 0..3 {
                if d[k] < 0.0 {
                    wlo[k] = lo[k];
                }
                if d[k] > 0.0 {
                    whi[k] = hi[k];
                }
            }
        }
        Bounds {
            lo: wlo.max(lo),
            hi: whi.min(hi),
        }
    }

    /// True when the wedge's line through `x` is clear from the emitter
    /// feature to the occluder feature and from there to `x`.
    pub(super) fn unblocked(&self, bvh: &TriangleBvh, x: DVec3) -> bool {
        let m = self.normal;
        // The point of segment (p, q) on the line through `apex` and `x`.
        let meet = |p: DVec3, q: DVec3, apex: DVec3| {
            let num = (p - apex).cross(x - apex).dot(m);
            let den = (q - p).cross(x - apex).dot(m);
            let s = if den.abs() > 0.0 {
                (-num / den).clamp(0.0, 1.0)
            } else {
                0.5
            };
            p.lerp(q, s)
        };
        let (from, through) = match self.kind {
            SegmentKind::Ev => {
                let p = self.base[0];
                (meet(self.source[0], self.source[1], p), p)
            }
            _ => {
                let v = self.source[0];
                (v, meet(self.base[0], self.base[1], v))
            }
        };
        bvh.visible(from, through) && bvh.visible(through, x)
    }
}

impl Context<'_> {
    /// Traces the critical wedges of one job of luminaire `l`.
    pub(super) fn run_job(&self, l: usize, job: Job) -> Traced {
        let lum = &self.luminaires[l];
        let mut traced = Traced::default();
        match job {
            Job::Edge(e, a, b) => self.ve_wedges(lum, e, (a, b), &mut traced),
            Job::Vertex(p) => self.ev_wedges(lum, p, &mut traced),
        }
        traced
    }

    /// The critical VE wedges of each luminaire vertex with occluder edge
    /// `e`, whose part in front of the luminaire is `(a, b)`.
    fn ve_wedges(&self, lum: &Luminaire, e: u32, (a, b): (DVec3, DVec3), traced: &mut Traced) {
        let tol = self.tol();
        let poly = &lum.polygon;
        let nv = poly.len();
        let edge = &self.occluders.edges[e as usize];
        let (pa, pb) = self.occluders.ends(edge);
        for i in 0..nv {
            let v = poly[i];
            let Some(m) = plane_normal(a - v, b - v) else {
                continue;
            };
            let emitter_one_side = one_side(
                (0..nv).filter(|&j| j != i).map(|j| (poly[j] - v).dot(m)),
                tol,
            );
            let occluder_tangent = one_side(
                edge.triangles.iter().map(|&t| {
                    (third(&self.scene.triangles[t as usize].positions, pa, pb) - v).dot(m)
                }),
                tol,
            );
            if !(emitter_one_side && occluder_tangent) {
                continue;
            }
            traced.wedges += 1;
            self.trace(lum, &Wedge::ve(v, a, b, m), traced);
        }
    }

    /// The critical EV wedges of each luminaire edge with occluder vertex
    /// `p`.
    fn ev_wedges(&self, lum: &Luminaire, p: u32, traced: &mut Traced) {
        let tol = self.tol();
        let poly = &lum.polygon;
        let nv = poly.len();
        let pv = self.occluders.vertices[p as usize];
        for i in 0..nv {
            let (w0, w1) = (poly[i], poly[(i + 1) % nv]);
            let Some(m) = plane_normal(w1 - w0, pv - w0) else {
                continue;
            };
            let emitter_one_side = one_side(poly.iter().map(|&q| (q - w0).dot(m)), tol);
            let occluder_tangent = one_side(
                self.occluders.vertex_triangles[p as usize]
                    .iter()
                    .flat_map(|&t| {
                        self.scene.triangles[t as usize]
                            .positions
                            .map(|q| (q - pv).dot(m))
                    }),
                tol,
            );
            if !(emitter_one_side && occluder_tangent) {
                continue;
            }
            traced.wedges += 1;
            self.trace(lum, &Wedge::ev(w0, w1, pv, m), traced);
        }
    }
}

/// The unit normal of the plane spanned by directions `u` and `w` from a
/// point; `None` when they are nearly parallel ([`DEGENERATE`]).
fn plane_normal(u: DVec3, w: DVec3) -> Option<DVec3> {
    let m = u.cross(w);
    let len = m.length();
    if !(len > DEGENERATE * u.length() * w.length()) {
        return None;
    }
    Some(m / len)
}

/// True when all values are ≥ −tol or all are ≤ tol.
fn one_side(values: impl Iterator<Item = f64>, tol: f64) -> bool {
    let (mut pos, mut neg) = (false, false);
    for d in values {
        pos |= d > tol;
        neg |= d < -tol;
    }
    !(pos && neg)
}
