//! The output mesh of a hierarchical solution, in one of three modes, with
//! every vertex value computed at the vertex.
//!
//! Owns: [`MeshMode`], [`MeshSettings`], [`MeshStats`], [`build_mesh`] and
//! [`PointEvaluator`] (the radiosity at any point of a patch).
//!
//! The steps:
//! 1. The points and constraints of each patch, by mode:
//!    - `uniform`: a regular grid at one spacing for the whole scene (chosen
//!      for a target vertex count), with points at that spacing along the
//!      patch edges;
//!    - `quadtree`: the corners of the hierarchy's leaves;
//!    - `discontinuity`: the leaf corners, with the discontinuity segments
//!      as constraint edges.
//! 2. [`triangulate_patches`]: spade's constrained Delaunay triangulation
//!    per patch, vertices shared bit for bit along patch edges.
//! 3. Each vertex's radiosity by a final gather at the vertex
//!    ([`point_radiosity`]) from the leaf that holds it, the emitters'
//!    direct light gathered at the vertex itself (exact form factor and
//!    its own rays) for up to [`MAX_DIRECT_EMITTERS`] emitter patches; an
//!    emitter from which no link of the solution brings light to any part
//!    of the vertex's patch is first checked with a few rays
//!    ([`dark_emitters`]).
//! 4. `discontinuity` only, output adaptivity: a triangle whose centroid's
//!    point value differs from the interpolation of its vertices by more
//!    than the tolerance gets its centroid as a new point; the patches are
//!    triangulated again and the new vertices evaluated, for a few passes
//!    within a vertex budget.
//! 5. `discontinuity` only: a vertex on a contact line (a D0 discontinuity,
//!    where the radiosity jumps) becomes one vertex per side of the line,
//!    each evaluated just off the line on its own side. The copies share
//!    their position, so the surface stays closed.
//!
//! Invariants: the mesh passes [`OutputMesh::validate`]; along patch edges
//! neighbouring patches have the same vertex positions (no cracks, no
//! T-vertices); the result depends only on the inputs and the seed, not on
//! the thread count (evaluations run in parallel, each into its own slot,
//! with rays seeded per leaf and source).

pub mod leaf;
pub mod point_gather;
pub mod triangulate;

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::discontinuity::{Segment, SegmentKind};
use crate::error::Result;
use crate::hierarchical::hierarchy::Hierarchy;
use crate::hierarchical::{HierarchicalSolution, scene_scales};
use crate::mesh::OutputMesh;
use crate::meshing::point_gather::{LinkRays, PointEvaluator};
use crate::meshing::triangulate::{
    PatchInput, PatchTriangulation, TriangulateOptions, triangulate_patches,
};
use crate::scene::Scene;
use crate::util::geometry::{
    PositionKey, closest_on_segment, outside_polygon, position_key, segment_distance,
};
use crate::util::union_find::UnionFind;
use crate::visibility::{ENDPOINT_GAP, TriangleBvh};

/// Where the output mesh puts its vertices.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum MeshMode {
    /// A regular grid, blind to the lighting.
    Uniform,
    /// The corners of the hierarchy's leaves.
    Quadtree,
    /// The leaf corners plus the discontinuity segments as constraint
    /// edges, with output adaptivity and split vertices on contact lines.
    Discontinuity,
}

impl MeshMode {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            MeshMode::Uniform => "uniform",
            MeshMode::Quadtree => "quadtree",
            MeshMode::Discontinuity => "discontinuity",
        }
    }
}

/// Knobs of [`build_mesh`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MeshSettings {
    pub mode: MeshMode,
    /// `uniform`: the number of vertices aimed at (`None`: as many as the
    /// hierarchy has leaves, the size of the `quadtree` mesh).
    pub uniform_vertices: Option<usize>,
    /// Output adaptivity: a centroid is added when its value and the
    /// interpolated one differ by more than this fraction of their mean
    /// (plus 1 % of the scene's mean emitted exitance, so that noise in the
    /// dark is not chased). 0 turns adaptivity off.
    pub adapt_tol: f64,
    /// Most vertices adaptivity may add, as a fraction of the initial
    /// vertex count.
    pub adapt_budget: f64,
    /// Adaptivity passes at most.
    pub adapt_passes: usize,
    /// Seed of the vertices' visibility rays.
    pub seed: u64,
}

impl MeshSettings {
    /// Checks the adaptivity tolerance (zero or positive). The error names
    /// the command-line option.
    pub fn validate(&self) -> Result<()> {
        if !(self.adapt_tol >= 0.0 && self.adapt_tol.is_finite()) {
            return Err(crate::Error::Setting(
                "--adapt-tol must be zero or positive".into(),
            ));
        }
        Ok(())
    }
}

