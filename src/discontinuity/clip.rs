//! Clipping of segments by half-spaces, in-plane half-planes and convex
//! polygons; the chord a plane cuts from a convex polygon; axis-aligned
//! boxes for culling.
//!
//! Owns: [`Bounds`], [`clip_to_half_space`], [`clip_segment`],
//! [`clip_to_polygon`], [`plane_chord`].
//!
//! Invariants: a clipped segment keeps the orientation of its input (the
//! end that survives stays first or last), and an end already inside is
//! returned bit for bit; `None` means nothing is left.

use glam::DVec3;

/// An axis-aligned box, closed on every side.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bounds {
    pub(super) lo: DVec3,
    pub(super) hi: DVec3,
}

impl Bounds {
    /// True when the two boxes share a point.
    pub(super) fn overlaps(&self, other: &Bounds) -> bool {
        self.lo.cmple(other.hi).all() && other.lo.cmple(self.hi).all()
    }
}

/// The part of segment (a, b) with (x − o) · n ≥ tol.
pub(super) fn clip_to_half_space(
    a: DVec3,
    b: DVec3,
    o: DVec3,
    n: DVec3,
    tol: f64,
) -> Option<(DVec3, DVec3)> {
    let (da, db) = ((a - o).dot(n) - tol, (b - o).dot(n) - tol);
    match (da >= 0.0, db >= 0.0) {
        (true, true) => Some((a, b)),
        (false, false) => None,
        (true, false) => Some((a, a + (da / (da - db)) * (b - a))),
        (false, true) => Some((a + (da / (da - db)) * (b - a), b)),
    }
}

/// The part of segment (a, b) with k · (x − o) ≥ 0.
pub(super) fn clip_segment(a: DVec3, b: DVec3, o: DVec3, k: DVec3) -> Option<(DVec3, DVec3)> {
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
pub(super) fn clip_to_polygon(
    polygon: &[DVec3],
    n: DVec3,
    a: DVec3,
    b: DVec3,
) -> Option<(DVec3, DVec3)> {
    let (mut a, mut b) = (a, b);
    let m = polygon.len();
    for i in 0..m {
        let (p, q) = (polygon[i], polygon[(i + 1) % m]);
        let k = n.cross(q - p);
        (a, b) = clip_segment(a, b, p, k)?;
    }
    Some((a, b))
}

/// The chord cut from a convex polygon by the plane m · x = d: the two
/// farthest apart of its crossings with the polygon's edges (vertices within
/// `tol` of the plane count as crossings). `None` when the plane misses the
/// polygon or the polygon lies in the plane.
pub(super) fn plane_chord(polygon: &[DVec3], m: DVec3, d: f64, tol: f64) -> Option<(DVec3, DVec3)> {
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
            let len = (points[j] - points[i]).length();
            if len > far {
                far = len;
                best = Some((points[i], points[j]));
            }
        }
    }
    best
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
}
