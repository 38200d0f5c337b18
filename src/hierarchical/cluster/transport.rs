//! Light through the cluster levels: the clusters' radiance pulled up from
//! the patch roots, the cluster links' power gathered and pushed down by
//! lobes to the patches, and which emitters the cluster links bring to
//! each patch.
//!
//! Invariant: a link's power is handed out in full to the receiver's
//! patches (the lobe shares sum to one), and a source cluster's radiance
//! is the exposed power of its patches: nothing is created or lost through
//! the cluster levels.

use glam::DVec3;
use rayon::prelude::*;

use super::link::ClusterLink;
use super::lobes::{Radiance, dot, dot3, lobes, normal_lobes};
use super::{Clusters, Node};
use crate::hierarchical::hierarchy::Element;
use crate::scene::Scene;

/// A patch root's exposed radiosity and exposed fraction: what its
/// cluster radiates and over how much of its area.
pub(super) fn exposed(root: &Element) -> (DVec3, f64) {
    (root.exposed_radiosity, f64::from(root.exposure))
}

impl Clusters {
    /// The clusters' radiance, pulled up from `patch(p)` = (exposed
    /// radiosity, exposed fraction) of each patch.
    pub fn pull(&self, scene: &Scene, patch: impl Fn(usize) -> (DVec3, f64)) -> Radiance {
        let t = &self.tree;
        let mut out = Radiance {
            power: vec![[DVec3::ZERO; 6]; t.len()],
            area: vec![[0.0; 6]; t.len()],
        };
        for c in (0..t.len()).rev() {
            let (mut power, mut area) = ([DVec3::ZERO; 6], [0.0; 6]);
            for k in t.clusters[c].kids {
                let (p, a) = match k {
                    Node::Patch(p) => {
                        let (b, exposure) = patch(p as usize);
                        let patch = &scene.patches[p as usize];
                        let a = normal_lobes(patch.normal).map(|w| w * patch.area * exposure);
                        (a.map(|a| b * a), a)
                    }
                    Node::Cluster(k) => (out.power[k as usize], out.area[k as usize]),
                };
                for i in 0..6 {
                    power[i] += p[i];
                    area[i] += a[i];
                }
            }
            out.power[c] = power;
            out.area[c] = area;
        }
        out
    }

    /// Updates the clusters' radiance from the patch roots.
    pub fn pull_from(&mut self, scene: &Scene, elements: &[Element]) {
        self.radiance = self.pull(scene, |p| exposed(&elements[p]));
    }

    /// Adds the irradiance the cluster links deliver to each patch to
    /// `gathered[patch]`: a link (into receiver r, along unit direction d
    /// from r to its source) delivers its transfer times `carried(r, link,
    /// d)`, the radiosity it carries; a patch takes that over its area; a
    /// cluster shares it by lobes, per unit of exposed projected area, and
    /// pushes that down the tree, each patch taking its share by its own
    /// normal and exposure `exposure(p)`.
    pub fn gather_with(
        &self,
        scene: &Scene,
        exposure: impl Fn(usize) -> f64 + Sync,
        carried: impl Fn(Node, &ClusterLink, DVec3) -> DVec3 + Sync,
        gathered: &mut [DVec3],
    ) {
        let t = &self.tree;
        let radiance = &self.radiance;
        // (direction, power) of each link gathered by `r`.
        let incoming = |r: Node, ls: &[ClusterLink]| -> Vec<(DVec3, DVec3)> {
            ls.iter()
                .map(|l| {
                    let d = (t.centre(l.source()) - t.centre(r)).normalize_or_zero();
                    (d, carried(r, l, d) * f64::from(l.transfer))
                })
                .collect()
        };
        let mut down: Vec<[DVec3; 6]> = self
            .to_cluster
            .par_iter()
            .enumerate()
            .with_min_len(64)
            .map(|(c, ls)| {
                let mut acc = [DVec3::ZERO; 6];
                for (d, power) in incoming(Node::Cluster(c as u32), ls) {
                    let w = lobes(d);
                    let area = dot(&radiance.area[c], &w);
                    if area > 0.0 {
                        for (a, w) in acc.iter_mut().zip(w) {
                            *a += power * (w / area);
                        }
                    }
                }
                acc
            })
            .collect();
        for c in 0..t.len() {
            let here = down[c];
            for k in t.clusters[c].kids {
                match k {
                    Node::Cluster(k) => {
                        for (a, h) in down[k as usize].iter_mut().zip(here) {
                            *a += h;
                        }
                    }
                    Node::Patch(p) => {
                        let n = scene.patches[p as usize].normal;
                        gathered[p as usize] +=
                            dot3(&here, &normal_lobes(n)) * exposure(p as usize);
                    }
                }
            }
        }
        let direct: Vec<DVec3> = self
            .to_patch
            .par_iter()
            .enumerate()
            .with_min_len(256)
            .map(|(p, ls)| {
                let power: DVec3 = incoming(Node::Patch(p as u32), ls)
                    .into_iter()
                    .map(|(_, e)| e)
                    .sum();
                power / scene.patches[p].area
            })
            .collect();
        for (g, d) in gathered.iter_mut().zip(direct) {
            *g += d;
        }
    }

