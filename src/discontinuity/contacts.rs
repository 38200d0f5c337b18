//! D0 discontinuities: contact lines, where an occluder edge rests on a
//! receiver or an occluder passes through it, and the radiosity jumps
//! across the line.
//!
//! Owns: [`Context::contacts`].
//!
//! An edge makes a contact line on a receiver when both its ends lie within
//! the contact tolerance of the receiver's plane and one of its triangles
//! rises in front of the plane. Flat edges (inside a planar occluder face)
//! never do. A triangle with corners farther than the tolerance on both
//! sides of a receiver's plane (a louvre sunk a few millimetres into a
//! wall, a box pushed into a floor) makes one along the chord the plane
//! cuts from it: no edge of it need lie on the receiver.
//!
//! Invariants: a contact segment is the edge (or chord) projected onto the
//! receiver's plane and clipped to its polygon, kept only when
//! `Receiver::keeps` it;
//! its weight sums the unoccluded irradiance of every luminaire facing the
//! receiver. Edge contacts come first, in edge order, then crossings in
//! triangle order, each in receiver order, whatever the thread count.

use glam::DVec3;
use rayon::prelude::*;

use super::CONTACT_TOL;
use super::clip::{Bounds, clip_to_polygon, plane_chord};
use super::context::Context;
use super::occluders::{Edge, third};
use super::{Segment, SegmentKind};

impl Context<'_> {
    /// D0: occluder edges lying in a receiver's plane with a triangle rising
    /// in front of it, then the chords of triangles passing through a
    /// receiver's plane, clipped to the receiver polygon.
    pub(super) fn contacts(&self) -> Vec<Segment> {
        let per_edge: Vec<Vec<Segment>> = self
            .occluders
            .edges
            .par_iter()
            .map(|e| self.edge_contacts(e))
            .collect();
        let per_triangle: Vec<Vec<Segment>> = (0..self.scene.triangles.len())
            .into_par_iter()
            .map(|t| self.crossings(t))
            .collect();
        per_edge.into_iter().chain(per_triangle).flatten().collect()
    }

    /// The lines along which triangle `t` passes through receivers, in
    /// receiver order.
    fn crossings(&self, t: usize) -> Vec<Segment> {
        let mut out = Vec::new();
        let p = self.scene.triangles[t].positions;
        let tol_c = CONTACT_TOL * self.diagonal;
        let bounds = Bounds {
            lo: p[0].min(p[1]).min(p[2]),
            hi: p[0].max(p[1]).max(p[2]),
        };
        let mut candidates = Vec::new();
        let straddles = |d: [f64; 3], slack: f64| {
            let (lo, hi) = (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]));
            lo < -tol_c + slack && hi > tol_c - slack
        };
        self.index.candidates(
            &self.receivers,
            &bounds,
            |g| straddles(p.map(|x| g.distance(x)), g.slack),
            &mut candidates,
        );
        for r in candidates {
            let rec = &self.receivers[r as usize];
            if !straddles(p.map(|x| rec.distance(x)), 0.0) {
                continue;
            }
            let Some((a, b)) = plane_chord(&p, rec.normal, rec.normal.dot(rec.center), tol_c)
            else {
                continue;
            };
            if let Some(s) = self.contact_segment(r, a, b) {
                out.push(s);
            }
        }
        out
    }

    /// The contact lines of one edge, in receiver order.
    fn edge_contacts(&self, e: &Edge) -> Vec<Segment> {
        let mut out = Vec::new();
        if e.flat {
            return out;
        }
        let (pa, pb) = self.occluders.ends(e);
        let edge_bounds = Bounds {
            lo: pa.min(pb),
            hi: pa.max(pb),
        };
        let tol_c = CONTACT_TOL * self.diagonal;
        let mut candidates = Vec::new();
        self.index.candidates(
            &self.receivers,
            &edge_bounds,
            |g| g.distance(pa).abs() <= tol_c + g.slack && g.distance(pb).abs() <= tol_c + g.slack,
            &mut candidates,
        );
        for r in candidates {
            if let Some(s) = self.contact(e, r) {
                out.push(s);
            }
        }
        out
    }

    /// The contact line of edge `e` on receiver `r`, if it touches it.
    fn contact(&self, e: &Edge, r: u32) -> Option<Segment> {
        let rec = &self.receivers[r as usize];
        let tol_c = CONTACT_TOL * self.diagonal;
        let (pa, pb) = self.occluders.ends(e);
        if rec.distance(pa).abs() > tol_c || rec.distance(pb).abs() > tol_c {
            return None;
        }
        let rises = e.triangles.iter().any(|&t| {
            let c = third(&self.scene.triangles[t as usize].positions, pa, pb);
            rec.distance(c) > tol_c
        });
        if !rises {
            return None;
        }
        self.contact_segment(r, pa, pb)
    }

    /// The contact segment on receiver `r` of the line from `pa` to `pb`
    /// (within the contact tolerance of its plane): projected, clipped to
    /// its polygon, weighed by the luminaires facing it.
    fn contact_segment(&self, r: u32, pa: DVec3, pb: DVec3) -> Option<Segment> {
        let rec = &self.receivers[r as usize];
        let (a, b) = clip_to_polygon(&rec.polygon, rec.normal, rec.project(pa), rec.project(pb))?;
        if !rec.keeps(a, b, self.diagonal) {
            return None;
        }
        let mid = 0.5 * (a + b);
        let weight = self
            .luminaires
            .iter()
            .filter(|l| l.receivers.binary_search(&r).is_ok())
            .map(|l| self.weight(l, r, mid))
            .sum();
        Some(Segment {
            patch: r,
            a,
            b,
            kind: SegmentKind::Contact,
            emitter: None,
            weight,
        })
    }
}
