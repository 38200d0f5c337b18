//! Convergence charts of `nusselt chart`: the residual histories of one
//! or more solves, read from their `report.json`, against iteration and
//! against time.
//!
//! Owns: reading the history from a report (tolerant of other fields and
//! versions), the legend labels, and the two charts.
//!
//! Invariant: a report is only read, never trusted: a file that is not a
//! report, or has an empty history, is an error naming the file.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::error::{Error, Result};
use crate::lab::chart::{Axis, CHART_SIZE, ChartImages, LineChart, Series, draw_line_chart};
use crate::report::HistoryEntry;

/// The convergence history of one solve, as read from its `report.json`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvergenceRun {
    /// The report it came from.
    pub path: PathBuf,
    /// The solver, as the report names it (`method`).
    pub method: String,
    /// The residual after each iteration, with the time it was reached.
    pub history: Vec<HistoryEntry>,
}

/// The parts of `report.json` a convergence chart needs; other fields are
/// ignored so that reports of other versions still chart.
#[derive(Deserialize)]
struct ReportHistory {
    method: String,
    convergence: HistoryOnly,
}

#[derive(Deserialize)]
struct HistoryOnly {
    history: Vec<HistoryEntry>,
}

/// Reads the method and convergence history of a `report.json` written by
/// `nusselt solve`. Fails, naming the file, when it cannot be read, is not
/// a report, or has an empty history.
pub fn read_convergence(path: &Path) -> Result<ConvergenceRun> {
    let bytes = std::fs::read(path).map_err(|e| Error::input(path, e))?;
    let report: ReportHistory = serde_json::from_slice(&bytes)
        .map_err(|e| Error::input(path, format!("not a nusselt report.json: {e}")))?;
    if report.convergence.history.is_empty() {
        return Err(Error::input(
            path,
            "the convergence history is empty (nothing to chart)",
        ));
    }
    Ok(ConvergenceRun {
        path: path.to_path_buf(),
        method: report.method,
        history: report.convergence.history,
    })
}

/// The legend label of each run: its method, followed by its file (the
/// file name when that tells the runs apart, else the whole path) when
/// another run has the same method.
pub fn run_labels(runs: &[ConvergenceRun]) -> Vec<String> {
    let file_names_unique = {
        let names: Vec<_> = runs.iter().map(|r| r.path.file_name()).collect();
        names
            .iter()
            .enumerate()
            .all(|(i, n)| names[..i].iter().all(|m| m != n))
    };
    runs.iter()
        .map(|run| {
            let shared = runs
                .iter()
                .filter(|other| other.method == run.method)
                .count()
                > 1;
            if !shared {
                return run.method.clone();
            }
            let file = match run.path.file_name() {
                Some(name) if file_names_unique => name.to_string_lossy().into_owned(),
                _ => run.path.display().to_string(),
            };
            format!("{} ({file})", run.method)
        })
        .collect()
}

/// A chart to be written as `<stem>.svg` and `<stem>.png`.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedChart {
    /// The file stem, without extension.
    pub stem: &'static str,
    /// The chart drawn.
    pub images: ChartImages,
}

/// The two convergence charts of `runs`: `residual-iterations` (residual
/// against iteration, log y) and `residual-time` (residual against seconds,
/// log-log). Zero residuals and zero times cannot sit on a log axis and are
/// skipped (counted in [`ChartImages::skipped_points`]).
pub fn convergence_charts(runs: &[ConvergenceRun]) -> Result<Vec<NamedChart>> {
    if runs.is_empty() {
        return Err(Error::Setting("no reports to chart".into()));
    }
    let labels = run_labels(runs);
    let series = |f: fn(&HistoryEntry) -> (f64, f64)| -> Vec<Series> {
        runs.iter()
            .zip(&labels)
            .map(|(run, label)| Series {
                label: label.clone(),
                points: run.history.iter().map(f).collect(),
            })
            .collect()
    };
    let by_iteration = LineChart {
        title: "Convergence: residual against iteration".into(),
        x: Axis::linear("iteration"),
        y: Axis::log("residual (relative)"),
        series: series(|h| (h.iteration as f64, h.residual)),
    };
    let by_time = LineChart {
        title: "Convergence: residual against time".into(),
        x: Axis::log("solve time (s)"),
        y: Axis::log("residual (relative)"),
        series: series(|h| (h.seconds, h.residual)),
    };
    Ok(vec![
        NamedChart {
            stem: "residual-iterations",
            images: draw_line_chart(&by_iteration, CHART_SIZE)?,
        },
        NamedChart {
            stem: "residual-time",
            images: draw_line_chart(&by_time, CHART_SIZE)?,
        },
    ])
}
