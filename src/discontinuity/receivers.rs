//! Receivers: every scene patch, as the polygon its segments must lie in.
//!
//! Owns: [`Receiver`] and the test a candidate segment must pass to be kept
//! on it ([`Receiver::keeps`]: long enough, not along its boundary).
//!
//! Invariants: a receiver's polygon is its patch's, each corner projected
//! exactly onto the plane through the patch centroid with the patch normal,
//! so segments cut in that plane lie in the polygon's plane; its box holds
//! the polygon, padded by the contact tolerance.

use glam::DVec3;

use super::clip::Bounds;
use crate::scene::Patch;
use crate::util::geometry::line_distance;

/// Segments shorter than this fraction of the diagonal are dropped.
const MIN_LENGTH: f64 = 1e-5;
/// A segment this close (fraction of the diagonal) to one of its polygon's
/// edge lines along its whole length lies on the boundary and is dropped.
const BOUNDARY_TOL: f64 = 1e-5;

/// A receiver patch, projected exactly onto its plane.
pub(super) struct Receiver {
    /// The patch's corners in its plane, counter-clockwise about `normal`.
    pub(super) polygon: Vec<DVec3>,
    /// The patch's unit normal.
    pub(super) normal: DVec3,
    /// The patch centroid: a point of the plane.
    pub(super) center: DVec3,
    /// The polygon's box, padded by `pad` on every side.
    pub(super) bounds: Bounds,
}

impl Receiver {
    /// The receiver of `patch`, its box padded by `pad`.
    pub(super) fn new(patch: &Patch, pad: DVec3) -> Receiver {
        let center = patch.centroid();
        let n = patch.normal;
        let polygon: Vec<DVec3> = patch
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
            bounds: Bounds {
                lo: rlo - pad,
                hi: rhi + pad,
            },
        }
    }

    /// Signed distance of `p` from the plane, positive in front.
    pub(super) fn distance(&self, p: DVec3) -> f64 {
        (p - self.center).dot(self.normal)
    }

    /// `p` projected onto the plane along the normal.
    pub(super) fn project(&self, p: DVec3) -> DVec3 {
        p - self.distance(p) * self.normal
    }

    /// True when the segment (a, b), already in the polygon, is long enough
    /// and not along the polygon boundary; tolerances are fractions of
    /// `diagonal`.
    pub(super) fn keeps(&self, a: DVec3, b: DVec3, diagonal: f64) -> bool {
        if !((b - a).length() >= MIN_LENGTH * diagonal) {
            return false;
        }
        let tol_b = BOUNDARY_TOL * diagonal;
        let n = self.polygon.len();
        !(0..n).any(|i| {
            let (p, q) = (self.polygon[i], self.polygon[(i + 1) % n]);
            line_distance(p, q, a) <= tol_b && line_distance(p, q, b) <= tol_b
        })
    }
}
