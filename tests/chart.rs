//! Charts (`nusselt::lab::chart`, `nusselt chart`): convergence charts from
//! synthetic reports, the reusable line chart, log axes, errors, and text
//! drawn with the bundled font (no font library linked).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use nusselt::lab::chart::{
    Axis, CHART_SIZE, LineChart, Series, contact_sheet, draw_line_chart, false_colour_png,
};
use nusselt::lab::convergence::{convergence_charts, read_convergence, run_labels};
use nusselt::report::{HistoryEntry, Report};

use crate::fixtures::{assert_user_error, nusselt};

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
    assert_eq!(images.skipped_points, 0);
    assert_eq!(png_size(&images.png), CHART_SIZE);

    // Axis ranges: one point on log axes spans exactly its enclosing
    // decades, 1e2 to 1e3 (x) and 1e-2 to 1e-1 (y), no more.
    let labels = svg_labels(&images.svg);
    for decade in ["1e2", "1e3", "1e-2", "1e-1"] {
        assert!(labels.contains(decade), "tick {decade} missing: {labels:?}");
    }
    for beyond in ["1e1", "1e4", "1e-3", "1e0"] {
        assert!(!labels.contains(beyond), "tick {beyond} drawn: {labels:?}");
    }

    // SVG elements: one marker (the one point; the empty series draws
    // none) of radius 3, on the x tick of 1e2 and the y grid line of 5e-2.
    let circles = svg_elements(&images.svg, "circle");
    assert_eq!(circles.len(), 1, "{circles:?}");
    let marker = &circles[0];
    assert_eq!(marker["r"], "3");
    let (cx, cy): (i32, i32) = (marker["cx"].parse().unwrap(), marker["cy"].parse().unwrap());
    let x_ticks: Vec<i32> = svg_elements(&images.svg, "polyline")
        .iter()
        .filter_map(|p| {
            let [(x0, y0), (x1, y1)] = points(&p["points"])[..] else {
                return None;
            };
            (x0 == x1 && y1 - y0 == 5).then_some(x0)
        })
        .collect();
    assert_eq!(x_ticks.iter().min(), Some(&cx), "x ticks {x_ticks:?}");
    let grid_rows: Vec<i32> = svg_elements(&images.svg, "line")
        .iter()
        .filter(|l| l["y1"] == l["y2"])
        .map(|l| l["y1"].parse().unwrap())
        .collect();
    assert!(grid_rows.contains(&cy), "y {cy} not on a grid line");
    // Series lines, 2 px wide: the one-point series and its legend entry
    // in the marker's colour, the empty series in the legend only.
    let wide: Vec<String> = svg_elements(&images.svg, "polyline")
        .into_iter()
        .filter(|p| p["stroke-width"] == "2")
        .map(|p| p["stroke"].clone())
        .collect();
    assert_eq!(wide.len(), 3, "{wide:?}");
    assert_eq!(wide.iter().filter(|c| **c == marker["fill"]).count(), 2);
    let other = wide.iter().find(|c| **c != marker["fill"]).unwrap().clone();

    // Drawn pixels of the PNG: both legend lines alike; the marker's colour
    // also fills a disc of radius 3 centred where the SVG puts it.
    // The legend's box is the last rectangle drawn (its border).
    let rects = svg_elements(&images.svg, "rect");
    let legend = rects.last().unwrap();
    let [lx, ly, lw, lh] = ["x", "y", "width", "height"].map(|k| legend[k].parse::<u32>().unwrap());
    let in_legend = |&(x, y): &(u32, u32)| x >= lx && x < lx + lw && y >= ly && y < ly + lh;
    let first = pixels_of(&images.png, &marker["fill"]);
    let second = pixels_of(&images.png, &other);
    assert!(
        !second.is_empty() && second.iter().all(in_legend),
        "{second:?}"
    );
    let (legend_first, disc): (Vec<_>, Vec<_>) = first.into_iter().partition(in_legend);
    assert_eq!(legend_first.len(), second.len());
    assert!(
        (25..=45).contains(&disc.len()),
        "marker of {} pixels",
        disc.len()
    );
    let n = disc.len() as f64;
    let mean_x = disc.iter().map(|p| p.0 as f64).sum::<f64>() / n;
    let mean_y = disc.iter().map(|p| p.1 as f64).sum::<f64>() / n;
    assert!(
        (mean_x - cx as f64).abs() <= 1.0 && (mean_y - cy as f64).abs() <= 1.0,
        "marker at ({mean_x}, {mean_y}), SVG ({cx}, {cy})"
    );
}

/// The attributes of every `name` element of `svg`.
fn svg_elements(svg: &str, name: &str) -> Vec<std::collections::HashMap<String, String>> {
    let doc = roxmltree::Document::parse(svg).unwrap();
    doc.descendants()
        .filter(|n| n.is_element() && n.tag_name().name() == name)
        .map(|n| {
            n.attributes()
                .map(|a| (a.name().to_string(), a.value().to_string()))
                .collect()
        })
        .collect()
}

/// The trimmed text of every `text` element of `svg`.
fn svg_labels(svg: &str) -> std::collections::HashSet<String> {
    let doc = roxmltree::Document::parse(svg).unwrap();
    doc.descendants()
        .filter(|n| n.is_element() && n.tag_name().name() == "text")
        .filter_map(|n| n.text())
        .map(|t| t.trim().to_string())
        .collect()
}

