//! `nusselt study`: sweeps of methods and settings against a path-traced
//! reference, for speed-against-accuracy charts.
//!
//! Owns: the sweep configuration (JSON, every field optional), running each
//! configuration through the pipeline, measuring it against the reference
//! with `compare`, and assembling `results.csv`, the charts and the contact
//! sheet (charts plot the mean relative error: RMSE is dominated by the
//! few pixels on an emitter's edge, which every method gets about equally
//! wrong; pairs of image and relative-error map, 0 to 20 %, magma; the
//! reference pairs with its own relative noise). Invariant: the reference is computed once per (scene, view, spp,
//! seed) and cached beside the results; every run renders the same view so
//! images compare pixel for pixel.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::classic::matrix::{Kernel, MatrixSettings};
use crate::classic::solve::ClassicMethod;
use crate::error::{Error, Result};
use crate::hierarchical::{Accuracy, HierarchicalSettings, Preset};
use crate::lab::chart::{self, Axis, LineChart, Series};
use crate::lab::compare::{self, Named};
use crate::output::{self, OutputSet};
use crate::pipeline::{self, Method, SolveSettings};
use crate::reference::{self, ReferenceSettings, ReferenceStats};
use crate::render::RenderSettings;
use crate::render::frame::Frame;
use crate::render::view::{View, ViewOverrides};
use crate::scene::Scene;
use crate::util::progress::Progress;

/// One line of the sweep: a method, and the settings it is run at.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Series name in charts and the CSV.
    pub label: String,
    /// `hierarchical`, `direct`, `jacobi`, `gauss-seidel` or `shooting`.
    pub method: String,
    /// Classic methods: the form-factor kernel (default point-polygon).
    #[serde(default)]
    pub kernel: Option<Kernel>,
    /// Classic methods: element sizes as fractions of the scene diagonal.
    #[serde(default)]
    pub element_fractions: Vec<f64>,
    /// Hierarchical: accuracy presets (`preview`, `default`, `high`).
    #[serde(default)]
    pub accuracy: Vec<String>,
}

/// The sweep; `nusselt study --config FILE` reads it as JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StudyConfig {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel of the reference.
    pub reference_spp: u32,
    /// Samples per pixel of each run's render.
    pub render_spp: u32,
    pub seed: u64,
    pub runs: Vec<RunSpec>,
}

impl Default for StudyConfig {
    fn default() -> Self {
        let classic = |label: &str, method: &str, kernel: Kernel, fractions: &[f64]| RunSpec {
            label: label.into(),
            method: method.into(),
            kernel: Some(kernel),
            element_fractions: fractions.to_vec(),
            accuracy: Vec::new(),
        };
        StudyConfig {
            width: 128,
            height: 128,
            reference_spp: 1024,
            render_spp: 16,
            seed: 0,
            runs: vec![
                RunSpec {
                    label: "hierarchical".into(),
                    method: "hierarchical".into(),
                    kernel: None,
                    element_fractions: Vec::new(),
                    accuracy: vec!["preview".into(), "default".into(), "high".into()],
                },
                classic(
                    "jacobi, point-polygon",
                    "jacobi",
                    Kernel::PointPolygon,
                    &[0.1, 0.07, 0.05, 0.035],
                ),
                classic(
                    "gauss-seidel, hemicube",
                    "gauss-seidel",
                    Kernel::Hemicube,
                    &[0.1, 0.07, 0.05],
                ),
                classic(
                    "shooting, point-polygon",
                    "shooting",
                    Kernel::PointPolygon,
                    &[0.1, 0.07, 0.05],
                ),
            ],
        }
    }
}

/// One measured run: a row of `results.csv`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StudyRow {
    pub label: String,
    pub method: String,
    pub setting: String,
    pub elements: usize,
    pub leaves: usize,
    pub links: u64,
    /// Seconds to the solution: linking, form factors, refinement, solve
    /// (not output meshing or rendering).
    pub solve_seconds: f64,
    pub render_seconds: f64,
    pub converged: bool,
    pub rmse: f64,
    pub relative_rmse: f64,
    pub mean_relative_error: f64,
    /// RMSE with the reference's own noise taken out, when it is known.
    pub noise_corrected_rmse: Option<f64>,
}

