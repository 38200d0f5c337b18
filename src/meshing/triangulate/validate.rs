//! The validator of a triangulation of a scene: [`validate_patch_mesh`]
//! checks, independently of how the mesh was made, the invariants the
//! module doc of [`super`] promises.
//!
//! Per patch: vertices finite, distinct and in the plane; triangles valid,
//! counter-clockwise and not degenerate, no directed edge used twice; edges
//! with one triangle on the patch boundary; areas summing to the patch
//! area; input segments covered by mesh edges and input points being
//! vertices. Across patches: every boundary edge overlapping a collinear
//! edge of another patch has a bit-identical twin there.
//!
//! Invariants: it only reads; within a patch the checks run in the order
//! above and stop at the first violation; the twin check runs only when
//! every patch passes, over the edge pairs in sorted order. (Patches are
//! checked in parallel: with several failing patches, which one is
//! reported is not fixed.)

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use rayon::prelude::*;

use super::frame::Polygon;
use super::grid::{EdgeRef, edge_grid};
use super::{CORNER, PatchInput, PatchTriangulation};
use crate::scene::{Patch, Scene};
use crate::util::geometry::{PositionKey, position_key, segment_distance};

/// A triangle's height (twice its area over its longest side) must exceed
/// this many weld radii.
const MIN_HEIGHT: f64 = 1e-3;

/// Largest difference between the triangles' area sum and the patch area,
/// relative to the latter (plus what the boundary vertices' deviation from
/// the edges explains).
const AREA: f64 = 1e-9;

/// Validation tolerance of a patch: a few weld radii.
fn check_tolerance(shape: &Polygon) -> f64 {
    2.0 * CORNER * shape.eps
}

/// An undirected edge by the bit patterns of its ends.
type EdgeKey = (PositionKey, PositionKey);

fn edge_key(a: DVec3, b: DVec3) -> EdgeKey {
    let (ka, kb) = (position_key(a), position_key(b));
    if ka <= kb { (ka, kb) } else { (kb, ka) }
}

/// Checks the invariants of the module doc of [`super`] on a triangulation
/// of `scene` made from `inputs`: per patch, edges are shared by two
/// triangles or lie on the patch boundary; triangles are counter-clockwise
/// around the patch normal, not degenerate, and their areas sum to the patch
/// area; each clipped input segment is a union of mesh edges and each input
/// point inside the patch is a vertex. Across patches, every boundary edge
/// overlapping a collinear edge of another patch has a bit-identical twin
/// there. Returns the first violation found.
pub fn validate_patch_mesh(
    scene: &Scene,
    tris: &[PatchTriangulation],
    inputs: &[PatchInput],
) -> Result<(), String> {
    let np = scene.patches.len();
    if tris.len() != np || inputs.len() != np {
        return Err(format!(
            "{} triangulations and {} inputs for {np} patches",
            tris.len(),
            inputs.len()
        ));
    }
    let diagonal = scene.diagonal();
    let shapes: Vec<Polygon> = scene
        .patches
        .iter()
        .map(|p| Polygon::new(p, diagonal))
        .collect();
    let boundaries: Vec<Vec<BoundaryEdge>> = (0..np)
        .into_par_iter()
        .map(|i| check_patch(i, &scene.patches[i], &shapes[i], &tris[i], &inputs[i]))
        .collect::<Result<_, String>>()?;
    check_twins(&shapes, tris, &boundaries, diagonal)
}

/// A boundary edge of a patch mesh: the polygon edge it lies on, and its
/// ends.
type BoundaryEdge = (usize, [u32; 2]);

/// The directed edges of a patch mesh, with their use counts.
type Directed = HashMap<(u32, u32), u32>;

/// The checks of one patch; returns its boundary edges with the polygon
/// edge each lies on.
fn check_patch(
    i: usize,
    patch: &Patch,
    shape: &Polygon,
    mesh: &PatchTriangulation,
    input: &PatchInput,
) -> Result<Vec<BoundaryEdge>, String> {
    let check = PatchCheck {
        i,
        patch,
        shape,
        mesh,
        tol: check_tolerance(shape),
    };
    check.vertices()?;
    let (directed, area) = check.triangles()?;
    let mut sorted: Vec<_> = directed.keys().copied().collect();
    sorted.sort_unstable();
    let (boundary, deviation) = check.boundary_edges(&directed, &sorted)?;
    check.area(area, deviation)?;
    check.segments_covered(input, &directed, &sorted)?;
    check.points_are_vertices(input)?;
    Ok(boundary)
}

/// One patch's mesh under check.
struct PatchCheck<'a> {
    /// The patch index, for the messages.
    i: usize,
    patch: &'a Patch,
    shape: &'a Polygon,
    mesh: &'a PatchTriangulation,
    /// [`check_tolerance`] of the patch.
    tol: f64,
}

