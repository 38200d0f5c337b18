//! The rectangle-to-rectangle kernel: the exact unoccluded form factor
//! between two rectangles whose edges are aligned, in parallel planes
//! facing each other or in perpendicular planes, each wholly in front of
//! the other. Walls, floors, ceilings and their quadtree elements are
//! such pairs; in the gallery they are more than half of the links whose
//! form factor the hierarchical solver integrates exactly.
//!
//! Owns: [`aligned_rectangles`].
//!
//! Method: A₁F₁₂ = ∫∫ cos θ₁ cos θ₂ / (π r²) is a fourfold integral of a
//! kernel that depends on each axis through a difference of coordinates
//! (parallel: both in-plane axes; perpendicular: the common axis) or on
//! the coordinate itself (perpendicular: each plane's distance from the
//! other). Integrating it four times in closed form gives a function G of
//! the corner coordinates, and A₁F₁₂ = Σ ±G over the 16 combinations of
//! the two rectangles' extents (superposition of corner configurations).
//! The two G below were derived for this module; the tests hold them to
//! Howell's C-11 and C-14 and to the adaptive quadrature.
//!
//! Invariants: `None` whenever the pair is not such a configuration (the
//! caller integrates numerically) or when the 16 terms cancel so far that
//! rounding would show (elements far apart for their size); otherwise a
//! value in [0, 1]. Geometry that deviates from an exact rectangle by a
//! relative [`SHAPE_TOLERANCE`] (coordinates rounded to micrometres) is
//! taken as exact: the form factor moves by the same order.

use std::f64::consts::PI;

use glam::DVec3;

/// Relative deviation (of angles, in radians, and of lengths, against the
/// rectangles' size) within which a pair counts as exactly aligned.
pub const SHAPE_TOLERANCE: f64 = 1e-6;

/// The 16 terms may cancel to no less than this fraction of the sum of
/// their magnitudes (the result then keeps about 8 significant digits).
const CANCELLATION: f64 = 1e-8;

/// An aligned rectangle: its corner, unit edge directions and lengths.
struct Rect {
    origin: DVec3,
    axes: [DVec3; 2],
    lengths: [f64; 2],
}

impl Rect {
    /// `polygon` as a rectangle, when it is one within [`SHAPE_TOLERANCE`].
    fn of(polygon: &[DVec3]) -> Option<Rect> {
        let [p0, p1, p2, p3] = <[DVec3; 4]>::try_from(polygon).ok()?;
        let (e0, e1) = (p1 - p0, p3 - p0);
        let (l0, l1) = (e0.length(), e1.length());
        let size = l0 + l1;
        if !(l0 > 0.0 && l1 > 0.0 && size.is_finite()) {
            return None;
        }
        let (a, b) = (e0 / l0, e1 / l1);
        let square = a.dot(b).abs() <= SHAPE_TOLERANCE;
        let closed = (p2 - (p1 + e1)).length() <= SHAPE_TOLERANCE * size;
        (square && closed).then_some(Rect {
            origin: p0,
            axes: [a, b],
            lengths: [l0, l1],
        })
    }

    fn size(&self) -> f64 {
        self.lengths[0] + self.lengths[1]
    }

    /// The extent of the rectangle's corners along unit direction `d`.
    fn extent(&self, d: DVec3) -> [f64; 2] {
        let o = self.origin.dot(d);
        let (a, b) = (
            self.lengths[0] * self.axes[0].dot(d),
            self.lengths[1] * self.axes[1].dot(d),
        );
        [o + a.min(0.0) + b.min(0.0), o + a.max(0.0) + b.max(0.0)]
    }

    /// True when each edge of the rectangle lies along one of `dirs`.
    fn aligned_with(&self, dirs: [DVec3; 2]) -> bool {
        self.axes
            .iter()
            .all(|a| dirs.iter().any(|d| parallel(*a, *d)))
    }
}

