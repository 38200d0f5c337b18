//! Link refinement: evaluating (receiver, source) pairs, applying the
//! oracle's decisions (split the receiver, split the source, resample),
//! shadow splits summed per source patch, splits guided by discontinuity
//! segments, and gradient refinement of leaves.
//!
//! Invariant: refinement runs serially over candidate lists in id order;
//! only evaluation and decisions run in parallel, each into its own slot,
//! so links come out in the same order for any thread count. Under a time
//! budget a round settles its new links in batches ([`TIMED_BATCH`]), so
//! that it ends within one batch of the budget.

use glam::DVec3;
use rayon::prelude::*;

use crate::discontinuity::{Segment, SegmentKind};
use crate::hierarchical::hierarchy::ElementId;
use crate::hierarchical::link::{Inherited, Link};
use crate::hierarchical::oracle::{
    Decision, Oracle, decide, rays_needed, shadow_error, sharpen, split_at_any_visibility,
    visibility_error,
};
use crate::hierarchical::solver::{Pair, Solver, scene_scales, weighted_rho};

/// Under a time budget, a refinement round settles its new links in
/// batches of at least this many pairs, reading the clock between them: one
/// round of office-100k made millions of pairs before its first one was
/// evaluated, and settling them ran minutes past the budget.
const TIMED_BATCH: usize = 1 << 13;

/// The area, as a fraction of the minimum element area, down to which
/// elements crossed by a contact line (a D0 discontinuity: a louvre sunk
/// into a wall, a box on a floor) are split. The radiosity jumps across
/// such a line, and an element straddling it sends the bright side's
/// light, as its mean, into the dark side: under the gallery's lowest
/// louvre, where it meets the well's wall, the wall and the louvre's
/// lower face came out 26–37 % too bright. Other segments stop at four
/// times the minimum area. (Gallery, seeds 0 and 2: median 3.04 → 2.61 %
/// and 3.04 → 2.98 %, p90 9.01 → 8.00 % and 8.79 → 7.73 %, absorbed /
/// emitted 0.15–0.2 % lower; BENCHMARKS.md.)
pub const CONTACT_AREA_FRACTION: f64 = 1.0 / 16.0;

