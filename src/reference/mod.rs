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

mod probe;
mod tracer;

pub use probe::{ProbePoint, ProbeSettings, ProbeValue, probe_radiosity, random_points};

use std::time::Instant;

use glam::DVec3;
use rand::Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::render::frame::Frame;
use crate::render::view::View;
use crate::sampling::stream;
use crate::scene::Scene;
use crate::util::progress::Progress;
use tracer::Tracer;

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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sidecars_sit_beside_the_image() {
        let p = std::path::Path::new("out/ref.exr");
        assert_eq!(noise_path(p), std::path::Path::new("out/ref.noise.exr"));
        assert_eq!(stats_path(p), std::path::Path::new("out/ref.json"));
    }
}
