//! Box searches for the geometric passes that must not scan everything: f64
//! boxes rounded outwards into obvhs's f32 boxes, and a tree of them that
//! lists the boxes overlapping a query box.
//!
//! Invariant: rounding only grows a box (by a relative 1e-6 of its size
//! and of its coordinates, far above f32 rounding), so a query returns a
//! superset of the boxes that overlap it in f64; callers apply their exact
//! test to each.

use glam::{DVec3, Vec3A};
use obvhs::{BvhBuildParams, aabb::Aabb, bvh2::Bvh2, bvh2::builder::build_bvh2};

/// Relative growth of a box on its way to f32.
const ROUND_OUT: f64 = 1e-6;

/// An f32 box holding the f64 box `lo`–`hi`.
pub fn outer_aabb(lo: DVec3, hi: DVec3) -> Aabb {
    let pad = ROUND_OUT * ((hi - lo).max_element() + lo.abs().max(hi.abs()).max_element());
    Aabb::new(
        Vec3A::from((lo - pad).as_vec3()),
        Vec3A::from((hi + pad).as_vec3()),
    )
}

/// A tree over boxes, numbered in the order given.
pub struct BoxTree {
    /// The boxes, rounded out, in the order given.
    boxes: Vec<Aabb>,
    /// None when there are no boxes.
    tree: Option<Bvh2>,
}

impl BoxTree {
    /// The tree over `boxes` (lo, hi).
    pub fn new(boxes: impl Iterator<Item = (DVec3, DVec3)>) -> BoxTree {
        let boxes: Vec<Aabb> = boxes.map(|(lo, hi)| outer_aabb(lo, hi)).collect();
        let mut time = std::time::Duration::ZERO;
        let tree = (!boxes.is_empty())
            .then(|| build_bvh2(&boxes, BvhBuildParams::fast_build(), &mut time));
        BoxTree { boxes, tree }
    }

    /// Calls `visit` with the number of every box that may overlap
    /// `lo`–`hi`, each once, in no particular order.
    pub fn overlapping(&self, lo: DVec3, hi: DVec3, mut visit: impl FnMut(u32)) {
        let Some(tree) = &self.tree else { return };
        let query = outer_aabb(lo, hi);
        tree.aabb_traverse(query, |t, node| {
            let node = &t.nodes[node as usize];
            let first = node.first_index as usize;
            for &p in &t.primitive_indices[first..first + node.prim_count as usize] {
                // A leaf holds several boxes: each is tested on its own.
                if self.boxes[p as usize].intersect_aabb(&query) {
                    visit(p);
                }
            }
            true
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_query_finds_exactly_the_overlapping_boxes_here() {
        // Unit boxes on a 10 × 10 grid, one apart; a query box between
        // four of them touches those four only.
        let boxes: Vec<(DVec3, DVec3)> = (0..100)
            .map(|i| {
                let lo = DVec3::new(2.0 * (i % 10) as f64, 2.0 * (i / 10) as f64, 0.0);
                (lo, lo + DVec3::new(1.0, 1.0, 1.0))
            })
            .collect();
        let tree = BoxTree::new(boxes.iter().copied());
        let mut found = Vec::new();
        tree.overlapping(DVec3::new(2.5, 2.5, 0.5), DVec3::new(4.5, 4.5, 0.5), |i| {
            found.push(i)
        });
        found.sort_unstable();
        assert_eq!(found, [11, 12, 21, 22]);
        found.clear();
        tree.overlapping(DVec3::splat(-5.0), DVec3::splat(-4.0), |i| found.push(i));
        assert!(found.is_empty());
        BoxTree::new(std::iter::empty()).overlapping(DVec3::ZERO, DVec3::ONE, |_| {
            panic!("an empty tree holds nothing")
        });
    }
}
