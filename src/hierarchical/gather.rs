//! The solve on fixed links: exposure of new leaves, gather
//! (H = Σ F·V·B_source over each element's links, cluster links included)
//! and push-pull through the quadtrees, iterated (with Anderson mixing,
//! [`Mixing`]) until the reflected power settles element by element.
//!
//! Invariant: parents precede children in the arena, so push-down runs in
//! arena order and pull-up in reverse; gathers run in parallel over
//! receivers, each into its own slot.
//!
//! Links carry the exposed radiosity. A link hands its receiver the
//! source's mean radiosity over its *exposed* part: area inside a closed
//! solid (a floor under a box) is dark and seen by nothing, and averaging
//! it in would dim the link a second time after its visibility already
//! did. Leaves measure their exposure (rays along the normal from
//! jittered points that meet a back face first); push-pull carries it up.
//! An element's irradiance H is its mean over the whole element, and only
//! the exposed part receives it (rays from the buried part are blocked):
//! push-down hands a child e_child / e_parent of its parent's H, so a
//! buried child gets none and Σ A·H is kept, and a leaf's exposed part
//! reflects H / exposure, so light landing on a partly buried leaf is sent
//! on, not lost.
//!
//! A link whose rays found its source partly hidden weighs the source's
//! children by where those that got through landed
//! ([`Link::seen_shares`]), in every solve: through the gaps between
//! slats a wall sees a slat's lower edge, not its mean. In the final
//! solve, any other link to a split source weighs the source's
//! children as its receiver sees them ([`source_shares`]), not by area:
//! the mean would move light from receivers beside a source's bright part
//! to those beside its dark part, and the light received would no longer
//! add up to the light sent.

use std::collections::VecDeque;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::formfactor::form_factor_point_polygon;
use crate::hierarchical::hierarchy::{ElementId, Hierarchy};
use crate::hierarchical::link::{Link, far_apart};
use crate::hierarchical::solution::Iteration;
use crate::hierarchical::solver::Solver;
use crate::illumination::Illumination;
use crate::sampling::{PolygonSampler, pair_stream, stratified};
use crate::scene::Scene;

