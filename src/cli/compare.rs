//! `nusselt compare`: an image against a reference, metrics as JSON on
//! stdout and, with `-o`, the error images.
//!
//! Invariant: the error images and metrics are written together or not
//! at all.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;

use nusselt::output::OutputSet;

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// The image to judge (OpenEXR, RGB).
    test: PathBuf,
    /// The reference image (OpenEXR, RGB); a <stem>.noise.exr beside it is
    /// read as its per-pixel standard error.
    reference: PathBuf,
    /// Write error.exr, error.png and metrics.json into this folder
    /// (without it, only the metrics are printed).
    #[arg(short, long)]
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
    let comparison = nusselt::lab::compare::compare_files(&args.test, &args.reference)?;
    let json = nusselt::output::write_json(&comparison.metrics)?;
    if let Some(dir) = &args.output {
        let images = nusselt::lab::compare::error_images(
            &comparison.test,
            &comparison.reference,
            args.max_error,
        )?;
        let mut set = OutputSet::create(dir)?;
        set.stage("error.exr", &images.exr)?;
        set.stage("error.png", &images.png)?;
        set.stage("metrics.json", &json)?;
        set.commit()?;
    }
    print!("{}", String::from_utf8_lossy(&json));
    Ok(())
}
