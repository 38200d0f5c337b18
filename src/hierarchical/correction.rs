//! Defect correction: the converged hierarchical solution checked against
//! a ray-traced gather of its own radiosities, and the difference fed back
//! as a fixed irradiance per patch before the links are solved once more.
//!
//! Why. Every link approximates its share of the transport (a form
//! factor from a centroid, a source's mean over the part its rays saw, a
//! cluster's light shared by lobes). Each error is small, but in an
//! interior lit only by bounces the light goes round the room many times
//! and the small excess of every bounce adds up: in the gallery the hall's
//! leaves hold 2.3 % more than a gather of the solution itself gives them,
//! and the hall comes out 7 % too bright. With r the residual of the
//! solution B (what a gather of B by rays gives minus what the links give),
//! solving the links once more with r added,
//! B' = B + (I − ρK_links)⁻¹ ρ r, leaves an error of the links' error
//! times the correction's: second order.
//!
//! The gather (per patch, [`Solver::correct`]): stratified points over the
//! patch's exposed part, each with a cosine-distributed direction; a ray's
//! value is the reflected part of the exposed radiosity of the leaf it
//! hits. Emission is left out on both sides: direct light stays with the
//! links (and the final gather at the vertices), where light sampling
//! resolves small emitters that cosine rays would hardly hit. A patch of
//! at least the mean patch area gets `correction_rays` rays, a smaller
//! one a share in proportion to its area (at least 16), and any patch 16
//! per leaf of its quadtree ([`rays_for`]).
//!
//! Noise. A few hundred rays know a patch's gather to several per cent,
//! more than the residual itself (1–3 %), and fed back as it is the noise
//! would be the new error. Where the light comes through an opening it is
//! worse: a gallery hall wall's rays reach the light well 5 % of the time
//! and bring 38 % of its light from there, so 256 rays know its gather to
//! 15 % (hence the default of 1024; aiming rays at the brightest patches
//! did not narrow it, BENCHMARKS.md). So the residual is used as a share of the
//! links' reflected light, once the share is known: three standard errors
//! from zero, or known to `correction_tolerance` of that light. A patch
//! whose own rays do not know it takes the share pooled over the patches
//! facing its way in the nearest cluster above it that does ([`pooled`]);
//! a share not known even over the whole scene is dropped. Measured with
//! two passes (BENCHMARKS.md): gallery hall +6.9 % → +3.1 %, the corridor's
//! bias +1.4 % → +1.2 %, a furnace at ρ = 0.95 whose links leave Σ B·A
//! 3.4 % off, 0.24 %; the Cornell box, whose links are right to within the
//! rays' noise, unchanged.
//!
//! Small bright sources. Cosine rays sample every source by its solid
//! angle, so a small bright spot (the wall 2 mm from a 1 cm² lamp,
//! `scenes/stress/tiny-emitter.gltf`) is hardly ever hit: the rays' mean
//! is then typically below its expectation and their spread does not show
//! it. A patch's variance is therefore at least what its links predict
//! (`second_moments`: the mean square of the sources' reflected
//! radiosities, weighed by the links' F·V); without that floor two passes
//! took absorbed / emitted there from 1.02 to 0.58, with it 1.02 stays.
//!
//! Twins. A surface made two-sided by a reversed copy of its triangles
//! puts two triangles in one place, and a ray hits either; the patch
//! facing the ray is looked for on both (`front_patches`). Before that,
//! 3.7 % of the rays in a room with a panel and a lamp built so were
//! dropped as back-face hits, the bright panel's among them, and the
//! correction took 11 % of the room's reflected light (absorbed / emitted
//! 0.81; 1.006 since).
//!
//! On by default (two passes). What that cost the suite's tests: a
//! closed box's absorbed power may now exceed the emitted by the rays'
//! noise (≤ 10⁻³, measured 6·10⁻⁴ in the Cornell box), and the history
//! holds one capped solve per pass. `tiny-emitter`'s 2 % excess is the
//! links' (it is there without the correction; `tests/stress.rs` says why).
//!
//! Invariants: the correction depends only on the solution, the seed and
//! the patch (rays are keyed by patch), never on the thread count; a patch
//! that is buried, black or not sampled gets none; the correction is a
//! mean over the patch's whole area, like every irradiance in the solver
//! (its exposed part receives it over its exposure).

