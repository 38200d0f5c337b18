//! The cluster tree: a binary tree over the input patches with one root,
//! built from an `obvhs` BVH2 over the patches' boxes, with each cluster's
//! centre, bounding sphere, area, largest reflectance and projected area
//! by lobes.
//!
//! Invariants: every patch is a leaf exactly once; a cluster has exactly
//! two children; parents precede their children in `clusters`; a
//! cluster's patches are the contiguous run `order[first..first + count]`
//! ([`ClusterTree::validate`] checks all of it).

use std::time::Duration;

use glam::{DVec2, DVec3, Vec3A};
use obvhs::{BvhBuildParams, aabb::Aabb};

use super::Node;
use super::lobes::{Lobes, normal_lobes};
use crate::sampling::point_in_polygon;
use crate::scene::{Scene, polygon_centroid};

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
    /// The plane (unit normal n, offset d: n · x = d) every patch lies in
    /// facing n, when they all share one ([`ClusterTree::plane`]).
    pub plane: Option<(DVec3, f64)>,
    /// The two children.
    pub kids: [Node; 2],
    /// The patches are `order[first..first + count]`.
    pub first: u32,
    /// Number of patches under the cluster.
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
    /// Wall time the build took.
    pub build_time: Duration,
}

impl ClusterTree {
    /// For each patch, the clusters above it, nearest first.
    pub fn ancestors(&self) -> Vec<Vec<u32>> {
        let mut parent_of_cluster = vec![u32::MAX; self.len()];
        let mut parent_of_patch = vec![u32::MAX; self.order.len()];
        for (c, cl) in self.clusters.iter().enumerate() {
            for k in cl.kids {
                match k {
                    Node::Cluster(k) => parent_of_cluster[k as usize] = c as u32,
                    Node::Patch(p) => parent_of_patch[p as usize] = c as u32,
                }
            }
        }
        parent_of_patch
            .iter()
            .map(|&first| {
                let mut out = Vec::new();
                let mut c = first;
                while c != u32::MAX {
                    out.push(c);
                    c = parent_of_cluster[c as usize];
                }
                out
            })
            .collect()
    }

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
            let bvh = crate::util::boxes::build_bvh2(&boxes, params);
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

    pub(super) fn add_node(
        &mut self,
        scene: &Scene,
        bvh: &obvhs::bvh2::Bvh2,
        index: usize,
    ) -> Node {
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

    pub(super) fn add_list(&mut self, scene: &Scene, prims: &[u32]) -> Node {
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
    pub(super) fn open(&mut self) -> u32 {
        self.clusters.push(Cluster {
            centre: DVec3::ZERO,
            radius: 0.0,
            area: 0.0,
            reflectance: 0.0,
            projected: [0.0; 6],
            plane: None,
            kids: [Node::Patch(0); 2],
            first: self.order.len() as u32,
            count: 0,
        });
        (self.clusters.len() - 1) as u32
    }

    /// Fills cluster `c` from its two children.
    pub(super) fn close(&mut self, scene: &Scene, c: u32, kids: [Node; 2]) {
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
        let plane = match (self.plane(scene, kids[0]), self.plane(scene, kids[1])) {
            (Some(a), Some(b)) if same_plane(a, b, scene.diagonal()) => Some(a),
            _ => None,
        };
        self.clusters[c as usize] = Cluster {
            centre,
            radius,
            area,
            reflectance,
            projected,
            plane,
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

    /// The plane of a node's patches, facing their normal, when they share
    /// one: a patch's own, a cluster's [`Cluster::plane`].
    pub fn plane(&self, scene: &Scene, n: Node) -> Option<(DVec3, f64)> {
        match n {
            Node::Patch(p) => {
                let patch = &scene.patches[p as usize];
                Some((patch.normal, patch.normal.dot(patch.corners[0])))
            }
            Node::Cluster(c) => self.clusters[c as usize].plane,
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

    /// A point of node `n`, its patch and the normal there, from a point
    /// `u` of the unit square: the patch by area, then a point in it.
    pub(super) fn sample(&self, scene: &Scene, n: Node, u: DVec2) -> (u32, DVec3, DVec3) {
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
        (p, point_in_polygon(patch.vertices(), u), patch.normal)
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

/// Two planes (unit normal, offset) are one, facing the same way, to
/// within 10⁻⁶ rad and 10⁻⁷ of the scene's `diagonal`.
pub fn same_plane(a: (DVec3, f64), b: (DVec3, f64), diagonal: f64) -> bool {
    a.0.dot(b.0) >= 1e-6f64.cos() && (a.1 - b.1).abs() <= 1e-7 * diagonal
}