impl Solver<'_> {
    /// Measures the exposure of the leaves created since the last call:
    /// the fraction of [`EXPOSURE_RAYS`] stratified points of the element
    /// (jittered, seeded by the element) from which a ray along the normal
    /// does not first meet the back of a surface (a point under a box on
    /// the floor, inside a closed solid, sees only backs). Elements split
    /// meanwhile get theirs from their children in push-pull.
    pub(super) fn measure_exposure(&mut self) {
        let (scene, bvh, seed) = (self.scene, self.bvh, self.settings.seed);
        let first = self.measured;
        let h = &mut self.hierarchy;
        h.elements[first..]
            .par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .filter(|(_, e)| e.is_leaf())
            .for_each(|(i, e)| {
                let n = scene.patches[e.patch as usize].normal;
                let mut rng = pair_stream(seed ^ EXPOSURE_TAG, (first + i) as u32, 0);
                let sampler = PolygonSampler::new(e.vertices());
                let buried = stratified(EXPOSURE_RAYS, &mut rng)
                    .into_iter()
                    .filter(|&t| bvh.buried(scene, sampler.point(t), n))
                    .count();
                e.exposure = 1.0 - buried as f32 / EXPOSURE_RAYS as f32;
            });
        self.measured = h.len();
    }

    /// Measures what the punctual lights and the sky bring to the elements
    /// created since the last call ([`Illumination::element`], seeded by
    /// the element).
    pub(super) fn measure_external(&mut self) {
        let first = self.external.len();
        let n = self.hierarchy.len();
        if first >= n {
            return;
        }
        let accuracy = &self.settings.accuracy;
        let illumination =
            Illumination::new(self.scene, self.bvh, accuracy.sky_rays, self.settings.seed);
        if illumination.is_dark() {
            self.external.resize(n, DVec3::ZERO);
            self.external_spread.resize(n, 0.0);
            return;
        }
        let measured: Vec<(DVec3, f64)> = self.hierarchy.elements[first..]
            .par_iter()
            .enumerate()
            .with_min_len(16)
            .map(|(i, e)| illumination.element(e.patch, e.vertices(), (first + i) as u64))
            .collect();
        for (h, spread) in measured {
            self.external.push(h);
            self.external_spread.push(spread);
        }
    }

    /// Gather + push-pull, the inputs combined by [`Mixing`], until an
    /// iteration would change the reflected power, element by element, by
    /// less than the tolerance times Σ B·A (at least two iterations);
    /// appends to `history`. Returns whether the tolerance was met. With
    /// `shares` ([`source_shares`] of the current links), links weigh
    /// their split sources' children by them and the tolerance is the
    /// settings' (the final solve); without, the tolerance is at least
    /// [`ROUND_TOLERANCE`] (the solves between refinement rounds, which
    /// are cheaper so).
    pub(super) fn iterate(
        &mut self,
        irradiance: &mut [DVec3],
        history: &mut Vec<Iteration>,
        start: Instant,
        shares: Option<&[Vec<(u32, Shares)>]>,
    ) -> bool {
        self.measure_exposure();
        self.measure_external();
        if let Some(c) = &mut self.clusters {
            c.refresh_weights(self.scene, &self.hierarchy.elements, self.settings.seed);
        }
        let plan = self.clusters.as_ref().map(|c| c.plan());
        let mut power = f64::NAN;
        let mut mixing = Mixing::new(self.scene, &self.hierarchy);
        let tolerance = match shares {
            Some(_) => self.settings.tolerance,
            None => self.settings.tolerance.max(ROUND_TOLERANCE),
        };
        for k in 0..self.settings.max_iterations.max(2) {
            let mut gathered = self.gather(shares);
            if let (Some(c), Some(plan)) = (&self.clusters, &plan) {
                c.gather(self.scene, &self.hierarchy.elements, plan, &mut gathered);
            }
            for (g, c) in gathered.iter_mut().zip(&self.correction) {
                *g += *c;
            }
            // The lights' and sky's light, at the leaves (an element's
            // own mean: push-down brings nothing of it).
            for ((g, e), x) in gathered
                .iter_mut()
                .zip(&self.hierarchy.elements)
                .zip(&self.external)
            {
                if e.is_leaf() {
                    *g += *x;
                }
            }
            let change = mixing.mix(&mut gathered);
            let p = self.push_pull(&gathered, irradiance);
            if let Some(c) = &mut self.clusters {
                c.pull_from(self.scene, &self.hierarchy.elements);
            }
            let residual = match change {
                Some(c) if power > 0.0 => c / power,
                Some(_) => 0.0,
                None => 1.0,
            };
            power = p;
            history.push(Iteration {
                iteration: history.len() + 1,
                residual,
                seconds: start.elapsed().as_secs_f64(),
            });
            if k > 0 && residual < tolerance {
                return true;
            }
        }
        false
    }

    /// H_e = Σ over e's links of F·V·B_source, in parallel over receivers,
    /// B_source weighted over a split source's children by the shares the
    /// link's rays saw ([`Link::seen_shares`]), else by `shares`
    /// ([`source_shares`]), when given.
    pub(super) fn gather(&self, shares: Option<&[Vec<(u32, Shares)>]>) -> Vec<DVec3> {
        let h = &self.hierarchy;
        self.links
            .par_iter()
            .enumerate()
            .with_min_len(64)
            .map(|(r, ls)| {
                let sh = shares.map_or(&[][..], |s| &s[r][..]);
                let mean: DVec3 = ls
                    .iter()
                    .map(|l| {
                        let b = match l.seen_shares() {
                            Some(w) => seen_radiosity(h, l.source, w),
                            None => h.get(l.source).exposed_radiosity,
                        };
                        l.coupling() * b
                    })
                    .sum();
                let seen: DVec3 = sh
                    .iter()
                    .filter(|(i, _)| ls[*i as usize].seen_shares().is_none())
                    .map(|&(i, w)| {
                        let l = &ls[i as usize];
                        let s = h.get(l.source);
                        l.coupling() * (seen_radiosity(h, l.source, w) - s.exposed_radiosity)
                    })
                    .sum();
                mean + seen
            })
            .collect()
    }

    /// Push-pull from every root; returns Σ B·A (sum of channels) and fills
    /// the total irradiance per element.
    pub(super) fn push_pull(&mut self, gathered: &[DVec3], irradiance: &mut [DVec3]) -> f64 {
        // Parents precede children in the arena: push down in arena order,
        // then pull up in reverse.
        // An element's irradiance is its mean over its whole area, received
        // by its exposed part only, so a child gets its parent's share by
        // exposure: e_child / e_parent of the parent's mean (Σ A·H is kept,
        // and a buried child gets none).
        push_down(&self.hierarchy, gathered, irradiance);
        let h = &mut self.hierarchy;
        for i in (0..h.len()).rev() {
            let e = &h.elements[i];
            let (b, exposed, exposure) = match e.children() {
                None => {
                    // H is the leaf's mean over its whole area, and only its
                    // exposed part receives it (a link's rays from the buried
                    // part are blocked, a cluster shares by exposed area):
                    // the exposed part reflects H / exposure.
                    let p = &self.scene.patches[e.patch as usize];
                    let reflected = p.reflectance * irradiance[i];
                    let b = p.emission + reflected;
                    let exposed = match e.exposure > 0.0 {
                        true => p.emission + reflected / f64::from(e.exposure),
                        false => b,
                    };
                    (b, exposed, e.exposure)
                }
                Some(kids) => {
                    let (mut b, mut exposed, mut exposed_area) = (DVec3::ZERO, DVec3::ZERO, 0.0);
                    for k in kids {
                        let k = &h.elements[k.index()];
                        let a = k.area * f64::from(k.exposure);
                        b += k.area * k.radiosity;
                        exposed += a * k.exposed_radiosity;
                        exposed_area += a;
                    }
                    let b = b / e.area;
                    if exposed_area > 0.0 {
                        (b, exposed / exposed_area, (exposed_area / e.area) as f32)
                    } else {
                        (b, b, 0.0)
                    }
                }
            };
            let e = &mut h.elements[i];
            e.radiosity = b;
            e.exposed_radiosity = exposed;
            e.exposure = exposure.clamp(0.0, 1.0);
        }
        (0..h.root_count())
            .map(|r| h.elements[r].radiosity.element_sum() * h.elements[r].area)
            .sum()
    }
}

