//! D0 discontinuities: contact lines, where an occluder edge rests on a
//! receiver and the radiosity jumps across it.
//!
//! Owns: [`Context::contacts`].
//!
//! An edge makes a contact line on a receiver when both its ends lie within
//! the contact tolerance of the receiver's plane and one of its triangles
//! rises in front of the plane. Flat edges (inside a planar occluder face)
//! never do.
//!
//! Invariants: a contact segment is the edge projected onto the receiver's
//! plane and clipped to its polygon, kept only when `Receiver::keeps` it;
//! its weight sums the unoccluded irradiance of every luminaire facing the
//! receiver. Segments come in edge order, then receiver order, whatever the
//! thread count.

use rayon::prelude::*;

use super::CONTACT_TOL;
use super::clip::{Bounds, clip_to_polygon};
use super::context::Context;
use super::occluders::{Edge, third};
use super::{Segment, SegmentKind};

impl Context<'_> {
    /// D0: occluder edges lying in a receiver's plane with a triangle rising
    /// in front of it, clipped to the receiver polygon.
    pub(super) fn contacts(&self) -> Vec<Segment> {
        let per_edge: Vec<Vec<Segment>> = self
            .occluders
            .edges
            .par_iter()
            .map(|e| self.edge_contacts(e))
            .collect();
        per_edge.into_iter().flatten().collect()
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
        for (r, rec) in self.receivers.iter().enumerate() {
            if !edge_bounds.overlaps(&rec.bounds) {
                continue;
            }
            if let Some(s) = self.contact(e, r as u32) {
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
