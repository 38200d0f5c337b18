//! Clusters above the patches ([SAG94], [Sil95]): a binary tree over the
//! input patches with one root, the links that have a cluster at one end
//! or both, their oracle, and the gather and push-pull through the
//! cluster levels.
//!
//! Owns: [`ClusterTree`] (built from an `obvhs` BVH2 over the patches'
//! boxes), [`Clusters`] (the tree, the cluster links, the clusters'
//! radiance) and the cluster oracle [`Clusters::examine`].
//!
//! Transport. A link stores the Monte Carlo estimate of the geometric
//! transfer ∫∫ cos cos V / (π r²) between its two ends (points uniform by
//! area; pairs that do not face each other count as zero), so the power it
//! carries, transfer × the source's mean exposed radiosity toward the
//! receiver, is an unbiased estimate for a uniform source whatever the
//! clusters' shapes. Directions use six half-axis lobes (+x, −x, +y, −y,
//! +z, −z): a patch of normal n counts in lobe a with weight
//! max(0, ±n_a) / |n|₁ (exact for axis-aligned patches). A source
//! cluster's radiance toward d is its exposed power over its exposed area
//! in the lobes of d; a receiver cluster shares a link's power among its
//! patches by the same lobes, per unit of exposed area.
//!
//! Invariants:
//! - Every patch is a leaf of the tree exactly once; a cluster has exactly
//!   two children; parents precede their children in `clusters` (push down
//!   in index order, pull up in reverse). A cluster's patches are the
//!   contiguous run `order[first..first + count]`.
//! - Energy: a link's power is handed out in full to the receiver's
//!   patches (the lobe shares sum to one), and a source cluster's radiance
//!   is the exposed power of its patches; nothing is created or lost
//!   through the cluster levels. What the lobes cannot see is how light
//!   divides between members hidden from each other: the oracle bounds
//!   that by opening links whose sampled visibility is partial or whose
//!   light is bright ([`Clusters::examine`]).
//! - A cluster link joins nodes whose bounding spheres are disjoint; nodes
//!   that touch or overlap are opened until both are patches, whose pair
//!   goes to the element links of [`crate::hierarchical`]. No step visits
//!   all pairs of patches.
//! - Everything depends only on the scene, the seed and the order of the
//!   pairs: rays come from `pair_stream(seed, r, s)` keyed by the two nodes.

use std::f64::consts::PI;
use std::time::Duration;

use glam::{DVec2, DVec3, Vec3A};
use obvhs::{BvhBuildParams, aabb::Aabb, bvh2::builder::build_bvh2};
use rayon::prelude::*;

use crate::hierarchical::hierarchy::Element;
use crate::sampling::{pair_stream, point_in_polygon, stratified};
use crate::scene::{Scene, polygon_centroid};
use crate::visibility::TriangleBvh;

/// A node of the cluster tree: a cluster or an input patch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Node {
    Cluster(u32),
    Patch(u32),
}

impl Node {
    /// The key of the node's random streams (patches from 0 up, clusters
    /// from the top down).
    fn key(self) -> u32 {
        match self {
            Node::Patch(p) => p,
            Node::Cluster(c) => u32::MAX - c,
        }
    }
}

/// Six half-axis lobe weights.
type Lobes = [f64; 6];

/// The weights of a unit direction on the six half-axis lobes: the
/// positive and negative parts of its components.
pub fn lobes(d: DVec3) -> Lobes {
    [
        d.x.max(0.0),
        (-d.x).max(0.0),
        d.y.max(0.0),
        (-d.y).max(0.0),
        d.z.max(0.0),
        (-d.z).max(0.0),
    ]
}

/// A normal's lobes scaled to sum to 1: how a patch's power or area is
/// shared among the lobes.
pub fn normal_lobes(n: DVec3) -> Lobes {
    let l = lobes(n);
    let sum: f64 = l.iter().sum();
    if sum > 0.0 { l.map(|w| w / sum) } else { l }
}