impl PatchCheck<'_> {
    /// Vertices are finite, pairwise distinct (bit for bit) and in the
    /// plane.
    fn vertices(&self) -> Result<(), String> {
        let i = self.i;
        let mut seen = HashSet::new();
        for (k, &p) in self.mesh.positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(format!("patch {i}: vertex {k} is not finite"));
            }
            if !seen.insert(position_key(p)) {
                return Err(format!("patch {i}: vertex {k} duplicates another vertex"));
            }
            if (p - self.shape.corners[0]).dot(self.patch.normal).abs() > self.tol {
                return Err(format!("patch {i}: vertex {k} is off the patch plane"));
            }
        }
        Ok(())
    }

    /// Triangles exist, index real vertices, are counter-clockwise seen
    /// from the front and not degenerate, and use each directed edge once.
    /// Returns the directed edges and the area sum.
    fn triangles(&self) -> Result<(Directed, f64), String> {
        let i = self.i;
        let pos = &self.mesh.positions;
        let nv = pos.len();
        if self.mesh.triangles.is_empty() {
            return Err(format!("patch {i}: no triangles"));
        }
        let mut directed: Directed = HashMap::new();
        let mut area = 0.0;
        for (t, tri) in self.mesh.triangles.iter().enumerate() {
            if tri.iter().any(|&v| v as usize >= nv) {
                return Err(format!("patch {i}: triangle {t} indexes a missing vertex"));
            }
            let [a, b, c] = tri.map(|v| pos[v as usize]);
            let twice = (b - a).cross(c - a).dot(self.patch.normal);
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            if !(twice > 0.0) {
                return Err(format!(
                    "patch {i}: triangle {t} is clockwise or degenerate seen from the front"
                ));
            }
            if !(twice / longest > MIN_HEIGHT * self.shape.eps) {
                return Err(format!("patch {i}: triangle {t} is degenerate"));
            }
            area += 0.5 * twice;
            for e in 0..3 {
                let key = (tri[e], tri[(e + 1) % 3]);
                let count = directed.entry(key).or_insert(0);
                *count += 1;
                if *count > 1 {
                    return Err(format!(
                        "patch {i}: edge {key:?} is used twice in the same direction"
                    ));
                }
            }
        }
        Ok((directed, area))
    }

    /// The edges with one triangle (in `sorted` order), each on a polygon
    /// edge; returns them with that edge's index, and their ends' largest
    /// distance from it.
    fn boundary_edges(
        &self,
        directed: &Directed,
        sorted: &[(u32, u32)],
    ) -> Result<(Vec<BoundaryEdge>, f64), String> {
        let (i, shape, tol) = (self.i, self.shape, self.tol);
        let pos = &self.mesh.positions;
        let n = shape.n();
        let mut boundary = Vec::new();
        let mut deviation = 0.0f64;
        for &(a, b) in sorted {
            if directed.contains_key(&(b, a)) {
                continue;
            }
            let (pa, pb) = (pos[a as usize], pos[b as usize]);
            let on = (0..n).find(|&k| {
                let (c, d) = (shape.corners[k], shape.corners[(k + 1) % n]);
                segment_distance(pa, c, d) <= tol && segment_distance(pb, c, d) <= tol
            });
            let Some(k) = on else {
                return Err(format!(
                    "patch {i}: edge ({a}, {b}) has one triangle but is not on the patch boundary"
                ));
            };
            let (c, d) = (shape.corners[k], shape.corners[(k + 1) % n]);
            deviation = deviation
                .max(segment_distance(pa, c, d))
                .max(segment_distance(pb, c, d));
            boundary.push((k, [a, b]));
        }
        Ok((boundary, deviation))
    }

    /// The triangles' `area` sum is the patch area, to within [`AREA`] and
    /// what the boundary vertices' `deviation` from the edges explains.
    fn area(&self, area: f64, deviation: f64) -> Result<(), String> {
        let (shape, patch) = (self.shape, self.patch);
        let n = shape.n();
        let perimeter: f64 = (0..n)
            .map(|k| (shape.corners[(k + 1) % n] - shape.corners[k]).length())
            .sum();
        if !((area - patch.area).abs() <= AREA * patch.area + perimeter * deviation) {
            return Err(format!(
                "patch {}: triangle areas sum to {area}, the patch has {}",
                self.i, patch.area
            ));
        }
        Ok(())
    }

    /// Every clipped input segment is covered by collinear mesh edges.
    fn segments_covered(
        &self,
        input: &PatchInput,
        directed: &Directed,
        sorted: &[(u32, u32)],
    ) -> Result<(), String> {
        let (shape, tol) = (self.shape, self.tol);
        let pos = &self.mesh.positions;
        for (s, seg) in input.segments.iter().enumerate() {
            let (p, q) = (shape.frame.project(seg[0]), shape.frame.project(seg[1]));
            let Some((p, q)) = shape.clip(p, q) else {
                continue;
            };
            let (p, q) = (shape.frame.lift(p), shape.frame.lift(q));
            let len = (q - p).length();
            if len <= 2.0 * tol {
                continue;
            }
            let dir = (q - p) / len;
            let off = |x: DVec3| (x - p - dir * (x - p).dot(dir)).length();
            let mut spans: Vec<(f64, f64)> = sorted
                .iter()
                .filter(|&&(a, b)| a < b || !directed.contains_key(&(b, a)))
                .filter_map(|&(a, b)| {
                    let (pa, pb) = (pos[a as usize], pos[b as usize]);
                    if off(pa) > tol || off(pb) > tol {
                        return None;
                    }
                    let (ta, tb) = ((pa - p).dot(dir), (pb - p).dot(dir));
                    Some((ta.min(tb), ta.max(tb)))
                })
                .collect();
            spans.sort_by(|x, y| x.0.total_cmp(&y.0));
            let mut reach = 0.0f64;
            for (lo, hi) in spans {
                if lo <= reach + tol {
                    reach = reach.max(hi);
                }
            }
            if reach < len - tol {
                return Err(format!(
                    "patch {}: segment {s} is covered by mesh edges only up to {reach} of {len}",
                    self.i
                ));
            }
        }
        Ok(())
    }

    /// Every input point inside the patch is a vertex.
    fn points_are_vertices(&self, input: &PatchInput) -> Result<(), String> {
        let shape = self.shape;
        for (k, &p) in input.points.iter().enumerate() {
            let q = shape.frame.project(p);
            if shape.classify(q).is_none() {
                continue;
            }
            let x = shape.frame.lift(q);
            if !self
                .mesh
                .positions
                .iter()
                .any(|&v| (v - x).length() <= self.tol)
            {
                return Err(format!("patch {}: point {k} is not a mesh vertex", self.i));
            }
        }
        Ok(())
    }
}

