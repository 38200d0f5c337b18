//! The hierarchical path of a solve: occluders, discontinuity segments
//! (for that mesh mode), link, refine and solve \[HSA91\], the output mesh
//! of the mode, the render; and the report of each step.
//!
//! Invariant: the phases run in that order, each timed into the report;
//! snapshots of a hierarchical solve show the final state.

use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;
use serde_json::json;

use super::{SolveRun, SolveSettings, convergence_report, finish, new_report, secs};
use crate::discontinuity::discontinuity_segments_until;
use crate::error::Result;
use crate::hierarchical::budget::{MESH_SHARE, REFINE_SHARE, RENDER_SHARE, SHADOW_SHARE};
use crate::hierarchical::{HierarchicalSettings, HierarchicalSolution, solve_hierarchical_guided};
use crate::meshing::{MeshMode, MeshSettings, build_mesh};
use crate::render::render_until;
use crate::render::view::View;
use crate::report::{CorrectionReport, Counts, ImportanceReport, Power, Report};
use crate::scene::Scene;
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// Solves `scene` hierarchically and renders its default view.
pub(super) fn solve(
    scene: &Scene,
    settings: &SolveSettings,
    progress: &Progress,
) -> Result<SolveRun> {
    let start = Instant::now();
    // The budget's clock (the command's start: loading counts).
    let clock = settings.budget_start.unwrap_or(start);
    let mut report = new_report(scene, settings);
    let view = View::resolve(scene.cameras.first(), scene.bounds, &settings.view)?;
    settings.check_image_memory(&view, settings.hierarchical.memory_budget)?;
    // Before any work: a uniform output mesh of a given size must fit.
    settings
        .mesh
        .check_budget(scene, settings.hierarchical.memory_budget)?;

    let t = Instant::now();
    let phase = progress.spinner("occluders");
    let bvh = TriangleBvh::of_scene(scene);
    report.times.bvh = secs(t);
    drop(phase);

    // `--time-budget` bounds the whole run: wedge traces stop at its
    // SHADOW_SHARE, refinement at REFINE_SHARE (its own clock starts at
    // the solve), the output mesh at MESH_SHARE, the render at
    // RENDER_SHARE; writing takes the rest.
    let budget = settings.hierarchical.time_budget;
    let at = |share: f64| {
        budget.and_then(|t| {
            Duration::try_from_secs_f64(t * share)
                .ok()
                .and_then(|d| clock.checked_add(d))
        })
    };

    // The discontinuity mesh's segments also guide the refinement.
    let guide = if settings.mesh.mode == MeshMode::Discontinuity {
        let _phase = progress.spinner("shadow lines");
        let t = Instant::now();
        let found =
            discontinuity_segments_until(scene, &bvh, &settings.discontinuity, at(SHADOW_SHARE));
        report.times.discontinuities = Some(secs(t));
        if found.stats.late_jobs > 0 {
            report.warnings.push(format!(
                "shadow lines: {} wedge jobs were not traced: their share ({:.0} %) of \
                 --time-budget was spent",
                found.stats.late_jobs,
                100.0 * SHADOW_SHARE
            ));
        }
        found.by_patch(scene.patches.len())
    } else {
        Vec::new()
    };

    let mut hs = settings.hierarchical.clone();
    hs.time_budget = budget.map(|t| (t * REFINE_SHARE - clock.elapsed().as_secs_f64()).max(0.0));
    if settings.importance {
        hs.importance = Some(view_importance(scene, &bvh, &view));
    }
    let solution = solve_hierarchical_guided(scene, &bvh, &hs, &guide, progress);
    report_solution(&mut report, scene, &hs, &solution);

    let t = Instant::now();
    let mesh_settings = MeshSettings {
        seed: hs.seed,
        deadline: at(MESH_SHARE),
        ..settings.mesh.clone()
    };
    let (out, mesh_stats) = build_mesh(scene, &bvh, &solution, &guide, &mesh_settings, progress)?;
    report.times.output_mesh = secs(t);
    if mesh_stats.late_evaluations > 0 {
        report.warnings.push(format!(
            "output mesh: {} of {} points took their leaf's value, without rays: the time \
             budget's share ({:.0} %) for the output mesh was spent",
            mesh_stats.late_evaluations,
            mesh_stats.evaluations,
            100.0 * MESH_SHARE
        ));
    }
    report.mesh = Some(mesh_stats);

    let t = Instant::now();
    let (frame, short, skipped) =
        render_until(&out, &view, &settings.render, progress, at(RENDER_SHARE));
    report.times.render += secs(t);
    let pixels = u64::from(view.width) * u64::from(view.height);
    if short > 0 {
        report.warnings.push(format!(
            "render: {short} of {pixels} pixels got fewer samples than asked: the time budget was spent",
        ));
    }
    if skipped > 0 {
        report.warnings.push(format!(
            "render: {skipped} of {pixels} pixels got no sample and show the nearest rendered pixel \
             of their column: the time budget was spent",
        ));
    }
    let mut snapshots = Vec::new();
    for &k in &settings.snapshots {
        if !snapshots.iter().any(|(j, _)| *j == k) {
            snapshots.push((k, frame.clone()));
        }
    }

    report.counts = Counts {
        output_vertices: out.vertex_count(),
        output_triangles: out.triangles.len(),
        ..solution_counts(scene, &solution)
    };
    // The report shows the budget asked for, not refinement's share.
    hs.time_budget = budget;
    report.settings = settings_json(settings, &hs, &solution, &view);
    report.estimated_error = crate::meshing::seams::seam_steps(scene, &out);
    finish(
        scene, report, view, out, frame, snapshots, start, settings, progress,
    )
}

