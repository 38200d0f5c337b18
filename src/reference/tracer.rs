//! The path tracer behind every reference: tracing a ray to the radiating
//! surface it meets, and one sample of the radiance leaving a surface
//! point (next-event estimation and cosine sampling combined by multiple
//! importance sampling for the emitters, next-event estimation alone for
//! the punctual lights, cosine sampling alone for the sky; Russian
//! roulette).
//!
//! Invariant: uses the scene, its BVH and the caller's random stream only
//! (the estimator is documented in the parent module).

use std::f64::consts::PI;

use glam::{DVec2, DVec3};
use rand::Rng;
use rand_pcg::Pcg64Mcg;

use super::{MAX_BOUNCES_CAP, MAX_SURVIVAL, ROULETTE_START};
use crate::error::{Error, Result};
use crate::sampling::{cosine_direction, point_in_polygon};
use crate::scene::{Patch, Scene};
use crate::visibility::{ENDPOINT_GAP, TriangleBvh};

/// A surface point reached by a ray, on the radiating side of its patch.
pub(super) struct SurfaceHit<'a> {
    pub(super) point: DVec3,
    pub(super) patch: &'a Patch,
    pub(super) patch_index: u32,
}

/// What a ray meets first.
enum Traced<'a> {
    /// The radiating side of a patch.
    Hit(SurfaceHit<'a>),
    /// Nothing: it leaves the scene, into the sky.
    Escaped,
    /// The back of a one-sided surface.
    Blocked,
}

/// The scene prepared for path tracing.
pub(super) struct Tracer<'a> {
    scene: &'a Scene,
    pub(super) bvh: TriangleBvh,
    /// Unit normal of each scene triangle's front face.
    pub(super) normals: Vec<DVec3>,
    /// Emitting patches and the cumulative selection probabilities.
    lights: Vec<u32>,
    light_cdf: Vec<f64>,
    /// Probability of picking each patch for light sampling (0 for
    /// non-emitters).
    pick: Vec<f64>,
    /// Offset of continuation rays off their surface.
    pub(super) offset: f64,
    /// A distance beyond the whole scene (directional lights' shadow rays).
    far: f64,
    max_bounces: u32,
}

impl<'a> Tracer<'a> {
    pub(super) fn new(scene: &'a Scene, max_bounces: Option<u32>) -> Result<Tracer<'a>> {
        let bvh = TriangleBvh::of_scene(scene);
        let normals = scene
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.positions;
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect();
        let power = |p: &Patch| p.emission.max(DVec3::ZERO).element_sum() * p.area;
        let lights: Vec<u32> = (0..scene.patches.len() as u32)
            .filter(|&i| power(&scene.patches[i as usize]) > 0.0)
            .collect();
        let total: f64 = lights
            .iter()
            .map(|&i| power(&scene.patches[i as usize]))
            .sum();
        if !total.is_finite() || (lights.is_empty() && scene.lights.is_empty()) {
            return Err(Error::NoLight);
        }
        let mut pick = vec![0.0; scene.patches.len()];
        let mut acc = 0.0;
        let light_cdf = lights
            .iter()
            .map(|&i| {
                let p = power(&scene.patches[i as usize]) / total;
                pick[i as usize] = p;
                acc += p;
                acc
            })
            .collect();
        Ok(Tracer {
            scene,
            bvh,
            normals,
            lights,
            light_cdf,
            pick,
            offset: ENDPOINT_GAP * scene.diagonal(),
            far: scene.far(),
            max_bounces: max_bounces.unwrap_or(MAX_BOUNCES_CAP).min(MAX_BOUNCES_CAP),
        })
    }

    /// The radiating surface hit first along `o + t d` (`d` unit), or
    /// `None` when the ray escapes or meets the back of a one-sided surface.
    pub(super) fn trace(&self, o: DVec3, d: DVec3) -> Option<SurfaceHit<'a>> {
        match self.follow(o, d) {
            Traced::Hit(hit) => Some(hit),
            Traced::Escaped | Traced::Blocked => None,
        }
    }

