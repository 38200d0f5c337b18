//! The budget checks of a solve in progress: the memory estimate, whether
//! a split or a cluster opening may go ahead, and which budget stopped
//! refinement.
//!
//! Invariant: every `Hierarchy::split` goes through
//! [`Solver::refuse_split`], every cluster opening through
//! [`Solver::refuse_links`]; the first budget that refuses is remembered
//! and reported ([`BudgetHit`]).

use glam::DVec3;

use crate::hierarchical::budget::{Budget, BudgetHit};
use crate::hierarchical::cluster::{ClusterLink, Node, Step};
use crate::hierarchical::gather::Shares;
use crate::hierarchical::hierarchy::ElementId;
use crate::hierarchical::link::Link;
use crate::hierarchical::oracle::Decision;
use crate::hierarchical::solver::{Pair, Solver};

/// Bytes per element in [`memory_estimate`]: the element, its link list,
/// its irradiance and gathered irradiance, its list of oracle decisions,
/// its list of source shares.
const ELEMENT_BYTES: u64 = (std::mem::size_of::<crate::hierarchical::hierarchy::Element>()
    + std::mem::size_of::<Vec<Link>>()
    + std::mem::size_of::<Vec<(u32, Shares)>>()
    + 2 * std::mem::size_of::<DVec3>()
    + std::mem::size_of::<Vec<Decision>>()) as u64;

/// Bytes per link in [`memory_estimate`] other than a kept cluster link:
/// an element link, its oracle decision, and the pair and evaluation it
/// takes while being settled, or a cluster pair waiting for the oracle
/// (the pair with spare capacity, the oracle's step), whichever is
/// larger. Not every link is being settled at once, so this also covers
/// the spare capacity of the link lists; and a solve's source shares (4
/// bytes a link at most, 8 with its index), which live only while no link
/// is being settled.
const LINK_BYTES: u64 = max(
    std::mem::size_of::<Link>()
        + std::mem::size_of::<Decision>()
        + std::mem::size_of::<Pair>()
        + std::mem::size_of::<(Link, u64, Decision)>(),
    2 * std::mem::size_of::<(Node, Node)>() + std::mem::size_of::<(Step, u64)>(),
) as u64;

const fn max(a: usize, b: usize) -> usize {
    if a > b { a } else { b }
}

/// Bytes per kept cluster link in [`memory_estimate`]: the link, doubled
/// for the spare capacity of its list.
const CLUSTER_LINK_BYTES: u64 = 2 * std::mem::size_of::<ClusterLink>() as u64;

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

impl Solver<'_> {
    /// True when the time budget is spent.
    pub(super) fn out_of_time(&self) -> bool {
        self.settings
            .time_budget
            .is_some_and(|t| self.start.elapsed().as_secs_f64() > t)
    }

    /// The budget that splitting `id` (four new elements unless it is
    /// split already) and adding `extra` links would exceed, if any.
    pub(super) fn exceeded(&self, id: ElementId, extra: u64) -> Option<Budget> {
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
    pub(super) fn refuse_split(&mut self, id: ElementId, extra: u64) -> bool {
        let hit = self.exceeded(id, extra);
        if self.budget.is_none() {
            self.budget = hit;
        }
        hit.is_some()
    }

    /// True when `extra` more links would exceed the link or memory
    /// budget, or (when `timed`) the time budget is spent; the budget is
    /// remembered as for a split.
    pub(super) fn refuse_links(&mut self, extra: u64, timed: bool) -> bool {
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

    /// The budget that refused a split, with its limit and what was
    /// reached.
    pub(super) fn budget_hit(&self) -> Option<BudgetHit> {
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
}
