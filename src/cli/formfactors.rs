//! `nusselt formfactors`: the form factors between the input surfaces (one
//! glTF node each), as CSV on stdout.
//!
//! Invariant: the CSV's first three columns are `from,to,form_factor` (the
//! contract); diagnostics follow, the kernel's error estimate last. A surface name with a comma, a quote or
//! a line break is quoted (RFC 4180, by [`nusselt::output::csv`]).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{ArgMatches, Args};
use serde::Serialize;

use nusselt::classic::matrix::FormFactorMatrix;
use nusselt::classic::surfaces::SurfaceMethod;
use nusselt::output::csv;
use nusselt::pipeline;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

use super::args::{Common, KernelArgs, LoadArgs, kernel_inapplicable};
use super::init_threads;

/// A row of the CSV: the surfaces' names, the factors to 9 decimals, the
/// reciprocity error to 4 significant digits, the kernel's estimated
/// absolute error of the factor (empty for the hemicube, which has none).
#[derive(Serialize)]
struct PairRow<'a> {
    from: &'a str,
    to: &'a str,
    #[serde(serialize_with = "csv::fixed::<9, _>")]
    form_factor: f64,
    #[serde(serialize_with = "csv::fixed::<9, _>")]
    reverse: f64,
    #[serde(serialize_with = "csv::sci::<3, _>")]
    reciprocity_error: f64,
    #[serde(serialize_with = "csv::fixed::<9, _>")]
    row_sum: f64,
    #[serde(serialize_with = "csv::sci_or_empty::<3, _>")]
    error: Option<f64>,
}

#[derive(Args, Debug)]
pub struct FormFactorArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// analytic = polygon-polygon quadrature, sampling = area sampling, hemicube.
    #[arg(long, value_enum, default_value_t = SurfaceMethod::Analytic)]
    method: SurfaceMethod,
    /// Cut surfaces into elements no larger than this (metres) before
    /// integrating; default: whole patches (analytic, sampling) or 1/25 of
    /// the scene diagonal (hemicube, which samples at element centroids).
    #[arg(long)]
    element_size: Option<f64>,
    #[command(flatten)]
    kernel: KernelArgs,
    #[command(flatten)]
    load: LoadArgs,
    #[command(flatten)]
    common: Common,
}

/// The kernel flags given that the chosen `--method` does not read, as one
/// sentence; `None` when every flag given applies.
pub fn inapplicable(matches: &ArgMatches) -> Option<String> {
    let method = matches
        .get_one::<SurfaceMethod>("method")
        .copied()
        .unwrap_or(SurfaceMethod::Analytic);
    kernel_inapplicable(matches, method.kernel(), |k| {
        SurfaceMethod::of(k).map(|m| format!("--method {}", m.name()))
    })
}

/// Runs `nusselt formfactors`.
pub fn run(args: FormFactorArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let progress = Progress::new(!args.common.quiet);
    let mut options = args.load.options()?;
    let settings = args
        .kernel
        .settings(args.method.kernel(), args.common.seed)?;
    options.memory_budget = settings.memory_budget;
    let scene = super::load(&args.scene, &options, &progress)?;
    let element_size = match (args.element_size, args.method) {
        (Some(h), _) if h > 0.0 && h.is_finite() => h,
        (Some(_), _) => bail!("--element-size must be positive"),
        (None, SurfaceMethod::Hemicube) => scene.diagonal() * pipeline::DEFAULT_ELEMENT_FRACTION,
        (None, _) => f64::INFINITY,
    };
    let mesh = nusselt::classic::uniform::UniformMesh::within_budget(
        &scene,
        element_size,
        settings.memory_budget,
        "with their dense matrix",
        FormFactorMatrix::bytes_for_count,
    )?;
    let bvh = TriangleBvh::of_scene(&scene);
    let (matrix, stats, errors) =
        FormFactorMatrix::assemble_with_errors(&mesh, &bvh, &settings, &progress)?;
    let errors = stats.max_error.is_some().then_some(errors.as_slice());
    let pairs = nusselt::classic::surfaces::surface_form_factors(&scene, &mesh, &matrix, errors);
    let out = csv::encode(
        &[
            "from",
            "to",
            "form_factor",
            "reverse",
            "reciprocity_error",
            "row_sum",
            "error",
        ],
        pairs.iter().map(|p| PairRow {
            from: &p.from,
            to: &p.to,
            form_factor: p.form_factor,
            reverse: p.reverse,
            reciprocity_error: p.reciprocity_error,
            row_sum: p.row_sum,
            error: p.error,
        }),
    )?;
    std::io::stdout()
        .write_all(&out)
        .context("writing the form factors to stdout")?;
    for w in &scene.warnings {
        super::warn(w);
    }
    Ok(())
}
