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

use serde::Serialize;

use crate::error::Result;
use crate::lab::chart::{self, Axis, LineChart, Series};
use crate::lab::study::{StudyResult, StudyRow};
use crate::output::{OutputSet, csv};

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

/// A row of `results.csv`: counts as integers, times to the microsecond,
/// errors to 7 significant digits (the noise-corrected RMSE empty when
/// the reference's noise is not known).
#[derive(Serialize)]
struct ResultsRow<'a> {
    label: &'a str,
    method: &'a str,
    setting: &'a str,
    elements: usize,
    leaves: usize,
    links: u64,
    #[serde(serialize_with = "csv::fixed::<6, _>")]
    solve_seconds: f64,
    #[serde(serialize_with = "csv::fixed::<6, _>")]
    render_seconds: f64,
    converged: bool,
    #[serde(serialize_with = "csv::sci::<6, _>")]
    rmse: f64,
    #[serde(serialize_with = "csv::sci::<6, _>")]
    relative_rmse: f64,
    #[serde(serialize_with = "csv::sci::<6, _>")]
    mean_relative_error: f64,
    #[serde(serialize_with = "csv::sci_or_empty::<6, _>")]
    noise_corrected_rmse: Option<f64>,
}

/// `results.csv`: a header and one line per row.
pub(super) fn encode_results(rows: &[StudyRow]) -> Result<Vec<u8>> {
    csv::encode(
        &[
            "label",
            "method",
            "setting",
            "elements",
            "leaves",
            "links",
            "solve_seconds",
            "render_seconds",
            "converged",
            "rmse",
            "relative_rmse",
            "mean_relative_error",
            "noise_corrected_rmse",
        ],
        rows.iter().map(|r| ResultsRow {
            label: &r.label,
            method: &r.method,
            setting: &r.setting,
            elements: r.elements,
            leaves: r.leaves,
            links: r.links,
            solve_seconds: r.solve_seconds,
            render_seconds: r.render_seconds,
            converged: r.converged,
            rmse: r.rmse,
            relative_rmse: r.relative_rmse,
            mean_relative_error: r.mean_relative_error,
            noise_corrected_rmse: r.noise_corrected_rmse,
        }),
    )
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

#[cfg(test)]
mod tests {
    use super::*;

    fn row(label: &str, noise: Option<f64>) -> StudyRow {
        StudyRow {
            label: label.into(),
            method: "jacobi".into(),
            setting: "0.4".into(),
            elements: 96,
            leaves: 96,
            links: 9216,
            solve_seconds: 0.0123456789,
            render_seconds: 1.5,
            converged: true,
            rmse: 0.012345678,
            relative_rmse: f64::NAN,
            mean_relative_error: 1234.5,
            noise_corrected_rmse: noise,
        }
    }

    #[test]
    fn rows_keep_their_number_formats() {
        let text =
            String::from_utf8(encode_results(&[row("j", None), row("k", Some(0.5))]).unwrap())
                .unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "label,method,setting,elements,leaves,links,solve_seconds,render_seconds,converged,\
             rmse,relative_rmse,mean_relative_error,noise_corrected_rmse"
        );
        assert_eq!(
            lines[1],
            "j,jacobi,0.4,96,96,9216,0.012346,1.500000,true,1.234568e-2,NaN,1.234500e3,"
        );
        assert!(lines[2].ends_with(",5.000000e-1"), "{}", lines[2]);
    }

    /// A label with a comma, quotes and a line break comes back whole from
    /// a standard CSV reader (it used to be quoted by hand).
    #[test]
    fn a_label_with_commas_quotes_and_line_breaks_round_trips() {
        let label = "gs, \"hemicube\"\nfine";
        let bytes = encode_results(&[row(label, None), row("plain", None)]).unwrap();
        let mut reader = ::csv::Reader::from_reader(bytes.as_slice());
        let records: Vec<::csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
        assert_eq!(records.len(), 2);
        assert_eq!(&records[0][0], label);
        assert_eq!(&records[0][1], "jacobi");
        assert_eq!(&records[1][0], "plain");
        assert_eq!(records[0].len(), 13);
    }
}
