//! Clusters above the patches (\[SAG94\], \[Sil95\]): a binary tree over the
//! input patches with one root, the links that have a cluster at one end
//! or both, their oracle, and the gather and push-pull through the
//! cluster levels.
//!
//! Owns: [`ClusterTree`] (built from an `obvhs` BVH2 over the patches'
//! boxes), [`Clusters`] (the tree, the cluster links, the clusters'
//! radiance) and the cluster oracle [`Clusters::examine`].
//!
//! Transport. A link stores the Monte Carlo estimate of the geometric
//! transfer ∫∫ cos cos V / (π r²) between its two ends (points uniform by
//! area; pairs that do not face each other count as zero), so the power it
//! carries, transfer × the source's mean exposed radiosity toward the
//! receiver, is an unbiased estimate for a uniform source whatever the
//! clusters' shapes. Directions use six half-axis lobes (+x, −x, +y, −y,
//! +z, −z): a patch of normal n counts in lobe a with weight
//! max(0, ±n_a) / |n|₁ (exact for axis-aligned patches). A source
//! cluster's radiance toward d is its exposed power over its exposed area
//! in the lobes of d; a receiver cluster shares a link's power among its
//! patches by the same lobes, per unit of exposed area.
//!
//! Invariants:
//! - Every patch is a leaf of the tree exactly once; a cluster has exactly
//!   two children; parents precede their children in `clusters` (push down
//!   in index order, pull up in reverse). A cluster's patches are the
//!   contiguous run `order[first..first + count]`.
//! - Energy: a link's power is handed out in full to the receiver's
//!   patches (the lobe shares sum to one), and a source cluster's radiance
//!   is the exposed power of its patches; nothing is created or lost
//!   through the cluster levels. What the lobes cannot see is how light
//!   divides between members hidden from each other: the oracle bounds
//!   that by opening links whose sampled visibility is partial or whose
//!   light is bright ([`Clusters::examine`]).
//! - A cluster link joins nodes whose bounding spheres are disjoint; nodes
//!   that touch or overlap are opened until both are patches, whose pair
//!   goes to the element links of [`crate::hierarchical`]. No step visits
//!   all pairs of patches.
//! - Everything depends only on the scene, the seed and the order of the
//!   pairs: rays come from `pair_stream(seed, r, s)` keyed by the two nodes.

mod link;
mod lobes;
mod oracle;
mod transport;
mod tree;

pub use link::{CLUSTER_RAYS, ClusterLink, Evaluation, RETRY_RAYS};
pub use lobes::{Radiance, lobes, normal_lobes};
pub use oracle::Step;
pub use transport::Plan;
pub use tree::{Cluster, ClusterTree};

use glam::DVec3;

use crate::scene::Scene;
use lobes::Lobes;

/// A node of the cluster tree: a cluster or an input patch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Node {
    /// A cluster, by index into the tree.
    Cluster(u32),
    /// An input patch, by index.
    Patch(u32),
}

impl Node {
    /// The key of the node's random streams (patches from 0 up, clusters
    /// from the top down).
    fn key(self) -> u32 {
        match self {
            Node::Patch(p) => p,
            Node::Cluster(c) => u32::MAX - c,
        }
    }
}

/// The tree, the cluster links and the clusters' radiosity during a solve.
#[derive(Clone, Debug)]
pub struct Clusters {
    /// The cluster tree.
    pub tree: ClusterTree,
    radiance: Radiance,
    /// Links gathered by each cluster.
    pub to_cluster: Vec<Vec<ClusterLink>>,
    /// Links from clusters gathered by each patch.
    pub to_patch: Vec<Vec<ClusterLink>>,
    /// Importance weights in [0, 1] of the patches and (the largest of
    /// their patches') of the clusters; empty: 1.
    patch_weight: Vec<f64>,
    cluster_weight: Vec<f64>,
}

impl Clusters {
    /// The tree of `scene` with no links, radiating the patches' emission.
    pub fn new(scene: &Scene) -> Clusters {
        let tree = ClusterTree::new(scene);
        let mut c = Clusters {
            radiance: Radiance::default(),
            to_cluster: vec![Vec::new(); tree.len()],
            to_patch: vec![Vec::new(); scene.patches.len()],
            patch_weight: Vec::new(),
            cluster_weight: Vec::new(),
            tree,
        };
        c.radiance = c.pull(scene, |p| (scene.patches[p].emission, 1.0));
        c
    }

    /// Number of cluster links.
    pub fn link_count(&self) -> u64 {
        self.to_cluster
            .iter()
            .chain(&self.to_patch)
            .map(|l| l.len() as u64)
            .sum()
    }

    /// Bytes held (tree, links, radiance).
    pub fn memory_bytes(&self) -> u64 {
        let lists = (self.to_cluster.capacity() + self.to_patch.capacity())
            * std::mem::size_of::<Vec<ClusterLink>>();
        let links: usize = self
            .to_cluster
            .iter()
            .chain(&self.to_patch)
            .map(|l| l.capacity() * std::mem::size_of::<ClusterLink>())
            .sum();
        let radiance = self.radiance.power.capacity() * std::mem::size_of::<[DVec3; 6]>()
            + self.radiance.area.capacity() * std::mem::size_of::<Lobes>();
        (self.tree.memory_bytes() + lists + links + radiance) as u64
    }

    /// The links gathered by `receiver`.
    pub fn links(&self, receiver: Node) -> &[ClusterLink] {
        match receiver {
            Node::Cluster(c) => &self.to_cluster[c as usize],
            Node::Patch(p) => &self.to_patch[p as usize],
        }
    }

    fn links_mut(&mut self, receiver: Node) -> &mut Vec<ClusterLink> {
        match receiver {
            Node::Cluster(c) => &mut self.to_cluster[c as usize],
            Node::Patch(p) => &mut self.to_patch[p as usize],
        }
    }

    /// Sets the patches' importance weights; a cluster takes its largest.
    pub fn set_weights(&mut self, patch: &[f64]) {
        self.cluster_weight = self.tree.fold_up(|p| patch[p as usize], f64::max);
        self.patch_weight = patch.to_vec();
    }

    /// The importance weight of node `n` (1 without importance).
    fn weight(&self, n: Node) -> f64 {
        match n {
            Node::Patch(p) => self.patch_weight.get(p as usize),
            Node::Cluster(c) => self.cluster_weight.get(c as usize),
        }
        .copied()
        .unwrap_or(1.0)
    }

    /// Keeps `link` with `receiver`.
    pub fn add(&mut self, receiver: Node, link: ClusterLink) {
        self.links_mut(receiver).push(link);
    }

    /// The children of cluster `c`.
    pub fn kids(&self, c: u32) -> [Node; 2] {
        self.tree.clusters[c as usize].kids
    }
}