fn dot(a: &Lobes, b: &Lobes) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// A patch root's exposed radiosity and exposed fraction: what its
/// cluster radiates and over how much of its area.
fn exposed(root: &Element) -> (DVec3, f64) {
    (root.exposed_radiosity, f64::from(root.exposure))
}

fn dot3(a: &[DVec3; 6], b: &Lobes) -> DVec3 {
    a.iter().zip(b).map(|(x, y)| *x * *y).sum()
}

/// One cluster: two children, its patches, and the bounds the oracle uses.
#[derive(Clone, Debug, PartialEq)]
pub struct Cluster {
    /// Area-weighted centroid of the patches.
    pub centre: DVec3,
    /// Radius of a sphere about `centre` holding every patch.
    pub radius: f64,
    /// Total patch area.
    pub area: f64,
    /// Largest reflectance channel of any patch.
    pub reflectance: f64,
    /// Σ A · normal_lobes(n) over the patches: the area seen from
    /// direction −d is about `projected · lobes(d)`.
    pub projected: Lobes,
    pub kids: [Node; 2],
    /// The patches are `order[first..first + count]`.
    pub first: u32,
    pub count: u32,
}

/// The cluster tree of a scene.
#[derive(Clone, Debug)]
pub struct ClusterTree {
    /// Parents before children; cluster 0 is the root when there are two
    /// patches or more.
    pub clusters: Vec<Cluster>,
    /// The patches in tree order (each cluster's are contiguous).
    pub order: Vec<u32>,
    /// Running sums of patch area over `order` (one more entry).
    cumulative_area: Vec<f64>,
    /// Centroid and bounding radius of each patch.
    patch_centre: Vec<DVec3>,
    patch_radius: Vec<f64>,
    /// The root, `None` for a scene without patches.
    pub root: Option<Node>,
    pub build_time: Duration,
}

impl ClusterTree {
    /// Builds the tree from a BVH2 over the patches' boxes (one patch per
    /// leaf; a leaf holding several is split in halves).
    pub fn new(scene: &Scene) -> ClusterTree {
        let start = std::time::Instant::now();
        let n = scene.patches.len();
        let patch_centre: Vec<DVec3> = scene
            .patches
            .iter()
            .map(|p| polygon_centroid(p.vertices()))
            .collect();
        let patch_radius = scene
            .patches
            .iter()
            .zip(&patch_centre)
            .map(|(p, c)| {
                p.vertices()
                    .iter()
                    .map(|v| v.distance(*c))
                    .fold(0.0, f64::max)
            })
            .collect();
        let mut tree = ClusterTree {
            clusters: Vec::with_capacity(n.saturating_sub(1)),
            order: Vec::with_capacity(n),
            cumulative_area: Vec::new(),
            patch_centre,
            patch_radius,
            root: None,
            build_time: Duration::ZERO,
        };
        if n > 0 {
            let boxes: Vec<Aabb> = scene
                .patches
                .iter()
                .map(|p| {
                    let pts: Vec<Vec3A> = p
                        .vertices()
                        .iter()
                        .map(|v| Vec3A::from(v.as_vec3()))
                        .collect();
                    Aabb::from_points(&pts)
                })
                .collect();
            let params = BvhBuildParams {
                max_prims_per_leaf: 1,
                ..BvhBuildParams::fast_build()
            };
            let mut core = Duration::ZERO;
            let bvh = build_bvh2(&boxes, params, &mut core);
            tree.root = Some(tree.add_node(scene, &bvh, 0));
        }
        let mut sum = 0.0;
        tree.cumulative_area.push(0.0);
        for &p in &tree.order {
            sum += scene.patches[p as usize].area;
            tree.cumulative_area.push(sum);
        }
        tree.build_time = start.elapsed();
        tree
    }

    fn add_node(&mut self, scene: &Scene, bvh: &obvhs::bvh2::Bvh2, index: usize) -> Node {
        let node = &bvh.nodes[index];
        if node.prim_count > 0 {
            let first = node.first_index as usize;
            let prims = &bvh.primitive_indices[first..first + node.prim_count as usize];
            return self.add_list(scene, prims);
        }
        let c = self.open();
        let first = node.first_index as usize;
        let a = self.add_node(scene, bvh, first);
        let b = self.add_node(scene, bvh, first + 1);
        self.close(scene, c, [a, b]);
        Node::Cluster(c)
    }