use std::collections::HashMap;
use std::f64::consts::PI;

use glam::DVec3;
use rand::seq::SliceRandom;
use rayon::prelude::*;

use crate::hierarchical::cluster::ClusterTree;
use crate::hierarchical::gather::push_down;
use crate::hierarchical::hierarchy::Hierarchy;
use crate::hierarchical::solution::CorrectionPass;
use crate::hierarchical::solver::Solver;
use crate::sampling::{PolygonSampler, pair_stream, stratified};
use crate::scene::Scene;
use crate::visibility::{ENDPOINT_GAP, TriangleBvh};

/// A patch gets at least this many rays per leaf of its quadtree (and at
/// most [`MAX_RAYS`]): a patch refined to many leaves is large against its
/// detail, or lit unevenly, and its mean needs more rays to be known.
const RAYS_PER_LEAF: usize = 16;
const MAX_RAYS: usize = 1 << 16;
/// Fewest rays a patch smaller than the mean gets: enough for a variance.
const MIN_RAYS: usize = 16;

/// Rays for a patch of area `area` when a patch of the mean area
/// `mean_area` or larger gets `rays`: in proportion to the area below the
/// mean, at least [`MIN_RAYS`] and [`RAYS_PER_LEAF`] per leaf, at most
/// [`MAX_RAYS`]. A pool's variance is Σ a² σ² / n over its patches, least
/// for a given number of rays when n ∝ a σ: a small patch's rays buy
/// little, and small patches are pooled.
fn rays_for(rays: usize, area: f64, mean_area: f64, leaves: usize) -> usize {
    let share = if mean_area > 0.0 {
        (area / mean_area).min(1.0)
    } else {
        1.0
    };
    ((rays as f64 * share).ceil() as usize)
        .max(MIN_RAYS)
        .max(RAYS_PER_LEAF * leaves)
        .min(MAX_RAYS)
}

/// Mixed into the seed of the correction's rays.
const CORRECTION_TAG: u64 = 0x636f_7272_6563_7421;

