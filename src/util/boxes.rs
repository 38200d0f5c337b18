//! Box searches for the geometric passes that must not scan everything: f64
//! boxes rounded outwards into obvhs's f32 boxes, a tree of them that lists
//! the boxes overlapping a query box, and the one way every obvhs binary
//! BVH of the crate is built ([`ploc`], [`build_bvh2`]).
//!
//! Invariants: rounding only grows a box (by a relative 1e-6 of its size
//! and of its coordinates, far above f32 rounding), so a query returns a
//! superset of the boxes that overlap it in f64; callers apply their exact
//! test to each. Up to [`PLOC_WHOLE`] boxes, a build is obvhs's own, node
//! for node; above it, its time grows as n log n whatever the boxes.

use glam::{DVec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::{Bvh2, leaf_collapser::collapse, node::Bvh2Node, reinsertion::ReinsertionOptimizer},
    ploc::{PlocBuilder, morton::morton_encode_u64_unorm},
};
use rayon::prelude::*;

/// The most boxes one PLOC build is given whole. A PLOC pass merges only
/// pairs of nodes that choose each other, so where the merge cost rises
/// steadily along the Morton order (the slivers of a fan, whose boxes all
/// reach its centre), a pass merges a few pairs and the build takes time
/// quadratic in the boxes: with obvhs 0.4, 0.7 s for the 79,000 boxes of a
/// 10,000-sliver fan, 38 s for the 800,000 of a 100,000-sliver fan. Up to
/// this count that costs at most about 0.1 s, and every bundled scene is
/// built as obvhs builds it.
pub const PLOC_WHOLE: usize = 1 << 15;

/// Above [`PLOC_WHOLE`], the boxes are cut into Morton-ordered chunks of
/// this size, each built alone (in parallel), and a PLOC tree over the
/// chunks' boxes joins them, so the quadratic part costs n times this.
/// The 100,000-sliver fan's occluder tree (800,000 boxes with its sliver
/// splits): 48 s whole; in chunks of 2,048 12 s, of 512 7.2 s, of 256
/// 4.5 s (bench-visibility, 2 cores shared). Forced on the bundled scenes,
/// chunks of 256 cost about a tenth of the rays per second (office-10k,
/// gallery), within the machine's noise at 4,096.
pub const PLOC_CHUNK: usize = 1 << 8;

/// obvhs's PLOC tree over `aabbs` (leaf k holds `indices[k]`), with the
/// search settings of `params`; above [`PLOC_WHOLE`] boxes, in chunks
/// (see there).
pub fn ploc(aabbs: &[Aabb], indices: Vec<u32>, params: &BvhBuildParams) -> Bvh2 {
    let one = |boxes: &[Aabb], indices: Vec<u32>| {
        PlocBuilder::with_capacity(boxes.len()).build(
            params.ploc_search_distance,
            boxes,
            indices,
            params.sort_precision,
            params.search_depth_threshold,
        )
    };
    if aabbs.len() <= PLOC_WHOLE {
        return one(aabbs, indices);
    }
    let total = aabbs.iter().fold(Aabb::empty(), |t, b| t.union(b));
    let size = total.diagonal().as_dvec3();
    let scale = DVec3::select(size.cmpgt(DVec3::ZERO), 1.0 / size, DVec3::ZERO);
    let lo = total.min.as_dvec3();
    let mut order: Vec<(u64, u32)> = aabbs
        .par_iter()
        .enumerate()
        .map(|(k, b)| {
            let unit = ((b.center().as_dvec3() - lo) * scale).clamp(DVec3::ZERO, DVec3::ONE);
            (morton_encode_u64_unorm(unit), k as u32)
        })
        .collect();
    order.par_sort_unstable();
    let chunks: Vec<Bvh2> = order
        .par_chunks(PLOC_CHUNK)
        .map(|chunk| {
            let boxes: Vec<Aabb> = chunk.iter().map(|&(_, k)| aabbs[k as usize]).collect();
            one(
                &boxes,
                chunk.iter().map(|&(_, k)| indices[k as usize]).collect(),
            )
        })
        .collect();
    let roots: Vec<Aabb> = chunks.iter().map(|c| *c.nodes[0].aabb()).collect();
    let top = one(&roots, (0..roots.len() as u32).collect());
    graft(top, &chunks, indices)
}

