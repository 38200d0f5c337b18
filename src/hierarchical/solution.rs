//! What a hierarchical solve returns: the hierarchy, the links, the
//! irradiance, the convergence history and the rounds of refinement, and
//! what budget (if any) stopped it.
//!
//! Invariant: after a solve, every element's radiosity is consistent with
//! push-pull (B = E + ρ H at leaves, the area-weighted mean of the
//! children above), and `links[e]` are the links element `e` gathers over.

use glam::DVec3;

use crate::hierarchical::budget::{BudgetHit, Coarsened};
use crate::hierarchical::cluster::Clusters;
use crate::hierarchical::gather::seen_radiosity;
use crate::hierarchical::hierarchy::Hierarchy;
use crate::hierarchical::link::Link;
use crate::hierarchical::oracle::Thresholds;

/// One gather + push-pull iteration.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Iteration {
    /// Number of the iteration over the whole solve, from 1.
    pub iteration: usize,
    /// Relative change of the total power Σ B·A.
    pub residual: f64,
    /// Seconds since the solve started.
    pub seconds: f64,
}

/// What one refinement round did: what it split, the sizes after it, and
/// the solve that followed (also the `rounds` of `report.json`).
#[derive(
    Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct Round {
    /// Number of the round, from 0.
    pub round: usize,
    /// Links the oracle split this round.
    pub split_links: u64,
    /// Leaves split for their radiosity gradient.
    pub gradient_splits: u64,
    /// Links sampled again with more visibility rays because their source
    /// got brighter ([`crate::hierarchical::oracle::rays_needed`]).
    pub resampled_links: u64,
    /// Elements after the round.
    pub elements: usize,
    /// Leaves after the round.
    pub leaves: usize,
    /// Links after the round.
    pub links: u64,
    /// Iterations of the solve that followed.
    pub iterations: usize,
    /// Wall time of the round.
    pub seconds: f64,
}

/// Timings, in seconds.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct HierarchicalTimes {
    /// Initial linking (cluster oracle or all patch pairs).
    pub linking: f64,
    /// Refinement after the initial linking (guided splits and rounds).
    pub refinement: f64,
    /// Gather and push-pull iterations.
    pub solve: f64,
    /// The defect correction's rays.
    pub correction: f64,
}

/// What one pass of defect correction found (`hierarchical::correction`).
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
pub struct CorrectionPass {
    /// The net residual: the area-weighted (ray gather − links) that was
    /// fed back, over the links' reflected light. The first pass says how
    /// far the links were from their own transport; later passes should
    /// fall towards the rays' noise.
    pub residual: f64,
    /// Rays cast.
    pub rays: usize,
    /// Of them, rays that hit the back of a one-sided surface (left out
    /// of the gather).
    pub back_faces: usize,
}

/// The result of `solve_hierarchical`.
#[derive(Clone, Debug)]
pub struct HierarchicalSolution {
    /// The quadtrees of the patches.
    pub hierarchy: Hierarchy,
    /// `links[e]`: the links element e gathers over.
    pub links: Vec<Vec<Link>>,
    /// Total irradiance H (own links + pushed from ancestors) per element;
    /// meaningful at leaves, where B = E + ρ H.
    pub irradiance: Vec<DVec3>,
    /// Every gather + push-pull iteration.
    pub history: Vec<Iteration>,
    /// Every refinement round.
    pub rounds: Vec<Round>,
    /// The last solve met the tolerance.
    pub converged: bool,
    /// The budget that stopped refinement, if one did.
    pub budget: Option<BudgetHit>,
    /// Refinement stopped at `max_rounds` with links still to split.
    pub rounds_exhausted: bool,
    /// Visibility rays cast.
    pub visibility_rays: u64,
    /// Seconds per phase.
    pub times: HierarchicalTimes,
    /// The thresholds used, in scene units.
    pub thresholds: Thresholds,
    /// When a budget stopped the first linking: how much coarser the
    /// thresholds it started again with are (`None`: the settings' own).
    pub coarsened: Option<Coarsened>,
    /// The clusters and their links, when the solve clustered.
    pub clusters: Option<Clusters>,
    /// Per patch, the irradiance the cluster links deliver (constant over
    /// the patch; empty without clusters), and the part of it that comes
    /// from emission.
    pub cluster_irradiance: Vec<DVec3>,
    /// Per patch, the part of `cluster_irradiance` that comes from emission (the sources' own light).
    pub cluster_direct: Vec<DVec3>,
    /// Per patch, the irradiance the defect correction adds (a mean over
    /// the patch's whole area, like `irradiance`; empty: none).
    pub correction: Vec<DVec3>,
    /// Per element, the mean irradiance the punctual lights and the sky
    /// bring (a part of `irradiance` at the leaves; zero without them).
    pub external: Vec<DVec3>,
    /// Sky rays per point of the final gather ([`crate::hierarchical::Accuracy::sky_rays`]).
    pub sky_rays: usize,
    /// What each defect-correction pass found.
    pub correction_passes: Vec<CorrectionPass>,
    /// Per patch, the importance weight refinement used last (empty
    /// without importance).
    pub importance: Vec<f64>,
}

impl HierarchicalSolution {
    /// Number of links, cluster links included.
    pub fn link_count(&self) -> u64 {
        self.links.iter().map(|l| l.len() as u64).sum::<u64>() + self.cluster_link_count()
    }

    /// Number of links with a cluster at one end or both.
    pub fn cluster_link_count(&self) -> u64 {
        self.clusters.as_ref().map_or(0, Clusters::link_count)
    }

    /// Bytes held by the hierarchy and the links (capacities included).
    pub fn memory_bytes(&self) -> u64 {
        let lists = self.links.capacity() * std::mem::size_of::<Vec<Link>>();
        let links: usize = self
            .links
            .iter()
            .map(|l| l.capacity() * std::mem::size_of::<Link>())
            .sum();
        let irradiance = (self.irradiance.capacity()
            + self.cluster_irradiance.capacity()
            + self.cluster_direct.capacity())
            * std::mem::size_of::<DVec3>();
        let clusters = self.clusters.as_ref().map_or(0, Clusters::memory_bytes);
        (self.hierarchy.memory_bytes() + lists + links + irradiance) as u64 + clusters
    }

    /// Irradiance per element from the element links whose source lies on
    /// a patch accepted by `from_patch`, own links plus those of every
    /// ancestor, each link's source weighed as the solve weighs it over
    /// its children when its rays saw them partly hidden
    /// ([`Link::seen_shares`]; cluster links, which mix patches, are not
    /// counted).
    pub fn irradiance_from(&self, from_patch: impl Fn(u32) -> bool) -> Vec<DVec3> {
        let h = &self.hierarchy;
        let own: Vec<DVec3> = self
            .links
            .iter()
            .map(|ls| {
                ls.iter()
                    .filter(|l| from_patch(h.get(l.source).patch))
                    .map(|l| {
                        let b = match l.seen_shares() {
                            Some(w) => seen_radiosity(h, l.source, w),
                            None => h.get(l.source).exposed_radiosity,
                        };
                        l.coupling() * b
                    })
                    .sum()
            })
            .collect();
        // Parents precede their children in the arena; a child gets its
        // parent's mean by exposure, as in the solve.
        let mut total = own;
        for i in 0..h.len() {
            let e = &h.elements[i];
            if let Some(p) = e.parent() {
                let parent = f64::from(h.elements[p.index()].exposure);
                if parent > 0.0 {
                    let down = total[p.index()] * (f64::from(e.exposure) / parent);
                    total[i] += down;
                }
            }
        }
        total
    }
}