    fn add_list(&mut self, scene: &Scene, prims: &[u32]) -> Node {
        if let [p] = prims {
            self.order.push(*p);
            return Node::Patch(*p);
        }
        let c = self.open();
        let (l, r) = prims.split_at(prims.len() / 2);
        let a = self.add_list(scene, l);
        let b = self.add_list(scene, r);
        self.close(scene, c, [a, b]);
        Node::Cluster(c)
    }

    /// A new cluster whose patches start at the current end of `order`.
    fn open(&mut self) -> u32 {
        self.clusters.push(Cluster {
            centre: DVec3::ZERO,
            radius: 0.0,
            area: 0.0,
            reflectance: 0.0,
            projected: [0.0; 6],
            kids: [Node::Patch(0); 2],
            first: self.order.len() as u32,
            count: 0,
        });
        (self.clusters.len() - 1) as u32
    }

    /// Fills cluster `c` from its two children.
    fn close(&mut self, scene: &Scene, c: u32, kids: [Node; 2]) {
        let (mut area, mut moment, mut reflectance, mut projected) =
            (0.0, DVec3::ZERO, 0.0f64, [0.0; 6]);
        for k in kids {
            let (a, centre, rho, proj) = match k {
                Node::Patch(p) => {
                    let patch = &scene.patches[p as usize];
                    let w = normal_lobes(patch.normal);
                    (
                        patch.area,
                        self.patch_centre[p as usize],
                        patch.reflectance.max_element(),
                        w.map(|x| x * patch.area),
                    )
                }
                Node::Cluster(k) => {
                    let k = &self.clusters[k as usize];
                    (k.area, k.centre, k.reflectance, k.projected)
                }
            };
            area += a;
            moment += a * centre;
            reflectance = reflectance.max(rho);
            for (p, q) in projected.iter_mut().zip(proj) {
                *p += q;
            }
        }
        let centre = if area > 0.0 {
            moment / area
        } else {
            0.5 * (self.centre(kids[0]) + self.centre(kids[1]))
        };
        let radius = kids
            .iter()
            .map(|&k| centre.distance(self.centre(k)) + self.radius(k))
            .fold(0.0, f64::max);
        let first = self.clusters[c as usize].first;
        self.clusters[c as usize] = Cluster {
            centre,
            radius,
            area,
            reflectance,
            projected,
            kids,
            first,
            count: self.order.len() as u32 - first,
        };
    }

    /// Centre of a node.
    pub fn centre(&self, n: Node) -> DVec3 {
        match n {
            Node::Patch(p) => self.patch_centre[p as usize],
            Node::Cluster(c) => self.clusters[c as usize].centre,
        }
    }

    /// Bounding radius of a node about its centre.
    pub fn radius(&self, n: Node) -> f64 {
        match n {
            Node::Patch(p) => self.patch_radius[p as usize],
            Node::Cluster(c) => self.clusters[c as usize].radius,
        }
    }

    /// A value per cluster made from its two children's, bottom up:
    /// `patch(p)` for a patch, `join` of the two for a cluster.
    pub fn fold_up<T: Copy + Default>(
        &self,
        patch: impl Fn(u32) -> T,
        join: impl Fn(T, T) -> T,
    ) -> Vec<T> {
        let mut out = vec![T::default(); self.len()];
        for c in (0..self.len()).rev() {
            let [a, b] = self.clusters[c].kids.map(|k| match k {
                Node::Patch(p) => patch(p),
                Node::Cluster(k) => out[k as usize],
            });
            out[c] = join(a, b);
        }
        out
    }

    /// Number of clusters.
    pub fn len(&self) -> usize {
        self.clusters.len()
    }

    /// True when there are no clusters (fewer than two patches).
    pub fn is_empty(&self) -> bool {
        self.clusters.is_empty()
    }

