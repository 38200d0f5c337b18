//! Output adaptivity of the `discontinuity` mode (step 4 of
//! [`build_mesh`](super::build_mesh)): one pass finds the triangles whose
//! centroid's point value differs from the interpolation of their vertices
//! by more than the tolerance, and proposes their centroids as new points.
//! Centroid values go into the vertex value cache: a triangle left as it
//! was is not evaluated again in the next pass, and a centroid that
//! becomes a vertex keeps its value.
//!
//! Invariants: only triangles larger than the hierarchy's minimum element
//! area are checked; the proposals are ordered worst first, ties in check
//! order (patch, then triangle), so the result does not depend on the
//! thread count; at most the remaining budget is proposed.

use super::{MeshStats, ValueCache};
use crate::meshing::point_gather::PointEvaluator;
use crate::meshing::triangulate::PatchTriangulation;
use glam::DVec3;

/// The difference a centroid may show is measured against its values'
/// mean plus this fraction of the scene's mean emitted exitance, so that
/// noise in the dark is not chased.
const DARK: f64 = 0.01;

/// The knobs of one adaptivity pass.
pub(super) struct Adaptivity {
    /// Largest relative difference ([`super::MeshSettings::adapt_tol`]).
    pub(super) tol: f64,
    /// The scene's mean emitted exitance.
    pub(super) exitance: f64,
    /// The hierarchy's minimum element area: smaller triangles are left
    /// alone.
    pub(super) min_area: f64,
}

impl Adaptivity {
    /// One pass over `tris` (whose vertex values are all in `cache`): the
    /// centroids to add as (patch, point), worst first, at most `room`.
    /// Counts its evaluations into `stats`.
    pub(super) fn centroids_to_add(
        &self,
        tris: &[PatchTriangulation],
        cache: &mut ValueCache,
        points: &PointEvaluator,
        room: usize,
        stats: &mut MeshStats,
    ) -> Vec<(usize, DVec3)> {
        let checks = self.centroid_checks(tris, cache);
        let centroids: Vec<(usize, DVec3)> = checks.iter().map(|&(p, x, _)| (p, x)).collect();
        stats.evaluations += cache.evaluate(&centroids, points);
        let excess: Vec<f64> = checks
            .iter()
            .map(|&(p, x, interpolated)| {
                let b = cache.get(p, x);
                let scale =
                    self.tol * (0.5 * (b + interpolated).max_element() + DARK * self.exitance);
                (b - interpolated).abs().max_element() / scale
            })
            .collect();
        let mut order: Vec<usize> = (0..checks.len()).filter(|&k| excess[k] > 1.0).collect();
        // Worst first; ties in check order (deterministic).
        order.sort_by(|&a, &b| excess[b].total_cmp(&excess[a]).then(a.cmp(&b)));
        order.truncate(room);
        order
            .into_iter()
            .map(|k| {
                let (p, x, _) = checks[k];
                (p, x)
            })
            .collect()
    }

    /// Every triangle above the minimum element area, as (patch, centroid,
    /// mean of its vertex values).
    fn centroid_checks(
        &self,
        tris: &[PatchTriangulation],
        cache: &ValueCache,
    ) -> Vec<(usize, DVec3, DVec3)> {
        tris.iter()
            .enumerate()
            .flat_map(|(p, tri)| {
                tri.triangles.iter().filter_map(move |t| {
                    let [a, b, c] = t.map(|i| tri.positions[i as usize]);
                    if !(0.5 * (b - a).cross(c - a).length() > self.min_area) {
                        return None;
                    }
                    let mean = t
                        .iter()
                        .map(|&i| cache.get(p, tri.positions[i as usize]))
                        .sum::<DVec3>()
                        / 3.0;
                    Some((p, (a + b + c) / 3.0, mean))
                })
            })
            .collect()
    }
}
