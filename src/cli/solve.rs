//! `nusselt solve`: load, solve, write the outputs, print a summary.
//!
//! Invariant: every setting is checked before the scene is loaded, and
//! outputs are written only after the whole solve succeeded.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;

use clap::ArgMatches;
use nusselt::classic::matrix::Kernel;
use nusselt::classic::solve::Convergence;
use nusselt::hierarchical::HierarchicalSettings;
use nusselt::meshing::{MeshMode, MeshSettings};
use nusselt::pipeline::{self, Method, SolveSettings};
use nusselt::render::RenderSettings;
use nusselt::util::progress::Progress;

use super::args::{
    Common, HierarchicalArgs, HierarchicalExtras, KernelArgs, LoadArgs, SkyArgs, ViewArgs,
    at_least_one, flags_apply, given, kernel_inapplicable,
};
use super::{checked, init_threads};

#[derive(Args, Debug)]
pub struct SolveArgs {
    /// The scene: .gltf or .glb.
    scene: PathBuf,
    /// Output folder (default: out/<scene stem>).
    #[arg(short, long, value_name = "DIR")]
    output: Option<PathBuf>,
    /// Solver: hierarchical (adaptive elements and links, the default), or
    /// a classic solver on a uniform mesh with a dense matrix.
    #[arg(long, value_enum, default_value_t = Method::Hierarchical)]
    method: Method,
    /// Gathering: stop when a sweep changes no radiosity by more than this
    /// fraction of the largest. Shooting: stop when the unshot power is below
    /// this fraction of the emitted power. Hierarchical: stop the final
    /// gathering when an iteration changes the reflected power, summed
    /// element by element, by less than this fraction of the total power
    /// Σ B·A (the rounds before it stop at 1e-4 or this, whichever is
    /// looser).
    #[arg(
        hide_short_help = true,
        help_heading = "Accuracy",
        long,
        default_value_t = 1e-6
    )]
    tolerance: f64,
    /// Iteration budget: sweeps (gathering, per round for hierarchical) or
    /// shots (shooting).
    #[arg(
        hide_short_help = true,
        help_heading = "Accuracy",
        long,
        default_value_t = 1_000_000,
        value_parser = at_least_one::<usize>
    )]
    max_iterations: usize,
    #[command(flatten)]
    hierarchical: HierarchicalArgs,
    /// Hierarchical: refine only as much as the view (the scene's camera or
    /// the view flags) needs: link errors count by the importance of their
    /// receiver, seen directly or reflecting toward what is seen
    /// (Smits, Arvo and Salesin 1992). The report's `importance` says it
    /// was used.
    #[arg(help_heading = "Hierarchical", long)]
    importance: bool,
    /// Classic methods: largest element edge in metres (default: 1/25 of the
    /// scene diagonal). Refused with hierarchical, which sizes its elements
    /// itself.
    #[arg(help_heading = "Classic methods", long)]
    element_size: Option<f64>,
    /// Classic methods: the form-factor kernel.
    #[arg(help_heading = "Kernel", long, value_enum, default_value_t = Kernel::PointPolygon)]
    kernel: Kernel,
    #[command(flatten)]
    kernel_args: KernelArgs,
    /// Hierarchical: the output mesh's vertices: a regular grid, the
    /// hierarchy's leaf corners, or the leaf corners plus the shadow
    /// discontinuities as constraint edges, with output adaptivity (the
    /// default).
    #[arg(help_heading = "Output", long, value_enum)]
    mesh: Option<MeshMode>,
    /// Discontinuity mesh: largest relative difference between a triangle's
    /// interpolated and point-evaluated centroid value before a vertex is
    /// added there (0 turns output adaptivity off).
    #[arg(hide_short_help = true, help_heading = "Output", long, default_value_t = MeshSettings::default().adapt_tol)]
    adapt_tol: f64,
    /// Uniform mesh: vertices aimed at (default: as many as the hierarchy
    /// has leaves).
    #[arg(hide_short_help = true, help_heading = "Output", long)]
    uniform_vertices: Option<usize>,
    /// Also write lightmap atlases RES texels square: lightmap-B.exr
    /// (radiosity), lightmap-H.exr (irradiance), lightmap.png (display),
    /// over the input's TEXCOORD_1 or generated charts; the bake gets them
    /// as TEXCOORD_1 and an emissive texture.
    #[arg(help_heading = "Output", long, value_name = "RES")]
    lightmap: Option<u32>,
    /// Write the bake as one binary glTF, baked.glb, instead of
    /// baked.gltf + baked.bin.
    #[arg(help_heading = "Output", long)]
    glb: bool,
    /// Display exposure of render.png and the bake's COLOR_0 (default: the
    /// solution's own, the same for any view; the report records it).
    #[arg(help_heading = "Output", long)]
    exposure: Option<f32>,
    /// Draw the output mesh's edges over render.png (render.exr stays
    /// clean).
    #[arg(help_heading = "Output", long)]
    wireframe: bool,
    /// Render snapshots after these iterations, e.g. 1,2,24,100.
    #[arg(help_heading = "Output", long, value_delimiter = ',')]
    snapshots: Vec<usize>,
    #[command(flatten)]
    load: LoadArgs,
    #[command(flatten)]
    sky: SkyArgs,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    common: Common,
}

