//! Shadow discontinuity segments on receiver patches: the D0 contact lines
//! where an occluder touches a receiver, and the D1 lines of the critical
//! wedges of the primary emitters [LTG92] [LTG93].
//!
//! Owns: the occluder edge graph (welded by exact vertex position), the
//! luminaires (emitter patches merged into convex polygons), the VE and EV
//! wedges, their tracing onto receivers, and the significance ranking.
//!
//! A wedge is a planar region in which a visibility event between an emitter
//! and an occluder happens:
//!
//! ```text
//!   VE: emitter vertex v, occluder edge ab       EV: emitter edge w0w1, occluder vertex p
//!          v                                         w0 ------ w1
//!         / \                                           \    /
//!        a---b     <- occluder edge                      \  /
//!       /     \                                           p        <- occluder vertex
//!      /wedge  \   <- beyond ab, away from v             / \
//!                                                       /wedge
//! ```
//!
//! A wedge is kept only when it is critical: the emitter lies entirely on one
//! side of its plane (for VE, the emitter's other vertices; for EV, always
//! true of a convex emitter's edge) and the occluder is tangent to it (for VE,
//! every triangle on the edge lies on one side; for EV, every triangle
//! touching the vertex does). Such a wedge bounds the region where a part of
//! the emitter starts or stops being hidden: a gradient (D1) discontinuity of
//! the direct light, or the umbra/penumbra boundary.
//!
//! Invariants:
//! - Every segment lies in its receiver's plane (the plane through the patch
//!   centroid with the patch normal) and inside its polygon; segments along
//!   the polygon's own boundary are dropped.
//! - Collinear overlapping segments on one patch are merged; crossing
//!   segments are left whole (splitting is the triangulator's job).
//! - The result does not depend on the thread count: work is split into
//!   ordered jobs and collected in order.
//!
//! Approximations (documented, deliberate):
//! - A wedge's trace is clipped by ray-cast visibility at a handful of points
//!   along the segment (source → occluder feature → receiver point), with
//!   bisection at changes; an occluded stretch shorter than the sample
//!   spacing can be missed.
//! - Only wedges of luminaires with at least `min_emitter_fraction` of the
//!   strongest luminaire's power are traced; EEE events are not.
//! - Significance is the unoccluded irradiance of the wedge's luminaire at
//!   the segment midpoint, relative to the scene's mean emitted exitance.
//! - Receivers of a wedge are found by a linear scan of the patches facing
//!   its luminaire, culled by the wedge's bounding box within the scene: cost
//!   O(wedges × receivers), about 0.2 s for the 5,902-triangle three-room
//!   scene on 2 cores.
//! - Emitter patches that do not merge into one convex luminaire are traced
//!   separately, so their shared vertices make lines that cancel in the sum.
//!
//! References: [LTG92] Lischinski, Tampieri, Greenberg, "Discontinuity
//! meshing for accurate radiosity", IEEE CG&A 1992; [LTG93] "Combining
//! hierarchical radiosity and discontinuity meshing", SIGGRAPH 1993.

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

use crate::formfactor::form_factor_point_polygon;
use crate::scene::{Scene, polygon_area_normal};
use crate::visibility::TriangleBvh;

/// Sidedness tolerance for planes, as a fraction of the scene diagonal.
const PLANE_TOL: f64 = 1e-7;
/// How far an occluder edge may be from a receiver plane and still touch it.
const CONTACT_TOL: f64 = 1e-6;
/// Segments shorter than this fraction of the diagonal are dropped.
const MIN_LENGTH: f64 = 1e-5;
/// A segment this close to one of its polygon's edge lines along its whole
/// length lies on the boundary and is dropped.
const BOUNDARY_TOL: f64 = 1e-5;
/// Collinear segments within this distance (fraction of the diagonal) and
/// angle (radians) are merged.
const MERGE_DIST: f64 = 1e-6;
const MERGE_ANGLE: f64 = 1e-6;
/// Bisection steps locating a change of visibility along a segment.
const BISECTIONS: usize = 10;
/// Visibility samples along a segment: one per this fraction of the
/// diagonal, within the bounds below.
const SAMPLE_SPACING: f64 = 0.01;
const MIN_SAMPLES: usize = 5;
const MAX_SAMPLES: usize = 33;

/// What produced a segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SegmentKind {
    /// D0: an occluder edge resting on the receiver.
    Contact,
    /// D1: emitter vertex × occluder edge.
    Ve,
    /// D1: emitter edge × occluder vertex.
    Ev,
}

/// A discontinuity segment on one receiver patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Index into [`Scene::patches`].
    pub patch: u32,
    pub a: DVec3,
    pub b: DVec3,
    pub kind: SegmentKind,
    /// The luminaire whose wedge made the segment, named by its lowest patch
    /// index; `None` for contact lines, which belong to no emitter.
    pub emitter: Option<u32>,
    /// Significance: the unoccluded irradiance at the midpoint from the
    /// segment's luminaire (from every luminaire, for contact lines) over the
    /// scene's mean emitted exitance.
    pub weight: f64,
}

/// Knobs of [`discontinuity_segments`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct DiscontinuitySettings {
    /// A luminaire is traced when its power is at least this fraction of the
    /// strongest luminaire's.
    pub min_emitter_fraction: f64,
    /// A D1 segment is kept when its weight is at least this.
    pub min_contribution: f64,
    /// At most this many segments in all; contact lines go first, then D1
    /// segments by decreasing weight.
    pub max_segments: usize,
    /// Trace D1 wedges; when false only contact lines are found.
    pub include_d1: bool,
}

impl Default for DiscontinuitySettings {
    /// 1 % of the strongest luminaire; 0.1 % of the mean exitance (about a
    /// hundredth of the direct light on a Cornell box floor); 20 000
    /// segments; D1 on.
    fn default() -> Self {
        DiscontinuitySettings {
            min_emitter_fraction: 1e-2,
            min_contribution: 1e-3,
            max_segments: 20_000,
            include_d1: true,
        }
    }
}

