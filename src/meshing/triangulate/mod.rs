//! Crack-free constrained triangulation of every patch of a [`Scene`].
//!
//! Owns: turning each patch polygon, plus extra points and constraint
//! segments lying in its plane, into triangles, such that neighbouring
//! patches agree vertex for vertex along the edges they share; and the
//! validator [`validate_patch_mesh`] that checks exactly that. spade's
//! constrained Delaunay triangulation is used here and nowhere else.
//!
//! The pipeline:
//!
//! ```text
//!  per patch (parallel)        global (sequential, hashed)       per patch (parallel)
//!  ┌───────────────────┐   ┌──────────────────────────────┐   ┌────────────────────────┐
//!  │ 2D frame, classify│   │ weld corners + boundary pts  │   │ chain = corners + edge │
//!  │ points, clip segs │──▶│ (canonical f64 positions);   │──▶│ lists; split crossings;│
//!  │ to the polygon    │   │ each canonical point goes to │   │ CDT; keep faces inside │
//!  └───────────────────┘   │ every patch edge it lies on  │   │ the chain (flood fill) │
//!                          └──────────────────────────────┘   └────────────────────────┘
//! ```
//!
//! With refinement the three steps run twice: the first run refines each
//! patch alone and harvests its Steiner points; the second run treats them as
//! ordinary input points (so Steiner points on a patch edge reach the
//! neighbours too) and does not refine.
//!
//! Invariants of the result:
//! - every vertex on a patch's boundary has one canonical f64 position shared
//!   bit for bit by every patch whose edge passes through it, so every
//!   boundary edge has a twin in each collinearly overlapping neighbour edge
//!   (no cracks, no T-vertices);
//! - triangles are counter-clockwise seen from the patch front and tile the
//!   patch (their areas sum to the patch area);
//! - every input segment, clipped to the patch and split at crossings, is a
//!   union of mesh edges;
//! - no panic escapes: spade is guarded (points welded, segments deduplicated
//!   as unordered pairs and split at their crossings before insertion, its
//!   splitting and refinement calls isolated with `catch_unwind`).
//!
//! Tolerances are relative: the weld radius of a patch is `1e-7 ×` the scene
//! diagonal, reduced to 1 % of the patch's width for thin patches; points
//! within 2 weld radii of an edge go on it, boundary points within 8 of a
//! corner become that corner.
//!
//! Refinement runs inside a frame of four extra vertices around the patch:
//! rounding leaves boundary points a hair inside the hull, and spade would
//! keep splitting the hull edges of those slivers. Steiner points outside the
//! patch are dropped; ones on its edges are shared like any boundary point.

use std::collections::{HashMap, HashSet};
use std::panic::{AssertUnwindSafe, catch_unwind};

use glam::{DVec2, DVec3};
use rayon::prelude::*;
use spade::handles::FixedVertexHandle;
use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, HasPosition, Point2, RefinementParameters,
    Triangulation,
};

use crate::error::{Error, Result};
use crate::scene::{Patch, Scene};

/// Extra input of one patch: points to become vertices and segments to
/// become chains of edges. Both are in world space and meant to lie in the
/// patch plane (they are projected onto it); anything outside the patch is
/// clipped away.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PatchInput {
    pub points: Vec<DVec3>,
    pub segments: Vec<[DVec3; 2]>,
}

/// Quality refinement settings.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangulateOptions {
    /// Refine towards this smallest angle (degrees, in (0, 34]); `None`
    /// keeps the plain constrained Delaunay triangulation.
    pub min_angle_deg: Option<f64>,
    /// Most Steiner points refinement may add to one patch.
    pub max_added_vertices: usize,
}

impl Default for TriangulateOptions {
    fn default() -> Self {
        TriangulateOptions {
            min_angle_deg: None,
            max_added_vertices: 1000,
        }
    }
}

impl TriangulateOptions {
    /// Refinement towards 25° with at most 1000 Steiner points per patch.
    pub fn refined() -> Self {
        TriangulateOptions {
            min_angle_deg: Some(25.0),
            max_added_vertices: 1000,
        }
    }
}

/// The triangulation of one patch, in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PatchTriangulation {
    pub positions: Vec<DVec3>,
    /// Counter-clockwise seen from the patch front.
    pub triangles: Vec<[u32; 3]>,
    /// Edges of the (clipped, split) input segments inside the patch.
    pub constrained_edges: Vec<[u32; 2]>,
    /// Edges along the patch boundary, counter-clockwise.
    pub boundary_edges: Vec<[u32; 2]>,
}

/// Weld radius relative to the scene diagonal.
const WELD: f64 = 1e-7;
/// Largest weld radius relative to a patch's width.
const THIN: f64 = 1e-2;
/// A point within this many weld radii of a patch edge is put on it.
const ON_EDGE: f64 = 2.0;
/// A boundary point within this many weld radii of a corner becomes the
/// corner: near a corner, a point would be close to both edges' lines.
const CORNER: f64 = 8.0;