    /// A point of node `n` and the normal there, from a point `u` of the
    /// unit square: the patch by area, then a point in it.
    fn sample(&self, scene: &Scene, n: Node, u: DVec2) -> (DVec3, DVec3) {
        let (p, u) = match n {
            Node::Patch(p) => (p, u),
            Node::Cluster(c) => {
                let c = &self.clusters[c as usize];
                let (lo, hi) = (c.first as usize, (c.first + c.count) as usize);
                let sums = &self.cumulative_area[lo..=hi];
                let t = sums[0] + u.x * (sums[hi - lo] - sums[0]);
                // The last running sum at or below t.
                let j = sums.partition_point(|&s| s <= t).clamp(1, hi - lo) - 1;
                let width = sums[j + 1] - sums[j];
                let ux = if width > 0.0 {
                    ((t - sums[j]) / width).clamp(0.0, 1.0)
                } else {
                    0.5
                };
                (self.order[lo + j], DVec2::new(ux, u.y))
            }
        };
        let patch = &scene.patches[p as usize];
        (point_in_polygon(patch.vertices(), u), patch.normal)
    }

    /// Checks the invariants of the module doc against `scene`; the first
    /// violation is returned as a message.
    pub fn validate(&self, scene: &Scene) -> Result<(), String> {
        let n = scene.patches.len();
        let mut seen = vec![false; n];
        for &p in &self.order {
            if std::mem::replace(&mut seen[p as usize], true) {
                return Err(format!("patch {p} appears twice"));
            }
        }
        if self.order.len() != n || (n > 1 && self.clusters.len() != n - 1) {
            return Err(format!(
                "{} patches, {} in the tree, {} clusters",
                n,
                self.order.len(),
                self.clusters.len()
            ));
        }
        for (i, c) in self.clusters.iter().enumerate() {
            let mut patches: Vec<u32> = Vec::new();
            for k in c.kids {
                match k {
                    Node::Patch(p) => patches.push(p),
                    Node::Cluster(k) if k as usize <= i => {
                        return Err(format!("cluster {i} has child {k} before it"));
                    }
                    Node::Cluster(k) => {
                        let k = &self.clusters[k as usize];
                        patches.extend(&self.order[k.first as usize..(k.first + k.count) as usize]);
                    }
                }
            }
            let run = &self.order[c.first as usize..(c.first + c.count) as usize];
            let mut a = patches.clone();
            let mut b = run.to_vec();
            a.sort_unstable();
            b.sort_unstable();
            if a != b {
                return Err(format!(
                    "cluster {i}: its run is not its children's patches"
                ));
            }
            let area: f64 = run.iter().map(|&p| scene.patches[p as usize].area).sum();
            if (area - c.area).abs() > 1e-9 * area.max(1e-300) {
                return Err(format!("cluster {i}: area {} for {area}", c.area));
            }
            for &p in run {
                for v in scene.patches[p as usize].vertices() {
                    if v.distance(c.centre) > c.radius * (1.0 + 1e-9) + 1e-12 {
                        return Err(format!("cluster {i}: patch {p} outside its sphere"));
                    }
                }
            }
        }
        Ok(())
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.clusters.capacity() * size_of::<Cluster>()
            + self.order.capacity() * size_of::<u32>()
            + (self.cumulative_area.capacity() + self.patch_radius.capacity()) * size_of::<f64>()
            + self.patch_centre.capacity() * size_of::<DVec3>()
    }
}

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
const _: () = assert!(crate::load::MAX_TRIANGLES < CLUSTER_BIT as usize);
const _: () = assert!(std::mem::size_of::<ClusterLink>() == 12);

impl ClusterLink {
    fn new(source: Node, transfer: f64, visibility: f64) -> ClusterLink {
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

/// Receivers reflecting less than this count as reflecting this much in
/// the oracle: what a black surface absorbs is still reported.
const RHO_FLOOR: f64 = 0.05;

/// What [`Clusters::evaluate`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Evaluation {
    Link(ClusterLink),
    /// No pair of points faced each other.
    Nothing,
    /// Light passes, but the lobes give one end no projected area along
    /// the centres' direction: the pair must be opened.
    Unrepresentable,
}

/// What [`Clusters::sample`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Sampled {
    /// No pair of points faced each other.
    Nothing,
    /// A ray got through.
    Seen,
    /// Every ray was blocked.
    Blocked,
}

