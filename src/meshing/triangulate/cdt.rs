//! spade's constrained Delaunay triangulation of one patch, the only place
//! the crate calls spade: [`mesh_patch`] (the final triangulation) and
//! [`steiner_points`] (quality refinement, harvesting the points it adds).
//!
//! The steps of both, on the [`PatchConstraints`] of the patch:
//! 1. insert every vertex (a vertex at the 2D position of an earlier one
//!    takes that one's id);
//! 2. refinement only: insert a frame of four vertices far around the
//!    patch ([`Hull::Frame`]);
//! 3. insert the boundary chain as constraint edges marked `true`, then the
//!    constraint pieces (spade splits those it refuses at the crossings);
//! 4. refinement: refine, and keep the Steiner points on the patch's edges
//!    or inside it; triangulation: flood-fill the faces outside the chain
//!    from the convex hull, and output the faces inside, the constraint
//!    edges and the boundary edges.
//!
//! Invariants: spade never panics through here (its splitting and
//! refinement calls run under `catch_unwind`, failures are [`Error::Mesh`]);
//! output triangles are counter-clockwise in the frame; the kept faces'
//! area equals the chain polygon's area to within [`TILING`], else the patch
//! is an error.

use std::panic::{AssertUnwindSafe, catch_unwind};

use glam::{DVec2, DVec3};
use spade::handles::{FixedDirectedEdgeHandle, FixedVertexHandle};
use spade::{
    AngleLimit, ConstrainedDelaunayTriangulation, HasPosition, Point2, RefinementParameters,
    Triangulation,
};

use super::PatchTriangulation;
use super::constraints::{PatchConstraints, VertexSet};
use super::frame::{Frame2, LocalPatch, Place, Polygon};
use super::weld::Connection;
use crate::error::{Error, Result};

/// Refinement leaves triangles smaller than the square of this many weld
/// radii alone, so that Steiner points stay well apart from each other.
const STEINER_SPACING: f64 = 1e3;

/// The refinement frame lies this fraction of the patch's larger
/// bounding-box side outside the box.
const FRAME_MARGIN: f64 = 0.5;

/// Largest difference between the kept faces' area and the chain polygon's,
/// relative to the latter.
const TILING: f64 = 1e-9;

/// The id of vertices spade created (refinement, splits).
const CREATED: u32 = u32::MAX;

/// The id of the refinement frame's vertices.
const FRAME: u32 = u32::MAX - 1;

/// A spade vertex: 2D position and the index into the patch's vertex list
/// ([`CREATED`] for vertices spade created, [`FRAME`] for the frame).
#[derive(Clone, Copy, Debug)]
struct V2 {
    p: Point2<f64>,
    id: u32,
}

/// Vertices spade creates itself (refinement, splits).
impl From<Point2<f64>> for V2 {
    fn from(p: Point2<f64>) -> V2 {
        V2 { p, id: CREATED }
    }
}

impl HasPosition for V2 {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.p
    }
}

/// Undirected edge data: true on the patch boundary chain.
type Cdt = ConstrainedDelaunayTriangulation<V2, (), bool>;

/// What makes the convex hull of a patch's triangulation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Hull {
    /// The patch's own vertices.
    Chain,
    /// Four extra vertices far around the patch. Rounding leaves boundary
    /// points a hair inside the convex hull of the chain; refinement would
    /// split the hull edges of those slivers without end.
    Frame,
}

/// Steiner points harvested from a refined patch.
#[derive(Default)]
pub(super) struct Harvest {
    /// On an edge: (edge index, world position).
    pub(super) boundary: Vec<(usize, DVec3)>,
    /// Inside, in the patch frame.
    pub(super) interior: Vec<DVec2>,
}

fn mesh_error(patch: usize, what: &str) -> Error {
    Error::Mesh(format!("patch {patch}: {what}"))
}

/// Triangulates patch `index`: its constrained Delaunay triangulation,
/// restricted to the inside of the boundary chain.
pub(super) fn mesh_patch(
    index: usize,
    local: &LocalPatch,
    conn: &Connection,
) -> Result<PatchTriangulation> {
    let (cdt, constraints) = triangulate(index, local, conn, Hull::Chain)?;
    let outside = outside_faces(&cdt);
    let (mut out, out_index, area2) =
        kept_triangles(&cdt, &constraints.set, &local.shape.frame, &outside);
    add_constraint_edges(&cdt, &outside, &out_index, &mut out);
    check_tiling(index, &constraints, area2)?;
    Ok(out)
}

