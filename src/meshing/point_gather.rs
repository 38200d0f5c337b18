//! The final gather: the radiosity at any point of a solved scene, from
//! the links of the leaf that holds the point and of its ancestors, each
//! source's exact point-to-polygon form factor taken from the point
//! itself, the emitters' direct light gathered at the point with its
//! own visibility rays, and the punctual lights' and sky's light at the
//! point (`crate::illumination`).
//!
//! Owns: [`point_light`] (one point, one leaf: its radiosity and
//! irradiance, [`PointLight`]), [`PointEvaluator`]
//! (any point of a patch: finds the leaf, chooses the emitters gathered
//! directly) and [`dark_emitters`] (emitters the solution shows hidden
//! from a whole patch).
//!
//! Invariants: a value depends only on the solution, the point, the seed
//! and the leaf (rays are seeded per leaf and source), never on the thread
//! count or the order of evaluation (except which points a spent time
//! budget turns into leaf values); values are finite and, from
//! [`PointEvaluator`], non-negative.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::formfactor::form_factor_point_polygon;
use crate::hierarchical::HierarchicalSolution;
use crate::hierarchical::hierarchy::ElementId;
use crate::hierarchical::link::weighted_visibility;
use crate::hierarchical::oracle::receiver_threshold;
use crate::illumination::Illumination;
use crate::sampling::{PolygonSampler, pair_stream, stratified};
use crate::scene::Scene;
use crate::visibility::{Shaft, TriangleBvh};

/// Visibility rays per link not too dim to matter in [`point_light`].
pub const POINT_RAYS: usize = 8;

/// A link whose light at a point, ρ F B, is below this fraction of the
/// brightness threshold `bf_eps` keeps its own visible fraction in
/// [`point_light`]: the point's rays could move the value by less
/// than that.
pub const DIM_LINK_FRACTION: f64 = 0.2;

/// Visibility rays per emitter patch for the direct light at a point...
pub const DIRECT_RAYS: usize = 64;

/// ... and when some but not all of them were blocked.
pub const PENUMBRA_RAYS: usize = 256;

/// Which links of the final gather cast their own visibility rays from
/// the point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LinkRays {
    /// Links bright enough to matter ([`DIM_LINK_FRACTION`]), wholly
    /// visible ones included: a link sees its source whole from the points
    /// its rays left, not from every point of its receiver (a wall point 1
    /// cm behind a louvre's edge, under a skylight its leaf sees whole:
    /// 40 times too bright in the gallery). The others keep their visible
    /// fraction.
    #[default]
    Bright,
    /// Every link, dim ones included.
    Every,
}

/// How [`point_light`] gathers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PointGather<'a> {
    /// Which links cast rays from the point.
    pub link_rays: LinkRays,
    /// Emitter patches whose emission is gathered at the point itself
    /// (exact form factor, [`DIRECT_RAYS`] rays, [`PENUMBRA_RAYS`] in a
    /// penumbra) rather than through the
    /// links, which then carry only the emitters' reflected light: a
    /// link's visibility is an average over its receiver, wrong at points
    /// in a penumbra, and a fully occluded link is not kept at all. Either
    /// empty or every emitter patch of the scene.
    pub direct: &'a [u32],
    /// Per patch, the `direct` emitters (bit i for `direct[i]`) from which
    /// the solution brings no light to any part of the patch
    /// ([`dark_emitters`]): at a point there, [`PROBE_RAYS`] rays go
    /// first, and when all are blocked the emitter counts as hidden.
    /// Empty: none.
    pub dark: &'a [u64],
}

/// Rays that confirm an emitter the solution found hidden from a whole
/// patch, in [`point_light`] (see [`PointGather::dark`]).
pub const PROBE_RAYS: usize = 16;

/// For each patch, the emitters among `direct` (at most 64, bit i for
/// `direct[i]`) that no link of the solution carrying light joins to the
/// patch: no element link on any of its elements with a source on the
/// emitter, no cluster link whose source holds it.
pub fn dark_emitters(scene: &Scene, solution: &HierarchicalSolution, direct: &[u32]) -> Vec<u64> {
    let n = scene.patches.len();
    let mut bit = vec![0u64; n];
    for (i, &k) in direct.iter().enumerate() {
        bit[k as usize] |= 1 << i;
    }
    let h = &solution.hierarchy;
    let mut lit = match &solution.clusters {
        Some(c) => c.emitters_lighting(direct),
        None => vec![0; n],
    };
    let per_element: Vec<u64> = solution
        .links
        .par_iter()
        .with_min_len(256)
        .map(|ls| {
            ls.iter()
                .filter(|l| l.coupling() > 0.0)
                .map(|l| bit[h.get(l.source).patch as usize])
                .fold(0, |a, b| a | b)
        })
        .collect();
    for (e, mask) in h.elements.iter().zip(per_element) {
        lit[e.patch as usize] |= mask;
    }
    let all = if direct.len() == 64 {
        u64::MAX
    } else {
        (1u64 << direct.len()) - 1
    };
    lit.into_iter().map(|m| all & !m).collect()
}

