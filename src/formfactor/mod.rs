//! Form-factor kernels: pure geometry, no visibility, no hierarchy.
//!
//! Owns the closed-form kernels the solvers build on. Argument order is
//! always (receiver, source), matching F_ij: "i gathers from j".
//!
//! Invariants: every kernel returns a finite value in [0, 1], including for
//! touching, coplanar and degenerate configurations.
//!
//! References: Lambert's contour integral for a differential area to a
//! polygon, as catalogued by Howell; [CW93] §4.

pub mod closed_form;
pub mod hemicube;

use glam::DVec3;
use rand::Rng;
use rand::seq::SliceRandom;

use crate::sampling::{point_in_polygon, stratified};

/// A kernel's result with its error estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Estimate {
    /// The form factor, in [0, 1].
    pub value: f64,
    /// Estimated absolute error (quadrature: sum of the local differences
    /// between successive rules; sampling: one standard error).
    pub error: f64,
    /// Integrand evaluations (quadrature points or sample pairs).
    pub evaluations: usize,
}

/// Differential-area-to-polygon form factor F(dA → polygon) by Lambert's
/// contour formula:
///
/// F = (1 / 2π) · |Σ_i γ_i · n · (R_i × R_{i+1}) / |R_i × R_{i+1}||
///
/// with R_i = v_i − x and γ_i the angle between R_i and R_{i+1}. The polygon
/// (any winding, planar, convex or not) is first clipped to the half-space
/// in front of the receiver's tangent plane. `normal` must be unit length.
///
/// ```
/// use glam::DVec3;
/// use nusselt::formfactor::form_factor_point_polygon;
/// // Under a corner of a 1 × 2 rectangle at height 1 (Howell): 0.167375.
/// let rect = [
///     DVec3::new(0.0, 0.0, 1.0),
///     DVec3::new(1.0, 0.0, 1.0),
///     DVec3::new(1.0, 2.0, 1.0),
///     DVec3::new(0.0, 2.0, 1.0),
/// ];
/// let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &rect);
/// assert!((f - 0.167375).abs() < 1e-6);
/// ```
pub fn form_factor_point_polygon(x: DVec3, normal: DVec3, polygon: &[DVec3]) -> f64 {
    // Clipping adds at most one vertex per crossing: small polygons stay on
    // the stack.
    let mut stack = [DVec3::ZERO; 16];
    let heap: Vec<DVec3>;
    let v: &[DVec3] = if polygon.len() < stack.len() {
        let n = clip_to_half_space(x, normal, polygon, &mut stack);
        &stack[..n]
    } else {
        let mut out = vec![DVec3::ZERO; 2 * polygon.len()];
        let n = clip_to_half_space(x, normal, polygon, &mut out);
        out.truncate(n);
        heap = out;
        &heap
    };
    let n = v.len();
    if n < 3 {
        return 0.0;
    }
    // A polygon lying in the tangent plane subtends no projected solid angle
    // (the contour sum would wrongly count the whole disc around x).
    let height = v.iter().map(|p| (*p - x).dot(normal)).fold(0.0, f64::max);
    let reach = v.iter().map(|p| (*p - x).length()).fold(0.0, f64::max);
    if !(height > 1e-12 * reach) {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..n {
        let a = v[i] - x;
        let b = v[(i + 1) % n] - x;
        let c = a.cross(b);
        let len = c.length();
        if len > 0.0 {
            let gamma = len.atan2(a.dot(b));
            sum += gamma * normal.dot(c) / len;
        }
    }
    let f = sum.abs() / (2.0 * std::f64::consts::PI);
    if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Sutherland–Hodgman clip of `polygon` to {p : (p − x) · n ≥ 0}. Writes the
/// clipped polygon into `out` (which must hold at least `polygon.len() + 1`
/// vertices) and returns its vertex count.
fn clip_to_half_space(x: DVec3, n: DVec3, polygon: &[DVec3], out: &mut [DVec3]) -> usize {
    let m = polygon.len();
    let mut k = 0;
    let mut push = |p: DVec3, k: &mut usize| {
        if *k < out.len() {
            out[*k] = p;
            *k += 1;
        }
    };
    for i in 0..m {
        let p = polygon[i];
        let q = polygon[(i + 1) % m];
        let dp = (p - x).dot(n);
        let dq = (q - x).dot(n);
        if dp >= 0.0 {
            push(p, &mut k);
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            let t = dp / (dp - dq);
            push(p + t * (q - p), &mut k);
        }
    }
    k
}

/// Radon's 7-point, degree-5 rule on a triangle: barycentric points and
/// weights (summing to 1).
const RADON: [([f64; 3], f64); 7] = {
    // r = (6 ∓ √15) / 21, weights (155 ∓ √15) / 1200; the centre weighs 9/40.
    const A: f64 = 0.101_286_507_323_456_34;
    const B: f64 = 0.470_142_064_105_115_1;
    const WA: f64 = 0.125_939_180_544_827_2;
    const WB: f64 = 0.132_394_152_788_506_2;
    [
        ([1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0], 0.225),
        ([A, A, 1.0 - 2.0 * A], WA),
        ([A, 1.0 - 2.0 * A, A], WA),
        ([1.0 - 2.0 * A, A, A], WA),
        ([B, B, 1.0 - 2.0 * B], WB),
        ([B, 1.0 - 2.0 * B, B], WB),
        ([1.0 - 2.0 * B, B, B], WB),
    ]
};

/// Most integrand evaluations one polygon-to-polygon quadrature may spend.
pub const MAX_EVALUATIONS: usize = 2_000_000;

/// Polygon-to-polygon form factor F_ij = (1/A_i) ∫_{A_i} F(dA_x → A_j) dA_x,
/// by adaptive quadrature over the receiver of the exact inner integral
/// ([`form_factor_point_polygon`]), unoccluded.
///
/// Globally adaptive: the receiver's fan triangles are integrated with
/// Radon's 7-point rule; the triangle whose rule disagrees most with the sum
/// over its four midpoint children is split, until the disagreements sum to
/// at most `tolerance` (absolute, on F) or [`MAX_EVALUATIONS`] is spent. The
/// error estimate is that sum. Refinement goes where the integrand is rough:
/// along edges the two polygons share.
///
/// ```
/// use glam::DVec3;
/// use nusselt::formfactor::form_factor_polygon_polygon;
/// // Two unit squares facing each other at distance 1 (Howell C-11).
/// let sq = |z: f64| [
///     DVec3::new(0.0, 0.0, z), DVec3::new(1.0, 0.0, z),
///     DVec3::new(1.0, 1.0, z), DVec3::new(0.0, 1.0, z),
/// ];
/// let mut top = sq(1.0);
/// top.reverse(); // faces down
/// let f = form_factor_polygon_polygon(&sq(0.0), &top, 1e-9);
/// assert!((f.value - 0.199825).abs() < 1e-6);
/// ```
pub fn form_factor_polygon_polygon(
    receiver: &[DVec3],
    source: &[DVec3],
    tolerance: f64,
) -> Estimate {
    form_factor_polygon_polygon_with(receiver, source, tolerance, MAX_EVALUATIONS, |_| 1.0)
}

/// A triangle of the adaptive quadrature: its four midpoint children, their
/// rule values, and how far their sum is from the parent's rule value.
struct Piece {
    children: [[DVec3; 3]; 4],
    parts: [f64; 4],
    diff: f64,
}

impl PartialEq for Piece {
    fn eq(&self, other: &Self) -> bool {
        self.diff == other.diff
    }
}
impl Eq for Piece {}
impl PartialOrd for Piece {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Piece {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.diff.total_cmp(&other.diff)
    }
}

/// [`form_factor_polygon_polygon`] with the inner integral weighted by
/// `visible(x)`, the fraction of the source visible from receiver point x
/// (for example from a fixed set of shadow rays), spending at most
/// `max_evaluations` integrand evaluations.
pub fn form_factor_polygon_polygon_with(
    receiver: &[DVec3],
    source: &[DVec3],
    tolerance: f64,
    max_evaluations: usize,
    visible: impl Fn(DVec3) -> f64,
) -> Estimate {
    form_factor_polygon_polygon_checked(receiver, source, tolerance, max_evaluations, None, visible)
}

/// [`form_factor_polygon_polygon_with`] given `guess`, an estimate by a
/// lower-order rule: when the first Radon pass agrees with it within
/// `tolerance`, that pass is the answer (an embedded-rule error estimate)
/// and no refinement is spent.
pub fn form_factor_polygon_polygon_checked(
    receiver: &[DVec3],
    source: &[DVec3],
    tolerance: f64,
    max_evaluations: usize,
    guess: Option<f64>,
    visible: impl Fn(DVec3) -> f64,
) -> Estimate {
    let (area, normal) = crate::scene::polygon_area_normal(receiver);
    if !(area > 0.0) || source.len() < 3 {
        return Estimate::default();
    }
    let f = |x: DVec3| form_factor_point_polygon(x, normal, source) * visible(x).clamp(0.0, 1.0);
    let mut evaluations = 0;
    let fan: Vec<([DVec3; 3], f64)> = (1..receiver.len() - 1)
        .map(|k| {
            let tri = [receiver[0], receiver[k], receiver[k + 1]];
            (tri, radon(&tri, &f, &mut evaluations))
        })
        .collect();
    if let Some(g) = guess {
        let value = fan.iter().map(|t| t.1).sum::<f64>() / area;
        let diff = (value - g).abs();
        if value.is_finite() && diff <= tolerance {
            return Estimate {
                value: value.clamp(0.0, 1.0),
                error: diff,
                evaluations,
            };
        }
    }
    let piece = |tri: [DVec3; 3], value: f64, evaluations: &mut usize| {
        let [a, b, c] = tri;
        let (ab, bc, ca) = (0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a));
        let children = [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]];
        let parts = children.map(|ch| radon(&ch, &f, evaluations));
        let diff = (parts.iter().sum::<f64>() - value).abs();
        Piece {
            children,
            parts,
            diff,
        }
    };
    let mut heap = std::collections::BinaryHeap::new();
    for (tri, value) in fan {
        heap.push(piece(tri, value, &mut evaluations));
    }
    let budget = tolerance.max(0.0) * area;
    let mut error: f64 = heap.iter().map(|p| p.diff).sum();
    while error > budget && evaluations < max_evaluations {
        let Some(worst) = heap.pop() else { break };
        error -= worst.diff;
        for (ch, part) in worst.children.iter().zip(worst.parts) {
            let p = piece(*ch, part, &mut evaluations);
            error += p.diff;
            heap.push(p);
        }
    }
    let value: f64 = heap.iter().map(|p| p.parts.iter().sum::<f64>()).sum();
    // Recompute the error from the pieces (the running sum drifts).
    let error: f64 = heap.iter().map(|p| p.diff).sum();
    let value = value / area;
    if !value.is_finite() {
        return Estimate::default();
    }
    Estimate {
        value: value.clamp(0.0, 1.0),
        error: error / area,
        evaluations,
    }
}