/// The weld radius of a patch.
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
struct Frame2 {
    origin: DVec3,
    u: DVec3,
    v: DVec3,
}

impl Frame2 {
    fn of(patch: &Patch) -> Frame2 {
        let c = patch.vertices();
        let u = (c[1] - c[0]).normalize_or_zero();
        Frame2 {
            origin: c[0],
            u,
            v: patch.normal.cross(u),
        }
    }
    fn project(&self, p: DVec3) -> DVec2 {
        let d = p - self.origin;
        DVec2::new(d.dot(self.u), d.dot(self.v))
    }
    fn lift(&self, q: DVec2) -> DVec3 {
        self.origin + q.x * self.u + q.y * self.v
    }
}

/// Where a classified point lies on the patch.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Place {
    Corner(usize),
    /// On edge k (from corner k to k + 1) at parameter t in (0, 1).
    Edge(usize, f64),
    Inside,
}

/// The patch polygon in its frame, with its weld radius.
#[derive(Clone, Debug)]
struct Polygon {
    frame: Frame2,
    corners: Vec<DVec3>,
    poly: Vec<DVec2>,
    eps: f64,
}

impl Polygon {
    fn new(patch: &Patch, diagonal: f64) -> Polygon {
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

    fn n(&self) -> usize {
        self.poly.len()
    }

    /// Signed distance of q from edge k's line, positive inside.
    fn edge_distance(&self, k: usize, q: DVec2) -> f64 {
        let (a, b) = (self.poly[k], self.poly[(k + 1) % self.n()]);
        (b - a).normalize_or_zero().perp_dot(q - a)
    }

    /// None when q lies outside by more than the weld radius.
    fn classify(&self, q: DVec2) -> Option<Place> {
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
    fn edge_point(&self, k: usize, t: f64) -> DVec3 {
        let (a, b) = (self.corners[k], self.corners[(k + 1) % self.n()]);
        a + t * (b - a)
    }

    /// The part of segment p–q inside the polygon (Cyrus–Beck), if longer
    /// than the weld radius. The ends may lie up to half a weld radius
    /// outside; [`Polygon::classify`] puts them on the boundary.
    fn clip(&self, p: DVec2, q: DVec2) -> Option<(DVec2, DVec2)> {
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

/// One end of a clipped segment, before the global weld.
#[derive(Clone, Copy, Debug)]
enum End {
    Corner(usize),
    Boundary(usize),
    Interior(usize),
}

/// A patch's input, classified in its own frame.
#[derive(Clone, Debug)]
struct LocalPatch {
    shape: Polygon,
    /// Points on an edge (edge index, world position), not at corners.
    boundary: Vec<(usize, DVec3)>,
    interior: Vec<DVec2>,
    segments: Vec<[End; 2]>,
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

    fn build(patch_index: usize, shape: Polygon, input: &PatchInput) -> Result<LocalPatch> {
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

/// A uniform 3D grid of ids by cell.
struct Grid3 {
    cell: f64,
    map: HashMap<[i64; 3], Vec<u32>>,
}

impl Grid3 {
    fn new(cell: f64) -> Grid3 {
        Grid3 {
            cell,
            map: HashMap::new(),
        }
    }
    fn cell_of(&self, p: DVec3) -> [i64; 3] {
        (p / self.cell).floor().to_array().map(|x| x as i64)
    }
    fn cells(&self, lo: DVec3, hi: DVec3) -> impl Iterator<Item = [i64; 3]> + use<> {
        let (a, b) = (self.cell_of(lo), self.cell_of(hi));
        (a[0]..=b[0]).flat_map(move |x| {
            (a[1]..=b[1]).flat_map(move |y| (a[2]..=b[2]).map(move |z| [x, y, z]))
        })
    }
    fn insert_box(&mut self, lo: DVec3, hi: DVec3, id: u32) {
        for c in self.cells(lo, hi).collect::<Vec<_>>() {
            self.map.entry(c).or_default().push(id);
        }
    }
    /// Inserts a segment as a chain of boxes no longer than a cell.
    fn insert_segment(&mut self, a: DVec3, b: DVec3, id: u32) {
        let pieces = ((b - a).length() / self.cell).ceil().clamp(1.0, 1e6) as usize;
        for i in 0..pieces {
            let p = a.lerp(b, i as f64 / pieces as f64);
            let q = if i + 1 == pieces {
                b
            } else {
                a.lerp(b, (i + 1) as f64 / pieces as f64)
            };
            self.insert_box(p.min(q), p.max(q), id);
        }
    }
    /// Ids in the cells overlapping the box around p of half-size r,
    /// deduplicated and sorted.
    fn query(&self, p: DVec3, r: f64, out: &mut Vec<u32>) {
        out.clear();
        for c in self.cells(p - DVec3::splat(r), p + DVec3::splat(r)) {
            if let Some(ids) = self.map.get(&c) {
                out.extend_from_slice(ids);
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let g = parent[parent[i as usize] as usize];
        parent[i as usize] = g;
        i = g;
    }
    i
}

/// Welds points closer than the smaller of their radii, or [`CORNER`] times
/// that when one of them is a corner (union-find, the smallest index
/// represents a group). Two groups whose corner owners
/// (patch ids) intersect are never merged: a patch keeps its corners apart.
/// Returns the representative of each point.
fn weld(points: &[DVec3], radius: &[f64], owner: &[Option<u32>]) -> Vec<u32> {
    let n = points.len();
    let cell = CORNER * radius.iter().copied().fold(f64::MIN_POSITIVE, f64::max);
    let mut grid = Grid3::new(cell);
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut owners: Vec<Vec<u32>> = owner.iter().map(|o| o.iter().copied().collect()).collect();
    let mut near = Vec::new();
    for i in 0..n {
        let p = points[i];
        grid.query(p, CORNER * radius[i], &mut near);
        for &j in &near {
            // Corners attract from further away than ordinary points.
            let reach = if owner[i].is_some() || owner[j as usize].is_some() {
                CORNER
            } else {
                1.0
            };
            if (points[j as usize] - p).length() > reach * radius[i].min(radius[j as usize]) {
                continue;
            }
            let (ri, rj) = (find(&mut parent, i as u32), find(&mut parent, j));
            if ri == rj
                || owners[ri as usize]
                    .iter()
                    .any(|o| owners[rj as usize].contains(o))
            {
                continue;
            }
            let (keep, drop) = (ri.min(rj), ri.max(rj));
            parent[drop as usize] = keep;
            let moved = std::mem::take(&mut owners[drop as usize]);
            owners[keep as usize].extend(moved);
        }
        grid.insert_box(p, p, i as u32);
    }
    (0..n as u32).map(|i| find(&mut parent, i)).collect()
}

/// The shared boundary points: canonical positions, and for every patch
/// the canonical ids of its corners, of its own boundary points and the
/// sorted lists of canonical points on each of its edges.
struct Connection {
    points: Vec<DVec3>,
    corners: Vec<Vec<u32>>,
    boundary: Vec<Vec<u32>>,
    edges: Vec<Vec<Vec<u32>>>,
}

/// Builds a grid over all patch edges; returns it with the edge list
/// (patch, edge index, a, b).
type EdgeRef = (u32, usize, DVec3, DVec3);

fn edge_grid(edges: &[EdgeRef], diagonal: f64) -> Grid3 {
    let mut lengths: Vec<f64> = edges.iter().map(|e| (e.3 - e.2).length()).collect();
    lengths.sort_by(f64::total_cmp);
    let median = lengths.get(lengths.len() / 2).copied().unwrap_or(diagonal);
    let cell = median.clamp(diagonal * 1e-3, diagonal.max(f64::MIN_POSITIVE));
    let mut grid = Grid3::new(cell);
    for (i, e) in edges.iter().enumerate() {
        grid.insert_segment(e.2, e.3, i as u32);
    }
    grid
}

fn connect(locals: &[LocalPatch], diagonal: f64) -> Connection {
    // Items: every corner, then every local boundary point.
    let mut pts = Vec::new();
    let mut radius = Vec::new();
    let mut owner = Vec::new();
    for (p, l) in locals.iter().enumerate() {
        for &c in &l.shape.corners {
            pts.push(c);
            radius.push(l.shape.eps);
            owner.push(Some(p as u32));
        }
    }
    for l in locals {
        for &(_, b) in &l.boundary {
            pts.push(b);
            radius.push(l.shape.eps);
            owner.push(None);
        }
    }
    let rep = weld(&pts, &radius, &owner);
    let mut canon_of_rep: HashMap<u32, u32> = HashMap::new();
    let mut points = Vec::new();
    let canon: Vec<u32> = rep
        .iter()
        .map(|&r| {
            *canon_of_rep.entry(r).or_insert_with(|| {
                points.push(pts[r as usize]);
                points.len() as u32 - 1
            })
        })
        .collect();
    let mut item = 0;
    let mut corners = Vec::with_capacity(locals.len());
    for l in locals {
        corners.push(canon[item..item + l.shape.n()].to_vec());
        item += l.shape.n();
    }
    let mut boundary = Vec::with_capacity(locals.len());
    for l in locals {
        boundary.push(canon[item..item + l.boundary.len()].to_vec());
        item += l.boundary.len();
    }

    // Every canonical point goes to every patch edge it lies on.
    let mut edges: Vec<EdgeRef> = Vec::new();
    for (p, l) in locals.iter().enumerate() {
        for k in 0..l.shape.n() {
            let a = points[corners[p][k] as usize];
            let b = points[corners[p][(k + 1) % l.shape.n()] as usize];
            edges.push((p as u32, k, a, b));
        }
    }
    let grid = edge_grid(&edges, diagonal);
    let r_max = locals
        .iter()
        .map(|l| ON_EDGE * l.shape.eps)
        .fold(0.0, f64::max);
    // Parameter and distance of x on edge e, when it lies on it.
    let on_edge = |e: &EdgeRef, x: DVec3, force: bool| -> Option<(f64, f64)> {
        let l = &locals[e.0 as usize];
        let (a, b) = (e.2, e.3);
        let ab = b - a;
        let t = (x - a).dot(ab) / ab.length_squared();
        let eps = l.shape.eps;
        let off = (a + t * ab - x).length();
        let inside = t > 0.0
            && t < 1.0
            && (x - a).length() > CORNER * eps
            && (x - b).length() > CORNER * eps
            && (force || off <= ON_EDGE * eps);
        inside.then_some((t, off))
    };
    let hits: Vec<Vec<(u32, f64)>> = (0..points.len())
        .into_par_iter()
        .map(|i| {
            let mut near = Vec::new();
            grid.query(points[i], r_max, &mut near);
            // Near a corner a point can be close to both edges' lines: it
            // goes on the nearer one only.
            let mut found: Vec<(u32, f64, f64)> = Vec::new();
            for &e in &near {
                let edge = &edges[e as usize];
                if corners[edge.0 as usize].contains(&(i as u32)) {
                    continue;
                }
                let Some((t, off)) = on_edge(edge, points[i], false) else {
                    continue;
                };
                match found.iter_mut().find(|f| edges[f.0 as usize].0 == edge.0) {
                    Some(f) if off < f.2 => *f = (e, t, off),
                    Some(_) => {}
                    None => found.push((e, t, off)),
                }
            }
            found
                .into_iter()
                .map(|(e, t, _)| (e, t))
                .collect::<Vec<_>>()
        })
        .collect();
    let mut lists: Vec<Vec<(f64, u32)>> = vec![Vec::new(); edges.len()];
    for (i, h) in hits.iter().enumerate() {
        for &(e, t) in h {
            lists[e as usize].push((t, i as u32));
        }
    }
    // A patch's own boundary points stay on their edge even when the weld
    // moved them a little further than the search radius.
    let mut first_edge = Vec::with_capacity(locals.len());
    let mut count = 0;
    for l in locals {
        first_edge.push(count);
        count += l.shape.n();
    }
    for (p, l) in locals.iter().enumerate() {
        for (j, &(k, _)) in l.boundary.iter().enumerate() {
            let id = boundary[p][j];
            let e = first_edge[p] + k;
            if corners[p].contains(&id) {
                continue;
            }
            let placed = first_edge[p]..first_edge[p] + l.shape.n();
            if lists[placed]
                .iter()
                .any(|list| list.iter().any(|x| x.1 == id))
            {
                continue;
            }
            if let Some((t, _)) = on_edge(&edges[e], points[id as usize], true) {
                lists[e].push((t, id));
            }
        }
    }
    let mut per_patch: Vec<Vec<Vec<u32>>> = locals.iter().map(|_| Vec::new()).collect();
    for (e, mut list) in lists.into_iter().enumerate() {
        list.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let mut ids: Vec<u32> = Vec::with_capacity(list.len());
        for (_, id) in list {
            if !ids.contains(&id) {
                ids.push(id);
            }
        }
        per_patch[edges[e].0 as usize].push(ids);
    }
    Connection {
        points,
        corners,
        boundary,
        edges: per_patch,
    }
}

/// A spade vertex: 2D position and the index into the patch's vertex list
/// (`u32::MAX` for vertices spade created).
#[derive(Clone, Copy, Debug)]
struct V2 {
    p: Point2<f64>,
    id: u32,
}

/// Vertices spade creates itself (refinement, splits).
impl From<Point2<f64>> for V2 {
    fn from(p: Point2<f64>) -> V2 {
        V2 { p, id: u32::MAX }
    }
}

impl HasPosition for V2 {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.p
    }
}

/// The id of the refinement frame's vertices.
const FRAME: u32 = u32::MAX - 1;

/// Undirected edge data: true on the patch boundary chain.
type Cdt = ConstrainedDelaunayTriangulation<V2, (), bool>;

/// A vertex of the patch being meshed.
#[derive(Clone, Copy, Debug)]
struct Vtx {
    p2: DVec2,
    p3: DVec3,
    /// Bit k set: lies on polygon edge k.
    edges: u8,
}

/// A 2D grid of vertex ids.
struct Grid2 {
    cell: f64,
    map: HashMap<[i64; 2], Vec<u32>>,
}

impl Grid2 {
    fn cell_of(&self, p: DVec2) -> [i64; 2] {
        (p / self.cell).floor().to_array().map(|x| x as i64)
    }
    fn insert(&mut self, p: DVec2, id: u32) {
        let c = self.cell_of(p);
        self.map.entry(c).or_default().push(id);
    }
    fn query_box(&self, lo: DVec2, hi: DVec2, out: &mut Vec<u32>) {
        let (a, b) = (self.cell_of(lo), self.cell_of(hi));
        for x in a[0]..=b[0] {
            for y in a[1]..=b[1] {
                if let Some(ids) = self.map.get(&[x, y]) {
                    out.extend_from_slice(ids);
                }
            }
        }
    }
    /// Ids near segment a–b (within r), sorted and deduplicated.
    fn query_segment(&self, a: DVec2, b: DVec2, r: f64, out: &mut Vec<u32>) {
        out.clear();
        let pieces = ((b - a).length() / self.cell).ceil().clamp(1.0, 1e6) as usize;
        for i in 0..pieces {
            let p = a.lerp(b, i as f64 / pieces as f64);
            let q = a.lerp(b, (i + 1) as f64 / pieces as f64);
            let rr = DVec2::splat(r);
            self.query_box(p.min(q) - rr, p.max(q) + rr, out);
        }
        out.sort_unstable();
        out.dedup();
    }
}

/// The vertex set of one patch under construction, welded as it grows.
struct VertexSet {
    verts: Vec<Vtx>,
    grid: Grid2,
    eps: f64,
}

impl VertexSet {
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
}

/// Steiner points harvested from a refined patch.
#[derive(Default)]
struct Harvest {
    boundary: Vec<(usize, DVec3)>,
    interior: Vec<DVec2>,
}

fn mesh_error(patch: usize, what: &str) -> Error {
    Error::Mesh(format!("patch {patch}: {what}"))
}

/// Proper crossing point of segments a–b and c–d, if any.
fn crossing(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> Option<DVec2> {
    let (r, s) = (b - a, d - c);
    let denom = r.perp_dot(s);
    if !(denom.abs() > 1e-14 * r.length() * s.length()) {
        return None;
    }
    let t = (c - a).perp_dot(s) / denom;
    let u = (c - a).perp_dot(r) / denom;
    (t > 0.0 && t < 1.0 && u > 0.0 && u < 1.0).then(|| a + t * r)
}

/// Adds a constraint edge, splitting at crossings when spade refuses it;
/// the splitting call is isolated because spade can panic in it.
fn add_constraint(
    cdt: &mut Cdt,
    a: FixedVertexHandle,
    b: FixedVertexHandle,
) -> std::result::Result<Vec<spade::handles::FixedDirectedEdgeHandle>, ()> {
    if a == b {
        return Ok(Vec::new());
    }
    let edges = cdt.try_add_constraint(a, b);
    if !edges.is_empty() {
        return Ok(edges);
    }
    catch_unwind(AssertUnwindSafe(|| {
        cdt.add_constraint_and_split(a, b, V2::from)
    }))
    .map_err(|_| ())
}

/// Triangulates one patch. With `refine`, returns only the harvested
/// Steiner points.
fn mesh_patch(
    index: usize,
    local: &LocalPatch,
    conn: &Connection,
    refine: Option<&RefinementParameters<f64>>,
) -> Result<(PatchTriangulation, Harvest)> {
    let shape = &local.shape;
    let (frame, eps, n) = (shape.frame, shape.eps, shape.n());
    let corners = &conn.corners[index];
    let extent = shape
        .poly
        .iter()
        .fold(0.0f64, |m, p| m.max(p.length()))
        .max(eps);
    let expected = (n + local.interior.len() + 2 * local.segments.len()).max(1) as f64;
    let mut set = VertexSet {
        verts: Vec::new(),
        grid: Grid2 {
            cell: (2.0 * extent / expected.sqrt()).max(4.0 * eps),
            map: HashMap::new(),
        },
        eps,
    };

    // The boundary chain: each corner followed by its edge's points.
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
    let n_chain = chain.len();

    let interior: Vec<u32> = local
        .interior
        .iter()
        .map(|&q| set.weld(q, &frame))
        .collect();
    let end_vertex = |set: &mut VertexSet, e: End| -> u32 {
        match e {
            End::Corner(k) => local_of[&corners[k]],
            End::Boundary(b) => {
                let c = conn.boundary[index][b];
                match local_of.get(&c) {
                    Some(&v) => v,
                    None => set.weld(frame.project(conn.points[c as usize]), &frame),
                }
            }
            End::Interior(i) => interior[i],
        }
    };
    let along_boundary = |set: &VertexSet, a: u32, b: u32| {
        set.verts[a as usize].edges & set.verts[b as usize].edges != 0
    };
    let mut segments: Vec<[u32; 2]> = Vec::new();
    for s in &local.segments {
        let (a, b) = (end_vertex(&mut set, s[0]), end_vertex(&mut set, s[1]));
        if a != b && !along_boundary(&set, a, b) {
            segments.push([a.min(b), a.max(b)]);
        }
    }
    segments.sort_unstable();
    segments.dedup();

    // Crossings become vertices; then every segment is split at each vertex
    // lying on it.
    for i in 0..segments.len() {
        for j in i + 1..segments.len() {
            let [a, b] = segments[i];
            let [c, d] = segments[j];
            if a == c || a == d || b == c || b == d {
                continue;
            }
            let p = |v: u32| set.verts[v as usize].p2;
            let (pa, pb, pc, pd) = (p(a), p(b), p(c), p(d));
            let (lo1, hi1) = (pa.min(pb), pa.max(pb));
            let (lo2, hi2) = (pc.min(pd), pc.max(pd));
            if lo1.x > hi2.x || lo2.x > hi1.x || lo1.y > hi2.y || lo2.y > hi1.y {
                continue;
            }
            if let Some(x) = crossing(pa, pb, pc, pd) {
                if [pa, pb, pc, pd].iter().all(|&q| (q - x).length() > eps) {
                    set.weld(x, &frame);
                }
            }
        }
    }
    let mut pieces: Vec<[u32; 2]> = Vec::new();
    let mut near = Vec::new();
    for &[a, b] in &segments {
        let (pa, pb) = (set.verts[a as usize].p2, set.verts[b as usize].p2);
        let ab = pb - pa;
        set.grid.query_segment(pa, pb, eps, &mut near);
        let mut on: Vec<(f64, u32)> = near
            .iter()
            .filter(|&&v| v != a && v != b)
            .filter_map(|&v| {
                let q = set.verts[v as usize].p2;
                let t = (q - pa).dot(ab) / ab.length_squared();
                let off = (pa + t * ab - q).length();
                (t > 0.0 && t < 1.0 && off <= eps).then_some((t, v))
            })
            .collect();
        on.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let mut prev = a;
        for v in on.into_iter().map(|x| x.1).chain([b]) {
            if v != prev && !along_boundary(&set, prev, v) {
                pieces.push([prev.min(v), prev.max(v)]);
            }
            prev = v;
        }
    }
    pieces.sort_unstable();
    pieces.dedup();

    // The constrained Delaunay triangulation.
    let mut cdt = Cdt::new();
    let mut handle = Vec::with_capacity(set.verts.len());
    for (i, v) in set.verts.iter().enumerate() {
        let before = cdt.num_vertices();
        let p = spade::mitigate_underflow(Point2::new(v.p2.x, v.p2.y));
        let h = cdt
            .insert(V2 { p, id: i as u32 })
            .map_err(|e| mesh_error(index, &format!("vertex {i} rejected by spade: {e:?}")))?;
        if cdt.num_vertices() == before {
            // Same 2D position as an earlier vertex: keep the earlier one.
            let first = handle.iter().position(|&x| x == h).unwrap_or(i);
            cdt.vertex_data_mut(h).id = first as u32;
        }
        handle.push(h);
    }
    if refine.is_some() {
        // Rounding leaves boundary points a hair inside the convex hull of
        // the chain; spade would split the hull edges of those slivers
        // without end. A frame around the patch makes the hull far away;
        // Steiner points outside the patch are dropped.
        let (lo, hi) = shape
            .poly
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        let margin = 0.5 * (hi - lo).max_element();
        for q in [
            lo - margin,
            DVec2::new(hi.x + margin, lo.y - margin),
            hi + margin,
            DVec2::new(lo.x - margin, hi.y + margin),
        ] {
            cdt.insert(V2 {
                p: Point2::new(q.x, q.y),
                id: FRAME,
            })
            .map_err(|e| mesh_error(index, &format!("frame rejected by spade: {e:?}")))?;
        }
    }
    for i in 0..n_chain {
        let (a, b) = (
            handle[chain[i] as usize],
            handle[chain[(i + 1) % n_chain] as usize],
        );
        let edges = add_constraint(&mut cdt, a, b)
            .map_err(|_| mesh_error(index, "spade failed on a boundary edge"))?;
        for e in edges {
            *cdt.undirected_edge_data_mut(e.as_undirected()).data_mut() = true;
        }
    }
    for &[a, b] in &pieces {
        add_constraint(&mut cdt, handle[a as usize], handle[b as usize])
            .map_err(|_| mesh_error(index, "spade failed on a constraint segment"))?;
    }

    if let Some(params) = refine {
        let mut harvest = Harvest::default();
        if catch_unwind(AssertUnwindSafe(|| cdt.refine(params.clone()))).is_ok() {
            for v in cdt.vertices() {
                if v.data().id != u32::MAX {
                    continue; // an input or frame vertex
                }
                let q = DVec2::new(v.position().x, v.position().y);
                match shape.classify(q) {
                    Some(Place::Edge(k, t)) => harvest.boundary.push((k, shape.edge_point(k, t))),
                    Some(Place::Inside) => harvest.interior.push(q),
                    _ => {}
                }
            }
        }
        return Ok((PatchTriangulation::default(), harvest));
    }

    // Faces reachable from the convex hull without crossing the boundary
    // chain are outside.
    let mut outside = vec![false; cdt.num_all_faces()];
    let mut todo: Vec<_> = cdt.convex_hull().map(|e| e.rev().fix()).collect();
    while let Some(e) = todo.pop() {
        let edge = cdt.directed_edge(e);
        if *edge.as_undirected().data().data() {
            continue;
        }
        if let Some(face) = edge.face().as_inner() {
            let f = face.fix().index();
            if !outside[f] {
                outside[f] = true;
                todo.push(edge.prev().rev().fix());
                todo.push(edge.next().rev().fix());
            }
        }
    }

    let position = |h: FixedVertexHandle| -> DVec3 {
        let v = cdt.vertex(h);
        match v.data().id {
            u32::MAX => frame.lift(DVec2::new(v.position().x, v.position().y)),
            id => set.verts[id as usize].p3,
        }
    };
    let mut out = PatchTriangulation::default();
    let mut out_index: Vec<u32> = vec![u32::MAX; cdt.num_vertices()];
    let mut use_vertex = |h: FixedVertexHandle, out: &mut PatchTriangulation| -> u32 {
        let slot = &mut out_index[h.index()];
        if *slot == u32::MAX {
            *slot = out.positions.len() as u32;
            out.positions.push(position(h));
        }
        *slot
    };
    let mut area2 = 0.0;
    for face in cdt.inner_faces() {
        if outside[face.fix().index()] {
            continue;
        }
        let [a, b, c] = face.vertices().map(|v| v.fix());
        let [pa, pb, pc] = face.positions().map(|p| DVec2::new(p.x, p.y));
        let twice = (pb - pa).perp_dot(pc - pa);
        area2 += twice;
        let tri = [a, b, c].map(|h| use_vertex(h, &mut out));
        out.triangles.push(if twice >= 0.0 {
            tri
        } else {
            [tri[0], tri[2], tri[1]]
        });
    }
    for e in cdt.undirected_edges() {
        if !e.is_constraint_edge() {
            continue;
        }
        let [a, b] = e.vertices().map(|v| v.fix());
        if out_index[a.index()] == u32::MAX || out_index[b.index()] == u32::MAX {
            continue;
        }
        let pair = [out_index[a.index()], out_index[b.index()]];
        if *e.data().data() {
            // Orient counter-clockwise: the inside face is on the left.
            let d = e.as_directed();
            let left_inside = d
                .face()
                .as_inner()
                .is_some_and(|f| !outside[f.fix().index()]);
            out.boundary_edges.push(if left_inside {
                pair
            } else {
                [pair[1], pair[0]]
            });
        } else {
            out.constrained_edges.push(pair);
        }
    }
    // The kept faces must tile the chain polygon.
    let chain_area2: f64 = (0..n_chain)
        .map(|i| {
            let a = set.verts[chain[i] as usize].p2;
            let b = set.verts[chain[(i + 1) % n_chain] as usize].p2;
            a.perp_dot(b)
        })
        .sum();
    if !((area2 - chain_area2).abs() <= 1e-9 * chain_area2.abs()) {
        return Err(mesh_error(index, "the triangles do not tile the patch"));
    }
    Ok((out, Harvest::default()))
}

/// Triangulates every patch of `scene` with its input (one per patch, in
/// patch order). Deterministic; parallel over patches.
pub fn triangulate_patches(
    scene: &Scene,
    inputs: &[PatchInput],
    opts: &TriangulateOptions,
) -> Result<Vec<PatchTriangulation>> {
    if inputs.len() != scene.patches.len() {
        return Err(Error::Mesh(format!(
            "{} patch inputs for {} patches",
            inputs.len(),
            scene.patches.len()
        )));
    }
    if let Some(a) = opts.min_angle_deg {
        if !(a > 0.0 && a <= 34.0) {
            return Err(Error::Setting(format!(
                "minimum triangle angle {a}° is outside (0, 34]"
            )));
        }
    }
    let diagonal = scene.diagonal();
    if !(diagonal > 0.0 && diagonal.is_finite()) {
        return Err(Error::Mesh("the scene has no extent".into()));
    }
    let mut locals: Vec<LocalPatch> = scene
        .patches
        .par_iter()
        .zip(inputs)
        .enumerate()
        .map(|(i, (patch, input))| LocalPatch::build(i, Polygon::new(patch, diagonal), input))
        .collect::<Result<_>>()?;

    if let Some(angle) = opts.min_angle_deg {
        let conn = connect(&locals, diagonal);
        let harvests: Vec<Harvest> = locals
            .par_iter()
            .enumerate()
            .map(|(i, local)| {
                // Triangles smaller than this are left alone so that Steiner
                // points stay well apart from each other.
                let min_area = (1e3 * local.shape.eps).powi(2);
                let params = RefinementParameters::new()
                    .with_angle_limit(AngleLimit::from_deg(angle))
                    .with_max_additional_vertices(opts.max_added_vertices)
                    .with_min_required_area(min_area);
                mesh_patch(i, local, &conn, Some(&params)).map(|r| r.1)
            })
            .collect::<Result<_>>()?;
        for (local, h) in locals.iter_mut().zip(harvests) {
            local.boundary.extend(h.boundary);
            local.interior.extend(h.interior);
        }
    }
    let conn = connect(&locals, diagonal);

    locals
        .par_iter()
        .enumerate()
        .map(|(i, local)| mesh_patch(i, local, &conn, None).map(|r| r.0))
        .collect()
}

/// Validation tolerance of a patch: a few weld radii.
fn check_tolerance(shape: &Polygon) -> f64 {
    2.0 * CORNER * shape.eps
}

fn point_segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (a + t * ab - p).length()
}

/// Bit pattern of a position, +0 and -0 alike.
fn bits(p: DVec3) -> [u64; 3] {
    [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits)
}

/// An undirected edge by the bit patterns of its ends.
type EdgeKey = ([u64; 3], [u64; 3]);

fn edge_key(a: DVec3, b: DVec3) -> EdgeKey {
    let (ka, kb) = (bits(a), bits(b));
    if ka <= kb { (ka, kb) } else { (kb, ka) }
}

/// The checks of one patch; returns its boundary edges with the polygon
/// edge each lies on.
fn check_patch(
    i: usize,
    patch: &Patch,
    shape: &Polygon,
    mesh: &PatchTriangulation,
    input: &PatchInput,
) -> Result<Vec<(usize, [u32; 2])>, String> {
    let tol = check_tolerance(shape);
    let pos = &mesh.positions;
    let nv = pos.len();
    let mut seen = HashSet::new();
    for (k, &p) in pos.iter().enumerate() {
        if !p.is_finite() {
            return Err(format!("patch {i}: vertex {k} is not finite"));
        }
        if !seen.insert(bits(p)) {
            return Err(format!("patch {i}: vertex {k} duplicates another vertex"));
        }
        if (p - shape.corners[0]).dot(patch.normal).abs() > tol {
            return Err(format!("patch {i}: vertex {k} is off the patch plane"));
        }
    }
    if mesh.triangles.is_empty() {
        return Err(format!("patch {i}: no triangles"));
    }
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    let mut area = 0.0;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if tri.iter().any(|&v| v as usize >= nv) {
            return Err(format!("patch {i}: triangle {t} indexes a missing vertex"));
        }
        let [a, b, c] = tri.map(|v| pos[v as usize]);
        let twice = (b - a).cross(c - a).dot(patch.normal);
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        if !(twice > 0.0) {
            return Err(format!(
                "patch {i}: triangle {t} is clockwise or degenerate seen from the front"
            ));
        }
        if !(twice / longest > 1e-3 * shape.eps) {
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
    let n = shape.n();
    let mut boundary = Vec::new();
    let mut deviation = 0.0f64;
    let mut sorted: Vec<_> = directed.keys().copied().collect();
    sorted.sort_unstable();
    for &(a, b) in &sorted {
        if directed.contains_key(&(b, a)) {
            continue;
        }
        let (pa, pb) = (pos[a as usize], pos[b as usize]);
        let on = (0..n).find(|&k| {
            let (c, d) = (shape.corners[k], shape.corners[(k + 1) % n]);
            point_segment_distance(pa, c, d) <= tol && point_segment_distance(pb, c, d) <= tol
        });
        let Some(k) = on else {
            return Err(format!(
                "patch {i}: edge ({a}, {b}) has one triangle but is not on the patch boundary"
            ));
        };
        let (c, d) = (shape.corners[k], shape.corners[(k + 1) % n]);
        deviation = deviation
            .max(point_segment_distance(pa, c, d))
            .max(point_segment_distance(pb, c, d));
        boundary.push((k, [a, b]));
    }
    let perimeter: f64 = (0..n)
        .map(|k| (shape.corners[(k + 1) % n] - shape.corners[k]).length())
        .sum();
    if !((area - patch.area).abs() <= 1e-9 * patch.area + perimeter * deviation) {
        return Err(format!(
            "patch {i}: triangle areas sum to {area}, the patch has {}",
            patch.area
        ));
    }

    // Every clipped segment is covered by collinear mesh edges.
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
                "patch {i}: segment {s} is covered by mesh edges only up to {reach} of {len}"
            ));
        }
    }
    // Every point inside the patch is a vertex.
    for (k, &p) in input.points.iter().enumerate() {
        let q = shape.frame.project(p);
        if shape.classify(q).is_none() {
            continue;
        }
        let x = shape.frame.lift(q);
        if !pos.iter().any(|&v| (v - x).length() <= tol) {
            return Err(format!("patch {i}: point {k} is not a mesh vertex"));
        }
    }
    Ok(boundary)
}

/// Checks the invariants of the module doc on a triangulation of `scene`
/// made from `inputs`: per patch, edges are shared by two triangles or lie
/// on the patch boundary; triangles are counter-clockwise around the patch
/// normal, not degenerate, and their areas sum to the patch area; each
/// clipped input segment is a union of mesh edges and each input point
/// inside the patch is a vertex. Across patches, every boundary edge
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
    let boundaries: Vec<Vec<(usize, [u32; 2])>> = (0..np)
        .into_par_iter()
        .map(|i| check_patch(i, &scene.patches[i], &shapes[i], &tris[i], &inputs[i]))
        .collect::<Result<_, String>>()?;

    // Twins across collinearly overlapping patch edges.
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
    let grid = edge_grid(&edges, diagonal);
    let r = shapes.iter().map(check_tolerance).fold(0.0, f64::max);
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
    for (e, f) in pairs {
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
