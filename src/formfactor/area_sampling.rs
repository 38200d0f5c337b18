//! The area-sampling kernel (the lecture's "Method 2"): stratified point
//! pairs between two polygons, one visibility query each.
//!
//! Invariant: unbiased, with its standard error as the error estimate;
//! deterministic for a given random stream.

use glam::DVec3;
use rand::Rng;
use rand::seq::SliceRandom;

use super::Estimate;
use crate::sampling::{point_in_polygon, stratified};

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
