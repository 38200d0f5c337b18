//! The occluder edge graph: every scene triangle is an occluder, its
//! vertices welded by exact position and its edges shared between the
//! triangles that use them.
//!
//! Owns: [`Occluders`] (vertices, the triangles at each vertex, edges),
//! [`Edge`] and [`third`].
//!
//! Invariants:
//! - Vertices are numbered in order of first appearance in
//!   `scene.triangles`, edges in order of first use; each edge is stored
//!   once, with `a < b`, and lists its triangles in scene order.
//! - Welding is exact ([`position_key`]): positions that differ in any bit
//!   (other than the sign of zero) are different vertices.
//! - An edge is `flat` only when exactly two coplanar triangles share it and
//!   lie on opposite sides of it; a flat edge is never a silhouette and never
//!   a contact line.

use std::collections::HashMap;

use glam::DVec3;

use crate::scene::{Scene, polygon_area_normal};
use crate::util::geometry::{PositionKey, line_distance, position_key};

/// An edge of the welded occluder graph.
pub(super) struct Edge {
    /// The lower vertex index.
    pub(super) a: u32,
    /// The higher vertex index.
    pub(super) b: u32,
    /// Triangles (indices into `scene.triangles`) on this edge.
    pub(super) triangles: Vec<u32>,
    /// Shared by exactly two coplanar triangles that continue each other:
    /// never a silhouette.
    pub(super) flat: bool,
}

/// The welded vertices and edges of all scene triangles.
pub(super) struct Occluders {
    pub(super) vertices: Vec<DVec3>,
    /// Triangles touching each vertex.
    pub(super) vertex_triangles: Vec<Vec<u32>>,
    pub(super) edges: Vec<Edge>,
}

impl Occluders {
    /// Welds the triangles of `scene` and marks the flat edges, coplanar
    /// within `tol` (a length).
    pub(super) fn weld(scene: &Scene, tol: f64) -> Occluders {
        let (vertices, vertex_triangles, tri_vertices) = weld_vertices(scene);
        let mut edges = shared_edges(&tri_vertices);
        for e in &mut edges {
            e.flat = is_flat(e, &vertices, scene, tol);
        }
        Occluders {
            vertices,
            vertex_triangles,
            edges,
        }
    }

    /// The positions of the two ends of `e`.
    pub(super) fn ends(&self, e: &Edge) -> (DVec3, DVec3) {
        (self.vertices[e.a as usize], self.vertices[e.b as usize])
    }
}

/// Welds vertices by exact position, in order of first appearance: the
/// positions, the triangles at each, and each triangle's three indices.
fn weld_vertices(scene: &Scene) -> (Vec<DVec3>, Vec<Vec<u32>>, Vec<[u32; 3]>) {
    let mut ids: HashMap<PositionKey, u32> = HashMap::new();
    let mut vertices = Vec::new();
    let mut vertex_triangles: Vec<Vec<u32>> = Vec::new();
    let mut tri_vertices = Vec::with_capacity(scene.triangles.len());
    for (t, tri) in scene.triangles.iter().enumerate() {
        let v = tri.positions.map(|p| {
            *ids.entry(position_key(p)).or_insert_with(|| {
                vertices.push(p);
                vertex_triangles.push(Vec::new());
                (vertices.len() - 1) as u32
            })
        });
        for &i in &v {
            let list = &mut vertex_triangles[i as usize];
            if list.last() != Some(&(t as u32)) {
                list.push(t as u32);
            }
        }
        tri_vertices.push(v);
    }
    (vertices, vertex_triangles, tri_vertices)
}

/// The edges of the welded triangles, each once, in order of first use;
/// edges collapsed by welding (both ends one vertex) are skipped.
fn shared_edges(tri_vertices: &[[u32; 3]]) -> Vec<Edge> {
    let mut edge_ids: HashMap<(u32, u32), usize> = HashMap::new();
    let mut edges: Vec<Edge> = Vec::new();
    for (t, v) in tri_vertices.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (v[e], v[(e + 1) % 3]);
            if a == b {
                continue;
            }
            let k = (a.min(b), a.max(b));
            let id = *edge_ids.entry(k).or_insert_with(|| {
                edges.push(Edge {
                    a: k.0,
                    b: k.1,
                    triangles: Vec::new(),
                    flat: false,
                });
                edges.len() - 1
            });
            edges[id].triangles.push(t as u32);
        }
    }
    edges
}

/// True when exactly two triangles share `e`, coplanar within `tol`, and lie
/// on opposite sides of it.
fn is_flat(e: &Edge, vertices: &[DVec3], scene: &Scene, tol: f64) -> bool {
    let [t1, t2] = e.triangles[..] else {
        return false;
    };
    let (pa, pb) = (vertices[e.a as usize], vertices[e.b as usize]);
    let (_, n1) = polygon_area_normal(&scene.triangles[t1 as usize].positions);
    let c1 = third(&scene.triangles[t1 as usize].positions, pa, pb);
    let c2 = third(&scene.triangles[t2 as usize].positions, pa, pb);
    // Coplanar, and the triangles lie on opposite sides of the edge.
    let along = (pb - pa).normalize_or_zero();
    let side = n1.cross(along);
    (c2 - pa).dot(n1).abs() <= tol && (c1 - pa).dot(side) * (c2 - pa).dot(side) < 0.0
}

/// The triangle vertex that is neither `a` nor `b` (the farthest from the
/// edge line, which is robust to welding).
pub(super) fn third(t: &[DVec3; 3], a: DVec3, b: DVec3) -> DVec3 {
    let mut best = t[0];
    let mut far = -1.0;
    for &p in t {
        let d = line_distance(a, b, p);
        if d > far {
            far = d;
            best = p;
        }
    }
    best
}
