//! Cluster links and their evaluation: a link with a cluster at one end
//! or both stores the Monte Carlo estimate of the geometric transfer
//! ∫∫ cos cos V / (π r²) between its two ends, from stratified point pairs
//! uniform by area.
//!
//! Invariants: a link is twelve bytes (packed source, f32 transfer,
//! fixed-point visibility); its transfer never exceeds the smaller end's
//! area (a form factor is at most 1 either way); rays come from
//! `pair_stream(seed, r, s)` keyed by the two nodes.

use std::f64::consts::PI;

use glam::{DVec2, DVec3};

use super::lobes::{dot, lobes};
use super::{Clusters, Node};
use crate::sampling::{pair_stream, stratified};
use crate::scene::Scene;
use crate::visibility::TriangleBvh;

/// A link into a cluster or a patch from a cluster or a patch (at least
/// one of the two a cluster), kept with its receiver.
///
/// Twelve bytes: the scale-up scenes keep tens of millions. (Its direction
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
}

/// Marks a cluster in [`ClusterLink`]'s packed source: patch and cluster
/// indices stay below it (the loader's triangle cap is far lower).
const CLUSTER_BIT: u32 = 1 << 31;
const _: () = assert!(crate::scene::MAX_TRIANGLES < CLUSTER_BIT as usize);
const _: () = assert!(std::mem::size_of::<ClusterLink>() == 12);

impl ClusterLink {
    pub(super) fn new(source: Node, transfer: f64, visibility: f64) -> ClusterLink {
        let source = match source {
            Node::Patch(p) => p,
            Node::Cluster(c) => c | CLUSTER_BIT,
        };
        ClusterLink {
            source,
            transfer: transfer as f32,
            visibility: (visibility.clamp(0.0, 1.0) * f64::from(u16::MAX)).round() as u16,
        }
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

    /// Casts rays between points of `r` and `s`, uniform by area:
    /// [`CLUSTER_RAYS`] stratified pairs, then [`RETRY_RAYS`] more when
    /// none faced each other. `visit` sees each pair that faces: its kernel
    /// cos θ_x cos θ_y / r² when the ray gets through, `None` when blocked,
    /// and returns false to stop. Returns the pairs drawn and the
    /// pairs that faced (rays cast).
    pub(super) fn cast(
        &self,
        scene: &Scene,
        bvh: &TriangleBvh,
        r: Node,
        s: Node,
        seed: u64,
        mut visit: impl FnMut(Option<f64>) -> bool,
    ) -> (u32, u32) {
        let t = &self.tree;
        let mut rng = pair_stream(seed, r.key(), s.key());
        let (mut pairs, mut valid) = (0u32, 0u32);
        for n in [CLUSTER_RAYS, RETRY_RAYS] {
            for (a, b) in stratified(n, &mut rng)
                .into_iter()
                .zip(stratified(n, &mut rng))
            {
                pairs += 1;
                let (x, nx) = t.sample(scene, r, a);
                let (y, ny) = t.sample(scene, s, DVec2::new(b.y, b.x));
                let d = y - x;
                let (cx, cy) = (d.dot(nx), -d.dot(ny));
                // (Coincident points face nothing.)
                if !(cx > 0.0 && cy > 0.0) {
                    continue;
                }
                valid += 1;
                let k = bvh
                    .visible(x, y)
                    .then(|| cx * cy / d.length_squared().powi(2));
                if !visit(k) {
                    return (pairs, valid);
                }
            }
            if valid > 0 {
                break;
            }
        }
        (pairs, valid)
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
        let (_, valid) = self.cast(scene, bvh, r, s, seed, |k| {
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
    /// two, uniform by area: its visible fraction (of the rays joining
    /// points that face each other) and its coupling, the Monte Carlo mean
    /// of the kernel cos θ_x cos θ_y V / r² over the pairs scaled so that
    /// the link delivers that mean's power through the lobes. A uniform
    /// source's transfer is then estimated without bias, whatever the
    /// clusters' shapes.
    pub fn evaluate(
        &self,
        scene: &Scene,
        bvh: &TriangleBvh,
        r: Node,
        s: Node,
        seed: u64,
    ) -> (Evaluation, u64) {
        let t = &self.tree;
        let (mut seen, mut kernel) = (0u32, 0.0);
        let (pairs, valid) = self.cast(scene, bvh, r, s, seed, |k| {
            if let Some(k) = k {
                seen += 1;
                kernel += k;
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
        let link = ClusterLink::new(
            s,
            // A form factor is at most 1 either way: a link the budget
            // keeps between touching nodes, whose 1/r² is unbounded, never
            // carries more than its source radiates.
            (area(r) * area(s) * mean / PI).min(area(r).min(area(s))),
            f64::from(seen) / f64::from(valid),
        );
        (Evaluation::Link(link), rays)
    }
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
        }
        assert_eq!(ClusterLink::new(Node::Patch(3), 0.0, 0.0).visibility(), 0.0);
        let v = ClusterLink::new(Node::Cluster(3), 0.0, 0.3).visibility();
        assert!((v - 0.3).abs() < 1e-4, "{v}");
    }
}
