//! The hierarchical solver's state and its driver: initial linking, the
//! rounds of refine → solve ("multigridding", \[HSA91\] §5), and the
//! solution handed back.
//!
//! Invariant: the solver's state lives in [`Solver`]; each step of a
//! round is a method in its own file (`linking`, `refine`, `gather`,
//! `importance`, `budget`), all running serially over id-ordered lists
//! with only independent work in parallel.

use std::time::Instant;

use glam::DVec3;

use crate::discontinuity::Segment;
use crate::hierarchical::budget::{Budget, Coarsened};
use crate::hierarchical::cluster::Clusters;
use crate::hierarchical::gather::{Shares, source_shares};
use crate::hierarchical::hierarchy::{ElementId, Hierarchy};
use crate::hierarchical::link::{Evaluator, Inherited, Link};
use crate::hierarchical::oracle::{Ends, RHO_FLOOR, Thresholds};
use crate::hierarchical::settings::HierarchicalSettings;
use crate::hierarchical::solution::{
    CorrectionPass, HierarchicalSolution, HierarchicalTimes, Iteration, Round,
};
use crate::scene::Scene;
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// Mean source exitance Φ / A_total (largest channel; Φ the emitted power
/// and the bound on what the lights and sky bring, [`Scene::source_power`]),
/// the largest patch emitted power (or that bound, if larger) and the total
/// area: the scales of the relative thresholds.
pub(crate) fn scene_scales(scene: &Scene) -> (f64, f64, f64) {
    let area = scene.total_area();
    let exitance = scene.source_power().max_element() / area;
    let lights = scene
        .lights
        .power_bound(scene.bounds.1 - scene.bounds.0)
        .max_element();
    let largest = scene
        .patches
        .iter()
        .map(|p| (p.emission * p.area).max_element())
        .fold(lights, f64::max);
    (exitance, largest, area)
}

/// A (receiver, source) pair waiting for its link to be evaluated.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pair {
    pub(super) receiver: ElementId,
    pub(super) source: ElementId,
    /// What the link this pair refines saw of its source.
    pub(super) inherited: Inherited,
}

impl Pair {
    pub(super) fn refining(receiver: ElementId, source: ElementId, inherited: Inherited) -> Pair {
        Pair {
            receiver,
            source,
            inherited,
        }
    }
}

/// The state of a solve in progress.
pub(super) struct Solver<'a> {
    pub(super) scene: &'a Scene,
    pub(super) bvh: &'a TriangleBvh,
    pub(super) settings: &'a HierarchicalSettings,
    pub(super) thresholds: Thresholds,
    pub(super) hierarchy: Hierarchy,
    pub(super) links: Vec<Vec<Link>>,
    pub(super) n_links: u64,
    /// Of `n_links`, the kept cluster links.
    pub(super) n_cluster_links: u64,
    pub(super) rays: u64,
    /// The first budget that refused a split.
    pub(super) budget: Option<Budget>,
    /// Links resampled with more rays so far.
    pub(super) resampled: u64,
    /// Elements `..measured` have their exposure measured (the arena only
    /// grows).
    pub(super) measured: usize,
    pub(super) clusters: Option<Clusters>,
    pub(super) start: Instant,
    /// Per patch, the weight in [0, 1] of its links' errors (empty: 1).
    pub(super) weight: Vec<f64>,
    /// Times the first linking started again with thresholds
    /// [`COARSENING`] times coarser, and the budget that stopped it last.
    pub(super) coarsened: u32,
    pub(super) coarsened_by: Option<Budget>,
    /// True until the first linking is done: only it starts again coarser.
    pub(super) first_linking: bool,
    /// Per patch, the irradiance the defect correction adds to every
    /// gather (`super::correction`; empty: none yet).
    pub(super) correction: Vec<DVec3>,
    /// Per element, the mean irradiance the punctual lights and the sky
    /// bring (`crate::illumination`), and its spread over the element;
    /// measured for every element when it is created, used at the
    /// leaves.
    pub(super) external: Vec<DVec3>,
    pub(super) external_spread: Vec<f64>,
}

/// How much coarser every threshold gets when a budget stops the first
/// linking ([`Solver::coarsen`]).
pub(super) const COARSENING: f64 = 4.0;

/// Restarts of the first linking at most: thresholds up to 4⁵ = 1024
/// times coarser. (Touching clusters always open down to their patches,
/// so beyond some point coarser thresholds no longer shrink the links.)
pub(super) const MAX_COARSENING: u32 = 5;