impl SolveArgs {
    /// The settings of the solve, checked.
    fn settings(&self) -> Result<SolveSettings> {
        let matrix = self.kernel_args.settings(self.kernel, self.common.seed)?;
        let hierarchical = self.hierarchical.settings(HierarchicalExtras {
            seed: self.common.seed,
            rays: self
                .kernel_args
                .visibility_rays
                .unwrap_or(HierarchicalSettings::default().visibility_rays)
                .max(1),
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            memory_budget: matrix.memory_budget,
        })?;
        let mode = self.mesh.unwrap_or(MeshMode::Discontinuity);
        if self.method != Method::Hierarchical && self.mesh.is_some_and(|m| m != MeshMode::Uniform)
        {
            bail!(
                "--mesh {} needs --method hierarchical (the classic methods use a uniform mesh)",
                mode.name()
            );
        }
        let settings = SolveSettings {
            method: self.method,
            hierarchical,
            mesh: MeshSettings {
                mode,
                uniform_vertices: self.uniform_vertices,
                adapt_tol: self.adapt_tol,
                ..MeshSettings::default()
            },
            discontinuity: Default::default(),
            element_size: self.element_size,
            matrix,
            convergence: Convergence {
                tolerance: self.tolerance,
                max_iterations: self.max_iterations,
            },
            render: RenderSettings::with_samples(self.view.spp, self.common.seed),
            view: self.view.overrides(),
            snapshots: self.snapshots.clone(),
            wireframe: self.wireframe,
            importance: self.importance,
            exposure: self.exposure,
            glb: self.glb,
            lightmap: self.lightmap,
            budget_start: None,
        };
        // Both methods' parts, whichever runs: a bad flag is an error even
        // where it does not apply.
        checked(settings.hierarchical.validate())?;
        checked(settings.mesh.validate())?;
        checked(settings.validate())?;
        Ok(settings)
    }
}

/// The flags (argument ids) only the classic methods read.
const CLASSIC_ONLY: [&str; 6] = [
    "element_size",
    "kernel",
    "sampling_tolerance",
    "quadrature_tolerance",
    "hemicube_resolution",
    "no_hemicube_rotation",
];

/// The flags (argument ids) only the hierarchical method reads.
const HIERARCHICAL_ONLY: [&str; 21] = [
    "accuracy",
    "oracle",
    "ff_eps",
    "bf_eps",
    "bf_relative_floor",
    "power_eps",
    "cluster_eps",
    "min_area",
    "gradient_tol",
    "max_links",
    "max_elements",
    "max_rounds",
    "sky_rays",
    "clustering",
    "time_budget",
    "correction_passes",
    "correction_rays",
    "correction_tolerance",
    "adapt_tol",
    "uniform_vertices",
    "importance",
];

/// The flags given on the command line that the chosen `--method` (or,
/// for a classic method, its `--kernel`) does not read, as one sentence;
/// `None` when every flag given applies.
pub fn inapplicable(matches: &ArgMatches) -> Option<String> {
    let method = matches
        .get_one::<Method>("method")
        .copied()
        .unwrap_or(Method::Hierarchical);
    let (ids, applies_to) = match method {
        Method::Hierarchical => (
            &CLASSIC_ONLY[..],
            "the classic methods (--method direct|jacobi|gauss-seidel|shooting)",
        ),
        Method::Classic(_) => (&HIERARCHICAL_ONLY[..], "--method hierarchical"),
    };
    let flags = given(matches, ids);
    if !flags.is_empty() {
        return Some(format!(
            "{} only to {applies_to}, not to --method {}",
            flags_apply(&flags),
            method.name()
        ));
    }
    match method {
        Method::Hierarchical => None,
        Method::Classic(_) => {
            let kernel = matches
                .get_one::<Kernel>("kernel")
                .copied()
                .unwrap_or(Kernel::PointPolygon);
            kernel_inapplicable(matches, kernel, |k| Some(format!("--kernel {}", k.name())))
        }
    }
}

/// Runs `nusselt solve`.
pub fn run(args: SolveArgs) -> Result<()> {
    init_threads(args.common.threads)?;
    let start = Instant::now();
    let progress = Progress::new(!args.common.quiet);
    let mut options = args.load.options_with(&args.sky)?;
    if !(args.tolerance > 0.0) {
        bail!("--tolerance must be positive");
    }
    let mut settings = args.settings()?;
    settings.budget_start = Some(start);
    // The loader's sizes (triangles after instancing, textures) are
    // checked against the same budget.
    options.memory_budget = settings.matrix.memory_budget;
    let dir = args
        .output
        .clone()
        .unwrap_or_else(|| default_folder(&args.scene));
    // Fail before working: the folder must take the files.
    nusselt::output::check_folder(&dir)?;
    let scene = super::load(&args.scene, &options, &progress)?;
    let load_time = start.elapsed().as_secs_f64();
    let mut run = pipeline::solve(&scene, &settings, &progress)
        .with_context(|| format!("solving {}", args.scene.display()))?;
    run.report.scene = args.scene.display().to_string();
    run.report.times.load = load_time;
    run.report.times.total += load_time;
    let phase = progress.spinner("write");
    pipeline::write_outputs(&dir, &mut run)?;
    drop(phase);
    for w in &run.report.warnings {
        super::warn(w);
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

/// `out/<scene stem>`.
fn default_folder(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    Path::new("out").join(stem)
}