impl Default for MeshSettings {
    /// Discontinuity mode, 5 % tolerance, at most 50 % more vertices in at
    /// most 3 passes.
    fn default() -> Self {
        MeshSettings {
            mode: MeshMode::Discontinuity,
            uniform_vertices: None,
            adapt_tol: 0.05,
            adapt_budget: 0.5,
            adapt_passes: 3,
            seed: 0,
        }
    }
}

/// What [`build_mesh`] did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeshStats {
    pub mode: String,
    /// Discontinuity segments given as constraints.
    pub segments: usize,
    /// Mesh edges on those segments.
    pub constrained_edges: usize,
    /// Vertices of the first triangulation.
    pub initial_vertices: usize,
    /// Vertices added by output adaptivity.
    pub adaptive_vertices: usize,
    /// Extra vertex copies made on contact lines.
    pub split_vertices: usize,
    /// Emitter patches whose light is gathered at each vertex (0: through
    /// the links, beyond [`MAX_DIRECT_EMITTERS`]).
    pub direct_emitters: usize,
    /// Point evaluations (vertices, copies and centroid checks).
    pub evaluations: usize,
    pub triangulate_seconds: f64,
    pub evaluate_seconds: f64,
}

/// A vertex value's cache key: its patch and exact position.
type Key = (u32, PositionKey);

fn key(patch: usize, x: DVec3) -> Key {
    (patch as u32, position_key(x))
}