/// Counts gathered while finding discontinuities.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DiscontinuityStats {
    /// Luminaires traced (after the power threshold).
    pub luminaires: usize,
    /// (luminaire, occluder edge) pairs that passed the silhouette test.
    pub silhouette_edges: usize,
    /// Critical wedges traced.
    pub wedges: usize,
    /// Visibility rays cast.
    pub rays: usize,
    /// Segments before merging and the budget.
    pub raw_segments: usize,
    /// Segments removed by `max_segments`.
    pub dropped_by_budget: usize,
}

/// The segments, ordered by patch, and the counters.
#[derive(Clone, Debug, Default)]
pub struct Discontinuities {
    pub segments: Vec<Segment>,
    pub stats: DiscontinuityStats,
}

impl Discontinuities {
    /// The segments of each patch, indexed by patch.
    pub fn by_patch(&self, n_patches: usize) -> Vec<Vec<Segment>> {
        let mut out = vec![Vec::new(); n_patches];
        for s in &self.segments {
            if let Some(v) = out.get_mut(s.patch as usize) {
                v.push(*s);
            }
        }
        out
    }
}

/// Finds the contact lines and, when enabled, the D1 wedge traces of the
/// significant luminaires on every receiver patch of `scene`. `bvh` must hold
/// `scene.triangles` (see `pipeline::scene_bvh`).
pub fn discontinuity_segments(
    scene: &Scene,
    bvh: &TriangleBvh,
    settings: &DiscontinuitySettings,
) -> Discontinuities {
    let ctx = Context::new(scene, bvh, settings);
    let mut stats = DiscontinuityStats {
        luminaires: ctx.luminaires.len(),
        ..DiscontinuityStats::default()
    };

    let mut raw: Vec<Segment> = ctx.contacts();
    if settings.include_d1 {
        let jobs: Vec<(usize, Job)> = (0..ctx.luminaires.len())
            .flat_map(|l| ctx.jobs(l, &mut stats).into_iter().map(move |j| (l, j)))
            .collect();
        let traced: Vec<(Vec<Segment>, usize, usize)> = jobs
            .par_iter()
            .map(|&(l, job)| ctx.run_job(l, job))
            .collect();
        for (segs, wedges, rays) in traced {
            raw.extend(segs);
            stats.wedges += wedges;
            stats.rays += rays;
        }
    }
    stats.raw_segments = raw.len();

    let mut segments = merge_collinear(raw, scene);
    let before = segments.len();
    apply_budget(&mut segments, settings.max_segments);
    stats.dropped_by_budget = before - segments.len();
    Discontinuities { segments, stats }
}

/// A unit of parallel work for one luminaire.
#[derive(Clone, Copy, Debug)]
enum Job {
    /// VE wedges of every luminaire vertex with this occluder edge (clipped
    /// to the luminaire's front half-space).
    Edge(u32, DVec3, DVec3),
    /// EV wedges of every luminaire edge with this occluder vertex.
    Vertex(u32),
}

/// An emitter polygon: one emitter patch, or several coplanar adjacent ones
/// of one surface and emission whose union is convex.
struct Luminaire {
    polygon: Vec<DVec3>,
    normal: DVec3,
    /// Scalar (channel-mean) exitance.
    exitance: f64,
    power: f64,
    /// Lowest patch index: the luminaire's name in segments.
    patch: u32,
    patches: Vec<u32>,
    /// Receivers facing this luminaire.
    receivers: Vec<u32>,
}

/// A receiver patch, projected exactly onto its plane.
struct Receiver {
    polygon: Vec<DVec3>,
    normal: DVec3,
    center: DVec3,
    lo: DVec3,
    hi: DVec3,
}

impl Receiver {
    fn distance(&self, p: DVec3) -> f64 {
        (p - self.center).dot(self.normal)
    }
}

/// An edge of the welded occluder graph.
struct Edge {
    a: u32,
    b: u32,
    /// Triangles (indices into `scene.triangles`) on this edge.
    triangles: Vec<u32>,
    /// Shared by exactly two coplanar triangles that continue each other:
    /// never a silhouette.
    flat: bool,
}

struct Context<'a> {
    scene: &'a Scene,
    bvh: &'a TriangleBvh,
    settings: &'a DiscontinuitySettings,
    diagonal: f64,
    lo: DVec3,
    hi: DVec3,
    vertices: Vec<DVec3>,
    /// Triangles touching each vertex.
    vertex_triangles: Vec<Vec<u32>>,
    edges: Vec<Edge>,
    receivers: Vec<Receiver>,
    luminaires: Vec<Luminaire>,
    /// Scalar mean exitance over all emitting area.
    mean_exitance: f64,
}

fn scalar(v: DVec3) -> f64 {
    (v.x + v.y + v.z) / 3.0
}

type Key = [u64; 3];

fn key(p: DVec3) -> Key {
    [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits)
}

impl<'a> Context<'a> {
    fn new(
        scene: &'a Scene,
        bvh: &'a TriangleBvh,
        settings: &'a DiscontinuitySettings,
    ) -> Context<'a> {
        let diagonal = scene.diagonal();
        let pad = DVec3::splat(CONTACT_TOL * diagonal);
        let (lo, hi) = (scene.bounds.0 - pad, scene.bounds.1 + pad);

