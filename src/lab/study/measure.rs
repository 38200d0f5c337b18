//! Measuring the runs of a study against its reference.
//!
//! Owns the reference a study compares with ([`StudyReference`]: given by
//! the caller, or read from the study's folder through
//! [`crate::lab::reference_cache`] with its key in sidecars, or path traced
//! and staged for caching there) and [`StudyRow`], the measurements of one
//! run as `results.csv` has them.
//!
//! Invariants: the reference is computed at most once per (scene, view,
//! spp, seed) and folder; it must have the size of the study's view, so
//! every run compares pixel for pixel; metrics are those of
//! [`crate::lab::compare`], all channels pooled.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::lab::compare::{self, ChannelMetrics, Metrics, Named};
use crate::lab::reference_cache::{self, Naming, ReferenceCache, ReferenceKey};
use crate::lab::study::{RunSpec, StudyConfig};
use crate::pipeline::SolveRun;
use crate::render::frame::Frame;
use crate::render::view::View;
use crate::scene::Scene;
use crate::util::progress::Progress;

/// One measured run: a row of `results.csv`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StudyRow {
    /// The run's [`RunSpec::label`].
    pub label: String,
    /// The run's [`RunSpec::method`].
    pub method: String,
    /// The accuracy preset, or the element fraction.
    pub setting: String,
    /// Elements of the solution.
    pub elements: usize,
    /// Leaf elements of the solution.
    pub leaves: usize,
    /// Hierarchical links, or the classic matrix's non-zero form factors.
    pub links: u64,
    /// Seconds to the solution: linking, form factors, refinement, solve
    /// (not output meshing or rendering).
    pub solve_seconds: f64,
    /// Seconds of the render compared.
    pub render_seconds: f64,
    /// The solver met its tolerance within its budget.
    pub converged: bool,
    /// RMSE against the reference, all channels pooled.
    pub rmse: f64,
    /// RMSE over the reference's mean (NaN when that mean is not positive).
    pub relative_rmse: f64,
    /// Mean relative error (NaN for a black reference).
    pub mean_relative_error: f64,
    /// RMSE with the reference's own noise taken out, when it is known.
    pub noise_corrected_rmse: Option<f64>,
}

impl StudyRow {
    /// The row of `run`, the run at `setting` of `spec`, with `o` its
    /// pooled metrics against the reference.
    pub(super) fn new(spec: &RunSpec, setting: &str, run: &SolveRun, o: &ChannelMetrics) -> Self {
        let times = &run.report.times;
        StudyRow {
            label: spec.label.clone(),
            method: spec.method.clone(),
            setting: setting.to_string(),
            elements: run.report.counts.elements,
            leaves: run.report.counts.leaves,
            links: run.report.counts.links,
            solve_seconds: times.solving(),
            render_seconds: times.render,
            converged: run.report.convergence.converged,
            rmse: o.rmse,
            relative_rmse: o.relative_rmse.unwrap_or(f64::NAN),
            mean_relative_error: o.mean_relative_error.unwrap_or(f64::NAN),
            noise_corrected_rmse: o.noise_corrected_rmse,
        }
    }
}

/// The reference every run of a study is compared with.
pub(super) struct StudyReference {
    /// The reference image.
    pub image: Frame,
    /// Its standard error per pixel, when known.
    pub noise: Option<Frame>,
    /// The file the reference is named by in the metrics.
    pub path: PathBuf,
}

/// Where a study's reference comes from.
pub(super) struct ReferenceSource<'a> {
    pub scene: &'a Scene,
    pub scene_name: &'a str,
    pub config: &'a StudyConfig,
    pub view: &'a View,
    /// The study's folder, which caches the reference.
    pub dir: &'a Path,
    pub progress: &'a Progress,
}

impl StudyReference {
    /// The reference: `given` (image and noise, when known), else the one
    /// cached in the study's folder for this scene, view, spp and seed,
    /// else path traced, its files pushed onto `files` to be written with
    /// the study. Fails when it does not have the view's size.
    pub(super) fn resolve(
        source: &ReferenceSource,
        given: Option<(Frame, Option<Frame>)>,
        files: &mut Vec<(String, Vec<u8>)>,
    ) -> Result<StudyReference> {
        let key = ReferenceKey {
            scene: source.scene_name,
            view: source.view,
            spp: source.config.reference_spp,
            seed: source.config.seed,
        };
        let cache = ReferenceCache {
            dir: source.dir,
            naming: Naming::Sidecars,
        };
        let (image, noise) = match given {
            Some((image, noise)) => (image, noise),
            None => {
                let (image, noise) = match cache.load(&key)? {
                    Some(cached) => cached,
                    None => {
                        let rendered =
                            reference_cache::render(source.scene, &key, source.progress)?;
                        files.extend(cache.files(&key, &rendered)?);
                        (rendered.image, rendered.noise)
                    }
                };
                (image, Some(noise))
            }
        };
        let view = source.view;
        if (image.width, image.height) != (view.width, view.height) {
            return Err(Error::Setting(format!(
                "the reference is {} × {} but the study renders {} × {}",
                image.width, image.height, view.width, view.height
            )));
        }
        Ok(StudyReference {
            image,
            noise,
            path: cache.image_path(&key),
        })
    }

    /// The metrics of `frame` (named `label`) against the reference, with
    /// the reference's noise taken out when it is known.
    pub(super) fn compare(&self, label: &str, frame: &Frame) -> Result<Metrics> {
        compare::compare_frames(
            Named {
                path: Path::new(label),
                frame,
            },
            Named {
                path: &self.path,
                frame: &self.image,
            },
            self.noise.as_ref().map(|n| Named {
                path: &self.path,
                frame: n,
            }),
        )
    }
}
