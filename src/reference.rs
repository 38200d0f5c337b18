//! The reference renderer: an independent, unbiased path tracer of the same
//! scene and view, the yardstick the radiosity solvers are checked against.
//!
//! Owns: the light transport estimator and the per-pixel noise estimate.
//!
//! Invariants:
//! - **Shares nothing with the radiosity code.** It uses only the scene
//!   (patches' ρ, E, normals and the triangles' patch ids), the BVH
//!   ([`TriangleBvh`]), the view ([`View::ray`], the same camera and pixel
//!   footprint as `render`, so images line up pixel for pixel) and the
//!   seeded streams of [`crate::sampling`]. No element, form factor, matrix,
//!   solver or output mesh is involved.
//! - Physics as the contract states it: Lambertian, one-sided patches
//!   (reflectance ρ, emitted radiance L_e = E / π on the front only);
//!   hitting the back of a one-sided surface ends the path with radiance 0;
//!   double-sided surfaces are two patches, one per side.
//! - Deterministic: sample `s` of pixel `(x, y)` draws from
//!   `stream(seed ^ TAG, (y·width + x) << 32 | s)`, never from a per-thread
//!   generator, and each pixel's sums run in sample order, so the image is
//!   bit-identical for any thread count.
//!
//! Estimator (per sample): a uniformly random point in the pixel's footprint
//! (box filter) gives the camera ray; at every surface vertex the direct
//! light is estimated twice and combined by multiple importance sampling
//! with the power heuristic [Veach97, §9.2]:
//! - light sampling: an emitting patch is picked with probability
//!   proportional to its power Σ_c E_c·A, a point uniformly on it, and a
//!   shadow ray ([`TriangleBvh::visible`]) tests it; its area density is
//!   converted to solid angle, p_light = P(patch) / A · r² / cos θ_light;
//! - BSDF sampling: the continuation direction is cosine-distributed,
//!   p_bsdf = cos θ / π; when that ray hits the front of an emitter, L_e is
//!   counted with weight p_bsdf² / (p_bsdf² + p_light²).
//!
//! The camera ray's own hit on an emitter counts L_e in full. Russian
//! roulette starts after [`ROULETTE_START`] bounces: a path survives with
//! probability min(max channel of its throughput, [`MAX_SURVIVAL`]) and its
//! throughput is divided by that probability. Paths have no bounce limit
//! unless one is set, but never exceed the safety cap
//! [`MAX_BOUNCES_CAP`] (at which the remaining throughput of any
//! physical scene, ρ < 1, is negligible).
//!
//! Noise estimate: pixel positions are independent and uniform, so the
//! samples of a pixel are independent and identically distributed. The
//! noise image holds, per pixel and channel, the standard error of the
//! pixel mean estimated from the sample variance,
//! `sqrt(Σ (x_i − x̄)² / (N (N − 1)))`, whose square is an unbiased
//! estimate of the variance of the pixel value.

use std::f64::consts::PI;
use std::time::Instant;

use glam::{DVec2, DVec3};
use rand::Rng;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::render::frame::Frame;
use crate::render::view::View;
use crate::sampling::{point_in_polygon, stream};
use crate::scene::{Patch, Scene};
use crate::util::progress::Progress;
use crate::visibility::{ENDPOINT_GAP, TriangleBvh};

/// Hard cap on the bounces of any path, whatever `max_bounces` says.
pub const MAX_BOUNCES_CAP: u32 = 10_000;
/// Russian roulette applies from this bounce on.
pub const ROULETTE_START: u32 = 3;
/// Largest survival probability of Russian roulette, so that paths in
/// scenes of very high reflectance still end.
pub const MAX_SURVIVAL: f64 = 0.99;
/// Mixed into the seed so that the reference and `render` never share a
/// stream for the same seed.
const SEED_TAG: u64 = 0x7265_6665_7265_6e63;

/// Settings of a reference render.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceSettings {
    /// Paths per pixel; at least 2 (the noise estimate needs two).
    pub samples_per_pixel: u32,
    /// Seed of every path.
    pub seed: u64,
    /// Largest number of reflections of a path; `None` for unlimited (up to
    /// [`MAX_BOUNCES_CAP`]). 0 shows only the emitters seen directly.
    pub max_bounces: Option<u32>,
}

impl ReferenceSettings {
    /// Checks the sample count (at least 2: the noise estimate needs two).
    /// The error names the command-line option.
    pub fn validate(&self) -> Result<()> {
        if self.samples_per_pixel < 2 {
            return Err(Error::Setting(
                "--spp must be at least 2 for the reference's noise estimate".into(),
            ));
        }
        Ok(())
    }
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        ReferenceSettings {
            samples_per_pixel: 64,
            seed: 0,
            max_bounces: None,
        }
    }
}