impl Solver<'_> {
    /// Carries out a split decision on the counted link (receiver `r`,
    /// `link`): the link is removed and the child pairs are appended to
    /// `next`. Returns false (nothing done) for `Accept` or when the link
    /// budget is reached.
    pub(super) fn apply(
        &mut self,
        r: ElementId,
        link: Link,
        decision: Decision,
        next: &mut Vec<Pair>,
    ) -> bool {
        let target = match decision {
            Decision::Accept => return false,
            Decision::Resample => {
                // The same pair again, with the rays it now needs.
                next.push(Pair::refining(r, link.source, Inherited::Nothing));
                self.resampled += 1;
                return true;
            }
            Decision::SplitReceiver => r,
            Decision::SplitSource => link.source,
        };
        if self.refuse_split(target, 3) {
            return false;
        }
        let children = self.hierarchy.split(target);
        let (receivers, sources) = if decision == Decision::SplitReceiver {
            (children, [link.source; 4])
        } else {
            ([r; 4], children)
        };
        // One link becomes four.
        self.n_links += 3;
        let inherited = link.inherited();
        next.extend(
            receivers
                .into_iter()
                .zip(sources)
                .map(|(r, s)| Pair::refining(r, s, inherited)),
        );
        true
    }

    /// Evaluates the (receiver, source) pairs and refines until every link
    /// is accepted, shadows included ([`Solver::shadow_splits`]), or the
    /// budget stops it. Returns the links split.
    pub(super) fn settle(&mut self, mut pending: Vec<Pair>) -> u64 {
        let mut splits = 0;
        loop {
            splits += self.settle_links(pending);
            let (more, moved) = self.shadow_splits();
            if more.is_empty() {
                return splits;
            }
            splits += moved;
            pending = more;
        }
    }

    /// Receivers crossed by a shadow edge of a whole source patch: for each
    /// receiver above the minimum area, the shadow errors of its links are
    /// summed per source patch ([`shadow_error`]); where a sum exceeds the
    /// threshold, the receiver is split and those of the patch's links
    /// whose visibility varies over it move to the children. This bounds
    /// the error of a shadow that the per-link oracle misses because the
    /// source was split into many small pieces, each link's share below
    /// the threshold. Returns the child pairs to evaluate and the links
    /// moved.
    pub(super) fn shadow_splits(&mut self) -> (Vec<Pair>, u64) {
        let t = self.thresholds;
        let weight = &self.weight;
        let h = &self.hierarchy;
        let scene = self.scene;
        let eps = match t.oracle {
            Oracle::Ff => t.ff_eps,
            Oracle::Bf => t.bf_eps,
            Oracle::Power => t.power_eps,
        };
        // Per receiver, the source patches whose links move down (sorted).
        let marked: Vec<Vec<u32>> = self
            .links
            .par_iter()
            .enumerate()
            .with_min_len(64)
            .map(|(r, ls)| {
                let re = &h.elements[r];
                if !(re.area > t.min_area) || ls.iter().all(|l| l.spread() == 0.0) {
                    return Vec::new();
                }
                let rho = weighted_rho(scene, weight, re.patch);
                let mut per_patch: Vec<(u32, f64)> = ls
                    .iter()
                    .filter(|l| l.spread() > 0.0)
                    .map(|l| {
                        let s = h.get(l.source);
                        (
                            s.patch,
                            shadow_error(&t, l, re.area, rho, s.exposed_radiosity),
                        )
                    })
                    .collect();
                per_patch.sort_by_key(|(p, _)| *p);
                let mut out = Vec::new();
                for group in per_patch.chunk_by(|a, b| a.0 == b.0) {
                    if group.iter().map(|(_, e)| e).sum::<f64>() > eps {
                        out.push(group[0].0);
                    }
                }
                out
            })
            .collect();
        let mut pending = Vec::new();
        let mut moved = 0;
        for (r, patches) in marked.into_iter().enumerate() {
            if patches.is_empty() {
                continue;
            }
            let own = std::mem::take(&mut self.links[r]);
            let (down, keep): (Vec<Link>, Vec<Link>) = own.into_iter().partition(|l| {
                l.spread() > 0.0
                    && patches
                        .binary_search(&self.hierarchy.get(l.source).patch)
                        .is_ok()
            });
            self.links[r] = keep;
            let extra = 3 * down.len() as u64;
            if self.refuse_split(ElementId(r as u32), extra) {
                self.links[r].extend(down);
                continue;
            }
            self.n_links += extra;
            moved += down.len() as u64;
            for child in self.hierarchy.split(ElementId(r as u32)) {
                pending.extend(
                    down.iter()
                        .map(|l| Pair::refining(child, l.source, Inherited::Nothing)),
                );
            }
        }
        self.links.resize_with(self.hierarchy.len(), Vec::new);
        (pending, moved)
    }

    /// Evaluates the (receiver, source) pairs in parallel, then keeps the
    /// accepted links, splits for the others and repeats until every new
    /// link is accepted (or the budget stops it). Returns the links split.
    pub(super) fn settle_links(&mut self, mut pending: Vec<Pair>) -> u64 {
        let mut splits = 0;
        while !pending.is_empty() {
            let evaluator = self.evaluator();
            let t = &self.thresholds;
            let evaluated: Vec<(Link, u64, Decision)> = pending
                .par_iter()
                .with_min_len(8)
                .map(|p| {
                    let ends = self.ends(p.receiver, p.source);
                    let plan = |l: &Link| {
                        let n = rays_needed(t, l, &ends);
                        if split_at_any_visibility(t, l, &ends, n) {
                            0
                        } else {
                            n
                        }
                    };
                    let (mut link, mut cast) =
                        evaluator.evaluate(p.receiver, p.source, p.inherited, plan);
                    let d = decide(t, &link, &ends);
                    if d == Decision::Accept {
                        sharpen(self.scene, t, &mut link, &ends);
                        // Accepted on rays that the decision hung on (the
                        // full count was cast): the link carries light with
                        // fresh rays' reading whenever the deciding one was
                        // partial, saw nothing, or is all-or-nothing in a
                        // penumbra, and every later decision still uses the
                        // deciding one. The oracle keeps the links that read
                        // dark and splits those that read bright, so
                        // carrying the deciding reading loses the light of
                        // every partly hidden pair that happened to read low
                        // (4 % of the direct light under a baffle; between
                        // the gallery's lower louvres and its skylight,
                        // links read below 0.2 carried a quarter of what
                        // 1,020 fresh rays see), and deciding later on the
                        // fresh reading does the same one round on.
                        let partial = link.partly_visible() || link.spread() > 0.0;
                        let fresh = link.rays() >= t.max_rays()
                            && !link.unobstructed()
                            && (partial
                                || link.visibility() == 0.0
                                || p.inherited == Inherited::PartlyVisible);
                        if fresh {
                            let (reading, more) =
                                evaluator.fresh_visibility(p.receiver, p.source, link.rays());
                            link = link.carrying(&reading);
                            cast += more;
                        }
                    }
                    (link, cast, d)
                })
                .collect();
            let mut next = Vec::new();
            for (p, (link, cast, decision)) in pending.iter().zip(evaluated) {
                let r = p.receiver;
                self.rays += cast;
                if self.apply(r, link, decision, &mut next) {
                    splits += u64::from(decision != Decision::Resample);
                    continue;
                }
                let mut link = link;
                if decision != Decision::Accept && cast == 0 {
                    // The budget refused a split the oracle decided without
                    // visibility rays: the kept link needs its visibility.
                    let ends = self.ends(r, link.source);
                    let t = &self.thresholds;
                    let plan = |l: &Link| rays_needed(t, l, &ends);
                    let (l, c) = self.evaluator().evaluate(r, link.source, p.inherited, plan);
                    link = l;
                    sharpen(self.scene, t, &mut link, &ends);
                    self.rays += c;
                }
                // Fully occluded or facing away: no light, no link. A link
                // that only a few rays found occluded stays (carrying
                // nothing) until the solve ends: should its source brighten,
                // it is resampled like the others. Dropping it now would
                // bias the resampled links' light low (only those that
                // saw something would get a second look).
                let few_rays = link.rays() > 0 && link.rays() < self.thresholds.max_rays();
                // (A link the oracle read as lit stays, whatever its fresh
                // reading carries: it may be split later like any other.)
                let lit = link.form_factor > 0.0 && link.visibility() > 0.0;
                if link.coupling() > 0.0 || lit || (few_rays && link.form_factor > 0.0) {
                    self.links[r.index()].push(link);
                } else {
                    self.n_links -= 1;
                }
            }
            self.links.resize_with(self.hierarchy.len(), Vec::new);
            pending = next;
        }
        splits
    }

    /// Splits every element crossed by a discontinuity segment of its patch
    /// (`guide[patch]`) while its area exceeds four times the minimum
    /// element area, or [`CONTACT_AREA_FRACTION`] of it for a contact
    /// line, level by level from the roots. The split element's
    /// links that may carry a shadow edge (partly visible, or with a
    /// visibility spread) move to its children and are settled by the
    /// oracle, which may refine them further. Returns the links moved.
    pub(super) fn follow_discontinuities(&mut self, guide: &[Vec<Segment>]) -> u64 {
        let bound = 4.0 * self.thresholds.min_area;
        let contact_bound = CONTACT_AREA_FRACTION * self.thresholds.min_area;
        let tol = 1e-9 * self.scene.diagonal();
        let mut frontier: Vec<ElementId> = (0..self.hierarchy.root_count())
            .filter(|&p| guide.get(p).is_some_and(|s| !s.is_empty()))
            .map(|p| self.hierarchy.root(p))
            .collect();
        let mut moved = 0;
        while !frontier.is_empty() {
            let mut next = Vec::new();
            let mut pending = Vec::new();
            for id in frontier {
                let e = self.hierarchy.get(id);
                let normal = self.scene.patches[e.patch as usize].normal;
                let crossed = guide[e.patch as usize].iter().any(|s| {
                    let limit = match s.kind {
                        SegmentKind::Contact => contact_bound,
                        _ => bound,
                    };
                    e.area > limit && segment_crosses(e.vertices(), normal, s.a, s.b, tol)
                });
                if !crossed {
                    continue;
                }
                let own = std::mem::take(&mut self.links[id.index()]);
                let (down, keep): (Vec<Link>, Vec<Link>) = own
                    .into_iter()
                    .partition(|l| l.partly_visible() || l.spread() > 0.0);
                self.links[id.index()] = keep;
                let extra = 3 * down.len() as u64;
                if self.refuse_split(id, extra) {
                    self.links[id.index()].extend(down);
                    continue;
                }
                self.n_links += extra;
                moved += down.len() as u64;
                for child in self.hierarchy.split(id) {
                    pending.extend(
                        down.iter()
                            .map(|l| Pair::refining(child, l.source, Inherited::Nothing)),
                    );
                    next.push(child);
                }
            }
            self.links.resize_with(self.hierarchy.len(), Vec::new);
            moved += self.settle(pending);
            frontier = next;
        }
        moved
    }

    /// Splits leaves across which the punctual lights' light varies (a
    /// shadow edge, a spot's rim, a steep falloff): ρ times the spread of
    /// [`Solver::measure_external`] above `gradient_tol` × the scene's
    /// exitance, while the area exceeds four times the minimum element
    /// area, level by level. Links stay on the split element (push-down
    /// feeds the children) for the oracle to refine. Returns the leaves
    /// split.
    pub(super) fn follow_lights(&mut self) -> u64 {
        if self.scene.lights.punctual.is_empty() {
            return 0;
        }
        let (exitance, _, _) = scene_scales(self.scene);
        let tol = self.settings.accuracy.gradient_tol * exitance;
        let bound = 4.0 * self.thresholds.min_area;
        if !(tol > 0.0) {
            return 0;
        }
        let mut frontier: Vec<ElementId> = self.hierarchy.leaves().collect();
        let mut splits = 0;
        while !frontier.is_empty() {
            self.measure_external();
            let mut next = Vec::new();
            for id in frontier {
                let e = self.hierarchy.get(id);
                let rho = self.scene.patches[e.patch as usize]
                    .reflectance
                    .max_element();
                if !(e.area > bound && rho * self.external_spread[id.index()] > tol) {
                    continue;
                }
                if self.refuse_split(id, 0) {
                    break;
                }
                splits += 1;
                next.extend(self.hierarchy.split(id));
            }
            self.links.resize_with(self.hierarchy.len(), Vec::new);
            frontier = next;
        }
        splits
    }

    /// Re-runs the oracle on every link with the current radiosities and
    /// refines those it rejects. Returns the links split.
    pub(super) fn refine(&mut self) -> u64 {
        let mut next = Vec::new();
        let mut splits = 0;
        let eps = self.thresholds.cluster_eps;
        if let Some(c) = self.clusters.as_mut() {
            let rejected = c.take_rejected(self.scene, &self.hierarchy.elements, eps);
            self.n_links -= rejected.len() as u64;
            self.n_cluster_links -= rejected.len() as u64;
            splits += rejected.len() as u64;
            next = self.link_clusters(rejected);
        }
        let decisions = self.decisions();
        for (r, ds) in decisions.iter().enumerate() {
            if ds.iter().all(|d| *d == Decision::Accept) {
                continue;
            }
            let old = std::mem::take(&mut self.links[r]);
            for (l, d) in old.into_iter().zip(ds) {
                if !self.apply(ElementId(r as u32), l, *d, &mut next) {
                    self.links[r].push(l);
                } else if *d != Decision::Resample {
                    splits += 1;
                }
            }
            // Under a time budget the round's new links are settled as they
            // come, so that the clock, read at every split, stops the round
            // within one batch (settling touches only receiver r, the
            // elements split so far and their children, never the links of
            // a receiver this loop has yet to reach; shadow splits, which
            // may, wait for the end).
            if self.settings.time_budget.is_some() && next.len() >= TIMED_BATCH {
                self.links.resize_with(self.hierarchy.len(), Vec::new);
                splits += self.settle_links(std::mem::take(&mut next));
            }
        }
        self.links.resize_with(self.hierarchy.len(), Vec::new);
        splits + self.settle(next)
    }

    /// Splits leaves whose radiosity differs from a sibling's by more than
    /// `tol` (W/m²), pushing down to the children those of their own links
    /// that can explain such a gradient: links whose brightness-weighted
    /// variation ρ_r B_s (F_err + V_err F) exceeds `tol / 4`. The other links
    /// keep feeding the split element as a whole. A leaf without such a
    /// link is not split (its children would all be alike). Returns the
    /// leaves split.
    pub(super) fn refine_gradients(&mut self, tol: f64) -> u64 {
        if !(tol > 0.0) {
            return 0;
        }
        let h = &self.hierarchy;
        let mut marked = Vec::new();
        for e in &h.elements {
            let Some(kids) = e.children() else { continue };
            for &k in &kids {
                let leaf = h.get(k);
                if !leaf.is_leaf() || !(leaf.area > self.thresholds.min_area) {
                    continue;
                }
                let w = self.weight.get(leaf.patch as usize).copied().unwrap_or(1.0);
                let differs = kids
                    .iter()
                    .any(|&o| w * (h.get(o).radiosity - leaf.radiosity).abs().max_element() > tol);
                if differs {
                    marked.push(k);
                }
            }
        }
        let mut pending = Vec::new();
        let mut split = 0;
        for k in marked {
            let rho = weighted_rho(self.scene, &self.weight, self.hierarchy.get(k).patch);
            let own = std::mem::take(&mut self.links[k.index()]);
            let (down, keep): (Vec<Link>, Vec<Link>) = own.into_iter().partition(|l| {
                let b = (rho * self.hierarchy.get(l.source).exposed_radiosity).max_element();
                let v_err = visibility_error(l);
                b * (l.error as f64 + v_err * l.form_factor as f64) > 0.25 * tol
            });
            self.links[k.index()] = keep;
            let extra = 3 * down.len() as u64;
            if down.is_empty() || self.refuse_split(k, extra) {
                self.links[k.index()].extend(down);
                continue;
            }
            split += 1;
            self.n_links += extra;
            for child in self.hierarchy.split(k) {
                for l in &down {
                    pending.push(Pair::refining(child, l.source, l.inherited()));
                }
            }
        }
        self.links.resize_with(self.hierarchy.len(), Vec::new);
        self.settle(pending);
        split
    }

    /// The oracle's decisions on every link, per receiver.
    pub(super) fn decisions(&self) -> Vec<Vec<Decision>> {
        let t = self.thresholds;
        self.links
            .par_iter()
            .enumerate()
            .map(|(r, ls)| {
                let r = ElementId(r as u32);
                ls.iter()
                    .map(|l| decide(&t, l, &self.ends(r, l.source)))
                    .collect()
            })
            .collect()
    }

    /// Links the oracle would split now.
    pub(super) fn rejected_links(&self) -> usize {
        self.decisions()
            .iter()
            .flatten()
            .filter(|d| **d != Decision::Accept)
            .count()
    }
}

/// True when segment `ab` (in the plane of the convex polygon `vertices`,
/// counter-clockwise about `normal`) passes through the polygon's interior
/// by more than `tol`: Cyrus–Beck clipping against the edges' inward
/// normals.
fn segment_crosses(vertices: &[DVec3], normal: DVec3, a: DVec3, b: DVec3, tol: f64) -> bool {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let d = b - a;
    for (i, &p) in vertices.iter().enumerate() {
        let q = vertices[(i + 1) % vertices.len()];
        let edge = q - p;
        let len = edge.length();
        if !(len > 0.0) {
            continue;
        }
        // Inward unit normal of the edge, in the plane.
        let m = normal.cross(edge) / len;
        // Inside by more than tol: (a + t d - p)·m > tol.
        let num = (a - p).dot(m) - tol;
        let den = d.dot(m);
        if den.abs() < 1e-300 {
            if !(num > 0.0) {
                return false;
            }
            continue;
        }
        let t = -num / den;
        if den > 0.0 {
            lo = lo.max(t);
        } else {
            hi = hi.min(t);
        }
    }
    (hi - lo) * d.length() > tol
}
