//! The `solve` job end to end: scene → mesh → form factors → solution →
//! output mesh → image, with a report; and writing its outputs.
//!
//! Owns: the order of the phases and their timing. Each phase lives in its
//! own module; this one only wires them together.
//!
//! Invariant: [`solve`] does no IO; [`write_outputs`] stages every file and
//! renames them only when all were written, so a failed run leaves earlier
//! outputs intact.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;
use serde_json::json;

use crate::classic::matrix::{FormFactorMatrix, MatrixSettings};
use crate::classic::solve::{ClassicMethod, Convergence, System};
use crate::classic::uniform::UniformMesh;
use crate::discontinuity::{DiscontinuitySettings, discontinuity_segments};
use crate::error::Result;
use crate::hierarchical::{HierarchicalSettings, solve_hierarchical_guided};
use crate::mesh::OutputMesh;
use crate::meshing::{MeshMode, MeshSettings, build_mesh};
use crate::output::{self, OutputSet};
use crate::render::frame::Frame;
use crate::render::view::{View, ViewOverrides};
use crate::render::{RenderSettings, render};
use crate::report::{ConvergenceReport, Counts, HistoryEntry, ImportanceReport, Power, Report};
use crate::scene::Scene;
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// Default element size as a fraction of the scene diagonal.
pub const DEFAULT_ELEMENT_FRACTION: f64 = 1.0 / 25.0;

/// How a scene is solved: hierarchically (the default), or by a classic
/// solver on a uniform mesh with a dense matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Hierarchical,
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

/// Everything `nusselt solve` can be told.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveSettings {
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
    pub convergence: Convergence,
    pub render: RenderSettings,
    pub view: ViewOverrides,
    /// Iterations after which to render a snapshot.
    pub snapshots: Vec<usize>,
    /// Draw the output mesh's edges over `render.png` (not `render.exr`).
    pub wireframe: bool,
    /// Hierarchical: weigh refinement by the importance of the solve's view
    /// ([`view_importance`]).
    pub importance: bool,
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
        }
    }
}

/// The results of a solve, ready to be written.
#[derive(Clone, Debug)]
pub struct SolveRun {
    pub mesh: OutputMesh,
    /// Overlay the mesh's edges on `render.png`.
    pub wireframe: bool,
    pub frame: Frame,
    /// Renders after the requested iterations (the final state for those
    /// past the last iteration).
    pub snapshots: Vec<(usize, Frame)>,
    pub report: Report,
}

/// The occluder BVH over every input triangle of `scene`.
pub fn scene_bvh(scene: &Scene) -> TriangleBvh {
    let occluders: Vec<[glam::Vec3; 3]> = scene
        .triangles
        .iter()
        .map(|t| t.positions.map(|p| p.as_vec3()))
        .collect();
    TriangleBvh::new(&occluders, scene.diagonal())
}

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// Solves `scene` with the method of `settings` and renders the default
/// view (and the requested snapshots). `report.times.load` and
/// `report.scene` are left for the caller.
pub fn solve(scene: &Scene, settings: &SolveSettings, progress: &Progress) -> Result<SolveRun> {
    match settings.method {
        Method::Hierarchical => solve_with_hierarchy(scene, settings, progress),
        Method::Classic(method) => solve_classic(scene, settings, method, progress),
    }
}

/// Rays per side at most of [`view_importance`]'s grid.
const IMPORTANCE_GRID: u32 = 256;

/// The patches `view` sees directly: 1 for each patch hit first (on its
/// front) by a ray of a grid over the image (at most [`IMPORTANCE_GRID`]
/// rays a side, pixel centres), 0 for the others.
pub fn view_importance(scene: &Scene, bvh: &TriangleBvh, view: &View) -> Vec<f32> {
    let scale = (f64::from(IMPORTANCE_GRID) / f64::from(view.width.max(view.height))).min(1.0);
    let (w, h) = (
        ((f64::from(view.width) * scale).round() as u32).max(1),
        ((f64::from(view.height) * scale).round() as u32).max(1),
    );
    let far = 4.0 * scene.diagonal() + view.eye.distance(0.5 * (scene.bounds.0 + scene.bounds.1));
    let hits: Vec<Option<u32>> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (f64::from(i % w) + 0.5, f64::from(i / w) + 0.5);
            let (eye, dir) = view.ray(x / scale, y / scale);
            let hit = bvh.closest_hit(eye, dir, far)?;
            let t = &scene.triangles[hit.triangle as usize];
            let p = t.positions;
            let normal = (p[1] - p[0]).cross(p[2] - p[0]);
            if normal.dot(dir) < 0.0 {
                Some(t.front_patch)
            } else {
                t.back_patch
            }
        })
        .collect();
    let mut seen = vec![0.0; scene.patches.len()];
    for p in hits.into_iter().flatten() {
        seen[p as usize] = 1.0;
    }
    seen
}