fn parallel(a: DVec3, b: DVec3) -> bool {
    a.cross(b).length() <= SHAPE_TOLERANCE
}

/// The exact unoccluded form factor from rectangle `receiver` (unit
/// normal `n_r`) to rectangle `source` (unit normal `n_s`), both given by
/// four corners in order, when their edges are aligned and they face each
/// other in parallel planes, or stand in perpendicular planes each wholly
/// in front of the other (touching along an edge or not); `None` for any
/// other pair, or when the closed form would lose its precision to
/// cancellation (see the module doc).
///
/// ```
/// use glam::DVec3;
/// use nusselt::formfactor::rectangles::aligned_rectangles;
/// // Floor and wall of a unit cube sharing an edge (Howell C-14): 0.200044.
/// let floor = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 0.0, 1.0), DVec3::Z];
/// let wall = [DVec3::ZERO, DVec3::Y, DVec3::new(1.0, 1.0, 0.0), DVec3::X];
/// let f = aligned_rectangles(&floor, DVec3::Y, &wall, DVec3::Z).unwrap();
/// assert!((f - 0.200044).abs() < 1e-6);
/// ```
pub fn aligned_rectangles(
    receiver: &[DVec3],
    n_r: DVec3,
    source: &[DVec3],
    n_s: DVec3,
) -> Option<f64> {
    let (r, s) = (Rect::of(receiver)?, Rect::of(source)?);
    let tol = SHAPE_TOLERANCE * r.size().max(s.size());
    let area = r.lengths[0] * r.lengths[1];
    let cos = n_r.dot(n_s);
    let (sum, magnitude) = if parallel(n_r, n_s) {
        // Facing each other across a gap: source in front of the receiver,
        // so (normals opposite) the receiver in front of the source.
        let z = (s.origin - r.origin).dot(n_r);
        if !(cos < 0.0 && z > tol && s.aligned_with(r.axes)) {
            return None;
        }
        let [u, v] = r.axes;
        let (xr, xs, yr, ys) = (r.extent(u), s.extent(u), r.extent(v), s.extent(v));
        superpose(|i, k, j, l| parallel_g(xr[i] - xs[k], yr[j] - ys[l], z))
    } else if cos.abs() <= SHAPE_TOLERANCE {
        // The common axis: the receiver's edge direction that lies in the
        // source's plane.
        let [a, b] = r.axes;
        let (w, across) = if parallel(b, n_s) { (a, b) } else { (b, a) };
        if !(parallel(across, n_s) && s.aligned_with([w, n_r])) {
            return None;
        }
        // Distances of the receiver from the source's plane and of the
        // source from the receiver's: both sides in front.
        let x = r.extent(n_s).map(|c| c - s.origin.dot(n_s));
        let zeta = s.extent(n_r).map(|c| c - r.origin.dot(n_r));
        if !(x[0] >= -tol && zeta[0] >= -tol) {
            return None;
        }
        let (x, zeta) = (x.map(|c| c.max(0.0)), zeta.map(|c| c.max(0.0)));
        let (y, eta) = (r.extent(w), s.extent(w));
        superpose(|i, l, j, k| perpendicular_g(x[i], zeta[l], y[j] - eta[k]))
    } else {
        return None;
    };
    let f = sum / area;
    let rounding_safe = sum.abs() >= CANCELLATION * magnitude;
    (f.is_finite() && rounding_safe).then(|| f.clamp(0.0, 1.0))
}

/// Σ (−1)^(i+j+k+l) g(i, j, k, l) over the 16 combinations of lower (0)
/// and upper (1) ends of the four extents, and the sum of the terms'
/// magnitudes.
fn superpose(g: impl Fn(usize, usize, usize, usize) -> f64) -> (f64, f64) {
    let (mut sum, mut magnitude) = (0.0, 0.0);
    for n in 0..16 {
        let [i, j, k, l] = [n & 1, (n >> 1) & 1, (n >> 2) & 1, (n >> 3) & 1];
        let t = g(i, j, k, l);
        sum += if (i + j + k + l) % 2 == 0 { t } else { -t };
        magnitude += t.abs();
    }
    (sum, magnitude)
}

