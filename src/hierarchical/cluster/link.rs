//! Cluster links and their evaluation: a link with a cluster at one end
//! or both stores the Monte Carlo estimate of the geometric transfer
//! ∫∫ cos cos V / (π r²) between its two ends, from stratified point pairs
//! uniform by area, and which of those pairs got through, so that the
//! radiosity it carries is that of the source points its rays reached
//! ([`Clusters::sampled_radiosity`]), not the source cluster's mean.
//!
//! Invariants: a link is twenty bytes (packed source, f32 transfer,
//! fixed-point visibility, the pairs that got through, the source weight);
//! its transfer never exceeds the smaller end's area (a form factor is at
//! most 1 either way); rays come from `pair_stream(seed, r, s)` keyed by
//! the two nodes (or `!seed` for fresh ones), so the pairs can be drawn
//! again exactly.

use std::f64::consts::PI;

use glam::{DVec2, DVec3};

use rayon::prelude::*;

use super::lobes::{dot, lobes};
use super::transport::exposed;
use super::{Clusters, Node};
use crate::hierarchical::hierarchy::Element;
use crate::sampling::{pair_stream, stratified};
use crate::scene::Scene;
use crate::visibility::TriangleBvh;

/// A link into a cluster or a patch from a cluster or a patch (at least
/// one of the two a cluster), kept with its receiver.
///
/// Twenty bytes: the scale-up scenes keep tens of millions. (Its direction
/// is the line between the two nodes' centres, recomputed when needed.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClusterLink {
    /// The source node: a patch index, or a cluster index with
    /// [`CLUSTER_BIT`] set.
    source: u32,
    /// ∫∫ cos θ_r cos θ_s V / (π r²) dA_s dA_r over the two (m²): the
    /// power received per unit of the source's radiosity.
    pub transfer: f32,
    /// Visible fraction of the sampled rays, fixed point (0 and 1 exact).
    visibility: u16,
    /// Bit i: pair i of the first [`CLUSTER_RAYS`] faced and got through.
    seen: u8,
    /// [`FRESH`], [`UNSAMPLED`].
    flags: u8,
    /// Per channel, the radiosity of the source points the rays reached
    /// over the source cluster's mean toward the receiver, log-encoded
    /// ([`encode_weight`]): what the link multiplies the mean by.
    weight: [u16; 3],
}

/// [`ClusterLink`] flag: its rays were drawn from `!seed` (fresh rays).
const FRESH: u8 = 1;
/// [`ClusterLink`] flag: its pairs are not known (none of the first
/// [`CLUSTER_RAYS`] faced, or it was made without rays): it carries the
/// source cluster's mean.
const UNSAMPLED: u8 = 2;

/// Steps per octave of the log-encoded source weight.
const WEIGHT_STEPS: f64 = 2048.0;
/// Octaves below 1 the encoding reaches (and above it).
const WEIGHT_OCTAVES: f64 = 15.0;

/// A source weight w ≥ 0 as 0 (w = 0) or 1 + (log₂ w + 15) · 2048,
/// clamped to 2⁻¹⁵..2¹⁶: steps of 0.03 %.
fn encode_weight(w: f64) -> u16 {
    if !(w > 0.0) {
        return 0;
    }
    if !w.is_finite() {
        return u16::MAX;
    }
    let q = 1.0 + (w.log2() + WEIGHT_OCTAVES) * WEIGHT_STEPS;
    q.round().clamp(1.0, f64::from(u16::MAX)) as u16
}

fn decode_weight(q: u16) -> f64 {
    if q == 0 {
        0.0
    } else {
        ((f64::from(q) - 1.0) / WEIGHT_STEPS - WEIGHT_OCTAVES).exp2()
    }
}

/// The encoding of a source weight of exactly 1.
const UNIT_WEIGHT: u16 = 1 + (WEIGHT_OCTAVES * WEIGHT_STEPS) as u16;
const _: () = assert!(UNIT_WEIGHT as f64 == 1.0 + WEIGHT_OCTAVES * WEIGHT_STEPS);

/// Marks a cluster in [`ClusterLink`]'s packed source: patch and cluster
/// indices stay below it (the loader's triangle cap is far lower).
const CLUSTER_BIT: u32 = 1 << 31;
const _: () = assert!(crate::scene::MAX_TRIANGLES < CLUSTER_BIT as usize);
const _: () = assert!(std::mem::size_of::<ClusterLink>() == 20);