/// What arrives at a point and what leaves it: B = E + ρ H with the E and
/// ρ of its patch.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PointLight {
    /// Radiosity B.
    pub radiosity: DVec3,
    /// Irradiance H.
    pub irradiance: DVec3,
}

impl PointLight {
    /// Both clamped at zero (a gather of non-negative terms; rounding
    /// aside).
    pub fn non_negative(self) -> PointLight {
        PointLight {
            radiosity: self.radiosity.max(DVec3::ZERO),
            irradiance: self.irradiance.max(DVec3::ZERO),
        }
    }
}

/// Radiosity and irradiance at point `x` of leaf `leaf` by a final gather over the links
/// of the leaf and its ancestors: each link's source contributes its exact
/// point-to-polygon form factor from `x` (not the link's mean over its
/// receiver) times its radiosity, and, for a link not too dim to matter
/// ([`DIM_LINK_FRACTION`]), the kernel-weighted visible
/// fraction of [`POINT_RAYS`] rays from `x` (seeded by `seed`, the leaf
/// and the source: deterministic). `gather`
/// says which links cast rays and which emitters are gathered directly.
/// `x` is moved a millionth of the way toward the leaf's centroid first,
/// so that a point on an edge takes its value from inside the leaf.
pub fn point_light(
    scene: &Scene,
    bvh: &TriangleBvh,
    solution: &HierarchicalSolution,
    leaf: ElementId,
    x: DVec3,
    seed: u64,
    gather: PointGather,
) -> PointLight {
    let h = &solution.hierarchy;
    let e = h.get(leaf);
    let patch = &scene.patches[e.patch as usize];
    let x = x + 1e-6 * (e.centroid() - x);
    if bvh.buried(scene, x, patch.normal) {
        // Under a box, inside a solid: nothing reaches the point.
        return PointLight {
            radiosity: patch.emission,
            irradiance: DVec3::ZERO,
        };
    }
    // Whether nothing stands in the shaft between x and `polygon` (normal
    // `n_s`): then it is wholly visible, with no ray.
    let clear = |polygon: &[DVec3], n_s: DVec3| {
        let fronts = [(x, patch.normal), (polygon[0], n_s)];
        Shaft::new(&[x], polygon, &fronts).is_some_and(|s| bvh.shaft_clear(&s))
    };
    // The kernel-weighted sums (all, seen) of `n` rays from x to
    // stratified points of `polygon`, drawn from `rng`.
    let rays = |polygon: &[DVec3], n_s: DVec3, n: usize, rng: &mut _| {
        let sampler = PolygonSampler::new(polygon);
        let targets = stratified(n, rng)
            .into_iter()
            .map(|t| (x, sampler.point(t)));
        weighted_visibility(bvh, targets, patch.normal, n_s)
    };
    let t = &solution.thresholds;
    let dim_light = DIM_LINK_FRACTION * t.bf_eps * receiver_threshold(t, e);
    let mut irradiance = DVec3::ZERO;
    let dark = gather.dark.get(e.patch as usize).copied().unwrap_or(0);
    for (i, &k) in gather.direct.iter().enumerate() {
        let emitter = &scene.patches[k as usize];
        if !((x - emitter.corners[0]).dot(emitter.normal) > 0.0) {
            continue;
        }
        let f = form_factor_point_polygon(x, patch.normal, emitter.vertices());
        if !(f > 0.0) {
            continue;
        }
        let (polygon, n_s) = (emitter.vertices(), emitter.normal);
        let v = if clear(polygon, n_s) {
            1.0
        } else {
            // Streams above the element ids: patch k's rays.
            let visible = |n: usize| {
                let mut rng = pair_stream(seed, leaf.0, u32::MAX - k);
                let (total, seen) = rays(polygon, n_s, n, &mut rng);
                (total > 0.0).then(|| seen / total)
            };
            if dark >> i & 1 == 1 && visible(PROBE_RAYS) == Some(0.0) {
                continue;
            }
            match visible(DIRECT_RAYS) {
                // In a penumbra: a finer estimate.
                Some(v) if v > 0.0 && v < 1.0 => visible(PENUMBRA_RAYS).unwrap_or(0.0),
                v => v.unwrap_or(0.0),
            }
        };
        irradiance += f * v * emitter.emission;
    }
    if let Some(&c) = solution.cluster_irradiance.get(e.patch as usize) {
        // The patch's mean, which only its exposed part receives.
        let c = match gather.direct.is_empty() {
            true => c,
            false => c - solution.cluster_direct[e.patch as usize],
        };
        let exposure = f64::from(h.elements[e.patch as usize].exposure);
        if exposure > 0.0 {
            irradiance += c / exposure;
        }
    }
    if let Some(&c) = solution.correction.get(e.patch as usize) {
        // Defect correction: a mean over the patch, like the cluster light.
        let exposure = f64::from(h.elements[e.patch as usize].exposure);
        if exposure > 0.0 {
            irradiance += c / exposure;
        }
    }
    let mut id = Some(leaf);
    while let Some(k) = id {
        for l in &solution.links[k.index()] {
            let s = h.get(l.source);
            let source = &scene.patches[s.patch as usize];
            if !((x - s.corners[0]).dot(source.normal) > 0.0) {
                continue;
            }
            let mut b = s.exposed_radiosity;
            if !gather.direct.is_empty() {
                b -= source.emission;
            }
            if b.max_element() <= 0.0 {
                continue;
            }
            let f = form_factor_point_polygon(x, patch.normal, s.vertices());
            if !(f > 0.0) {
                continue;
            }
            let dim = (patch.reflectance * f * b).max_element() < dim_light;
            let v = if l.unobstructed() {
                1.0
            } else if gather.link_rays == LinkRays::Every || !dim {
                // No shaft first: a clear shaft would only save these few
                // rays, which then all get through.
                let mut rng = pair_stream(seed, leaf.0, l.source.0);
                match rays(s.vertices(), source.normal, POINT_RAYS, &mut rng) {
                    (total, seen) if total > 0.0 => seen / total,
                    _ => l.carried_visibility(),
                }
            } else {
                l.carried_visibility()
            };
            irradiance += f * v * b;
        }
        id = h.get(k).parent();
    }
    // The punctual lights (exact, so their shadows are sharp) and the sky.
    irradiance += Illumination::new(scene, bvh, solution.sky_rays, seed).at(e.patch, x);
    PointLight {
        radiosity: patch.emission + patch.reflectance * irradiance,
        irradiance,
    }
}

