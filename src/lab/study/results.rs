//! The files of a study: `results.csv`, the three charts, the renders, and
//! writing them all.
//!
//! Owns the CSV's columns and number formats, which charts there are
//! (each plots the mean relative error, not the RMSE: the RMSE is
//! dominated by the few pixels on an emitter's edge, which every method
//! gets about equally wrong), the file names of the renders, and
//! [`write_study`]. Invariant: files are staged and renamed together, so a
//! study folder is never half old and half new.

use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::lab::chart::{self, Axis, LineChart, Series};
use crate::lab::study::{StudyResult, StudyRow};
use crate::output::OutputSet;

/// The file name of the render of the run at `setting` of the line
/// labelled `label`, under `runs/`.
pub(super) fn run_png_name(label: &str, setting: &str) -> String {
    format!("runs/{}-{}.png", slug(label), slug(setting))
}

/// `s` with every character but ASCII letters, digits and `.` made `-`.
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

/// `results.csv`: a header and one line per row, the label quoted.
pub(super) fn csv(rows: &[StudyRow]) -> String {
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

/// The charts of `rows`, each as (`<stem>.svg`, SVG bytes) and
/// (`<stem>.png`, PNG bytes): error against time, error against elements,
/// links against elements, one series per label.
pub(super) fn charts(rows: &[StudyRow]) -> Result<Vec<(String, Vec<u8>)>> {
    let mut files = Vec::new();
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
            series: series(rows, pick),
        };
        let images = chart::draw_line_chart(&chart, chart::CHART_SIZE)?;
        files.push((format!("{stem}.svg"), images.svg.into_bytes()));
        files.push((format!("{stem}.png"), images.png));
    }
    Ok(files)
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