/// The output mesh of `solution` in the mode of `settings`. `segments` are
/// the discontinuity segments by patch (used by `discontinuity` only).
pub fn build_mesh(
    scene: &Scene,
    bvh: &TriangleBvh,
    solution: &HierarchicalSolution,
    segments: &[Vec<Segment>],
    settings: &MeshSettings,
) -> Result<(OutputMesh, MeshStats)> {
    let h = &solution.hierarchy;
    let np = scene.patches.len();
    let mode = settings.mode;
    let mut stats = MeshStats {
        mode: mode.name().into(),
        ..MeshStats::default()
    };
    let mut inputs = match mode {
        MeshMode::Uniform => {
            let target = settings.uniform_vertices.unwrap_or(h.leaf_count()).max(1);
            uniform_points(scene, (scene.total_area() / target as f64).sqrt())
        }
        MeshMode::Quadtree | MeshMode::Discontinuity => leaf_corners(h, np),
    };
    let mut contacts: Vec<Vec<Segment>> = vec![Vec::new(); np];
    if mode == MeshMode::Discontinuity {
        let snap = 2e-5 * scene.diagonal();
        for (p, segs) in segments.iter().enumerate().take(np) {
            inputs[p].segments = segs.iter().map(|s| [s.a, s.b]).collect();
            // A leaf corner a hair off a segment would make a sliver and,
            // on a contact line, a T-vertex with the occluder's edge: it
            // goes onto the segment.
            for x in &mut inputs[p].points {
                for s in segs {
                    let (d, y) = closest_on_segment(*x, s.a, s.b);
                    if d > 0.0 && d < snap {
                        *x = y;
                    }
                }
            }
            contacts[p] = segs
                .iter()
                .filter(|s| s.kind == SegmentKind::Contact)
                .copied()
                .collect();
            stats.segments += segs.len();
        }
    }

    let points = PointEvaluator::new(scene, bvh, solution, settings.seed);
    stats.direct_emitters = points.direct_emitters().len();
    let eval = |patch: usize, x: DVec3| points.value(patch, x, LinkRays::PartlyVisible);
    let (exitance, _, _) = scene_scales(scene);
    let min_area = solution.thresholds.min_area;
    let mut cache: HashMap<Key, DVec3> = HashMap::new();
    let mut added = 0;
    let mut pass = 0;
    let tol = 1e-6 * scene.diagonal();
    let mut exchanges = 0;
    let tris = loop {
        let t = Instant::now();
        let tris = triangulate_patches(scene, &inputs, &TriangulateOptions::default())?;
        stats.triangulate_seconds += t.elapsed().as_secs_f64();
        // A contact line lies inside one patch and along another's edge:
        // each needs the other's vertices there (no T-vertices).
        if exchanges < 3 {
            let missing = contact_points(scene, &tris, &contacts, tol);
            if missing.iter().any(|m| !m.is_empty()) {
                for (input, m) in inputs.iter_mut().zip(missing) {
                    input.points.extend(m);
                }
                exchanges += 1;
                continue;
            }
        }

        let t = Instant::now();
        let mut missing: Vec<(usize, DVec3)> = Vec::new();
        let mut seen = HashSet::new();
        for (p, tri) in tris.iter().enumerate() {
            for &x in &tri.positions {
                if !cache.contains_key(&key(p, x)) && seen.insert(key(p, x)) {
                    missing.push((p, x));
                }
            }
        }
        let values: Vec<DVec3> = missing
            .par_iter()
            .with_min_len(16)
            .map(|&(p, x)| eval(p, x))
            .collect();
        stats.evaluations += missing.len();
        for (&(p, x), v) in missing.iter().zip(values) {
            cache.insert(key(p, x), v);
        }
        if pass == 0 {
            stats.initial_vertices = tris.iter().map(|t| t.positions.len()).sum();
        }
        let budget = (settings.adapt_budget * stats.initial_vertices as f64) as usize;
        let adapt = mode == MeshMode::Discontinuity
            && settings.adapt_tol > 0.0
            && pass < settings.adapt_passes
            && added < budget;
        if !adapt {
            stats.evaluate_seconds += t.elapsed().as_secs_f64();
            break tris;
        }

        // Output adaptivity: check every triangle above the minimum element
        // area at its centroid.
        let checks: Vec<(usize, DVec3, DVec3)> = tris
            .iter()
            .enumerate()
            .flat_map(|(p, tri)| {
                let cache = &cache;
                tri.triangles.iter().filter_map(move |t| {
                    let [a, b, c] = t.map(|i| tri.positions[i as usize]);
                    if !(0.5 * (b - a).cross(c - a).length() > min_area) {
                        return None;
                    }
                    let mean = t
                        .iter()
                        .map(|&i| cache[&key(p, tri.positions[i as usize])])
                        .sum::<DVec3>()
                        / 3.0;
                    Some((p, (a + b + c) / 3.0, mean))
                })
            })
            .collect();
        let excess: Vec<f64> = checks
            .par_iter()
            .with_min_len(16)
            .map(|&(p, x, interpolated)| {
                let b = eval(p, x);
                let scale =
                    settings.adapt_tol * (0.5 * (b + interpolated).max_element() + 0.01 * exitance);
                (b - interpolated).abs().max_element() / scale
            })
            .collect();
        stats.evaluations += checks.len();
        stats.evaluate_seconds += t.elapsed().as_secs_f64();
        let mut order: Vec<usize> = (0..checks.len()).filter(|&k| excess[k] > 1.0).collect();
        // Worst first; ties in check order (deterministic).
        order.sort_by(|&a, &b| excess[b].total_cmp(&excess[a]).then(a.cmp(&b)));
        order.truncate(budget - added);
        if order.is_empty() {
            break tris;
        }
        for &k in &order {
            let (p, x, _) = checks[k];
            inputs[p].points.push(x);
        }
        added += order.len();
        pass += 1;
    };
    stats.adaptive_vertices = added;

    let t = Instant::now();
    let nudge = 10.0 * ENDPOINT_GAP * scene.diagonal();
    let mut mesh = OutputMesh::default();
    for (p, tri) in tris.iter().enumerate() {
        let base = mesh.positions.len() as u32;
        let normal = scene.patches[p].normal.as_vec3();
        for &x in &tri.positions {
            mesh.positions.push(x.as_vec3());
            mesh.normals.push(normal);
            mesh.patch.push(p as u32);
            mesh.radiosity.push(cache[&key(p, x)].as_vec3());
        }
        let mut triangles = tri.triangles.clone();
        stats.constrained_edges += tri.constrained_edges.len();
        let copies = split_contact_vertices(tri, &contacts[p], tol);
        let values: Vec<DVec3> = copies
            .par_iter()
            .map(|(_, v, towards)| {
                // Off the line by more than the rays' endpoint gap, so that
                // the occluder standing there blocks them.
                let x = tri.positions[*v as usize];
                let d = *towards - x;
                points.value(p, x + d * (nudge / d.length()).min(0.5), LinkRays::Every)
            })
            .collect();
        stats.evaluations += copies.len();
        for ((slots, v, _), value) in copies.into_iter().zip(values) {
            let Some(slots) = slots else {
                mesh.radiosity[(base + v) as usize] = value.as_vec3();
                continue;
            };
            stats.split_vertices += 1;
            let copy = mesh.positions.len() as u32 - base;
            mesh.positions.push(tri.positions[v as usize].as_vec3());
            mesh.normals.push(normal);
            mesh.patch.push(p as u32);
            mesh.radiosity.push(value.as_vec3());
            for (t, corner) in slots {
                triangles[t][corner] = copy;
            }
        }
        mesh.triangles
            .extend(triangles.iter().map(|t| t.map(|i| base + i)));
    }
    stats.evaluate_seconds += t.elapsed().as_secs_f64();
    Ok((mesh, stats))
}

