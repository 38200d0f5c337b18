//! `report.json`: what a run did, for users and for the study tools.
//!
//! Owns: the report's schema. Every field is plain data (serde); the
//! pipeline fills it, `output` writes it, `nusselt render` reads the view
//! back from it. Its JSON Schema is generated from these types
//! ([`crate::schema`]).
//!
//! Invariants: times are wall-clock seconds per phase; powers are watts per
//! RGB channel; counts are exact. What does not apply to a run (a phase
//! its method does not have, the row sums of a matrix the hierarchical
//! method never builds) is `null`, never a zero. [`SCHEMA_VERSION`] changes
//! whenever a field is removed, renamed or changes meaning.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::render::view::View;

/// Seconds spent in each phase of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhaseTimes {
    /// Reading the scene.
    pub load: f64,
    /// Hierarchical: initial linking of the input patches (`null` for the
    /// classic methods, as every phase a method does not have).
    #[serde(default)]
    pub linking: Option<f64>,
    /// Hierarchical: link and gradient refinement after the first solve.
    #[serde(default)]
    pub refinement: Option<f64>,
    /// Building the occluder BVH.
    pub bvh: f64,
    /// Hierarchical, discontinuity mesh: finding the discontinuity segments.
    #[serde(default)]
    pub discontinuities: Option<f64>,
    /// Classic: the uniform mesh.
    #[serde(default)]
    pub mesh: Option<f64>,
    /// Classic: the form-factor matrix.
    #[serde(default)]
    pub form_factors: Option<f64>,
    /// The solve proper (gathering, shooting or elimination; with the
    /// hierarchical method's defect correction).
    pub solve: f64,
    /// The output mesh and its vertex values.
    pub output_mesh: f64,
    /// Rendering the default view and the snapshots.
    pub render: f64,
    /// With `--lightmap`: charting, packing and filling the atlases.
    #[serde(default)]
    pub lightmap: Option<f64>,
    /// Writing the outputs.
    pub write: f64,
    /// The whole run.
    pub total: f64,
}

impl PhaseTimes {
    /// Seconds spent building and solving the system: the BVH, the mesh
    /// and form factors or the linking and refinement, and the solve
    /// (without loading, discontinuities, output mesh, render and write).
    pub fn solving(&self) -> f64 {
        let optional = [self.mesh, self.form_factors, self.linking, self.refinement];
        self.bvh + optional.into_iter().flatten().sum::<f64>() + self.solve
    }
}

/// Sizes of everything the run built.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Counts {
    /// Triangles read from the file.
    pub input_triangles: usize,
    /// Degenerate triangles dropped.
    pub degenerate_dropped: usize,
    /// Triangle pairs merged into quad patches.
    pub merged_quads: usize,
    /// Radiosity patches.
    pub patches: usize,
    /// Elements (hierarchy nodes, or uniform elements).
    pub elements: usize,
    /// Leaves (elements without children).
    pub leaves: usize,
    /// Non-zero element interactions (matrix entries or hierarchy links).
    pub links: u64,
    /// Visibility rays cast.
    pub visibility_rays: u64,
    /// Bytes held by the elements and the links (or the matrix).
    #[serde(default)]
    pub memory_bytes: u64,
    /// Vertices of the output mesh.
    pub output_vertices: usize,
    /// Triangles of the output mesh.
    pub output_triangles: usize,
    /// Hierarchical: clusters above the patches (0 without clustering,
    /// `null` for the classic methods).
    #[serde(default)]
    pub clusters: Option<usize>,
    /// Hierarchical: of `links`, those with a cluster at one end or both.
    #[serde(default)]
    pub cluster_links: Option<u64>,
}

/// How the view's importance weighed refinement.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ImportanceReport {
    /// Patches the view sees directly (importance 1).
    pub patches_seen: usize,
    /// Patches whose links' errors counted at more than 1 % (seen, or
    /// reflecting light toward what is seen).
    pub patches_weighted: usize,
}

/// One step of an iterative solve.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct HistoryEntry {
    /// Iteration (sweep or shot) number, from 1.
    pub iteration: usize,
    /// Relative change it made.
    pub residual: f64,
    /// Seconds since the solve started.
    pub seconds: f64,
}

/// How the solve ended.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ConvergenceReport {
    /// The tolerance was met.
    pub converged: bool,
    /// Iterations run.
    pub iterations: usize,
    /// The tolerance asked for.
    pub tolerance: f64,
    /// Every iteration.
    pub history: Vec<HistoryEntry>,
    /// Hierarchical: one entry per refinement round.
    #[serde(default)]
    pub rounds: Vec<crate::hierarchical::Round>,
    /// Hierarchical: refinement ran all `--max-rounds` rounds with links
    /// still above the threshold (more rounds would refine further);
    /// `null` for the classic methods.
    #[serde(default)]
    pub rounds_exhausted: Option<bool>,
}

/// What the defect correction did (`hierarchical::correction`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CorrectionReport {
    /// What each pass found.
    pub passes: Vec<crate::hierarchical::CorrectionPass>,
    /// Seconds in the correction's rays (part of `times.solve`).
    pub seconds: f64,
}

