//! Ray queries against a triangle set: occlusion of point-to-point segments
//! and closest hits, on an `obvhs` compressed wide BVH.
//!
//! Owns: ray queries and shaft queries (`shaft.rs`: whether anything at
//! all stands between two pieces of surface) on obvhs's wide BVH; the
//! other use of obvhs is the cluster tree's BVH2,
//! [`crate::hierarchical::cluster`]. Geometry is held in f32 (what obvhs
//! traverses); callers pass f64 points.
//!
//! Invariants:
//! - A segment query ignores hits within `endpoint_gap` (a fixed fraction of
//!   the scene diagonal, [`ENDPOINT_GAP`]) of either endpoint, so that points
//!   lying on surfaces never occlude themselves, whatever the scene's scale.
//! - Batched queries return results in input order and are independent of the
//!   thread count.

use std::time::Duration;

use glam::{DVec3, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::reinsertion::ReinsertionOptimizer,
    cwbvh::{CwBvh, bvh2_to_cwbvh::bvh2_to_cwbvh},
    ray::{Ray, RayHit},
    splits::{split_aabbs_precise, split_aabbs_preset},
    triangle::Triangle,
};
use rayon::prelude::*;

use crate::scene::Scene;

mod shaft;
pub use shaft::{SHAFT_GAP, Shaft};

/// Hits closer than this fraction of the scene diagonal to a segment's
/// endpoints do not count as occlusion.
pub const ENDPOINT_GAP: f64 = 1e-5;

/// A closest-hit result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit (in units of the direction's length).
    pub t: f64,
    /// Index of the triangle in the order it was given.
    pub triangle: u32,
}

/// A BVH over triangles, ready for occlusion and closest-hit queries.
pub struct TriangleBvh {
    bvh: CwBvh,
    /// Triangles in BVH primitive order.
    triangles: Vec<Triangle>,
    /// Input index of each triangle in `triangles`.
    input_index: Vec<u32>,
    /// Number of triangles given.
    input_count: usize,
    endpoint_gap: f64,
    /// The scene's length scale the BVH was built for.
    diagonal: f64,
    /// Coordinates are stored times this power of two (see
    /// [`SCALED_DIAGONAL`]).
    scale: f64,
    build_time: Duration,
}

/// The diagonal the geometry is scaled to (by a power of two, exactly)
/// before it goes into the BVH. obvhs's compressed BVH skips every node
/// the ray leaves before parameter 1e-4: with unit directions, a surface
/// within 1e-4 of a ray's origin is not seen. At this scale that blind
/// spot is 1e-8 of the diagonal, far below [`ENDPOINT_GAP`], whatever the
/// scene's size (unscaled, it was 0.1 mm: a ray started that close to a
/// surface passed through it).
const SCALED_DIAGONAL: f64 = 1e4;

/// A triangle whose box's half area is more than this many times its own
/// area is a sliver (a right triangle along the axes: 2; an equilateral one
/// turned in space: under 5).
const SLIVER_RATIO: f32 = 8.0;

/// Sliver boxes may grow the BVH's references to at most this many times
/// the triangle count (a fan's slivers: 8 boxes each). More buys little:
/// a fan's slivers need boxes in proportion to their length over their
/// width, and a budget of 2^21 references took a 16,000-triangle fan's
/// build from 3 s to 23 s and 1.2 GB for a render 2.2× as fast.
const SLIVER_BUDGET: usize = 16;

/// And to at most this many references in all (about 80 bytes each while
/// building; the full reinsertion pass over them costs seconds a million).
const MAX_REFERENCES: usize = 1 << 20;

