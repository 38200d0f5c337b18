//! Charts and false-colour maps: the only user of `plotters`, of the
//! colour-map crate (`colorous`) and of the bundled font (`dejavu`).
//!
//! Owns: drawing, not data. [`draw_line_chart`] turns any set of labelled
//! series with axis titles and log flags into SVG text and PNG bytes (the
//! convergence charts of [`crate::lab::convergence`] and the study's
//! error-against-time and error-against-elements charts use it);
//! [`false_colour_png`] draws a scalar field with a colour map and a
//! labelled scale bar (the `error.png` of `nusselt compare`);
//! [`contact_sheet`] lays labelled tiles out on one canvas.
//!
//! Invariants:
//! - Nothing here touches the file system or knows of the solver: data
//!   comes in as numbers and pixels, the bytes go to `output` for writing.
//! - Points that a log axis cannot show (zero, negative) and non-finite
//!   points are skipped and counted, never drawn and never a panic. A chart
//!   with no drawable point at all is an error, not an empty picture.
//! - The same input gives the same bytes on every machine. All text is
//!   laid out and rasterised in Rust (plotters' `ab_glyph` text) with
//!   DejaVu Sans, whose bytes the `dejavu` crate compiles into the binary;
//!   it is registered as plotters' `sans-serif` before anything is drawn,
//!   and plotters knows no other font: no system font is looked up, and no
//!   font library (fontconfig, FreeType) is linked. The SVGs name that
//!   family, so a viewer draws their text in its own sans-serif, at the
//!   places DejaVu Sans's metrics gave.
//!
//! Known weakness: plotters' `ab_glyph` text puts each glyph's ink at its
//! pen position, leaving out the glyph's left side bearing, so letter
//! spacing in the PNGs is a pixel uneven at the smallest sizes (the scale
//! bar's 12 px labels).

use std::ops::Range;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use crate::error::{Error, Result};

/// What chart errors name.
const CHART: &str = "the chart";
/// What false-colour map errors name.
const MAP: &str = "the false-colour map";

/// The font family every text of a chart names; [`bundled_font`] registers
/// DejaVu Sans under it.
const FONT_FAMILY: &str = "sans-serif";

/// Registers DejaVu Sans (the `dejavu` crate's copy of its regular face) as
/// plotters' [`FONT_FAMILY`], once per process; every drawing function
/// calls it before it draws. Other styles of the family (bold, italic) fall
/// back to that face in plotters; another family is an error when drawn,
/// never a system font. `what` names the picture in the error.
fn bundled_font(what: &'static str) -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let registered = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, dejavu::sans::regular())
            .is_ok()
    });
    if registered {
        Ok(())
    } else {
        Err(Error::encode(
            what,
            "the bundled font (DejaVu Sans) could not be read",
        ))
    }
}

/// Default size of a line chart in pixels (SVG user units).
pub const CHART_SIZE: (u32, u32) = (900, 560);
/// Series with at most this many points get a marker at each point (so a
/// one-point series is visible); longer ones are drawn as lines only.
pub const MARKER_LIMIT: usize = 60;

/// One labelled line of a chart.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The series' name in the legend.
    pub label: String,
    /// (x, y) in drawing order.
    pub points: Vec<(f64, f64)>,
}

/// An axis: its title and whether it is logarithmic.
#[derive(Clone, Debug, PartialEq)]
pub struct Axis {
    /// The axis' description, drawn beside it.
    pub title: String,
    /// Base-10 logarithmic rather than linear.
    pub log: bool,
}

impl Axis {
    /// A linear axis titled `title`.
    pub fn linear(title: impl Into<String>) -> Axis {
        Axis {
            title: title.into(),
            log: false,
        }
    }

    /// A base-10 logarithmic axis titled `title`.
    pub fn log(title: impl Into<String>) -> Axis {
        Axis {
            title: title.into(),
            log: true,
        }
    }

    /// Whether `v` can be placed on this axis.
    fn accepts(&self, v: f64) -> bool {
        v.is_finite() && (!self.log || v > 0.0)
    }

    /// The drawn range around the data range `lo..=hi` (lo ≤ hi): log axes
    /// extend to (just beyond) whole decades so at least two labelled ticks show; linear
    /// axes get a 5 % margin, and a degenerate range is widened.
    fn range(&self, lo: f64, hi: f64) -> Range<f64> {
        if self.log {
            let a = lo.log10().floor();
            let mut b = hi.log10().ceil();
            if b <= a {
                b = a + 1.0;
            }
            // A hair beyond the decades, so rounding in the axis' own
            // logarithms keeps the end decades labelled.
            10f64.powf(a) / 1.01..10f64.powf(b) * 1.01
        } else if hi > lo {
            let pad = 0.05 * (hi - lo);
            (lo - pad)..(hi + pad)
        } else {
            let pad = if lo == 0.0 { 1.0 } else { 0.5 * lo.abs() };
            (lo - pad)..(hi + pad)
        }
    }
}