/// What the solve did, into the report: importance, phase times, power,
/// convergence, and the warnings for a solve that stopped short.
fn report_solution(
    report: &mut Report,
    scene: &Scene,
    hs: &HierarchicalSettings,
    solution: &HierarchicalSolution,
) {
    if let Some(seen) = &hs.importance {
        let count = |f: &dyn Fn(usize) -> bool| (0..scene.patches.len()).filter(|&p| f(p)).count();
        report.importance = Some(ImportanceReport {
            patches_seen: count(&|p| seen[p] > 0.0),
            patches_weighted: count(&|p| solution.importance.get(p).is_some_and(|&w| w > 0.01)),
        });
    }
    report.times.linking = Some(solution.times.linking);
    report.times.refinement = Some(solution.times.refinement);
    report.times.solve = solution.times.solve + solution.times.correction;
    if !solution.correction_passes.is_empty() {
        report.correction = Some(CorrectionReport {
            passes: solution.correction_passes.clone(),
            seconds: solution.times.correction,
        });
    }

    let h = &solution.hierarchy;
    let leaves: Vec<usize> = h.leaves().map(|id| id.index()).collect();
    let sum = |f: &dyn Fn(usize) -> DVec3| -> [f64; 3] {
        leaves.iter().map(|&i| f(i)).sum::<DVec3>().to_array()
    };
    let patch = |i: usize| &scene.patches[h.elements[i].patch as usize];
    report.power = Power {
        emitted: sum(&|i| (patch(i).emission + solution.external[i]) * h.elements[i].area),
        lights: sum(&|i| solution.external[i] * h.elements[i].area),
        absorbed: sum(&|i| {
            (DVec3::ONE - patch(i).reflectance) * solution.irradiance[i] * h.elements[i].area
        }),
        radiated: sum(&|i| h.elements[i].radiosity * h.elements[i].area),
    };
    report.convergence = convergence_report(
        solution.converged,
        hs.tolerance,
        solution
            .history
            .iter()
            .map(|h| (h.iteration, h.residual, h.seconds)),
    );
    report.convergence.rounds = solution.rounds.clone();
    if !solution.converged {
        report.warnings.push(format!(
            "hierarchical: the last solve did not reach the tolerance {} within {} iterations",
            hs.tolerance, hs.max_iterations
        ));
    }
    if let Some(hit) = &solution.budget {
        report.warnings.push(hit.message());
    }
    let done = solution.correction_passes.len();
    if done < hs.correction_passes as usize {
        report.warnings.push(format!(
            "hierarchical: {done} of {} correction passes ran: the time budget's share ({:.0} %) \
             for the solve was spent",
            hs.correction_passes,
            100.0 * REFINE_SHARE
        ));
    }
    report.budget = solution.budget;
    if let Some(c) = &solution.coarsened {
        report.warnings.push(c.message());
    }
    report.coarsened = solution.coarsened;
    // The preset's number of rounds is part of what it promises: running
    // them all is the normal path, recorded, not warned about.
    report.convergence.rounds_exhausted = Some(solution.rounds_exhausted);
}

/// The counts of the scene and the solution (the output mesh's are left
/// for the caller).
fn solution_counts(scene: &Scene, solution: &HierarchicalSolution) -> Counts {
    let h = &solution.hierarchy;
    Counts {
        input_triangles: scene.stats.input_triangles,
        degenerate_dropped: scene.stats.degenerate_dropped,
        merged_quads: scene.stats.merged_quads,
        patches: scene.patches.len(),
        elements: h.len(),
        leaves: h.leaf_count(),
        links: solution.link_count(),
        visibility_rays: solution.visibility_rays,
        memory_bytes: solution.memory_bytes(),
        output_vertices: 0,
        output_triangles: 0,
        clusters: Some(solution.clusters.as_ref().map_or(0, |c| c.tree.len())),
        cluster_links: Some(solution.cluster_link_count()),
    }
}

/// Every setting of the run, as `report.json` records it.
fn settings_json(
    settings: &SolveSettings,
    hs: &HierarchicalSettings,
    solution: &HierarchicalSolution,
    view: &View,
) -> serde_json::Value {
    let th = &solution.thresholds;
    json!({
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
    })
}

/// Rays per side at most of [`view_importance`]'s grid.
const IMPORTANCE_GRID: u32 = 256;

/// The patches `view` sees directly: 1 for each patch hit first (on its
/// front) by a ray of a grid over the image (at most `IMPORTANCE_GRID`
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
