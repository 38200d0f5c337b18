//! The hierarchical radiosity solver [HSA91] with multigridding: initial
//! linking (from the root cluster's self-link when clustering,
//! [`crate::hierarchical::cluster`], else every facing pair of input patches),
//! oracle-driven link refinement, gradient refinement, and gather +
//! push-pull iterations (through the cluster levels too).
//!
//! Owns: [`Accuracy`] (the presets and every threshold),
//! [`HierarchicalSettings`] (with the resource budgets, [`BudgetHit`]),
//! [`solve_hierarchical`] and the output mesh of a hierarchy,
//! [`leaf_output_mesh`].
//!
//! Invariants:
//! - Links live with their receivers (`links[receiver]`), in an order that
//!   depends only on the scene and the settings: refinement runs serially
//!   over candidate lists in id order, and only the independent work (link
//!   evaluation, oracle decisions, gathers) runs in parallel, each result
//!   written to its own slot. Results are identical for any thread count.
//! - Every threshold is relative to the scene (mean emitted exitance,
//!   largest patch emitted power, total area), so a setting means the same
//!   at any scale.
//! - After [`solve_hierarchical`], every element's radiosity is consistent
//!   with push-pull: B = E + ρ H at leaves, the area-weighted mean of the
//!   children above.
//! - Resource budgets: no split or cluster opening makes the link count
//!   exceed `max_links`, the element count exceed `max_elements`, or
//!   [`memory_estimate`] exceed `memory_budget`, nor happens after
//!   `time_budget` seconds; a refused split keeps its link, a refused
//!   opening keeps its cluster link, the round loop stops, and
//!   [`HierarchicalSolution::budget`] names the first budget that refused
//!   one. Every `Hierarchy::split` call goes through `Solver::refuse_split`,
//!   every opening through `Solver::refuse_links`; a pair of touching
//!   clusters ignores the time budget, and one the link or memory budget
//!   refuses carries no light. (Without clustering the initial
//!   patch-to-patch links are not budgeted.)
//! - Cluster links count in the link total and the budgets; their
//!   irradiance is added to the patch roots' before push-pull.
//!
//! The loop ("multigridding", [HSA91] §5): refine every link with the
//! current radiosities; gather + push-pull until the total power Σ B·A
//! changes by less than the tolerance; split leaves whose radiosity differs
//! from a sibling's by more than the gradient tolerance; repeat until a
//! round changes nothing or `max_rounds` is reached.

pub mod cluster;
pub mod hierarchy;
pub mod link;
pub mod oracle;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::discontinuity::Segment;
use crate::hierarchical::cluster::{ClusterLink, Clusters, Evaluation, Node, Step};
use crate::hierarchical::hierarchy::{ElementId, Hierarchy, split_corners};
use crate::hierarchical::link::{Link, evaluate_link, faces_each_other};
use crate::hierarchical::oracle::{
    Decision, Oracle, Thresholds, decide, rays_needed, shadow_error, sharpen,
    split_at_any_visibility, visibility_error,
};
use crate::scene::{Scene, polygon_centroid};
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// The named accuracy presets of `--accuracy`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    Preview,
    Default,
    High,
}

/// Every threshold of the hierarchical solver, relative to the scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Accuracy {
    /// ff oracle: largest accepted form factor.
    pub ff_eps: f64,
    /// bf oracle: largest accepted ρ_r B_s (V F_err + V_err F + V_err F_err),
    /// as a fraction of the mean emitted exitance (Φ / A_total).
    pub bf_eps: f64,
    /// power oracle: largest accepted A_r F V ρ_r B_s, as a fraction of the
    /// largest patch emitted power.
    pub power_eps: f64,
    /// Cluster oracle: largest accepted ρ_r times the irradiance error of
    /// a link with a cluster at one end (W/m², as a fraction of the mean
    /// emitted exitance). Finer than `bf_eps`: a cluster link also shares
    /// its light among members it cannot see apart ([`crate::hierarchical::cluster`]).
    pub cluster_eps: f64,
    /// Elements at or below this fraction of the total area are not split.
    pub min_area: f64,
    /// Leaves whose radiosity differs from a sibling's by more than this
    /// fraction of the mean emitted exitance are split (0 disables).
    pub gradient_tol: f64,
    /// Link budget: refinement stops when it is reached (`None`: unlimited).
    pub max_links: Option<u64>,
    /// Element budget: no split makes the hierarchy larger (`None`:
    /// unlimited).
    pub max_elements: Option<u64>,
    /// Refinement rounds (refine, solve) at most.
    pub max_rounds: usize,
}

impl Accuracy {
    /// Quick look: coarse shadows.
    pub fn preview() -> Accuracy {
        Accuracy {
            ff_eps: 0.05,
            bf_eps: 0.2,
            power_eps: 1e-3,
            cluster_eps: 0.02,
            min_area: 1e-4,
            gradient_tol: 0.5,
            max_links: None,
            max_elements: None,
            max_rounds: 3,
        }
    }

    /// The default: soft shadows resolved on the Cornell box in about a
    /// second.
    #[allow(clippy::should_implement_trait)]
    pub fn default() -> Accuracy {
        Accuracy {
            ff_eps: 0.01,
            bf_eps: 0.03,
            power_eps: 1e-4,
            cluster_eps: 0.003,
            min_area: 2e-5,
            gradient_tol: 0.15,
            max_links: None,
            max_elements: None,
            max_rounds: 5,
        }
    }

    /// Finer elements and links for final images.
    pub fn high() -> Accuracy {
        Accuracy {
            ff_eps: 0.002,
            bf_eps: 0.006,
            power_eps: 2e-5,
            cluster_eps: 0.0006,
            min_area: 4e-6,
            gradient_tol: 0.05,
            max_links: None,
            max_elements: None,
            max_rounds: 8,
        }
    }

    /// The preset's values.
    pub fn preset(p: Preset) -> Accuracy {
        match p {
            Preset::Preview => Accuracy::preview(),
            Preset::Default => Accuracy::default(),
            Preset::High => Accuracy::high(),
        }
    }
}

impl Default for Accuracy {
    fn default() -> Self {
        Accuracy::default()
    }
}

