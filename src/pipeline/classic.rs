//! The classic path of a solve: occluders, a uniform mesh, the dense
//! form-factor matrix, a classic solver (with snapshots rendered as it
//! goes), the output mesh and the render; and the report of each step.
//!
//! Invariant: the phases run in that order, each timed into the report;
//! snapshot renders count as render time, not solve time.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;
use serde_json::json;

use super::{
    DEFAULT_ELEMENT_FRACTION, SolveRun, SolveSettings, convergence_report, finish, new_report, secs,
};
use crate::classic::matrix::FormFactorMatrix;
use crate::classic::solve::{ClassicMethod, Solution, System};
use crate::classic::uniform::UniformMesh;
use crate::error::Result;
use crate::illumination::Illumination;
use crate::render::frame::Frame;
use crate::render::render;
use crate::render::view::View;
use crate::report::{Counts, Power, Report};
use crate::scene::Scene;
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// Solves `scene` with the classic `method` and renders its default view.
pub(super) fn solve(
    scene: &Scene,
    settings: &SolveSettings,
    method: ClassicMethod,
    progress: &Progress,
) -> Result<SolveRun> {
    let start = Instant::now();
    let mut report = new_report(scene, settings);
    let view = View::resolve(scene.cameras.first(), scene.bounds, &settings.view)?;
    let element_size = settings
        .element_size
        .unwrap_or(scene.diagonal() * DEFAULT_ELEMENT_FRACTION);

    let t = Instant::now();
    let phase = progress.spinner("occluders");
    let bvh = TriangleBvh::of_scene(scene);
    report.times.bvh = secs(t);

    let t = Instant::now();
    phase.message("uniform mesh");
    // Counted and checked before anything is allocated: the elements, the
    // f32 matrix and, for the direct method, its f64 factorisation.
    let direct = method == ClassicMethod::Direct;
    let mesh = UniformMesh::within_budget(
        scene,
        element_size,
        settings.matrix.memory_budget,
        if direct {
            "with their dense matrix and its factorisation"
        } else {
            "with their dense matrix"
        },
        |n| {
            let matrix = FormFactorMatrix::bytes_for_count(n);
            match direct {
                true => matrix.saturating_mul(3),
                false => matrix,
            }
        },
    )?;
    report.times.mesh = Some(secs(t));
    drop(phase);
    // The images too, before the form factors take their time.
    settings.check_image_memory(&view, settings.matrix.memory_budget)?;

    let t = Instant::now();
    let (matrix, stats) = FormFactorMatrix::assemble(&mesh, &bvh, &settings.matrix, progress)?;
    report.times.form_factors = Some(secs(t));

    let t = Instant::now();
    let (reflectance, emission, area) = mesh.element_values(scene);
    // The punctual lights' and sky's light: each element reflects its mean
    // as if it emitted it.
    let illumination = Illumination::new(scene, &bvh, 1, settings.hierarchical.seed);
    let external: Vec<DVec3> = mesh
        .elements
        .par_iter()
        .enumerate()
        .map(|(i, e)| illumination.element(e.patch, &e.corners, i as u64).0)
        .collect();
    let source: Vec<DVec3> = (0..emission.len())
        .map(|i| emission[i] + reflectance[i] * external[i])
        .collect();
    let system = System {
        matrix: &matrix,
        reflectance: &reflectance,
        emission: &source,
        area: &area,
    };
    let (mut solution, mut snapshots, snapshot_time) =
        solve_with_snapshots(scene, settings, method, &mesh, &system, &view, progress)?;
    for (h, x) in solution.irradiance.iter_mut().zip(&external) {
        *h += *x;
    }
    report.times.solve = secs(t) - snapshot_time;
    report.times.render += snapshot_time;
    report_solution(
        &mut report,
        settings,
        method,
        &system,
        &emission,
        &external,
        &solution,
    );
    drop(matrix);

    let t = Instant::now();
    let out = mesh.output_mesh(scene, &solution.radiosity, &solution.irradiance);
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
        clusters: None,
        cluster_links: None,
    };
    report.max_row_sum = Some(stats.max_row_sum);
    report.mean_row_sum = Some(stats.mean_row_sum);
    report.mean_row_error = stats.mean_row_error;
    report.max_form_factor_error = stats.max_error;
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
    report.estimated_error = crate::meshing::seams::seam_steps(scene, &out);
    finish(
        scene, report, view, out, frame, snapshots, start, settings, progress,
    )
}

/// Renders after the requested iterations, with their iteration number.
type Snapshots = Vec<(usize, Frame)>;

/// Runs the classic solver, rendering the requested snapshots as it goes;
/// returns the solution, the snapshots and the seconds they took.
fn solve_with_snapshots(
    scene: &Scene,
    settings: &SolveSettings,
    method: ClassicMethod,
    mesh: &UniformMesh,
    system: &System,
    view: &View,
    progress: &Progress,
) -> Result<(Solution, Snapshots, f64)> {
    let mut snapshots = Vec::new();
    let mut snapshot_time = 0.0;
    let phase = progress.spinner(method.name());
    let mut observe = |iteration: usize, b: &[DVec3]| {
        phase.message(format!("iteration {iteration}"));
        if settings.snapshots.contains(&iteration) {
            let t = Instant::now();
            // Only rendered, which takes B: no irradiance kept.
            let out = mesh.output_mesh(scene, b, &vec![DVec3::ZERO; b.len()]);
            snapshots.push((
                iteration,
                render(&out, view, &settings.render, &Progress::hidden()),
            ));
            snapshot_time += secs(t);
        }
    };
    let solution = crate::classic::solve::solve(
        system,
        method,
        &settings.convergence,
        settings.matrix.memory_budget,
        &mut observe,
    )?;
    Ok((solution, snapshots, snapshot_time))
}

/// The solution's power balance and convergence, into the report, with a
/// warning when it did not converge.
fn report_solution(
    report: &mut Report,
    settings: &SolveSettings,
    method: ClassicMethod,
    system: &System,
    emission: &[DVec3],
    external: &[DVec3],
    solution: &Solution,
) {
    let sum = |f: &dyn Fn(usize) -> DVec3| -> [f64; 3] {
        (0..system.area.len()).map(f).sum::<DVec3>().to_array()
    };
    let (reflectance, area) = (system.reflectance, system.area);
    report.power = Power {
        emitted: sum(&|i| (emission[i] + external[i]) * area[i]),
        lights: sum(&|i| external[i] * area[i]),
        absorbed: sum(&|i| (DVec3::ONE - reflectance[i]) * solution.irradiance[i] * area[i]),
        radiated: sum(&|i| solution.radiosity[i] * area[i]),
    };
    report.convergence = convergence_report(
        solution.converged,
        settings.convergence.tolerance,
        solution
            .history
            .iter()
            .map(|h| (h.iteration, h.residual, h.seconds)),
    );
    if !solution.converged {
        report.warnings.push(format!(
            "{} did not reach the tolerance {} within {} iterations",
            method.name(),
            settings.convergence.tolerance,
            settings.convergence.max_iterations
        ));
    }
}
