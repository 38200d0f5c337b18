//! Planar polygon measures: area, unit normal and centroid.
//!
//! Invariant: total on any polygon of three or more vertices (a degenerate
//! one has zero area, the +z normal and its vertex mean as centroid).

use glam::DVec3;

/// Area-weighted centroid of a planar polygon.
pub fn polygon_centroid(v: &[DVec3]) -> DVec3 {
    let mut sum = DVec3::ZERO;
    let mut weight = 0.0;
    for i in 1..v.len() - 1 {
        let a = (v[i] - v[0]).cross(v[i + 1] - v[0]).length();
        sum += a * (v[0] + v[i] + v[i + 1]) / 3.0;
        weight += a;
    }
    if weight > 0.0 {
        sum / weight
    } else {
        v.iter().sum::<DVec3>() / v.len() as f64
    }
}

/// Area and unit normal of a planar polygon (Newell's method).
pub fn polygon_area_normal(v: &[DVec3]) -> (f64, DVec3) {
    let mut n = DVec3::ZERO;
    for i in 1..v.len() - 1 {
        n += (v[i] - v[0]).cross(v[i + 1] - v[0]);
    }
    let len = n.length();
    (0.5 * len, if len > 0.0 { n / len } else { DVec3::Z })
}
