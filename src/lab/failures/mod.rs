//! The failure-mode table: every method on every stress scene, measured.
//!
//! Owns the table's settings ([`TableSettings`]) and its driver
//! ([`scene_table`]: one scene, every method, one [`SceneTable`]). The parts
//! live one concept to a file:
//!
//! - `methods`: the methods of the table ([`table_methods`]: each
//!   form-factor kernel under Gauss-Seidel, each classic solver with the
//!   point-polygon kernel, and the hierarchical solver with each
//!   output-mesh mode);
//! - `closed_form`: the exact powers a stress scene has ([`closed_form()`]);
//! - `yardstick`: the path-traced [`Reference`] image, the pixels it is
//!   compared on and its own noise;
//! - `measure`: running one method within its budget and measuring it
//!   ([`measure()`]);
//! - `symptoms`: naming what went wrong by fixed rules ([`symptoms()`],
//!   [`limits`]);
//! - `markdown`: writing the table ([`markdown()`]).
//!
//! `cargo run --release --example failure-table` drives it.
//!
//! Invariants:
//! - A run that fails, panics or produces non-finite values is a row of the
//!   table, never an abort: the table documents failures, so it must
//!   survive them.
//! - Every run has a budget (sweeps, shots, links, the dense matrix's
//!   memory) and reports whether it converged within it.
//! - The yardsticks are independent of the methods measured: the closed
//!   forms of [`crate::formfactor::closed_form`] and Lambert's point-to-polygon formula
//!   for power, and the path tracer of [`crate::reference`] for the image.
//! - Symptoms are derived from the measurements by fixed rules
//!   ([`symptoms()`]), so regenerating the table cannot flatter a method.

mod closed_form;
mod markdown;
mod measure;
mod methods;
mod symptoms;
mod yardstick;

use std::path::Path;

use glam::DVec3;

use crate::error::Result;
use crate::render::view::{View, ViewOverrides};
use crate::scene::Scene;

pub use closed_form::{ClosedForm, Quantity, closed_form, receiver_integrals};
pub use markdown::markdown;
pub use measure::{Measure, Outcome, measure};
pub use methods::{TableMethod, table_methods};
pub use symptoms::{limits, symptoms};
pub use yardstick::{HOT_SPOT, Reference, receiver_pixels, reference, reference_noise};

/// The table's view, samples and budgets.
#[derive(Clone, Debug, PartialEq)]
pub struct TableSettings {
    /// Width of the reference and of every render, pixels.
    pub width: u32,
    /// Height of the reference and of every render, pixels.
    pub height: u32,
    /// Paths per pixel of the reference.
    pub reference_spp: u32,
    /// Samples per pixel of each method's render.
    pub render_spp: u32,
    /// Seed of the reference, the sampled kernels and the renders.
    pub seed: u64,
    /// Gathering budget: sweeps (Jacobi, Gauss-Seidel; per round for the
    /// hierarchical solver).
    pub max_sweeps: usize,
    /// Shooting budget: shots.
    pub max_shots: usize,
    /// Hierarchical link budget.
    pub max_links: u64,
}

impl Default for TableSettings {
    fn default() -> Self {
        TableSettings {
            width: 96,
            height: 64,
            reference_spp: 1024,
            render_spp: 16,
            seed: 0,
            max_sweeps: 1000,
            max_shots: 200_000,
            max_links: 1_000_000,
        }
    }
}

impl TableSettings {
    /// The scene camera's view at the table's size.
    pub fn view(&self) -> ViewOverrides {
        ViewOverrides {
            width: Some(self.width),
            height: Some(self.height),
            ..ViewOverrides::default()
        }
    }
}

/// Every method on one scene.
#[derive(Clone, Debug)]
pub struct SceneTable {
    /// The scene's name (file stem).
    pub name: String,
    /// The scene's closed form, when it has one.
    pub exact: Option<ClosedForm>,
    /// The reference's own relative noise ([`reference_noise`]).
    pub reference_noise: f64,
    /// Seconds the reference took to render (NaN when read from the cache).
    pub reference_seconds: f64,
    /// (method label, what became of it), in method order.
    pub rows: Vec<(&'static str, Outcome)>,
}

impl SceneTable {
    /// The fastest successful run, in seconds.
    pub fn fastest(&self) -> f64 {
        self.rows
            .iter()
            .filter_map(|(_, o)| match o {
                Outcome::Ran(m) => Some(m.seconds),
                _ => None,
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// Runs every method of `methods` on `scene` (called `name`), against its
/// closed form and its reference (cached in `cache`). `each` is told of
/// every finished row.
pub fn scene_table(
    scene: &Scene,
    name: &str,
    t: &TableSettings,
    methods: &[TableMethod],
    cache: Option<&Path>,
    mut each: impl FnMut(&str, &Outcome),
) -> Result<SceneTable> {
    let view = View::resolve(scene.cameras.first(), scene.bounds, &t.view())?;
    let reference = reference(scene, name, &view, t, cache)?;
    let exact = closed_form(name, scene);
    let mut rows = Vec::new();
    for m in methods {
        let outcome = measure(scene, m, exact.as_ref(), &reference);
        each(m.label, &outcome);
        rows.push((m.label, outcome));
    }
    Ok(SceneTable {
        name: name.to_string(),
        exact,
        reference_noise: reference_noise(&reference),
        reference_seconds: reference.seconds,
        rows,
    })
}

/// The mean of the three channels of `v`.
fn mean3(v: DVec3) -> f64 {
    (v.x + v.y + v.z) / 3.0
}