impl Solver<'_> {
    /// One pass of defect correction: measures each patch's residual with
    /// at least `rays` rays (see the module doc), adds it to the correction
    /// the gathers carry, and says what it found.
    pub(super) fn correct(
        &mut self,
        irradiance: &[DVec3],
        rays: usize,
        pass: u32,
    ) -> CorrectionPass {
        let scene = self.scene;
        let h = &self.hierarchy;
        let direct = self.direct_irradiance();
        let mean = patch_means(h, irradiance);
        let faces = front_patches(scene);
        let seed = self.settings.seed ^ CORRECTION_TAG ^ u64::from(pass).rotate_left(32);
        let mut leaves = vec![0usize; scene.patches.len()];
        for e in h.elements.iter().filter(|e| e.is_leaf()) {
            leaves[e.patch as usize] += 1;
        }
        let second = self.second_moments();
        let mean_area =
            scene.patches.iter().map(|p| p.area).sum::<f64>() / scene.patches.len().max(1) as f64;
        // Per patch: what its links bring from reflection, and what the
        // rays find (with the variance of that mean).
        let samples: Vec<(Sample, usize, usize)> = (0..scene.patches.len())
            .into_par_iter()
            .with_min_len(16)
            .map(|p| {
                let exposure = f64::from(h.elements[p].exposure);
                let patch = &scene.patches[p];
                let links = mean[p] - direct[p];
                if exposure <= 0.0 || patch.reflectance.max_element() <= 0.0 {
                    return (Sample::default(), 0, 0);
                }
                let rays = rays_for(rays, patch.area, mean_area, leaves[p]);
                let g = gather_reflected(scene, self.bvh, h, &faces, p, rays, seed);
                let counted = (g.rays - g.back_faces) as f64;
                let sample = match g.mean {
                    Some((ray, variance)) => {
                        // The spread the links say the rays should have
                        // met: a small bright source the rays missed
                        // still counts.
                        let h2 = links.element_sum().powi(2);
                        let predicted = (second[p] * exposure - h2).max(0.0) / counted;
                        Sample {
                            area: scene.patches[p].area,
                            residual: ray * exposure - links,
                            links,
                            variance: (variance * exposure * exposure).max(predicted),
                        }
                    }
                    None => Sample::default(),
                };
                (sample, g.rays, g.back_faces)
            })
            .collect();
        let cast: usize = samples.iter().map(|s| s.1).sum();
        let back_faces: usize = samples.iter().map(|s| s.2).sum();
        let samples: Vec<Sample> = samples.into_iter().map(|s| s.0).collect();
        let own_tree;
        let tree = match &self.clusters {
            Some(c) => &c.tree,
            None => {
                own_tree = ClusterTree::new(scene);
                &own_tree
            }
        };
        let residual = pooled(scene, tree, &samples, self.settings.correction_tolerance);
        let (mut moved, mut total) = (0.0, 0.0);
        for (p, r) in residual.iter().enumerate() {
            let a = scene.patches[p].area;
            moved += a * r.element_sum();
            total += a * (mean[p] - direct[p]).element_sum();
        }
        if self.correction.is_empty() {
            self.correction = residual;
        } else {
            for (c, r) in self.correction.iter_mut().zip(&residual) {
                *c += *r;
            }
        }
        CorrectionPass {
            residual: if total > 0.0 { moved / total } else { 0.0 },
            rays: cast,
            back_faces,
        }
    }

    /// Per patch, the second moment the links predict for a cosine ray's
    /// value (channels summed): Σ over the links of its elements, each
    /// weighed by its receiver's share of the patch, of F·V times the
    /// area mean of (reflected radiosity)² over the source's leaves. A
    /// source that is small and bright, whose light the links carry but
    /// few rays would hit, makes it large.
    fn second_moments(&self) -> Vec<f64> {
        let (scene, h) = (self.scene, &self.hierarchy);
        let mut square = vec![0.0; h.len()];
        for i in (0..h.len()).rev() {
            let e = &h.elements[i];
            square[i] = match e.children() {
                None => {
                    let emission = scene.patches[e.patch as usize].emission;
                    (e.exposed_radiosity - emission)
                        .max(DVec3::ZERO)
                        .element_sum()
                        .powi(2)
                }
                Some(kids) => {
                    kids.iter()
                        .map(|k| h.get(*k).area * square[k.index()])
                        .sum::<f64>()
                        / e.area
                }
            };
        }
        let mut out = vec![0.0; scene.patches.len()];
        for (i, ls) in self.links.iter().enumerate() {
            let e = &h.elements[i];
            let share = e.area / h.elements[e.patch as usize].area;
            out[e.patch as usize] += share
                * ls.iter()
                    .map(|l| l.coupling() * square[l.source.index()])
                    .sum::<f64>();
        }
        out
    }

    /// Per patch, the mean irradiance (over its whole area) that the links
    /// bring from the sources' emission, and the punctual lights and sky
    /// bring: the direct light, which the rays do not gather.
    fn direct_irradiance(&self) -> Vec<DVec3> {
        let (scene, h) = (self.scene, &self.hierarchy);
        let mut gathered: Vec<DVec3> = self
            .links
            .par_iter()
            .with_min_len(256)
            .map(|ls| {
                ls.iter()
                    .map(|l| l.coupling() * scene.patches[h.get(l.source).patch as usize].emission)
                    .sum()
            })
            .collect();
        if let Some(c) = &self.clusters {
            let (_, direct) = c.patch_irradiance(scene, &h.elements, self.settings.seed);
            for (g, d) in gathered.iter_mut().zip(direct) {
                *g += d;
            }
        }
        // The punctual lights and the sky: direct light too.
        for ((g, e), x) in gathered.iter_mut().zip(&h.elements).zip(&self.external) {
            if e.is_leaf() {
                *g += *x;
            }
        }
        let mut down = vec![DVec3::ZERO; h.len()];
        push_down(h, &gathered, &mut down);
        patch_means(h, &down)
    }
}