/// The hierarchical path: discontinuity segments (for that mesh mode), link,
/// refine and solve [HSA91], then the output mesh of the mode. Snapshots
/// show the final state.
fn solve_with_hierarchy(
    scene: &Scene,
    settings: &SolveSettings,
    progress: &Progress,
) -> Result<SolveRun> {
    let start = Instant::now();
    let hs = &settings.hierarchical;
    let mut report = Report {
        nusselt_version: env!("CARGO_PKG_VERSION").to_string(),
        method: settings.method.name().into(),
        threads: rayon::current_num_threads(),
        warnings: scene.warnings.clone(),
        ..Report::default()
    };
    let view = View::resolve(scene.cameras.first(), scene.bounds, &settings.view)?;

    let t = Instant::now();
    let bvh = scene_bvh(scene);
    report.times.bvh = secs(t);

    // The discontinuity mesh's segments also guide the refinement.
    let t = Instant::now();
    let guide = if settings.mesh.mode == MeshMode::Discontinuity {
        discontinuity_segments(scene, &bvh, &settings.discontinuity).by_patch(scene.patches.len())
    } else {
        Vec::new()
    };
    report.times.discontinuities = secs(t);

    let mut hs = hs.clone();
    if settings.importance {
        hs.importance = Some(view_importance(scene, &bvh, &view));
    }
    let hs = &hs;
    let solution = solve_hierarchical_guided(scene, &bvh, hs, &guide, progress);
    if let Some(seen) = &hs.importance {
        let count = |f: &dyn Fn(usize) -> bool| (0..scene.patches.len()).filter(|&p| f(p)).count();
        report.importance = Some(ImportanceReport {
            patches_seen: count(&|p| seen[p] > 0.0),
            patches_weighted: count(&|p| solution.importance.get(p).is_some_and(|&w| w > 0.01)),
        });
    }
    report.times.linking = solution.times.linking;
    report.times.refinement = solution.times.refinement;
    report.times.solve = solution.times.solve;

    let h = &solution.hierarchy;
    let leaves: Vec<usize> = h.leaves().map(|id| id.index()).collect();
    let sum = |f: &dyn Fn(usize) -> DVec3| -> [f64; 3] {
        leaves.iter().map(|&i| f(i)).sum::<DVec3>().to_array()
    };
    let patch = |i: usize| &scene.patches[h.elements[i].patch as usize];
    report.power = Power {
        emitted: sum(&|i| patch(i).emission * h.elements[i].area),
        absorbed: sum(&|i| {
            (DVec3::ONE - patch(i).reflectance) * solution.irradiance[i] * h.elements[i].area
        }),
        radiated: sum(&|i| h.elements[i].radiosity * h.elements[i].area),
    };
    report.convergence = ConvergenceReport {
        converged: solution.converged,
        iterations: solution.history.len(),
        tolerance: hs.tolerance,
        history: solution
            .history
            .iter()
            .map(|h| HistoryEntry {
                iteration: h.iteration,
                residual: h.residual,
                seconds: h.seconds,
            })
            .collect(),
        rounds: solution.rounds.clone(),
    };
    if !solution.converged {
        report.warnings.push(format!(
            "hierarchical: the last solve did not reach the tolerance {} within {} iterations",
            hs.tolerance, hs.max_iterations
        ));
    }
    if let Some(hit) = &solution.budget {
        report.warnings.push(hit.message());
    }
    report.budget = solution.budget;
    if solution.rounds_exhausted {
        report.warnings.push(format!(
            "hierarchical: refinement stopped after {} rounds with links still above the threshold",
            hs.accuracy.max_rounds
        ));
    }

    let t = Instant::now();
    let mesh_settings = MeshSettings {
        seed: hs.seed,
        ..settings.mesh.clone()
    };
    let (out, mesh_stats) = build_mesh(scene, &bvh, &solution, &guide, &mesh_settings)?;
    report.times.output_mesh = secs(t);
    report.mesh = Some(mesh_stats);

    let t = Instant::now();
    let frame = render(&out, &view, &settings.render, progress);
    report.times.render += secs(t);
    let mut snapshots = Vec::new();
    for &k in &settings.snapshots {
        if !snapshots.iter().any(|(j, _)| *j == k) {
            snapshots.push((k, frame.clone()));
        }
    }

    report.counts = Counts {
        input_triangles: scene.stats.input_triangles,
        degenerate_dropped: scene.stats.degenerate_dropped,
        merged_quads: scene.stats.merged_quads,
        patches: scene.patches.len(),
        elements: h.len(),
        leaves: leaves.len(),
        links: solution.link_count(),
        visibility_rays: solution.visibility_rays,
        memory_bytes: solution.memory_bytes(),
        output_vertices: out.vertex_count(),
        output_triangles: out.triangles.len(),
        clusters: solution.clusters.as_ref().map_or(0, |c| c.tree.len()),
        cluster_links: solution.cluster_link_count(),
    };
    let th = &solution.thresholds;
    report.settings = json!({
        "method": settings.method.name(),
        "hierarchical": hs,
        "mesh": settings.mesh,
        "discontinuity": (settings.mesh.mode == MeshMode::Discontinuity)
            .then_some(&settings.discontinuity),
        "scaled_thresholds": {
            "ff_eps": th.ff_eps,
            "bf_eps": th.bf_eps,
            "power_eps": th.power_eps,
            "cluster_eps": th.cluster_eps,
            "min_area": th.min_area,
        },
        "render": settings.render,
        "snapshots": settings.snapshots,
        "width": view.width,
        "height": view.height,
    });
    Ok(finish(
        report,
        view,
        out,
        frame,
        snapshots,
        start,
        settings.wireframe,
    ))
}

