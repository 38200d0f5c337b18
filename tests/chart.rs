//! Charts (`nusselt::lab::chart`, `nusselt chart`): convergence charts from
//! synthetic reports, the reusable line chart, log axes, and errors.

use std::fs;
use std::path::{Path, PathBuf};

use nusselt::lab::chart::{Axis, CHART_SIZE, LineChart, Series, draw_line_chart};
use nusselt::lab::convergence::{convergence_charts, read_convergence, run_labels};
use nusselt::report::{HistoryEntry, Report};

use crate::util::{assert_user_error, nusselt};

/// A report as `nusselt solve` writes it, with a geometric residual decay.
fn report(method: &str, iterations: usize, rate: f64, seconds_per_iteration: f64) -> Report {
    let mut r = Report {
        method: method.into(),
        ..Report::default()
    };
    r.convergence.history = (1..=iterations)
        .map(|k| HistoryEntry {
            iteration: k,
            residual: 0.1 * rate.powi(k as i32),
            seconds: seconds_per_iteration * k as f64,
        })
        .collect();
    r.convergence.iterations = iterations;
    r
}

fn write_report(dir: &Path, name: &str, r: &Report) -> PathBuf {
    let p = dir.join(name);
    fs::create_dir_all(p.parent().unwrap()).unwrap();
    fs::write(&p, serde_json::to_vec_pretty(r).unwrap()).unwrap();
    p
}

/// Parses `svg` as XML and returns all its text content.
fn svg_text(svg: &str) -> String {
    let doc = roxmltree::Document::parse(svg).expect("the SVG is well-formed XML");
    assert_eq!(doc.root_element().tag_name().name(), "svg");
    doc.descendants()
        .filter_map(|n| n.text())
        .collect::<Vec<_>>()
        .join("\n")
}

fn png_size(bytes: &[u8]) -> (u32, u32) {
    let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).unwrap();
    (img.width(), img.height())
}

#[test]
fn convergence_charts_of_two_reports() {
    let dir = tempfile::tempdir().unwrap();
    let runs = [
        read_convergence(&write_report(
            dir.path(),
            "a/report.json",
            &report("jacobi", 30, 0.6, 0.01),
        ))
        .unwrap(),
        read_convergence(&write_report(
            dir.path(),
            "b/report.json",
            &report("gauss-seidel", 15, 0.3, 0.012),
        ))
        .unwrap(),
    ];
    assert_eq!(runs[0].method, "jacobi");
    assert_eq!(runs[1].history.len(), 15);
    let charts = convergence_charts(&runs).unwrap();
    let stems: Vec<_> = charts.iter().map(|c| c.stem).collect();
    assert_eq!(stems, ["residual-iterations", "residual-time"]);
    for chart in &charts {
        assert!(chart.images.svg.starts_with("<svg"));
        let text = svg_text(&chart.images.svg);
        for label in ["jacobi", "gauss-seidel", "residual (relative)"] {
            assert!(text.contains(label), "{label} missing from {}", chart.stem);
        }
        assert_eq!(png_size(&chart.images.png), CHART_SIZE);
        assert_eq!(chart.images.skipped_points, 0);
    }
    assert!(svg_text(&charts[0].images.svg).contains("iteration"));
    assert!(svg_text(&charts[1].images.svg).contains("solve time (s)"));
    // Deterministic.
    assert_eq!(convergence_charts(&runs).unwrap(), charts);
}

#[test]
fn runs_sharing_a_method_are_told_apart_by_file() {
    let dir = tempfile::tempdir().unwrap();
    let r = report("jacobi", 5, 0.5, 0.1);
    let named = |p: PathBuf| read_convergence(&p).unwrap();
    let a = named(write_report(dir.path(), "coarse.json", &r));
    let b = named(write_report(dir.path(), "fine.json", &r));
    let c = named(write_report(
        dir.path(),
        "x.json",
        &report("shooting", 5, 0.5, 0.1),
    ));
    assert_eq!(
        run_labels(&[a.clone(), b.clone(), c.clone()]),
        ["jacobi (coarse.json)", "jacobi (fine.json)", "shooting"]
    );
    // Same file names in different folders: the whole path.
    let d = named(write_report(dir.path(), "one/report.json", &r));
    let e = named(write_report(dir.path(), "two/report.json", &r));
    let labels = run_labels(&[d, e, c]);
    assert!(labels[0].starts_with("jacobi (") && labels[0].contains("one"));
    assert!(labels[1].contains("two"));
    assert_eq!(labels[2], "shooting");
    let svg = &convergence_charts(&[a, b]).unwrap()[0].images.svg;
    let text = svg_text(svg);
    assert!(text.contains("jacobi (coarse.json)") && text.contains("jacobi (fine.json)"));
}