/// One patch's measurement: its area, the residual (rays less links) and
/// what the links bring, as mean irradiances, and the variance of the
/// rays' mean (channels summed).
#[derive(Clone, Copy, Default)]
struct Sample {
    area: f64,
    residual: DVec3,
    links: DVec3,
    variance: f64,
}

/// Per patch, its residual as a share of what its links bring, pooled over
/// the smallest group around it whose pooled share is known
/// ([`Pool::settled`]: significant, or known to `tolerance`): the patch
/// alone, else the patches facing the same way (by the normal's dominant
/// axis) in the nearest cluster above it that qualifies, else nothing (a
/// share not known even over the whole scene is left alone). A patch's
/// own residual is mostly the noise of a few hundred rays; the share is a
/// property of the region's links and varies slowly, so the pool keeps it
/// and drops the noise.
fn pooled(scene: &Scene, tree: &ClusterTree, samples: &[Sample], tolerance: f64) -> Vec<DVec3> {
    let n = samples.len();
    let class: Vec<usize> = scene.patches.iter().map(|p| facing(p.normal)).collect();
    // Running sums over the tree order, one set per facing.
    let mut sums = vec![[Pool::default(); FACINGS]; n + 1];
    for (k, &p) in tree.order.iter().enumerate() {
        let mut next = sums[k];
        next[class[p as usize]].add(&samples[p as usize]);
        sums[k + 1] = next;
    }
    let ancestors = tree.ancestors();
    (0..n)
        .map(|p| {
            let s = &samples[p];
            if s.area <= 0.0 {
                return DVec3::ZERO;
            }
            let mut pool = Pool::default();
            pool.add(s);
            let mut groups = ancestors[p].iter().map(|&c| {
                let c = &tree.clusters[c as usize];
                let (a, b) = (c.first as usize, (c.first + c.count) as usize);
                sums[b][class[p]].less(&sums[a][class[p]])
            });
            while !pool.settled(tolerance) {
                match groups.next() {
                    Some(g) => pool = g,
                    None => return DVec3::ZERO,
                }
            }
            pool.share() * s.links
        })
        .collect()
}

/// Standard errors from zero at which a share counts as found.
const SIGNIFICANCE: f64 = 3.0;

/// Facings a patch can have: the dominant axis of its normal and its sign.
const FACINGS: usize = 6;

fn facing(n: DVec3) -> usize {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    2 * axis + usize::from(n[axis] < 0.0)
}

/// Area-weighted sums of a group of samples.
#[derive(Clone, Copy, Default)]
struct Pool {
    residual: DVec3,
    links: DVec3,
    variance: f64,
}

impl Pool {
    fn add(&mut self, s: &Sample) {
        self.residual += s.area * s.residual;
        self.links += s.area * s.links;
        self.variance += s.area * s.area * s.variance;
    }

    fn less(&self, o: &Pool) -> Pool {
        Pool {
            residual: self.residual - o.residual,
            links: self.links - o.links,
            variance: (self.variance - o.variance).max(0.0),
        }
    }

    /// Whether the share is known: significant (at least [`SIGNIFICANCE`]
    /// standard errors from zero), or known to `tolerance` of the links'
    /// light (a small share, but a known one).
    fn settled(&self, tolerance: f64) -> bool {
        let (links, error) = (self.links.element_sum(), self.variance.sqrt());
        links > 0.0
            && (error <= tolerance * links
                || self.residual.element_sum().abs() >= SIGNIFICANCE * error)
    }