/// The wide BVH of `tris`, built as obvhs's slowest preset builds it (full
/// reinsertion, its pre-splits of large triangles: 2.2× the rays per second
/// of its medium build on office-10k, 2.9× on the gallery, for 20–70 ms
/// more building; bench-visibility), plus splits of slivers' boxes.
///
/// obvhs splits a triangle's box only when it is large against the
/// scene's average, so long thin triangles of similar size are never
/// split: in a fan of n slivers meeting at one point, every box overlaps
/// the centre's region and a ray visits O(n) of them (onto a fan of 4,096,
/// 424 triangle tests a ray; the default render of a 4,000-triangle fan
/// took 56 s, of a 16-triangle disc 4 s). Each
/// sliver's box is split along its longest axis, each piece fitted to the
/// triangle's part inside it, while that halves the boxes' area, to at
/// most 2^k pieces with k chosen so the references stay within
/// [`SLIVER_BUDGET`] times the triangles.
fn build(tris: &[Triangle]) -> CwBvh {
    let params = BvhBuildParams::very_slow_build();
    let mut aabbs: Vec<Aabb> = tris.iter().map(Triangle::aabb).collect();
    let mut indices: Vec<u32> = (0..tris.len() as u32).collect();
    let largest = aabbs.iter().map(Aabb::half_area).fold(0.0, f32::max);
    let average = aabbs.iter().map(Aabb::half_area).sum::<f32>() / tris.len() as f32;
    split_aabbs_preset(&mut aabbs, &mut indices, tris, average, largest);
    let area = |i: u32| {
        let t = &tris[i as usize];
        0.5 * (t.v1 - t.v0).cross(t.v2 - t.v0).length()
    };
    let positions: Vec<usize> = (0..aabbs.len())
        .filter(|&k| aabbs[k].half_area() > SLIVER_RATIO * area(indices[k]))
        .collect();
    let room = (SLIVER_BUDGET * tris.len())
        .min(MAX_REFERENCES)
        .saturating_sub(aabbs.len())
        / positions.len().max(1);
    let rounds = room.max(1).ilog2().min(10);
    if !positions.is_empty() && rounds > 0 {
        let mut pieces: Vec<Aabb> = positions.iter().map(|&k| aabbs[k]).collect();
        let mut of: Vec<u32> = positions.iter().map(|&k| indices[k]).collect();
        // Thresholds 0: every sliver is a candidate; a split is kept when
        // it takes the box's half area below 1/1.8 of what it was.
        split_aabbs_precise(&mut pieces, &mut of, tris, 0.0, 0.0, 1.8, 1.8, rounds, 12);
        // The first pieces replace the slivers' boxes, the rest are added.
        for (&k, piece) in positions.iter().zip(&pieces) {
            aabbs[k] = *piece;
        }
        aabbs.extend_from_slice(&pieces[positions.len()..]);
        indices.extend_from_slice(&of[positions.len()..]);
    }
    let mut bvh2 = crate::util::boxes::ploc(&aabbs, indices, &params);
    bvh2.uses_spatial_splits = true;
    ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
    bvh2_to_cwbvh(&bvh2, params.max_prims_per_leaf.clamp(1, 3), true, false)
}

impl TriangleBvh {
    /// Builds the BVH. `diagonal` is the scene's length scale.
    pub fn new(triangles: &[[Vec3; 3]], diagonal: f64) -> TriangleBvh {
        let start = std::time::Instant::now();
        // A power of two: scaling f32 coordinates by it is exact.
        let scale = if diagonal > 0.0 && diagonal.is_finite() {
            (SCALED_DIAGONAL / diagonal)
                .log2()
                .round()
                .clamp(-60.0, 60.0)
                .exp2()
        } else {
            1.0
        };
        let s = scale as f32;
        let tris: Vec<Triangle> = triangles
            .iter()
            .map(|t| Triangle {
                v0: (t[0] * s).into(),
                v1: (t[1] * s).into(),
                v2: (t[2] * s).into(),
            })
            .collect();
        let (bvh, ordered, input_index) = if tris.is_empty() {
            (CwBvh::default(), Vec::new(), Vec::new())
        } else {
            let bvh = build(&tris);
            let ordered = bvh
                .primitive_indices
                .iter()
                .map(|&i| tris[i as usize])
                .collect();
            let index = bvh.primitive_indices.clone();
            (bvh, ordered, index)
        };
        TriangleBvh {
            bvh,
            triangles: ordered,
            input_index,
            input_count: triangles.len(),
            endpoint_gap: ENDPOINT_GAP * diagonal,
            diagonal,
            scale,
            build_time: start.elapsed(),
        }
    }

    /// The occluder BVH of a scene: every input triangle, at the scene's
    /// length scale. The one way the pipeline, the path tracer and the
    /// tools build it.
    pub fn of_scene(scene: &Scene) -> TriangleBvh {
        let occluders: Vec<[Vec3; 3]> = scene
            .triangles
            .iter()
            .map(|t| t.positions.map(|p| p.as_vec3()))
            .collect();
        TriangleBvh::new(&occluders, scene.diagonal())
    }