/// A line chart: a title, two axes, and the series drawn on them.
#[derive(Clone, Debug, PartialEq)]
pub struct LineChart {
    /// The caption above the chart.
    pub title: String,
    /// The horizontal axis.
    pub x: Axis,
    /// The vertical axis.
    pub y: Axis,
    /// The lines, coloured in order.
    pub series: Vec<Series>,
}

/// A chart drawn twice: as SVG text and as a PNG.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartImages {
    /// The chart as SVG text.
    pub svg: String,
    /// The chart as PNG bytes.
    pub png: Vec<u8>,
    /// Points left out because an axis could not show them (non-positive
    /// on a log axis, or not finite).
    pub skipped_points: usize,
}

/// Draws `chart` at `size` (width, height in pixels) as SVG and PNG: one
/// coloured line per series, a legend with the series labels, axis titles,
/// and log axes where asked.
///
/// Fails when there are no series, a size is below 200×150, or no point of
/// any series can be drawn; a series whose points are all skipped stays in
/// the legend.
pub fn draw_line_chart(chart: &LineChart, size: (u32, u32)) -> Result<ChartImages> {
    if chart.series.is_empty() {
        return Err(Error::encode(CHART, "there are no series to draw"));
    }
    bundled_font(CHART)?;
    if size.0 < 200 || size.1 < 150 {
        return Err(Error::encode(
            CHART,
            format!("{}×{} pixels is too small", size.0, size.1),
        ));
    }
    let mut skipped_points = 0;
    let series: Vec<Series> = chart
        .series
        .iter()
        .map(|s| {
            let points: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|&(x, y)| chart.x.accepts(x) && chart.y.accepts(y))
                .collect();
            skipped_points += s.points.len() - points.len();
            Series {
                label: s.label.clone(),
                points,
            }
        })
        .collect();
    let all = || series.iter().flat_map(|s| s.points.iter().copied());
    if all().next().is_none() {
        return Err(Error::encode(
            CHART,
            format!(
                "none of the {skipped_points} points of \"{}\" can be drawn{}",
                chart.title,
                if chart.x.log || chart.y.log {
                    " (a log axis shows only positive values)"
                } else {
                    ""
                }
            ),
        ));
    }
    let (xlo, xhi, ylo, yhi) = all().fold(
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ),
        |(a, b, c, d), (x, y)| (a.min(x), b.max(x), c.min(y), d.max(y)),
    );
    let xr = chart.x.range(xlo, xhi);
    let yr = chart.y.range(ylo, yhi);

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw_axes(&root, chart, &series, xr.clone(), yr.clone())?;
        root.present().map_err(|e| Error::encode(CHART, e))?;
    }
    let mut rgb = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw_axes(&root, chart, &series, xr, yr)?;
        root.present().map_err(|e| Error::encode(CHART, e))?;
    }
    let png = crate::output::png::encode_rgb8(size.0, size.1, &rgb)?;
    Ok(ChartImages {
        svg,
        png,
        skipped_points,
    })
}

/// Picks the coordinate types for the axes' log flags and draws.
fn draw_axes<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    chart: &LineChart,
    series: &[Series],
    xr: Range<f64>,
    yr: Range<f64>,
) -> Result<()> {
    match (chart.x.log, chart.y.log) {
        (false, false) => draw_on(root, chart, series, xr, yr),
        (true, false) => draw_on(root, chart, series, xr.log_scale(), yr),
        (false, true) => draw_on(root, chart, series, xr, yr.log_scale()),
        (true, true) => draw_on(root, chart, series, xr.log_scale(), yr.log_scale()),
    }
}

/// Tick label of a value on a log axis: a power of ten as `1e-3`, other
/// values with two significant digits.
fn log_label(v: &f64) -> String {
    let e = v.log10();
    if (e - e.round()).abs() < 1e-9 {
        format!("1e{}", e.round() as i64)
    } else {
        format!("{v:.1e}")
    }
}

/// Tick label of a value on a linear axis: up to four significant digits,
/// without trailing zeros.
fn linear_label(v: &f64) -> String {
    if *v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}");
    }
    let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Draws the chart on `root` with the given coordinate specifications.
