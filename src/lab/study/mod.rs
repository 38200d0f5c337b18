//! `nusselt study`: sweeps of methods and settings against a path-traced
//! reference, for speed-against-accuracy charts.
//!
//! Owns the driver, [`run_study`], in phases: resolve the view, get the
//! reference, run and measure every configuration, then assemble the
//! files. The parts live one concept to a file:
//!
//! - `config`: the sweep's JSON ([`StudyConfig`], [`RunSpec`]) and its
//!   expansion into pipeline settings;
//! - `measure`: the reference (given, cached beside the results through
//!   `crate::lab::reference_cache`, or path traced) and one run's
//!   [`StudyRow`];
//! - `sheet`: the contact sheet (pairs of image and relative-error map, 0
//!   to 20 %, magma; the reference pairs with its own relative noise);
//! - `results`: `results.csv`, the charts (mean relative error: RMSE is
//!   dominated by the few pixels on an emitter's edge, which every method
//!   gets about equally wrong) and [`write_study`].
//!
//! Invariants: the reference is computed once per (scene, view, spp, seed)
//! and cached beside the results; every run renders the same view so
//! images compare pixel for pixel; [`run_study`] writes nothing itself,
//! [`write_study`] writes everything together.

mod config;
mod measure;
mod results;
mod sheet;

use std::path::Path;

use crate::error::Result;
use crate::output;
use crate::pipeline;
use crate::render::frame::Frame;
use crate::render::view::View;
use crate::scene::Scene;
use crate::util::progress::Progress;

pub use config::{RunSpec, StudyConfig};
pub use measure::StudyRow;
pub use results::write_study;

use measure::{ReferenceSource, StudyReference};
use sheet::{ContactSheet, RunTile};

/// Everything a study produces, ready to write.
pub struct StudyResult {
    /// One row per run, in configuration order.
    pub rows: Vec<StudyRow>,
    /// (file name, bytes): results.csv, charts, contact sheet, renders.
    pub files: Vec<(String, Vec<u8>)>,
}

/// Runs the sweep of `config` on `scene` against the reference (given, or
/// computed and cached in `dir`).
pub fn run_study(
    scene: &Scene,
    scene_name: &str,
    config: &StudyConfig,
    given_reference: Option<(Frame, Option<Frame>)>,
    dir: &Path,
    progress: &Progress,
) -> Result<StudyResult> {
    config.validate()?;
    // The view every run renders, and the reference at that view.
    let overrides = config.view();
    let view = View::resolve(scene.cameras.first(), scene.bounds, &overrides)?;
    let mut files = Vec::new();
    let source = ReferenceSource {
        scene,
        scene_name,
        config,
        view: &view,
        dir,
        progress,
    };
    let reference = StudyReference::resolve(&source, given_reference, &mut files)?;
    let exposure = pipeline::frame_exposure(&reference.image);
    let mut sheet = ContactSheet::new(&reference, exposure);
    // Every run: solve, measure, keep its render and its tiles.
    let mut rows = Vec::new();
    for spec in &config.runs {
        for (setting, s) in spec.runs(scene, config, &overrides)? {
            let run = pipeline::solve(scene, &s, &Progress::hidden())?;
            let metrics = reference.compare(&spec.label, &run.frame)?;
            let o = &metrics.overall;
            rows.push(StudyRow::new(spec, &setting, &run, o));
            files.push((
                results::run_png_name(&spec.label, &setting),
                output::png::encode_png(&run.frame, exposure)?,
            ));
            let tile = RunTile {
                method: s.method,
                method_name: &spec.method,
                setting: &setting,
                mean_relative_error: o.mean_relative_error,
            };
            sheet.push_run(tile, &run.frame, &reference.image);
        }
    }
    // The results: the CSV, the charts, the contact sheet.
    files.push(("results.csv".into(), results::encode_results(&rows)?));
    files.extend(results::charts(&rows)?);
    files.push((
        "contact-sheet.png".into(),
        sheet.encode(view.width, view.height)?,
    ));
    Ok(StudyResult { rows, files })
}