/// ρ of `patch`, at least [`RHO_FLOOR`] per channel, times its importance
/// weight (`weight` empty: 1).
pub(super) fn weighted_rho(scene: &Scene, weight: &[f64], patch: u32) -> DVec3 {
    let rho = scene.patches[patch as usize]
        .reflectance
        .max(DVec3::splat(RHO_FLOOR));
    weight.get(patch as usize).map_or(rho, |w| rho * *w)
}

/// Solves `scene` by hierarchical radiosity. Never fails: a scene without
/// links simply radiates its emission.
pub fn solve_hierarchical(
    scene: &Scene,
    bvh: &TriangleBvh,
    settings: &HierarchicalSettings,
    progress: &Progress,
) -> HierarchicalSolution {
    solve_hierarchical_guided(scene, bvh, settings, &[], progress)
}

/// [`solve_hierarchical`] with the discontinuity segments of each patch
/// (indexed by patch; shorter or empty means none) as a guide: after the
/// initial linking, elements crossed by a segment are split down to four
/// times the minimum element area and their partly visible links move to
/// the children (`Solver::follow_discontinuities`), so the hierarchy
/// resolves shadows along the segments and not elsewhere.
pub fn solve_hierarchical_guided(
    scene: &Scene,
    bvh: &TriangleBvh,
    settings: &HierarchicalSettings,
    guide: &[Vec<Segment>],
    progress: &Progress,
) -> HierarchicalSolution {
    let start = Instant::now();
    let mut solver = Solver::new(scene, bvh, settings, start);
    let mut times = HierarchicalTimes::default();

    let t = Instant::now();
    let phase = progress.spinner("linking");
    let first_splits = solver.initial_links();
    times.linking = t.elapsed().as_secs_f64();
    let t = Instant::now();
    phase.message("following shadow lines and lights");
    let guided_splits = solver.follow_discontinuities(guide);
    let lit_splits = solver.follow_lights();
    times.refinement += t.elapsed().as_secs_f64();
    drop(phase);

    let mut rounds = solver.run_rounds(
        first_splits + guided_splits + lit_splits,
        &mut times,
        progress,
    );
    let phase = match settings.correction_passes {
        0 => Progress::hidden().phase("", 0),
        passes => progress.phase("correction", u64::from(passes)),
    };
    for pass in 0..settings.correction_passes {
        // A pass costs as much as a round of links: none begins once the
        // time budget is spent (the report warns).
        if solver.out_of_time() {
            break;
        }
        phase.message(format!("pass {}", pass + 1));
        let t = Instant::now();
        let residual = solver.correct(&rounds.irradiance, settings.correction_rays, pass);
        rounds.correction_passes.push(residual);
        times.correction += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let shares = Some(&rounds.shares[..]);
        rounds.converged =
            solver.iterate(&mut rounds.irradiance, &mut rounds.history, start, shares);
        times.solve += t.elapsed().as_secs_f64();
        phase.inc(1);
    }
    drop(phase);
    solver.finish(rounds, times)
}

impl Solver<'_> {
    /// The link evaluator over the current hierarchy.
    pub(super) fn evaluator(&self) -> Evaluator<'_> {
        Evaluator {
            scene: self.scene,
            elements: &self.hierarchy.elements,
            bvh: self.bvh,
            seed: self.settings.seed,
        }
    }

    /// The ends of the link (receiver `r`, source `s`) as the oracle sees
    /// them.
    pub(super) fn ends(&self, r: ElementId, s: ElementId) -> Ends<'_> {
        let receiver = self.hierarchy.get(r);
        Ends {
            receiver,
            reflectance: weighted_rho(self.scene, &self.weight, receiver.patch),
            source: self.hierarchy.get(s),
            state: self.hierarchy.source_state(s),
        }
    }
}

/// The thresholds of `settings`, scaled to `scene`.
fn scaled_thresholds(scene: &Scene, settings: &HierarchicalSettings) -> Thresholds {
    let acc = &settings.accuracy;
    let (exitance, largest_power, area) = scene_scales(scene);
    Thresholds {
        oracle: settings.oracle,
        ff_eps: acc.ff_eps,
        bf_eps: acc.bf_eps * exitance,
        bf_relative: (acc.bf_relative_floor < 1.0).then_some((acc.bf_relative_floor, exitance)),
        cluster_eps: acc.cluster_eps * exitance,
        power_eps: acc.power_eps * largest_power,
        min_area: acc.min_area * area,
        rays: settings.visibility_rays.max(1),
    }
}