fn draw_on<DB, X, Y>(
    root: &DrawingArea<DB, Shift>,
    chart: &LineChart,
    series: &[Series],
    x: X,
    y: Y,
) -> Result<()>
where
    DB: DrawingBackend,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let fail = |e: DrawingAreaErrorKind<DB::ErrorType>| Error::encode(CHART, e);
    root.fill(&WHITE).map_err(fail)?;
    let mut ctx = ChartBuilder::on(root)
        .caption(&chart.title, (FONT_FAMILY, 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(76)
        .build_cartesian_2d(x, y)
        .map_err(fail)?;
    let x_label: &dyn Fn(&f64) -> String = if chart.x.log {
        &log_label
    } else {
        &linear_label
    };
    let y_label: &dyn Fn(&f64) -> String = if chart.y.log {
        &log_label
    } else {
        &linear_label
    };
    ctx.configure_mesh()
        .x_desc(chart.x.title.as_str())
        .y_desc(chart.y.title.as_str())
        .x_label_formatter(x_label)
        .y_label_formatter(y_label)
        .label_style((FONT_FAMILY, 14))
        .axis_desc_style((FONT_FAMILY, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(fail)?;
    for (k, s) in series.iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        let style = ShapeStyle::from(colour).stroke_width(2);
        ctx.draw_series(LineSeries::new(s.points.iter().copied(), style))
            .map_err(fail)?
            .label(s.label.as_str())
            .legend(move |(lx, ly)| PathElement::new([(lx, ly), (lx + 20, ly)], style));
        if s.points.len() <= MARKER_LIMIT {
            ctx.draw_series(
                s.points
                    .iter()
                    .map(|&p| Circle::new(p, 3, ShapeStyle::from(colour).filled())),
            )
            .map_err(fail)?;
        }
    }
    ctx.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT_FAMILY, 14))
        .draw()
        .map_err(fail)?;
    Ok(())
}

/// Height in pixels of the scale bar strip below a false-colour map.
pub const SCALE_BAR_HEIGHT: u32 = 72;
/// Smallest width of a false-colour map with its scale bar, so the tick
/// labels fit under a small image (the image is centred).
pub const SCALE_BAR_MIN_WIDTH: u32 = 360;
/// Background of the canvas around the image and behind the scale bar.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];

/// The colour of `t` in [0, 1] on the map (magma: black → purple → orange →
/// pale yellow, perceptually ordered). Values outside are clamped; NaN is
/// treated as 0.
pub fn colour_map(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let c = colorous::MAGMA.eval_continuous(t);
    [c.r, c.g, c.b]
}

/// A `width` × `height` scalar field (`values`, row-major, row 0 at the top)
/// as a false-colour PNG with a labelled scale bar below it.
///
/// Value 0 maps to the bottom of the colour map and `max` to the top;
/// larger values (and +∞) saturate. The scale bar spans 0 to `max`, its
/// ticks labelled by `tick_label` (e.g. as percentages), titled `title`.
/// The canvas is `max(width, SCALE_BAR_MIN_WIDTH)` wide and `height +
/// SCALE_BAR_HEIGHT` high; the image sits centred at the top.
pub fn false_colour_png(
    width: u32,
    height: u32,
    values: &[f64],
    max: f64,
    title: &str,
    tick_label: &dyn Fn(&f64) -> String,
) -> Result<Vec<u8>> {
    if width == 0 || height == 0 || values.len() != width as usize * height as usize {
        return Err(Error::encode(
            MAP,
            format!("{} values for a {width}×{height} image", values.len()),
        ));
    }
    if !(max > 0.0 && max.is_finite()) {
        return Err(Error::encode(
            MAP,
            format!("the scale maximum {max} is not a positive number"),
        ));
    }
    bundled_font(MAP)?;
    let canvas_w = width.max(SCALE_BAR_MIN_WIDTH);
    let canvas_h = height
        .checked_add(SCALE_BAR_HEIGHT)
        .ok_or_else(|| Error::encode(MAP, "the image is too tall"))?;
    let mut rgb: Vec<u8> = BACKGROUND
        .iter()
        .copied()
        .cycle()
        .take(canvas_w as usize * canvas_h as usize * 3)
        .collect();
    let left = ((canvas_w - width) / 2) as usize;
    for (row, line) in values.chunks_exact(width as usize).enumerate() {
        for (col, &v) in line.iter().enumerate() {
            let at = (row * canvas_w as usize + left + col) * 3;
            rgb[at..at + 3].copy_from_slice(&colour_map(v / max));
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (canvas_w, canvas_h)).into_drawing_area();
        let (_, strip) = root.split_vertically(height);
        draw_scale_bar(&strip, max, title, tick_label)?;
        root.present().map_err(|e| Error::encode(MAP, e))?;
    }
    crate::output::png::encode_rgb8(canvas_w, canvas_h, &rgb)
}