/// The classic path: uniform mesh, dense matrix, classic solver.
fn solve_classic(
    scene: &Scene,
    settings: &SolveSettings,
    method: ClassicMethod,
    progress: &Progress,
) -> Result<SolveRun> {
    let start = Instant::now();
    let mut report = Report {
        nusselt_version: env!("CARGO_PKG_VERSION").to_string(),
        method: settings.method.name().into(),
        threads: rayon::current_num_threads(),
        warnings: scene.warnings.clone(),
        ..Report::default()
    };
    let view = View::resolve(scene.cameras.first(), scene.bounds, &settings.view)?;
    let element_size = settings
        .element_size
        .unwrap_or(scene.diagonal() * DEFAULT_ELEMENT_FRACTION);
    if !(element_size > 0.0 && element_size.is_finite()) {
        return Err(crate::Error::Setting(format!(
            "element size {element_size} must be positive"
        )));
    }

    let t = Instant::now();
    let bvh = scene_bvh(scene);
    report.times.bvh = secs(t);

    let t = Instant::now();
    let mesh = UniformMesh::new(scene, element_size);
    report.times.mesh = secs(t);

    let t = Instant::now();
    let (matrix, stats) = FormFactorMatrix::assemble(&mesh, &bvh, &settings.matrix, progress)?;
    report.times.form_factors = secs(t);

    let t = Instant::now();
    let (reflectance, emission, area) = mesh.element_values(scene);
    let system = System {
        matrix: &matrix,
        reflectance: &reflectance,
        emission: &emission,
        area: &area,
    };
    let mut snapshots = Vec::new();
    let mut snapshot_time = 0.0;
    let mut observe = |iteration: usize, b: &[DVec3]| {
        if settings.snapshots.contains(&iteration) {
            let t = Instant::now();
            let out = mesh.output_mesh(scene, b);
            snapshots.push((
                iteration,
                render(&out, &view, &settings.render, &Progress::hidden()),
            ));
            snapshot_time += secs(t);
        }
    };
    let solution = crate::classic::solve::solve(
        &system,
        method,
        &settings.convergence,
        settings.matrix.memory_budget,
        &mut observe,
    )?;
    report.times.solve = secs(t) - snapshot_time;
    report.times.render += snapshot_time;
    drop(matrix);

    let area = |i: usize| mesh.elements[i].area;
    let sum = |f: &dyn Fn(usize) -> DVec3| -> [f64; 3] {
        (0..mesh.elements.len()).map(f).sum::<DVec3>().to_array()
    };
    report.power = Power {
        emitted: sum(&|i| emission[i] * area(i)),
        absorbed: sum(&|i| (DVec3::ONE - reflectance[i]) * solution.irradiance[i] * area(i)),
        radiated: sum(&|i| solution.radiosity[i] * area(i)),
    };
    report.convergence = ConvergenceReport {
        converged: solution.converged,
        iterations: solution.history.len(),
        tolerance: settings.convergence.tolerance,
        history: solution
            .history
            .iter()
            .map(|h| HistoryEntry {
                iteration: h.iteration,
                residual: h.residual,
                seconds: h.seconds,
            })
            .collect(),
        rounds: Vec::new(),
    };
    if !solution.converged {
        report.warnings.push(format!(
            "{} did not reach the tolerance {} within {} iterations",
            method.name(),
            settings.convergence.tolerance,
            settings.convergence.max_iterations
        ));
    }

    let t = Instant::now();
    let out = mesh.output_mesh(scene, &solution.radiosity);
    report.times.output_mesh = secs(t);

    let t = Instant::now();
    let frame = render(&out, &view, &settings.render, progress);
    report.times.render += secs(t);
    // Snapshots asked for after the solver stopped show the final state.
    let last = solution.history.len();
    for &k in &settings.snapshots {
        if k > last && !snapshots.iter().any(|(j, _)| *j == k) {
            snapshots.push((k, frame.clone()));
        }
    }

    report.counts = Counts {
        input_triangles: scene.stats.input_triangles,
        degenerate_dropped: scene.stats.degenerate_dropped,
        merged_quads: scene.stats.merged_quads,
        patches: scene.patches.len(),
        elements: mesh.elements.len(),
        leaves: mesh.elements.len(),
        links: stats.nonzero_pairs,
        visibility_rays: stats.visibility_rays,
        memory_bytes: FormFactorMatrix::bytes_for(mesh.elements.len()),
        output_vertices: out.vertex_count(),
        output_triangles: out.triangles.len(),
        clusters: 0,
        cluster_links: 0,
    };
    report.max_row_sum = stats.max_row_sum;
    report.mean_row_sum = stats.mean_row_sum;
    report.settings = json!({
        "method": method,
        "element_size": element_size,
        "matrix": settings.matrix,
        "convergence": settings.convergence,
        "render": settings.render,
        "snapshots": settings.snapshots,
        "width": view.width,
        "height": view.height,
    });
    Ok(finish(
        report,
        view,
        out,
        frame,
        snapshots,
        start,
        settings.wireframe,
    ))
}

