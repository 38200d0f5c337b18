//! The polygon-to-polygon kernel: adaptive quadrature over the receiver
//! (Radon's 7-point rule on fan triangles, globally adaptive) of the
//! exact point-to-polygon inner integral, each point weighted by a
//! visibility closure.
//!
//! Invariant: the result is in [0, 1] with an error estimate (the summed
//! disagreement between successive rules), and never spends more than the
//! evaluation budget it is given.

use glam::DVec3;

use super::{Estimate, Ranked, form_factor_point_polygon};

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

/// A triangle of the adaptive quadrature: its four midpoint children and
/// their rule values (ranked by how far their sum is from the parent's).
struct Piece {
    children: [[DVec3; 3]; 4],
    parts: [f64; 4],
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
        Ranked {
            key: diff,
            item: Piece { children, parts },
        }
    };
    let mut heap = std::collections::BinaryHeap::new();
    for (tri, value) in fan {
        heap.push(piece(tri, value, &mut evaluations));
    }
    let budget = tolerance.max(0.0) * area;
    let mut error: f64 = heap.iter().map(|p| p.key).sum();
    while error > budget && evaluations < max_evaluations {
        let Some(Ranked { key, item: worst }) = heap.pop() else {
            break;
        };
        error -= key;
        for (ch, part) in worst.children.iter().zip(worst.parts) {
            let p = piece(*ch, part, &mut evaluations);
            error += p.key;
            heap.push(p);
        }
    }
    let value: f64 = heap.iter().map(|p| p.item.parts.iter().sum::<f64>()).sum();
    // Recompute the error from the pieces (the running sum drifts).
    let error: f64 = heap.iter().map(|p| p.key).sum();
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