/// Draws the colour map from 0 to `max` as a horizontal bar with ticks.
fn draw_scale_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    max: f64,
    title: &str,
    tick_label: &dyn Fn(&f64) -> String,
) -> Result<()> {
    let fail = |e: DrawingAreaErrorKind<DB::ErrorType>| Error::encode(MAP, e);
    let (w, _) = area.dim_in_pixel();
    let mut ctx = ChartBuilder::on(area)
        .margin_top(6)
        .margin_left(16)
        .margin_right(24)
        .x_label_area_size(40)
        .build_cartesian_2d(0.0..max, 0.0..1.0)
        .map_err(fail)?;
    ctx.configure_mesh()
        .disable_mesh()
        .disable_y_axis()
        .x_labels(6)
        .x_label_formatter(tick_label)
        .x_desc(title)
        .label_style((FONT_FAMILY, 12))
        .axis_desc_style((FONT_FAMILY, 13))
        .draw()
        .map_err(fail)?;
    let steps = w.max(2) as usize;
    ctx.draw_series((0..steps).map(|k| {
        let a = max * k as f64 / steps as f64;
        let b = max * (k + 1) as f64 / steps as f64;
        let [r, g, bl] = colour_map((a + b) / (2.0 * max));
        Rectangle::new([(a, 0.0), (b, 1.0)], RGBColor(r, g, bl).filled())
    }))
    .map_err(fail)?;
    Ok(())
}

/// Height of the label strip above each contact-sheet tile.
pub const TILE_LABEL_HEIGHT: u32 = 18;

/// A contact sheet: `tiles` (label, `width` × `height` 8-bit RGB pixels,
/// row 0 at the top) laid out `columns` to a row, each under its label, on
/// a white canvas, as PNG.
pub fn contact_sheet(
    tiles: &[(String, Vec<[u8; 3]>)],
    width: u32,
    height: u32,
    columns: usize,
) -> Result<Vec<u8>> {
    const SHEET: &str = "the contact sheet";
    let n = width as usize * height as usize;
    if tiles.is_empty() || columns == 0 || n == 0 {
        return Err(Error::encode(SHEET, "nothing to lay out"));
    }
    if let Some((label, _)) = tiles.iter().find(|(_, px)| px.len() != n) {
        return Err(Error::encode(
            SHEET,
            format!("tile '{label}' is not {width}×{height}"),
        ));
    }
    bundled_font(SHEET)?;
    let columns = columns.min(tiles.len());
    let rows = tiles.len().div_ceil(columns);
    let gap = 4u32;
    let cell_w = width + gap;
    let cell_h = height + TILE_LABEL_HEIGHT + gap;
    let (canvas_w, canvas_h) = (columns as u32 * cell_w + gap, rows as u32 * cell_h + gap);
    let mut rgb: Vec<u8> = BACKGROUND
        .iter()
        .copied()
        .cycle()
        .take(canvas_w as usize * canvas_h as usize * 3)
        .collect();
    for (k, (_, pixels)) in tiles.iter().enumerate() {
        let x0 = gap + (k % columns) as u32 * cell_w;
        let y0 = gap + (k / columns) as u32 * cell_h + TILE_LABEL_HEIGHT;
        for (row, line) in pixels.chunks_exact(width as usize).enumerate() {
            let at = ((y0 as usize + row) * canvas_w as usize + x0 as usize) * 3;
            for (col, p) in line.iter().enumerate() {
                rgb[at + 3 * col..at + 3 * col + 3].copy_from_slice(p);
            }
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (canvas_w, canvas_h)).into_drawing_area();
        let style = (FONT_FAMILY, 11).into_font().color(&BLACK);
        // About 6 px per character at this size: cut labels to the tile.
        let fit = (width as usize / 6).max(4);
        for (k, (label, _)) in tiles.iter().enumerate() {
            let label: String = if label.chars().count() > fit {
                label
                    .chars()
                    .take(fit - 1)
                    .chain(std::iter::once('…'))
                    .collect()
            } else {
                label.clone()
            };
            let x0 = gap + (k % columns) as u32 * cell_w;
            let y0 = gap + (k / columns) as u32 * cell_h;
            root.draw(&Text::new(label, (x0 as i32, y0 as i32 + 2), style.clone()))
                .map_err(|e| Error::encode(SHEET, e))?;
        }
        root.present().map_err(|e| Error::encode(SHEET, e))?;
    }
    crate::output::png::encode_rgb8(canvas_w, canvas_h, &rgb)
}