/// Figures of a reference render; written as the `<stem>.json` sidecar.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceStats {
    /// The scene file, as given (empty when rendered from memory).
    pub scene: String,
    /// Paths per pixel.
    pub spp: u32,
    /// Seed of every path.
    pub seed: u64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The bounce limit, `null` when unlimited.
    pub max_bounces: Option<u32>,
    /// Wall time of the path tracing, seconds.
    pub time_seconds: f64,
    /// Paths traced per second of wall time (width × height × spp / time).
    pub samples_per_second: f64,
    /// Mean of the image over all pixels and channels.
    pub mean_radiance: f64,
    /// Root mean square of the noise image over all pixels and channels.
    pub noise_rms: f64,
    /// `noise_rms / mean_radiance`: the expected relative RMS error of the
    /// image (0 for a black image).
    pub relative_noise: f64,
}

/// A reference image, its per-pixel standard error, and its figures.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceImage {
    /// Mean radiance per pixel.
    pub image: Frame,
    /// Standard error of each pixel value, per channel (module doc).
    pub noise: Frame,
    /// What the render did and how noisy it is.
    pub stats: ReferenceStats,
}

/// Path traces `scene` from `view`.
pub fn render_reference(
    scene: &Scene,
    view: &View,
    settings: &ReferenceSettings,
    progress: &Progress,
) -> Result<ReferenceImage> {
    settings.validate()?;
    let n = settings.samples_per_pixel;
    let start = Instant::now();
    let tracer = Tracer::new(scene, settings.max_bounces)?;
    let (w, h) = (view.width, view.height);
    let seed = settings.seed ^ SEED_TAG;
    let phase = progress.phase("reference", h as u64);
    let rows: Vec<Vec<([f32; 3], [f32; 3])>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let row = (0..w)
                .map(|x| {
                    let pixel = u64::from(y) * u64::from(w) + u64::from(x);
                    // Welford's running mean and sum of squared deviations.
                    let mut mean = DVec3::ZERO;
                    let mut m2 = DVec3::ZERO;
                    for s in 0..n {
                        let mut rng = stream(seed, pixel << 32 | u64::from(s));
                        let px = f64::from(x) + rng.random::<f64>();
                        let py = f64::from(y) + rng.random::<f64>();
                        let (o, d) = view.ray(px, py);
                        let l = tracer.radiance(o, d, &mut rng);
                        let delta = l - mean;
                        mean += delta / f64::from(s + 1);
                        m2 += delta * (l - mean);
                    }
                    let n = f64::from(n);
                    let se = (m2 / ((n - 1.0) * n)).max(DVec3::ZERO).map(f64::sqrt);
                    (mean.as_vec3().to_array(), se.as_vec3().to_array())
                })
                .collect();
            phase.inc(1);
            row
        })
        .collect();
    drop(phase);
    let time = start.elapsed().as_secs_f64();
    let (image, noise): (Vec<[f32; 3]>, Vec<[f32; 3]>) = rows.into_iter().flatten().unzip();
    let values = 3.0 * image.len() as f64;
    let mean_radiance = image.iter().flatten().map(|&v| f64::from(v)).sum::<f64>() / values;
    let noise_rms = (noise
        .iter()
        .flatten()
        .map(|&v| f64::from(v).powi(2))
        .sum::<f64>()
        / values)
        .sqrt();
    let samples = f64::from(w) * f64::from(h) * f64::from(settings.samples_per_pixel);
    let stats = ReferenceStats {
        scene: String::new(),
        spp: settings.samples_per_pixel,
        seed: settings.seed,
        width: w,
        height: h,
        max_bounces: settings.max_bounces,
        time_seconds: time,
        samples_per_second: if time > 0.0 { samples / time } else { 0.0 },
        mean_radiance,
        noise_rms,
        relative_noise: if mean_radiance > 0.0 {
            noise_rms / mean_radiance
        } else {
            0.0
        },
    };
    Ok(ReferenceImage {
        image: Frame {
            width: w,
            height: h,
            pixels: image,
        },
        noise: Frame {
            width: w,
            height: h,
            pixels: noise,
        },
        stats,
    })
}

/// Where the noise image of `image` goes: `<stem>.noise.exr` beside it.
pub fn noise_path(image: &std::path::Path) -> std::path::PathBuf {
    sidecar(image, "noise.exr")
}

/// Where the JSON sidecar of `image` goes: `<stem>.json` beside it.
pub fn stats_path(image: &std::path::Path) -> std::path::PathBuf {
    sidecar(image, "json")
}

fn sidecar(image: &std::path::Path, suffix: &str) -> std::path::PathBuf {
    let stem = image
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "reference".into());
    image.with_file_name(format!("{stem}.{suffix}"))
}

