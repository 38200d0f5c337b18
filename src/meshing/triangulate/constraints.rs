//! What one patch's constrained Delaunay triangulation is made from, before
//! spade sees it: the welded vertex set, the boundary chain and the
//! constraint pieces ([`PatchConstraints`]).
//!
//! The steps, in this order (vertex ids are given in the same order):
//! 1. the boundary chain: each corner followed by the canonical points on
//!    its edge, from the [`Connection`];
//! 2. the interior points, welded;
//! 3. the segment ends, welded; segments along the boundary are dropped,
//!    the rest deduplicated as unordered pairs;
//! 4. proper crossings of two segments become vertices;
//! 5. every segment is split at each vertex lying on it, into pieces.
//!
//! Invariants: chain vertices keep their canonical positions, one vertex
//! per canonical id; every later vertex is made by welding, so it lies
//! farther than the weld radius from every vertex made before it; no piece
//! joins two vertices on a common polygon edge (the chain has those edges);
//! pieces are sorted unordered pairs without repeats, and two segments
//! crossing away from their ends meet at a shared vertex.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::frame::{End, Frame2, LocalPatch};
use super::grid::Grid2;
use super::weld::Connection;

/// Two segments are parallel when the sine of their angle is below this.
const PARALLEL: f64 = 1e-14;

/// A vertex of the patch being meshed.
#[derive(Clone, Copy, Debug)]
pub(super) struct Vtx {
    /// In the patch frame.
    pub(super) p2: DVec2,
    /// In world space (canonical for chain vertices).
    pub(super) p3: DVec3,
    /// Bit k set: lies on polygon edge k.
    edges: u8,
}

/// The vertex set of one patch under construction, welded as it grows.
pub(super) struct VertexSet {
    pub(super) verts: Vec<Vtx>,
    grid: Grid2,
    eps: f64,
}

impl VertexSet {
    /// An empty set for `local`, its grid sized for the expected number of
    /// vertices.
    fn for_patch(local: &LocalPatch) -> VertexSet {
        let shape = &local.shape;
        let (eps, n) = (shape.eps, shape.n());
        let extent = shape
            .poly
            .iter()
            .fold(0.0f64, |m, p| m.max(p.length()))
            .max(eps);
        let expected = (n + local.interior.len() + 2 * local.segments.len()).max(1) as f64;
        VertexSet {
            verts: Vec::new(),
            grid: Grid2::new((2.0 * extent / expected.sqrt()).max(4.0 * eps)),
            eps,
        }
    }

    fn push(&mut self, v: Vtx) -> u32 {
        let id = self.verts.len() as u32;
        self.grid.insert(v.p2, id);
        self.verts.push(v);
        id
    }

    /// The existing vertex within the weld radius of q, else a new one.
    fn weld(&mut self, q: DVec2, frame: &Frame2) -> u32 {
        let mut near = Vec::new();
        let r = DVec2::splat(self.eps);
        self.grid.query_box(q - r, q + r, &mut near);
        let best = near
            .iter()
            .map(|&i| ((self.verts[i as usize].p2 - q).length(), i))
            .filter(|&(d, _)| d <= self.eps)
            .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        match best {
            Some((_, i)) => i,
            None => self.push(Vtx {
                p2: q,
                p3: frame.lift(q),
                edges: 0,
            }),
        }
    }

    /// Whether a and b lie on a common polygon edge.
    fn along_boundary(&self, a: u32, b: u32) -> bool {
        self.verts[a as usize].edges & self.verts[b as usize].edges != 0
    }

    fn p2(&self, v: u32) -> DVec2 {
        self.verts[v as usize].p2
    }
}

/// The input of one patch's CDT.
pub(super) struct PatchConstraints {
    pub(super) set: VertexSet,
    /// The boundary polygon as vertex ids, counter-clockwise.
    pub(super) chain: Vec<u32>,
    /// Constraint edges inside the patch.
    pub(super) pieces: Vec<[u32; 2]>,
}

impl PatchConstraints {
    /// The vertices and constraints of patch `index` (steps 1–5 of the
    /// module doc).
    pub(super) fn build(index: usize, local: &LocalPatch, conn: &Connection) -> PatchConstraints {
        let mut set = VertexSet::for_patch(local);
        let (chain, local_of) = boundary_chain(&mut set, index, local, conn);
        let frame = local.shape.frame;
        let interior: Vec<u32> = local
            .interior
            .iter()
            .map(|&q| set.weld(q, &frame))
            .collect();
        let ends = Ends {
            index,
            conn,
            frame,
            local_of: &local_of,
            interior: &interior,
        };
        let segments = segment_edges(&mut set, local, &ends);
        weld_crossings(&mut set, &segments, &frame);
        let pieces = split_at_vertices(&set, &segments);
        PatchConstraints { set, chain, pieces }
    }
}