/// The common end of every solve: exposure, view and total time.
fn finish(
    mut report: Report,
    view: View,
    mesh: OutputMesh,
    frame: Frame,
    snapshots: Vec<(usize, Frame)>,
    start: Instant,
    wireframe: bool,
) -> SolveRun {
    report.exposure = frame_exposure(&frame);
    report.view = Some(view);
    report.times.total = secs(start);
    SolveRun {
        mesh,
        wireframe,
        frame,
        snapshots,
        report,
    }
}

/// The display exposure of a run, chosen from its main render's pixels (a
/// small bright emitter clips, the rest is well exposed), and then shared by
/// `render.png`, the snapshots, the bake's `COLOR_0` and later
/// `nusselt render --png` of the same solution.
pub fn frame_exposure(frame: &Frame) -> f32 {
    output::png::auto_exposure(frame.pixels.iter().map(|p| output::png::luminance(*p)))
}

/// Writes the five outputs of the contract, and any snapshots, into `dir`
/// (staged, then renamed together). Fills `report.times.write` before writing the report.
pub fn write_outputs(dir: &Path, run: &mut SolveRun) -> Result<Vec<PathBuf>> {
    let t = Instant::now();
    let mut set = OutputSet::create(dir)?;
    let exposure = run.report.exposure;
    set.stage("solution.exr", &output::exr::encode_solution(&run.mesh)?)?;
    let (gltf, bin) = output::baked::encode_baked_gltf(&run.mesh, exposure, "baked.bin")?;
    set.stage("baked.bin", &bin)?;
    set.stage("baked.gltf", &gltf)?;
    set.stage("render.exr", &output::exr::encode_image(&run.frame)?)?;
    let png = match (&run.report.view, run.wireframe) {
        (Some(view), true) => {
            let overlay = output::png::Overlay {
                coverage: &crate::render::wireframe::wireframe_mask(&run.mesh, view),
                color: crate::render::wireframe::LINE_COLOR,
            };
            output::png::encode_png_with_overlay(&run.frame, exposure, &overlay)?
        }
        _ => output::png::encode_png(&run.frame, exposure)?,
    };
    set.stage("render.png", &png)?;
    for (iteration, frame) in &run.snapshots {
        set.stage(
            &format!("snapshot-{iteration:05}.exr"),
            &output::exr::encode_image(frame)?,
        )?;
        set.stage(
            &format!("snapshot-{iteration:05}.png"),
            &output::png::encode_png(frame, exposure)?,
        )?;
    }
    run.report.times.write = secs(t);
    run.report.times.total += run.report.times.write;
    set.stage("report.json", &output::write_json(&run.report)?)?;
    set.commit()
}