/// The points of an SVG `points` attribute, `x,y x,y …`.
fn points(attribute: &str) -> Vec<(i32, i32)> {
    attribute
        .split_whitespace()
        .map(|p| {
            let (x, y) = p.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

/// The PNG pixels within 40 per channel of the SVG colour `#RRGGBB`.
fn pixels_of(png: &[u8], colour: &str) -> Vec<(u32, u32)> {
    let channel = |k: usize| i32::from_str_radix(&colour[1 + 2 * k..3 + 2 * k], 16).unwrap();
    let want = [channel(0), channel(1), channel(2)];
    let img = image::load_from_memory_with_format(png, image::ImageFormat::Png)
        .unwrap()
        .to_rgb8();
    img.enumerate_pixels()
        .filter(|(_, _, p)| (0..3).all(|k| (p.0[k] as i32 - want[k]).abs() <= 40))
        .map(|(x, y, _)| (x, y))
        .collect()
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

/// The pixels at which two PNGs of the same size differ.
fn changed_pixels(a: &[u8], b: &[u8]) -> Vec<(u32, u32)> {
    let read = |png| {
        image::load_from_memory_with_format(png, image::ImageFormat::Png)
            .unwrap()
            .to_rgb8()
    };
    let (a, b) = (read(a), read(b));
    assert_eq!(a.dimensions(), b.dimensions());
    a.enumerate_pixels()
        .filter(|&(x, y, p)| p != b.get_pixel(x, y))
        .map(|(x, y, _)| (x, y))
        .collect()
}

/// Pixels that are neither white nor black: the anti-aliased edges that
/// rasterised glyphs have.
fn grey_pixels(png: &[u8], rows: std::ops::Range<u32>) -> usize {
    let img = image::load_from_memory_with_format(png, image::ImageFormat::Png)
        .unwrap()
        .to_rgb8();
    img.enumerate_pixels()
        .filter(|&(_, y, p)| rows.contains(&y) && p.0.iter().any(|&c| c > 0 && c < 255))
        .count()
}

#[test]
fn text_is_drawn_with_the_bundled_font_and_repeats_byte_for_byte() {
    // The line chart: the same input twice gives the same bytes; another
    // title changes the caption's pixels (text is really drawn, and
    // anti-aliased: a font was rasterised) and nothing below it.
    let chart = LineChart {
        title: "residual against iteration".into(),
        x: Axis::linear("iteration"),
        y: Axis::log("residual (relative)"),
        series: vec![Series {
            label: "jacobi".into(),
            points: (1..=20).map(|k| (k as f64, 0.5f64.powi(k))).collect(),
        }],
    };
    let first = draw_line_chart(&chart, CHART_SIZE).unwrap();
    let again = draw_line_chart(&chart, CHART_SIZE).unwrap();
    assert!(first.png == again.png, "two renders of one chart differ");
    assert_eq!(first.svg, again.svg);
    let retitled = LineChart {
        title: "Gauss-Seidel, 1e-6".into(),
        ..chart.clone()
    };
    let other = draw_line_chart(&retitled, CHART_SIZE).unwrap();
    let changed = changed_pixels(&first.png, &other.png);
    assert!(changed.len() > 100, "{} pixels changed", changed.len());
    // The caption: 16 px of margin and a line of 22 px text.
    let caption = 0..16 + 30;
    assert!(
        changed.iter().all(|(_, y)| caption.contains(y)),
        "changes outside the caption: {:?}",
        changed
            .iter()
            .filter(|(_, y)| !caption.contains(y))
            .take(5)
            .collect::<Vec<_>>()
    );
    assert!(grey_pixels(&first.png, caption) > 50);

    // The false-colour map: another scale-bar title changes the strip
    // below the image only.
    let (w, h) = (64, 48);
    let values: Vec<f64> = (0..w * h).map(|k| (k % w) as f64 / w as f64).collect();
    let percent = |v: &f64| format!("{:.0} %", v * 100.0);
    let map = |title: &str| false_colour_png(w, h, &values, 1.0, title, &percent).unwrap();
    assert!(map("relative error") == map("relative error"));
    let changed = changed_pixels(&map("relative error"), &map("absolute error"));
    assert!(!changed.is_empty());
    assert!(changed.iter().all(|&(_, y)| y >= h), "{:?}", &changed[..1]);

    // The contact sheet: another label changes its tile's label strip only.
    let (w, h) = (96, 64);
    let tile = |label: &str| (label.to_string(), vec![[40u8, 90, 160]; (w * h) as usize]);
    let sheet = |label: &str| contact_sheet(&[tile("reference"), tile(label)], w, h, 2).unwrap();
    assert!(sheet("jacobi") == sheet("jacobi"));
    let changed = changed_pixels(&sheet("jacobi"), &sheet("shooting"));
    assert!(!changed.is_empty());
    assert!(
        changed.iter().all(|&(x, y)| x > w && y < 4 + 18),
        "{:?}",
        &changed[..1]
    );
}

#[test]
fn the_binary_links_no_font_library() {
    let binary = env!("CARGO_BIN_EXE_nusselt");
    let out = match Command::new("ldd").arg(binary).output() {
        Ok(out) => out,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            println!("skipped: no ldd on this machine to list the binary's libraries");
            return;
        }
        Err(e) => panic!("ldd {binary}: {e}"),
    };
    let libraries = String::from_utf8_lossy(&out.stdout).to_lowercase();
    assert!(out.status.success(), "ldd {binary}: {out:?}");
    assert!(
        libraries.contains("libc."),
        "ldd listed no libc: {libraries}"
    );
    for library in ["fontconfig", "freetype"] {
        assert!(
            !libraries.contains(library),
            "the binary links {library}:\n{libraries}"
        );
    }
}