/// The fourfold antiderivative for parallel planes a distance z apart,
/// in the two in-plane coordinate differences u and v:
/// ∂⁴G/∂u²∂v² = z² / (π (u² + v² + z²)²).
fn parallel_g(u: f64, v: f64, z: f64) -> f64 {
    let z2 = z * z;
    let (su, sv) = ((u * u + z2).sqrt(), (v * v + z2).sqrt());
    (u * sv * (u / sv).atan() + v * su * (v / su).atan() - 0.5 * z2 * (u * u + v * v + z2).ln())
        / (2.0 * PI)
}

/// The antiderivative for perpendicular planes, at the receiver's distance
/// x from the source's plane, the source's distance ζ from the
/// receiver's, and the difference v along the common axis:
/// ∂⁴G/∂x∂ζ∂v² = x ζ / (π (x² + ζ² + v²)²), G = (v c atan(v/c) −
/// (c² − v²) ln(c² + v²) / 4) / (2π) with c² = x² + ζ².
fn perpendicular_g(x: f64, zeta: f64, v: f64) -> f64 {
    let c2 = x * x + zeta * zeta;
    let r2 = c2 + v * v;
    let c = c2.sqrt();
    let arc = if c > 0.0 { v * c * (v / c).atan() } else { 0.0 };
    let log = if r2 > 0.0 {
        0.25 * (c2 - v * v) * r2.ln()
    } else {
        0.0
    };
    (arc - log) / (2.0 * PI)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formfactor::closed_form::{c11, c14};
    use crate::formfactor::form_factor_polygon_polygon;
    use rand::{Rng, SeedableRng};

    /// Rectangle from a corner and two edge vectors, counter-clockwise
    /// about e0 × e1.
    fn rect(o: DVec3, e0: DVec3, e1: DVec3) -> [DVec3; 4] {
        [o, o + e0, o + e0 + e1, o + e1]
    }

    fn normal(p: &[DVec3; 4]) -> DVec3 {
        (p[1] - p[0]).cross(p[3] - p[0]).normalize()
    }

    fn closed(r: &[DVec3; 4], s: &[DVec3; 4]) -> Option<f64> {
        aligned_rectangles(r, normal(r), s, normal(s))
    }

    #[test]
    fn opposed_rectangles_match_howell_c11() {
        for (a, b, c) in [(1.0, 1.0, 1.0), (2.0, 0.5, 0.3), (0.1, 3.0, 2.0)] {
            let floor = rect(
                DVec3::ZERO,
                DVec3::new(a, 0.0, 0.0),
                DVec3::new(0.0, b, 0.0),
            );
            let top = rect(
                DVec3::new(0.0, 0.0, c),
                DVec3::new(0.0, b, 0.0),
                DVec3::new(a, 0.0, 0.0),
            );
            let f = closed(&floor, &top).unwrap();
            assert!(
                (f - c11(a, b, c)).abs() < 1e-12 * c11(a, b, c).max(1.0),
                "{f}"
            );
        }
    }

    #[test]
    fn rectangles_sharing_an_edge_match_howell_c14() {
        for (w, h, l) in [(1.0, 1.0, 1.0), (0.2, 3.0, 1.5), (4.0, 0.1, 0.5)] {
            // Receiver in the floor (z = 0, depth w along x), source the
            // wall x = 0 of height h, sharing the edge along y of length l.
            let floor = rect(
                DVec3::ZERO,
                DVec3::new(w, 0.0, 0.0),
                DVec3::new(0.0, l, 0.0),
            );
            let wall = rect(
                DVec3::ZERO,
                DVec3::new(0.0, l, 0.0),
                DVec3::new(0.0, 0.0, h),
            );
            let f = closed(&floor, &wall).unwrap();
            assert!((f - c14(w, h, l)).abs() < 1e-12, "{f} {}", c14(w, h, l));
        }
    }

    /// Aligned pairs in random placements (offsets, gaps, overlaps in
    /// projection, touching edges), rotated as a whole, against the
    /// adaptive quadrature.
    #[test]
    fn random_aligned_pairs_match_the_quadrature() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut checked = 0;
        for k in 0..300 {
            let mut len = || rng.random_range(0.05f64..2.0);
            let (a, b, c, d) = (len(), len(), len(), len());
            let mut off = || rng.random_range(-1.5f64..1.5);
            let (ox, oy, oz) = (off(), off(), off());
            let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
            let floor = rect(DVec3::ZERO, a * x, b * y);
            let other = if k % 2 == 0 {
                // Parallel, facing down from height |oz| + small.
                let h = oz.abs() + 0.01;
                rect(DVec3::new(ox, oy, h), d * y, c * x)
            } else {
                // Perpendicular wall x = ox ≤ 0 facing +x, on or above
                // the floor's plane.
                let wall_x = -ox.abs() * f64::from(u8::from(k % 3 != 0));
                let base = oz.abs() * f64::from(u8::from(k % 5 != 0));
                rect(DVec3::new(wall_x, oy, base), d * y, c * z)
            };
            let axis = DVec3::new(off(), off(), off() + 0.1).normalize();
            let turn = glam::DQuat::from_axis_angle(axis, rng.random_range(0.0..6.0));
            let shift = DVec3::new(3.0, -2.0, 7.0);
            let place = |p: [DVec3; 4]| p.map(|q| turn * q + shift);
            let (r, s) = (place(floor), place(other));
            let Some(f) = closed(&r, &s) else {
                // Only a perpendicular wall partly below the floor's plane
                // may be refused; here none is.
                panic!("pair {k} refused");
            };
            let q = form_factor_polygon_polygon(&r, &s, 1e-9).value;
            assert!((f - q).abs() < 1e-7 + 1e-6 * q, "pair {k}: {f} vs {q}");
            checked += 1;
        }
        assert_eq!(checked, 300);
    }

    #[test]
    fn other_pairs_are_left_to_the_quadrature() {
        let floor = rect(DVec3::ZERO, DVec3::X, DVec3::Y);
        // Tilted by 10°: neither parallel nor perpendicular.
        let t = 10f64.to_radians();
        let tilted = rect(
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::Y,
            DVec3::new(t.cos(), 0.0, -t.sin()),
        );
        assert_eq!(closed(&floor, &tilted), None);
        // Perpendicular but rotated about the floor's normal by 30°.
        let r = glam::DQuat::from_rotation_z(30f64.to_radians());
        let wall = rect(DVec3::new(-1.0, 0.0, 0.0), r * DVec3::Y, DVec3::Z);
        assert_eq!(closed(&floor, &wall), None);
        // A wall reaching below the floor's plane.
        let sunk = rect(DVec3::new(-0.5, 0.0, -0.5), DVec3::Y, DVec3::Z);
        assert_eq!(closed(&floor, &sunk), None);
        // Parallel, facing the same way.
        let above = rect(DVec3::new(0.0, 0.0, 1.0), DVec3::X, DVec3::Y);
        assert_eq!(closed(&floor, &above), None);
        // A triangle, a parallelogram.
        let skew = rect(
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::Y,
            DVec3::new(1.0, 0.3, 0.0),
        );
        assert_eq!(closed(&floor, &skew), None);
        // Far apart for their size: the terms cancel beyond rounding.
        let tiny = rect(DVec3::new(0.0, 0.0, 1e3), 1e-3 * DVec3::Y, 1e-3 * DVec3::X);
        assert_eq!(closed(&floor, &tiny), None);
    }
}