    /// What the ray `o + t d` (`d` unit) meets first.
    fn follow(&self, o: DVec3, d: DVec3) -> Traced<'a> {
        let Some(hit) = self.bvh.closest_hit(o, d, f64::from(f32::MAX)) else {
            return Traced::Escaped;
        };
        let triangle = &self.scene.triangles[hit.triangle as usize];
        let patch_index = if self.normals[hit.triangle as usize].dot(d) < 0.0 {
            triangle.front_patch
        } else {
            match triangle.back_patch {
                Some(back) => back,
                None => return Traced::Blocked,
            }
        };
        Traced::Hit(SurfaceHit {
            point: o + hit.t * d,
            patch: &self.scene.patches[patch_index as usize],
            patch_index,
        })
    }

    /// The punctual lights' irradiance at `x` (normal `n`), one shadow ray
    /// each: delta lights are reached by light sampling only.
    fn punctual(&self, x: DVec3, n: DVec3) -> DVec3 {
        let mut h = DVec3::ZERO;
        for light in &self.scene.lights.punctual {
            if let Some(i) = light.incident(x, n, self.far)
                && self.bvh.visible(x, i.toward)
            {
                h += i.irradiance;
            }
        }
        h
    }

    /// One sample of the radiance arriving at `o` from direction `-d`.
    pub(super) fn radiance(&self, o: DVec3, d: DVec3, rng: &mut Pcg64Mcg) -> DVec3 {
        let Some(hit) = self.trace(o, d) else {
            return DVec3::ZERO;
        };
        self.leaving(hit, rng)
    }

    /// One sample of the radiance leaving `hit` (its emission included)
    /// toward where it was seen from.
    pub(super) fn leaving(&self, hit: SurfaceHit<'a>, rng: &mut Pcg64Mcg) -> DVec3 {
        self.leaving_from(hit, None, rng)
    }

    /// [`Tracer::leaving`], the first continuation's cosine-distributed
    /// direction made from the unit-square point `first` when given (a
    /// stratum of the caller's) instead of from `rng`.
    pub(super) fn leaving_from(
        &self,
        mut hit: SurfaceHit<'a>,
        first: Option<DVec2>,
        rng: &mut Pcg64Mcg,
    ) -> DVec3 {
        let mut radiance = hit.patch.emission / PI;
        let mut throughput = DVec3::ONE;
        let mut bounce = 0;
        while bounce < self.max_bounces {
            bounce += 1;
            let rho = hit.patch.reflectance;
            if rho.max_element() <= 0.0 {
                break;
            }
            let x = hit.point;
            let n = hit.patch.normal;
            radiance += throughput
                * rho
                * (self.direct_by_light_sampling(x, n, rng) + self.punctual(x, n) / PI);

            // Cosine-weighted continuation: BSDF × cos / pdf = ρ.
            let wi = match first.filter(|_| bounce == 1) {
                Some(u) => cosine_direction(n, u.x, u.y),
                None => cosine_direction(n, rng.random(), rng.random()),
            };
            let cos_x = n.dot(wi);
            if !(cos_x > 0.0) {
                break;
            }
            throughput *= rho;
            let next = match self.follow(x + self.offset * n, wi) {
                Traced::Hit(next) => next,
                Traced::Escaped => {
                    // The sky, reached by cosine sampling only.
                    if let Some(sky) = &self.scene.lights.sky {
                        radiance += throughput * sky.radiance(wi);
                    }
                    break;
                }
                Traced::Blocked => break,
            };
            if next.patch.is_emitter() {
                let to_light = next.point - x;
                let cos_light = -next.patch.normal.dot(wi);
                if cos_light > 0.0 {
                    let p_bsdf = cos_x / PI;
                    let p_light = self.pick[next.patch_index as usize] / next.patch.area
                        * to_light.length_squared()
                        / cos_light;
                    radiance +=
                        throughput * next.patch.emission / PI * power_weight(p_bsdf, p_light);
                }
            }
            hit = next;
            if bounce >= ROULETTE_START {
                let survive = throughput.max_element().min(MAX_SURVIVAL);
                if !(rng.random::<f64>() < survive) {
                    break;
                }
                throughput /= survive;
            }
        }
        radiance
    }

    /// The MIS-weighted light-sampling estimate of the irradiance-like
    /// integral ∫ L_e cos θ / π dω at `x` (normal `n`): reflected radiance
    /// is ρ times this.
    fn direct_by_light_sampling(&self, x: DVec3, n: DVec3, rng: &mut Pcg64Mcg) -> DVec3 {
        if self.lights.is_empty() {
            return DVec3::ZERO;
        }
        let u: f64 = rng.random();
        let k = self
            .light_cdf
            .partition_point(|&c| c <= u)
            .min(self.lights.len() - 1);
        let index = self.lights[k] as usize;
        let light = &self.scene.patches[index];
        let y = point_in_polygon(light.vertices(), DVec2::new(rng.random(), rng.random()));
        let to_light = y - x;
        let r2 = to_light.length_squared();
        if !(r2 > 0.0) {
            return DVec3::ZERO;
        }
        let wi = to_light / r2.sqrt();
        let cos_x = n.dot(wi);
        let cos_light = -light.normal.dot(wi);
        if !(cos_x > 0.0 && cos_light > 0.0 && self.bvh.visible(x, y)) {
            return DVec3::ZERO;
        }
        let p_light = self.pick[index] / light.area * r2 / cos_light;
        let p_bsdf = cos_x / PI;
        // (ρ/π) L_e cos θ / p_light, with ρ applied by the caller.
        light.emission / PI * (cos_x / PI) / p_light * power_weight(p_light, p_bsdf)
    }
}

/// The power-heuristic weight of the strategy with density `p` against the
/// one with density `other`: p² / (p² + other²), safe for huge ratios.
fn power_weight(p: f64, other: f64) -> f64 {
    let r = other / p;
    if r.is_finite() {
        1.0 / (1.0 + r * r)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_weights_sum_to_one_and_survive_extremes() {
        for (a, b) in [(1.0, 1.0), (0.3, 7.0), (1e-300, 1e300), (5.0, 0.0)] {
            let s = power_weight(a, b) + power_weight(b, a);
            assert!((s - 1.0).abs() < 1e-12, "{a} {b}: {s}");
        }
        assert_eq!(power_weight(2.0, 0.0), 1.0);
    }
}
