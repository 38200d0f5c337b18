//! The hierarchical radiosity solver \[HSA91\] with multigridding: initial
//! linking (from the root cluster's self-link when clustering,
//! [`crate::hierarchical::cluster`], else every facing pair of input patches),
//! oracle-driven link refinement, gradient refinement, and gather +
//! push-pull iterations (through the cluster levels too).
//!
//! Owns: [`Accuracy`] (the presets and every threshold),
//! [`HierarchicalSettings`] (with the resource budgets, [`BudgetHit`]),
//! [`solve_hierarchical`] and the output mesh of a hierarchy,
//! `leaf_output_mesh`.
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
//! The loop ("multigridding", \[HSA91\] §5): refine every link with the
//! current radiosities; gather + push-pull until the total power Σ B·A
//! changes by less than the tolerance; split leaves whose radiosity differs
//! from a sibling's by more than the gradient tolerance; repeat until a
//! round changes nothing or `max_rounds` is reached.

pub mod budget;
pub mod cluster;
mod correction;
mod gather;
pub mod hierarchy;
mod importance;
mod limits;
pub mod link;
mod linking;
pub mod oracle;
mod refine;
pub mod settings;
pub mod solution;
mod solver;

pub use budget::{Budget, BudgetHit, Coarsened};
pub use limits::memory_estimate;
pub use refine::CONTACT_AREA_FRACTION;
pub use settings::{
    Accuracy, Clustering, DEFAULT_CORRECTION_PASSES, DEFAULT_CORRECTION_RAYS,
    DEFAULT_CORRECTION_TOLERANCE, DEFAULT_MEMORY_BUDGET, HierarchicalSettings, Preset,
};
pub use solution::{CorrectionPass, HierarchicalSolution, HierarchicalTimes, Iteration, Round};
pub(crate) use solver::scene_scales;
pub use solver::{solve_hierarchical, solve_hierarchical_guided};