/// A surface point reached by a ray, on the radiating side of its patch.
struct SurfaceHit<'a> {
    point: DVec3,
    patch: &'a Patch,
    patch_index: u32,
}

/// The scene prepared for path tracing.
struct Tracer<'a> {
    scene: &'a Scene,
    bvh: TriangleBvh,
    /// Unit normal of each scene triangle's front face.
    normals: Vec<DVec3>,
    /// Emitting patches and the cumulative selection probabilities.
    lights: Vec<u32>,
    light_cdf: Vec<f64>,
    /// Probability of picking each patch for light sampling (0 for
    /// non-emitters).
    pick: Vec<f64>,
    /// Offset of continuation rays off their surface.
    offset: f64,
    max_bounces: u32,
}

impl<'a> Tracer<'a> {
    fn new(scene: &'a Scene, max_bounces: Option<u32>) -> Result<Tracer<'a>> {
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
        if lights.is_empty() || !(total.is_finite() && total > 0.0) {
            return Err(Error::NoEmitters);
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
            max_bounces: max_bounces.unwrap_or(MAX_BOUNCES_CAP).min(MAX_BOUNCES_CAP),
        })
    }

    /// The radiating surface hit first along `o + t d` (`d` unit), or
    /// `None` when the ray escapes or meets the back of a one-sided surface.
    fn trace(&self, o: DVec3, d: DVec3) -> Option<SurfaceHit<'a>> {
        let hit = self.bvh.closest_hit(o, d, f64::from(f32::MAX))?;
        let triangle = &self.scene.triangles[hit.triangle as usize];
        let patch_index = if self.normals[hit.triangle as usize].dot(d) < 0.0 {
            triangle.front_patch
        } else {
            triangle.back_patch?
        };
        Some(SurfaceHit {
            point: o + hit.t * d,
            patch: &self.scene.patches[patch_index as usize],
            patch_index,
        })
    }

    /// One sample of the radiance arriving at `o` from direction `-d`.
    fn radiance(&self, o: DVec3, d: DVec3, rng: &mut Pcg64Mcg) -> DVec3 {
        let Some(mut hit) = self.trace(o, d) else {
            return DVec3::ZERO;
        };
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
            radiance += throughput * rho * self.direct_by_light_sampling(x, n, rng);

            // Cosine-weighted continuation: BSDF × cos / pdf = ρ.
            let wi = cosine_direction(n, rng.random(), rng.random());
            let cos_x = n.dot(wi);
            if !(cos_x > 0.0) {
                break;
            }
            throughput *= rho;
            let Some(next) = self.trace(x + self.offset * n, wi) else {
                break;
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

/// A cosine-distributed unit direction about unit `n` from two uniform
/// numbers in [0, 1) (Malley's method: uniform disc, projected up).
fn cosine_direction(n: DVec3, u1: f64, u2: f64) -> DVec3 {
    let (t, b) = n.any_orthonormal_pair();
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    (r * phi.cos() * t + r * phi.sin() * b + z * n).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_directions_have_the_cosine_moments() {
        // E[cos θ] = 2/3 and E[cos² θ] = 1/2 for the cosine density.
        let n = DVec3::new(1.0, 2.0, -0.5).normalize();
        let mut rng = stream(5, 0);
        let k = 200_000;
        let (mut m1, mut m2) = (0.0, 0.0);
        for _ in 0..k {
            let d = cosine_direction(n, rng.random(), rng.random());
            assert!((d.length() - 1.0).abs() < 1e-12);
            let c = d.dot(n);
            assert!(c >= 0.0);
            m1 += c;
            m2 += c * c;
        }
        assert!(
            (m1 / k as f64 - 2.0 / 3.0).abs() < 3e-3,
            "{}",
            m1 / k as f64
        );
        assert!((m2 / k as f64 - 0.5).abs() < 3e-3, "{}", m2 / k as f64);
    }

    #[test]
    fn power_weights_sum_to_one_and_survive_extremes() {
        for (a, b) in [(1.0, 1.0), (0.3, 7.0), (1e-300, 1e300), (5.0, 0.0)] {
            let s = power_weight(a, b) + power_weight(b, a);
            assert!((s - 1.0).abs() < 1e-12, "{a} {b}: {s}");
        }
        assert_eq!(power_weight(2.0, 0.0), 1.0);
    }

    #[test]
    fn sidecars_sit_beside_the_image() {
        let p = std::path::Path::new("out/ref.exr");
        assert_eq!(noise_path(p), std::path::Path::new("out/ref.noise.exr"));
        assert_eq!(stats_path(p), std::path::Path::new("out/ref.json"));
    }
}
