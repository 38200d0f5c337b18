//! Step 1 of [`build_mesh`](super::build_mesh): the points and constraint
//! segments of every patch, by mode ([`patch_inputs`]).
//!
//! Owns: the regular grid of `uniform` ([`uniform_points`]), the leaf
//! corners of `quadtree` and `discontinuity` ([`leaf_corners`]), and, for
//! `discontinuity`, the discontinuity segments as constraints with the leaf
//! corners snapped onto them.
//!
//! Invariants: one [`PatchInput`] per patch, in patch order; `uniform`
//! points lie at least a quarter spacing inside their patch or on its
//! edges, and are at most [`uniform_point_bound`] (counted without
//! allocating, so the budget is checked before the grid is built); a
//! snapped corner lies on a segment of its own patch (it moves only when
//! it was within [`tolerance::SNAP`] of the scene diagonal).

use glam::DVec3;

use super::{MeshMode, MeshSettings, MeshStats};
use crate::discontinuity::Segment;
use crate::hierarchical::hierarchy::Hierarchy;
use crate::meshing::triangulate::PatchInput;
use crate::scene::Scene;
use crate::util::geometry::{closest_on_segment, outside_polygon};
use crate::util::tolerance;

/// The points (and, for `discontinuity`, the constraint segments) of every
/// patch in the mode of `settings`; `segments` are the discontinuity
/// segments by patch. Counts the segments into `stats`.
pub(super) fn patch_inputs(
    scene: &Scene,
    h: &Hierarchy,
    segments: &[Vec<Segment>],
    settings: &MeshSettings,
    stats: &mut MeshStats,
) -> Vec<PatchInput> {
    let np = scene.patches.len();
    let mut inputs = match settings.mode {
        MeshMode::Uniform => {
            let target = settings.uniform_vertices.unwrap_or(h.leaf_count()).max(1);
            uniform_points(scene, uniform_spacing(scene, target))
        }
        MeshMode::Quadtree | MeshMode::Discontinuity => leaf_corners(h, np),
    };
    if settings.mode == MeshMode::Discontinuity {
        let snap = tolerance::SNAP * scene.diagonal();
        for (p, segs) in segments.iter().enumerate().take(np) {
            inputs[p].segments = segs.iter().map(|s| [s.a, s.b]).collect();
            snap_to_segments(&mut inputs[p].points, segs, snap);
            stats.segments += segs.len();
        }
    }
    inputs
}

/// A leaf corner a hair off a segment would make a sliver and, on a
/// contact line, a T-vertex with the occluder's edge: every point closer
/// than `snap` to a segment (but not on it) goes onto it, segment by
/// segment.
fn snap_to_segments(points: &mut [DVec3], segs: &[Segment], snap: f64) {
    for x in points {
        for s in segs {
            let (d, y) = closest_on_segment(*x, s.a, s.b);
            if d > 0.0 && d < snap {
                *x = y;
            }
        }
    }
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

/// The grid spacing of `uniform` for about `target` vertices.
fn uniform_spacing(scene: &Scene, target: usize) -> f64 {
    (scene.total_area() / target.max(1) as f64).sqrt()
}

/// At most how many points [`uniform_points`] makes for about `target`
/// vertices (saturating; nothing is allocated): per patch, the points along
/// its edges and every node of the grid over its bounding rectangle.
pub(super) fn uniform_point_bound(scene: &Scene, target: usize) -> u64 {
    let spacing = uniform_spacing(scene, target);
    // `as u64` saturates (and maps NaN to 0); +1 per axis and edge covers
    // the rounding of ceil and floor.
    let count = |x: f64| (x.max(0.0) + 1.0) as u64;
    scene
        .patches
        .iter()
        .map(|patch| {
            let vs = patch.vertices();
            let edges = (0..vs.len())
                .map(|i| count((vs[(i + 1) % vs.len()] - vs[i]).length() / spacing))
                .fold(0u64, u64::saturating_add);
            let u = (vs[1] - vs[0]).normalize_or_zero();
            let v = patch.normal.cross(u);
            let extent = |axis: DVec3| {
                let (lo, hi) = vs
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &p| {
                        let x = (p - vs[0]).dot(axis);
                        (a.min(x), b.max(x))
                    });
                count((hi - lo) / spacing)
            };
            edges.saturating_add(extent(u).saturating_mul(extent(v)))
        })
        .fold(0u64, u64::saturating_add)
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