/// Anderson mixing of the gather iteration (\[WN11\]; for a linear map
/// like this one it is GMRES restarted over a window). Plain gathering
/// converges by the dominant eigenvalue of ρ·K a step, about 0.75 in the
/// gallery (40 iterations to 1e-6). Each iteration here keeps the last
/// [`MIXING_DEPTH`] inputs x and their residuals f = T(x) − x (T: push-pull
/// then gather), and takes as the next input the combination of the
/// mapped ones T(x) whose combined residual is least in the norm of the
/// reflected power. The fixed point is T's; only the path to it changes.
///
/// A simpler jump along the last change (Aitken's extrapolation) was
/// tried first and lost: the hierarchy's map is not symmetric (cluster
/// links, source shares), its modes rotate and alternate (a louvre and
/// the one above it trade light back and forth), and a jump tuned to the
/// dominant ratio multiplied those by up to six, so that the iterations
/// it saved were spent again.
struct Mixing {
    /// Per element and channel, A·ρ: what a change of irradiance is worth
    /// in reflected power.
    weight: Vec<DVec3>,
    /// The last inputs and their residuals, oldest first.
    inputs: VecDeque<Vec<DVec3>>,
    residuals: VecDeque<Vec<DVec3>>,
}

/// Inputs [`Mixing`] combines, the newest included.
const MIXING_DEPTH: usize = 4;

/// The loosest tolerance of the solves between refinement rounds, which
/// only steer the oracle: its decisions weigh errors of several percent,
/// and the final solve, at the full tolerance, starts from theirs.
const ROUND_TOLERANCE: f64 = 1e-4;

impl Mixing {
    fn new(scene: &Scene, h: &Hierarchy) -> Mixing {
        let weight = (h.elements.iter())
            .map(|e| e.area * scene.patches[e.patch as usize].reflectance)
            .collect();
        Mixing::weighted(weight)
    }

    fn weighted(weight: Vec<DVec3>) -> Mixing {
        Mixing {
            weight,
            inputs: VecDeque::new(),
            residuals: VecDeque::new(),
        }
    }

    /// Takes `mapped` = T(last input) and replaces it by the next input.
    /// Returns Σ A·|ρ·f| over elements and channels for the last input's
    /// residual f (how much the reflected power would still change,
    /// element by element, so that changes of opposite sign do not
    /// cancel), or None on the first call.
    fn mix(&mut self, mapped: &mut [DVec3]) -> Option<f64> {
        let Some(x) = self.inputs.back() else {
            self.inputs.push_back(mapped.to_vec());
            return None;
        };
        let f: Vec<DVec3> = mapped.iter().zip(x).map(|(t, x)| *t - *x).collect();
        let change = self
            .weight
            .iter()
            .zip(&f)
            .map(|(w, f)| (*w * *f).abs().element_sum())
            .sum();
        self.residuals.push_back(f);
        if self.residuals.len() > 1 {
            self.combine(mapped);
        }
        self.inputs.push_back(mapped.to_vec());
        if self.inputs.len() > MIXING_DEPTH {
            self.inputs.pop_front();
            self.residuals.pop_front();
        }
        Some(change)
    }