impl ClusterLink {
    /// A link carrying its source's mean (no known pairs).
    pub(super) fn new(source: Node, transfer: f64, visibility: f64) -> ClusterLink {
        let source = match source {
            Node::Patch(p) => p,
            Node::Cluster(c) => c | CLUSTER_BIT,
        };
        ClusterLink {
            source,
            transfer: transfer as f32,
            visibility: (visibility.clamp(0.0, 1.0) * f64::from(u16::MAX)).round() as u16,
            seen: 0,
            flags: UNSAMPLED,
            weight: [UNIT_WEIGHT; 3],
        }
    }

    /// The source weight per channel: what the link multiplies its source
    /// cluster's mean radiosity by (1 for a patch source or unknown pairs).
    pub fn weight(&self) -> DVec3 {
        DVec3::from_array(self.weight.map(decode_weight))
    }

    /// Sets the source weight per channel.
    pub(super) fn set_weight(&mut self, w: DVec3) {
        self.weight = w.to_array().map(encode_weight);
    }

    /// True when the pairs its rays got through are known.
    pub(super) fn sampled(&self) -> bool {
        self.flags & UNSAMPLED == 0 && self.source & CLUSTER_BIT != 0
    }

    /// The node the link gathers from.
    pub fn source(&self) -> Node {
        if self.source & CLUSTER_BIT == 0 {
            Node::Patch(self.source)
        } else {
            Node::Cluster(self.source & !CLUSTER_BIT)
        }
    }

    /// Visible fraction in [0, 1] of the sampled rays.
    pub fn visibility(&self) -> f64 {
        f64::from(self.visibility) / f64::from(u16::MAX)
    }
}

/// Point pairs (rays) per cluster link; when no pair faces each other,
/// [`RETRY_RAYS`] more are tried.
pub const CLUSTER_RAYS: usize = 8;
/// See [`CLUSTER_RAYS`].
pub const RETRY_RAYS: usize = 32;

/// What [`Clusters::evaluate`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Evaluation {
    /// The link, to keep.
    Link(ClusterLink),
    /// No pair of points faced each other.
    Nothing,
    /// Light passes, but the lobes give one end no projected area along
    /// the centres' direction: the pair must be opened.
    Unrepresentable,
}

/// What [`Clusters::sample`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Sampled {
    /// No pair of points faced each other.
    Nothing,
    /// A ray got through.
    Seen,
    /// Every ray was blocked.
    Blocked,
}

impl Clusters {
    /// Projected area of node `n` seen from unit direction `toward`
    /// (pointing away from it): exact for a patch, by lobes for a cluster.
    pub(super) fn projected(&self, scene: &Scene, n: Node, toward: DVec3) -> f64 {
        match n {
            Node::Patch(p) => {
                let patch = &scene.patches[p as usize];
                patch.area * patch.normal.dot(toward).max(0.0)
            }
            Node::Cluster(c) => dot(&self.tree.clusters[c as usize].projected, &lobes(toward)),
        }
    }

    /// The pairs of points of `r` and `s` its rays join, uniform by area,
    /// in order: [`CLUSTER_RAYS`] stratified pairs, then [`RETRY_RAYS`] more
    /// (`visit` says whether the first ones will do). `visit` sees pair i:
    /// x, y, the source patch holding y, and the kernel cos θ_x cos θ_y / r²
    /// when the two face each other; it returns false to stop.
    fn pairs(
        &self,
        scene: &Scene,
        r: Node,
        s: Node,
        seed: u64,
        mut visit: impl FnMut(usize, DVec3, DVec3, u32, Option<f64>) -> bool,
        mut more: impl FnMut() -> bool,
    ) {
        let t = &self.tree;
        let mut rng = pair_stream(seed, r.key(), s.key());
        let mut i = 0;
        for n in [CLUSTER_RAYS, RETRY_RAYS] {
            for (a, b) in stratified(n, &mut rng)
                .into_iter()
                .zip(stratified(n, &mut rng))
            {
                let (_, x, nx) = t.sample(scene, r, a);
                let (patch, y, ny) = t.sample(scene, s, DVec2::new(b.y, b.x));
                let d = y - x;
                let (cx, cy) = (d.dot(nx), -d.dot(ny));
                // (Coincident points face nothing.)
                let k = (cx > 0.0 && cy > 0.0).then(|| cx * cy / d.length_squared().powi(2));
                if !visit(i, x, y, patch, k) {
                    return;
                }
                i += 1;
            }
            if !more() {
                return;
            }
        }
    }