/// Everything a study produces, ready to write.
pub struct StudyResult {
    pub rows: Vec<StudyRow>,
    /// (file name, bytes): results.csv, charts, contact sheet, renders.
    pub files: Vec<(String, Vec<u8>)>,
}

fn parse_method(name: &str) -> Result<Method> {
    Ok(match name {
        "hierarchical" => Method::Hierarchical,
        "direct" => Method::Classic(ClassicMethod::Direct),
        "jacobi" => Method::Classic(ClassicMethod::Jacobi),
        "gauss-seidel" => Method::Classic(ClassicMethod::GaussSeidel),
        "shooting" => Method::Classic(ClassicMethod::Shooting),
        other => return Err(Error::Setting(format!("study: unknown method '{other}'"))),
    })
}

fn preset(name: &str, seed: u64) -> Result<HierarchicalSettings> {
    let p: Preset = serde_json::from_value(serde_json::Value::String(name.into()))
        .map_err(|_| Error::Setting(format!("study: unknown accuracy preset '{name}'")))?;
    Ok(HierarchicalSettings {
        accuracy: Accuracy::preset(p),
        seed,
        ..HierarchicalSettings::default()
    })
}

/// The reference image for `view`: read from `dir/reference.exr` when its
/// sidecar says it was made for this scene, view, spp and seed, otherwise
/// path traced and cached there (staged into `set`).
fn reference_image(
    scene: &Scene,
    scene_name: &str,
    view: &View,
    config: &StudyConfig,
    dir: &Path,
    progress: &Progress,
    files: &mut Vec<(String, Vec<u8>)>,
) -> Result<(Frame, Frame)> {
    let image_path = dir.join("reference.exr");
    let stats_path = reference::stats_path(&image_path);
    if let Ok(bytes) = std::fs::read(&stats_path) {
        if let Ok(stats) = serde_json::from_slice::<ReferenceStats>(&bytes) {
            let cached_view = std::fs::read(dir.join("reference-view.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<View>(&b).ok());
            if stats.scene == scene_name
                && stats.spp == config.reference_spp
                && stats.seed == config.seed
                && cached_view.as_ref() == Some(view)
            {
                let image = output::exr::read_image(&image_path)?;
                let noise = output::exr::read_image(&reference::noise_path(&image_path))?;
                return Ok((image, noise));
            }
        }
    }
    let settings = ReferenceSettings {
        samples_per_pixel: config.reference_spp.max(2),
        seed: config.seed,
        max_bounces: None,
    };
    let mut result = reference::render_reference(scene, view, &settings, progress)?;
    result.stats.scene = scene_name.to_string();
    files.push((
        "reference.exr".into(),
        output::exr::encode_image(&result.image)?,
    ));
    files.push((
        "reference.noise.exr".into(),
        output::exr::encode_image(&result.noise)?,
    ));
    files.push(("reference.json".into(), output::write_json(&result.stats)?));
    files.push(("reference-view.json".into(), output::write_json(view)?));
    Ok((result.image, result.noise))
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
    let overrides = ViewOverrides {
        width: Some(config.width),
        height: Some(config.height),
        ..ViewOverrides::default()
    };
    let view = View::resolve(scene.cameras.first(), scene.bounds, &overrides)?;
    let mut files = Vec::new();
    let (reference, noise) = match given_reference {
        Some((image, noise)) => (image, noise),
        None => {
            let (image, noise) =
                reference_image(scene, scene_name, &view, config, dir, progress, &mut files)?;
            (image, Some(noise))
        }
    };
    if (reference.width, reference.height) != (view.width, view.height) {
        return Err(Error::Setting(format!(
            "the reference is {} × {} but the study renders {} × {}",
            reference.width, reference.height, view.width, view.height
        )));
    }
    let exposure = pipeline::frame_exposure(&reference);
    let reference_path = dir.join("reference.exr");
    let mut rows = Vec::new();
    // Tiles go in pairs (image, its error): the reference pairs with its own
    // relative noise.
    let mut tiles = vec![("reference".to_string(), display(&reference, exposure))];
    tiles.push(match &noise {
        Some(n) => {
            let noisy = Frame {
                pixels: reference
                    .pixels
                    .iter()
                    .zip(&n.pixels)
                    .map(|(r, e)| [r[0] + e[0], r[1] + e[1], r[2] + e[2]])
                    .collect(),
                ..reference.clone()
            };
            (
                "reference noise".to_string(),
                false_colour(&compare::relative_luminance_error(&noisy, &reference)),
            )
        }
        None => (
            "(noise unknown)".to_string(),
            vec![chart::BACKGROUND; reference.pixels.len()],
        ),
    });
    for spec in &config.runs {
        let method = parse_method(&spec.method)?;
        let settings: Vec<(String, SolveSettings)> = match method {
            Method::Hierarchical => spec
                .accuracy
                .iter()
                .map(|a| {
                    Ok((
                        a.clone(),
                        SolveSettings {
                            method,
                            hierarchical: preset(a, config.seed)?,
                            ..base_settings(config, &overrides)
                        },
                    ))
                })
                .collect::<Result<_>>()?,
            Method::Classic(_) => spec
                .element_fractions
                .iter()
                .map(|&f| {
                    let mut s = SolveSettings {
                        method,
                        element_size: Some(f * scene.diagonal()),
                        ..base_settings(config, &overrides)
                    };
                    s.matrix.kernel = spec.kernel.unwrap_or(Kernel::PointPolygon);
                    (format!("{f}"), s)
                })
                .collect(),
        };
        for (setting, s) in settings {
            let run = pipeline::solve(scene, &s, &Progress::hidden())?;
            let metrics = compare::compare_frames(
                Named {
                    path: Path::new(&spec.label),
                    frame: &run.frame,
                },
                Named {
                    path: &reference_path,
                    frame: &reference,
                },
                noise.as_ref().map(|n| Named {
                    path: &reference_path,
                    frame: n,
                }),
            )?;
            let o = &metrics.overall;
            let times = &run.report.times;
            rows.push(StudyRow {
                label: spec.label.clone(),
                method: spec.method.clone(),
                setting: setting.clone(),
                elements: run.report.counts.elements,
                leaves: run.report.counts.leaves,
                links: run.report.counts.links,
                solve_seconds: times.bvh
                    + times.mesh
                    + times.form_factors
                    + times.linking
                    + times.refinement
                    + times.solve,
                render_seconds: times.render,
                converged: run.report.convergence.converged,
                rmse: o.rmse,
                relative_rmse: o.relative_rmse.unwrap_or(f64::NAN),
                mean_relative_error: o.mean_relative_error.unwrap_or(f64::NAN),
                noise_corrected_rmse: o.noise_corrected_rmse,
            });
            let name = format!("{}-{}", slug(&spec.label), slug(&setting));
            files.push((
                format!("runs/{name}.png"),
                output::png::encode_png(&run.frame, exposure)?,
            ));
            let errors = compare::relative_luminance_error(&run.frame, &reference);
            let short = match method {
                Method::Hierarchical => setting.clone(),
                Method::Classic(_) => format!("h={setting}"),
            };
            tiles.push((
                format!("{short} {}", spec.method),
                display(&run.frame, exposure),
            ));
            tiles.push((
                format!(
                    "mean rel. err. {:.1} %",
                    100.0 * o.mean_relative_error.unwrap_or(f64::NAN)
                ),
                false_colour(&errors),
            ));
        }
    }
    files.push(("results.csv".into(), csv(&rows).into_bytes()));
    for (stem, title, x, y, pick) in [
        (
            "error-time",
            "Mean relative error against solve time",
            Axis::log("solve time (s)"),
            Axis::log("mean relative error"),
            (|r: &StudyRow| (r.solve_seconds, r.mean_relative_error))
                as fn(&StudyRow) -> (f64, f64),
        ),
        (
            "error-elements",
            "Mean relative error against elements",
            Axis::log("elements"),
            Axis::log("mean relative error"),
            |r: &StudyRow| (r.elements as f64, r.mean_relative_error),
        ),
        (
            "links-elements",
            "Links against elements",
            Axis::log("elements"),
            Axis::log("links"),
            |r: &StudyRow| (r.elements as f64, r.links as f64),
        ),
    ] {
        let chart = LineChart {
            title: title.into(),
            x,
            y,
            series: series(&rows, pick),
        };
        let images = chart::draw_line_chart(&chart, chart::CHART_SIZE)?;
        files.push((format!("{stem}.svg"), images.svg.into_bytes()));
        files.push((format!("{stem}.png"), images.png));
    }
    files.push((
        "contact-sheet.png".into(),
        chart::contact_sheet(&tiles, view.width, view.height, 6)?,
    ));
    Ok(StudyResult { rows, files })
}

fn base_settings(config: &StudyConfig, overrides: &ViewOverrides) -> SolveSettings {
    SolveSettings {
        matrix: MatrixSettings {
            seed: config.seed,
            ..MatrixSettings::default()
        },
        render: RenderSettings {
            samples_per_pixel: config.render_spp,
            seed: config.seed,
        },
        view: overrides.clone(),
        ..SolveSettings::default()
    }
}

/// One chart series per label, points in run order.
fn series(rows: &[StudyRow], pick: fn(&StudyRow) -> (f64, f64)) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    for r in rows {
        let p = pick(r);
        match out.iter_mut().find(|s| s.label == r.label) {
            Some(s) => s.points.push(p),
            None => out.push(Series {
                label: r.label.clone(),
                points: vec![p],
            }),
        }
    }
    out
}

/// Relative errors on the colour map, 0 to [`compare::DEFAULT_MAX_ERROR`].
fn false_colour(errors: &[f64]) -> Vec<[u8; 3]> {
    errors
        .iter()
        .map(|&e| chart::colour_map(e / compare::DEFAULT_MAX_ERROR))
        .collect()
}

/// 8-bit sRGB pixels of `frame` at `exposure`.
fn display(frame: &Frame, exposure: f32) -> Vec<[u8; 3]> {
    frame
        .pixels
        .iter()
        .map(|p| p.map(|c| output::png::display_byte(c, exposure)))
        .collect()
}

fn slug(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' {
                c
            } else {
                '-'
            }
        })
        .collect()
}