    /// Replaces `mapped` by the combination of the kept inputs' images
    /// whose residual is least: min ‖W (f − ΔF γ)‖ over γ, the columns of
    /// ΔF the differences of consecutive residuals, W = A·ρ; then
    /// x_next = T(x) − Σ γ_i (Δx_i + Δf_i). Needs two residuals.
    fn combine(&self, mapped: &mut [DVec3]) {
        let (x, r) = (&self.inputs, &self.residuals);
        let m = r.len() - 1;
        let weigh = |f: &dyn Fn(usize) -> DVec3| -> Vec<DVec3> {
            self.weight
                .iter()
                .enumerate()
                .map(|(e, w)| *w * f(e))
                .collect()
        };
        let columns: Vec<Vec<DVec3>> = (0..m).map(|i| weigh(&|e| r[i + 1][e] - r[i][e])).collect();
        let last = weigh(&|e| r[m][e]);
        let dot =
            |a: &[DVec3], b: &[DVec3]| -> f64 { a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum() };
        let gram = nalgebra::DMatrix::from_fn(m, m, |i, j| dot(&columns[i], &columns[j]));
        let rhs = nalgebra::DVector::from_fn(m, |i, _| dot(&columns[i], &last));
        let eps = 1e-12 * gram.diagonal().iter().fold(0.0, |a: f64, &b| a.max(b));
        let Some(gamma) = gram.svd(true, true).solve(&rhs, eps).ok() else {
            return;
        };
        if !gamma.iter().all(|g| g.is_finite()) {
            return;
        }
        for (e, t) in mapped.iter_mut().enumerate() {
            for i in 0..m {
                let step = x[i + 1][e] - x[i][e] + r[i + 1][e] - r[i][e];
                *t -= gamma[i] * step;
            }
        }
    }
}

/// Points per leaf at which [`Solver::measure_exposure`] tests for burial.
/// The exposed part of a leaf reflects its irradiance over its exposure,
/// so the estimate has to follow the part a link's rays find blocked:
/// jittered, not the quarters' centroids. (Four fixed centroids marked a
/// 6 cm strip of the gallery's well buried all along a slat that cuts
/// 1.6 mm into the wall: 0.75 m² for 0.17 m².)
const EXPOSURE_RAYS: usize = 16;

/// Mixed into the seed of the exposure rays.
const EXPOSURE_TAG: u64 = 0x6578_706f_7375_7265;

/// Children seen within this ratio of each other per unit area count by
/// area ([`source_shares`]).
const EVEN_SHARES: f64 = 1.2;

/// How a link weighs its split source's four children, in 255ths of the
/// largest.
pub(crate) type Shares = [u8; 4];

/// For every element, the links (by index in its list) that weigh their
/// split source's children unequally, with their [`Shares`]: each child's
/// point-to-polygon form factor from the receiver's centroid. A receiver
/// near a split source sees its children unequally (a floor next to a
/// wall sees the wall's foot far larger than its top); handing it the
/// children's mean radiosity instead, receivers near the bright part get
/// too little and those near the dark part too much, and the sum over
/// receivers no longer equals the light the source sends out (on a room of
/// 0.7 paint at the preview preset, 0.25 % too much per bounce, 0.8 % in
/// the absorbed power). Far apart, or seen nearly in proportion to area,
/// the children count by area and the link is not listed.
pub(crate) fn source_shares(
    scene: &Scene,
    h: &Hierarchy,
    links: &[Vec<Link>],
) -> Vec<Vec<(u32, Shares)>> {
    links
        .par_iter()
        .enumerate()
        .with_min_len(64)
        .map(|(r, ls)| {
            let r = &h.elements[r];
            let n_r = scene.patches[r.patch as usize].normal;
            let c = r.centroid();
            ls.iter()
                .map(|l| {
                    let s = h.get(l.source);
                    let Some(kids) = s.children() else {
                        return [0; 4];
                    };
                    let n_s = scene.patches[s.patch as usize].normal;
                    if !((c - s.corners[0]).dot(n_s) > 0.0) {
                        return [0; 4];
                    }
                    if far_apart(r, n_r, s, n_s) {
                        return [0; 4];
                    }
                    // Nearly in proportion to area (by the kernel at the
                    // children's centroids first, which is cheap, then by
                    // the form factors): the mean is as good, and reads one
                    // element instead of four.
                    let even = |w: &[f64; 4]| {
                        let (lo, hi) = (0..4)
                            .map(|i| w[i] / h.get(kids[i]).area)
                            .fold((f64::INFINITY, 0.0f64), |(l, u), x| (l.min(x), u.max(x)));
                        hi <= EVEN_SHARES * lo
                    };
                    let kernel = kids.map(|k| {
                        let k = h.get(k);
                        let d = k.centroid() - c;
                        k.area * (d.dot(n_r) * -d.dot(n_s) / d.length_squared().powi(2)).max(0.0)
                    });
                    if even(&kernel) {
                        return [0; 4];
                    }
                    let w = kids.map(|k| form_factor_point_polygon(c, n_r, h.get(k).vertices()));
                    let top = w.iter().copied().fold(0.0, f64::max);
                    if !(top > 0.0) || !top.is_finite() || even(&w) {
                        return [0; 4];
                    }
                    w.map(|w| (255.0 * w / top).round() as u8)
                })
                .enumerate()
                .filter(|(_, w)| *w != [0; 4])
                .map(|(i, w)| (i as u32, w))
                .collect()
        })
        .collect()
}