/// How `solve --method hierarchical` runs.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HierarchicalSettings {
    pub oracle: Oracle,
    pub accuracy: Accuracy,
    /// Rays per link for its visible fraction.
    pub visibility_rays: usize,
    pub seed: u64,
    /// Stop gathering when Σ B·A changes by less than this fraction.
    pub tolerance: f64,
    /// Gather + push-pull iterations per round at most.
    pub max_iterations: usize,
    /// Bytes the hierarchy, the links and the solver's working arrays may
    /// take, as [`memory_estimate`] counts them: no split crosses it.
    pub memory_budget: u64,
    /// Whether links start from a cluster hierarchy above the patches
    /// ([`crate::hierarchical::cluster`]) or from every pair of patches.
    pub clustering: Clustering,
    /// Seconds of linking and refinement after which no element is split
    /// and no cluster pair opened unless its clusters touch: the links as
    /// they are then are solved. Results then depend on the machine's
    /// speed (`None`: no limit).
    pub time_budget: Option<f64>,
    /// View importance [SAS92]: per patch, 1 where a view sees it directly
    /// (else 0). Refinement then weighs each receiver's link errors by the
    /// patch's importance, this seen-ness carried back along the links
    /// (see [`Solver::update_importance`]); `None`: every patch counts
    /// fully.
    #[serde(skip)]
    pub importance: Option<Vec<f32>>,
}

/// `--clustering`: how the initial links are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Clustering {
    /// Clusters when the scene has at least [`Clustering::AUTO_PATCHES`]
    /// patches.
    #[default]
    Auto,
    /// Always start from the root cluster's self-link.
    On,
    /// Link every pair of patches that face each other (k² pairs).
    Off,
}

impl Clustering {
    /// Patch count from which `Auto` clusters: a million patch pairs.
    pub const AUTO_PATCHES: usize = 1000;

    /// True when a scene of `patches` patches is clustered.
    pub fn applies(self, patches: usize) -> bool {
        match self {
            Clustering::Auto => patches >= Clustering::AUTO_PATCHES,
            Clustering::On => true,
            Clustering::Off => false,
        }
    }
}

impl Default for HierarchicalSettings {
    fn default() -> Self {
        HierarchicalSettings {
            oracle: Oracle::Bf,
            accuracy: Accuracy::default(),
            visibility_rays: 32,
            seed: 0,
            tolerance: 1e-5,
            max_iterations: 10_000,
            memory_budget: DEFAULT_MEMORY_BUDGET,
            clustering: Clustering::Auto,
            time_budget: None,
            importance: None,
        }
    }
}

/// Default of [`HierarchicalSettings::memory_budget`]: 2 GiB, the same as
/// the dense matrix's.
pub const DEFAULT_MEMORY_BUDGET: u64 = crate::classic::matrix::DEFAULT_MEMORY_BUDGET;

/// Bytes per element in [`memory_estimate`]: the element, its link list,
/// its irradiance and gathered irradiance, its list of oracle decisions.
const ELEMENT_BYTES: u64 = (std::mem::size_of::<crate::hierarchical::hierarchy::Element>()
    + std::mem::size_of::<Vec<Link>>()
    + 2 * std::mem::size_of::<DVec3>()
    + std::mem::size_of::<Vec<Decision>>()) as u64;

/// Bytes per link in [`memory_estimate`] other than a kept cluster link:
/// an element link, its oracle decision, and the pair and evaluation it
/// takes while being settled; or a cluster pair waiting for the oracle
/// (the pair with spare capacity, the oracle's step), which is less. Not
/// every link is being settled at once, so this also covers the spare
/// capacity of the link lists.
const LINK_BYTES: u64 = (std::mem::size_of::<Link>()
    + std::mem::size_of::<Decision>()
    + std::mem::size_of::<Pair>()
    + std::mem::size_of::<(Link, u64, Decision)>()) as u64;

/// Bytes per kept cluster link in [`memory_estimate`]: the link, doubled
/// for the spare capacity of its list.
const CLUSTER_LINK_BYTES: u64 = 2 * std::mem::size_of::<ClusterLink>() as u64;

const _: () = assert!(
    LINK_BYTES as usize
        >= 2 * std::mem::size_of::<(Node, Node)>() + std::mem::size_of::<(Step, u64)>()
);

/// The peak memory of a hierarchical solve with `elements` elements and
/// `links` links, `cluster_links` of them kept cluster links, in bytes:
/// counts times per-item sizes, the elements' doubled for the spare
/// capacity of growing vectors. Cheap (no walk over the lists), and above
/// what the solver holds: the memory budget is checked against it. (The
/// scene, its BVH and the cluster tree, fixed before solving starts, are
/// not counted.)
pub fn memory_estimate(elements: u64, links: u64, cluster_links: u64) -> u64 {
    let cluster_links = cluster_links.min(links);
    elements
        .saturating_mul(2 * ELEMENT_BYTES)
        .saturating_add((links - cluster_links).saturating_mul(LINK_BYTES))
        .saturating_add(cluster_links.saturating_mul(CLUSTER_LINK_BYTES))
}

/// A resource budget of the hierarchical solver.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Budget {
    /// [`Accuracy::max_links`].
    Links,
    /// [`Accuracy::max_elements`].
    Elements,
    /// [`HierarchicalSettings::memory_budget`], in bytes.
    Memory,
    /// [`HierarchicalSettings::time_budget`], in milliseconds.
    Time,
}

impl Budget {
    /// What it counts, as in "the link budget".
    pub fn noun(self) -> &'static str {
        match self {
            Budget::Links => "link",
            Budget::Elements => "element",
            Budget::Memory => "memory",
            Budget::Time => "time",
        }
    }

    /// The command-line option that sets it.
    pub fn option(self) -> &'static str {
        match self {
            Budget::Links => "--max-links",
            Budget::Elements => "--max-elements",
            Budget::Memory => "--memory-budget",
            Budget::Time => "--time-budget",
        }
    }
}

/// The budget that stopped refinement (also `budget` in `report.json`):
/// its limit and the value reached when the solve ended (links, elements,
/// or estimated bytes; at most the limit unless the initial linking alone
/// exceeded it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BudgetHit {
    pub kind: Budget,
    pub limit: u64,
    pub reached: u64,
}

