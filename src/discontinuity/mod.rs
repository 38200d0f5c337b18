//! Shadow discontinuity segments on receiver patches: the D0 contact lines
//! where an occluder touches a receiver, the D1 lines of the critical
//! wedges of the primary emitters \[LTG92\] \[LTG93\], and the hard shadow
//! lines of the punctual lights (a point light's VE wedges: D0 lines of
//! its light, no penumbra).
//!
//! Owns: the public results ([`Segment`], [`SegmentKind`],
//! [`Discontinuities`], [`DiscontinuityStats`]), the knobs
//! ([`DiscontinuitySettings`]), the drivers [`discontinuity_segments`] and
//! [`discontinuity_segments_until`] (the same within a deadline), and the
//! plane tolerances the submodules share.
//!
//! The steps, one submodule each (read in this order):
//! 1. `context`: the read-only state of one run, built once: the welded
//!    occluder edge graph (`occluders`), the receivers projected onto their
//!    planes (`receivers`) and grouped by plane for searching (`planes`), and the significant luminaires, emitter patches
//!    merged into convex polygons (`luminaires`).
//! 2. `contacts`: D0, occluder edges resting on a receiver and occluders
//!    passing through one.
//! 3. D1, when enabled: `silhouettes` lists, per luminaire, the occluder
//!    edges and vertices that may be on its silhouette (the parallel jobs);
//!    `wedges` builds the critical VE and EV wedges of each job; `trace`
//!    cuts each wedge with its receivers and keeps the visible runs.
//! 4. `merge`: collinear overlapping pieces merged, then the segment budget
//!    by significance.
//!
//! `clip` holds the segment-clipping helpers and the box tests.
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
//! Approximations (documented, deliberate; details in the submodules):
//! - A wedge's trace is clipped by ray-cast visibility at a handful of points
//!   along the segment, so an occluded stretch shorter than the sample
//!   spacing can be missed (`trace`).
//! - Only wedges of luminaires with at least `min_emitter_fraction` of the
//!   strongest luminaire's power are traced; EEE events are not.
//! - Significance is the unoccluded irradiance of the wedge's luminaire at
//!   the segment midpoint, relative to the scene's mean emitted exitance.
//! - Emitter patches that do not merge into one convex luminaire are traced
//!   separately (`luminaires`).
//!
//! References: \[LTG92\] Lischinski, Tampieri, Greenberg, "Discontinuity
//! meshing for accurate radiosity", IEEE CG&A 1992; \[LTG93\] "Combining
//! hierarchical radiosity and discontinuity meshing", SIGGRAPH 1993.

mod clip;
mod contacts;
mod context;
mod luminaires;
mod merge;
mod occluders;
mod planes;
mod receivers;
mod silhouettes;
mod trace;
mod wedges;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::scene::Scene;
use crate::visibility::TriangleBvh;
use context::Context;
use merge::{apply_budget, merge_collinear};
use silhouettes::Job;
use wedges::Traced;

/// Sidedness tolerance for planes, as a fraction of the scene diagonal.
const PLANE_TOL: f64 = 1e-7;
/// How far an occluder edge may be from a receiver plane and still touch it,
/// as a fraction of the scene diagonal; also the padding of the boxes.
const CONTACT_TOL: f64 = 1e-6;

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
    /// One end, in the patch's plane.
    pub a: DVec3,
    /// The other end, in the patch's plane.
    pub b: DVec3,
    /// What produced the segment.
    pub kind: SegmentKind,
    /// The luminaire whose wedge made the segment, named by its lowest patch
    /// index (punctual light k: the patch count plus k); `None` for
    /// contact lines, which belong to no emitter.
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
    /// Wedge jobs (luminaire, silhouette feature) left untraced because
    /// the deadline had passed.
    pub late_jobs: usize,
}

/// The segments, ordered by patch, and the counters.
#[derive(Clone, Debug, Default)]
pub struct Discontinuities {
    /// Ordered by patch, then by line.
    pub segments: Vec<Segment>,
    /// The counters of the run that found them.
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
    discontinuity_segments_until(scene, bvh, settings, None)
}

/// [`discontinuity_segments`] within a time budget that ends at `deadline`:
/// wedge jobs that begin after it trace nothing (counted in
/// `stats.late_jobs`), so which D1 segments a late run finds depends on the
/// clock.
pub fn discontinuity_segments_until(
    scene: &Scene,
    bvh: &TriangleBvh,
    settings: &DiscontinuitySettings,
    deadline: Option<Instant>,
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
        let late = || deadline.is_some_and(|d| Instant::now() >= d);
        let traced: Vec<Option<Traced>> = jobs
            .par_iter()
            .map(|&(l, job)| (!late()).then(|| ctx.run_job(l, job)))
            .collect();
        for t in traced {
            let Some(t) = t else {
                stats.late_jobs += 1;
                continue;
            };
            raw.extend(t.segments);
            stats.wedges += t.wedges;
            stats.rays += t.rays;
        }
    }
    stats.raw_segments = raw.len();

    let mut segments = merge_collinear(raw, scene);
    let before = segments.len();
    apply_budget(&mut segments, settings.max_segments);
    stats.dropped_by_budget = before - segments.len();
    Discontinuities { segments, stats }
}