/// Emitter patches whose light is gathered at each point rather than
/// through the links, at most: beyond, the cost per vertex would grow with
/// the emitter count, and the links carry the direct light too.
pub const MAX_DIRECT_EMITTERS: usize = 64;

/// Radiosity at any point of a solved scene: [`point_light`] from the
/// leaf holding the point, clamped at zero, with the direct light of up to
/// [`MAX_DIRECT_EMITTERS`] emitter patches gathered at the point.
pub struct PointEvaluator<'a> {
    scene: &'a Scene,
    bvh: &'a TriangleBvh,
    solution: &'a HierarchicalSolution,
    seed: u64,
    direct: Vec<u32>,
    /// [`PointGather::dark`].
    dark: Vec<u64>,
    /// Points evaluated from then on take their leaf's value
    /// ([`PointEvaluator::leaf_value`]).
    deadline: Option<Instant>,
    /// How many did.
    late: AtomicUsize,
}

impl<'a> PointEvaluator<'a> {
    /// The evaluator of `solution`, gathering the direct light of every
    /// emitter patch at each point when there are at most
    /// [`MAX_DIRECT_EMITTERS`].
    pub fn new(
        scene: &'a Scene,
        bvh: &'a TriangleBvh,
        solution: &'a HierarchicalSolution,
        seed: u64,
    ) -> Self {
        let mut direct: Vec<u32> = (0..scene.patches.len() as u32)
            .filter(|&p| scene.patches[p as usize].is_emitter())
            .collect();
        if direct.len() > MAX_DIRECT_EMITTERS {
            direct.clear();
        }
        let dark = dark_emitters(scene, solution, &direct);
        PointEvaluator {
            scene,
            bvh,
            solution,
            seed,
            direct,
            dark,
            deadline: None,
            late: AtomicUsize::new(0),
        }
    }

    /// The emitter patches gathered at each point (empty beyond
    /// [`MAX_DIRECT_EMITTERS`]).
    pub fn direct_emitters(&self) -> &[u32] {
        &self.direct
    }

    /// The radiosity and irradiance at `x` on patch `patch`, `link_rays`
    /// saying which links cast their own rays from `x`.
    pub fn value(&self, patch: usize, x: DVec3, link_rays: LinkRays) -> PointLight {
        if self.late() {
            self.late.fetch_add(1, Ordering::Relaxed);
            return self.leaf_value(patch, x);
        }
        let leaf = self.solution.hierarchy.leaf_at(self.scene, patch, x);
        let gather = PointGather {
            link_rays,
            direct: &self.direct,
            dark: &self.dark,
        };
        point_light(
            self.scene,
            self.bvh,
            self.solution,
            leaf,
            x,
            self.seed,
            gather,
        )
        .non_negative()
    }

    /// The evaluator with a time budget that ends at `deadline`: from
    /// then on [`PointEvaluator::value`] gives [`PointEvaluator::leaf_value`].
    pub fn until(self, deadline: Option<Instant>) -> Self {
        PointEvaluator { deadline, ..self }
    }

    /// True once the deadline has passed.
    pub fn late(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }

    /// How many values were leaf values for the deadline.
    pub fn late_count(&self) -> usize {
        self.late.load(Ordering::Relaxed)
    }

    /// The light of the leaf of `patch` holding `x`: its mean radiosity and
    /// irradiance, no rays. What a point gets once the time budget is
    /// spent: piecewise constant over the leaves.
    pub fn leaf_value(&self, patch: usize, x: DVec3) -> PointLight {
        let leaf = self.solution.hierarchy.leaf_at(self.scene, patch, x);
        PointLight {
            radiosity: self.solution.hierarchy.get(leaf).radiosity,
            irradiance: self.solution.irradiance[leaf.index()],
        }
        .non_negative()
    }
}
