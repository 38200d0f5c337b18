//! Small geometric helpers that know nothing of scenes, patches or light:
//! distances to segments, lines and convex polygons, and exact position
//! keys for hashing.
//!
//! Invariant: every function here is total on finite input (a degenerate
//! segment or line is treated as its first point) and deterministic.

use glam::DVec3;

/// Distance from `x` to the segment `ab`, and the closest point of it.
pub fn closest_on_segment(x: DVec3, a: DVec3, b: DVec3) -> (f64, DVec3) {
    let d = b - a;
    let len2 = d.length_squared();
    let t = if len2 > 0.0 {
        ((x - a).dot(d) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let y = a + t * d;
    ((y - x).length(), y)
}

/// Distance from `x` to the segment `ab`.
pub fn segment_distance(x: DVec3, a: DVec3, b: DVec3) -> f64 {
    closest_on_segment(x, a, b).0
}

/// Distance from `x` to the line through `p` and `q` (to `p` when they
/// coincide).
pub fn line_distance(p: DVec3, q: DVec3, x: DVec3) -> f64 {
    let d = q - p;
    let len = d.length();
    if len > 0.0 {
        d.cross(x - p).length() / len
    } else {
        (x - p).length()
    }
}

/// How far `x` lies outside the convex polygon `vertices` (counter-
/// clockwise about `normal`): the largest distance beyond an edge line,
/// negative inside.
pub fn outside_polygon(vertices: &[DVec3], normal: DVec3, x: DVec3) -> f64 {
    let mut worst = f64::NEG_INFINITY;
    for (i, &p) in vertices.iter().enumerate() {
        let edge = vertices[(i + 1) % vertices.len()] - p;
        let len = edge.length();
        if len > 0.0 {
            worst = worst.max(-normal.cross(edge).dot(x - p) / len);
        }
    }
    worst
}

/// An exact position as a hash key: the bit patterns of its coordinates,
/// with −0 and +0 alike.
pub type PositionKey = [u64; 3];

/// The [`PositionKey`] of `p`.
pub fn position_key(p: DVec3) -> PositionKey {
    [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_to_segments_lines_and_polygons() {
        let (a, b) = (DVec3::ZERO, DVec3::X);
        assert_eq!(segment_distance(DVec3::new(0.5, 2.0, 0.0), a, b), 2.0);
        assert_eq!(segment_distance(DVec3::new(3.0, 0.0, 0.0), a, b), 2.0);
        assert_eq!(line_distance(a, b, DVec3::new(3.0, 0.0, 4.0)), 4.0);
        assert_eq!(segment_distance(DVec3::Y, a, a), 1.0);
        let square = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert_eq!(
            outside_polygon(&square, DVec3::Z, DVec3::new(0.5, 0.25, 0.0)),
            -0.25
        );
        assert_eq!(
            outside_polygon(&square, DVec3::Z, DVec3::new(3.0, 0.5, 0.0)),
            2.0
        );
        assert_eq!(
            position_key(DVec3::new(-0.0, 1.0, 2.0)),
            position_key(DVec3::new(0.0, 1.0, 2.0))
        );
    }
}
