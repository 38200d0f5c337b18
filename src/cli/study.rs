//! `nusselt study`: a sweep of methods and settings against a path-traced
//! reference (cached in the output folder), with its CSV and charts.
//!
//! Invariant: the study's files are written together or not at all.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use nusselt::load::{LoadOptions, load_scene};
use nusselt::util::progress::Progress;

use super::args::Common;
use super::init_threads;

#[derive(Args, Debug)]
pub struct StudyArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// Output folder (the reference is cached here).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// The sweep as JSON (see README); default: every method at a few settings.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Use this reference image (and the <stem>.noise.exr beside it, if any)
    /// instead of path tracing one.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Image width (overrides the config).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (overrides the config).
    #[arg(long)]
    height: Option<u32>,
    /// Reference samples per pixel (overrides the config).
    #[arg(long)]
    reference_spp: Option<u32>,
    #[command(flatten)]
    common: Common,
}

/// Runs `nusselt study`.
pub fn run(args: StudyArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let progress = Progress::new(!args.common.quiet);
    let mut config: nusselt::lab::study::StudyConfig = match &args.config {
        Some(path) => {
            let bytes =
                std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
            serde_json::from_slice(&bytes)
                .with_context(|| format!("{}: not a study configuration", path.display()))?
        }
        None => Default::default(),
    };
    config.width = args.width.unwrap_or(config.width);
    config.height = args.height.unwrap_or(config.height);
    config.reference_spp = args.reference_spp.unwrap_or(config.reference_spp);
    config.seed = args.common.seed;
    config.validate()?;
    let scene = load_scene(&args.scene, &LoadOptions::default())?;
    let given = match &args.reference {
        Some(path) => {
            let image = nusselt::output::exr::read_image(path)?;
            let noise_path = nusselt::lab::compare::noise_path(path);
            let noise = noise_path
                .exists()
                .then(|| nusselt::output::exr::read_image(&noise_path))
                .transpose()?;
            Some((image, noise))
        }
        None => None,
    };
    let name = args.scene.display().to_string();
    let result =
        nusselt::lab::study::run_study(&scene, &name, &config, given, &args.output, &progress)?;
    nusselt::lab::study::write_study(&args.output, &result)?;
    if !args.common.quiet {
        println!("{} runs → {}", result.rows.len(), args.output.display());
    }
    Ok(())
}