/// `top` with each of its leaves (one chunk number each, as PLOC leaves
/// hold one box) replaced by that chunk's tree. A PLOC leaf names its
/// primitive by the value it was given in `indices`, and its tree's
/// `primitive_indices` are those values, in the order given, so leaves
/// keep their numbers and the whole tree takes the caller's `indices`.
/// obvhs keeps a node's two children side by side, the left one at an odd
/// index: every tree has an odd node count, so each chunk's non-root
/// nodes, appended in order, keep that parity.
fn graft(top: Bvh2, chunks: &[Bvh2], indices: Vec<u32>) -> Bvh2 {
    let mut nodes = top.nodes;
    let mut depth = 0;
    for i in 0..nodes.len() {
        if !nodes[i].is_leaf() {
            continue;
        }
        let chunk = &chunks[top.primitive_indices[nodes[i].first_index as usize] as usize];
        // Chunk node k > 0 goes to base + k - 1.
        let base = nodes.len() as u32 - 1;
        nodes[i] = moved(&chunk.nodes[0], base);
        nodes.extend(chunk.nodes[1..].iter().map(|n| moved(n, base)));
        depth = depth.max(chunk.max_depth);
    }
    Bvh2 {
        nodes,
        primitive_indices: indices,
        max_depth: top.max_depth + depth,
        ..Bvh2::default()
    }
}

/// `n` with its children's numbers (not its primitive's) moved by `base`.
fn moved(n: &Bvh2Node, base: u32) -> Bvh2Node {
    let first = match n.is_leaf() {
        true => n.first_index,
        false => n.first_index + base,
    };
    Bvh2Node::new(*n.aabb(), n.prim_count, first)
}

/// obvhs's `build_bvh2` (PLOC, reinsertion, leaves collapsed, reinsertion
/// again) with the PLOC step of [`ploc`].
pub fn build_bvh2(aabbs: &[Aabb], params: BvhBuildParams) -> Bvh2 {
    let mut bvh = ploc(aabbs, (0..aabbs.len() as u32).collect(), &params);
    let mut optimizer = ReinsertionOptimizer::default();
    optimizer.run(&mut bvh, params.reinsertion_batch_ratio, None);
    collapse(
        &mut bvh,
        params.max_prims_per_leaf.clamp(1, 255),
        params.collapse_traversal_cost,
    );
    optimizer.run(
        &mut bvh,
        params.reinsertion_batch_ratio * params.post_collapse_reinsertion_batch_ratio_multiplier,
        None,
    );
    bvh
}

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
        let tree = (!boxes.is_empty()).then(|| build_bvh2(&boxes, BvhBuildParams::fast_build()));
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

    #[test]
    fn trees_of_more_boxes_than_a_chunk_hold_each_box_once_and_find_the_same() {
        // The boxes of a fan of slivers meeting at the origin (the case
        // that makes one PLOC build quadratic), plus a few far ones.
        let n = PLOC_WHOLE + 777;
        let boxes: Vec<(DVec3, DVec3)> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                let tip = DVec3::new(a.cos(), a.sin(), 0.0) * (1.0 + (i % 7) as f64);
                (tip.min(DVec3::ZERO), tip.max(DVec3::ZERO) + DVec3::Z * 1e-3)
            })
            .collect();
        let aabbs: Vec<Aabb> = boxes.iter().map(|&(lo, hi)| outer_aabb(lo, hi)).collect();
        for params in [
            BvhBuildParams::fast_build(),
            BvhBuildParams::very_slow_build(),
        ] {
            let bvh = build_bvh2(&aabbs, params);
            bvh.validate(&aabbs, false, false);
            let mut seen = vec![0u32; n];
            for node in bvh.nodes.iter().filter(|n| n.is_leaf()) {
                let first = node.first_index as usize;
                for &p in &bvh.primitive_indices[first..first + node.prim_count as usize] {
                    seen[p as usize] += 1;
                }
            }
            assert!(
                seen.iter().all(|&c| c == 1),
                "every box in exactly one leaf"
            );
        }
        let tree = BoxTree::new(boxes.iter().copied());
        for q in 0..50 {
            let c = DVec3::new((q % 10) as f64 - 4.5, (q / 10) as f64 - 2.5, 0.0) * 1.3;
            let (lo, hi) = (c - 0.2, c + 0.2);
            let mut found = Vec::new();
            tree.overlapping(lo, hi, |i| found.push(i));
            found.sort_unstable();
            let query = outer_aabb(lo, hi);
            let expected: Vec<u32> = (0..n as u32)
                .filter(|&i| aabbs[i as usize].intersect_aabb(&query))
                .collect();
            assert_eq!(found, expected, "query {q}");
        }
    }
}
