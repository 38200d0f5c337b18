//! Contact lines of the `discontinuity` mode: the D0 discontinuities where
//! an object rests on a surface and the radiosity jumps across the line.
//!
//! Owns two steps of [`build_mesh`](super::build_mesh):
//! - the exchange of vertices along contact lines ([`contact_points`]): a
//!   contact segment lies inside one patch and along an edge of each patch
//!   resting there, so each needs the other's vertices on it (no
//!   T-vertices);
//! - the split of contact-line vertices ([`split_contact_vertices`],
//!   [`side_values`]): a vertex on the line becomes one vertex per side,
//!   each evaluated just off the line on its own side.
//!
//! Invariants: points closer than the coincidence tolerance (`tol`, from
//! [`tolerance::COINCIDENT`](crate::util::tolerance::COINCIDENT)) are one
//! point; a split vertex's copies share its position exactly, so the surface
//! stays closed; the first side of a vertex keeps it, and sides come in the
//! order of their first triangle around the vertex.

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use rayon::prelude::*;

use crate::discontinuity::{Segment, SegmentKind};
use crate::meshing::point_gather::{LinkRays, PointEvaluator, PointLight};
use crate::meshing::triangulate::PatchTriangulation;
use crate::scene::Scene;
use crate::util::boxes::BoxTree;
use crate::util::geometry::segment_distance;
use crate::util::union_find::UnionFind;
use crate::visibility::ENDPOINT_GAP;

/// A side's value is evaluated this many ray endpoint gaps
/// ([`ENDPOINT_GAP`], relative to the scene diagonal) off the line, so that
/// the occluder standing there blocks the rays...
pub(super) const NUDGE: f64 = 10.0 * ENDPOINT_GAP;

/// ... but at most this fraction of the way to the side's first
/// triangle's centroid.
const MAX_NUDGE_FRACTION: f64 = 0.5;

/// The contact segments among `segments`, by patch (for the first `np`
/// patches; the others have none).
pub(super) fn contact_segments(segments: &[Vec<Segment>], np: usize) -> Vec<Vec<Segment>> {
    let mut contacts: Vec<Vec<Segment>> = vec![Vec::new(); np];
    for (p, segs) in segments.iter().enumerate().take(np) {
        contacts[p] = segs
            .iter()
            .filter(|s| s.kind == SegmentKind::Contact)
            .copied()
            .collect();
    }
    contacts
}

/// The points each patch lacks along the contact lines `contacts` (by
/// patch): a contact segment of patch `a` lies along an edge of every
/// patch `b` resting there; the vertices of `a` and of those `b` on the
/// segment must be vertices of all of them.
pub(super) fn contact_points(
    scene: &Scene,
    tris: &[PatchTriangulation],
    contacts: &[Vec<Segment>],
    tol: f64,
) -> Vec<Vec<DVec3>> {
    let mut add = vec![Vec::new(); tris.len()];
    if contacts.iter().all(Vec::is_empty) {
        return add;
    }
    let edges = PatchEdges::new(scene);
    for (a, segs) in contacts.iter().enumerate() {
        for s in segs {
            let sharing = edges.along(a, s, tol);
            if sharing.len() == 1 {
                continue;
            }
            let on: Vec<DVec3> = sharing
                .iter()
                .flat_map(|&p| tris[p].positions.iter().copied())
                .filter(|&x| segment_distance(x, s.a, s.b) <= tol)
                .collect();
            for &p in &sharing {
                for &x in &on {
                    let known = |y: &DVec3| (*y - x).length() <= tol;
                    if !tris[p].positions.iter().any(known) && !add[p].iter().any(known) {
                        add[p].push(x);
                    }
                }
            }
        }
    }
    add
}

/// Every patch edge (patch, ends), with a tree over their boxes.
struct PatchEdges {
    edges: Vec<(usize, DVec3, DVec3)>,
    tree: BoxTree,
}

impl PatchEdges {
    fn new(scene: &Scene) -> PatchEdges {
        let mut edges = Vec::new();
        for (b, patch) in scene.patches.iter().enumerate() {
            let vs = patch.vertices();
            for i in 0..vs.len() {
                edges.push((b, vs[i], vs[(i + 1) % vs.len()]));
            }
        }
        let tree = BoxTree::new(edges.iter().map(|&(_, p, q)| (p.min(q), p.max(q))));
        PatchEdges { edges, tree }
    }

    /// Patch `a`, then every other patch with an edge along its contact
    /// segment `s` (the segment's midpoint on the edge, its ends on the
    /// edge's line), in patch order.
    fn along(&self, a: usize, s: &Segment, tol: f64) -> Vec<usize> {
        let mid = 0.5 * (s.a + s.b);
        let mut sharing = Vec::new();
        let reach = DVec3::splat(tol);
        self.tree.overlapping(mid - reach, mid + reach, |e| {
            let (b, p, q) = self.edges[e as usize];
            let line = (q - p).normalize_or_zero();
            let off_line = |x: DVec3| (x - p - (x - p).dot(line) * line).length();
            if b != a
                && segment_distance(mid, p, q) <= tol
                && off_line(s.a) <= tol
                && off_line(s.b) <= tol
            {
                sharing.push(b);
            }
        });
        sharing.sort_unstable();
        sharing.dedup();
        sharing.insert(0, a);
        sharing
    }
}