        // Weld vertices by exact position, in order of first appearance.
        let mut ids: HashMap<Key, u32> = HashMap::new();
        let mut vertices = Vec::new();
        let mut vertex_triangles: Vec<Vec<u32>> = Vec::new();
        let mut tri_vertices = Vec::with_capacity(scene.triangles.len());
        for (t, tri) in scene.triangles.iter().enumerate() {
            let v = tri.positions.map(|p| {
                *ids.entry(key(p)).or_insert_with(|| {
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
        let tol = PLANE_TOL * diagonal;
        for e in &mut edges {
            if let [t1, t2] = e.triangles[..] {
                let (pa, pb) = (vertices[e.a as usize], vertices[e.b as usize]);
                let (_, n1) = polygon_area_normal(&scene.triangles[t1 as usize].positions);
                let c1 = third(&scene.triangles[t1 as usize].positions, pa, pb);
                let c2 = third(&scene.triangles[t2 as usize].positions, pa, pb);
                // Coplanar, and the triangles lie on opposite sides of the edge.
                let along = (pb - pa).normalize_or_zero();
                let side = n1.cross(along);
                e.flat = (c2 - pa).dot(n1).abs() <= tol
                    && (c1 - pa).dot(side) * (c2 - pa).dot(side) < 0.0;
            }
        }

        let receivers: Vec<Receiver> = scene
            .patches
            .iter()
            .map(|p| {
                let center = p.centroid();
                let n = p.normal;
                let polygon: Vec<DVec3> = p
                    .vertices()
                    .iter()
                    .map(|&v| v - (v - center).dot(n) * n)
                    .collect();
                let (mut rlo, mut rhi) = (polygon[0], polygon[0]);
                for &v in &polygon {
                    rlo = rlo.min(v);
                    rhi = rhi.max(v);
                }
                Receiver {
                    polygon,
                    normal: n,
                    center,
                    lo: rlo - pad,
                    hi: rhi + pad,
                }
            })
            .collect();

        let (power, area) = scene
            .patches
            .iter()
            .filter(|p| p.is_emitter())
            .fold((0.0, 0.0), |(w, a), p| {
                (w + scalar(p.emission) * p.area, a + p.area)
            });
        let mean_exitance = if area > 0.0 { power / area } else { 0.0 };

        let mut luminaires = luminaires(scene, diagonal);
        let strongest = luminaires.iter().map(|l| l.power).fold(0.0, f64::max);
        luminaires
            .retain(|l| l.power > 0.0 && l.power >= settings.min_emitter_fraction * strongest);
        for l in &mut luminaires {
            let own = &l.patches;
            l.receivers = (0..receivers.len() as u32)
                .filter(|r| !own.contains(r))
                .filter(|&r| {
                    let rec = &receivers[r as usize];
                    let lit = l.polygon.iter().any(|&v| rec.distance(v) > tol);
                    let ahead = rec
                        .polygon
                        .iter()
                        .any(|&v| (v - l.polygon[0]).dot(l.normal) > tol);
                    lit && ahead
                })
                .collect();
        }

        Context {
            scene,
            bvh,
            settings,
            diagonal,
            lo,
            hi,
            vertices,
            vertex_triangles,
            edges,
            receivers,
            luminaires,
            mean_exitance,
        }
    }

    fn tol(&self) -> f64 {
        PLANE_TOL * self.diagonal
    }

    /// Unoccluded irradiance at `x` on receiver `r` from luminaire `l`, over
    /// the mean exitance.
    fn weight(&self, l: &Luminaire, r: u32, x: DVec3) -> f64 {
        if !(self.mean_exitance > 0.0) {
            return 0.0;
        }
        let n = self.receivers[r as usize].normal;
        form_factor_point_polygon(x, n, &l.polygon) * l.exitance / self.mean_exitance
    }

    /// D0: occluder edges lying in a receiver's plane with a triangle rising
    /// in front of it, clipped to the receiver polygon.
    fn contacts(&self) -> Vec<Segment> {
        let tol_c = CONTACT_TOL * self.diagonal;
        let per_edge: Vec<Vec<Segment>> = self
            .edges
            .par_iter()
            .map(|e| {
                let mut out = Vec::new();
                if e.flat {
                    return out;
                }
                let (pa, pb) = (self.vertices[e.a as usize], self.vertices[e.b as usize]);
                let (elo, ehi) = (pa.min(pb), pa.max(pb));
                for (r, rec) in self.receivers.iter().enumerate() {
                    if !overlaps(elo, ehi, rec.lo, rec.hi) {
                        continue;
                    }
                    if rec.distance(pa).abs() > tol_c || rec.distance(pb).abs() > tol_c {
                        continue;
                    }
                    let rises = e.triangles.iter().any(|&t| {
                        let c = third(&self.scene.triangles[t as usize].positions, pa, pb);
                        rec.distance(c) > tol_c
                    });
                    if !rises {
                        continue;
                    }
                    let project = |p: DVec3| p - rec.distance(p) * rec.normal;
                    let Some((a, b)) =
                        clip_to_polygon(&rec.polygon, rec.normal, project(pa), project(pb))
                    else {
                        continue;
                    };
                    if !self.keepable(rec, a, b) {
                        continue;
                    }
                    let mid = 0.5 * (a + b);
                    let weight = self
                        .luminaires
                        .iter()
                        .filter(|l| l.receivers.binary_search(&(r as u32)).is_ok())
                        .map(|l| self.weight(l, r as u32, mid))
                        .sum();
                    out.push(Segment {
                        patch: r as u32,
                        a,
                        b,
                        kind: SegmentKind::Contact,
                        emitter: None,
                        weight,
                    });
                }
                out
            })
            .collect();
        per_edge.into_iter().flatten().collect()
    }

    /// Long enough and not along the polygon boundary.
    fn keepable(&self, rec: &Receiver, a: DVec3, b: DVec3) -> bool {
        if !((b - a).length() >= MIN_LENGTH * self.diagonal) {
            return false;
        }
        let tol_b = BOUNDARY_TOL * self.diagonal;
        let n = rec.polygon.len();
        !(0..n).any(|i| {
            let (p, q) = (rec.polygon[i], rec.polygon[(i + 1) % n]);
            line_distance(p, q, a) <= tol_b && line_distance(p, q, b) <= tol_b
        })
    }

    /// The jobs of luminaire `l`: its silhouette edges, then its silhouette
    /// vertices, in edge order.
    fn jobs(&self, l: usize, stats: &mut DiscontinuityStats) -> Vec<Job> {
        let lum = &self.luminaires[l];
        let tol = self.tol();
        let front = |p: DVec3| (p - lum.polygon[0]).dot(lum.normal);
        let mut jobs = Vec::new();
        let mut vertex_seen = vec![false; self.vertices.len()];
        let mut vertex_jobs = Vec::new();
        for (i, e) in self.edges.iter().enumerate() {
            if e.flat {
                continue;
            }
            let own = e.triangles.iter().all(|&t| {
                let tri = &self.scene.triangles[t as usize];
                lum.patches.contains(&tri.front_patch)
                    || tri.back_patch.is_some_and(|b| lum.patches.contains(&b))
            });
            if own {
                continue;
            }
            let (pa, pb) = (self.vertices[e.a as usize], self.vertices[e.b as usize]);
            let Some((a, b)) = clip_to_half_space(pa, pb, lum.polygon[0], lum.normal, tol) else {
                continue;
            };
            if !self.maybe_silhouette(e, pa, pb, lum) {
                continue;
            }
            stats.silhouette_edges += 1;
            jobs.push(Job::Edge(i as u32, a, b));
            for (v, p) in [(e.a, pa), (e.b, pb)] {
                if front(p) > tol && !vertex_seen[v as usize] {
                    vertex_seen[v as usize] = true;
                    vertex_jobs.push(Job::Vertex(v));
                }
            }
        }
        jobs.extend(vertex_jobs);
        jobs
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
        let all = |n: DVec3, front: bool| {
            lum.polygon.iter().all(|&v| {
                let d = (v - pa).dot(n);
                if front { d >= -tol } else { d <= tol }
            })
        };
        let both_front = all(n1, true) && all(n2, true);
        let both_back = all(n1, false) && all(n2, false);
        !(both_front || both_back)
    }

    /// Traces the wedges of one job: (segments, wedges traced, rays cast).
    fn run_job(&self, l: usize, job: Job) -> (Vec<Segment>, usize, usize) {
        let lum = &self.luminaires[l];
        let tol = self.tol();
        let mut out = Vec::new();
        let mut wedges = 0;
        let mut rays = 0;
        let poly = &lum.polygon;
        let nv = poly.len();
        match job {
            Job::Edge(e, a, b) => {
                let edge = &self.edges[e as usize];
                let (pa, pb) = (
                    self.vertices[edge.a as usize],
                    self.vertices[edge.b as usize],
                );
                for i in 0..nv {
                    let v = poly[i];
                    let m = (a - v).cross(b - v);
                    let len = m.length();
                    if !(len > 1e-12 * (a - v).length() * (b - v).length()) {
                        continue;
                    }
                    let m = m / len;
                    let emitter_one_side = one_side(
                        (0..nv).filter(|&j| j != i).map(|j| (poly[j] - v).dot(m)),
                        tol,
                    );
                    let occluder_tangent = one_side(
                        edge.triangles.iter().map(|&t| {
                            (third(&self.scene.triangles[t as usize].positions, pa, pb) - v).dot(m)
                        }),
                        tol,
                    );
                    if !(emitter_one_side && occluder_tangent) {
                        continue;
                    }
                    wedges += 1;
                    let wedge = Wedge::ve(v, a, b, m);
                    rays += self.trace(lum, &wedge, &mut out);
                }
            }
            Job::Vertex(p) => {
                let pv = self.vertices[p as usize];
                for i in 0..nv {
                    let (w0, w1) = (poly[i], poly[(i + 1) % nv]);
                    let m = (w1 - w0).cross(pv - w0);
                    let len = m.length();
                    if !(len > 1e-12 * (w1 - w0).length() * (pv - w0).length()) {
                        continue;
                    }
                    let m = m / len;
                    let emitter_one_side = one_side(poly.iter().map(|&q| (q - w0).dot(m)), tol);
                    let occluder_tangent = one_side(
                        self.vertex_triangles[p as usize].iter().flat_map(|&t| {
                            self.scene.triangles[t as usize]
                                .positions
                                .map(|q| (q - pv).dot(m))
                        }),
                        tol,
                    );
                    if !(emitter_one_side && occluder_tangent) {
                        continue;
                    }
                    wedges += 1;
                    let wedge = Wedge::ev(w0, w1, pv, m);
                    rays += self.trace(lum, &wedge, &mut out);
                }
            }
        }
        (out, wedges, rays)
    }

    /// Traces one wedge onto the luminaire's receivers; returns rays cast.
    fn trace(&self, lum: &Luminaire, wedge: &Wedge, out: &mut Vec<Segment>) -> usize {
        let tol = self.tol();
        let (wlo, whi) = wedge.bounds(self.lo, self.hi);
        let mut rays = 0;
        for &r in &lum.receivers {
            let rec = &self.receivers[r as usize];
            if !overlaps(wlo, whi, rec.lo, rec.hi) {
                continue;
            }
            // The occluder feature must stand in front of the receiver, not
            // in its plane, and the light must come from its front.
            let feature_front = wedge
                .base
                .iter()
                .map(|&p| rec.distance(p))
                .fold(f64::MIN, f64::max);
            let feature_on_plane = wedge.base.iter().all(|&p| rec.distance(p).abs() <= tol);
            let source_front = wedge.source.iter().any(|&p| rec.distance(p) > tol);
            if feature_on_plane || !(feature_front > tol) || !source_front {
                continue;
            }
            let Some((mut a, mut b)) = plane_chord(&rec.polygon, wedge.normal, wedge.offset, tol)
            else {
                continue;
            };
            let mut inside = true;
            for &(o, k) in &wedge.half_planes[..wedge.n_half_planes] {
                match clip_segment(a, b, o, k) {
                    Some((p, q)) => (a, b) = (p, q),
                    None => {
                        inside = false;
                        break;
                    }
                }
            }
            if !inside || !self.keepable(rec, a, b) {
                continue;
            }
            if !(self.weight(lum, r, 0.5 * (a + b)) >= self.settings.min_contribution) {
                continue;
            }
            let len = (b - a).length();
            let k = ((len / (SAMPLE_SPACING * self.diagonal)).ceil() as usize)
                .clamp(MIN_SAMPLES, MAX_SAMPLES);
            let mut cast = 0;
            let runs = visible_runs(k, |u| {
                cast += 2;
                wedge.unblocked(self.bvh, a.lerp(b, u))
            });
            rays += cast;
            for (u0, u1) in runs {
                let (p, q) = (a.lerp(b, u0), a.lerp(b, u1));
                if !self.keepable(rec, p, q) {
                    continue;
                }
                let weight = self.weight(lum, r, 0.5 * (p + q));
                if weight >= self.settings.min_contribution {
                    out.push(Segment {
                        patch: r,
                        a: p,
                        b: q,
                        kind: wedge.kind,
                        emitter: Some(lum.patch),
                        weight,
                    });
                }
            }
        }
        rays
    }
}

/// A critical wedge: its plane, the in-plane half-planes bounding it, and
/// the features that generate it.
struct Wedge {
    kind: SegmentKind,
    normal: DVec3,
    offset: f64,
    /// (point, in-plane normal): the region is k · (x − o) ≥ 0 for each.
    half_planes: [(DVec3, DVec3); 3],
    n_half_planes: usize,
    /// Occluder feature: the edge (VE) or the vertex twice (EV).
    base: [DVec3; 2],
    /// Emitter feature: the vertex twice (VE) or the edge (EV).
    source: [DVec3; 2],
    /// Directions from `base` outward along the wedge's two side rays.
    directions: [DVec3; 2],
}

impl Wedge {
    fn ve(v: DVec3, a: DVec3, b: DVec3, m: DVec3) -> Wedge {
        let toward = |k: DVec3, o: DVec3, inside: DVec3| {
            if k.dot(inside - o) < 0.0 { -k } else { k }
        };
        let k1 = toward(m.cross(a - v), v, b);
        let k2 = toward(m.cross(b - v), v, a);
        let k3 = -toward(m.cross(b - a), a, v);
        Wedge {
            kind: SegmentKind::Ve,
            normal: m,
            offset: m.dot(v),
            half_planes: [(v, k1), (v, k2), (a, k3)],
            n_half_planes: 3,
            base: [a, b],
            source: [v, v],
            directions: [a - v, b - v],
        }
    }

    fn ev(w0: DVec3, w1: DVec3, p: DVec3, m: DVec3) -> Wedge {
        let (d0, d1) = (p - w0, p - w1);
        let orient = |k: DVec3, d: DVec3| if k.dot(d) < 0.0 { -k } else { k };
        let k1 = orient(m.cross(d0), d1);
        let k2 = orient(m.cross(d1), d0);
        Wedge {
            kind: SegmentKind::Ev,
            normal: m,
            offset: m.dot(p),
            half_planes: [(p, k1), (p, k2), (p, DVec3::ZERO)],
            n_half_planes: 2,
            base: [p, p],
            source: [w0, w1],
            directions: [d0, d1],
        }
    }

    /// A box holding the wedge's part inside the scene box `(lo, hi)`: along
    /// each axis the wedge is unbounded wherever a side ray heads.
    fn bounds(&self, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
        let mut wlo = self.base[0].min(self.base[1]);
        let mut whi = self.base[0].max(self.base[1]);
        for d in self.directions {
            for k in 0..3 {
                if d[k] < 0.0 {
                    wlo[k] = lo[k];
                }
                if d[k] > 0.0 {
                    whi[k] = hi[k];
                }
            }
        }
        (wlo.max(lo), whi.min(hi))
    }

    /// True when the wedge's line through `x` is clear from the emitter
    /// feature to the occluder feature and from there to `x`.
    fn unblocked(&self, bvh: &TriangleBvh, x: DVec3) -> bool {
        let m = self.normal;
        // The point of segment (p, q) on the line through `apex` and `x`.
        let meet = |p: DVec3, q: DVec3, apex: DVec3| {
            let num = (p - apex).cross(x - apex).dot(m);
            let den = (q - p).cross(x - apex).dot(m);
            let s = if den.abs() > 0.0 {
                (-num / den).clamp(0.0, 1.0)
            } else {
                0.5
            };
            p.lerp(q, s)
        };
        let (from, through) = match self.kind {
            SegmentKind::Ev => {
                let p = self.base[0];
                (meet(self.source[0], self.source[1], p), p)
            }
            _ => {
                let v = self.source[0];
                (v, meet(self.base[0], self.base[1], v))
            }
        };
        bvh.visible(from, through) && bvh.visible(through, x)
    }
}

/// Intervals of [0, 1] where `visible` holds, from `k` bin-centre samples
/// refined by bisection at each change; an end bin that is visible extends
/// its interval to the end.
fn visible_runs(k: usize, mut visible: impl FnMut(f64) -> bool) -> Vec<(f64, f64)> {
    let u = |i: usize| (i as f64 + 0.5) / k as f64;
    let status: Vec<bool> = (0..k).map(|i| visible(u(i))).collect();
    let mut runs = Vec::new();
    let mut start: Option<f64> = if status[0] { Some(0.0) } else { None };
    for i in 1..k {
        if status[i] == status[i - 1] {
            continue;
        }
        // Bisect between the two sample points.
        let (mut lo, mut hi) = (u(i - 1), u(i));
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (lo + hi);
            if visible(mid) == status[i - 1] {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let edge = 0.5 * (lo + hi);
        match start.take() {
            Some(s) => runs.push((s, edge)),
            None => start = Some(edge),
        }
    }
    if let Some(s) = start {
        runs.push((s, 1.0));
    }
    runs
}

/// The triangle vertex that is neither `a` nor `b` (the farthest from the
/// edge line, which is robust to welding).
fn third(t: &[DVec3; 3], a: DVec3, b: DVec3) -> DVec3 {
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

/// Distance from `x` to the line through `p` and `q`.
fn line_distance(p: DVec3, q: DVec3, x: DVec3) -> f64 {
    let d = q - p;
    let len = d.length();
    if len > 0.0 {
        d.cross(x - p).length() / len
    } else {
        (x - p).length()
    }
}

/// True when all values are ≥ −tol or all are ≤ tol.
fn one_side(values: impl Iterator<Item = f64>, tol: f64) -> bool {
    let (mut pos, mut neg) = (false, false);
    for d in values {
        pos |= d > tol;
        neg |= d < -tol;
    }
    !(pos && neg)
}

fn overlaps(alo: DVec3, ahi: DVec3, blo: DVec3, bhi: DVec3) -> bool {
    alo.cmple(bhi).all() && blo.cmple(ahi).all()
}

/// The part of segment (a, b) with (x − o) · n ≥ tol.
fn clip_to_half_space(a: DVec3, b: DVec3, o: DVec3, n: DVec3, tol: f64) -> Option<(DVec3, DVec3)> {
    let (da, db) = ((a - o).dot(n) - tol, (b - o).dot(n) - tol);
    match (da >= 0.0, db >= 0.0) {
        (true, true) => Some((a, b)),
        (false, false) => None,
        (true, false) => Some((a, a + (da / (da - db)) * (b - a))),
        (false, true) => Some((a + (da / (da - db)) * (b - a), b)),
    }
}

/// The part of segment (a, b) with k · (x − o) ≥ 0.
fn clip_segment(a: DVec3, b: DVec3, o: DVec3, k: DVec3) -> Option<(DVec3, DVec3)> {
    let (fa, fb) = (k.dot(a - o), k.dot(b - o));
    match (fa >= 0.0, fb >= 0.0) {
        (true, true) => Some((a, b)),
        (false, false) => None,
        (true, false) => Some((a, a.lerp(b, fa / (fa - fb)))),
        (false, true) => Some((a.lerp(b, fa / (fa - fb)), b)),
    }
}

/// Segment (a, b), in the plane of the convex counter-clockwise `polygon`
/// with normal `n`, clipped to the polygon.
fn clip_to_polygon(polygon: &[DVec3], n: DVec3, a: DVec3, b: DVec3) -> Option<(DVec3, DVec3)> {
    let (mut a, mut b) = (a, b);
    let m = polygon.len();
    for i in 0..m {
        let (p, q) = (polygon[i], polygon[(i + 1) % m]);
        let k = n.cross(q - p);
        (a, b) = clip_segment(a, b, p, k)?;
    }
    Some((a, b))
}

/// The chord cut from a convex polygon by the plane m · x = d.
fn plane_chord(polygon: &[DVec3], m: DVec3, d: f64, tol: f64) -> Option<(DVec3, DVec3)> {
    let s: Vec<f64> = polygon.iter().map(|&p| m.dot(p) - d).collect();
    if s.iter().all(|x| x.abs() <= tol) {
        return None; // the polygon lies in the plane
    }
    let n = polygon.len();
    let mut points: Vec<DVec3> = Vec::with_capacity(4);
    for i in 0..n {
        let j = (i + 1) % n;
        if s[i].abs() <= tol {
            points.push(polygon[i]);
        } else if (s[i] > tol && s[j] < -tol) || (s[i] < -tol && s[j] > tol) {
            let t = s[i] / (s[i] - s[j]);
            points.push(polygon[i].lerp(polygon[j], t));
        }
    }
    let mut best: Option<(DVec3, DVec3)> = None;
    let mut far = 0.0;
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            let d = (points[j] - points[i]).length();
            if d > far {
                far = d;
                best = Some((points[i], points[j]));
            }
        }
    }
    best
}

/// Groups emitter patches into luminaires: adjacent (sharing an edge),
/// coplanar patches of one surface and one emission whose union is convex
/// become one polygon; others stay single patches. Ordered by lowest patch.
fn luminaires(scene: &Scene, diagonal: f64) -> Vec<Luminaire> {
    let emitters: Vec<u32> = (0..scene.patches.len() as u32)
        .filter(|&i| scene.patches[i as usize].is_emitter())
        .collect();
    let tol = PLANE_TOL * diagonal;
    // Union-find over emitters through shared edges.
    let mut parent: Vec<usize> = (0..emitters.len()).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut edge_owner: HashMap<(Key, Key), usize> = HashMap::new();
    for (k, &p) in emitters.iter().enumerate() {
        let v = scene.patches[p as usize].vertices();
        for i in 0..v.len() {
            let (a, b) = (key(v[i]), key(v[(i + 1) % v.len()]));
            // A neighbour walks the shared edge the other way.
            if let Some(&other) = edge_owner.get(&(b, a)) {
                let (pi, po) = (
                    &scene.patches[p as usize],
                    &scene.patches[emitters[other] as usize],
                );
                let same = pi.surface == po.surface
                    && pi.emission == po.emission
                    && pi.normal.dot(po.normal) > 1.0 - 1e-12
                    && po
                        .vertices()
                        .iter()
                        .all(|&q| (q - pi.corners[0]).dot(pi.normal).abs() <= tol);
                if same {
                    let (x, y) = (find(&mut parent, k), find(&mut parent, other));
                    let (x, y) = (x.min(y), x.max(y));
                    parent[y] = x;
                }
            }
            edge_owner.insert((a, b), k);
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut group_of: HashMap<usize, usize> = HashMap::new();
    for k in 0..emitters.len() {
        let root = find(&mut parent, k);
        let g = *group_of.entry(root).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(k);
    }
    let single = |p: u32| {
        let patch = &scene.patches[p as usize];
        Luminaire {
            polygon: patch.vertices().to_vec(),
            normal: patch.normal,
            exitance: scalar(patch.emission),
            power: scalar(patch.emission) * patch.area,
            patch: p,
            patches: vec![p],
            receivers: Vec::new(),
        }
    };
    let mut out = Vec::new();
    for g in groups {
        let patches: Vec<u32> = g.iter().map(|&k| emitters[k]).collect();
        match union_polygon(scene, &patches) {
            Some(polygon) if patches.len() > 1 => {
                let first = &scene.patches[patches[0] as usize];
                let (area, _) = polygon_area_normal(&polygon);
                out.push(Luminaire {
                    polygon,
                    normal: first.normal,
                    exitance: scalar(first.emission),
                    power: scalar(first.emission) * area,
                    patch: patches[0],
                    patches,
                    receivers: Vec::new(),
                });
            }
            _ => out.extend(patches.into_iter().map(single)),
        }
    }
    out
}

/// The boundary of the union of coplanar, edge-sharing patches, without
/// collinear vertices, when it is one convex loop.
fn union_polygon(scene: &Scene, patches: &[u32]) -> Option<Vec<DVec3>> {
    let mut directed: Vec<(DVec3, DVec3)> = Vec::new();
    for &p in patches {
        let v = scene.patches[p as usize].vertices();
        for i in 0..v.len() {
            directed.push((v[i], v[(i + 1) % v.len()]));
        }
    }
    let keys: Vec<(Key, Key)> = directed.iter().map(|&(a, b)| (key(a), key(b))).collect();
    let mut count: HashMap<(Key, Key), usize> = HashMap::new();
    for &k in &keys {
        *count.entry(k).or_default() += 1;
    }
    let mut next: HashMap<Key, DVec3> = HashMap::new();
    let mut start = None;
    for (i, &(a, b)) in keys.iter().enumerate() {
        if count.contains_key(&(b, a)) {
            continue; // interior edge
        }
        if next.insert(a, directed[i].1).is_some() {
            return None; // a vertex where the boundary touches itself
        }
        start.get_or_insert(directed[i].0);
    }
    let start = start?;
    let mut loop_ = vec![start];
    let mut at = start;
    for _ in 0..next.len() {
        at = *next.get(&key(at))?;
        if key(at) == key(start) {
            break;
        }
        loop_.push(at);
    }
    if loop_.len() != next.len() {
        return None; // several loops
    }
    let normal = scene.patches[patches[0] as usize].normal;
    // Drop collinear vertices, then require strict convexity.
    let n = loop_.len();
    let corners: Vec<DVec3> = (0..n)
        .filter(|&i| {
            let (p, c, q) = (loop_[(i + n - 1) % n], loop_[i], loop_[(i + 1) % n]);
            let (u, w) = (c - p, q - c);
            u.cross(w).length() > 1e-9 * u.length() * w.length()
        })
        .map(|i| loop_[i])
        .collect();
    let m = corners.len();
    if m < 3 {
        return None;
    }
    let convex = (0..m).all(|i| {
        let (p, c, q) = (corners[(i + m - 1) % m], corners[i], corners[(i + 1) % m]);
        (c - p).cross(q - c).dot(normal) > 0.0
    });
    convex.then_some(corners)
}

/// Merges collinear overlapping segments of each patch and orders the result
/// by patch, then by line.
fn merge_collinear(raw: Vec<Segment>, scene: &Scene) -> Vec<Segment> {
    let mut by_patch: Vec<(u32, Vec<Segment>)> = Vec::new();
    let mut sorted = raw;
    sorted.sort_by_key(|s| s.patch); // stable: keeps generation order
    for s in sorted {
        match by_patch.last_mut() {
            Some((p, v)) if *p == s.patch => v.push(s),
            _ => by_patch.push((s.patch, vec![s])),
        }
    }
    let merged: Vec<Vec<Segment>> = by_patch
        .into_par_iter()
        .map(|(p, segs)| merge_patch(segs, scene.patches[p as usize].normal, scene.diagonal()))
        .collect();
    merged.into_iter().flatten().collect()
}

/// Merges the collinear overlapping segments of one patch with unit
/// `normal`; `segs` is not empty.
fn merge_patch(segs: Vec<Segment>, normal: DVec3, diagonal: f64) -> Vec<Segment> {
    let dist = MERGE_DIST * diagonal;
    // A frame in the patch plane.
    let ex = normal.any_orthonormal_vector();
    let ey = normal.cross(ex);
    let origin = segs[0].a;
    // Line parameters: angle in [−MERGE_ANGLE, π − MERGE_ANGLE), signed offset.
    let lines: Vec<(f64, f64)> = segs
        .iter()
        .map(|s| {
            let d = s.b - s.a;
            let mut theta = d.dot(ey).atan2(d.dot(ex));
            if theta < -MERGE_ANGLE {
                theta += std::f64::consts::PI;
            }
            if theta >= std::f64::consts::PI - MERGE_ANGLE {
                theta -= std::f64::consts::PI;
            }
            let (sin, cos) = theta.sin_cos();
            let p = s.a - origin;
            let offset = -sin * p.dot(ex) + cos * p.dot(ey);
            (theta, offset)
        })
        .collect();
    let mut order: Vec<usize> = (0..segs.len()).collect();
    order.sort_by(|&i, &j| lines[i].0.total_cmp(&lines[j].0).then(i.cmp(&j)));
    let mut out = Vec::new();
    let mut i = 0;
    while i < order.len() {
        // Same direction: consecutive angles within the tolerance.
        let mut j = i + 1;
        while j < order.len() && lines[order[j]].0 - lines[order[j - 1]].0 <= MERGE_ANGLE {
            j += 1;
        }
        let mut group: Vec<usize> = order[i..j].to_vec();
        group.sort_by(|&x, &y| lines[x].1.total_cmp(&lines[y].1).then(x.cmp(&y)));
        let mut g = 0;
        while g < group.len() {
            let mut h = g + 1;
            while h < group.len() && lines[group[h]].1 - lines[group[h - 1]].1 <= dist {
                h += 1;
            }
            merge_line(&segs, &group[g..h], dist, &mut out);
            g = h;
        }
        i = j;
    }
    out
}

/// Merges the overlapping members of one line's segments.
fn merge_line(segs: &[Segment], members: &[usize], dist: f64, out: &mut Vec<Segment>) {
    let anchor = segs[members[0]];
    let dir = (anchor.b - anchor.a).normalize_or_zero();
    let t = |p: DVec3| (p - anchor.a).dot(dir);
    // (t_lo, t_hi, point_lo, point_hi, segment)
    let mut spans: Vec<(f64, f64, DVec3, DVec3, usize)> = members
        .iter()
        .map(|&k| {
            let s = segs[k];
            if t(s.a) <= t(s.b) {
                (t(s.a), t(s.b), s.a, s.b, k)
            } else {
                (t(s.b), t(s.a), s.b, s.a, k)
            }
        })
        .collect();
    spans.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.4.cmp(&y.4)));
    let mut current: Option<(f64, f64, DVec3, DVec3, Segment)> = None;
    for (lo, hi, plo, phi, k) in spans {
        let s = segs[k];
        current = match current {
            Some((clo, chi, cplo, cphi, mut best)) if lo <= chi + dist => {
                if rank(&s) > rank(&best) {
                    best = s;
                }
                if hi > chi {
                    Some((clo, hi, cplo, phi, best))
                } else {
                    Some((clo, chi, cplo, cphi, best))
                }
            }
            done => {
                if let Some((_, _, a, b, best)) = done {
                    out.push(Segment { a, b, ..best });
                }
                Some((lo, hi, plo, phi, s))
            }
        };
    }
    if let Some((_, _, a, b, best)) = current {
        out.push(Segment { a, b, ..best });
    }
}

/// Contact lines outrank D1 segments; then weight decides.
fn rank(s: &Segment) -> (bool, f64) {
    (s.kind == SegmentKind::Contact, s.weight)
}

/// Keeps at most `max` segments: the best by [`rank`], in their order.
fn apply_budget(segments: &mut Vec<Segment>, max: usize) {
    if segments.len() <= max {
        return;
    }
    let mut order: Vec<usize> = (0..segments.len()).collect();
    order.sort_by(|&i, &j| {
        let (ri, rj) = (rank(&segments[i]), rank(&segments[j]));
        rj.0.cmp(&ri.0).then(rj.1.total_cmp(&ri.1)).then(i.cmp(&j))
    });
    let mut keep = vec![false; segments.len()];
    for &i in &order[..max] {
        keep[i] = true;
    }
    let mut k = 0;
    segments.retain(|_| {
        k += 1;
        keep[k - 1]
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_chord_of_a_square() {
        let sq = [
            DVec3::new(0., 0., 0.),
            DVec3::new(1., 0., 0.),
            DVec3::new(1., 1., 0.),
            DVec3::new(0., 1., 0.),
        ];
        let (a, b) = plane_chord(&sq, DVec3::X, 0.25, 1e-12).unwrap();
        assert!((a.x - 0.25).abs() < 1e-15 && (b.x - 0.25).abs() < 1e-15);
        assert!(((a - b).length() - 1.0).abs() < 1e-15);
        assert!(plane_chord(&sq, DVec3::X, 2.0, 1e-12).is_none());
        assert!(plane_chord(&sq, DVec3::Z, 0.0, 1e-12).is_none());
    }

    #[test]
    fn visible_runs_finds_the_gap() {
        let runs = visible_runs(9, |u| !(0.3..0.6).contains(&u));
        assert_eq!(runs.len(), 2);
        assert_eq!(runs[0].0, 0.0);
        assert!((runs[0].1 - 0.3).abs() < 1e-3);
        assert!((runs[1].0 - 0.6).abs() < 1e-3);
        assert_eq!(runs[1].1, 1.0);
        assert!(visible_runs(5, |_| false).is_empty());
    }

    #[test]
    fn merge_joins_overlapping_collinear_pieces() {
        let seg = |a: [f64; 3], b: [f64; 3], w: f64| Segment {
            patch: 0,
            a: DVec3::from_array(a),
            b: DVec3::from_array(b),
            kind: SegmentKind::Ve,
            emitter: Some(0),
            weight: w,
        };
        let segs = vec![
            seg([0., 0., 0.], [1., 0., 0.], 0.1),
            seg([2., 0., 0.], [0.5, 0., 0.], 0.3),
            seg([0., 1., 0.], [1., 1., 0.], 0.2),
            seg([3., 0., 0.], [4., 0., 0.], 0.2),
        ];
        let out = merge_patch(segs, DVec3::Z, 1.0);
        assert_eq!(out.len(), 3);
        let long = out
            .iter()
            .find(|s| (s.b - s.a).length() > 1.5)
            .expect("merged");
        assert_eq!(long.weight, 0.3);
        assert!(
            (long.a.x.min(long.b.x)).abs() < 1e-15 && (long.a.x.max(long.b.x) - 2.0).abs() < 1e-15
        );
    }
}