/// What the oracle decided for a (receiver, source) pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Nothing passes (back to back, or fully occluded).
    Drop,
    /// Keep the link.
    Accept(ClusterLink),
    /// A cluster's link to itself: its children's pairs replace it.
    SelfLink(u32),
    /// Open the receiver (a cluster) / the source (a cluster).
    OpenReceiver,
    OpenSource,
    /// Two patches: for the element links.
    Patches,
}

/// What the clusters radiate, per lobe: the exposed power and the
/// exposed area it leaves from.
#[derive(Clone, Debug, Default)]
pub struct Radiance {
    /// Σ B_exposed · A · exposure · normal_lobes(n) over the patches (W).
    power: Vec<[DVec3; 6]>,
    /// Σ A · exposure · normal_lobes(n) over the patches (m²).
    area: Vec<Lobes>,
}

impl Radiance {
    /// Mean exposed radiosity of cluster `c` seen from direction `out`
    /// (unit, pointing away from it).
    fn toward(&self, c: usize, out: DVec3) -> DVec3 {
        let w = lobes(out);
        let a = dot(&self.area[c], &w);
        if a > 0.0 {
            dot3(&self.power[c], &w) / a
        } else {
            DVec3::ZERO
        }
    }
}

/// The tree, the cluster links and the clusters' radiosity during a solve.
#[derive(Clone, Debug)]
pub struct Clusters {
    pub tree: ClusterTree,
    radiance: Radiance,
    /// Links gathered by each cluster.
    pub to_cluster: Vec<Vec<ClusterLink>>,
    /// Links from clusters gathered by each patch.
    pub to_patch: Vec<Vec<ClusterLink>>,
    /// Importance weights in [0, 1] of the patches and (the largest of
    /// their patches') of the clusters; empty: 1.
    patch_weight: Vec<f64>,
    cluster_weight: Vec<f64>,
}

impl Clusters {
    /// The tree of `scene` with no links, radiating the patches' emission.
    pub fn new(scene: &Scene) -> Clusters {
        let tree = ClusterTree::new(scene);
        let mut c = Clusters {
            radiance: Radiance::default(),
            to_cluster: vec![Vec::new(); tree.len()],
            to_patch: vec![Vec::new(); scene.patches.len()],
            patch_weight: Vec::new(),
            cluster_weight: Vec::new(),
            tree,
        };
        c.radiance = c.pull(scene, |p| (scene.patches[p].emission, 1.0));
        c
    }

    /// Number of cluster links.
    pub fn link_count(&self) -> u64 {
        self.to_cluster
            .iter()
            .chain(&self.to_patch)
            .map(|l| l.len() as u64)
            .sum()
    }

    /// Bytes held (tree, links, radiance).
    pub fn memory_bytes(&self) -> u64 {
        let lists = (self.to_cluster.capacity() + self.to_patch.capacity())
            * std::mem::size_of::<Vec<ClusterLink>>();
        let links: usize = self
            .to_cluster
            .iter()
            .chain(&self.to_patch)
            .map(|l| l.capacity() * std::mem::size_of::<ClusterLink>())
            .sum();
        let radiance = self.radiance.power.capacity() * std::mem::size_of::<[DVec3; 6]>()
            + self.radiance.area.capacity() * std::mem::size_of::<Lobes>();
        (self.tree.memory_bytes() + lists + links + radiance) as u64
    }

    /// The links gathered by `receiver`.
    pub fn links(&self, receiver: Node) -> &[ClusterLink] {
        match receiver {
            Node::Cluster(c) => &self.to_cluster[c as usize],
            Node::Patch(p) => &self.to_patch[p as usize],
        }
    }

    fn links_mut(&mut self, receiver: Node) -> &mut Vec<ClusterLink> {
        match receiver {
            Node::Cluster(c) => &mut self.to_cluster[c as usize],
            Node::Patch(p) => &mut self.to_patch[p as usize],
        }
    }

