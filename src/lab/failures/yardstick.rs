//! The image yardstick of the failure table: the path-traced reference of
//! a stress scene, the pixels it is compared on, and its own noise.
//!
//! Owns [`Reference`] and what makes it fair to compare against: leaving
//! out the pixels on or next to an emitter ([`receiver_pixels`]) and the
//! hot spots ([`HOT_SPOT`]), and the scale image errors are relative to.
//! The reference is cached on disk through [`crate::lab::reference_cache`]
//! (key in the file name), so a second table run only re-runs the methods.
//!
//! Invariant: the reference depends only on the scene, the table's view,
//! paths per pixel and seed, never on a method measured against it.

use std::f64::consts::PI;
use std::path::Path;
use std::time::Instant;

use crate::error::Result;
use crate::lab::failures::{TableSettings, mean3};
use crate::lab::reference_cache::{self, Naming, ReferenceCache, ReferenceKey};
use crate::render::frame::Frame;
use crate::render::view::View;
use crate::scene::Scene;
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// Reference image, its per-pixel noise, the pixels compared and the
/// seconds it took.
#[derive(Clone, Debug)]
pub struct Reference {
    /// Mean radiance per pixel.
    pub image: Frame,
    /// Standard error of each pixel value, per channel.
    pub noise: Frame,
    /// Pixels compared: those not within a pixel of an emitter
    /// ([`receiver_pixels`]) and not a hot spot ([`HOT_SPOT`]).
    pub counted: Vec<bool>,
    /// What image errors are relative to: the reference's mean over the
    /// counted pixels, or where that is 0 (nothing lit), the emitters' mean
    /// radiance.
    pub scale: f64,
    /// Seconds the path tracing took (with writing the cache); NaN when the
    /// reference was read from the cache.
    pub seconds: f64,
}

/// Pixels of `view` that see no emitter, even at their edges: 3 × 3 rays
/// per pixel, and the pixels next to one that hits an emitter are dropped
/// too. An emitter's edge is a step from L_e to its surroundings that every
/// method renders alike and the reference anti-aliases with far more
/// samples, so it would dominate the error without saying anything about
/// the solution.
pub fn receiver_pixels(scene: &Scene, view: &View) -> Vec<bool> {
    let bvh = TriangleBvh::of_scene(scene);
    let (w, h) = (view.width as usize, view.height as usize);
    let sees_emitter: Vec<bool> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (0..9).any(|k| {
                let (sx, sy) = ((k % 3) as f64 / 2.0, (k / 3) as f64 / 2.0);
                let (o, d) = view.ray(x + sx, y + sy);
                bvh.closest_hit(o, d, f64::INFINITY).is_some_and(|hit| {
                    let t = &scene.triangles[hit.triangle as usize];
                    std::iter::once(t.front_patch)
                        .chain(t.back_patch)
                        .any(|p| scene.patches[p as usize].is_emitter())
                })
            })
        })
        .collect();
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            !(-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (nx, ny) = (x + dx, y + dy);
                    nx >= 0
                        && ny >= 0
                        && (nx as usize) < w
                        && (ny as usize) < h
                        && sees_emitter[ny as usize * w + nx as usize]
                })
            })
        })
        .collect()
}

/// The path-traced reference of `scene` from `view`, read from `cache`
/// (a folder) when a previous run left it there for the same name, size,
/// spp and seed, otherwise rendered and stored there.
pub fn reference(
    scene: &Scene,
    name: &str,
    view: &View,
    t: &TableSettings,
    cache: Option<&Path>,
) -> Result<Reference> {
    let key = ReferenceKey {
        scene: name,
        view,
        spp: t.reference_spp,
        seed: t.seed,
    };
    let cache = cache.map(|dir| ReferenceCache {
        dir,
        naming: Naming::KeyInFileName,
    });
    let cached = match &cache {
        Some(c) => c.load(&key)?,
        None => None,
    };
    let (image, noise, seconds) = match cached {
        Some((image, noise)) => (image, noise, f64::NAN),
        None => {
            let start = Instant::now();
            let r = reference_cache::render(scene, &key, &Progress::hidden())?;
            if let Some(c) = &cache {
                c.write(&key, &r)?;
            }
            (r.image, r.noise, start.elapsed().as_secs_f64())
        }
    };
    let counted = without_hot_spots(&image, receiver_pixels(scene, view));
    let scale = error_scale(scene, &image, &counted);
    Ok(Reference {
        image,
        noise,
        counted,
        scale,
        seconds,
    })
}

/// [`Reference::scale`]: the mean of `image` over the `counted` pixels, or
/// where that is not positive, the emitters' mean radiance (1 without
/// emitters).
fn error_scale(scene: &Scene, image: &Frame, counted: &[bool]) -> f64 {
    let scale = masked_mean(image, counted);
    if scale > 0.0 {
        return scale;
    }
    let (power, area) = scene
        .patches
        .iter()
        .filter(|p| p.is_emitter())
        .fold((0.0, 0.0), |(w, a), p| {
            (w + mean3(p.emission) * p.area, a + p.area)
        });
    if area > 0.0 { power / area / PI } else { 1.0 }
}

/// Pixels whose reference value exceeds this multiple of the median lit
/// pixel are hot spots, left out of the image errors.
pub const HOT_SPOT: f64 = 20.0;

/// `counted` without the hot spots of `image`: pixels brighter than
/// [`HOT_SPOT`] × the median of the counted pixels that are not black. A
/// hot spot (a wall 2 mm from a lamp) is an emitter in all but name: a few
/// sub-pixel features whose value the reference itself resolves only to
/// within its noise, and which would otherwise decide the whole error.
fn without_hot_spots(image: &Frame, mut counted: Vec<bool>) -> Vec<bool> {
    let value = |p: &[f32; 3]| (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0;
    let mut lit: Vec<f64> = image
        .pixels
        .iter()
        .zip(&counted)
        .filter(|(_, c)| **c)
        .map(|(p, _)| value(p))
        .filter(|&v| v > 0.0)
        .collect();
    if lit.is_empty() {
        return counted;
    }
    let mid = lit.len() / 2;
    let median = *lit.select_nth_unstable_by(mid, f64::total_cmp).1;
    for (c, p) in counted.iter_mut().zip(&image.pixels) {
        if value(p) > HOT_SPOT * median {
            *c = false;
        }
    }
    counted
}

/// The reference's own noise: RMS of its per-pixel standard error over the
/// counted pixels, relative to [`Reference::scale`].
pub fn reference_noise(r: &Reference) -> f64 {
    let squares = Frame {
        pixels: r.noise.pixels.iter().map(|p| p.map(|c| c * c)).collect(),
        ..r.noise.clone()
    };
    masked_mean(&squares, &r.counted).sqrt() / r.scale
}

/// Mean over channels and counted pixels.
pub(super) fn masked_mean(f: &Frame, counted: &[bool]) -> f64 {
    let (sum, n) = f
        .pixels
        .iter()
        .zip(counted)
        .filter(|(_, c)| **c)
        .fold((0.0, 0usize), |(s, n), (p, _)| {
            (s + p.iter().map(|&c| c as f64).sum::<f64>(), n + 3)
        });
    if n > 0 { sum / n as f64 } else { 0.0 }
}
