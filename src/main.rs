//! The `nusselt` command line.
//!
//! Owns: argument parsing (clap), the thread pool, and turning every failure
//! into one `error:` line on stderr with exit code 1 (usage errors exit 2,
//! through clap). Invariant: nothing a user can cause ends in a panic
//! message or a backtrace; an internal bug is still reported as one line.

// `!(x > y)` rejects NaN along with out-of-range values, on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};
use glam::DVec3;

use nusselt::classic::matrix::{FormFactorMatrix, Kernel, MatrixSettings};
use nusselt::classic::solve::{ClassicMethod, Convergence};
use nusselt::hierarchical::oracle::Oracle;
use nusselt::hierarchical::{Accuracy, Clustering, HierarchicalSettings, Preset};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::meshing::{MeshMode, MeshSettings};
use nusselt::output::OutputSet;
use nusselt::pipeline::{self, SolveSettings};
use nusselt::reference::{self, ReferenceSettings};
use nusselt::render::RenderSettings;
use nusselt::render::view::{View, ViewOverrides};
use nusselt::report::Report;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

#[derive(Parser, Debug)]
#[command(
    name = "nusselt",
    version,
    about = "Radiosity for glTF scenes of diffuse surfaces"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Solve a scene and write solution.exr, baked.gltf, render.exr/png and report.json.
    Solve(Box<SolveArgs>),
    /// Render a new view of an earlier solution without solving again.
    Render(RenderArgs),
    /// Form factors between the scene's surfaces (glTF nodes), as CSV on stdout.
    Formfactors(FormFactorArgs),
    /// Compare an image with a reference: metrics as JSON on stdout, error images with -o.
    Compare(CompareArgs),
    /// Convergence charts (SVG and PNG) from the report.json of one or more solves.
    Chart(ChartArgs),
    /// Path-trace an independent reference image of the same view, with a
    /// per-pixel noise image and a JSON sidecar.
    Reference(ReferenceArgs),
    /// Sweep methods and settings against a path-traced reference: results.csv, charts, contact sheet.
    Study(StudyArgs),
}

#[derive(Args, Debug)]
struct StudyArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// Output folder (the reference is cached here).
    #[arg(short, long)]
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