    /// Number of triangles (as given: a triangle split into several boxes
    /// counts once).
    pub fn len(&self) -> usize {
        self.input_count
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Wall time the build took.
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    /// True when nothing blocks the open segment between `a` and `b`.
    pub fn visible(&self, a: DVec3, b: DVec3) -> bool {
        if self.triangles.is_empty() {
            return true;
        }
        let d = b - a;
        let len = d.length();
        if !(len > 2.0 * self.endpoint_gap) {
            return true;
        }
        // A unit direction and parameters in scaled units (see
        // [`SCALED_DIAGONAL`]); `+ 0.0` as in `closest_hit`.
        let s = self.scale;
        let ray = Ray::new(
            Vec3A::from((a * s).as_vec3()),
            Vec3A::from((d / len + 0.0).as_vec3()),
            (self.endpoint_gap * s) as f32,
            ((len - self.endpoint_gap) * s) as f32,
        );
        self.bvh
            .ray_traverse_miss(ray, |ray, id| self.triangles[id].intersect(ray))
    }

    /// [`Self::visible`] for many segments, in parallel, results in order.
    pub fn visible_batch(&self, segments: &[(DVec3, DVec3)]) -> Vec<bool> {
        segments
            .par_iter()
            .with_min_len(64)
            .map(|&(a, b)| self.visible(a, b))
            .collect()
    }

    /// Whether the point `x` of a surface with normal `n` is buried: rays
    /// from just above it, along `n` and in four directions 70° from it,
    /// all meet the back of a single-sided surface first (a floor point
    /// under a box, a point inside a closed solid; not one under a plate
    /// that light reaches from the side). Such a point sees only backs and
    /// receives nothing. Stops at the first ray that escapes.
    pub fn buried(&self, scene: &Scene, x: DVec3, n: DVec3) -> bool {
        let diagonal = scene.diagonal();
        let from = x + 1e-6 * diagonal * n;
        let (t, b) = n.any_orthonormal_pair();
        let (sin, cos) = 70f64.to_radians().sin_cos();
        let tilted = [t, b, -t, -b].map(|d| cos * n + sin * d);
        std::iter::once(n).chain(tilted).all(|d| {
            self.closest_hit(from, d, 2.0 * diagonal)
                .is_some_and(|hit| {
                    let tri = &scene.triangles[hit.triangle as usize];
                    let p = tri.positions;
                    tri.back_patch.is_none() && (p[1] - p[0]).cross(p[2] - p[0]).dot(d) > 0.0
                })
        })
    }

    /// The closest triangle hit by the ray `origin + t·direction`,
    /// `t` in (0, t_max].
    pub fn closest_hit(&self, origin: DVec3, direction: DVec3, t_max: f64) -> Option<Hit> {
        if self.triangles.is_empty() {
            return None;
        }
        let len = direction.length();
        if !(len > 0.0) {
            return None;
        }
        // A unit direction, parameters in scaled units (see
        // [`SCALED_DIAGONAL`]). `+ 0.0` turns −0 components into +0: obvhs
        // takes a −0 component for negative when inverting it but not
        // when ordering the slabs, so an exactly axis-aligned ray with a −0
        // component (a back patch's normal, a probe's normal negated)
        // misses everything.
        let k = self.scale * len;
        let ray = Ray::new(
            Vec3A::from((origin * self.scale).as_vec3()),
            Vec3A::from((direction / len + 0.0).as_vec3()),
            0.0,
            (t_max * k).min(f64::from(f32::MAX)) as f32,
        );
        let mut hit = RayHit::none();
        if self
            .bvh
            .ray_traverse(ray, &mut hit, |ray, id| self.triangles[id].intersect(ray))
        {
            Some(Hit {
                t: hit.t as f64 / k,
                triangle: self.input_index[hit.primitive_id as usize],
            })
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f32, half: f32) -> [[Vec3; 3]; 2] {
        let p = |x: f32, y: f32| Vec3::new(x, y, z);
        [
            [p(-half, -half), p(half, -half), p(half, half)],
            [p(-half, -half), p(half, half), p(-half, half)],
        ]
    }

    #[test]
    fn blocker_between_points_occludes() {
        let tris = square(0.0, 1.0);
        let bvh = TriangleBvh::new(&tris, 2.0);
        assert!(!bvh.visible(DVec3::new(0.1, 0.2, -1.0), DVec3::new(0.0, 0.0, 1.0)));
        assert!(bvh.visible(DVec3::new(3.0, 0.0, -1.0), DVec3::new(3.0, 0.0, 1.0)));
        // Endpoints on the square itself never occlude themselves.
        assert!(bvh.visible(DVec3::new(0.3, 0.3, 0.0), DVec3::new(0.3, 0.3, 2.0)));
        assert!(bvh.visible(DVec3::new(0.3, 0.3, 2.0), DVec3::new(0.3, 0.3, 0.0)));
    }

    /// A disc of `n` slivers meeting at its centre (in z = 0), and the
    /// mean number of triangle tests of a vertical ray down onto it.
    fn fan_tests_per_ray(n: usize) -> f64 {
        let rim = |k: usize| {
            let a = std::f32::consts::TAU * k as f32 / n as f32;
            Vec3::new(a.cos(), a.sin(), 0.0)
        };
        let tris: Vec<[Vec3; 3]> = (0..n).map(|k| [Vec3::ZERO, rim(k), rim(k + 1)]).collect();
        let bvh = TriangleBvh::new(&tris, 2.0);
        let (mut tests, mut hits, rays) = (0usize, 0usize, 400);
        for i in 0..rays {
            // A spiral of points over the disc.
            let (r, a) = (
                ((i as f32 + 0.5) / rays as f32).sqrt() * 0.99,
                i as f32 * 2.4,
            );
            let origin = Vec3A::new(r * a.cos(), r * a.sin(), 1.0) * bvh.scale as f32;
            let ray = Ray::new(origin, Vec3A::new(0.0, 0.0, -1.0), 0.0, f32::MAX);
            let mut hit = RayHit::none();
            hits += usize::from(bvh.bvh.ray_traverse(ray, &mut hit, |ray, id| {
                tests += 1;
                bvh.triangles[id].intersect(ray)
            }));
        }
        assert_eq!(hits, rays, "every ray hits the disc");
        tests as f64 / rays as f64
    }

    /// Slivers' boxes are split: without, a ray onto a fan of 256 slivers
    /// tested 27.8 triangles and onto one of 4,096 423.6 (the boxes all
    /// overlap near the centre); with, 7.6 and 57.5.
    #[test]
    fn a_fan_of_slivers_costs_a_ray_far_fewer_than_its_triangles() {
        let (small, large) = (fan_tests_per_ray(256), fan_tests_per_ray(4096));
        eprintln!("fan: {small:.1} tests a ray at 256 slivers, {large:.1} at 4096");
        assert!(large < 128.0, "{large} tests a ray");
    }

    #[test]
    fn closest_hit_reports_input_index_and_distance() {
        let mut tris = square(1.0, 1.0).to_vec();
        tris.extend(square(2.0, 1.0));
        let bvh = TriangleBvh::new(&tris, 4.0);
        let hit = bvh
            .closest_hit(DVec3::new(0.5, -0.2, 0.0), DVec3::Z, 10.0)
            .unwrap();
        assert!((hit.t - 1.0).abs() < 1e-6);
        assert!(hit.triangle < 2, "nearest square is triangles 0 and 1");
        let hit = bvh
            .closest_hit(DVec3::new(0.5, -0.2, 1.5), DVec3::Z, 10.0)
            .unwrap();
        assert!((hit.t - 0.5).abs() < 1e-6);
        assert!(hit.triangle >= 2);
        assert!(
            bvh.closest_hit(DVec3::new(5.0, 0.0, 0.0), DVec3::Z, 10.0)
                .is_none()
        );
    }

    #[test]
    fn batch_matches_single_queries() {
        let tris = square(0.0, 1.0);
        let bvh = TriangleBvh::new(&tris, 2.0);
        let segs: Vec<_> = (0..500)
            .map(|i| {
                let x = i as f64 / 100.0 - 2.5;
                (DVec3::new(x, 0.0, -1.0), DVec3::new(-x, 0.1, 1.0))
            })
            .collect();
        let batch = bvh.visible_batch(&segs);
        for (s, v) in segs.iter().zip(batch) {
            assert_eq!(bvh.visible(s.0, s.1), v);
        }
    }
}