/// The boundary chain: each corner followed by its edge's points, as new
/// vertices of `set`. Returns the chain and the vertex of each canonical id
/// on it.
fn boundary_chain(
    set: &mut VertexSet,
    index: usize,
    local: &LocalPatch,
    conn: &Connection,
) -> (Vec<u32>, HashMap<u32, u32>) {
    let (frame, n) = (local.shape.frame, local.shape.n());
    let corners = &conn.corners[index];
    let mut local_of: HashMap<u32, u32> = HashMap::new();
    let mut chain: Vec<u32> = Vec::new();
    for k in 0..n {
        let ids = std::iter::once(corners[k]).chain(conn.edges[index][k].iter().copied());
        for (j, c) in ids.enumerate() {
            if local_of.contains_key(&c) {
                continue;
            }
            let p3 = conn.points[c as usize];
            let edges = if j == 0 {
                (1u8 << k) | (1u8 << ((k + n - 1) % n))
            } else {
                1u8 << k
            };
            let id = set.push(Vtx {
                p2: frame.project(p3),
                p3,
                edges,
            });
            local_of.insert(c, id);
            chain.push(id);
        }
    }
    (chain, local_of)
}

/// Where a segment end of one patch finds its vertex.
struct Ends<'a> {
    index: usize,
    conn: &'a Connection,
    frame: Frame2,
    /// Chain vertex of each canonical id.
    local_of: &'a HashMap<u32, u32>,
    /// Vertex of each interior point.
    interior: &'a [u32],
}

impl Ends<'_> {
    /// The vertex of segment end `e`: a chain vertex for corners and
    /// boundary points on the chain, else the welded canonical position.
    fn vertex(&self, set: &mut VertexSet, e: End) -> u32 {
        match e {
            End::Corner(k) => self.local_of[&self.conn.corners[self.index][k]],
            End::Boundary(b) => {
                let c = self.conn.boundary[self.index][b];
                match self.local_of.get(&c) {
                    Some(&v) => v,
                    None => set.weld(
                        self.frame.project(self.conn.points[c as usize]),
                        &self.frame,
                    ),
                }
            }
            End::Interior(i) => self.interior[i],
        }
    }
}

/// The segments of `local` as sorted vertex pairs, without repeats and
/// without those along the boundary.
fn segment_edges(set: &mut VertexSet, local: &LocalPatch, ends: &Ends) -> Vec<[u32; 2]> {
    let mut segments: Vec<[u32; 2]> = Vec::new();
    for s in &local.segments {
        let (a, b) = (ends.vertex(set, s[0]), ends.vertex(set, s[1]));
        if a != b && !set.along_boundary(a, b) {
            segments.push([a.min(b), a.max(b)]);
        }
    }
    segments.sort_unstable();
    segments.dedup();
    segments
}

/// Proper crossing point of segments a–b and c–d, if any.
fn crossing(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> Option<DVec2> {
    let (r, s) = (b - a, d - c);
    let denom = r.perp_dot(s);
    if !(denom.abs() > PARALLEL * r.length() * s.length()) {
        return None;
    }
    let t = (c - a).perp_dot(s) / denom;
    let u = (c - a).perp_dot(r) / denom;
    (t > 0.0 && t < 1.0 && u > 0.0 && u < 1.0).then(|| a + t * r)
}

/// Every proper crossing of two segments farther than the weld radius from
/// their ends becomes a (welded) vertex.
fn weld_crossings(set: &mut VertexSet, segments: &[[u32; 2]], frame: &Frame2) {
    let eps = set.eps;
    for i in 0..segments.len() {
        for j in i + 1..segments.len() {
            let [a, b] = segments[i];
            let [c, d] = segments[j];
            if a == c || a == d || b == c || b == d {
                continue;
            }
            let (pa, pb, pc, pd) = (set.p2(a), set.p2(b), set.p2(c), set.p2(d));
            let (lo1, hi1) = (pa.min(pb), pa.max(pb));
            let (lo2, hi2) = (pc.min(pd), pc.max(pd));
            if lo1.x > hi2.x || lo2.x > hi1.x || lo1.y > hi2.y || lo2.y > hi1.y {
                continue;
            }
            if let Some(x) = crossing(pa, pb, pc, pd)
                && [pa, pb, pc, pd].iter().all(|&q| (q - x).length() > eps)
            {
                set.weld(x, frame);
            }
        }
    }
}

/// Every segment split at each vertex within the weld radius of it, into
/// sorted pairs without repeats (pieces along the boundary dropped).
fn split_at_vertices(set: &VertexSet, segments: &[[u32; 2]]) -> Vec<[u32; 2]> {
    let eps = set.eps;
    let mut pieces: Vec<[u32; 2]> = Vec::new();
    let mut near = Vec::new();
    for &[a, b] in segments {
        let (pa, pb) = (set.p2(a), set.p2(b));
        let ab = pb - pa;
        set.grid.query_segment(pa, pb, eps, &mut near);
        let mut on: Vec<(f64, u32)> = near
            .iter()
            .filter(|&&v| v != a && v != b)
            .filter_map(|&v| {
                let q = set.p2(v);
                let t = (q - pa).dot(ab) / ab.length_squared();
                let off = (pa + t * ab - q).length();
                (t > 0.0 && t < 1.0 && off <= eps).then_some((t, v))
            })
            .collect();
        on.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let mut prev = a;
        for v in on.into_iter().map(|x| x.1).chain([b]) {
            if v != prev && !set.along_boundary(prev, v) {
                pieces.push([prev.min(v), prev.max(v)]);
            }
            prev = v;
        }
    }
    pieces.sort_unstable();
    pieces.dedup();
    pieces
}