/// A vertex side to evaluate on a contact line: `None` for the vertex
/// itself (its first side), or the (triangle, corner) slots that move to a
/// new copy; the vertex; and a point inside the side's first triangle to
/// nudge towards.
pub(super) type SideCopy = (Option<Vec<(usize, usize)>>, u32, DVec3);

/// Finds the vertices of `tri` on the contact lines `contacts` and groups
/// their triangles into sides: two triangles around a vertex are on one
/// side when they share an edge that is not on a contact line. The first
/// side keeps the vertex, each other side gets a copy (its slots in the
/// triangle list are listed for renumbering by the caller).
pub(super) fn split_contact_vertices(
    tri: &PatchTriangulation,
    contacts: &[Segment],
    tol: f64,
) -> Vec<SideCopy> {
    if contacts.is_empty() {
        return Vec::new();
    }
    let on_contact = |x: DVec3| {
        contacts
            .iter()
            .any(|s| segment_distance(x, s.a, s.b) <= tol)
    };
    let contact_edges: HashSet<[u32; 2]> = tri
        .constrained_edges
        .iter()
        .filter(|e| e.iter().all(|&i| on_contact(tri.positions[i as usize])))
        .map(|&[a, b]| [a.min(b), a.max(b)])
        .collect();
    if contact_edges.is_empty() {
        return Vec::new();
    }
    let mut around: HashMap<u32, Vec<usize>> = HashMap::new();
    for (t, corners) in tri.triangles.iter().enumerate() {
        for &v in corners {
            around.entry(v).or_default().push(t);
        }
    }
    let mut on_line: Vec<u32> = contact_edges.iter().flatten().copied().collect();
    on_line.sort_unstable();
    on_line.dedup();
    let mut out = Vec::new();
    for v in on_line {
        let sides = sides_around(tri, v, &around[&v], &contact_edges);
        for (k, members) in sides.into_iter().enumerate() {
            let first = tri.triangles[members[0]];
            let towards = first
                .iter()
                .map(|&i| tri.positions[i as usize])
                .sum::<DVec3>()
                / 3.0;
            let slots = (k > 0).then(|| {
                members
                    .iter()
                    .map(|&t| {
                        let corner = tri.triangles[t].iter().position(|&i| i == v).unwrap_or(0);
                        (t, corner)
                    })
                    .collect()
            });
            out.push((slots, v, towards));
        }
    }
    out
}

/// The triangles `ts` around vertex `v` grouped into sides (disjoint sets
/// joined across edges not in `contact_edges`), each side's triangles in
/// the order of `ts`, sides in the order of their first triangle.
fn sides_around(
    tri: &PatchTriangulation,
    v: u32,
    ts: &[usize],
    contact_edges: &HashSet<[u32; 2]>,
) -> Vec<Vec<usize>> {
    let mut sides_of = UnionFind::new(ts.len());
    for i in 0..ts.len() {
        for j in i + 1..ts.len() {
            let (a, b) = (tri.triangles[ts[i]], tri.triangles[ts[j]]);
            let joined = a.iter().any(|&w| {
                w != v && b.contains(&w) && !contact_edges.contains(&[v.min(w), v.max(w)])
            });
            if joined {
                sides_of.union(i, j);
            }
        }
    }
    let mut sides: Vec<(usize, Vec<usize>)> = Vec::new();
    for i in 0..ts.len() {
        let r = sides_of.find(i);
        match sides.iter_mut().find(|(root, _)| *root == r) {
            Some((_, members)) => members.push(ts[i]),
            None => sides.push((r, vec![ts[i]])),
        }
    }
    sides.into_iter().map(|(_, members)| members).collect()
}

/// The value of each side in `copies` of patch `p`'s vertices: evaluated
/// `nudge` off the vertex towards the side's triangle (at most
/// [`MAX_NUDGE_FRACTION`] of the way), with every link casting its own rays.
pub(super) fn side_values(
    points: &PointEvaluator,
    p: usize,
    tri: &PatchTriangulation,
    copies: &[SideCopy],
    nudge: f64,
) -> Vec<PointLight> {
    copies
        .par_iter()
        .map(|(_, v, towards)| {
            // Off the line by more than the rays' endpoint gap, so that
            // the occluder standing there blocks them.
            let x = tri.positions[*v as usize];
            let d = *towards - x;
            points.value(
                p,
                x + d * (nudge / d.length()).min(MAX_NUDGE_FRACTION),
                LinkRays::Every,
            )
        })
        .collect()
}
