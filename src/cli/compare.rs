//! `nusselt compare`: an image against a reference image, metrics as JSON
//! on stdout and, with `-o`, the error images; or a solution against a
//! table of point references (`nusselt probe`), the point errors as JSON
//! and, with `-o`, one row per point.
//!
//! Invariant: the files of `-o` are written together or not at all.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;

use nusselt::lab::points;
use nusselt::output::OutputSet;

/// What `compare -o DIR` writes, either form: the files of the other form
/// from an earlier comparison are removed with the commit.
const COMPARE_OUTPUTS: &[&str] = &["error.exr", "error.png", "points.csv", "metrics.json"];

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// The image to judge (OpenEXR, RGB), or a solution.exr when the
    /// reference is a point table.
    test: PathBuf,
    /// The reference image (OpenEXR, RGB; a <stem>.noise.exr beside it is
    /// read as its per-pixel standard error), or a point table (.csv)
    /// written by `nusselt probe`.
    reference: PathBuf,
    /// Write error.exr, error.png and metrics.json (point tables:
    /// points.csv and metrics.json) into this folder (without it, only the
    /// metrics are printed).
    #[arg(short, long, value_name = "DIR")]
    output: Option<PathBuf>,
    /// Relative error at the top of error.png's colour scale (0.2 = 20 %).
    #[arg(long, default_value_t = nusselt::lab::compare::DEFAULT_MAX_ERROR)]
    max_error: f64,
}

/// Runs `nusselt compare`.
pub fn run(args: CompareArgs) -> Result<()> {
    if !(args.max_error > 0.0 && args.max_error.is_finite()) {
        bail!("--max-error must be a positive fraction (0.2 = 20 %)");
    }
    if args
        .reference
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
    {
        return compare_points(&args);
    }
    super::recover_beside(&args.test)?;
    super::recover_beside(&args.reference)?;
    let comparison = nusselt::lab::compare::compare_files(&args.test, &args.reference)?;
    let json = nusselt::output::write_json(&comparison.metrics)?;
    if let Some(dir) = &args.output {
        let images = nusselt::lab::compare::error_images(
            &comparison.test,
            &comparison.reference,
            args.max_error,
        )?;
        let mut set = OutputSet::create(dir)?.replacing(COMPARE_OUTPUTS);
        set.stage("error.exr", &images.exr)?;
        set.stage("error.png", &images.png)?;
        set.stage("metrics.json", &json)?;
        set.commit()?;
    }
    print!("{}", String::from_utf8_lossy(&json));
    Ok(())
}

/// A solution against a point table.
fn compare_points(args: &CompareArgs) -> Result<()> {
    super::recover_beside(&args.test)?;
    let mesh = nusselt::output::exr::read_solution(&args.test)?;
    let table = points::read_table(&args.reference)?;
    let (score, errors) = points::score(&mesh, &table)?;
    let json = nusselt::output::write_json(&score)?;
    if let Some(dir) = &args.output {
        let csv = points::encode_errors(&errors)?;
        let mut set = OutputSet::create(dir)?.replacing(COMPARE_OUTPUTS);
        set.stage("points.csv", &csv)?;
        set.stage("metrics.json", &json)?;
        set.commit()?;
    }
    print!("{}", String::from_utf8_lossy(&json));
    Ok(())
}
