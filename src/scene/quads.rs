//! Merging triangles into quad patches: pairs of adjacent, coplanar
//! triangles of one surface, primitive and material whose union is a convex
//! quad (so each patch, and each output vertex, comes from one primitive).
//!
//! Invariant: greedy and deterministic (triangles in input order, the
//! longest edge first); a merged quad runs counter-clockwise like its
//! triangles and has no 180° corner.

use std::collections::HashMap;

use glam::DVec3;

use super::InputTriangle;
use super::polygon::polygon_area_normal;
use crate::util::geometry::{PositionKey, position_key};

/// Largest distance of the fourth corner from the first triangle's plane,
/// as a fraction of the scene diagonal.
const COPLANAR_DISTANCE: f64 = 1e-7;
/// Largest angle (radians) between the normals of two merged triangles.
const COPLANAR_ANGLE: f64 = 1e-6;
/// Smallest |sin| of a merged quad's corner angle: no 180° corners.
const CONVEX_SIN: f64 = 1e-6;

/// Groups triangles into patches: `(a, None)` for a lone triangle, `(a,
/// Some((b, quad)))` for a merged pair. Greedy and deterministic: triangles
/// are visited in order and first try their longest edge (the diagonal of a
/// rectangle split in two), then their other edges.
#[allow(clippy::type_complexity)]
pub(super) fn pair_triangles(
    tris: &[InputTriangle],
    diagonal: f64,
) -> Vec<(usize, Option<(usize, [DVec3; 4])>)> {
    let mut edges: HashMap<(PositionKey, PositionKey), Vec<usize>> = HashMap::new();
    for (i, t) in tris.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (
                position_key(t.positions[e]),
                position_key(t.positions[(e + 1) % 3]),
            );
            // Directed edge a->b; a consistently wound neighbour has b->a.
            edges.entry((a, b)).or_default().push(i);
        }
    }
    let mut partner: Vec<Option<(usize, [DVec3; 4])>> = vec![None; tris.len()];
    let mut taken = vec![false; tris.len()];
    for pass in 0..2 {
        for i in 0..tris.len() {
            if taken[i] {
                continue;
            }
            let t = &tris[i];
            let mut order = [0usize, 1, 2];
            let len = |e: usize| (t.positions[(e + 1) % 3] - t.positions[e]).length();
            order.sort_by(|&x, &y| len(y).total_cmp(&len(x)));
            let candidates: &[usize] = if pass == 0 { &order[..1] } else { &order[1..] };
            for &e in candidates {
                let (a, b) = (t.positions[e], t.positions[(e + 1) % 3]);
                let Some(others) = edges.get(&(position_key(b), position_key(a))) else {
                    continue;
                };
                let found = others.iter().copied().find_map(|j| {
                    if j == i || taken[j] {
                        return None;
                    }
                    merge_quad(t, &tris[j], e, diagonal).map(|q| (j, q))
                });
                if let Some((j, quad)) = found {
                    taken[i] = true;
                    taken[j] = true;
                    partner[i] = Some((j, quad));
                    break;
                }
            }
        }
    }
    let mut out = Vec::with_capacity(tris.len());
    for i in 0..tris.len() {
        match partner[i] {
            Some(p) => out.push((i, Some(p))),
            None if !taken[i] => out.push((i, None)),
            None => {} // the second triangle of a pair
        }
    }
    out
}

/// The convex quad formed by `t1` and `t2` across `t1`'s edge `e`, if they
/// share a surface, primitive and material and are coplanar.
fn merge_quad(
    t1: &InputTriangle,
    t2: &InputTriangle,
    e: usize,
    diagonal: f64,
) -> Option<[DVec3; 4]> {
    if t1.material != t2.material
        || t1.surface != t2.surface
        || t1.origin.primitive != t2.origin.primitive
    {
        return None;
    }
    let a = t1.positions[e];
    let b = t1.positions[(e + 1) % 3];
    let c = t1.positions[(e + 2) % 3];
    let d = *t2
        .positions
        .iter()
        .find(|&&p| position_key(p) != position_key(a) && position_key(p) != position_key(b))?;
    let (_, n1) = polygon_area_normal(&t1.positions);
    let (_, n2) = polygon_area_normal(&t2.positions);
    if n1.dot(n2) < COPLANAR_ANGLE.cos() || (d - a).dot(n1).abs() > COPLANAR_DISTANCE * diagonal {
        return None;
    }
    // t1 = (a, b, c) and t2 = (b, a, d): the quad runs a, d, b, c.
    let quad = [a, d, b, c];
    for i in 0..4 {
        let p = quad[i];
        let prev = quad[(i + 3) % 4];
        let next = quad[(i + 1) % 4];
        let (u, w) = (p - prev, next - p);
        let sin = u.cross(w).dot(n1) / (u.length() * w.length());
        if !(sin > CONVEX_SIN) {
            return None;
        }
    }
    Some(quad)
}
