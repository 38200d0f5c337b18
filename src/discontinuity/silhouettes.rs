//! The occluder features that may be on a luminaire's silhouette, as the
//! units of parallel D1 work.
//!
//! Owns: [`Job`] and [`Context::jobs`] (with the silhouette test).
//!
//! An edge is a candidate for luminaire `l` when it is not flat, not made
//! only of `l`'s own patches, reaches in front of `l`'s plane, and its two
//! faces are not seen from the same side from every point of `l`. Its ends
//! in front of `l` are the candidate vertices.
//!
//! Invariants: a luminaire's jobs are its candidate edges in edge order,
//! then its candidate vertices in order of first appearance along those
//! edges, each vertex once; an edge job carries the part of the edge in
//! front of the luminaire's plane.

use glam::DVec3;

use super::DiscontinuityStats;
use super::clip::clip_to_half_space;
use super::context::Context;
use super::luminaires::Luminaire;
use super::occluders::{Edge, third};

/// A unit of parallel work for one luminaire.
#[derive(Clone, Copy, Debug)]
pub(super) enum Job {
    /// VE wedges of every luminaire vertex with this occluder edge (clipped
    /// to the luminaire's front half-space).
    Edge(u32, DVec3, DVec3),
    /// EV wedges of every luminaire edge with this occluder vertex.
    Vertex(u32),
}

/// Which side of a face plane a point is on (points in the plane count as
/// both).
#[derive(Clone, Copy, Debug)]
enum Side {
    Front,
    Back,
}

impl Context<'_> {
    /// The jobs of luminaire `l`: its silhouette edges, then its silhouette
    /// vertices, in edge order. Counts the edges in `stats`.
    pub(super) fn jobs(&self, l: usize, stats: &mut DiscontinuityStats) -> Vec<Job> {
        let lum = &self.luminaires[l];
        let tol = self.tol();
        let mut jobs = Vec::new();
        let mut vertex_seen = vec![false; self.occluders.vertices.len()];
        let mut vertex_jobs = Vec::new();
        for (i, e) in self.occluders.edges.iter().enumerate() {
            if e.flat || self.is_own_edge(lum, e) {
                continue;
            }
            let (pa, pb) = self.occluders.ends(e);
            let clipped = match lum.omni {
                true => Some((pa, pb)),
                false => clip_to_half_space(pa, pb, lum.polygon[0], lum.normal, tol),
            };
            let Some((a, b)) = clipped else {
                continue;
            };
            if !self.maybe_silhouette(e, pa, pb, lum) {
                continue;
            }
            stats.silhouette_edges += 1;
            jobs.push(Job::Edge(i as u32, a, b));
            for (v, p) in [(e.a, pa), (e.b, pb)] {
                if lum.front(p) > tol && !vertex_seen[v as usize] {
                    vertex_seen[v as usize] = true;
                    vertex_jobs.push(Job::Vertex(v));
                }
            }
        }
        jobs.extend(vertex_jobs);
        jobs
    }

    /// True when every triangle on `e` belongs (by either side) to one of
    /// the luminaire's own patches.
    fn is_own_edge(&self, lum: &Luminaire, e: &Edge) -> bool {
        e.triangles.iter().all(|&t| {
            let tri = &self.scene.triangles[t as usize];
            lum.patches.contains(&tri.front_patch)
                || tri.back_patch.is_some_and(|b| lum.patches.contains(&b))
        })
    }

    /// False when, from every point of the luminaire, the edge's two faces
    /// are both seen from the front or both from the back. Face normals are
    /// oriented away from the other face, so the test does not depend on the
    /// mesh's winding.
    fn maybe_silhouette(&self, e: &Edge, pa: DVec3, pb: DVec3, lum: &Luminaire) -> bool {
        let [t1, t2] = e.triangles[..] else {
            return true; // boundary or non-manifold edge
        };
        let tol = self.tol();
        let c1 = third(&self.scene.triangles[t1 as usize].positions, pa, pb);
        let c2 = third(&self.scene.triangles[t2 as usize].positions, pa, pb);
        let orient = |c: DVec3, other: DVec3| {
            let n = (pb - pa).cross(c - pa).normalize_or_zero();
            if (other - pa).dot(n) > 0.0 { -n } else { n }
        };
        let n1 = orient(c1, c2);
        let n2 = orient(c2, c1);
        // Points on a face plane see that face edge-on: either side will do.
        let all = |n: DVec3, side: Side| {
            lum.polygon.iter().all(|&v| {
                let d = (v - pa).dot(n);
                match side {
                    Side::Front => d >= -tol,
                    Side::Back => d <= tol,
                }
            })
        };
        let both_front = all(n1, Side::Front) && all(n2, Side::Front);
        let both_back = all(n1, Side::Back) && all(n2, Side::Back);
        !(both_front || both_back)
    }
}