    /// Casts rays between points of `r` and `s`, uniform by area:
    /// [`CLUSTER_RAYS`] stratified pairs, then [`RETRY_RAYS`] more when
    /// none faced each other. `visit` sees each pair that faces: its index,
    /// its source patch and its kernel cos θ_x cos θ_y / r² when the ray
    /// gets through (`None` when blocked), and returns false to stop.
    /// Returns the pairs drawn and the pairs that faced (rays cast).
    pub(super) fn cast(
        &self,
        scene: &Scene,
        bvh: &TriangleBvh,
        r: Node,
        s: Node,
        seed: u64,
        mut visit: impl FnMut(usize, u32, Option<f64>) -> bool,
    ) -> (u32, u32) {
        let mut pairs = 0u32;
        let valid = std::cell::Cell::new(0u32);
        self.pairs(
            scene,
            r,
            s,
            seed,
            |i, x, y, patch, k| {
                pairs += 1;
                let Some(k) = k else {
                    return true;
                };
                valid.set(valid.get() + 1);
                visit(i, patch, bvh.visible(x, y).then_some(k))
            },
            || valid.get() == 0,
        );
        (pairs, valid.get())
    }

    /// The source points that `link`'s rays (into receiver `r`) reached,
    /// drawn again from its stream without a ray: `visit` sees each one's
    /// patch and kernel cos θ_x cos θ_y / r². Nothing when the link's pairs
    /// are not known.
    pub fn link_samples(
        &self,
        scene: &Scene,
        r: Node,
        link: &ClusterLink,
        seed: u64,
        mut visit: impl FnMut(u32, f64),
    ) {
        if !link.sampled() || link.seen == 0 {
            return;
        }
        let seed = if link.flags & FRESH != 0 { !seed } else { seed };
        self.pairs(
            scene,
            r,
            link.source(),
            seed,
            |i, _, _, patch, k| {
                if link.seen >> i & 1 == 1
                    && let Some(k) = k
                {
                    visit(patch, k);
                }
                i + 1 < CLUSTER_RAYS
            },
            || false,
        );
    }

    /// The mean of `b(patch)` over the source points that `link`'s rays
    /// (into receiver `r`) reached, weighted by their kernels: the
    /// radiosity the link carries ([`Clusters::link_samples`]). `None` when
    /// the link's pairs are not known or none got through.
    pub fn sampled_radiosity(
        &self,
        scene: &Scene,
        r: Node,
        link: &ClusterLink,
        seed: u64,
        b: impl Fn(u32) -> DVec3,
    ) -> Option<DVec3> {
        let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
        self.link_samples(scene, r, link, seed, |patch, k| {
            sum += k * b(patch);
            weight += k;
        });
        (weight > 0.0).then(|| sum / weight)
    }

    /// Whether any ray of [`Clusters::cast`] gets through, stopping at the
    /// first that does, and the rays cast.
    pub(super) fn sample(
        &self,
        scene: &Scene,
        bvh: &TriangleBvh,
        r: Node,
        s: Node,
        seed: u64,
    ) -> (Sampled, u64) {
        let mut seen = false;
        let (_, valid) = self.cast(scene, bvh, r, s, seed, |_, _, k| {
            seen = k.is_some();
            !seen
        });
        let out = match (valid, seen) {
            (0, _) => Sampled::Nothing,
            (_, true) => Sampled::Seen,
            _ => Sampled::Blocked,
        };
        (out, u64::from(valid))
    }

    /// The link (receiver `r`, source `s`) from rays between points of the
    /// two, uniform by area (`fresh`: from the `!seed` stream, independent
    /// of the rays that decided the pair): its visible fraction (of the
    /// rays joining points that face each other) and its coupling, the
    /// Monte Carlo mean of the kernel cos θ_x cos θ_y V / r² over the pairs
    /// scaled so that the link delivers that mean's power through the
    /// lobes; and which pairs got through, with the source weight they give
    /// with the patches' radiosities `elements` (see
    /// [`Clusters::refresh_weights`]). The power the link carries is then
    /// the Monte Carlo estimate over its own rays, whatever the source's
    /// members radiate.
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate(
        &self,
        scene: &Scene,
        elements: &[Element],
        bvh: &TriangleBvh,
        r: Node,
        s: Node,
        seed: u64,
        fresh: bool,
    ) -> (Evaluation, u64) {
        let t = &self.tree;
        let (mut seen, mut kernel, mut mask) = (0u32, 0.0, 0u8);
        let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
        let stream = if fresh { !seed } else { seed };
        let (pairs, valid) = self.cast(scene, bvh, r, s, stream, |i, patch, k| {
            if let Some(k) = k {
                seen += 1;
                kernel += k;
                if i < CLUSTER_RAYS {
                    mask |= 1 << i;
                    sum += k * exposed(&elements[patch as usize]).0;
                    weight += k;
                }
            }
            true
        });
        let rays = u64::from(valid);
        if valid == 0 {
            return (Evaluation::Nothing, rays);
        }
        let d = t.centre(s) - t.centre(r);
        let dir = d.normalize();
        if !(self.projected(scene, r, dir) > 0.0 && self.projected(scene, s, -dir) > 0.0) {
            return (Evaluation::Unrepresentable, rays);
        }
        let area = |n: Node| match n {
            Node::Patch(p) => scene.patches[p as usize].area,
            Node::Cluster(c) => t.clusters[c as usize].area,
        };
        let mean = kernel / f64::from(pairs);
        let mut link = ClusterLink::new(
            s,
            // A form factor is at most 1 either way: a link the budget
            // keeps between touching nodes, whose 1/r² is unbounded, never
            // carries more than its source radiates.
            (area(r) * area(s) * mean / PI).min(area(r).min(area(s))),
            f64::from(seen) / f64::from(valid),
        );
        // Pairs beyond the first CLUSTER_RAYS (drawn when none of those
        // faced) are not kept: such a link carries its source's mean.
        if pairs as usize <= CLUSTER_RAYS {
            link.seen = mask;
            link.flags = if fresh { FRESH } else { 0 };
            if let Node::Cluster(c) = s {
                let mean = self.radiance.toward(c as usize, -dir);
                link.set_weight(source_weight((weight > 0.0).then(|| sum / weight), mean));
            }
        }
        (Evaluation::Link(link), rays)
    }