/// Twins across collinearly overlapping patch edges: every boundary edge of
/// a patch that overlaps another patch's edge (within the tolerance, by
/// more than it) is a boundary edge of that patch too, bit for bit.
fn check_twins(
    shapes: &[Polygon],
    tris: &[PatchTriangulation],
    boundaries: &[Vec<BoundaryEdge>],
    diagonal: f64,
) -> Result<(), String> {
    let mut keys: HashSet<(usize, EdgeKey)> = HashSet::new();
    for (i, b) in boundaries.iter().enumerate() {
        for &(_, [u, v]) in b {
            let pos = &tris[i].positions;
            keys.insert((i, edge_key(pos[u as usize], pos[v as usize])));
        }
    }
    let mut edges: Vec<EdgeRef> = Vec::new();
    for (p, s) in shapes.iter().enumerate() {
        for k in 0..s.n() {
            edges.push((p as u32, k, s.corners[k], s.corners[(k + 1) % s.n()]));
        }
    }
    let r = shapes.iter().map(check_tolerance).fold(0.0, f64::max);
    for (e, f) in near_edge_pairs(&edges, r, diagonal) {
        let (pe, ke, _, _) = edges[e];
        let (pf, _, fa, fb) = edges[f];
        let tol = check_tolerance(&shapes[pe as usize]).max(check_tolerance(&shapes[pf as usize]));
        let len = (fb - fa).length();
        let dir = (fb - fa) / len;
        let off = |x: DVec3| (x - fa - dir * (x - fa).dot(dir)).length();
        let pos = &tris[pe as usize].positions;
        for &(k, [u, v]) in &boundaries[pe as usize] {
            if k != ke {
                continue;
            }
            let (a, b) = (pos[u as usize], pos[v as usize]);
            if off(a) > tol || off(b) > tol {
                continue;
            }
            let (ta, tb) = ((a - fa).dot(dir), (b - fa).dot(dir));
            let overlap = ta.max(tb).min(len) - ta.min(tb).max(0.0);
            if overlap > tol && !keys.contains(&(pf as usize, edge_key(a, b))) {
                return Err(format!(
                    "patch {pe}: boundary edge {a}–{b} has no twin in patch {pf} (crack or T-vertex)"
                ));
            }
        }
    }
    Ok(())
}

/// The pairs of edges of different patches where an end of one lies in a
/// grid cell near the other (within `r`), both ways round, sorted.
fn near_edge_pairs(edges: &[EdgeRef], r: f64, diagonal: f64) -> Vec<(usize, usize)> {
    let grid = edge_grid(edges, diagonal);
    let mut pairs = HashSet::new();
    let mut near = Vec::new();
    for (e, edge) in edges.iter().enumerate() {
        for end in [edge.2, edge.3] {
            grid.query(end, r, &mut near);
            for &f in &near {
                let other = &edges[f as usize];
                if other.0 == edge.0 {
                    continue;
                }
                pairs.insert((e, f as usize));
                pairs.insert((f as usize, e));
            }
        }
    }
    let mut pairs: Vec<(usize, usize)> = pairs.into_iter().collect();
    pairs.sort_unstable();
    pairs
}
