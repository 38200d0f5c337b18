//! The cluster oracle: whether a link with a cluster at one end may stand
//! for all the links between the two ends' members, and if not, which end
//! to open.
//!
//! Invariants: a link joins nodes whose bounding spheres are disjoint
//! (touching nodes are opened until both are patches); rays are cast only
//! for a pair that some visibility would let pass, and a decision that
//! hangs on the rays keeps the value of fresh ones, so links never select
//! on their own noise.

use std::f64::consts::PI;

use glam::DVec3;
use rayon::prelude::*;

use super::link::{CLUSTER_RAYS, ClusterLink, Evaluation, Sampled};
use super::transport::exposed;
use super::tree::same_plane;
use super::{Clusters, Node};
use crate::hierarchical::hierarchy::Element;
use crate::hierarchical::link::Evaluator;
use crate::hierarchical::oracle::RHO_FLOOR;
use crate::scene::Scene;

/// What the oracle decided for a (receiver, source) pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Nothing passes (back to back, or fully occluded).
    Drop,
    /// Keep the link.
    Accept(ClusterLink),
    /// A cluster's link to itself: its children's pairs replace it.
    SelfLink(u32),
    /// Open the receiver (a cluster) / the source (a cluster).
    OpenReceiver,
    /// Open the source (a cluster).
    OpenSource,
    /// Two patches: for the element links.
    Patches,
}

impl Clusters {
    /// An upper bound of `source`'s intensity in any direction (W/sr,
    /// largest channel).
    pub(super) fn intensity_bound(&self, scene: &Scene, elements: &[Element], source: Node) -> f64 {
        match source {
            Node::Patch(p) => {
                let (b, exposure) = exposed(&elements[p as usize]);
                b.max_element() * exposure * scene.patches[p as usize].area / PI
            }
            Node::Cluster(c) => {
                let w = &self.radiance.power[c as usize];
                let axis = |a: usize| w[2 * a].max_element().max(w[2 * a + 1].max_element());
                (axis(0).powi(2) + axis(1).powi(2) + axis(2).powi(2)).sqrt() / PI
            }
        }
    }

    /// The least and greatest distance between points of the bounding
    /// spheres of `r` and `s` (the least is negative when they overlap).
    pub(super) fn distances(&self, r: Node, s: Node) -> (f64, f64) {
        let t = &self.tree;
        let gap = t.centre(r).distance(t.centre(s));
        let reach = t.radius(r) + t.radius(s);
        (gap - reach, gap + reach)
    }

    /// True when the bounding spheres of `r` and `s` are disjoint: a link
    /// between them has a bounded kernel (1/r² ≤ 1/r_min²).
    pub fn separated(&self, r: Node, s: Node) -> bool {
        self.distances(r, s).0 > 0.0
    }

    /// The oracle's error of a link (receiver `r`, source `s`) with
    /// visible fraction `v`: the largest change of radiosity, ρ_r times
    /// irradiance, that treating the two as points can make over the
    /// receiver, W/m². Infinite when their spheres touch. Least at v = 0
    /// (what a gap missed by the rays could carry), greatest at v = ½ or 1.
    pub(super) fn error(
        &self,
        scene: &Scene,
        elements: &[Element],
        r: Node,
        s: Node,
        v: f64,
    ) -> f64 {
        let t = &self.tree;
        let (r_min, r_max) = self.distances(r, s);
        if !(r_min > 0.0) {
            return f64::INFINITY;
        }
        let rho = match r {
            Node::Patch(p) => scene.patches[p as usize].reflectance.max_element(),
            Node::Cluster(c) => t.clusters[c as usize].reflectance,
        }
        .max(RHO_FLOOR)
            * self.weight(r);
        let i = self.intensity_bound(scene, elements, s);
        if i == 0.0 {
            return 0.0;
        }
        // The spread of 1/r² over the pair, for the light that gets
        // through (V of it), and what a shadow edge or a member hidden from
        // the source can change: min(V, 1 − V) of the nearest irradiance.
        // Both at least 1/CLUSTER_RAYS of their whole (that many rays
        // cannot rule a gap out).
        let floor = 1.0 / CLUSTER_RAYS as f64;
        let near = rho * i / (r_min * r_min);
        rho * i * (1.0 / (r_min * r_min) - 1.0 / (r_max * r_max)) * v.max(floor)
            + near * v.min(1.0 - v).max(floor)
    }