    /// The residual over the links' light, per channel.
    fn share(&self) -> DVec3 {
        let ratio = |r: f64, l: f64| if l > 0.0 { r / l } else { 0.0 };
        DVec3::new(
            ratio(self.residual.x, self.links.x),
            ratio(self.residual.y, self.links.y),
            ratio(self.residual.z, self.links.z),
        )
    }
}

/// Per patch, the area-weighted mean over its leaves of `per_element`.
fn patch_means(h: &Hierarchy, per_element: &[DVec3]) -> Vec<DVec3> {
    let mut sum = vec![DVec3::ZERO; h.root_count()];
    for (i, e) in h.elements.iter().enumerate() {
        if e.is_leaf() {
            sum[e.patch as usize] += e.area * per_element[i];
        }
    }
    for (p, s) in sum.iter_mut().enumerate() {
        *s /= h.elements[p].area;
    }
    sum
}

/// Per input triangle, its patches (front, then the back one of a
/// double-sided triangle; `u32::MAX`: none). A triangle with the same
/// corners as another (a surface made two-sided by a reversed copy) takes
/// its twin's patch as well: a ray may hit either of the two, and the one
/// facing it must be found whichever it is.
fn front_patches(scene: &Scene) -> Vec<[u32; 2]> {
    fn add(slot: &mut [u32; 2], p: u32) {
        if slot[0] == u32::MAX {
            slot[0] = p;
        } else if slot[0] != p && slot[1] == u32::MAX {
            slot[1] = p;
        }
    }
    let mut out = vec![[u32::MAX; 2]; scene.triangles.len()];
    for (p, patch) in scene.patches.iter().enumerate() {
        for &t in &patch.triangles {
            if let Some(slot) = out.get_mut(t as usize) {
                add(slot, p as u32);
            }
        }
    }
    let mut twins: HashMap<[[u64; 3]; 3], Vec<usize>> = HashMap::new();
    for (t, tri) in scene.triangles.iter().enumerate() {
        let mut key = tri.positions.map(|v| v.to_array().map(f64::to_bits));
        key.sort_unstable();
        twins.entry(key).or_default().push(t);
    }
    for group in twins.values().filter(|g| g.len() > 1) {
        let patches: Vec<u32> = group
            .iter()
            .flat_map(|&t| out[t])
            .filter(|&p| p != u32::MAX)
            .collect();
        for &t in group {
            for &p in &patches {
                add(&mut out[t], p);
            }
        }
    }
    out
}