/// Energy balance, W per channel.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Power {
    /// The power entering the scene: Σ E_i A_i, plus `lights`.
    pub emitted: [f64; 3],
    /// Of `emitted`, what the punctual lights and the sky bring to the
    /// surfaces directly (Σ H_light,i A_i).
    #[serde(default)]
    pub lights: [f64; 3],
    /// Σ (1 − ρ_i) H_i A_i: what the surfaces absorb.
    pub absorbed: [f64; 3],
    /// Σ B_i A_i: all power leaving surfaces.
    pub radiated: [f64; 3],
}

/// The version of the report's layout; see the module doc for when it
/// changes.
pub const SCHEMA_VERSION: u32 = 2;

/// The whole report.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Report {
    /// [`SCHEMA_VERSION`] of the program that wrote it.
    pub schema_version: u32,
    /// Version of the program that wrote the report.
    pub nusselt_version: String,
    /// The scene file, as given.
    pub scene: String,
    /// The solver.
    pub method: String,
    /// Every setting of the run, by name.
    pub settings: serde_json::Value,
    /// Sizes of what the run built.
    pub counts: Counts,
    /// Hierarchical: how the output mesh was made.
    #[serde(default)]
    pub mesh: Option<crate::meshing::MeshStats>,
    /// Seconds per phase.
    pub times: PhaseTimes,
    /// How the solve ended.
    pub convergence: ConvergenceReport,
    /// Emitted, absorbed and radiated power.
    pub power: Power,
    /// Hierarchical: the resource budget that stopped refinement (`null`
    /// when none did, and for the classic methods).
    #[serde(default)]
    pub budget: Option<crate::hierarchical::BudgetHit>,
    /// Hierarchical: the budget that stopped the first linking and how much
    /// coarser the thresholds it started again with are (`null` when it
    /// fitted, and for the classic methods).
    #[serde(default)]
    pub coarsened: Option<crate::hierarchical::Coarsened>,
    /// Hierarchical with `--importance`: refinement was weighed by the
    /// view's importance (`null` when it was not).
    #[serde(default)]
    pub importance: Option<ImportanceReport>,
    /// The solve's own estimate of its vertex error: how much the vertices
    /// that coplanar patches share disagree (`meshing::seams`; a lower
    /// bound, blind to a bias all patches share). `null` when no two
    /// coplanar patches meet.
    #[serde(default)]
    pub estimated_error: Option<crate::meshing::seams::SeamSteps>,
    /// Hierarchical: the defect correction (`null` when off).
    #[serde(default)]
    pub correction: Option<CorrectionReport>,
    /// Classic: closure diagnostics of the form factors, the largest
    /// Σ_j F_ij (`null` for the hierarchical method, which has no matrix).
    #[serde(default)]
    pub max_row_sum: Option<f64>,
    /// Classic: the mean Σ_j F_ij over the rows.
    #[serde(default)]
    pub mean_row_sum: Option<f64>,
    /// Classic, with a kernel that estimates its error (`sampling`,
    /// `polygon-polygon`): the mean over the rows of Σ_j (estimated
    /// absolute error of F_ij), how far a row sum may be off by the
    /// kernel's own account (`null` otherwise).
    #[serde(default)]
    pub mean_row_error: Option<f64>,
    /// Classic, as `mean_row_error`: the largest estimated error of one
    /// form factor.
    #[serde(default)]
    pub max_form_factor_error: Option<f64>,
    /// The view of the main render.
    pub view: Option<View>,
    /// With `--lightmap`: the atlas (`null` without).
    #[serde(default)]
    pub lightmap: Option<crate::lightmap::LightmapStats>,
    /// Display exposure of `render.png` and the bake's `COLOR_0`: the
    /// solution's own (`output::png::solution_exposure`) or `--exposure`.
    pub exposure: f32,
    /// Worker threads.
    pub threads: usize,
    /// Non-fatal findings, one line each.
    pub warnings: Vec<String>,
    /// Every other file of the run, in the order written, with its size
    /// and CRC-32. `report.json` is the last file of the run put in place
    /// and the first removed when a later run replaces it (`output::commit`),
    /// so a folder whose `report.json` lists files that are all there with
    /// these sizes and CRCs holds one run's complete result set.
    #[serde(default)]
    pub files: Vec<FileRecord>,
}

/// One file of a run, as `report.json` lists it.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
pub struct FileRecord {
    /// The file's name in the run's folder.
    pub name: String,
    /// Its size in bytes.
    pub bytes: u64,
    /// Its CRC-32 (zlib's, as Python's `zlib.crc32` gives it).
    pub crc32: u32,
}

impl FileRecord {
    /// The record of `bytes` written as `name`.
    pub fn of(name: &str, bytes: &[u8]) -> FileRecord {
        FileRecord {
            name: name.to_string(),
            bytes: bytes.len() as u64,
            crc32: crc32fast::hash(bytes),
        }
    }

    /// Whether `bytes` are this record's file.
    pub fn matches(&self, bytes: &[u8]) -> bool {
        self.bytes == bytes.len() as u64 && self.crc32 == crc32fast::hash(bytes)
    }
}
