//! `nusselt reference`: an independent path-traced reference image of the
//! same view, with its per-pixel noise image and a JSON sidecar.
//!
//! Invariant: the image is written last, so when it is there its sidecars
//! are complete.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use nusselt::output::exr::{self, ImageInfo, Quantity};
use nusselt::reference::{self, ReferenceSettings};
use nusselt::render::view::View;
use nusselt::util::progress::Progress;

use super::args::{Common, ImageBudgetArgs, LoadArgs, SkyArgs, ViewArgs, exr_path, png_path};
use super::{checked, init_threads};

#[derive(Args, Debug)]
pub struct ReferenceArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// The image to write (.exr); `<stem>.noise.exr` and `<stem>.json` go
    /// beside it.
    #[arg(short, long, value_name = "IMAGE.exr", value_parser = exr_path)]
    output: PathBuf,
    /// Also write a tone-mapped PNG here (auto exposure).
    #[arg(long, value_name = "IMAGE.png", value_parser = png_path)]
    png: Option<PathBuf>,
    /// Largest number of reflections per path (default: unlimited, ended by
    /// Russian roulette; never more than 10,000).
    #[arg(long)]
    max_bounces: Option<u32>,
    #[command(flatten)]
    load: LoadArgs,
    #[command(flatten)]
    sky: SkyArgs,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    budget: ImageBudgetArgs,
    #[command(flatten)]
    common: Common,
}

/// Runs `nusselt reference`.
pub fn run(args: ReferenceArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let progress = Progress::new(!args.common.quiet);
    let budget = args.budget.bytes()?;
    let mut options = args.load.options_with(&args.sky)?;
    options.memory_budget = budget;
    let settings = ReferenceSettings {
        samples_per_pixel: args.view.spp,
        seed: args.common.seed,
        max_bounces: args.max_bounces,
    };
    checked(settings.validate())?;
    for target in std::iter::once(&args.output).chain(&args.png) {
        nusselt::output::check_target(target)?;
    }
    let scene = super::load(&args.scene, &options, &progress)?;
    let overrides = args.view.overrides();
    let view = View::resolve(scene.cameras.first(), scene.bounds, &overrides)?;
    super::checked(view.check_memory(&overrides, &[], budget))?;
    let mut result = reference::render_reference(&scene, &view, &settings, &progress)
        .with_context(|| format!("path tracing {}", args.scene.display()))?;
    result.stats.scene = args.scene.display().to_string();
    let stats = nusselt::output::write_json(&result.stats)?;
    let exposure = args.png.as_ref().map(|_| {
        nusselt::output::png::auto_exposure(
            result
                .image
                .pixels
                .iter()
                .map(|&p| nusselt::output::png::luminance(p)),
        )
    });
    let info = |quantity| {
        ImageInfo::new(quantity)
            .scene(&result.stats.scene)
            .view(Some(&view))
    };
    let image = exr::encode_image(&result.image, &info(Quantity::Radiance).exposure(exposure))?;
    let noise = exr::encode_image(&result.noise, &info(Quantity::RadianceStandardError))?;
    let png = match (&args.png, exposure) {
        (Some(path), Some(exposure)) => Some((
            path,
            nusselt::output::png::encode_png(&result.image, exposure)?,
        )),
        _ => None,
    };
    nusselt::output::write_atomic(&reference::noise_path(&args.output), &noise)?;
    nusselt::output::write_atomic(&reference::stats_path(&args.output), &stats)?;
    nusselt::output::write_atomic(&args.output, &image)?;
    if let Some((path, bytes)) = png {
        nusselt::output::write_atomic(path, &bytes)?;
    }
    for w in &scene.warnings {
        super::warn(w);
    }
    if !args.common.quiet {
        let s = &result.stats;
        println!(
            "{}: {} × {} at {} spp, {:.2} s ({:.3} M samples/s), relative noise {:.2} % → {}",
            args.scene.display(),
            s.width,
            s.height,
            s.spp,
            s.time_seconds,
            s.samples_per_second / 1e6,
            100.0 * s.relative_noise,
            args.output.display()
        );
    }
    Ok(())
}
