//! nusselt: global illumination of diffuse scenes by hierarchical
//! radiosity.
//!
//! A glTF 2.0 scene goes in; the light leaving every surface comes out, as
//! per-vertex radiosity (OpenEXR), a baked glTF, rendered views and a
//! report. The stages, each a module, in the order a solve runs them:
//!
//! | stage | module |
//! |---|---|
//! | read the glTF file | [`load`] |
//! | patches, materials, cameras | [`scene`] |
//! | ray queries against the occluders | [`visibility`], [`sampling`] |
//! | form-factor kernels | [`formfactor`] |
//! | uniform mesh, dense matrix, classic solvers | [`classic`] |
//! | shadow discontinuity segments (they guide refinement) | [`discontinuity`] |
//! | hierarchy, links, oracle, clusters, solve | [`hierarchical`] |
//! | output mesh and the final gather at its vertices | [`meshing`], [`mesh`] |
//! | images of the output mesh | [`render`] |
//! | the independent path tracer | [`reference`](mod@reference) |
//! | files and the report | [`output`], [`report`], [`schema`] |
//! | the `solve` job, phase by phase | [`pipeline`] |
//! | comparison, charts, studies, the failure table | [`lab`] |
//!
//! The library does no printing: it returns results and diagnostics, and
//! only [`output`] writes files. Every setting type checks itself
//! (`validate`), and the entry points call it.
//!
//! # Quick start
//!
//! Solve the bundled closed box, check that what the surfaces absorb is
//! what the emitter emits, and write the outputs:
//!
//! ```
//! use nusselt::{LoadOptions, Progress, SolveSettings, load_scene, solve, write_outputs};
//!
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/goral-box.gltf");
//! let scene = load_scene(path.as_ref(), &LoadOptions::default())?;
//! let mut settings = SolveSettings::default();
//! settings.view.width = Some(32);
//! settings.view.height = Some(32);
//! let mut run = solve(&scene, &settings, &Progress::hidden())?;
//!
//! let power = &run.report.power;
//! for c in 0..3 {
//!     let ratio = power.absorbed[c] / power.emitted[c];
//!     assert!((ratio - 1.0).abs() < 0.02, "absorbed/emitted {ratio}");
//! }
//! let dir = std::env::temp_dir().join("nusselt-quick-start");
//! let written = write_outputs(&dir, &mut run)?;
//! assert!(written.iter().any(|p| p.ends_with("solution.exr")));
//! # std::fs::remove_dir_all(&dir).ok();
//! # Ok::<(), nusselt::Error>(())
//! ```

// `!(x > y)` is used on purpose throughout: it rejects NaN along with the
// values the comparison excludes. Index loops are the clearest form of the
// numeric kernels here.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod error;
pub mod util;

// Input.
pub mod load;

pub mod scene;

// Geometry queries and kernels.
pub mod visibility;

pub mod sampling;

pub mod illumination;

pub mod formfactor;

// Solvers.
pub mod classic;

pub mod discontinuity;

pub mod hierarchical;

// Output mesh.
pub mod mesh;

pub mod meshing;

// Images and files.
pub mod render;

pub mod reference;

pub mod output;

pub mod lightmap;

pub mod report;
pub mod schema;

// The job, and the tools around it.
pub mod pipeline;

pub mod lab;

#[doc(hidden)]
pub mod fuzz;

pub use error::{Error, Result};
pub use hierarchical::{Accuracy, HierarchicalSettings, Preset};
pub use load::{LoadOptions, load_scene};
pub use mesh::OutputMesh;
pub use pipeline::{Method, SolveRun, SolveSettings, solve, write_outputs};
pub use report::Report;
pub use scene::Scene;
pub use util::progress::Progress;