/// The mean reflected radiosity (exposed radiosity less emission) reaching
/// the exposed points of patch `p`, by `rays` stratified points each with a
/// cosine-distributed direction: the irradiance from everything but
/// emission, and the variance of that mean (of the channels' sum, from
/// the spread of the rays).
fn gather_reflected(
    scene: &Scene,
    bvh: &TriangleBvh,
    h: &Hierarchy,
    faces: &[[u32; 2]],
    p: usize,
    rays: usize,
    seed: u64,
) -> Gathered {
    let patch = &scene.patches[p];
    let n = patch.normal;
    let (t, b) = n.any_orthonormal_pair();
    let gap = ENDPOINT_GAP * scene.diagonal();
    let mut rng = pair_stream(seed, p as u32, 0);
    let sampler = PolygonSampler::new(patch.vertices());
    let (mut sum, mut square, mut exposed) = (DVec3::ZERO, 0.0, 0usize);
    let mut out = Gathered::default();
    let points = stratified(rays, &mut rng);
    let mut directions = stratified(rays, &mut rng);
    // Strata of the two in independent order: `stratified` lists its
    // cells row by row, so pairing them in any fixed order would tie
    // where a point lies to which way its ray goes.
    directions.shuffle(&mut rng);
    // A patch with nothing buried needs no burial test.
    let whole = h.elements[p].exposure >= 1.0;
    for (u, w) in points.into_iter().zip(directions) {
        let x = sampler.point(u);
        if !whole && bvh.buried(scene, x, n) {
            continue;
        }
        exposed += 1;
        let (r, phi) = (w.x.sqrt(), 2.0 * PI * w.y);
        let d = t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - w.x).max(0.0).sqrt();
        let o = x + gap * n;
        let Some(hit) = bvh.closest_hit(o, d, f64::INFINITY) else {
            continue;
        };
        let Some(&q) = faces.get(hit.triangle as usize).and_then(|f| {
            f.iter()
                .find(|&&q| q != u32::MAX && scene.patches[q as usize].normal.dot(d) < 0.0)
        }) else {
            // The back of a one-sided surface: the ray started inside a
            // solid or slipped through a crack, and says nothing of what
            // the patch sees; it is counted, not averaged.
            exposed -= 1;
            out.back_faces += 1;
            continue;
        };
        let y = o + hit.t * d;
        let leaf = h.get(h.leaf_at(scene, q as usize, y));
        let value = (leaf.exposed_radiosity - scene.patches[q as usize].emission).max(DVec3::ZERO);
        sum += value;
        square += value.element_sum().powi(2);
    }
    out.rays = exposed + out.back_faces;
    if exposed > 1 {
        let n = exposed as f64;
        let mean = sum / n;
        let spread = (square / n - mean.element_sum().powi(2)).max(0.0);
        out.mean = Some((mean, spread / (n - 1.0)));
    }
    out
}

/// What one patch's rays found.
#[derive(Default)]
struct Gathered {
    /// The mean and its variance (channels summed); `None`: fewer than two
    /// rays counted.
    mean: Option<(DVec3, f64)>,
    /// Rays cast from exposed points.
    rays: usize,
    /// Of them, rays that hit the back of a one-sided surface.
    back_faces: usize,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{InputTriangle, Material, Surface};

    /// An 8 × 8 floor of unit quads facing up, a 4 × 4 wall facing +x and
    /// a lamp facing down.
    fn floor_and_wall() -> Scene {
        let mut input = Vec::new();
        let mut quad = |c: [DVec3; 4], surface: u32| {
            for positions in [[c[0], c[1], c[2]], [c[0], c[2], c[3]]] {
                input.push(InputTriangle {
                    positions,
                    material: 0,
                    surface,
                    reflectance: DVec3::splat(0.5),
                    emitted_radiance: DVec3::splat(f64::from(surface / 2)),
                    origin: Default::default(),
                });
            }
        };
        let lamp = |x: f64, y: f64| DVec3::new(x, y, 5.0);
        quad([lamp(3., 3.), lamp(3., 4.), lamp(4., 4.), lamp(4., 3.)], 2);
        for i in 0..8 {
            for j in 0..8 {
                let (x, y) = (f64::from(i), f64::from(j));
                let p = |dx: f64, dy: f64| DVec3::new(x + dx, y + dy, 0.0);
                quad([p(0., 0.), p(1., 0.), p(1., 1.), p(0., 1.)], 0);
            }
        }
        for j in 0..4 {
            for k in 0..4 {
                let (y, z) = (f64::from(j), f64::from(k));
                let p = |dy: f64, dz: f64| DVec3::new(0.0, y + dy, z + dz);
                quad([p(0., 0.), p(1., 0.), p(1., 1.), p(0., 1.)], 1);
            }
        }
        let material = Material {
            name: "grey".into(),
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::ZERO,
            double_sided: false,
        };
        let surfaces = (0..3)
            .map(|k| Surface {
                name: format!("s{k}"),
                node: k,
            })
            .collect();
        Scene::build(input, vec![material], surfaces, vec![], vec![]).unwrap()
    }