    /// Sets the patches' importance weights; a cluster takes its largest.
    pub fn set_weights(&mut self, patch: &[f64]) {
        self.cluster_weight = self.tree.fold_up(|p| patch[p as usize], f64::max);
        self.patch_weight = patch.to_vec();
    }

    /// The importance weight of node `n` (1 without importance).
    fn weight(&self, n: Node) -> f64 {
        match n {
            Node::Patch(p) => self.patch_weight.get(p as usize),
            Node::Cluster(c) => self.cluster_weight.get(c as usize),
        }
        .copied()
        .unwrap_or(1.0)
    }

    /// Keeps `link` with `receiver`.
    pub fn add(&mut self, receiver: Node, link: ClusterLink) {
        self.links_mut(receiver).push(link);
    }

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

    /// An upper bound of `source`'s intensity in any direction (W/sr,
    /// largest channel).
    fn intensity_bound(&self, scene: &Scene, elements: &[Element], source: Node) -> f64 {
        match source {
            Node::Patch(p) => {
                let (b, exposure) = exposed(&elements[p as usize]);
                b.max_element() * exposure * scene.patches[p as usize].area / PI
            }
            Node::Cluster(c) => {
                let w = &self.radiance.power[c as usize];
                let axis = |a: usize| w[2 * a].max_element().max(w[2 * a + 1].max_element());
                (axis(0).powi(2) + axis(1).powi(2) + axis(2).powi(2)).sqrt() / PI
            }
        }
    }

    /// The least and greatest distance between points of the bounding
    /// spheres of `r` and `s` (the least is negative when they overlap).
    fn distances(&self, r: Node, s: Node) -> (f64, f64) {
        let t = &self.tree;
        let gap = t.centre(r).distance(t.centre(s));
        let reach = t.radius(r) + t.radius(s);
        (gap - reach, gap + reach)
    }

    /// True when the bounding spheres of `r` and `s` are disjoint: a link
    /// between them has a bounded kernel (1/r² ≤ 1/r_min²).
    pub fn separated(&self, r: Node, s: Node) -> bool {
        self.distances(r, s).0 > 0.0
    }

    /// The oracle's error of a link (receiver `r`, source `s`) with
    /// visible fraction `v`: the largest change of radiosity, ρ_r times
    /// irradiance, that treating the two as points can make over the
    /// receiver, W/m². Infinite when their spheres touch. Least at v = 0
    /// (what a gap missed by the rays could carry), greatest at v = ½ or 1.
    fn error(&self, scene: &Scene, elements: &[Element], r: Node, s: Node, v: f64) -> f64 {
        let t = &self.tree;
        let (r_min, r_max) = self.distances(r, s);
        if !(r_min > 0.0) {
            return f64::INFINITY;
        }
        let rho = match r {
            Node::Patch(p) => scene.patches[p as usize].reflectance.max_element(),
            Node::Cluster(c) => t.clusters[c as usize].reflectance,
        }
        .max(RHO_FLOOR)
            * self.weight(r);
        let i = self.intensity_bound(scene, elements, s);
        if i == 0.0 {
            return 0.0;
        }
        // The spread of 1/r² over the pair, for the light that gets
        // through (V of it), and what a shadow edge or a member hidden from
        // the source can change: min(V, 1 − V) of the nearest irradiance.
        // Both at least 1/CLUSTER_RAYS of their whole (that many rays
        // cannot rule a gap out).
        let floor = 1.0 / CLUSTER_RAYS as f64;
        let near = rho * i / (r_min * r_min);
        rho * i * (1.0 / (r_min * r_min) - 1.0 / (r_max * r_max)) * v.max(floor)
            + near * v.min(1.0 - v).max(floor)
    }