/// Largest relative excess of absorbed over emitted power that
/// [`fuzz_pipeline`] accepts (per channel): preview accuracy on arbitrary
/// geometry (touching, penetrating, coplanar overlapping polygons).
pub const FUZZ_ENERGY_TOL: f64 = 0.05;

/// The body of the `pipeline` fuzz target: bytes become a tiny scene of one
/// to four parallelograms and up to three triangles (positions on a 1/32
/// grid of ±4, at a scale from 1 mm to 1 km, random reflectances, emissions
/// and sidedness, the first polygon always emitting), which is solved
/// hierarchically at preview accuracy and rendered at 12×8.
///
/// Returns an error when a result breaks an invariant: a non-finite or
/// negative radiosity or pixel, an output mesh that does not validate, or
/// absorbed power above the emitted power by more than [`FUZZ_ENERGY_TOL`].
/// A scene the library refuses (every polygon degenerate) is not an error.
/// It never panics by itself; a panic inside the library is a finding.
pub fn fuzz_pipeline(data: &[u8]) -> std::result::Result<(), String> {
    use crate::hierarchical::Accuracy;
    use crate::scene::{InputTriangle, Material, Surface};

    let mut bytes = data.iter().copied();
    let mut next = move || bytes.next().unwrap_or(0);
    let coord = |b: u8| f64::from(b) / 32.0 - 4.0;
    let scale = 10f64.powi(i32::from(next() % 7) - 3);
    let quads = 1 + usize::from(next() % 4);
    let triangles = usize::from(next() % 4);
    let mut input = Vec::new();
    let mut materials = Vec::new();
    let mut surfaces = Vec::new();
    for k in 0..quads + triangles {
        let mut point = || DVec3::new(coord(next()), coord(next()), coord(next())) * scale;
        let (o, a, b) = (point(), point(), point());
        let corners = if k < quads {
            vec![[o, o + a, o + a + b], [o, o + a + b, o + b]]
        } else {
            vec![[o, o + a, o + b]]
        };
        let flags = next();
        let reflectance = DVec3::new(
            f64::from(next()) / 256.0,
            f64::from(next()) / 256.0,
            f64::from(next()) / 256.0,
        );
        let emits = k == 0 || flags & 1 == 1;
        let emitted_radiance = if emits {
            DVec3::new(
                f64::from(next()) / 16.0 + 0.1,
                f64::from(next()) / 16.0 + 0.1,
                f64::from(next()) / 16.0 + 0.1,
            )
        } else {
            DVec3::ZERO
        };
        materials.push(Material {
            name: format!("m{k}"),
            reflectance,
            emitted_radiance,
            double_sided: flags & 2 == 2,
        });
        surfaces.push(Surface {
            name: format!("s{k}"),
            node: k,
        });
        for positions in corners {
            input.push(InputTriangle {
                positions,
                material: k as u32,
                surface: k as u32,
                reflectance,
                emitted_radiance,
            });
        }
    }
    let Ok(scene) = Scene::build(input, materials, surfaces, Vec::new(), Vec::new()) else {
        return Ok(());
    };
    let mut settings = SolveSettings::default();
    settings.hierarchical.accuracy = Accuracy::preview();
    settings.view.width = Some(12);
    settings.view.height = Some(8);
    settings.render.samples_per_pixel = 1;
    let run = solve(&scene, &settings, &Progress::new(false)).map_err(|e| e.to_string())?;
    run.mesh.validate()?;
    if let Some(v) = run
        .mesh
        .radiosity
        .iter()
        .find(|b| !(b.is_finite() && b.min_element() >= 0.0))
    {
        return Err(format!("output radiosity {v}"));
    }
    if let Some(p) = run
        .frame
        .pixels
        .iter()
        .find(|p| !p.iter().all(|c| c.is_finite() && *c >= 0.0))
    {
        return Err(format!("pixel {p:?}"));
    }
    let power = &run.report.power;
    for c in 0..3 {
        let (e, a) = (power.emitted[c], power.absorbed[c]);
        if !(e.is_finite() && a.is_finite() && a >= 0.0 && a <= e * (1.0 + FUZZ_ENERGY_TOL)) {
            return Err(format!(
                "channel {c}: absorbed {a} W against emitted {e} W (tolerance {FUZZ_ENERGY_TOL})"
            ));
        }
    }
    Ok(())
}