fn csv(rows: &[StudyRow]) -> String {
    let mut out = String::from(
        "label,method,setting,elements,leaves,links,solve_seconds,render_seconds,converged,rmse,relative_rmse,mean_relative_error,noise_corrected_rmse\n",
    );
    for r in rows {
        out.push_str(&format!(
            "\"{}\",{},{},{},{},{},{:.6},{:.6},{},{:.6e},{:.6e},{:.6e},{}\n",
            r.label.replace('"', "\"\""),
            r.method,
            r.setting,
            r.elements,
            r.leaves,
            r.links,
            r.solve_seconds,
            r.render_seconds,
            r.converged,
            r.rmse,
            r.relative_rmse,
            r.mean_relative_error,
            r.noise_corrected_rmse
                .map(|v| format!("{v:.6e}"))
                .unwrap_or_default()
        ));
    }
    out
}

/// Writes a study's files into `dir` (staged, renamed together).
pub fn write_study(dir: &Path, result: &StudyResult) -> Result<Vec<PathBuf>> {
    let mut set = OutputSet::create(dir)?;
    let runs = dir.join("runs");
    let mut run_set = OutputSet::create(&runs)?;
    for (name, bytes) in &result.files {
        match name.strip_prefix("runs/") {
            Some(file) => run_set.stage(file, bytes)?,
            None => set.stage(name, bytes)?,
        }
    }
    let mut written = run_set.commit()?;
    written.extend(set.commit()?);
    Ok(written)
}