    /// Sets every cluster link's source weight from the patches'
    /// radiosities `elements` and the clusters' radiance now: the radiosity
    /// of the source points its rays reached over its source cluster's
    /// mean toward the receiver, so that the link carries what its rays
    /// saw leave, not the mean of members they did not see (a louvre's lit
    /// face hidden from a hall by the rest of its cluster). Run before
    /// each solve.
    pub fn refresh_weights(&mut self, scene: &Scene, elements: &[Element], seed: u64) {
        let mut to_cluster = std::mem::take(&mut self.to_cluster);
        let mut to_patch = std::mem::take(&mut self.to_patch);
        let refresh = |r: Node, links: &mut Vec<ClusterLink>| {
            for l in links.iter_mut() {
                let Node::Cluster(c) = l.source() else {
                    continue;
                };
                if !l.sampled() {
                    continue;
                }
                let seen =
                    self.sampled_radiosity(scene, r, l, seed, |p| exposed(&elements[p as usize]).0);
                let d = (self.tree.centre(l.source()) - self.tree.centre(r)).normalize_or_zero();
                l.set_weight(source_weight(seen, self.radiance.toward(c as usize, -d)));
            }
        };
        to_cluster
            .par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .for_each(|(c, ls)| refresh(Node::Cluster(c as u32), ls));
        to_patch
            .par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .for_each(|(p, ls)| refresh(Node::Patch(p as u32), ls));
        self.to_cluster = to_cluster;
        self.to_patch = to_patch;
    }
}

/// Per channel, `seen` (the radiosity a link's rays reached) over `mean`
/// (its source cluster's mean): 1 where the mean is 0 or nothing was seen
/// yet (the solve has not lit the source: the mean carries nothing
/// either), 0 where the rays reached only dark points of a lit source.
fn source_weight(seen: Option<DVec3>, mean: DVec3) -> DVec3 {
    let Some(seen) = seen else {
        return DVec3::ONE;
    };
    DVec3::from_array([0, 1, 2].map(|i| {
        if mean[i] > 0.0 {
            seen[i] / mean[i]
        } else {
            1.0
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cluster_links_pack_their_source_and_visibility() {
        let top = CLUSTER_BIT - 1;
        for node in [
            Node::Patch(0),
            Node::Patch(top),
            Node::Cluster(0),
            Node::Cluster(top),
        ] {
            let link = ClusterLink::new(node, 0.5, 1.0);
            assert_eq!(link.source(), node);
            assert_eq!((link.transfer, link.visibility()), (0.5, 1.0));
            assert_eq!(link.weight(), DVec3::ONE);
        }
        assert_eq!(ClusterLink::new(Node::Patch(3), 0.0, 0.0).visibility(), 0.0);
        let v = ClusterLink::new(Node::Cluster(3), 0.0, 0.3).visibility();
        assert!((v - 0.3).abs() < 1e-4, "{v}");
    }

    #[test]
    fn source_weights_survive_their_encoding() {
        assert_eq!(decode_weight(encode_weight(1.0)), 1.0);
        assert_eq!(decode_weight(encode_weight(0.0)), 0.0);
        for w in [1e-4, 0.013, 0.5, 0.999, 1.7, 42.0, 3e4] {
            let back = decode_weight(encode_weight(w));
            assert!((back / w - 1.0).abs() < 2e-4, "{w} → {back}");
        }
        assert_eq!(encode_weight(f64::INFINITY), u16::MAX);
    }
}