/// The radiosity `source` hands a receiver whose view of its children is
/// `shares`: their exposed radiosities weighted by share × exposure, or
/// the source's exposed radiosity when the shares see only buried
/// children.
pub(crate) fn seen_radiosity(h: &Hierarchy, source: ElementId, shares: Shares) -> DVec3 {
    let s = h.get(source);
    let Some(kids) = s.children().filter(|_| shares != [0; 4]) else {
        return s.exposed_radiosity;
    };
    let (mut b, mut weight) = (DVec3::ZERO, 0.0);
    for (k, w) in kids.iter().zip(shares) {
        let k = h.get(*k);
        let w = f64::from(w) * f64::from(k.exposure);
        b += w * k.exposed_radiosity;
        weight += w;
    }
    if weight > 0.0 {
        b / weight
    } else {
        s.exposed_radiosity
    }
}

/// The push half of push-pull: each element's total irradiance, its own
/// gathered plus its parent's total shared by exposure (parents precede
/// children in the arena, so one pass in arena order does it).
pub(super) fn push_down(h: &Hierarchy, gathered: &[DVec3], total: &mut [DVec3]) {
    for i in 0..h.len() {
        let e = &h.elements[i];
        let down = e.parent().map_or(DVec3::ZERO, |p| {
            let parent = f64::from(h.elements[p.index()].exposure);
            match parent > 0.0 {
                true => total[p.index()] * (f64::from(e.exposure) / parent),
                false => DVec3::ZERO,
            }
        });
        total[i] = gathered[i] + down;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Iterates h ← e + M h until the residual's L1 norm is below 1e-10 of
    /// Σ h, with or without [`Mixing`]; returns the iterations and h.
    fn solve(m: [[f64; 2]; 2], e: [f64; 2], mixed: bool) -> (usize, [f64; 2]) {
        let mut mixing = Mixing::weighted(vec![DVec3::ONE; 2]);
        let mut h = [0.0; 2];
        for k in 1..10_000 {
            let mut g = [0, 1].map(|i| DVec3::splat(e[i] + m[i][0] * h[0] + m[i][1] * h[1]));
            let change = (g[0].x - h[0]).abs() + (g[1].x - h[1]).abs();
            if mixed {
                mixing.mix(&mut g);
            }
            let done = change < 1e-10 * (h[0] + h[1]);
            h = g.map(|g| g.x);
            if done {
                return (k, h);
            }
        }
        panic!("no convergence");
    }

    /// (I − M)⁻¹ e.
    fn fixed_point(m: [[f64; 2]; 2], e: [f64; 2]) -> [f64; 2] {
        let (a, b, c, d) = (1.0 - m[0][0], -m[0][1], -m[1][0], 1.0 - m[1][1]);
        let det = a * d - b * c;
        [(d * e[0] - b * e[1]) / det, (a * e[1] - c * e[0]) / det]
    }

    #[test]
    fn mixing_reaches_the_same_fixed_point_sooner() {
        // Eigenvalues 0.9 and 0.3 (a bright room beside a dim one); 0.8
        // and −0.65 (two facing plates trading light back and forth);
        // 0.75 ± 0.4i (a mode that rotates).
        for m in [
            [[0.6, 0.3], [0.3, 0.6]],
            [[0.1, 0.7], [0.75, 0.05]],
            [[0.75, 0.4], [-0.4, 0.75]],
        ] {
            let e = [1.0, 0.5];
            let (plain, a) = solve(m, e, false);
            let (fast, b) = solve(m, e, true);
            let exact = fixed_point(m, e);
            for (x, y) in a.iter().zip(&exact).chain(b.iter().zip(&exact)) {
                assert!((x - y).abs() < 1e-6 * y.abs(), "{a:?} {b:?} {exact:?}");
            }
            assert!(4 * fast < plain, "{fast} iterations mixed, {plain} plain");
        }
    }
}