impl BudgetHit {
    /// One line for the warnings, naming the option to raise.
    pub fn message(&self) -> String {
        let (limit, reached) = match self.kind {
            Budget::Links => (format!("{} links", self.limit), self.reached.to_string()),
            Budget::Elements => (format!("{} elements", self.limit), self.reached.to_string()),
            Budget::Memory => {
                let bytes = |b: u64| {
                    let gib = b as f64 / (1u64 << 30) as f64;
                    if gib >= 1.0 {
                        format!("{gib:.2} GiB")
                    } else {
                        format!("{:.1} MiB", gib * 1024.0)
                    }
                };
                (
                    bytes(self.limit),
                    format!("{} estimated", bytes(self.reached)),
                )
            }
            Budget::Time => {
                let secs = |ms: u64| format!("{:.1} s", ms as f64 / 1000.0);
                (secs(self.limit), secs(self.reached))
            }
        };
        format!(
            "hierarchical: refinement stopped at the {} budget of {limit} (reached {reached}); \
             raise {} for a finer solution",
            self.kind.noun(),
            self.kind.option()
        )
    }
}

/// One gather + push-pull iteration.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Iteration {
    pub iteration: usize,
    /// Relative change of the total power Σ B·A.
    pub residual: f64,
    /// Seconds since the solve started.
    pub seconds: f64,
}

/// What one refinement round did: what it split, the sizes after it, and
/// the solve that followed (also the `rounds` of `report.json`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Round {
    pub round: usize,
    /// Links the oracle split this round.
    pub split_links: u64,
    /// Leaves split for their radiosity gradient.
    pub gradient_splits: u64,
    /// Links sampled again with more visibility rays because their source
    /// got brighter ([`crate::hierarchical::oracle::rays_needed`]).
    pub resampled_links: u64,
    pub elements: usize,
    pub leaves: usize,
    pub links: u64,
    /// Iterations of the solve that followed.
    pub iterations: usize,
    pub seconds: f64,
}

/// Timings, in seconds.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct HierarchicalTimes {
    pub linking: f64,
    pub refinement: f64,
    pub solve: f64,
}

/// The result of [`solve_hierarchical`].
#[derive(Clone, Debug)]
pub struct HierarchicalSolution {
    pub hierarchy: Hierarchy,
    /// `links[e]`: the links element e gathers over.
    pub links: Vec<Vec<Link>>,
    /// Total irradiance H (own links + pushed from ancestors) per element;
    /// meaningful at leaves, where B = E + ρ H.
    pub irradiance: Vec<DVec3>,
    pub history: Vec<Iteration>,
    pub rounds: Vec<Round>,
    /// The last solve met the tolerance.
    pub converged: bool,
    /// The budget that stopped refinement, if one did.
    pub budget: Option<BudgetHit>,
    /// Refinement stopped at `max_rounds` with links still to split.
    pub rounds_exhausted: bool,
    pub visibility_rays: u64,
    pub times: HierarchicalTimes,
    /// The thresholds used, in scene units.
    pub thresholds: Thresholds,
    /// The clusters and their links, when the solve clustered.
    pub clusters: Option<Clusters>,
    /// Per patch, the irradiance the cluster links deliver (constant over
    /// the patch; empty without clusters), and the part of it that comes
    /// from emission.
    pub cluster_irradiance: Vec<DVec3>,
    pub cluster_direct: Vec<DVec3>,
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
    /// ancestor (cluster links, which mix patches, are not counted).
    pub fn irradiance_from(&self, from_patch: impl Fn(u32) -> bool) -> Vec<DVec3> {
        let h = &self.hierarchy;
        let own: Vec<DVec3> = self
            .links
            .iter()
            .map(|ls| {
                ls.iter()
                    .filter(|l| from_patch(h.get(l.source).patch))
                    .map(|l| l.coupling() * h.get(l.source).exposed_radiosity)
                    .sum()
            })
            .collect();
        // Parents precede their children in the arena.
        let mut total = own;
        for i in 0..h.len() {
            if let Some(p) = h.elements[i].parent() {
                let up = total[p.index()];
                total[i] += up;
            }
        }
        total
    }
}

/// Mean emitted exitance Φ / A_total (largest channel), and the largest
/// patch emitted power: the scales of the relative thresholds.
pub(crate) fn scene_scales(scene: &Scene) -> (f64, f64, f64) {
    let area = scene.total_area();
    let exitance = scene.emitted_power().max_element() / area;
    let largest = scene
        .patches
        .iter()
        .map(|p| (p.emission * p.area).max_element())
        .fold(0.0, f64::max);
    (exitance, largest, area)
}

/// A (receiver, source) pair waiting for its link to be evaluated.
#[derive(Clone, Copy, Debug)]
struct Pair {
    receiver: ElementId,
    source: ElementId,
    /// The link this pair refines saw its source whole: a visibility probe
    /// may stand for the full set of rays ([`evaluate_link`]).
    whole: bool,
}

impl Pair {
    fn refining(receiver: ElementId, source: ElementId, whole: bool) -> Pair {
        Pair {
            receiver,
            source,
            whole,
        }
    }
}

/// The state of a solve in progress.
struct Solver<'a> {
    scene: &'a Scene,
    bvh: &'a TriangleBvh,
    settings: &'a HierarchicalSettings,
    thresholds: Thresholds,
    hierarchy: Hierarchy,
    links: Vec<Vec<Link>>,
    n_links: u64,
    /// Of `n_links`, the kept cluster links.
    n_cluster_links: u64,
    rays: u64,
    /// The first budget that refused a split.
    budget: Option<Budget>,
    /// Links resampled with more rays so far.
    resampled: u64,
    /// Elements `..measured` have their exposure measured (the arena only
    /// grows).
    measured: usize,
    clusters: Option<Clusters>,
    start: Instant,
    /// Per patch, the weight in [0, 1] of its links' errors (empty: 1).
    weight: Vec<f64>,
}

/// Jacobi sweeps of the importance equation per update.
const IMPORTANCE_SWEEPS: usize = 12;

/// ρ of `patch` times its importance weight (`weight` empty: ρ).
fn weighted_rho(scene: &Scene, weight: &[f64], patch: u32) -> DVec3 {
    let rho = scene.patches[patch as usize].reflectance;
    weight.get(patch as usize).map_or(rho, |w| rho * *w)
}

