//! Deterministic random numbers and point sampling on polygons.
//!
//! Owns: how a seed becomes per-task random streams, area-uniform
//! mappings from the unit square to polygons, and cosine-distributed
//! directions.
//!
//! Invariant: a stream depends only on (seed, task key), never on the thread
//! that runs the task, so results are identical for any thread count.

use glam::{DVec2, DVec3};
use rand::Rng;
use rand_pcg::Pcg64Mcg;

/// A random stream for one task, keyed by the run's seed and the task's
/// identity (for example an element pair, or a pixel).
pub fn stream(seed: u64, key: u64) -> Pcg64Mcg {
    let mixed = (u128::from(seed) << 64) | u128::from(key);
    // Scramble so that neighbouring keys give unrelated streams.
    let state =
        mixed.wrapping_mul(0x2360_ED05_1FC6_5DA4_4385_DF64_9FCC_F645) ^ 0x5851_F42D_4C95_7F2D;
    Pcg64Mcg::new(state | 1)
}

/// Like [`stream`] but for a pair of u32 ids.
pub fn pair_stream(seed: u64, a: u32, b: u32) -> Pcg64Mcg {
    stream(seed, (u64::from(a) << 32) | u64::from(b))
}

/// `n` stratified points in the unit square: one jittered point per cell
/// of an a × b grid with a · b = n and a the largest divisor of n not above
/// √n, so that every cell is used and the points are uniform over the
/// square (a prime n gives one row of n cells).
pub fn stratified(n: usize, rng: &mut impl Rng) -> Vec<DVec2> {
    let rows = (1..=n.isqrt().max(1))
        .rev()
        .find(|a| n.is_multiple_of(*a))
        .unwrap_or(1);
    let columns = n.div_ceil(rows).max(1);
    (0..n)
        .map(|k| {
            let (i, j) = (k % columns, k / columns);
            DVec2::new(
                (i as f64 + rng.random::<f64>()) / columns as f64,
                (j as f64 + rng.random::<f64>()) / rows as f64,
            )
        })
        .collect()
}

/// A cosine-distributed unit direction about unit `n` from two uniform
/// numbers in [0, 1) (Malley's method: uniform disc, projected up).
pub fn cosine_direction(n: DVec3, u1: f64, u2: f64) -> DVec3 {
    let (t, b) = n.any_orthonormal_pair();
    let r = u1.sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    (r * phi.cos() * t + r * phi.sin() * b + z * n).normalize()
}

/// Maps a point of the unit square to a point of a convex planar polygon,
/// uniformly by area (see [`PolygonSampler`], which prepares a polygon
/// once for many points).
pub fn point_in_polygon(polygon: &[DVec3], s: DVec2) -> DVec3 {
    PolygonSampler::new(polygon).point(s)
}

/// A convex planar polygon prepared for uniform sampling: `s.x` picks a
/// fan triangle by cumulative area and is rescaled, then the square-root
/// mapping places the point in the triangle. The fan areas are computed
/// once (on the stack for up to 10 vertices).
pub struct PolygonSampler<'a> {
    polygon: &'a [DVec3],
    small: [f64; 8],
    large: Vec<f64>,
    total: f64,
}

impl<'a> PolygonSampler<'a> {
    /// A sampler of `polygon` (a fan from its first vertex).
    pub fn new(polygon: &'a [DVec3]) -> PolygonSampler<'a> {
        let p0 = polygon[0];
        let fan = polygon.len() - 2;
        let area = |i: usize| (polygon[i + 1] - p0).cross(polygon[i + 2] - p0).length();
        let mut small = [0.0; 8];
        let mut large = Vec::new();
        if fan <= small.len() {
            for (i, a) in small[..fan].iter_mut().enumerate() {
                *a = area(i);
            }
        } else {
            large = (0..fan).map(area).collect();
        }
        let mut sampler = PolygonSampler {
            polygon,
            small,
            large,
            total: 0.0,
        };
        sampler.total = sampler.areas().iter().sum();
        sampler
    }

    fn areas(&self) -> &[f64] {
        let fan = self.polygon.len() - 2;
        if fan <= self.small.len() {
            &self.small[..fan]
        } else {
            &self.large
        }
    }

    /// The point of the polygon that `s` (in the unit square) maps to.
    pub fn point(&self, s: DVec2) -> DVec3 {
        let areas = self.areas();
        let mut x = s.x * self.total;
        let mut tri = areas.len() - 1;
        for (i, &a) in areas.iter().enumerate() {
            if x < a || i == areas.len() - 1 {
                tri = i;
                x = if a > 0.0 {
                    (x / a).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                break;
            }
            x -= a;
        }
        let p = self.polygon;
        let (a, b, c) = (p[0], p[tri + 1], p[tri + 2]);
        let r = x.sqrt();
        a + r * (1.0 - s.y) * (b - a) + r * s.y * (c - a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_directions_have_the_cosine_moments() {
        // E[cos θ] = 2/3 and E[cos² θ] = 1/2 for the cosine density.
        let n = DVec3::new(1.0, 2.0, -0.5).normalize();
        let mut rng = stream(5, 0);
        let k = 200_000;
        let (mut m1, mut m2) = (0.0, 0.0);
        for _ in 0..k {
            let d = cosine_direction(n, rng.random(), rng.random());
            assert!((d.length() - 1.0).abs() < 1e-12);
            let c = d.dot(n);
            assert!(c >= 0.0);
            m1 += c;
            m2 += c * c;
        }
        assert!(
            (m1 / k as f64 - 2.0 / 3.0).abs() < 3e-3,
            "{}",
            m1 / k as f64
        );
        assert!((m2 / k as f64 - 0.5).abs() < 3e-3, "{}", m2 / k as f64);
    }

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: u64 = stream(1, 7).random();
        let b: u64 = stream(1, 7).random();
        let c: u64 = stream(1, 8).random();
        let d: u64 = stream(2, 7).random();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
    }

    #[test]
    fn polygon_samples_are_uniform_by_area() {
        // An L-shaped split: a quad whose fan triangles have areas 1 and 3.
        let quad = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let mut rng = stream(3, 0);
        let pts = stratified(10_000, &mut rng);
        let mean: DVec3 = pts
            .iter()
            .map(|&s| point_in_polygon(&quad, s))
            .sum::<DVec3>()
            / 1e4;
        let centroid = crate::scene::polygon_centroid(&quad);
        assert!((mean - centroid).length() < 0.01, "{mean} vs {centroid}");
    }

    #[test]
    fn stratified_counts_that_are_not_squares_cover_the_square() {
        // 8 points: a 2 × 4 grid, so each quarter of the square gets two
        // (a 3 × 3 grid cut at 8 cells would leave a corner empty).
        let mut rng = stream(5, 1);
        for _ in 0..50 {
            let pts = stratified(8, &mut rng);
            for (qx, qy) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let inside = pts
                    .iter()
                    .filter(|p| (p.x >= 0.5) == (qx == 1) && (p.y >= 0.5) == (qy == 1))
                    .count();
                assert_eq!(inside, 2, "{pts:?}");
            }
        }
    }
}