#[test]
fn log_axes_skip_non_positive_points() {
    let chart = LineChart {
        title: "skips".into(),
        x: Axis::linear("x"),
        y: Axis::log("y"),
        series: vec![Series {
            label: "s".into(),
            points: vec![
                (0.0, 1e-3),
                (1.0, 0.0),
                (2.0, -1.0),
                (3.0, 1e-4),
                (4.0, f64::NAN),
            ],
        }],
    };
    let images = draw_line_chart(&chart, (400, 300)).unwrap();
    assert_eq!(images.skipped_points, 3);
    assert_eq!(png_size(&images.png), (400, 300));
    let log_log = LineChart {
        x: Axis::log("x"),
        ..chart.clone()
    };
    assert_eq!(
        draw_line_chart(&log_log, (400, 300))
            .unwrap()
            .skipped_points,
        4
    );
    // Linear axes take zero and negative values.
    let linear = LineChart {
        y: Axis::linear("y"),
        ..chart
    };
    let images = draw_line_chart(&linear, (400, 300)).unwrap();
    assert_eq!(images.skipped_points, 1);
    assert!(svg_text(&images.svg).contains("skips"));
}

#[test]
fn one_point_and_constant_series_draw() {
    let chart = LineChart {
        title: "flat".into(),
        x: Axis::log("elements"),
        y: Axis::log("error"),
        series: vec![
            Series {
                label: "one".into(),
                points: vec![(100.0, 0.05)],
            },
            Series {
                label: "empty".into(),
                points: vec![],
            },
        ],
    };
    let images = draw_line_chart(&chart, CHART_SIZE).unwrap();
    let text = svg_text(&images.svg);
    assert!(text.contains("one") && text.contains("empty"));
}

#[test]
fn nothing_to_draw_is_an_error() {
    let empty = LineChart {
        title: "t".into(),
        x: Axis::linear("x"),
        y: Axis::log("y"),
        series: vec![],
    };
    assert!(draw_line_chart(&empty, CHART_SIZE).is_err());
    let zeros = LineChart {
        series: vec![Series {
            label: "zeros".into(),
            points: vec![(1.0, 0.0), (2.0, 0.0)],
        }],
        ..empty
    };
    let err = draw_line_chart(&zeros, CHART_SIZE).unwrap_err().to_string();
    assert!(err.contains("log axis"), "{err}");
    assert!(convergence_charts(&[]).is_err());
}

#[test]
fn unusable_reports_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let empty = write_report(dir.path(), "empty.json", &report("jacobi", 0, 0.5, 0.1));
    let err = read_convergence(&empty).unwrap_err().to_string();
    assert!(err.contains("empty.json") && err.contains("empty"), "{err}");
    let junk = dir.path().join("junk.json");
    fs::write(&junk, "{\"method\": 3}").unwrap();
    let err = read_convergence(&junk).unwrap_err().to_string();
    assert!(err.contains("junk.json"), "{err}");
    let err = read_convergence(&dir.path().join("absent.json"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("absent.json"), "{err}");
}

#[test]
fn cli_writes_both_charts_in_both_formats() {
    let dir = tempfile::tempdir().unwrap();
    write_report(
        dir.path(),
        "j/report.json",
        &report("jacobi", 20, 0.5, 0.01),
    );
    let mut direct = report("direct", 1, 0.5, 0.2);
    direct.convergence.history[0].residual = 0.0; // exact: not on a log axis
    write_report(dir.path(), "d/report.json", &direct);
    let out = nusselt(
        &["chart", "j/report.json", "d/report.json", "-o", "charts"],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("warning:") && stderr.contains("left off"),
        "{stderr}"
    );
    for stem in ["residual-iterations", "residual-time"] {
        let svg = fs::read_to_string(dir.path().join(format!("charts/{stem}.svg"))).unwrap();
        let text = svg_text(&svg);
        assert!(text.contains("jacobi") && text.contains("direct"), "{stem}");
        let png = fs::read(dir.path().join(format!("charts/{stem}.png"))).unwrap();
        assert_eq!(png_size(&png), CHART_SIZE);
    }

    assert_user_error(
        &nusselt(
            &["chart", "j/report.json", "nope.json", "-o", "c2"],
            dir.path(),
        ),
        "nope.json",
    );
    assert!(!dir.path().join("c2/residual-time.svg").exists());
    assert_eq!(
        nusselt(&["chart", "-o", "c3"], dir.path()).status.code(),
        Some(2)
    );
}