    /// The oracle on pair (receiver `r`, source `s`) with patch
    /// radiosities from `elements` and threshold `eps` (W/m²): which step
    /// to take, and the visibility rays it cast. Rays are cast only for a
    /// pair that some visibility would let pass: when only a wholly blocked
    /// one would, the first ray that gets through opens it. A partly
    /// visible pair whose shadow could exceed `eps` is opened.
    #[allow(clippy::too_many_arguments)]
    pub fn examine(
        &self,
        scene: &Scene,
        bvh: &TriangleBvh,
        elements: &[Element],
        r: Node,
        s: Node,
        eps: f64,
        seed: u64,
    ) -> (Step, u64) {
        let t = &self.tree;
        match (r, s) {
            (Node::Patch(a), Node::Patch(b)) if a == b => return (Step::Drop, 0),
            (Node::Cluster(a), Node::Cluster(b)) if a == b => return (Step::SelfLink(a), 0),
            (Node::Patch(_), Node::Patch(_)) => return (Step::Patches, 0),
            _ => {}
        }
        // Back to back: nothing of the other lies in front of a patch.
        let in_front = |p: Node, other: Node| match p {
            Node::Patch(k) => {
                let patch = &scene.patches[k as usize];
                (t.centre(other) - patch.corners[0]).dot(patch.normal) > -t.radius(other)
            }
            Node::Cluster(_) => true,
        };
        if !in_front(r, s) || !in_front(s, r) {
            return (Step::Drop, 0);
        }
        let open = if t.radius(r) >= t.radius(s) && matches!(r, Node::Cluster(_))
            || matches!(s, Node::Patch(_))
        {
            Step::OpenReceiver
        } else {
            Step::OpenSource
        };
        // Not even a wholly blocked pair would do.
        if self.error(scene, elements, r, s, 0.0) > eps {
            return (open, 0);
        }
        if self.error(scene, elements, r, s, 1.0) > eps {
            // Only a blocked pair would do: one ray that gets through
            // opens it. When none does, the kept value comes from fresh
            // rays (these ones chose the pair for seeing nothing).
            return match self.sample(scene, bvh, r, s, seed) {
                (Sampled::Nothing, rays) => (Step::Drop, rays),
                (Sampled::Seen, rays) => (open, rays),
                (Sampled::Blocked, rays) => {
                    let (again, more) = self.evaluate(scene, bvh, r, s, !seed);
                    match again {
                        Evaluation::Link(l) => (Step::Accept(l), rays + more),
                        Evaluation::Unrepresentable => (open, rays + more),
                        Evaluation::Nothing => (Step::Drop, rays + more),
                    }
                }
            };
        }
        let (evaluation, rays) = self.evaluate(scene, bvh, r, s, seed);
        match evaluation {
            Evaluation::Nothing => (Step::Drop, rays),
            Evaluation::Unrepresentable => (open, rays),
            Evaluation::Link(l) if self.error(scene, elements, r, s, l.visibility()) > eps => {
                (open, rays)
            }
            Evaluation::Link(l) if self.error(scene, elements, r, s, 0.5) <= eps => {
                // Accepted whatever the visibility: the decision did not
                // hang on these rays, so their estimate is kept.
                (Step::Accept(l), rays)
            }
            Evaluation::Link(_) => {
                // The kept value comes from fresh rays: the ones that
                // decided would favour links whose sample saw no shadow.
                let (again, more) = self.evaluate(scene, bvh, r, s, !seed);
                match again {
                    Evaluation::Link(l) => (Step::Accept(l), rays + more),
                    _ => (Step::Drop, rays + more),
                }
            }
        }
    }

    /// True when the oracle, with the current radiosities, would open the
    /// kept link (receiver `r`, `link`).
    pub fn rejects(
        &self,
        scene: &Scene,
        elements: &[Element],
        r: Node,
        link: &ClusterLink,
        eps: f64,
    ) -> bool {
        self.error(scene, elements, r, link.source(), link.visibility()) > eps
    }