/// ∫ f over a triangle by Radon's rule.
fn radon(t: &[DVec3; 3], f: &impl Fn(DVec3) -> f64, evaluations: &mut usize) -> f64 {
    let area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
    *evaluations += RADON.len();
    area * RADON
        .iter()
        .map(|(b, w)| w * f(b[0] * t[0] + b[1] * t[1] + b[2] * t[2]))
        .sum::<f64>()
}

/// Area-sampling form factor (the lecture's "Method 2", between two
/// polygons): the mean over `samples` stratified point pairs (x on the
/// receiver, y on the source) of A_j · cos θ_x cos θ_y / (π r²) · V(x, y).
/// The error estimate is the standard error of that mean. Unbiased, but its
/// variance grows without bound as the polygons approach each other.
pub fn form_factor_area_sampling(
    receiver: &[DVec3],
    source: &[DVec3],
    samples: usize,
    rng: &mut impl Rng,
    visible: impl Fn(DVec3, DVec3) -> bool,
) -> Estimate {
    let (_, n_r) = crate::scene::polygon_area_normal(receiver);
    let (area_s, n_s) = crate::scene::polygon_area_normal(source);
    let n = samples.max(1);
    let xs = stratified(n, rng);
    let mut ys = stratified(n, rng);
    ys.shuffle(rng);
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    for (sx, sy) in xs.iter().zip(&ys) {
        let x = point_in_polygon(receiver, *sx);
        let y = point_in_polygon(source, *sy);
        let d = y - x;
        let r2 = d.length_squared();
        let cos_x = n_r.dot(d);
        let cos_y = -n_s.dot(d);
        let mut g = 0.0;
        if r2 > 0.0 && cos_x > 0.0 && cos_y > 0.0 && visible(x, y) {
            g = area_s * cos_x * cos_y / (std::f64::consts::PI * r2 * r2);
        }
        if g.is_finite() {
            sum += g;
            sum_sq += g * g;
        }
    }
    let mean = sum / n as f64;
    let var = (sum_sq / n as f64 - mean * mean).max(0.0);
    Estimate {
        value: mean.clamp(0.0, 1.0),
        error: (var / n as f64).sqrt(),
        evaluations: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(w: f64, h: f64, z: f64) -> [DVec3; 4] {
        [
            DVec3::new(0.0, 0.0, z),
            DVec3::new(w, 0.0, z),
            DVec3::new(w, h, z),
            DVec3::new(0.0, h, z),
        ]
    }

    #[test]
    fn corner_of_rectangle_matches_howell() {
        let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &rect(1.0, 2.0, 1.0));
        assert!((f - 0.167375).abs() < 1e-6, "{f}");
        // Winding does not matter.
        let mut r = rect(1.0, 2.0, 1.0);
        r.reverse();
        let g = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &r);
        assert!((f - g).abs() < 1e-14);
    }

    #[test]
    fn infinite_plane_limit_and_behind() {
        let big = [
            DVec3::new(-1e4, -1e4, 1.0),
            DVec3::new(1e4, -1e4, 1.0),
            DVec3::new(1e4, 1e4, 1.0),
            DVec3::new(-1e4, 1e4, 1.0),
        ];
        let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &big);
        assert!((f - 1.0).abs() < 1e-3, "{f}");
        assert_eq!(form_factor_point_polygon(DVec3::ZERO, -DVec3::Z, &big), 0.0);
    }

    #[test]
    fn clipping_half_visible_polygon() {
        // A vertical wall standing on the receiver's plane, half of it below:
        // only the upper half counts, and equals the closed form of the half.
        let wall = [
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(1.0, 1.0, -1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
        ];
        let upper = [
            DVec3::new(-1.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
        ];
        let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &wall);
        let g = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &upper);
        assert!(f > 0.0 && (f - g).abs() < 1e-12);
    }

    #[test]
    fn touching_and_coplanar_are_finite() {
        let r = rect(1.0, 1.0, 0.0);
        for x in [
            DVec3::ZERO,
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(0.5, 0.5, 0.0),
        ] {
            assert_eq!(form_factor_point_polygon(x, DVec3::Z, &r), 0.0);
        }
        // A wall touching the receiver point along its bottom edge.
        let wall = [
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(-1.0, 0.0, 1.0),
        ];
        let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &wall);
        assert!(f.is_finite() && (0.0..=0.5).contains(&f), "{f}");
    }
}
