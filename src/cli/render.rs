//! `nusselt render`: a new view of an earlier solution, without solving
//! again.
//!
//! Invariant: with no view flags, the view is the solve's (from the
//! `report.json` beside the solution, when that report lists this
//! solution), so the image matches the solve's own render; the exposure is
//! the solve's from any view. A commit that a killed solve left half done
//! in the solution's folder is finished before anything is read.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use glam::DVec3;

use nusselt::output::exr::{self, ImageInfo, Quantity};
use nusselt::pipeline;
use nusselt::render::RenderSettings;
use nusselt::render::view::View;
use nusselt::report::Report;
use nusselt::util::progress::Progress;

use super::args::{Common, ImageBudgetArgs, ViewArgs, exr_path, png_path};
use super::init_threads;

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A solution.exr written by `nusselt solve`.
    solution: PathBuf,
    /// The image to write (.exr).
    #[arg(short, long, value_name = "IMAGE.exr", value_parser = exr_path)]
    output: PathBuf,
    /// Also write a tone-mapped PNG here.
    #[arg(long, value_name = "IMAGE.png", value_parser = png_path)]
    png: Option<PathBuf>,
    /// Display exposure of the PNG (default: the solve's, from the report
    /// beside the solution, else the solution's own).
    #[arg(long)]
    exposure: Option<f32>,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    budget: ImageBudgetArgs,
    #[command(flatten)]
    common: Common,
}

/// The solve's report, when it sits beside the solution and lists it (the
/// same size and CRC-32 as one of its `files`, under any name): it gives
/// the view and the exposure.
/// A report of another run (the solution was replaced or copied over) is
/// left aside with a warning; one of an older nusselt, which lists no
/// files, is trusted.
fn solve_report(solution: &std::path::Path, bytes: &[u8]) -> Option<Report> {
    let path = solution.with_file_name("report.json");
    let report: Report = serde_json::from_slice(&std::fs::read(&path).ok()?).ok()?;
    if report.files.is_empty() || report.files.iter().any(|f| f.matches(bytes)) {
        Some(report)
    } else {
        super::warn(&format!(
            "{} is not the report of {} (another run's); using the default view",
            path.display(),
            solution.display()
        ));
        None
    }
}

/// Runs `nusselt render`.
pub fn run(args: RenderArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    super::checked(pipeline::check_exposure(args.exposure))?;
    let budget = args.budget.bytes()?;
    let progress = Progress::new(!args.common.quiet);
    for target in std::iter::once(&args.output).chain(&args.png) {
        nusselt::output::check_target(target)?;
    }
    super::recover_beside(&args.solution)?;
    let bytes =
        std::fs::read(&args.solution).map_err(|e| nusselt::Error::input(&args.solution, e))?;
    let mesh = exr::decode_solution(&bytes, &args.solution)?;
    mesh.validate()
        .map_err(|e| anyhow::anyhow!("{}: invalid solution: {e}", args.solution.display()))?;
    let report = solve_report(&args.solution, &bytes);
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.as_dvec3()), hi.max(p.as_dvec3()))
        });
    let base = report
        .as_ref()
        .and_then(|r| r.view.clone())
        .map(|v| nusselt::scene::Camera {
            name: "report".into(),
            eye: v.eye,
            forward: v.forward,
            up: v.up,
            yfov: v.yfov,
            aspect_ratio: Some(v.width as f64 / v.height as f64),
        });
    let mut overrides = args.view.overrides();
    if let (Some(v), None, None) = (
        report.as_ref().and_then(|r| r.view.as_ref()),
        overrides.width,
        overrides.height,
    ) {
        overrides.width = Some(v.width);
        overrides.height = Some(v.height);
    }
    let view = View::resolve(base.as_ref(), (lo, hi), &overrides)?;
    super::checked(view.check_memory(&overrides, &[], budget))?;
    let settings = RenderSettings::with_samples(args.view.spp, args.common.seed);
    let frame = nusselt::render::render(&mesh, &view, &settings, &progress);
    let exposure = args.png.as_ref().map(|_| {
        args.exposure
            .or(report.as_ref().map(|r| r.exposure))
            .unwrap_or_else(|| nusselt::output::png::solution_exposure(&mesh))
    });
    let info = ImageInfo::new(Quantity::Radiance)
        .scene(report.as_ref().map_or("", |r| r.scene.as_str()))
        .view(Some(&view))
        .exposure(exposure);
    nusselt::output::write_atomic(&args.output, &exr::encode_image(&frame, &info)?)?;
    if let (Some(png), Some(exposure)) = (&args.png, exposure) {
        nusselt::output::write_atomic(png, &nusselt::output::png::encode_png(&frame, exposure)?)?;
    }
    Ok(())
}
