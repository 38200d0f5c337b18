//! The `solve` job end to end: scene → solution → output mesh → image,
//! with a report; and writing its outputs.
//!
//! Owns: [`SolveSettings`], [`SolveRun`], the order of the phases and
//! their timing (`hierarchical` and `classic` hold one path each).
//! Each phase lives in its own module; this one only wires them together.
//!
//! Invariant: [`solve`] does no IO; [`write_outputs`] only encodes what the
//! run computed (the wireframe overlay included) and stages every file,
//! renaming them only when all were written, so a failed run leaves
//! earlier outputs intact.

mod classic;
mod hierarchical;

pub use hierarchical::view_importance;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::classic::matrix::MatrixSettings;
use crate::classic::solve::{ClassicMethod, Convergence};
use crate::discontinuity::DiscontinuitySettings;
use crate::error::{Error, Result};
use crate::hierarchical::HierarchicalSettings;
use crate::lightmap::Lightmap;
use crate::mesh::OutputMesh;
use crate::meshing::MeshSettings;
use crate::output::baked::BakeLayout;
use crate::output::exr::{ImageInfo, Quantity};
use crate::output::{self, OutputSet};
use crate::render::RenderSettings;
use crate::render::frame::Frame;
use crate::render::view::{FRAME_BYTES_PER_PIXEL, View, ViewOverrides};
use crate::render::wireframe;
use crate::report::{ConvergenceReport, FileRecord, HistoryEntry, Report};
use crate::scene::Scene;
use crate::util::progress::Progress;

/// Default element size as a fraction of the scene diagonal.
pub const DEFAULT_ELEMENT_FRACTION: f64 = 1.0 / 25.0;

/// How a scene is solved: hierarchically (the default), or by a classic
/// solver on a uniform mesh with a dense matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Hierarchical radiosity: quadtrees, links, oracle refinement.
    Hierarchical,
    /// A classic solver on a uniform mesh with a dense matrix.
    Classic(ClassicMethod),
}

impl Method {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Method::Hierarchical => "hierarchical",
            Method::Classic(m) => m.name(),
        }
    }
}

/// `--method`: parsed and listed from the names of [`Method::name`].
impl clap::ValueEnum for Method {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            Method::Hierarchical,
            Method::Classic(ClassicMethod::Direct),
            Method::Classic(ClassicMethod::Jacobi),
            Method::Classic(ClassicMethod::GaussSeidel),
            Method::Classic(ClassicMethod::Shooting),
        ]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        let help = match self {
            Method::Hierarchical => {
                "Hierarchical radiosity [HSA91]: quadtrees, links, oracle refinement"
            }
            Method::Classic(ClassicMethod::Direct) => {
                "LU factorisation of the full system (Gaussian elimination)"
            }
            Method::Classic(ClassicMethod::Jacobi) => "Jacobi gathering",
            Method::Classic(ClassicMethod::GaussSeidel) => "Gauss-Seidel gathering",
            Method::Classic(ClassicMethod::Shooting) => {
                "Southwell shooting / progressive refinement"
            }
        };
        Some(clap::builder::PossibleValue::new(self.name()).help(help))
    }
}

/// Everything `nusselt solve` can be told.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveSettings {
    /// The solver.
    pub method: Method,
    /// Thresholds, oracle and rays of the hierarchical method.
    pub hierarchical: HierarchicalSettings,
    /// Hierarchical: the output mesh's mode and adaptivity.
    pub mesh: MeshSettings,
    /// Hierarchical, discontinuity mesh: which segments are traced.
    pub discontinuity: DiscontinuitySettings,
    /// Classic methods: largest element edge in metres; `None` =
    /// [`DEFAULT_ELEMENT_FRACTION`] of the scene diagonal.
    pub element_size: Option<f64>,
    /// Form-factor kernel, rays, seed and memory budget.
    pub matrix: MatrixSettings,
    /// Classic methods: when the iterative solvers stop.
    pub convergence: Convergence,
    /// Samples per pixel and seed of the renders.
    pub render: RenderSettings,
    /// The view of the main render, over the scene's camera.
    pub view: ViewOverrides,
    /// Iterations after which to render a snapshot.
    pub snapshots: Vec<usize>,
    /// Draw the output mesh's edges over `render.png` (not `render.exr`).
    pub wireframe: bool,
    /// Hierarchical: weigh refinement by the importance of the solve's view
    /// ([`view_importance`]).
    pub importance: bool,
    /// The display exposure of the PNGs and the bake's `COLOR_0`; `None`:
    /// the solution's own ([`output::png::solution_exposure`]).
    pub exposure: Option<f32>,
    /// Bake into one `baked.glb` ([`SolveRun::glb`]).
    pub glb: bool,
    /// Lightmap atlases of this side in texels ([`Lightmap`]).
    pub lightmap: Option<u32>,
    /// When `--time-budget`'s clock started: the command's start, so that
    /// loading the scene counts too. `None`: when [`solve`] starts.
    pub budget_start: Option<Instant>,
}

