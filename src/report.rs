//! `report.json`: what a run did, for users and for the study tools.
//!
//! Owns: the report's schema. Every field is plain data (serde); the
//! pipeline fills it, `output` writes it, `nusselt render` reads the view
//! back from it.
//!
//! Invariant: times are wall-clock seconds per phase; powers are watts per
//! RGB channel; counts are exact.

use serde::{Deserialize, Serialize};

use crate::render::view::View;

/// Seconds spent in each phase of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseTimes {
    pub load: f64,
    /// Hierarchical: initial linking of the input patches.
    #[serde(default)]
    pub linking: f64,
    /// Hierarchical: link and gradient refinement after the first solve.
    #[serde(default)]
    pub refinement: f64,
    pub bvh: f64,
    /// Hierarchical, discontinuity mesh: finding the discontinuity segments.
    #[serde(default)]
    pub discontinuities: f64,
    pub mesh: f64,
    pub form_factors: f64,
    pub solve: f64,
    pub output_mesh: f64,
    pub render: f64,
    pub write: f64,
    pub total: f64,
}

/// Sizes of everything the run built.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Counts {
    pub input_triangles: usize,
    pub degenerate_dropped: usize,
    pub merged_quads: usize,
    pub patches: usize,
    pub elements: usize,
    pub leaves: usize,
    /// Non-zero element interactions (matrix entries or hierarchy links).
    pub links: u64,
    pub visibility_rays: u64,
    /// Bytes held by the elements and the links (or the matrix).
    #[serde(default)]
    pub memory_bytes: u64,
    pub output_vertices: usize,
    pub output_triangles: usize,
    /// Hierarchical with clustering: clusters above the patches, and the
    /// links (counted in `links`) with a cluster at one end or both; 0
    /// without.
    #[serde(default)]
    pub clusters: usize,
    #[serde(default)]
    pub cluster_links: u64,
}

/// How the view's importance weighed refinement.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ImportanceReport {
    /// Patches the view sees directly (importance 1).
    pub patches_seen: usize,
    /// Patches whose links' errors counted at more than 1 % (seen, or
    /// reflecting light toward what is seen).
    pub patches_weighted: usize,
}

/// One step of an iterative solve.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HistoryEntry {
    pub iteration: usize,
    pub residual: f64,
    pub seconds: f64,
}

/// How the solve ended.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ConvergenceReport {
    pub converged: bool,
    pub iterations: usize,
    pub tolerance: f64,
    pub history: Vec<HistoryEntry>,
    /// Hierarchical: one entry per refinement round.
    #[serde(default)]
    pub rounds: Vec<crate::hierarchical::Round>,
}

/// Energy balance, W per channel.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Power {
    /// Σ E_i A_i.
    pub emitted: [f64; 3],
    /// Σ (1 − ρ_i) H_i A_i: what the surfaces absorb.
    pub absorbed: [f64; 3],
    /// Σ B_i A_i: all power leaving surfaces.
    pub radiated: [f64; 3],
}

/// The whole report.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub nusselt_version: String,
    pub scene: String,
    pub method: String,
    /// Every setting of the run, by name.
    pub settings: serde_json::Value,
    pub counts: Counts,
    /// Hierarchical: how the output mesh was made.
    #[serde(default)]
    pub mesh: Option<crate::meshing::MeshStats>,
    pub times: PhaseTimes,
    pub convergence: ConvergenceReport,
    pub power: Power,
    /// Hierarchical: the resource budget that stopped refinement (`null`
    /// when none did, and for the classic methods).
    #[serde(default)]
    pub budget: Option<crate::hierarchical::BudgetHit>,
    /// Hierarchical with `--importance`: refinement was weighed by the
    /// view's importance (`null` when it was not).
    #[serde(default)]
    pub importance: Option<ImportanceReport>,
    /// Closure diagnostics of the form factors: largest and mean Σ_j F_ij.
    pub max_row_sum: f64,
    pub mean_row_sum: f64,
    pub view: Option<View>,
    /// Display exposure used for `render.png` and `COLOR_0` of the bake.
    pub exposure: f32,
    pub threads: usize,
    pub warnings: Vec<String>,
}