/// Refines patch `index` towards `min_angle_deg`, adding at most
/// `max_added_vertices`, and returns the Steiner points on its edges or
/// inside it (none when spade panicked).
pub(super) fn steiner_points(
    index: usize,
    local: &LocalPatch,
    conn: &Connection,
    min_angle_deg: f64,
    max_added_vertices: usize,
) -> Result<Harvest> {
    let min_area = (STEINER_SPACING * local.shape.eps).powi(2);
    let params = RefinementParameters::new()
        .with_angle_limit(AngleLimit::from_deg(min_angle_deg))
        .with_max_additional_vertices(max_added_vertices)
        .with_min_required_area(min_area);
    let (mut cdt, _) = triangulate(index, local, conn, Hull::Frame)?;
    let shape = &local.shape;
    let mut harvest = Harvest::default();
    if catch_unwind(AssertUnwindSafe(|| cdt.refine(params))).is_ok() {
        for v in cdt.vertices() {
            if v.data().id != CREATED {
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
    Ok(harvest)
}

/// Steps 1–3: the constrained Delaunay triangulation of the patch's
/// vertices, chain and pieces, with `hull` around it.
fn triangulate(
    index: usize,
    local: &LocalPatch,
    conn: &Connection,
    hull: Hull,
) -> Result<(Cdt, PatchConstraints)> {
    let constraints = PatchConstraints::build(index, local, conn);
    let mut cdt = Cdt::new();
    let handle = insert_vertices(&mut cdt, index, &constraints.set)?;
    if hull == Hull::Frame {
        insert_frame(&mut cdt, index, &local.shape)?;
    }
    insert_constraints(&mut cdt, index, &handle, &constraints)?;
    Ok((cdt, constraints))
}

/// Inserts every vertex of `set`; returns their handles.
fn insert_vertices(cdt: &mut Cdt, index: usize, set: &VertexSet) -> Result<Vec<FixedVertexHandle>> {
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
    Ok(handle)
}

/// Inserts the four vertices of [`Hull::Frame`] around `shape`'s bounding
/// box. Steiner points outside the patch are dropped afterwards.
fn insert_frame(cdt: &mut Cdt, index: usize, shape: &Polygon) -> Result<()> {
    let (lo, hi) = shape
        .poly
        .iter()
        .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let margin = FRAME_MARGIN * (hi - lo).max_element();
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
    Ok(())
}

/// Inserts the boundary chain (its edges marked `true`), then the pieces.
fn insert_constraints(
    cdt: &mut Cdt,
    index: usize,
    handle: &[FixedVertexHandle],
    constraints: &PatchConstraints,
) -> Result<()> {
    let chain = &constraints.chain;
    let n_chain = chain.len();
    for i in 0..n_chain {
        let (a, b) = (
            handle[chain[i] as usize],
            handle[chain[(i + 1) % n_chain] as usize],
        );
        let edges = add_constraint(cdt, a, b)
            .map_err(|_| mesh_error(index, "spade failed on a boundary edge"))?;
        for e in edges {
            *cdt.undirected_edge_data_mut(e.as_undirected()).data_mut() = true;
        }
    }
    for &[a, b] in &constraints.pieces {
        add_constraint(cdt, handle[a as usize], handle[b as usize])
            .map_err(|_| mesh_error(index, "spade failed on a constraint segment"))?;
    }
    Ok(())
}

/// Adds a constraint edge, splitting at crossings when spade refuses it;
/// the splitting call is isolated because spade can panic in it.
fn add_constraint(
    cdt: &mut Cdt,
    a: FixedVertexHandle,
    b: FixedVertexHandle,
) -> std::result::Result<Vec<FixedDirectedEdgeHandle>, ()> {
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

/// Faces reachable from the convex hull without crossing the boundary
/// chain are outside; by face index.
fn outside_faces(cdt: &Cdt) -> Vec<bool> {
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
    outside
}

/// The faces not `outside` as counter-clockwise triangles, their vertices
/// numbered in order of first use. Returns the triangulation (no edges
/// yet), the output index of each spade vertex (`u32::MAX`: unused) and
/// twice the kept area in the frame.
fn kept_triangles(
    cdt: &Cdt,
    set: &VertexSet,
    frame: &Frame2,
    outside: &[bool],
) -> (PatchTriangulation, Vec<u32>, f64) {
    let position = |h: FixedVertexHandle| -> DVec3 {
        let v = cdt.vertex(h);
        match v.data().id {
            CREATED => frame.lift(DVec2::new(v.position().x, v.position().y)),
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
    (out, out_index, area2)
}

/// The constraint edges between output vertices: boundary chain edges
/// (oriented with the inside on their left) and the others.
fn add_constraint_edges(
    cdt: &Cdt,
    outside: &[bool],
    out_index: &[u32],
    out: &mut PatchTriangulation,
) {
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
}

/// The kept faces must tile the chain polygon: `area2` (twice their area)
/// equals twice the chain's area to within [`TILING`].
fn check_tiling(index: usize, constraints: &PatchConstraints, area2: f64) -> Result<()> {
    let (chain, set) = (&constraints.chain, &constraints.set);
    let n_chain = chain.len();
    let chain_area2: f64 = (0..n_chain)
        .map(|i| {
            let a = set.verts[chain[i] as usize].p2;
            let b = set.verts[chain[(i + 1) % n_chain] as usize].p2;
            a.perp_dot(b)
        })
        .sum();
    if !((area2 - chain_area2).abs() <= TILING * chain_area2.abs()) {
        return Err(mesh_error(index, "the triangles do not tile the patch"));
    }
    Ok(())
}