    /// Projected area of node `n` seen from unit direction `toward`
    /// (pointing away from it): exact for a patch, by lobes for a cluster.
    fn projected(&self, scene: &Scene, n: Node, toward: DVec3) -> f64 {
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
    fn cast(
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
    fn sample(
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

    /// Adds the irradiance the cluster links deliver to each patch to
    /// `gathered[patch]`, with the sources' radiance `radiance` (clusters)
    /// and `patch(p)` (patches: exposed radiosity, exposed fraction). A
    /// link delivers its transfer times the source's mean exposed
    /// radiosity toward the receiver; a patch takes it over its area; a
    /// cluster shares it by lobes, per unit of exposed projected area, and
    /// pushes that down the tree, each patch taking its share by its own
    /// normal and exposure.
    pub fn gather_with(
        &self,
        scene: &Scene,
        radiance: &Radiance,
        patch: impl Fn(usize) -> (DVec3, f64) + Sync,
        gathered: &mut [DVec3],
    ) {
        let t = &self.tree;
        // (direction, power) of each link gathered by `r`.
        let incoming = |r: Node, ls: &[ClusterLink]| -> Vec<(DVec3, DVec3)> {
            ls.iter()
                .map(|l| {
                    let d = (t.centre(l.source()) - t.centre(r)).normalize_or_zero();
                    let b = match l.source() {
                        Node::Patch(p) => patch(p as usize).0,
                        Node::Cluster(c) => radiance.toward(c as usize, -d),
                    };
                    (d, b * f64::from(l.transfer))
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
                        let exposure = patch(p as usize).1;
                        gathered[p as usize] += dot3(&here, &normal_lobes(n)) * exposure;
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

    /// [`Clusters::gather_with`] with the patch roots' radiosities.
    pub fn gather(&self, scene: &Scene, elements: &[Element], gathered: &mut [DVec3]) {
        self.gather_with(scene, &self.radiance, |p| exposed(&elements[p]), gathered);
    }

    /// Irradiance per patch from the cluster links: all of it, and the part
    /// that comes from the sources' emission.
    pub fn patch_irradiance(
        &self,
        scene: &Scene,
        elements: &[Element],
    ) -> (Vec<DVec3>, Vec<DVec3>) {
        let n = scene.patches.len();
        let mut total = vec![DVec3::ZERO; n];
        self.gather(scene, elements, &mut total);
        let emitted = |p: usize| (scene.patches[p].emission, exposed(&elements[p]).1);
        let radiance = self.pull(scene, emitted);
        let mut direct = vec![DVec3::ZERO; n];
        self.gather_with(scene, &radiance, emitted, &mut direct);
        (total, direct)
    }

    /// Removes and returns the links the oracle now rejects, as (receiver,
    /// source) pairs in a fixed order.
    pub fn take_rejected(
        &mut self,
        scene: &Scene,
        elements: &[Element],
        eps: f64,
    ) -> Vec<(Node, Node)> {
        let receivers: Vec<Node> = (0..self.to_cluster.len() as u32)
            .map(Node::Cluster)
            .chain((0..self.to_patch.len() as u32).map(Node::Patch))
            .collect();
        let marked: Vec<Vec<bool>> = receivers
            .par_iter()
            .with_min_len(256)
            .map(|&r| {
                self.links(r)
                    .iter()
                    .map(|l| self.rejects(scene, elements, r, l, eps))
                    .collect()
            })
            .collect();
        let mut out = Vec::new();
        for (r, marks) in receivers.into_iter().zip(marked) {
            if !marks.contains(&true) {
                continue;
            }
            let own = std::mem::take(self.links_mut(r));
            for (l, reject) in own.into_iter().zip(marks) {
                if reject {
                    out.push((r, l.source()));
                } else {
                    self.links_mut(r).push(l);
                }
            }
        }
        out
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

    /// The children of cluster `c`.
    pub fn kids(&self, c: u32) -> [Node; 2] {
        self.tree.clusters[c as usize].kids
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_lobes_share_one_and_are_exact_on_axes() {
        for n in [DVec3::X, -DVec3::Y, DVec3::new(1.0, 2.0, -2.0).normalize()] {
            let w = normal_lobes(n);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        // An axis-aligned normal: the lobe cosine is the true cosine.
        let d = DVec3::new(0.3, -0.5, 0.8).normalize();
        for n in [
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ] {
            let exact = n.dot(d).max(0.0);
            assert!((dot(&normal_lobes(n), &lobes(d)) - exact).abs() < 1e-12);
        }
    }

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