impl Solver<'_> {
    /// Carries the view's importance back along the links: Y = R + Kᵀ Y
    /// per patch, R the directly seen patches and K_pq the share of p's
    /// radiosity that its element links gather from q (Σ over links of
    /// A_r / A_p · ρ_p · F·V), by Jacobi sweeps; the weights are Y capped
    /// at 1. (Cluster links are left out: they carry far, weak light.)
    fn update_importance(&mut self) {
        let Some(seen) = &self.settings.importance else {
            return;
        };
        let (scene, h) = (self.scene, &self.hierarchy);
        let terms: Vec<(u32, u32, f64)> = self
            .links
            .iter()
            .enumerate()
            .flat_map(|(r, ls)| {
                let re = &h.elements[r];
                let p = &scene.patches[re.patch as usize];
                let share = re.area / p.area * p.reflectance.max_element();
                ls.iter()
                    .map(move |l| (re.patch, h.get(l.source).patch, share * l.coupling()))
            })
            .collect();
        let seen: Vec<f64> = seen.iter().map(|&v| f64::from(v)).collect();
        let mut y = seen.clone();
        for _ in 0..IMPORTANCE_SWEEPS {
            let mut next = seen.clone();
            for &(p, q, k) in &terms {
                next[q as usize] += k * y[p as usize];
            }
            y = next;
        }
        self.weight = y.into_iter().map(|v| v.min(1.0)).collect();
        if let Some(c) = &mut self.clusters {
            c.set_weights(&self.weight);
        }
    }

    /// True when the time budget is spent.
    fn out_of_time(&self) -> bool {
        self.settings
            .time_budget
            .is_some_and(|t| self.start.elapsed().as_secs_f64() > t)
    }

    /// The budget that splitting `id` (four new elements unless it is
    /// split already) and adding `extra` links would exceed, if any.
    fn exceeded(&self, id: ElementId, extra: u64) -> Option<Budget> {
        let acc = &self.settings.accuracy;
        let links = self.n_links + extra;
        let new = if self.hierarchy.get(id).is_leaf() {
            4
        } else {
            0
        };
        let elements = self.hierarchy.len() as u64 + new;
        if acc.max_links.is_some_and(|max| links > max) {
            Some(Budget::Links)
        } else if acc.max_elements.is_some_and(|max| elements > max) {
            Some(Budget::Elements)
        } else if memory_estimate(elements, links, self.n_cluster_links)
            > self.settings.memory_budget
        {
            Some(Budget::Memory)
        } else if self.out_of_time() {
            Some(Budget::Time)
        } else {
            None
        }
    }

    /// True when splitting `id` and adding `extra` links would exceed a
    /// budget; the first budget to refuse is remembered. Every split asks
    /// this first.
    fn refuse_split(&mut self, id: ElementId, extra: u64) -> bool {
        let hit = self.exceeded(id, extra);
        if self.budget.is_none() {
            self.budget = hit;
        }
        hit.is_some()
    }

    /// The budget that refused a split, with its limit and what was
    /// reached.
    fn budget_hit(&self) -> Option<BudgetHit> {
        let (elements, links) = (self.hierarchy.len() as u64, self.n_links);
        let acc = &self.settings.accuracy;
        self.budget.map(|kind| {
            let (limit, reached) = match kind {
                Budget::Links => (acc.max_links.unwrap_or(0), links),
                Budget::Elements => (acc.max_elements.unwrap_or(0), elements),
                Budget::Memory => (
                    self.settings.memory_budget,
                    memory_estimate(elements, links, self.n_cluster_links),
                ),
                Budget::Time => (
                    (self.settings.time_budget.unwrap_or(0.0) * 1000.0) as u64,
                    self.start.elapsed().as_millis() as u64,
                ),
            };
            BudgetHit {
                kind,
                limit,
                reached,
            }
        })
    }

    /// Carries out a split decision on the counted link (receiver `r`,
    /// `link`): the link is removed and the child pairs are appended to
    /// `next`. Returns false (nothing done) for `Accept` or when the link
    /// budget is reached.
    fn apply(
        &mut self,
        r: ElementId,
        link: Link,
        decision: Decision,
        next: &mut Vec<Pair>,
    ) -> bool {
        let target = match decision {
            Decision::Accept => return false,
            Decision::Resample => {
                // The same pair again, with the rays it now needs.
                next.push(Pair::refining(r, link.source, false));
                self.resampled += 1;
                return true;
            }
            Decision::SplitReceiver => r,
            Decision::SplitSource => link.source,
        };
        if self.refuse_split(target, 3) {
            return false;
        }
        let children = self.hierarchy.split(target);
        let (receivers, sources) = if decision == Decision::SplitReceiver {
            (children, [link.source; 4])
        } else {
            ([r; 4], children)
        };
        // One link becomes four.
        self.n_links += 3;
        let whole = link.wholly_visible();
        next.extend(
            receivers
                .into_iter()
                .zip(sources)
                .map(|(r, s)| Pair::refining(r, s, whole)),
        );
        true
    }

    /// Evaluates the (receiver, source) pairs and refines until every link
    /// is accepted, shadows included ([`Solver::shadow_splits`]), or the
    /// budget stops it. Returns the links split.
    fn settle(&mut self, mut pending: Vec<Pair>) -> u64 {
        let mut splits = 0;
        loop {
            splits += self.settle_links(pending);
            let (more, moved) = self.shadow_splits();
            if more.is_empty() {
                return splits;
            }
            splits += moved;
            pending = more;
        }
    }

    /// Receivers crossed by a shadow edge of a whole source patch: for each
    /// receiver above the minimum area, the shadow errors of its links are
    /// summed per source patch ([`shadow_error`]); where a sum exceeds the
    /// threshold, the receiver is split and those of the patch's links
    /// whose visibility varies over it move to the children. This bounds
    /// the error of a shadow that the per-link oracle misses because the
    /// source was split into many small pieces, each link's share below
    /// the threshold. Returns the child pairs to evaluate and the links
    /// moved.
    fn shadow_splits(&mut self) -> (Vec<Pair>, u64) {
        let t = self.thresholds;
        let weight = &self.weight;
        let h = &self.hierarchy;
        let scene = self.scene;
        let eps = match t.oracle {
            Oracle::Ff => t.ff_eps,
            Oracle::Bf => t.bf_eps,
            Oracle::Power => t.power_eps,
        };
        // Per receiver, the source patches whose links move down (sorted).
        let marked: Vec<Vec<u32>> = self
            .links
            .par_iter()
            .enumerate()
            .with_min_len(64)
            .map(|(r, ls)| {
                let re = &h.elements[r];
                if !(re.area > t.min_area) || ls.iter().all(|l| l.spread() == 0.0) {
                    return Vec::new();
                }
                let rho = weighted_rho(scene, weight, re.patch);
                let mut per_patch: Vec<(u32, f64)> = ls
                    .iter()
                    .filter(|l| l.spread() > 0.0)
                    .map(|l| {
                        let s = h.get(l.source);
                        (
                            s.patch,
                            shadow_error(&t, l, re.area, rho, s.exposed_radiosity),
                        )
                    })
                    .collect();
                per_patch.sort_by_key(|(p, _)| *p);
                let mut out = Vec::new();
                for group in per_patch.chunk_by(|a, b| a.0 == b.0) {
                    if group.iter().map(|(_, e)| e).sum::<f64>() > eps {
                        out.push(group[0].0);
                    }
                }
                out
            })
            .collect();
        let mut pending = Vec::new();
        let mut moved = 0;
        for (r, patches) in marked.into_iter().enumerate() {
            if patches.is_empty() {
                continue;
            }
            let own = std::mem::take(&mut self.links[r]);
            let (down, keep): (Vec<Link>, Vec<Link>) = own.into_iter().partition(|l| {
                l.spread() > 0.0
                    && patches
                        .binary_search(&self.hierarchy.get(l.source).patch)
                        .is_ok()
            });
            self.links[r] = keep;
            let extra = 3 * down.len() as u64;
            if self.refuse_split(ElementId(r as u32), extra) {
                self.links[r].extend(down);
                continue;
            }
            self.n_links += extra;
            moved += down.len() as u64;
            for child in self.hierarchy.split(ElementId(r as u32)) {
                pending.extend(down.iter().map(|l| Pair::refining(child, l.source, false)));
            }
        }
        self.links.resize_with(self.hierarchy.len(), Vec::new);
        (pending, moved)
    }

    /// Evaluates the (receiver, source) pairs in parallel, then keeps the
    /// accepted links, splits for the others and repeats until every new
    /// link is accepted (or the budget stops it). Returns the links split.
    fn settle_links(&mut self, mut pending: Vec<Pair>) -> u64 {
        let mut splits = 0;
        while !pending.is_empty() {
            let seed = self.settings.seed;
            let (scene, bvh, elements) = (self.scene, self.bvh, &self.hierarchy.elements);
            let t = &self.thresholds;
            let evaluated: Vec<(Link, u64, Decision)> = pending
                .par_iter()
                .with_min_len(8)
                .map(|p| {
                    let (r, s) = (p.receiver, p.source);
                    let (re, se) = (&elements[r.index()], &elements[s.index()]);
                    let rho = weighted_rho(scene, &self.weight, re.patch);
                    let state = self.hierarchy.source_state(s);
                    let plan = |l: &Link| {
                        let n = rays_needed(t, l, re, se, &state, rho);
                        if split_at_any_visibility(t, l, re, se, &state, rho, n) {
                            0
                        } else {
                            n
                        }
                    };
                    let (mut link, cast) =
                        evaluate_link(scene, elements, r, s, bvh, seed, p.whole, plan);
                    let d = decide(t, &link, re, se, &state, rho);
                    if d == Decision::Accept {
                        sharpen(scene, t, &mut link, re, se, &state);
                    }
                    (link, cast, d)
                })
                .collect();
            let mut next = Vec::new();
            for (p, (link, cast, decision)) in pending.iter().zip(evaluated) {
                let r = p.receiver;
                self.rays += cast;
                if self.apply(r, link, decision, &mut next) {
                    splits += u64::from(decision != Decision::Resample);
                    continue;
                }
                let mut link = link;
                if decision != Decision::Accept && cast == 0 {
                    // The budget refused a split the oracle decided without
                    // visibility rays: the kept link needs its visibility.
                    let (h, source) = (&self.hierarchy, link.source);
                    let state = h.source_state(source);
                    let t = &self.thresholds;
                    let (re, se) = (h.get(r), h.get(source));
                    let rho = weighted_rho(self.scene, &self.weight, re.patch);
                    let plan = |l: &Link| rays_needed(t, l, re, se, &state, rho);
                    let (l, c) = evaluate_link(
                        self.scene,
                        &h.elements,
                        r,
                        source,
                        self.bvh,
                        seed,
                        p.whole,
                        plan,
                    );
                    link = l;
                    sharpen(self.scene, t, &mut link, h.get(r), h.get(source), &state);
                    self.rays += c;
                }
                // Fully occluded or facing away: no light, no link. A link
                // that only a few rays found occluded stays (carrying
                // nothing) until the solve ends: should its source brighten,
                // it is resampled like the others. Dropping it now would
                // bias the resampled links' light low (only those that
                // saw something would get a second look).
                let few_rays = link.rays() > 0 && link.rays() < self.thresholds.max_rays();
                if link.coupling() > 0.0 || (few_rays && link.form_factor > 0.0) {
                    self.links[r.index()].push(link);
                } else {
                    self.n_links -= 1;
                }
            }
            self.links.resize_with(self.hierarchy.len(), Vec::new);
            pending = next;
        }
        splits
    }

    /// The first links: from the root cluster's self-link when clustering,
    /// else between every pair of patches that face each other; then
    /// settled.
    fn initial_links(&mut self) -> u64 {
        if let Some(root) = self.clusters.as_ref().and_then(|c| c.tree.root) {
            let pairs = self.link_clusters(vec![(root, root)]);
            return self.settle(pairs);
        }
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
                        false,
                    ))
                })
            })
            .collect();
        self.n_links += pairs.len() as u64;
        self.settle(pairs)
    }

    /// Runs the cluster oracle on (receiver, source) node pairs, opening
    /// clusters until every pair is accepted, dropped, or reaches two
    /// patches; returns those patch pairs (facing each other) for the
    /// element links. The pairs count as links from the start, so the
    /// link and memory budgets see every pair still pending; an opening
    /// the budgets refuse keeps its pair as a cluster link. (A cluster's
    /// self-link always opens: it has no cluster-link form.)
    fn link_clusters(&mut self, mut pending: Vec<(Node, Node)>) -> Vec<Pair> {
        let mut patches = Vec::new();
        let Some(mut clusters) = self.clusters.take() else {
            return patches;
        };
        let (scene, bvh, seed) = (self.scene, self.bvh, self.settings.seed);
        let tol = 1e-9 * scene.diagonal();
        let eps = self.thresholds.cluster_eps;
        self.n_links += pending.len() as u64;
        while !pending.is_empty() {
            let elements = &self.hierarchy.elements;
            let steps: Vec<(Step, u64)> = pending
                .par_iter()
                .with_min_len(16)
                .map(|&(r, s)| clusters.examine(scene, bvh, elements, r, s, eps, seed))
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
                            patches.push(Pair::refining(ElementId(a), ElementId(b), false));
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
                            let (evaluation, rays) = clusters.evaluate(scene, bvh, r, s, seed);
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

    /// True when `extra` more links would exceed the link or memory
    /// budget, or (when `timed`) the time budget is spent; the budget is
    /// remembered as for a split.
    fn refuse_links(&mut self, extra: u64, timed: bool) -> bool {
        let acc = &self.settings.accuracy;
        let links = self.n_links + extra;
        let hit = if acc.max_links.is_some_and(|max| links > max) {
            Some(Budget::Links)
        } else if memory_estimate(self.hierarchy.len() as u64, links, self.n_cluster_links)
            > self.settings.memory_budget
        {
            Some(Budget::Memory)
        } else if timed && self.out_of_time() {
            Some(Budget::Time)
        } else {
            None
        };
        if self.budget.is_none() {
            self.budget = hit;
        }
        hit.is_some()
    }

    /// Splits every element crossed by a discontinuity segment of its patch
    /// (`guide[patch]`) while its area exceeds four times the minimum
    /// element area, level by level from the roots. The split element's
    /// links that may carry a shadow edge (partly visible, or with a
    /// visibility spread) move to its children and are settled by the
    /// oracle, which may refine them further. Returns the links moved.
    fn follow_discontinuities(&mut self, guide: &[Vec<Segment>]) -> u64 {
        let bound = 4.0 * self.thresholds.min_area;
        let tol = 1e-9 * self.scene.diagonal();
        let mut frontier: Vec<ElementId> = (0..self.hierarchy.root_count())
            .filter(|&p| guide.get(p).is_some_and(|s| !s.is_empty()))
            .map(|p| self.hierarchy.root(p))
            .collect();
        let mut moved = 0;
        while !frontier.is_empty() {
            let mut next = Vec::new();
            let mut pending = Vec::new();
            for id in frontier {
                let e = self.hierarchy.get(id);
                let normal = self.scene.patches[e.patch as usize].normal;
                let crossed = guide[e.patch as usize]
                    .iter()
                    .any(|s| segment_crosses(e.vertices(), normal, s.a, s.b, tol));
                if !(e.area > bound) || !crossed {
                    continue;
                }
                let own = std::mem::take(&mut self.links[id.index()]);
                let (down, keep): (Vec<Link>, Vec<Link>) = own
                    .into_iter()
                    .partition(|l| l.partly_visible() || l.spread() > 0.0);
                self.links[id.index()] = keep;
                let extra = 3 * down.len() as u64;
                if self.refuse_split(id, extra) {
                    self.links[id.index()].extend(down);
                    continue;
                }
                self.n_links += extra;
                moved += down.len() as u64;
                for child in self.hierarchy.split(id) {
                    pending.extend(down.iter().map(|l| Pair::refining(child, l.source, false)));
                    next.push(child);
                }
            }
            self.links.resize_with(self.hierarchy.len(), Vec::new);
            moved += self.settle(pending);
            frontier = next;
        }
        moved
    }

    /// Re-runs the oracle on every link with the current radiosities and
    /// refines those it rejects. Returns the links split.
    fn refine(&mut self) -> u64 {
        let mut next = Vec::new();
        let mut splits = 0;
        let eps = self.thresholds.cluster_eps;
        if let Some(c) = self.clusters.as_mut() {
            let rejected = c.take_rejected(self.scene, &self.hierarchy.elements, eps);
            self.n_links -= rejected.len() as u64;
            self.n_cluster_links -= rejected.len() as u64;
            splits += rejected.len() as u64;
            next = self.link_clusters(rejected);
        }
        let decisions = self.decisions();
        for (r, ds) in decisions.iter().enumerate() {
            if ds.iter().all(|d| *d == Decision::Accept) {
                continue;
            }
            let old = std::mem::take(&mut self.links[r]);
            for (l, d) in old.into_iter().zip(ds) {
                if !self.apply(ElementId(r as u32), l, *d, &mut next) {
                    self.links[r].push(l);
                } else if *d != Decision::Resample {
                    splits += 1;
                }
            }
        }
        self.links.resize_with(self.hierarchy.len(), Vec::new);
        splits + self.settle(next)
    }

    /// Splits leaves whose radiosity differs from a sibling's by more than
    /// `tol` (W/m²), pushing down to the children those of their own links
    /// that can explain such a gradient: links whose brightness-weighted
    /// variation ρ_r B_s (F_err + V_err F) exceeds `tol / 4`. The other links
    /// keep feeding the split element as a whole. A leaf without such a
    /// link is not split (its children would all be alike). Returns the
    /// leaves split.
    fn refine_gradients(&mut self, tol: f64) -> u64 {
        if !(tol > 0.0) {
            return 0;
        }
        let h = &self.hierarchy;
        let mut marked = Vec::new();
        for e in &h.elements {
            let Some(kids) = e.children() else { continue };
            for &k in &kids {
                let leaf = h.get(k);
                if !leaf.is_leaf() || !(leaf.area > self.thresholds.min_area) {
                    continue;
                }
                let w = self.weight.get(leaf.patch as usize).copied().unwrap_or(1.0);
                let differs = kids
                    .iter()
                    .any(|&o| w * (h.get(o).radiosity - leaf.radiosity).abs().max_element() > tol);
                if differs {
                    marked.push(k);
                }
            }
        }
        let mut pending = Vec::new();
        let mut split = 0;
        for k in marked {
            let rho = weighted_rho(self.scene, &self.weight, self.hierarchy.get(k).patch);
            let own = std::mem::take(&mut self.links[k.index()]);
            let (down, keep): (Vec<Link>, Vec<Link>) = own.into_iter().partition(|l| {
                let b = (rho * self.hierarchy.get(l.source).exposed_radiosity).max_element();
                let v_err = visibility_error(l);
                b * (l.error as f64 + v_err * l.form_factor as f64) > 0.25 * tol
            });
            self.links[k.index()] = keep;
            let extra = 3 * down.len() as u64;
            if down.is_empty() || self.refuse_split(k, extra) {
                self.links[k.index()].extend(down);
                continue;
            }
            split += 1;
            self.n_links += extra;
            for child in self.hierarchy.split(k) {
                for l in &down {
                    pending.push(Pair::refining(child, l.source, l.wholly_visible()));
                }
            }
        }
        self.links.resize_with(self.hierarchy.len(), Vec::new);
        self.settle(pending);
        split
    }

    /// Measures the exposure of the leaves created since the last call: of
    /// the centroids of an element's four quarters, the fraction from which
    /// a ray along the normal does not first meet the back of a surface
    /// (a point under a box on the floor, inside a closed solid, sees only
    /// backs). Elements split meanwhile get theirs from their children in
    /// push-pull.
    fn measure_exposure(&mut self) {
        let (scene, bvh) = (self.scene, self.bvh);
        let gap = 1e-6 * scene.diagonal();
        let far = 2.0 * scene.diagonal();
        let h = &mut self.hierarchy;
        h.elements[self.measured..]
            .par_iter_mut()
            .with_min_len(64)
            .filter(|e| e.is_leaf())
            .for_each(|e| {
                let n = scene.patches[e.patch as usize].normal;
                let k = e.vertices().len();
                let buried = split_corners(e.shape, &e.corners)
                    .iter()
                    .filter(|q| {
                        let from = polygon_centroid(&q[..k]) + gap * n;
                        bvh.closest_hit(from, n, far).is_some_and(|hit| {
                            let t = scene.triangles[hit.triangle as usize].positions;
                            (t[1] - t[0]).cross(t[2] - t[0]).dot(n) > 0.0
                        })
                    })
                    .count();
                e.exposure = 1.0 - buried as f32 / 4.0;
            });
        self.measured = h.len();
    }

    /// Gather + push-pull until Σ B·A changes by less than the tolerance
    /// (at least two iterations); appends to `history`. Returns whether the
    /// tolerance was met.
    fn iterate(
        &mut self,
        irradiance: &mut [DVec3],
        history: &mut Vec<Iteration>,
        start: Instant,
    ) -> bool {
        self.measure_exposure();
        let mut power = f64::NAN;
        for k in 0..self.settings.max_iterations.max(2) {
            let mut gathered = self.gather();
            if let Some(c) = &self.clusters {
                c.gather(self.scene, &self.hierarchy.elements, &mut gathered);
            }
            let p = self.push_pull(&gathered, irradiance);
            if let Some(c) = &mut self.clusters {
                c.pull_from(self.scene, &self.hierarchy.elements);
            }
            let residual = if power.is_nan() {
                1.0
            } else if p > 0.0 {
                (p - power).abs() / p
            } else {
                0.0
            };
            power = p;
            history.push(Iteration {
                iteration: history.len() + 1,
                residual,
                seconds: start.elapsed().as_secs_f64(),
            });
            if k > 0 && residual < self.settings.tolerance {
                return true;
            }
        }
        false
    }

    /// The oracle's decisions on every link, per receiver.
    fn decisions(&self) -> Vec<Vec<Decision>> {
        let t = self.thresholds;
        let h = &self.hierarchy;
        let scene = self.scene;
        self.links
            .par_iter()
            .enumerate()
            .map(|(r, ls)| {
                let re = &h.elements[r];
                let rho = weighted_rho(scene, &self.weight, re.patch);
                ls.iter()
                    .map(|l| decide(&t, l, re, h.get(l.source), &h.source_state(l.source), rho))
                    .collect()
            })
            .collect()
    }

    /// Links the oracle would split now.
    fn rejected_links(&self) -> usize {
        self.decisions()
            .iter()
            .flatten()
            .filter(|d| **d != Decision::Accept)
            .count()
    }

    /// H_e = Σ over e's links of F·V·B_source, in parallel over receivers.
    fn gather(&self) -> Vec<DVec3> {
        let h = &self.hierarchy;
        self.links
            .par_iter()
            .with_min_len(64)
            .map(|ls| {
                ls.iter()
                    .map(|l| l.coupling() * h.get(l.source).exposed_radiosity)
                    .sum()
            })
            .collect()
    }

    /// Push-pull from every root; returns Σ B·A (sum of channels) and fills
    /// the total irradiance per element.
    fn push_pull(&mut self, gathered: &[DVec3], irradiance: &mut [DVec3]) -> f64 {
        // Parents precede children in the arena: push down in arena order,
        // then pull up in reverse.
        let h = &mut self.hierarchy;
        for i in 0..h.len() {
            let down = h.elements[i]
                .parent()
                .map_or(DVec3::ZERO, |p| irradiance[p.index()]);
            irradiance[i] = gathered[i] + down;
        }
        for i in (0..h.len()).rev() {
            let e = &h.elements[i];
            let (b, exposed, exposure) = match e.children() {
                None => {
                    let p = &self.scene.patches[e.patch as usize];
                    let b = p.emission + p.reflectance * irradiance[i];
                    (b, b, e.exposure)
                }
                Some(kids) => {
                    let (mut b, mut exposed, mut exposed_area) = (DVec3::ZERO, DVec3::ZERO, 0.0);
                    for k in kids {
                        let k = &h.elements[k.index()];
                        let a = k.area * f64::from(k.exposure);
                        b += k.area * k.radiosity;
                        exposed += a * k.exposed_radiosity;
                        exposed_area += a;
                    }
                    let b = b / e.area;
                    if exposed_area > 0.0 {
                        (b, exposed / exposed_area, (exposed_area / e.area) as f32)
                    } else {
                        (b, b, 0.0)
                    }
                }
            };
            let e = &mut h.elements[i];
            e.radiosity = b;
            e.exposed_radiosity = exposed;
            e.exposure = exposure.clamp(0.0, 1.0);
        }
        (0..h.root_count())
            .map(|r| h.elements[r].radiosity.element_sum() * h.elements[r].area)
            .sum()
    }
}

/// Solves `scene` by hierarchical radiosity. Never fails: a scene without
/// links simply radiates its emission.
pub fn solve_hierarchical(
    scene: &Scene,
    bvh: &TriangleBvh,
    settings: &HierarchicalSettings,
    progress: &Progress,
) -> HierarchicalSolution {
    solve_hierarchical_guided(scene, bvh, settings, &[], progress)
}

/// [`solve_hierarchical`] with the discontinuity segments of each patch
/// (indexed by patch; shorter or empty means none) as a guide: after the
/// initial linking, elements crossed by a segment are split down to four
/// times the minimum element area and their partly visible links move to
/// the children ([`Solver::follow_discontinuities`]), so the hierarchy
/// resolves shadows along the segments and not elsewhere.
pub fn solve_hierarchical_guided(
    scene: &Scene,
    bvh: &TriangleBvh,
    settings: &HierarchicalSettings,
    guide: &[Vec<Segment>],
    progress: &Progress,
) -> HierarchicalSolution {
    let start = Instant::now();
    let acc = &settings.accuracy;
    let (exitance, largest_power, area) = scene_scales(scene);
    let thresholds = Thresholds {
        oracle: settings.oracle,
        ff_eps: acc.ff_eps,
        bf_eps: acc.bf_eps * exitance,
        cluster_eps: acc.cluster_eps * exitance,
        power_eps: acc.power_eps * largest_power,
        min_area: acc.min_area * area,
        rays: settings.visibility_rays.max(1),
    };
    let mut solver = Solver {
        scene,
        bvh,
        settings,
        thresholds,
        hierarchy: Hierarchy::new(scene),
        links: vec![Vec::new(); scene.patches.len()],
        n_links: 0,
        n_cluster_links: 0,
        rays: 0,
        resampled: 0,
        budget: None,
        measured: 0,
        clusters: None,
        start,
        weight: Vec::new(),
    };
    let mut times = HierarchicalTimes::default();
    let phase = progress.phase("hierarchical", acc.max_rounds.max(1) as u64);

    let t = Instant::now();
    if settings.clustering.applies(scene.patches.len()) {
        solver.clusters = Some(Clusters::new(scene));
    }
    if let Some(seen) = &settings.importance {
        solver.weight = (0..scene.patches.len())
            .map(|p| seen.get(p).map_or(0.0, |&v| f64::from(v).clamp(0.0, 1.0)))
            .collect();
        if let Some(c) = &mut solver.clusters {
            c.set_weights(&solver.weight);
        }
    }
    let first_splits = solver.initial_links();
    times.linking = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let guided_splits = solver.follow_discontinuities(guide);
    times.refinement += t.elapsed().as_secs_f64();

    let mut irradiance = vec![DVec3::ZERO; solver.hierarchy.len()];
    let mut history = Vec::new();
    let mut rounds = Vec::new();
    let mut converged = false;
    let mut rounds_exhausted = false;
    let mut split_links = first_splits + guided_splits;
    let mut gradient_splits = 0;
    let mut resampled_links = std::mem::take(&mut solver.resampled);
    let mut round_start = Instant::now();
    let max_rounds = acc.max_rounds.max(1);
    for round in 0..max_rounds {
        // Solve with the current links, warm-started.
        let t = Instant::now();
        irradiance.resize(solver.hierarchy.len(), DVec3::ZERO);
        let first = history.len();
        converged = solver.iterate(&mut irradiance, &mut history, start);
        times.solve += t.elapsed().as_secs_f64();
        rounds.push(Round {
            round,
            split_links,
            gradient_splits,
            resampled_links,
            elements: solver.hierarchy.len(),
            leaves: solver.hierarchy.leaf_count(),
            links: solver.n_links,
            iterations: history.len() - first,
            seconds: round_start.elapsed().as_secs_f64(),
        });
        phase.inc(1);
        if solver.budget.is_some() {
            break;
        }
        if round + 1 == max_rounds {
            rounds_exhausted = solver.rejected_links() > 0;
            break;
        }
        // Refine with the new radiosities (and importance).
        round_start = Instant::now();
        let t = Instant::now();
        solver.update_importance();
        split_links = solver.refine();
        gradient_splits = solver.refine_gradients(acc.gradient_tol * exitance);
        resampled_links = std::mem::take(&mut solver.resampled);
        times.refinement += t.elapsed().as_secs_f64();
        if split_links == 0 && gradient_splits == 0 && resampled_links == 0 {
            break;
        }
    }
    // Links to fully occluded children were never kept, except those
    // waiting for a possible resample: drop them, and release spare
    // capacity so the memory figure is what the solution holds.
    for l in &mut solver.links {
        let before = l.len();
        l.retain(|l| l.coupling() > 0.0);
        solver.n_links -= (before - l.len()) as u64;
        l.shrink_to_fit();
    }
    solver.hierarchy.elements.shrink_to_fit();
    irradiance.shrink_to_fit();
    let budget = solver.budget_hit();
    let (cluster_irradiance, cluster_direct) = solver.clusters.as_ref().map_or_else(
        || (Vec::new(), Vec::new()),
        |c| c.patch_irradiance(scene, &solver.hierarchy.elements),
    );
    HierarchicalSolution {
        importance: solver.weight,
        clusters: solver.clusters,
        cluster_irradiance,
        cluster_direct,
        links: solver.links,
        irradiance,
        history,
        rounds,
        converged,
        budget,
        rounds_exhausted,
        visibility_rays: solver.rays,
        times,
        thresholds,
        hierarchy: solver.hierarchy,
    }
}

/// True when segment `ab` (in the plane of the convex polygon `vertices`,
/// counter-clockwise about `normal`) passes through the polygon's interior
/// by more than `tol`: Cyrus–Beck clipping against the edges' inward
/// normals.
fn segment_crosses(vertices: &[DVec3], normal: DVec3, a: DVec3, b: DVec3, tol: f64) -> bool {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let d = b - a;
    for (i, &p) in vertices.iter().enumerate() {
        let q = vertices[(i + 1) % vertices.len()];
        let edge = q - p;
        let len = edge.length();
        if !(len > 0.0) {
            continue;
        }
        // Inward unit normal of the edge, in the plane.
        let m = normal.cross(edge) / len;
        // Inside by more than tol: (a + t d - p)·m > tol.
        let num = (a - p).dot(m) - tol;
        let den = d.dot(m);
        if den.abs() < 1e-300 {
            if !(num > 0.0) {
                return false;
            }
            continue;
        }
        let t = -num / den;
        if den > 0.0 {
            lo = lo.max(t);
        } else {
            hi = hi.min(t);
        }
    }
    (hi - lo) * d.length() > tol
}
