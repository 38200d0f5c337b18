//! The first links of a solve: from the root cluster's self-link, opened
//! by the cluster oracle down to cluster links and patch pairs, or (without
//! clustering) between every pair of patches that face each other.
//!
//! Invariant: pending pairs count as links from the start, so the link and
//! memory budgets see every pair still pending; no step visits all pairs
//! of patches when clustering.

use rayon::prelude::*;

use crate::hierarchical::cluster::{ClusterLink, Evaluation, Node, Step};
use crate::hierarchical::hierarchy::ElementId;
use crate::hierarchical::link::{Inherited, faces_each_other};
use crate::hierarchical::solver::{Pair, Solver};

impl Solver<'_> {
    /// The first links: from the root cluster's self-link when clustering,
    /// else between every pair of patches that face each other; then
    /// settled. When a link, element or memory budget stops this, it
    /// starts again with coarser thresholds ([`Solver::coarsen`]), a few
    /// times at most.
    pub(super) fn initial_links(&mut self) -> u64 {
        loop {
            let pairs = match self.clusters.as_ref().and_then(|c| c.tree.root) {
                Some(root) => self.link_clusters(vec![(root, root)]),
                None => self.patch_pairs(),
            };
            // (A stopped cluster linking is not worth settling.)
            let splits = match self.may_coarsen() {
                false => self.settle(pairs),
                true => 0,
            };
            if !self.may_coarsen() {
                self.first_linking = false;
                return splits;
            }
            self.coarsen();
        }
    }

    /// Every pair of patches that face each other, counted as links.
    fn patch_pairs(&mut self) -> Vec<Pair> {
        let scene = self.scene;
        let tol = 1e-9 * scene.diagonal();
        let n = scene.patches.len();
        let pairs: Vec<Pair> = (0..n)
            .into_par_iter()
            .flat_map_iter(|r| {
                let pr = &scene.patches[r];
                (0..n).filter_map(move |s| {
                    let ps = &scene.patches[s];
                    (r != s
                        && faces_each_other(
                            pr.vertices(),
                            pr.normal,
                            ps.vertices(),
                            ps.normal,
                            tol,
                        ))
                    .then_some(Pair::refining(
                        ElementId(r as u32),
                        ElementId(s as u32),
                        Inherited::Nothing,
                    ))
                })
            })
            .collect();
        self.n_links += pairs.len() as u64;
        pairs
    }

    /// Runs the cluster oracle on (receiver, source) node pairs, opening
    /// clusters until every pair is accepted, dropped, or reaches two
    /// patches; returns those patch pairs (facing each other) for the
    /// element links. The pairs count as links from the start, so the
    /// link and memory budgets see every pair still pending; an opening
    /// the budgets refuse keeps its pair as a cluster link. (A cluster's
    /// self-link always opens: it has no cluster-link form.)
    pub(super) fn link_clusters(&mut self, mut pending: Vec<(Node, Node)>) -> Vec<Pair> {
        let mut patches = Vec::new();
        let Some(mut clusters) = self.clusters.take() else {
            return patches;
        };
        let (scene, bvh, seed) = (self.scene, self.bvh, self.settings.seed);
        let tol = 1e-9 * scene.diagonal();
        let eps = self.thresholds.cluster_eps;
        self.n_links += pending.len() as u64;
        while !pending.is_empty() {
            if self.may_coarsen() {
                // Stopped by a budget: it starts again coarser.
                break;
            }
            let evaluator = self.evaluator();
            let steps: Vec<(Step, u64)> = pending
                .par_iter()
                .with_min_len(16)
                .map(|&(r, s)| clusters.examine(&evaluator, r, s, eps))
                .collect();
            let mut next = Vec::new();
            for (&(r, s), (step, rays)) in pending.iter().zip(steps) {
                self.rays += rays;
                // The pair's fate when it stays a single link: kept, or gone.
                let kept: Option<ClusterLink> = match step {
                    Step::Drop => None,
                    Step::Accept(link) => Some(link),
                    Step::SelfLink(c) => {
                        let [a, b] = clusters.kids(c);
                        self.n_links += 3;
                        next.extend([(a, b), (b, a), (a, a), (b, b)]);
                        continue;
                    }
                    Step::Patches => {
                        let (Node::Patch(a), Node::Patch(b)) = (r, s) else {
                            unreachable!("the oracle names two patches")
                        };
                        let (pa, pb) = (&scene.patches[a as usize], &scene.patches[b as usize]);
                        if faces_each_other(pa.vertices(), pa.normal, pb.vertices(), pb.normal, tol)
                        {
                            patches.push(Pair::refining(
                                ElementId(a),
                                ElementId(b),
                                Inherited::Nothing,
                            ));
                            continue;
                        }
                        None
                    }
                    Step::OpenReceiver | Step::OpenSource => {
                        // Touching nodes must open to bound their error:
                        // only the hard budgets (links, memory) stop them.
                        let separated = clusters.separated(r, s);
                        if !self.refuse_links(1, separated) {
                            let open = if step == Step::OpenReceiver { r } else { s };
                            let Node::Cluster(c) = open else {
                                unreachable!("the oracle opens clusters only")
                            };
                            self.n_links += 1;
                            for k in clusters.kids(c) {
                                next.push(if step == Step::OpenReceiver {
                                    (k, s)
                                } else {
                                    (r, k)
                                });
                            }
                            continue;
                        }
                        if separated {
                            let elements = &self.hierarchy.elements;
                            let (evaluation, rays) =
                                clusters.evaluate(scene, elements, bvh, r, s, seed, false);
                            self.rays += rays;
                            match evaluation {
                                Evaluation::Link(link) => Some(link),
                                _ => None,
                            }
                        } else {
                            // Touching nodes as one link would be a guess
                            // with an unbounded kernel: under the budget
                            // their light is left out, never created.
                            None
                        }
                    }
                };
                match kept {
                    Some(link) => {
                        clusters.add(r, link);
                        self.n_cluster_links += 1;
                    }
                    None => self.n_links -= 1,
                }
            }
            pending = next;
        }
        self.clusters = Some(clusters);
        patches
    }
}