/// What the rounds of a solve leave behind, besides the solver's state.
pub(super) struct Rounds {
    irradiance: Vec<DVec3>,
    history: Vec<Iteration>,
    rounds: Vec<Round>,
    converged: bool,
    rounds_exhausted: bool,
    /// Per defect-correction pass, the residual it found
    /// ([`Solver::correct`]).
    correction_passes: Vec<CorrectionPass>,
    /// [`source_shares`] of the final links, for the solves after each
    /// correction pass (which changes no link).
    shares: Vec<Vec<(u32, Shares)>>,
}

impl<'a> Solver<'a> {
    /// A solver with one root element per patch and no links yet; the
    /// cluster tree when the scene is clustered, and the importance
    /// weights when the settings carry them.
    fn new(
        scene: &'a Scene,
        bvh: &'a TriangleBvh,
        settings: &'a HierarchicalSettings,
        start: Instant,
    ) -> Solver<'a> {
        let mut solver = Solver {
            scene,
            bvh,
            settings,
            // The relative bf threshold needs the receivers' radiosity:
            // from the first refinement on ([`Solver::run_rounds`]).
            thresholds: Thresholds {
                bf_relative: None,
                ..scaled_thresholds(scene, settings)
            },
            hierarchy: Hierarchy::new(scene),
            links: vec![Vec::new(); scene.patches.len()],
            n_links: 0,
            n_cluster_links: 0,
            rays: 0,
            resampled: 0,
            budget: None,
            measured: 0,
            clusters: None,
            start,
            weight: Vec::new(),
            coarsened: 0,
            coarsened_by: None,
            first_linking: true,
            correction: Vec::new(),
            external: Vec::new(),
            external_spread: Vec::new(),
        };
        if let Some(seen) = &settings.importance {
            solver.weight = (0..scene.patches.len())
                .map(|p| seen.get(p).map_or(0.0, |&v| f64::from(v).clamp(0.0, 1.0)))
                .collect();
        }
        solver.clear_links();
        solver
    }

    /// Back to one root element per patch and no links: the hierarchy,
    /// the links, the cluster tree (when the scene is clustered, with the
    /// importance weights) and the counts and budget that go with them.
    fn clear_links(&mut self) {
        let scene = self.scene;
        self.hierarchy = Hierarchy::new(scene);
        self.links = vec![Vec::new(); scene.patches.len()];
        self.n_links = 0;
        self.n_cluster_links = 0;
        self.budget = None;
        self.resampled = 0;
        self.measured = 0;
        self.external.clear();
        self.external_spread.clear();
        self.clusters = None;
        if self.settings.clustering.applies(scene.patches.len()) {
            let mut c = Clusters::new(scene);
            if !self.weight.is_empty() {
                c.set_weights(&self.weight);
            }
            self.clusters = Some(c);
        }
    }

    /// True when a link, element or memory budget stopped the links so far
    /// and the first linking may still start again coarser.
    pub(super) fn may_coarsen(&self) -> bool {
        use crate::hierarchical::budget::Budget;
        self.first_linking
            && self.coarsened < MAX_COARSENING
            && matches!(
                self.budget,
                Some(Budget::Links | Budget::Elements | Budget::Memory)
            )
    }

    /// Drops every link and element, and makes every threshold
    /// [`COARSENING`] times coarser, for the first linking to start again.
    /// A budget that stops the first linking leaves it half done (pairs of
    /// touching clusters unopened lose their light, coarse cluster links
    /// kept in their place carry light their sources' hidden members
    /// send): a solve at coarser thresholds that fits is the better answer.
    pub(super) fn coarsen(&mut self) {
        self.coarsened += 1;
        self.coarsened_by = self.budget;
        let t = &mut self.thresholds;
        t.ff_eps *= COARSENING;
        t.bf_eps *= COARSENING;
        t.power_eps *= COARSENING;
        t.cluster_eps *= COARSENING;
        self.clear_links();
    }

    /// The rounds ("multigridding", \[HSA91\] §5): solve with the current
    /// links (warm-started), then refine with the new radiosities (and
    /// importance), until a round changes nothing, a budget stops
    /// refinement or `max_rounds` is reached. `split_links` are the splits
    /// before the first round.
    fn run_rounds(
        &mut self,
        mut split_links: u64,
        times: &mut HierarchicalTimes,
        progress: &Progress,
    ) -> Rounds {
        let acc = &self.settings.accuracy;
        let (exitance, _, _) = scene_scales(self.scene);
        let phase = progress.phase("rounds", acc.max_rounds.max(1) as u64);
        let mut out = Rounds {
            irradiance: vec![DVec3::ZERO; self.hierarchy.len()],
            history: Vec::new(),
            rounds: Vec::new(),
            converged: false,
            rounds_exhausted: false,
            correction_passes: Vec::new(),
            shares: Vec::new(),
        };
        let mut gradient_splits = 0;
        let mut resampled_links = std::mem::take(&mut self.resampled);
        let mut round_start = Instant::now();
        let max_rounds = acc.max_rounds.max(1);
        let mut shared = false;
        let relative = scaled_thresholds(self.scene, self.settings).bf_relative;
        for round in 0..max_rounds {
            let t = Instant::now();
            out.irradiance.resize(self.hierarchy.len(), DVec3::ZERO);
            let first = out.history.len();
            // The last solve on the final links weighs split sources by
            // their shares ([`super::gather::source_shares`]).
            shared = round + 1 == max_rounds || self.budget.is_some();
            if shared {
                out.shares = source_shares(self.scene, &self.hierarchy, &self.links);
            }
            let shares = shared.then_some(&out.shares[..]);
            phase.message(format!(
                "round {}: solving {} links",
                round + 1,
                self.n_links
            ));
            out.converged = self.iterate(&mut out.irradiance, &mut out.history, self.start, shares);
            times.solve += t.elapsed().as_secs_f64();
            out.rounds.push(Round {
                round,
                split_links,
                gradient_splits,
                resampled_links,
                elements: self.hierarchy.len(),
                leaves: self.hierarchy.leaf_count(),
                links: self.n_links,
                iterations: out.history.len() - first,
                seconds: round_start.elapsed().as_secs_f64(),
            });
            phase.inc(1);
            if self.budget.is_some() {
                break;
            }
            if round + 1 == max_rounds {
                out.rounds_exhausted = self.rejected_links() > 0;
                break;
            }
            round_start = Instant::now();
            let t = Instant::now();
            phase.message(format!(
                "round {}: refining {} links",
                round + 2,
                self.n_links
            ));
            self.update_importance();
            self.thresholds.bf_relative = relative;
            split_links = self.refine();
            gradient_splits = self.refine_gradients(acc.gradient_tol * exitance);
            resampled_links = std::mem::take(&mut self.resampled);
            times.refinement += t.elapsed().as_secs_f64();
            if split_links == 0 && gradient_splits == 0 && resampled_links == 0 {
                break;
            }
        }
        if !shared {
            // Refinement changed nothing: once more on these links, with
            // shares (warm-started: a few iterations).
            let t = Instant::now();
            out.shares = source_shares(self.scene, &self.hierarchy, &self.links);
            let shares = Some(&out.shares[..]);
            out.converged = self.iterate(&mut out.irradiance, &mut out.history, self.start, shares);
            times.solve += t.elapsed().as_secs_f64();
        }
        out
    }

    /// The solution: links to fully occluded children were never kept,
    /// except those waiting for a possible resample, which go now; spare
    /// capacity is released so the memory figure is what the solution
    /// holds; the cluster links' light per patch is collected.
    fn finish(mut self, mut rounds: Rounds, times: HierarchicalTimes) -> HierarchicalSolution {
        for l in &mut self.links {
            let before = l.len();
            l.retain(|l| l.coupling() > 0.0);
            self.n_links -= (before - l.len()) as u64;
            l.shrink_to_fit();
        }
        self.hierarchy.elements.shrink_to_fit();
        rounds.irradiance.shrink_to_fit();
        let budget = self.budget_hit();
        let (cluster_irradiance, cluster_direct) = self.clusters.as_ref().map_or_else(
            || (Vec::new(), Vec::new()),
            |c| c.patch_irradiance(self.scene, &self.hierarchy.elements, self.settings.seed),
        );
        HierarchicalSolution {
            importance: self.weight,
            clusters: self.clusters,
            cluster_irradiance,
            cluster_direct,
            correction: self.correction,
            external: self.external,
            sky_rays: self.settings.accuracy.sky_rays,
            correction_passes: rounds.correction_passes,
            links: self.links,
            irradiance: rounds.irradiance,
            history: rounds.history,
            rounds: rounds.rounds,
            converged: rounds.converged,
            budget,
            rounds_exhausted: rounds.rounds_exhausted,
            visibility_rays: self.rays,
            times,
            thresholds: self.thresholds,
            coarsened: self.coarsened_by.map(|by| Coarsened {
                by,
                factor: COARSENING.powi(self.coarsened as i32),
            }),
            hierarchy: self.hierarchy,
        }
    }
}