impl SolveSettings {
    /// Refuses, before any work, a solve whose images would not fit
    /// `memory_budget`: the render of `view`, the snapshots (a frame
    /// each) and the lightmap atlases.
    pub fn check_image_memory(&self, view: &View, memory_budget: u64) -> Result<()> {
        let mut more = Vec::new();
        let mut snapshots = self.snapshots.clone();
        snapshots.sort_unstable();
        snapshots.dedup();
        if !snapshots.is_empty() {
            more.push((
                format!("its {} snapshots (--snapshots)", snapshots.len()),
                (snapshots.len() as u64)
                    .saturating_mul(view.pixels())
                    .saturating_mul(FRAME_BYTES_PER_PIXEL),
            ));
        }
        if let Some(resolution) = self.lightmap {
            more.push((
                format!("the lightmaps (--lightmap {resolution})"),
                u64::from(resolution).pow(2) * crate::lightmap::BYTES_PER_TEXEL,
            ));
        }
        view.check_memory(&self.view, &more, memory_budget)
    }

    /// Checks every part the method uses (its thresholds, kernel, mesh and
    /// convergence settings) and that the options fit the method. The
    /// error names the command-line option.
    pub fn validate(&self) -> Result<()> {
        check_exposure(self.exposure)?;
        if let Some(resolution) = self.lightmap {
            crate::lightmap::check_resolution(resolution)?;
        }
        match self.method {
            Method::Hierarchical => {
                self.hierarchical.validate()?;
                self.mesh.validate()?;
            }
            Method::Classic(_) => {
                self.matrix.validate()?;
                if !(self.convergence.tolerance > 0.0) {
                    return Err(Error::Setting("--tolerance must be positive".into()));
                }
                if let Some(h) = self.element_size
                    && !(h > 0.0 && h.is_finite())
                {
                    return Err(Error::Setting(format!("element size {h} must be positive")));
                }
                if self.importance {
                    return Err(Error::Setting(
                        "--importance needs --method hierarchical".into(),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl Default for SolveSettings {
    fn default() -> Self {
        SolveSettings {
            method: Method::Hierarchical,
            hierarchical: HierarchicalSettings::default(),
            mesh: MeshSettings::default(),
            discontinuity: DiscontinuitySettings::default(),
            element_size: None,
            matrix: MatrixSettings::default(),
            convergence: Convergence::default(),
            render: RenderSettings::default(),
            view: ViewOverrides::default(),
            snapshots: Vec::new(),
            wireframe: false,
            importance: false,
            exposure: None,
            glb: false,
            lightmap: None,
            budget_start: None,
        }
    }
}

/// The results of a solve, ready to be written.
#[derive(Clone, Debug)]
pub struct SolveRun {
    /// The output mesh with its per-vertex radiosity.
    pub mesh: OutputMesh,
    /// The main render.
    pub frame: Frame,
    /// With `--wireframe`: the coverage of the mesh's visible edges per
    /// pixel of `frame`, drawn over `render.png`.
    pub wireframe: Option<Vec<f32>>,
    /// Renders after the requested iterations (the final state for those
    /// past the last iteration).
    pub snapshots: Vec<(usize, Frame)>,
    /// Everything `report.json` says.
    pub report: Report,
    /// Write the bake as one `baked.glb` instead of `baked.gltf` +
    /// `baked.bin`.
    pub glb: bool,
    /// Where the mesh's vertices go in the bake (the scene's nodes).
    pub bake: BakeLayout,
    /// With `--lightmap`: the atlases (their coordinates are in `bake`).
    pub lightmap: Option<Lightmap>,
}

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// Solves `scene` with the method of `settings` and renders the default
/// view (and the requested snapshots). `report.times.load` and
/// `report.scene` are left for the caller.
pub fn solve(scene: &Scene, settings: &SolveSettings, progress: &Progress) -> Result<SolveRun> {
    settings.validate()?;
    match settings.method {
        Method::Hierarchical => hierarchical::solve(scene, settings, progress),
        Method::Classic(method) => classic::solve(scene, settings, method, progress),
    }
}

/// The report every run starts from: version, method, threads and the
/// scene's warnings.
fn new_report(scene: &Scene, settings: &SolveSettings) -> Report {
    Report {
        schema_version: crate::report::SCHEMA_VERSION,
        nusselt_version: env!("CARGO_PKG_VERSION").to_string(),
        method: settings.method.name().into(),
        threads: rayon::current_num_threads(),
        warnings: scene.warnings.clone(),
        ..Report::default()
    }
}

/// How an iterative solve ended, for the report.
fn convergence_report<'a>(
    converged: bool,
    tolerance: f64,
    history: impl ExactSizeIterator<Item = (usize, f64, f64)> + 'a,
) -> ConvergenceReport {
    ConvergenceReport {
        converged,
        iterations: history.len(),
        tolerance,
        history: history
            .map(|(iteration, residual, seconds)| HistoryEntry {
                iteration,
                residual,
                seconds,
            })
            .collect(),
        rounds: Vec::new(),
        rounds_exhausted: None,
    }
}

/// The common end of every solve, right after the main render: the
/// wireframe overlay (when asked for), exposure, view, the bake's layout on
/// the scene's nodes, the lightmap (when asked for) and total time.
#[allow(clippy::too_many_arguments)]
fn finish(
    scene: &Scene,
    mut report: Report,
    view: View,
    mesh: OutputMesh,
    frame: Frame,
    snapshots: Vec<(usize, Frame)>,
    start: Instant,
    settings: &SolveSettings,
    progress: &Progress,
) -> Result<SolveRun> {
    let t = Instant::now();
    let overlay = settings
        .wireframe
        .then(|| wireframe::wireframe_mask(&mesh, &view));
    report.times.render += secs(t);
    report.exposure = settings
        .exposure
        .unwrap_or_else(|| output::png::solution_exposure(&mesh));
    report.view = Some(view);
    let mut bake = BakeLayout::of_scene(scene, &mesh)?;
    let lightmap = match settings.lightmap {
        Some(resolution) => {
            let t = Instant::now();
            let _phase = progress.spinner("lightmap");
            let lightmap = Lightmap::build(scene, &mesh, resolution)?;
            bake.set_lightmap(
                lightmap.uv.clone(),
                output::png::encode_png(&lightmap.display(), report.exposure)?,
            );
            report.lightmap = Some(lightmap.stats.clone());
            report.times.lightmap = Some(secs(t));
            Some(lightmap)
        }
        None => None,
    };
    report.times.total = secs(start);
    Ok(SolveRun {
        mesh,
        frame,
        wireframe: overlay,
        snapshots,
        report,
        glb: settings.glb,
        bake,
        lightmap,
    })
}

/// `--exposure`: positive and finite when given.
pub fn check_exposure(exposure: Option<f32>) -> Result<()> {
    match exposure {
        Some(e) if !(e > 0.0 && e.is_finite()) => Err(Error::Setting(format!(
            "--exposure {e} must be positive and finite"
        ))),
        _ => Ok(()),
    }
}

/// The display exposure of an image without a solution (a reference),
/// chosen from its pixels: a small bright emitter clips, the rest is well
/// exposed. A solve's PNGs and bake use the solution's own
/// ([`output::png::solution_exposure`]) or `--exposure`.
pub fn frame_exposure(frame: &Frame) -> f32 {
    output::png::auto_exposure(frame.pixels.iter().map(|p| output::png::luminance(*p)))
}

/// Every name `solve` may write into its folder: a run removes those of an
/// earlier run that it does not write itself (snapshots, lightmaps, the
/// other form of the bake), so that they never stay beside its result.
pub const SOLVE_OUTPUTS: &[&str] = &[
    "solution.exr",
    "baked.gltf",
    "baked.bin",
    "baked.glb",
    "lightmap-B.exr",
    "lightmap-H.exr",
    "lightmap.png",
    "render.exr",
    "render.png",
    "snapshot-*.exr",
    "snapshot-*.png",
    "report.json",
];

/// A run's files as they are staged: each one also listed in the report.
struct Staging<'a> {
    set: OutputSet,
    files: &'a mut Vec<FileRecord>,
}

impl Staging<'_> {
    fn stage(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        self.set.stage(name, bytes)?;
        self.files.push(FileRecord::of(name, bytes));
        Ok(())
    }
}

/// Writes the five outputs of the contract (the bake as `baked.gltf` +
/// `baked.bin`, or `baked.glb`), and any snapshots and lightmaps, into
/// `dir` as one result set ([`OutputSet`]): `report.json` last, listing the
/// others ([`Report::files`]); an earlier run's [`SOLVE_OUTPUTS`] that this
/// run does not write are removed. Fills `report.times.write` before
/// writing the report.
pub fn write_outputs(dir: &Path, run: &mut SolveRun) -> Result<Vec<PathBuf>> {
    let t = Instant::now();
    let mut files = Vec::new();
    let mut set = Staging {
        set: OutputSet::create(dir)?.replacing(SOLVE_OUTPUTS),
        files: &mut files,
    };
    let exposure = run.report.exposure;
    let scene = run.report.scene.as_str();
    let info = |quantity| ImageInfo::new(quantity).scene(scene);
    let view_info = info(Quantity::Radiance)
        .view(run.report.view.as_ref())
        .exposure(Some(exposure));
    set.stage(
        "solution.exr",
        &output::exr::encode_solution(&run.mesh, scene)?,
    )?;
    if run.glb {
        set.stage(
            "baked.glb",
            &output::baked::encode_baked_glb(&run.mesh, &run.bake, exposure)?,
        )?;
    } else {
        let (gltf, bin) =
            output::baked::encode_baked_gltf(&run.mesh, &run.bake, exposure, "baked.bin")?;
        set.stage("baked.bin", &bin)?;
        set.stage("baked.gltf", &gltf)?;
    }
    if let Some(lightmap) = &run.lightmap {
        set.stage(
            "lightmap-B.exr",
            &output::exr::encode_image(&lightmap.radiosity, &info(Quantity::Radiosity))?,
        )?;
        set.stage(
            "lightmap-H.exr",
            &output::exr::encode_image(&lightmap.irradiance, &info(Quantity::Irradiance))?,
        )?;
        set.stage("lightmap.png", run.bake.lightmap_png().unwrap_or_default())?;
    }
    set.stage(
        "render.exr",
        &output::exr::encode_image(&run.frame, &view_info)?,
    )?;
    let png = match &run.wireframe {
        Some(coverage) => {
            let overlay = output::png::Overlay {
                coverage,
                color: wireframe::LINE_COLOR,
            };
            output::png::encode_png_with_overlay(&run.frame, exposure, &overlay)?
        }
        None => output::png::encode_png(&run.frame, exposure)?,
    };
    set.stage("render.png", &png)?;
    for (iteration, frame) in &run.snapshots {
        set.stage(
            &format!("snapshot-{iteration:05}.exr"),
            &output::exr::encode_image(frame, &view_info)?,
        )?;
        set.stage(
            &format!("snapshot-{iteration:05}.png"),
            &output::png::encode_png(frame, exposure)?,
        )?;
    }
    let mut set = set.set;
    run.report.files = files;
    run.report.times.write = secs(t);
    run.report.times.total += run.report.times.write;
    set.stage("report.json", &output::write_json(&run.report)?)?;
    set.commit()
}