    /// The oracle on pair (receiver `r`, source `s`) with patch
    /// radiosities from `at.elements` and threshold `eps` (W/m²): which step
    /// to take, and the visibility rays it cast. Rays are cast only for a
    /// pair that some visibility would let pass: when only a wholly blocked
    /// one would, the first ray that gets through opens it. A partly
    /// visible pair whose shadow could exceed `eps` is opened.
    pub fn examine(&self, at: &Evaluator, r: Node, s: Node, eps: f64) -> (Step, u64) {
        let Evaluator {
            scene,
            elements,
            bvh,
            seed,
        } = *at;
        let t = &self.tree;
        // Patches in one plane facing one way exchange no light: a flat
        // cluster has no self-link, and two nodes in one such plane no link
        // (a fan of n slivers meeting at a point otherwise opened every
        // pair of its touching clusters, O(n²)).
        let (pr, ps) = (t.plane(scene, r), t.plane(scene, s));
        let coplanar = matches!((pr, ps), (Some(a), Some(b)) if same_plane(a, b, scene.diagonal()));
        match (r, s) {
            (Node::Patch(a), Node::Patch(b)) if a == b => return (Step::Drop, 0),
            (Node::Cluster(a), Node::Cluster(b)) if a == b && pr.is_some() => {
                return (Step::Drop, 0);
            }
            (Node::Cluster(a), Node::Cluster(b)) if a == b => return (Step::SelfLink(a), 0),
            (Node::Patch(_), Node::Patch(_)) => return (Step::Patches, 0),
            _ if coplanar => return (Step::Drop, 0),
            _ => {}
        }
        // Back to back: nothing of the other lies in front of a patch or
        // a flat cluster.
        let in_front = |plane: Option<(DVec3, f64)>, other: Node| match plane {
            Some((n, d)) => t.centre(other).dot(n) - d > -t.radius(other),
            None => true,
        };
        if !in_front(pr, s) || !in_front(ps, r) {
            return (Step::Drop, 0);
        }
        let open = if t.radius(r) >= t.radius(s) && matches!(r, Node::Cluster(_))
            || matches!(s, Node::Patch(_))
        {
            Step::OpenReceiver
        } else {
            Step::OpenSource
        };
        // Not even a wholly blocked pair would do.
        if self.error(scene, elements, r, s, 0.0) > eps {
            return (open, 0);
        }
        if self.error(scene, elements, r, s, 1.0) > eps {
            // Only a blocked pair would do: one ray that gets through
            // opens it. When none does, the kept value comes from fresh
            // rays (these ones chose the pair for seeing nothing).
            return match self.sample(scene, bvh, r, s, seed) {
                (Sampled::Nothing, rays) => (Step::Drop, rays),
                (Sampled::Seen, rays) => (open, rays),
                (Sampled::Blocked, rays) => {
                    let (again, more) = self.evaluate(scene, elements, bvh, r, s, seed, true);
                    match again {
                        Evaluation::Link(l) => (Step::Accept(l), rays + more),
                        Evaluation::Unrepresentable => (open, rays + more),
                        Evaluation::Nothing => (Step::Drop, rays + more),
                    }
                }
            };
        }
        let (evaluation, rays) = self.evaluate(scene, elements, bvh, r, s, seed, false);
        match evaluation {
            Evaluation::Nothing => (Step::Drop, rays),
            Evaluation::Unrepresentable => (open, rays),
            Evaluation::Link(l) if self.error(scene, elements, r, s, l.visibility()) > eps => {
                (open, rays)
            }
            Evaluation::Link(l) if self.error(scene, elements, r, s, 0.5) <= eps => {
                // Accepted whatever the visibility: the decision did not
                // hang on these rays, so their estimate is kept.
                (Step::Accept(l), rays)
            }
            Evaluation::Link(_) => {
                // The kept value comes from fresh rays: the ones that
                // decided would favour links whose sample saw no shadow.
                let (again, more) = self.evaluate(scene, elements, bvh, r, s, seed, true);
                match again {
                    Evaluation::Link(l) => (Step::Accept(l), rays + more),
                    _ => (Step::Drop, rays + more),
                }
            }
        }
    }

    /// True when the oracle, with the current radiosities, would open the
    /// kept link (receiver `r`, `link`).
    pub fn rejects(
        &self,
        scene: &Scene,
        elements: &[Element],
        r: Node,
        link: &ClusterLink,
        eps: f64,
    ) -> bool {
        self.error(scene, elements, r, link.source(), link.visibility()) > eps
    }

    /// Removes and returns the links the oracle now rejects, as (receiver,
    /// source) pairs in a fixed order.
    pub fn take_rejected(
        &mut self,
        scene: &Scene,
        elements: &[Element],
        eps: f64,
    ) -> Vec<(Node, Node)> {
        let receivers: Vec<Node> = (0..self.to_cluster.len() as u32)
            .map(Node::Cluster)
            .chain((0..self.to_patch.len() as u32).map(Node::Patch))
            .collect();
        let marked: Vec<Vec<bool>> = receivers
            .par_iter()
            .with_min_len(256)
            .map(|&r| {
                self.links(r)
                    .iter()
                    .map(|l| self.rejects(scene, elements, r, l, eps))
                    .collect()
            })
            .collect();
        let mut out = Vec::new();
        for (r, marks) in receivers.into_iter().zip(marked) {
            if !marks.contains(&true) {
                continue;
            }
            let own = std::mem::take(self.links_mut(r));
            for (l, reject) in own.into_iter().zip(marks) {
                if reject {
                    out.push((r, l.source()));
                } else {
                    self.links_mut(r).push(l);
                }
            }
        }
        out
    }
}