    /// [`Clusters::gather_with`] in the solve: a patch source carries its
    /// exposed radiosity, a cluster source its radiance toward the
    /// receiver times the link's source weight
    /// ([`Clusters::refresh_weights`]).
    pub fn gather(&self, scene: &Scene, elements: &[Element], gathered: &mut [DVec3]) {
        let carried = |_: Node, l: &ClusterLink, d: DVec3| match l.source() {
            Node::Patch(p) => exposed(&elements[p as usize]).0,
            Node::Cluster(c) => self.radiance.toward(c as usize, -d) * l.weight(),
        };
        self.gather_with(scene, |p| exposed(&elements[p]).1, carried, gathered);
    }

    /// Irradiance per patch from the cluster links: all of it, and the part
    /// that comes from the sources' emission. Each link carries what its
    /// own rays reached, from the patches' radiosities as they are now
    /// ([`Clusters::sampled_radiosity`]; its source's mean when its pairs
    /// are not known).
    pub fn patch_irradiance(
        &self,
        scene: &Scene,
        elements: &[Element],
        seed: u64,
    ) -> (Vec<DVec3>, Vec<DVec3>) {
        let n = scene.patches.len();
        let emitted = self.pull(scene, |p| {
            (scene.patches[p].emission, exposed(&elements[p]).1)
        });
        let carried = |emission: bool| {
            let (radiance, emitted) = (&self.radiance, &emitted);
            move |r: Node, l: &ClusterLink, d: DVec3| {
                let b = |p: u32| match emission {
                    true => scene.patches[p as usize].emission,
                    false => exposed(&elements[p as usize]).0,
                };
                match l.source() {
                    Node::Patch(p) => b(p),
                    Node::Cluster(c) => self
                        .sampled_radiosity(scene, r, l, seed, b)
                        .unwrap_or_else(|| {
                            let mean = if emission { emitted } else { radiance };
                            mean.toward(c as usize, -d)
                        }),
                }
            }
        };
        let exposure = |p: usize| exposed(&elements[p]).1;
        let mut total = vec![DVec3::ZERO; n];
        self.gather_with(scene, exposure, carried(false), &mut total);
        let mut direct = vec![DVec3::ZERO; n];
        self.gather_with(scene, exposure, carried(true), &mut direct);
        (total, direct)
    }

    /// For each patch, which of `emitters` (at most 64: bit i stands for
    /// `emitters[i]`) send it light through cluster links: a link that
    /// carries some, whose source holds the emitter, gathered by the patch
    /// or by a cluster above it.
    pub fn emitters_lighting(&self, emitters: &[u32]) -> Vec<u64> {
        assert!(emitters.len() <= 64, "one bit per emitter");
        let t = &self.tree;
        let mut own = vec![0u64; self.to_patch.len()];
        for (i, &k) in emitters.iter().enumerate() {
            own[k as usize] |= 1 << i;
        }
        // The emitters each cluster holds.
        let held = t.fold_up(|p| own[p as usize], |a, b| a | b);
        let sources = |ls: &[ClusterLink]| {
            ls.iter()
                .filter(|l| l.transfer > 0.0)
                .map(|l| match l.source() {
                    Node::Patch(p) => own[p as usize],
                    Node::Cluster(c) => held[c as usize],
                })
                .fold(0, |a, b| a | b)
        };
        let mut out: Vec<u64> = self.to_patch.iter().map(|ls| sources(ls)).collect();
        // What each cluster and those above it gather, parents first.
        let mut above = vec![0u64; t.len()];
        for c in 0..t.len() {
            let here = above[c] | sources(&self.to_cluster[c]);
            for k in t.clusters[c].kids {
                match k {
                    Node::Cluster(k) => above[k as usize] = here,
                    Node::Patch(p) => out[p as usize] |= here,
                }
            }
        }
        out
    }
}
