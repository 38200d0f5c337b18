//! Running one method of the failure table and measuring it.
//!
//! Owns [`Measure`] (what a row reports), [`Outcome`] (ran, refused or
//! panicked) and [`measure()`], in phases: run the method with panics
//! caught, then its power against the closed form, its output's finiteness,
//! and its render against the reference.
//!
//! Invariants: a panic or a refusal is an [`Outcome`], never an abort; the
//! measured seconds are the solve alone (no loading, rendering or
//! writing), so rows compare solvers, not output.

use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::hierarchical::Budget;
use crate::lab::failures::yardstick::masked_mean;
use crate::lab::failures::{ClosedForm, Quantity, Reference, TableMethod};
use crate::pipeline::{self, SolveRun};
use crate::render::frame::Frame;
use crate::report::{PhaseTimes, Power};
use crate::scene::Scene;
use crate::util::progress::Progress;

/// The measurements of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Measure {
    /// The solver met its tolerance within its budget.
    pub converged: bool,
    /// Iterations (sweeps, shots or rounds) it ran.
    pub iterations: usize,
    /// Wall-clock seconds of everything but loading, rendering and writing.
    pub seconds: f64,
    /// Elements of the solution.
    pub elements: usize,
    /// Hierarchical links, or the classic matrix's non-zero form factors.
    pub links: u64,
    /// Vertices of the output mesh.
    pub vertices: usize,
    /// Absorbed / emitted power (channel means).
    pub absorbed_ratio: f64,
    /// (measured − exact) / exact of the closed form's quantity; / emitted
    /// when the exact value is 0.
    pub power_error: Option<f64>,
    /// RMSE of the render against the reference over the reference's mean.
    pub image_error: f64,
    /// (mean of the render − mean of the reference) / mean of the reference.
    pub image_bias: f64,
    /// Some vertex or pixel is NaN, infinite or negative.
    pub non_finite: bool,
    /// The budget that stopped refinement, if one did.
    pub budget: Option<Budget>,
}

/// What became of one method on one scene.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// The method ran (whether or not its results are any good).
    Ran(Measure),
    /// The method refused the scene (its error message).
    Refused(String),
    /// The method panicked (the panic message): a bug.
    Panicked(String),
}

/// Runs `method` on `scene` and measures it against `exact` and
/// `reference`.
pub fn measure(
    scene: &Scene,
    method: &TableMethod,
    exact: Option<&ClosedForm>,
    reference: &Reference,
) -> Outcome {
    // Run, with panics and refusals as outcomes.
    let run = catch_unwind(AssertUnwindSafe(|| {
        pipeline::solve(scene, &method.settings, &Progress::hidden())
    }));
    let run = match run {
        Err(payload) => return Outcome::Panicked(panic_message(payload.as_ref())),
        Ok(Err(e)) => return Outcome::Refused(e.to_string()),
        Ok(Ok(run)) => run,
    };
    let r = &run.report;
    // Power, against the closed form.
    let power = PowerMeans::of(&r.power);
    let power_error = exact.map(|c| power.error(c));
    // The output, against the reference.
    let non_finite = has_non_finite(&run);
    let (image_error, image_bias) = image_errors(&run.frame, reference);
    Outcome::Ran(Measure {
        converged: r.convergence.converged,
        iterations: r.convergence.iterations,
        seconds: solve_seconds(&r.times),
        elements: r.counts.elements,
        links: r.counts.links,
        vertices: r.counts.output_vertices,
        absorbed_ratio: power.absorbed_ratio(),
        power_error,
        image_error,
        image_bias,
        non_finite,
        budget: r.budget.as_ref().map(|b| b.kind),
    })
}

/// The message of a caught panic.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".into())
}

/// The channel means of a run's powers, watts.
struct PowerMeans<'a> {
    power: &'a Power,
    emitted: f64,
    absorbed: f64,
}

impl PowerMeans<'_> {
    fn of(power: &Power) -> PowerMeans<'_> {
        PowerMeans {
            power,
            emitted: power.emitted.iter().sum::<f64>() / 3.0,
            absorbed: power.absorbed.iter().sum::<f64>() / 3.0,
        }
    }

    /// [`Measure::power_error`] against `exact`.
    fn error(&self, exact: &ClosedForm) -> f64 {
        let measured = match exact.quantity {
            Quantity::Absorbed => self.absorbed,
            Quantity::Radiated => self.power.radiated.iter().sum::<f64>() / 3.0,
        };
        if exact.watts > 0.0 {
            (measured - exact.watts) / exact.watts
        } else {
            measured / self.emitted
        }
    }

    /// [`Measure::absorbed_ratio`]: 0 when nothing is emitted.
    fn absorbed_ratio(&self) -> f64 {
        if self.emitted > 0.0 {
            self.absorbed / self.emitted
        } else {
            0.0
        }
    }
}

/// Whether some pixel of the render or some vertex radiosity is NaN,
/// infinite or negative.
fn has_non_finite(run: &SolveRun) -> bool {
    let bad = |v: f32| !(v.is_finite() && v >= 0.0);
    run.frame.pixels.iter().flatten().any(|&v| bad(v))
        || run
            .mesh
            .radiosity
            .iter()
            .any(|b| b.to_array().into_iter().any(bad))
}

/// [`Measure::seconds`]: every phase of the solve, without loading,
/// rendering and writing.
fn solve_seconds(t: &PhaseTimes) -> f64 {
    t.solving() + t.discontinuities.unwrap_or(0.0) + t.output_mesh
}

/// RMSE and mean difference of `frame` against the reference over the
/// counted pixels, both relative to [`Reference::scale`].
fn image_errors(frame: &Frame, reference: &Reference) -> (f64, f64) {
    let diff = Frame {
        pixels: frame
            .pixels
            .iter()
            .zip(&reference.image.pixels)
            .map(|(t, r)| [t[0] - r[0], t[1] - r[1], t[2] - r[2]])
            .collect(),
        ..frame.clone()
    };
    let squares = Frame {
        pixels: diff.pixels.iter().map(|p| p.map(|c| c * c)).collect(),
        ..diff.clone()
    };
    let rmse = masked_mean(&squares, &reference.counted).sqrt();
    let bias = masked_mean(&diff, &reference.counted);
    (rmse / reference.scale, bias / reference.scale)
}