    /// Samples with a residual share `share(p)` of unit links' light, each
    /// with standard error `error` of that share.
    fn samples(scene: &Scene, share: impl Fn(usize) -> f64, error: f64) -> Vec<Sample> {
        (0..scene.patches.len())
            .map(|p| Sample {
                area: scene.patches[p].area,
                residual: DVec3::splat(share(p)),
                links: DVec3::ONE,
                variance: (3.0 * error).powi(2),
            })
            .collect()
    }

    #[test]
    fn rays_follow_the_area_below_the_mean_and_the_leaves_above_it() {
        // At or above the mean area: the full count, whatever the size.
        assert_eq!(rays_for(1024, 1.0, 1.0, 1), 1024);
        assert_eq!(rays_for(1024, 50.0, 1.0, 1), 1024);
        // Below it: in proportion, rounded up, at least MIN_RAYS.
        assert_eq!(rays_for(1024, 0.25, 1.0, 1), 256);
        assert_eq!(rays_for(1024, 0.3, 1.0, 1), 308);
        assert_eq!(rays_for(1024, 1e-3, 1.0, 1), MIN_RAYS);
        // Leaves ask for more, up to MAX_RAYS.
        assert_eq!(rays_for(1024, 1e-3, 1.0, 100), 100 * RAYS_PER_LEAF);
        assert_eq!(rays_for(1024, 1.0, 1.0, 1 << 20), MAX_RAYS);
        // No mean (no area at all): the full count.
        assert_eq!(rays_for(64, 0.0, 0.0, 1), 64);
    }

    #[test]
    fn a_share_known_well_enough_is_kept_and_noise_is_pooled_among_patches_facing_alike() {
        let scene = floor_and_wall();
        assert_eq!(scene.patches.len(), 81, "one patch per quad");
        let tree = ClusterTree::new(&scene);
        let up = |p: usize| scene.patches[p].normal.z > 0.5;
        let wall = |p: usize| scene.patches[p].normal.x > 0.5;
        // Known to 0.1 %: each patch keeps its own (significant, or for a
        // share of zero, known to better than the 0.5 % asked).
        let own = |p: usize| 0.01 * (p % 7) as f64;
        let kept = pooled(&scene, &tree, &samples(&scene, own, 0.001), 0.005);
        for (p, c) in kept.iter().enumerate() {
            assert!((c.x - own(p)).abs() < 1e-12, "patch {p}: {c}");
        }
        // Noisy shares (±15 % about 5 % on the floor, about −10 % on the
        // wall, a checkerboard of signs) known to 10 % each: no patch's own
        // is significant (2.5 standard errors at most); pools of their
        // neighbours facing the same way are, and come closer to the truth
        // than any patch alone. Neither surface borrows from the other.
        let noisy = |p: usize, floor: f64, wall: f64| {
            let c = crate::scene::polygon_centroid(scene.patches[p].vertices()).floor();
            let sign = if (c.x + c.y + c.z).rem_euclid(2.0) < 0.5 {
                1.0
            } else {
                -1.0
            };
            (if up(p) { floor } else { wall }) + 0.15 * sign
        };
        let got = pooled(
            &scene,
            &tree,
            &samples(&scene, |p| noisy(p, 0.05, -0.1), 0.1),
            0.005,
        );
        for (p, c) in got.iter().enumerate().filter(|&(p, _)| up(p) || wall(p)) {
            let truth = if up(p) { 0.05 } else { -0.1 };
            assert!(
                c.x != 0.0 && (c.x - truth).abs() < 0.075,
                "patch {p}: {} against {truth}",
                c.x
            );
        }
        // Noise alone: even the floor's pool (1.25 %) is neither significant
        // nor known to 0.5 %, and nothing is applied.
        let got = pooled(
            &scene,
            &tree,
            &samples(&scene, |p| noisy(p, 0.0, 0.0), 0.1),
            0.005,
        );
        for (p, c) in got.iter().enumerate().filter(|&(p, _)| up(p) || wall(p)) {
            assert_eq!(*c, DVec3::ZERO, "patch {p}");
        }
    }
}
