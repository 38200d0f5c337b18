//! The light the punctual lights and the sky bring to surface points: the
//! solvers' source term besides the emitters.
//!
//! Owns: [`Illumination`] (irradiance at a point, mean and spread over a
//! piece of a patch) and the ray counts it uses.
//!
//! A punctual light is a delta: its light at a point is exact, one shadow
//! ray to the light (to far away toward a directional one). The sky is an
//! integral over the hemisphere: cosine-distributed directions, stratified,
//! each ray that leaves the scene bringing π L(d) / N. Every point of the
//! patches facing one way uses the same directions (seeded by the normal),
//! so that values at neighbouring points differ by what they see, not by
//! their draws, and an output mesh shows no blotches; an open plane gets
//! exactly π L from a uniform sky. The estimate's error is that of a
//! stratified count: on a floor under a ceiling opening (tests/lights.rs)
//! 14 % (RMS over the floor) at 256 rays, 3.6 % at 1024, 1.3 % at 4096,
//! smooth over a surface.
//!
//! Invariants: values depend only on the scene, the point, the patch's
//! normal and the seed (never on the thread count); they are finite and non-negative;
//! the back of a patch receives nothing.

use std::f64::consts::PI;

use glam::DVec3;
use rand::seq::SliceRandom;

use crate::sampling::{PolygonSampler, cosine_direction, stratified, stream};
use crate::scene::Scene;
use crate::visibility::{ENDPOINT_GAP, TriangleBvh};

/// Points per element for the element's mean: each gets every punctual
/// light's exact light and one of as many stratified sky directions.
pub const ELEMENT_POINTS: usize = 36;

/// How far [`Illumination::at`] moves a point into its patch, as a
/// fraction of the scene diagonal: ten times the visibility's endpoint
/// gap.
const INWARD: f64 = 10.0 * ENDPOINT_GAP;

/// Stream tag of the sky directions, apart from every other stream.
const SKY_TAG: u64 = 0x736b_7900_0000_0000;
/// Stream tag of an element's points.
const ELEMENT_TAG: u64 = 0x656c_6d00_0000_0000;

/// The lights that are not surfaces, evaluated with visibility.
pub struct Illumination<'a> {
    scene: &'a Scene,
    bvh: &'a TriangleBvh,
    far: f64,
    sky_rays: usize,
    seed: u64,
}

impl<'a> Illumination<'a> {
    /// For `scene` and its BVH; `sky_rays` per point (at least 1).
    pub fn new(scene: &'a Scene, bvh: &'a TriangleBvh, sky_rays: usize, seed: u64) -> Self {
        Illumination {
            scene,
            bvh,
            far: scene.far(),
            sky_rays: sky_rays.max(1),
            seed,
        }
    }

    /// True when the scene has no punctual light and no sky: every value
    /// is zero.
    pub fn is_dark(&self) -> bool {
        self.scene.lights.is_empty()
    }

    /// The punctual lights' irradiance at `x` (normal `n`), each with one
    /// shadow ray from `from` (`x`, or a point just beside it).
    pub fn punctual(&self, x: DVec3, n: DVec3, from: DVec3) -> DVec3 {
        let lights = &self.scene.lights.punctual;
        let mut h = DVec3::ZERO;
        for light in lights {
            if let Some(i) = light.incident(x, n, self.far)
                && self.bvh.visible(from, i.toward)
            {
                h += i.irradiance;
            }
        }
        h
    }

    /// The sky's irradiance at `x` on `patch`, from the patch's
    /// [`Self::sky_rays`] directions: π / N Σ L(d) over those that leave
    /// the scene.
    pub fn sky(&self, patch: u32, x: DVec3) -> DVec3 {
        let Some(sky) = &self.scene.lights.sky else {
            return DVec3::ZERO;
        };
        let n = self.scene.patches[patch as usize].normal;
        let directions = self.directions(patch, self.sky_rays);
        let seen: DVec3 = directions
            .iter()
            .filter(|&&d| self.bvh.visible(x, x + self.far * d))
            .map(|&d| sky.radiance(d))
            .sum();
        debug_assert!(directions.iter().all(|d| d.dot(n) >= 0.0));
        PI * seen / directions.len() as f64
    }

    /// Punctual lights and sky at `x` on `patch`, the rays cast from just
    /// inside the patch: `x` moved [`INWARD`] toward the patch's centroid
    /// (at most half the way). From a point on the patch's edge, where a
    /// wall meets the floor, rays would pass out by the wall's edge,
    /// closer than the visibility's endpoint gap.
    pub fn at(&self, patch: u32, x: DVec3) -> DVec3 {
        if self.is_dark() {
            return DVec3::ZERO;
        }
        let p = &self.scene.patches[patch as usize];
        let inward = p.centroid() - x;
        let step = (INWARD * self.scene.diagonal()).min(0.5 * inward.length());
        let from = x + inward.normalize_or_zero() * step;
        self.punctual(x, p.normal, from) + self.sky(patch, from)
    }

