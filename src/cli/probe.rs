//! `nusselt probe`: path-traced radiosity at surface points, with standard
//! errors, as a table that `nusselt compare SOLUTION.exr TABLE.csv` scores
//! solutions against.
//!
//! Invariant: the table is written atomically, one row per point in the
//! order given (or drawn).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use nusselt::lab::points;
use nusselt::reference::{self, ProbeSettings};
use nusselt::util::progress::Progress;

use super::args::{Common, LoadArgs, MAX_PATHS, SkyArgs, csv_path};
use super::{checked, init_threads};

#[derive(Args, Debug)]
pub struct ProbeArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// The points: CSV with a header naming x,y,z,nx,ny,nz (the normal of
    /// the side whose radiosity is wanted).
    #[arg(long, conflicts_with = "random")]
    points: Option<PathBuf>,
    /// Instead of --points: this many points spread over the scene's
    /// non-emitting surfaces by area (deterministic for --seed).
    #[arg(long)]
    random: Option<usize>,
    /// The table to write (.csv): the points, their patch, radiosity r,g,b
    /// and its standard error se_r,se_g,se_b.
    #[arg(short, long, value_name = "TABLE.csv", value_parser = csv_path)]
    output: PathBuf,
    /// Paths per point, 2 (the standard error needs two) to 1048576.
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(2..=i64::from(MAX_PATHS)))]
    spp: u32,
    /// Largest number of reflections per path (default: unlimited).
    #[arg(long)]
    max_bounces: Option<u32>,
    #[command(flatten)]
    load: LoadArgs,
    #[command(flatten)]
    sky: SkyArgs,
    #[command(flatten)]
    common: Common,
}

/// Runs `nusselt probe`.
pub fn run(args: ProbeArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let progress = Progress::new(!args.common.quiet);
    let options = args.load.options_with(&args.sky)?;
    let settings = ProbeSettings {
        samples: args.spp,
        seed: args.common.seed,
        max_bounces: args.max_bounces,
    };
    checked(settings.validate())?;
    nusselt::output::check_target(&args.output)?;
    let scene = super::load(&args.scene, &options, &progress)?;
    let probe_points = match (&args.points, args.random) {
        (Some(path), None) => points::read_points(path)?,
        (None, Some(n)) if n > 0 => reference::random_points(&scene, n, args.common.seed),
        (None, Some(_)) => bail!("--random must be at least 1"),
        _ => bail!("give the points: --points FILE or --random N"),
    };
    let values = reference::probe_radiosity(&scene, &probe_points, &settings, &progress)
        .with_context(|| format!("probing {}", args.scene.display()))?;
    nusselt::output::write_atomic(&args.output, &points::encode_table(&values)?)?;
    if !args.common.quiet {
        println!(
            "{}: {} points at {} paths → {}",
            args.scene.display(),
            values.len(),
            args.spp,
            args.output.display()
        );
    }
    Ok(())
}