/// A vertex side to evaluate on a contact line: `None` for the vertex
/// itself (its first side), or the (triangle, corner) slots that move to a
/// new copy; the vertex; and a point inside the side's first triangle to
/// nudge towards.
type SideCopy = (Option<Vec<(usize, usize)>>, u32, DVec3);

/// Finds the vertices of `tri` on the contact lines `contacts` and groups
/// their triangles into sides: two triangles around a vertex are on one
/// side when they share an edge that is not on a contact line. The first
/// side keeps the vertex, each other side gets a copy (its slots in the
/// triangle list are listed for renumbering by the caller).
fn split_contact_vertices(
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
        let ts = &around[&v];
        // Disjoint sets of the triangles around v.
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
        for (k, (_, members)) in sides.into_iter().enumerate() {
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

/// The points each patch lacks along the contact lines `contacts` (by
/// patch): a contact segment of patch `a` lies along an edge of every
/// patch `b` resting there; the vertices of `a` and of those `b` on the
/// segment must be vertices of all of them.
fn contact_points(
    scene: &Scene,
    tris: &[PatchTriangulation],
    contacts: &[Vec<Segment>],
    tol: f64,
) -> Vec<Vec<DVec3>> {
    let mut add = vec![Vec::new(); tris.len()];
    for (a, segs) in contacts.iter().enumerate() {
        for s in segs {
            let mid = 0.5 * (s.a + s.b);
            let mut sharing = vec![a];
            sharing.extend((0..scene.patches.len()).filter(|&b| {
                let vs = scene.patches[b].vertices();
                b != a
                    && (0..vs.len()).any(|i| {
                        let (p, q) = (vs[i], vs[(i + 1) % vs.len()]);
                        let line = (q - p).normalize_or_zero();
                        let off_line = |x: DVec3| (x - p - (x - p).dot(line) * line).length();
                        segment_distance(mid, p, q) <= tol
                            && off_line(s.a) <= tol
                            && off_line(s.b) <= tol
                    })
            }));
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

/// The corners of every leaf, per patch.
fn leaf_corners(h: &Hierarchy, np: usize) -> Vec<PatchInput> {
    let mut inputs = vec![PatchInput::default(); np];
    for id in h.leaves() {
        let e = h.get(id);
        inputs[e.patch as usize]
            .points
            .extend_from_slice(e.vertices());
    }
    inputs
}

/// A regular grid of spacing `spacing` in each patch's plane, keeping the
/// points at least a quarter spacing inside, and points at about that
/// spacing along every edge.
fn uniform_points(scene: &Scene, spacing: f64) -> Vec<PatchInput> {
    scene
        .patches
        .iter()
        .map(|patch| {
            let vs = patch.vertices();
            let u = (vs[1] - vs[0]).normalize_or_zero();
            let v = patch.normal.cross(u);
            let mut points = Vec::new();
            for (i, &a) in vs.iter().enumerate() {
                let b = vs[(i + 1) % vs.len()];
                let n = ((b - a).length() / spacing).ceil().max(1.0) as usize;
                points.extend((1..n).map(|k| a + (b - a) * (k as f64 / n as f64)));
            }
            let (lo_u, hi_u, lo_v, hi_v) = vs.iter().fold(
                (
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                ),
                |(a, b, c, d), &p| {
                    let (pu, pv) = ((p - vs[0]).dot(u), (p - vs[0]).dot(v));
                    (a.min(pu), b.max(pu), c.min(pv), d.max(pv))
                },
            );
            // Centred in the patch's bounding rectangle.
            let nu = ((hi_u - lo_u) / spacing).floor() as usize;
            let nv = ((hi_v - lo_v) / spacing).floor() as usize;
            let u0 = 0.5 * (lo_u + hi_u - nu as f64 * spacing);
            let v0 = 0.5 * (lo_v + hi_v - nv as f64 * spacing);
            for i in 0..=nu {
                for j in 0..=nv {
                    let x = vs[0] + (u0 + i as f64 * spacing) * u + (v0 + j as f64 * spacing) * v;
                    if outside_polygon(vs, patch.normal, x) < -0.25 * spacing {
                        points.push(x);
                    }
                }
            }
            PatchInput {
                points,
                segments: Vec::new(),
            }
        })
        .collect()
}