    /// The mean irradiance over `polygon` (a piece of `patch`) from
    /// [`ELEMENT_POINTS`] stratified points (seeded by `key`), each with
    /// the exact punctual light and one sky direction of a stratified set;
    /// and the spread (largest less smallest, channel maximum) of the
    /// punctual light over those points, which says whether a shadow edge
    /// or a steep falloff crosses the piece.
    pub fn element(&self, patch: u32, polygon: &[DVec3], key: u64) -> (DVec3, f64) {
        if self.is_dark() {
            return (DVec3::ZERO, 0.0);
        }
        let n = self.scene.patches[patch as usize].normal;
        let mut rng = stream(self.seed ^ ELEMENT_TAG, key);
        let sampler = PolygonSampler::new(polygon);
        let points = stratified(ELEMENT_POINTS, &mut rng);
        let sky = self.scene.lights.sky.as_ref();
        let mut directions = match sky {
            Some(_) => sky_directions(n, ELEMENT_POINTS, &mut rng),
            None => Vec::new(),
        };
        directions.shuffle(&mut rng);
        let (mut sum, mut lo, mut hi) = (DVec3::ZERO, f64::INFINITY, 0.0f64);
        for (k, t) in points.into_iter().enumerate() {
            let x = sampler.point(t);
            let p = self.punctual(x, n, x);
            lo = lo.min(p.max_element());
            hi = hi.max(p.max_element());
            sum += p;
            if let (Some(sky), Some(&d)) = (sky, directions.get(k))
                && self.bvh.visible(x, x + self.far * d)
            {
                sum += PI * sky.radiance(d);
            }
        }
        (sum / ELEMENT_POINTS as f64, (hi - lo).max(0.0))
    }

    /// `count` stratified cosine-distributed directions about `patch`'s
    /// normal, the same for every patch facing the same way (the normal
    /// rounded to 1e-6), so that the estimate's error is smooth across a
    /// floor of many patches, not a step at each patch's edge.
    fn directions(&self, patch: u32, count: usize) -> Vec<DVec3> {
        let n = self.scene.patches[patch as usize].normal;
        let key = (n * 1e6)
            .round()
            .to_array()
            .iter()
            .fold(count as u64, |h, &c| {
                (h ^ (c as i64 as u64))
                    .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                    .rotate_left(17)
            });
        let mut rng = stream(self.seed ^ SKY_TAG, key);
        sky_directions(n, count, &mut rng)
    }
}

/// `count` stratified cosine-distributed unit directions about unit `n`.
fn sky_directions(n: DVec3, count: usize, rng: &mut impl rand::Rng) -> Vec<DVec3> {
    stratified(count, rng)
        .into_iter()
        .map(|u| cosine_direction(n, u.x, u.y))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{InputTriangle, Lights, Material, Scene, Sky, Surface};

    /// A 2 m square floor at y = 0 facing up, under a uniform sky of
    /// radiance `l`.
    fn open_floor(l: DVec3) -> Scene {
        let p = |x: f64, z: f64| DVec3::new(x, 0.0, z);
        let tri = |a, b, c| InputTriangle {
            positions: [a, b, c],
            material: 0,
            surface: 0,
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::ZERO,
            origin: Default::default(),
        };
        Scene::build_lit(
            vec![
                tri(p(-1.0, 1.0), p(1.0, 1.0), p(1.0, -1.0)),
                tri(p(-1.0, 1.0), p(1.0, -1.0), p(-1.0, -1.0)),
            ],
            vec![Material {
                name: "floor".into(),
                reflectance: DVec3::splat(0.5),
                emitted_radiance: DVec3::ZERO,
                double_sided: false,
            }],
            vec![Surface {
                name: "floor".into(),
                node: 0,
            }],
            Vec::new(),
            Vec::new(),
            Lights {
                punctual: Vec::new(),
                sky: Some(Sky::Uniform(l)),
            },
        )
        .unwrap()
    }

    #[test]
    fn an_open_plane_gets_pi_l_from_a_uniform_sky() {
        let l = DVec3::new(0.2, 0.5, 1.0);
        let scene = open_floor(l);
        let bvh = TriangleBvh::of_scene(&scene);
        let ill = Illumination::new(&scene, &bvh, 64, 3);
        let h = ill.at(0, DVec3::new(0.3, 0.0, -0.2));
        assert!((h - PI * l).abs().max_element() < 1e-12, "{h}");
        let (mean, spread) = ill.element(0, scene.patches[0].vertices(), 9);
        assert!((mean - PI * l).abs().max_element() < 1e-12, "{mean}");
        assert_eq!(spread, 0.0);
    }

    #[test]
    fn sky_directions_are_cosine_distributed() {
        let n = DVec3::new(0.3, 1.0, -0.2).normalize();
        let mut rng = stream(1, 2);
        let d = sky_directions(n, 4096, &mut rng);
        let mean_cos = d.iter().map(|d| d.dot(n)).sum::<f64>() / d.len() as f64;
        assert!((mean_cos - 2.0 / 3.0).abs() < 2e-3, "{mean_cos}");
    }
}