#[derive(Args, Debug)]
struct CompareArgs {
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

#[derive(Args, Debug)]
struct ChartArgs {
    /// report.json files written by `nusselt solve`.
    #[arg(required = true)]
    reports: Vec<PathBuf>,
    /// Output folder for residual-iterations.svg/.png and residual-time.svg/.png.
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Args, Debug)]
struct Common {
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of every random choice; the same seed gives the same output.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// No progress bars and no summary line.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Args, Debug)]
struct ViewArgs {
    /// Image width in pixels.
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels.
    #[arg(long)]
    height: Option<u32>,
    /// Camera position X,Y,Z (metres).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    eye: Option<DVec3>,
    /// Point the camera looks at, X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    target: Option<DVec3>,
    /// Up direction X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    up: Option<DVec3>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    fov: Option<f64>,
    /// Samples per pixel (`solve`, `render`: stratified, rounded up to a
    /// square; `reference`: independent paths, at least 2).
    #[arg(long, default_value_t = 16)]
    spp: u32,
}

impl ViewArgs {
    fn overrides(&self) -> ViewOverrides {
        ViewOverrides {
            eye: self.eye,
            target: self.target,
            up: self.up,
            fov_deg: self.fov,
            width: self.width,
            height: self.height,
        }
    }
}

#[derive(Args, Debug)]
struct SolveArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// Output folder (default: out/<scene stem>).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Solver: hierarchical (adaptive elements and links, the default), or
    /// a classic solver on a uniform mesh with a dense matrix.
    #[arg(long, value_enum, default_value_t = Method::Hierarchical)]
    method: Method,
    /// Classic methods: largest element edge in metres (default: 1/25 of the
    /// scene diagonal). Ignored by hierarchical, which sizes its elements
    /// itself.
    #[arg(long)]
    element_size: Option<f64>,
    #[command(flatten)]
    hierarchical: HierarchicalArgs,
    /// Hierarchical: the output mesh's vertices: a regular grid, the
    /// hierarchy's leaf corners, or the leaf corners plus the shadow
    /// discontinuities as constraint edges, with output adaptivity (the
    /// default).
    #[arg(long, value_enum)]
    mesh: Option<MeshName>,
    /// Discontinuity mesh: largest relative difference between a triangle's
    /// interpolated and point-evaluated centroid value before a vertex is
    /// added there (0 turns output adaptivity off).
    #[arg(long, default_value_t = MeshSettings::default().adapt_tol)]
    adapt_tol: f64,
    /// Uniform mesh: vertices aimed at (default: as many as the hierarchy
    /// has leaves).
    #[arg(long)]
    uniform_vertices: Option<usize>,
    /// Draw the output mesh's edges over render.png (render.exr stays
    /// clean).
    #[arg(long)]
    wireframe: bool,
    /// Hierarchical: refine only as much as the view (the scene's camera or
    /// the view flags) needs: link errors count by the importance of their
    /// receiver, seen directly or reflecting toward what is seen
    /// [SAS92]. The report's `importance` says it was used.
    #[arg(long)]
    importance: bool,
    #[command(flatten)]
    kernel: KernelArgs,
    /// Gathering: stop when a sweep changes no radiosity by more than this
    /// fraction of the largest. Shooting: stop when the unshot power is below
    /// this fraction of the emitted power. Hierarchical: stop each round's
    /// gathering when the total power Σ B·A changes by less than this
    /// fraction.
    #[arg(long, default_value_t = 1e-6)]
    tolerance: f64,
    /// Iteration budget: sweeps (gathering, per round for hierarchical) or
    /// shots (shooting).
    #[arg(long, default_value_t = 1_000_000)]
    max_iterations: usize,
    /// Render snapshots after these iterations, e.g. 1,2,24,100.
    #[arg(long, value_delimiter = ',')]
    snapshots: Vec<usize>,
    /// Reflectances at or above this are clamped to it.
    #[arg(long, default_value_t = 0.999)]
    max_reflectance: f64,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    common: Common,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum Method {
    /// Hierarchical radiosity [HSA91]: quadtrees, links, oracle refinement.
    Hierarchical,
    /// LU factorisation of the full system (Gaussian elimination).
    Direct,
    /// Jacobi gathering.
    Jacobi,
    /// Gauss-Seidel gathering.
    GaussSeidel,
    /// Southwell shooting / progressive refinement.
    Shooting,
}

impl Method {
    fn method(self) -> pipeline::Method {
        let classic = |m| pipeline::Method::Classic(m);
        match self {
            Method::Hierarchical => pipeline::Method::Hierarchical,
            Method::Direct => classic(ClassicMethod::Direct),
            Method::Jacobi => classic(ClassicMethod::Jacobi),
            Method::GaussSeidel => classic(ClassicMethod::GaussSeidel),
            Method::Shooting => classic(ClassicMethod::Shooting),
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum MeshName {
    /// A regular grid, blind to the lighting.
    Uniform,
    /// The corners of the hierarchy's leaves.
    Quadtree,
    /// Leaf corners and shadow discontinuities, with output adaptivity.
    Discontinuity,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum AccuracyName {
    /// Coarse: a quick look.
    Preview,
    /// Soft shadows resolved at interactive cost.
    Default,
    /// Finer elements and links for final images.
    High,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum OracleName {
    /// Form factor above --ff-eps [HSA91].
    Ff,
    /// Brightness-weighted error above --bf-eps (partly visible links first).
    Bf,
    /// Transported power above --power-eps.
    Power,
}

/// The hierarchical method's accuracy: one preset, and expert overrides of
/// each of its thresholds.
#[derive(Args, Debug)]
struct HierarchicalArgs {
    /// Accuracy preset of the hierarchical method; the flags below override
    /// single thresholds.
    #[arg(long, value_enum, default_value_t = AccuracyName::Default)]
    accuracy: AccuracyName,
    /// Refinement oracle of the hierarchical method.
    #[arg(long, value_enum, default_value_t = OracleName::Bf)]
    oracle: OracleName,
    /// ff oracle: largest form factor a link may keep.
    #[arg(long)]
    ff_eps: Option<f64>,
    /// bf oracle: largest ρ·B·(form-factor and visibility error) a link may
    /// keep, as a fraction of the mean emitted exitance.
    #[arg(long)]
    bf_eps: Option<f64>,
    /// power oracle: largest power a link may carry, as a fraction of the
    /// largest patch emitted power.
    #[arg(long)]
    power_eps: Option<f64>,
    /// Cluster oracle: largest ρ·(irradiance error) a link with a cluster
    /// at one end may keep, as a fraction of the mean emitted exitance.
    #[arg(long)]
    cluster_eps: Option<f64>,
    /// Smallest element, as a fraction of the total surface area.
    #[arg(long)]
    min_area: Option<f64>,
    /// Split leaves whose radiosity differs from a sibling's by more than
    /// this fraction of the mean emitted exitance (0 disables).
    #[arg(long)]
    gradient_tol: Option<f64>,
    /// Link budget: no split takes the link count past N; refinement stops
    /// there (the report says so).
    #[arg(long, value_name = "N")]
    max_links: Option<f64>,
    /// Element budget: no split takes the hierarchy past N elements;
    /// refinement stops there (the report says so).
    #[arg(long, value_name = "N")]
    max_elements: Option<f64>,
    /// Refinement rounds (refine + solve) at most.
    #[arg(long)]
    max_rounds: Option<usize>,
    /// Start the links from a cluster hierarchy above the patches (no
    /// step over every pair of patches); auto clusters scenes of 1,000
    /// patches or more.
    #[arg(long, value_enum, default_value_t = ClusteringName::Auto)]
    clustering: ClusteringName,
    /// Seconds of linking and refinement after which the links as they are
    /// get solved (the report says so); results then depend on the
    /// machine's speed.
    #[arg(long, value_name = "SECONDS")]
    time_budget: Option<f64>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum ClusteringName {
    Auto,
    On,
    Off,
}

impl HierarchicalArgs {
    fn settings(
        &self,
        seed: u64,
        rays: usize,
        tolerance: f64,
        max_iterations: usize,
        memory_budget: u64,
    ) -> Result<HierarchicalSettings> {
        let mut a = Accuracy::preset(match self.accuracy {
            AccuracyName::Preview => Preset::Preview,
            AccuracyName::Default => Preset::Default,
            AccuracyName::High => Preset::High,
        });
        let positive = |name: &str, v: Option<f64>, slot: &mut f64| -> Result<()> {
            if let Some(v) = v {
                if !(v > 0.0 && v.is_finite()) {
                    bail!("--{name} must be a positive number");
                }
                *slot = v;
            }
            Ok(())
        };
        // A budget: a whole number from 1 to 2^53 (exact in an f64).
        let count = |name: &str, v: Option<f64>| -> Result<Option<u64>> {
            match v {
                Some(v) if !((1.0..=9_007_199_254_740_992.0).contains(&v) && v.fract() == 0.0) => {
                    bail!("--{name} must be a whole number of at least 1, not {v}")
                }
                v => Ok(v.map(|v| v as u64)),
            }
        };
        positive("ff-eps", self.ff_eps, &mut a.ff_eps)?;
        positive("bf-eps", self.bf_eps, &mut a.bf_eps)?;
        positive("power-eps", self.power_eps, &mut a.power_eps)?;
        positive("cluster-eps", self.cluster_eps, &mut a.cluster_eps)?;
        positive("min-area", self.min_area, &mut a.min_area)?;
        if let Some(g) = self.gradient_tol {
            if !(g >= 0.0 && g.is_finite()) {
                bail!("--gradient-tol must be zero or positive");
            }
            a.gradient_tol = g;
        }
        a.max_links = count("max-links", self.max_links)?;
        a.max_elements = count("max-elements", self.max_elements)?;
        if let Some(r) = self.max_rounds {
            if r == 0 {
                bail!("--max-rounds must be at least 1");
            }
            a.max_rounds = r;
        }
        Ok(HierarchicalSettings {
            oracle: match self.oracle {
                OracleName::Ff => Oracle::Ff,
                OracleName::Bf => Oracle::Bf,
                OracleName::Power => Oracle::Power,
            },
            accuracy: a,
            visibility_rays: rays,
            seed,
            tolerance,
            max_iterations,
            memory_budget,
            time_budget: match self.time_budget {
                Some(t) if !(t > 0.0 && t.is_finite()) => {
                    bail!("--time-budget must be a positive number of seconds")
                }
                t => t,
            },
            importance: None,
            clustering: match self.clustering {
                ClusteringName::Auto => Clustering::Auto,
                ClusteringName::On => Clustering::On,
                ClusteringName::Off => Clustering::Off,
            },
        })
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum KernelName {
    /// Analytic from the receiver's centroid, visibility by rays.
    PointPolygon,
    /// Adaptive quadrature of the analytic inner integral, visibility by rays.
    PolygonPolygon,
    /// Area sampling (stratified point pairs, one ray each).
    Sampling,
    /// Hemicube at the receiver's centroid, z-buffer visibility.
    Hemicube,
}

/// How form factors are computed.
#[derive(Args, Debug)]
struct KernelArgs {
    /// Form-factor kernel.
    #[arg(long, value_enum, default_value_t = KernelName::PointPolygon)]
    kernel: KernelName,
    /// Visibility rays per element pair (point-polygon; default 4), per
    /// quadrature point (polygon-polygon; default 4) or per link
    /// (hierarchical; default 32).
    #[arg(long)]
    visibility_rays: Option<usize>,
    /// Point pairs per element pair (sampling; default 16 for `solve`,
    /// 4096 for `formfactors`).
    #[arg(long)]
    samples: Option<usize>,
    /// Absolute tolerance of each form factor (polygon-polygon).
    #[arg(long, default_value_t = 1e-4)]
    quadrature_tolerance: f64,
    /// Hemicube top-face resolution (cells per side; even).
    #[arg(long, default_value_t = 128)]
    hemicube_resolution: u32,
    /// Do not turn each hemicube by a random angle about its normal.
    #[arg(long)]
    no_hemicube_rotation: bool,
    /// Largest dense matrix (and direct-method factorisation) allowed, in
    /// GiB; for hierarchical, the estimated memory of the elements and
    /// links, where refinement stops (the report says so).
    #[arg(long, value_name = "GIB", default_value_t = 2.0)]
    memory_budget: f64,
}

impl KernelArgs {
    fn settings(&self, seed: u64, default_samples: usize) -> Result<MatrixSettings> {
        if !(self.memory_budget > 0.0 && self.memory_budget.is_finite()) {
            bail!("--memory-budget must be a positive number of GiB");
        }
        if self.hemicube_resolution < 2
            || self.hemicube_resolution % 2 != 0
            || self.hemicube_resolution > 8192
        {
            bail!("--hemicube-resolution must be an even number from 2 to 8192");
        }
        if !(self.quadrature_tolerance > 0.0) {
            bail!("--quadrature-tolerance must be positive");
        }
        Ok(MatrixSettings {
            kernel: match self.kernel {
                KernelName::PointPolygon => Kernel::PointPolygon,
                KernelName::PolygonPolygon => Kernel::PolygonPolygon,
                KernelName::Sampling => Kernel::Sampling,
                KernelName::Hemicube => Kernel::Hemicube,
            },
            visibility_rays: self.visibility_rays.unwrap_or(4).max(1),
            samples: self.samples.unwrap_or(default_samples).max(1),
            quadrature_tolerance: self.quadrature_tolerance,
            hemicube_resolution: self.hemicube_resolution,
            hemicube_rotation: !self.no_hemicube_rotation,
            seed,
            memory_budget: (self.memory_budget * (1u64 << 30) as f64) as u64,
        })
    }
}

#[derive(Args, Debug)]
struct FormFactorArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// analytic = polygon-polygon quadrature, sampling = area sampling, hemicube.
    #[arg(long, value_enum, default_value_t = FormFactorMethod::Analytic)]
    method: FormFactorMethod,
    /// Cut surfaces into elements no larger than this (metres) before
    /// integrating; default: whole patches (analytic, sampling) or 1/25 of
    /// the scene diagonal (hemicube, which samples at element centroids).
    #[arg(long)]
    element_size: Option<f64>,
    #[command(flatten)]
    kernel: KernelArgs,
    /// Reflectances at or above this are clamped to it.
    #[arg(long, default_value_t = 0.999)]
    max_reflectance: f64,
    #[command(flatten)]
    common: Common,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum FormFactorMethod {
    Analytic,
    Sampling,
    Hemicube,
}

#[derive(Args, Debug)]
struct RenderArgs {
    /// A solution.exr written by `nusselt solve`.
    solution: PathBuf,
    /// The image to write (.exr).
    #[arg(short, long)]
    output: PathBuf,
    /// Also write a tone-mapped PNG here.
    #[arg(long)]
    png: Option<PathBuf>,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    common: Common,
}

#[derive(Args, Debug)]
struct ReferenceArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// The image to write (.exr); `<stem>.noise.exr` and `<stem>.json` go
    /// beside it.
    #[arg(short, long)]
    output: PathBuf,
    /// Also write a tone-mapped PNG here (auto exposure).
    #[arg(long)]
    png: Option<PathBuf>,
    /// Largest number of reflections per path (default: unlimited, ended by
    /// Russian roulette; never more than 10,000).
    #[arg(long)]
    max_bounces: Option<u32>,
    /// Reflectances at or above this are clamped to it (as in `solve`).
    #[arg(long, default_value_t = 0.999)]
    max_reflectance: f64,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    common: Common,
}

fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got '{s}'"));
    }
    let mut v = [0.0; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("'{p}' is not a finite number"))?;
    }
    Ok(DVec3::from_array(v))
}

fn init_threads(threads: Option<usize>) -> Result<()> {
    if let Some(n) = threads {
        if n == 0 {
            bail!("--threads must be at least 1");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("setting up the thread pool")?;
    }
    Ok(())
}

fn run_solve(args: SolveArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let start = Instant::now();
    let progress = Progress::new(!args.common.quiet);
    if !(args.max_reflectance > 0.0 && args.max_reflectance < 1.0) {
        bail!("--max-reflectance must be in (0, 1)");
    }
    if !(args.tolerance > 0.0) {
        bail!("--tolerance must be positive");
    }
    let matrix = args.kernel.settings(args.common.seed, 16)?;
    let options = LoadOptions {
        max_reflectance: args.max_reflectance,
    };
    let scene = load_scene(&args.scene, &options)?;
    let load_time = start.elapsed().as_secs_f64();
    let hierarchical = args.hierarchical.settings(
        args.common.seed,
        args.kernel
            .visibility_rays
            .unwrap_or(HierarchicalSettings::default().visibility_rays)
            .max(1),
        args.tolerance,
        args.max_iterations,
        matrix.memory_budget,
    )?;
    let mode = match args.mesh {
        None | Some(MeshName::Discontinuity) => MeshMode::Discontinuity,
        Some(MeshName::Quadtree) => MeshMode::Quadtree,
        Some(MeshName::Uniform) => MeshMode::Uniform,
    };
    if args.method != Method::Hierarchical && args.mesh.is_some_and(|m| m != MeshName::Uniform) {
        bail!(
            "--mesh {} needs --method hierarchical (the classic methods use a uniform mesh)",
            mode.name()
        );
    }
    if !(args.adapt_tol >= 0.0 && args.adapt_tol.is_finite()) {
        bail!("--adapt-tol must be zero or positive");
    }
    let settings = SolveSettings {
        method: args.method.method(),
        hierarchical,
        mesh: MeshSettings {
            mode,
            uniform_vertices: args.uniform_vertices,
            adapt_tol: args.adapt_tol,
            ..MeshSettings::default()
        },
        discontinuity: Default::default(),
        element_size: args.element_size,
        matrix,
        convergence: Convergence {
            tolerance: args.tolerance,
            max_iterations: args.max_iterations,
        },
        render: RenderSettings {
            samples_per_pixel: args.view.spp,
            seed: args.common.seed,
        },
        view: args.view.overrides(),
        snapshots: args.snapshots.clone(),
        wireframe: args.wireframe,
        importance: args.importance,
    };
    if args.importance && args.method != Method::Hierarchical {
        bail!("--importance needs --method hierarchical");
    }
    let mut run = pipeline::solve(&scene, &settings, &progress)
        .with_context(|| format!("solving {}", args.scene.display()))?;
    run.report.scene = args.scene.display().to_string();
    run.report.times.load = load_time;
    run.report.times.total += load_time;
    let dir = args.output.unwrap_or_else(|| {
        let stem = args
            .scene
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into());
        Path::new("out").join(stem)
    });
    pipeline::write_outputs(&dir, &mut run)?;
    for w in &run.report.warnings {
        eprintln!("warning: {w}");
    }
    if !args.common.quiet {
        let c = &run.report.counts;
        println!(
            "{}: {} patches, {} elements, {} iterations{}, {:.2} s → {}",
            args.scene.display(),
            c.patches,
            c.elements,
            run.report.convergence.iterations,
            if run.report.convergence.converged {
                ""
            } else {
                " (not converged)"
            },
            run.report.times.total,
            dir.display()
        );
    }
    Ok(())
}

fn run_render(args: RenderArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let progress = Progress::new(!args.common.quiet);
    let mesh = nusselt::output::exr::read_solution(&args.solution)?;
    mesh.validate()
        .map_err(|e| anyhow::anyhow!("{}: invalid solution: {e}", args.solution.display()))?;
    // The solve's report, when it sits beside the solution, gives the view.
    let report_path = args.solution.with_file_name("report.json");
    let report: Option<Report> = std::fs::read(&report_path)
        .ok()
        .and_then(|bytes| serde_json::from_slice(&bytes).ok());
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
    let settings = RenderSettings {
        samples_per_pixel: args.view.spp,
        seed: args.common.seed,
    };
    let frame = nusselt::render::render(&mesh, &view, &settings, &progress);
    nusselt::output::write_atomic(&args.output, &nusselt::output::exr::encode_image(&frame)?)?;
    if let Some(png) = &args.png {
        let exposure = report
            .map(|r| r.exposure)
            .unwrap_or_else(|| pipeline::frame_exposure(&frame));
        nusselt::output::write_atomic(png, &nusselt::output::png::encode_png(&frame, exposure)?)?;
    }
    Ok(())
}

fn run_formfactors(args: FormFactorArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let progress = Progress::new(!args.common.quiet);
    if !(args.max_reflectance > 0.0 && args.max_reflectance < 1.0) {
        bail!("--max-reflectance must be in (0, 1)");
    }
    let options = LoadOptions {
        max_reflectance: args.max_reflectance,
    };
    let scene = load_scene(&args.scene, &options)?;
    let mut settings = args.kernel.settings(args.common.seed, 4096)?;
    settings.kernel = match args.method {
        FormFactorMethod::Analytic => Kernel::PolygonPolygon,
        FormFactorMethod::Sampling => Kernel::Sampling,
        FormFactorMethod::Hemicube => Kernel::Hemicube,
    };
    let element_size = match (args.element_size, args.method) {
        (Some(h), _) if h > 0.0 && h.is_finite() => h,
        (Some(_), _) => bail!("--element-size must be positive"),
        (None, FormFactorMethod::Hemicube) => scene.diagonal() * pipeline::DEFAULT_ELEMENT_FRACTION,
        (None, _) => f64::INFINITY,
    };
    let mesh = nusselt::classic::uniform::UniformMesh::new(&scene, element_size);
    let bvh = TriangleBvh::of_scene(&scene);
    let (matrix, _) = FormFactorMatrix::assemble(&mesh, &bvh, &settings, &progress)?;
    let pairs = nusselt::classic::surfaces::surface_form_factors(&scene, &mesh, &matrix);
    let mut out = String::from("from,to,form_factor,reverse,reciprocity_error,row_sum\n");
    for p in &pairs {
        out.push_str(&format!(
            "{},{},{:.9},{:.9},{:.3e},{:.9}\n",
            csv_field(&p.from),
            csv_field(&p.to),
            p.form_factor,
            p.reverse,
            p.reciprocity_error,
            p.row_sum
        ));
    }
    print!("{out}");
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

fn run_compare(args: CompareArgs) -> Result<()> {
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

fn run_chart(args: ChartArgs) -> Result<()> {
    let runs = args
        .reports
        .iter()
        .map(|p| nusselt::lab::convergence::read_convergence(p))
        .collect::<nusselt::Result<Vec<_>>>()?;
    let charts = nusselt::lab::convergence::convergence_charts(&runs)?;
    let mut set = OutputSet::create(&args.output)?;
    for chart in &charts {
        set.stage(&format!("{}.svg", chart.stem), chart.images.svg.as_bytes())?;
        set.stage(&format!("{}.png", chart.stem), &chart.images.png)?;
    }
    set.commit()?;
    for chart in &charts {
        if chart.images.skipped_points > 0 {
            eprintln!(
                "warning: {}: {} points with a zero or negative value were left off the log axes",
                chart.stem, chart.images.skipped_points
            );
        }
    }
    Ok(())
}

fn run_reference(args: ReferenceArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let progress = Progress::new(!args.common.quiet);
    if !(args.max_reflectance > 0.0 && args.max_reflectance < 1.0) {
        bail!("--max-reflectance must be in (0, 1)");
    }
    if args.view.spp < 2 {
        bail!("--spp must be at least 2 for the reference's noise estimate");
    }
    let options = LoadOptions {
        max_reflectance: args.max_reflectance,
    };
    let scene = load_scene(&args.scene, &options)?;
    let view = View::resolve(scene.cameras.first(), scene.bounds, &args.view.overrides())?;
    let settings = ReferenceSettings {
        samples_per_pixel: args.view.spp,
        seed: args.common.seed,
        max_bounces: args.max_bounces,
    };
    let mut result = reference::render_reference(&scene, &view, &settings, &progress)
        .with_context(|| format!("path tracing {}", args.scene.display()))?;
    result.stats.scene = args.scene.display().to_string();
    let image = nusselt::output::exr::encode_image(&result.image)?;
    let noise = nusselt::output::exr::encode_image(&result.noise)?;
    let stats = nusselt::output::write_json(&result.stats)?;
    let png = match &args.png {
        Some(path) => {
            let exposure = nusselt::output::png::auto_exposure(
                result
                    .image
                    .pixels
                    .iter()
                    .map(|&p| nusselt::output::png::luminance(p)),
            );
            Some((
                path,
                nusselt::output::png::encode_png(&result.image, exposure)?,
            ))
        }
        None => None,
    };
    // The image last: when it is there, its sidecars are complete.
    nusselt::output::write_atomic(&reference::noise_path(&args.output), &noise)?;
    nusselt::output::write_atomic(&reference::stats_path(&args.output), &stats)?;
    nusselt::output::write_atomic(&args.output, &image)?;
    if let Some((path, bytes)) = png {
        nusselt::output::write_atomic(path, &bytes)?;
    }
    for w in &scene.warnings {
        eprintln!("warning: {w}");
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

fn run_study(args: StudyArgs) -> Result<()> {
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

/// Quotes a CSV field when it needs it.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn main() -> ExitCode {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "error: internal error (a bug in nusselt): {}{at}",
            msg.replace('\n', " ")
        );
    }));
    let cli = Cli::parse();
    let result = std::panic::catch_unwind(|| match cli.command {
        Command::Solve(args) => run_solve(*args),
        Command::Render(args) => run_render(args),
        Command::Formfactors(args) => run_formfactors(args),
        Command::Compare(args) => run_compare(args),
        Command::Chart(args) => run_chart(args),
        Command::Reference(args) => run_reference(args),
        Command::Study(args) => run_study(args),
    });
    match result {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(err)) => {
            eprintln!("error: {}", format!("{err:#}").replace('\n', " "));
            ExitCode::from(1)
        }
        Err(_) => ExitCode::from(1),
    }
}
