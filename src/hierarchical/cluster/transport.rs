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

/// One link as the solve's gather reads it ([`Clusters::plan`]).
#[derive(Clone, Copy, Debug)]
struct Term {
    source: Node,
    /// Unit direction from the receiver's centre to the source's.
    direction: [f32; 3],
    /// Transfer times the source weight, per channel (m²).
    carry: [f32; 3],
}

/// The cluster links laid out for the solve's gathers: the terms of
/// receiver i (clusters first, then patches) are
/// `terms[start[i]..start[i + 1]]`. Valid until the links or their
/// weights change.
#[derive(Clone, Debug, Default)]
pub struct Plan {
    start: Vec<u32>,
    terms: Vec<Term>,
}

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
    /// `gathered[patch]`. `incoming(r, take)` calls `take(d, power)` for
    /// each link gathered by receiver `r`, with d the unit direction from
    /// `r` to the link's source and power what the link carries. A patch
    /// takes that over its area; a cluster shares it by lobes, per unit of
    /// exposed projected area, and pushes that down the tree, each patch
    /// taking its share by its own normal and exposure `exposure(p)`.
    fn distribute(
        &self,
        scene: &Scene,
        exposure: impl Fn(usize) -> f64 + Sync,
        incoming: impl Fn(Node, &mut dyn FnMut(DVec3, DVec3)) + Sync,
        gathered: &mut [DVec3],
    ) {
        let t = &self.tree;
        let radiance = &self.radiance;
        let mut down: Vec<[DVec3; 6]> = (0..t.len())
            .into_par_iter()
            .with_min_len(64)
            .map(|c| {
                let mut acc = [DVec3::ZERO; 6];
                incoming(Node::Cluster(c as u32), &mut |d, power| {
                    let w = lobes(d);
                    let area = dot(&radiance.area[c], &w);
                    if area > 0.0 {
                        for (a, w) in acc.iter_mut().zip(w) {
                            *a += power * (w / area);
                        }
                    }
                });
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
        let direct: Vec<DVec3> = (0..self.to_patch.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|p| {
                let mut power = DVec3::ZERO;
                incoming(Node::Patch(p as u32), &mut |_, e| power += e);
                power / scene.patches[p].area
            })
            .collect();
        for (g, d) in gathered.iter_mut().zip(direct) {
            *g += d;
        }
    }

    /// [`Clusters::distribute`] with each link carrying its transfer times
    /// `carried(r, link, d)`, the radiosity it brings receiver r from
    /// direction d.
    fn gather_with(
        &self,
        scene: &Scene,
        exposure: impl Fn(usize) -> f64 + Sync,
        carried: impl Fn(Node, &ClusterLink, DVec3) -> DVec3 + Sync,
        gathered: &mut [DVec3],
    ) {
        let t = &self.tree;
        let incoming = |r: Node, take: &mut dyn FnMut(DVec3, DVec3)| {
            for l in self.links(r) {
                let d = (t.centre(l.source()) - t.centre(r)).normalize_or_zero();
                take(d, carried(r, l, d) * f64::from(l.transfer));
            }
        };
        self.distribute(scene, exposure, incoming, gathered);
    }

    /// What the solve's gathers need of the links, which stay fixed while
    /// it iterates: each link's direction and its transfer times its
    /// source weight ([`Clusters::refresh_weights`]), so an iteration
    /// reads them instead of recomputing them from the tree and the
    /// encoded weights.
    pub fn plan(&self) -> Plan {
        let t = &self.tree;
        let receivers = (0..t.len() as u32)
            .map(Node::Cluster)
            .chain((0..self.to_patch.len() as u32).map(Node::Patch));
        let mut plan = Plan {
            start: vec![0],
            terms: Vec::with_capacity(self.link_count() as usize),
        };
        for r in receivers {
            for l in self.links(r) {
                let s = l.source();
                let d = (t.centre(s) - t.centre(r)).normalize_or_zero();
                let carry = match s {
                    Node::Patch(_) => DVec3::ONE,
                    Node::Cluster(_) => l.weight(),
                } * f64::from(l.transfer);
                plan.terms.push(Term {
                    source: s,
                    direction: d.as_vec3().to_array(),
                    carry: carry.as_vec3().to_array(),
                });
            }
            plan.start.push(plan.terms.len() as u32);
        }
        plan
    }

    /// The solve's gather ([`Clusters::distribute`]) by `plan`, made on
    /// the current links and weights: a patch source carries its exposed
    /// radiosity, a cluster source its radiance toward the receiver.
    pub fn gather(&self, scene: &Scene, elements: &[Element], plan: &Plan, gathered: &mut [DVec3]) {
        let clusters = self.tree.len();
        let incoming = |r: Node, take: &mut dyn FnMut(DVec3, DVec3)| {
            let i = match r {
                Node::Cluster(c) => c as usize,
                Node::Patch(p) => clusters + p as usize,
            };
            let terms = &plan.terms[plan.start[i] as usize..plan.start[i + 1] as usize];
            for term in terms {
                let d = glam::Vec3::from_array(term.direction).as_dvec3();
                let b = match term.source {
                    Node::Patch(p) => exposed(&elements[p as usize]).0,
                    Node::Cluster(c) => self.radiance.toward(c as usize, -d),
                };
                take(d, b * glam::Vec3::from_array(term.carry).as_dvec3());
            }
        };
        self.distribute(scene, |p| exposed(&elements[p]).1, incoming, gathered);
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
