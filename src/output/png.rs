//! 8-bit sRGB PNG encoding of linear images, with the exposure rules used
//! for every display output: a solution's own ([`solution_exposure`], for
//! a solve's PNGs and bake) and an image's ([`auto_exposure`], for a
//! reference without a solution). The only user of the `image` crate's PNG
//! encoder.
//!
//! Tone map (documented for users): each channel of a pixel's radiance L is
//! scaled by the exposure, clamped to [0, 1], passed through the sRGB
//! transfer function (IEC 61966-2-1) and rounded to 8 bits:
//!
//! ```text
//! v = clamp(L × exposure, 0, 1)        (NaN → 0)
//! s = 12.92 v                          if v ≤ 0.0031308
//!     1.055 v^(1/2.4) − 0.055          otherwise
//! byte = round(255 s)
//! ```
//!
//! An [`Overlay`] (line coverage a ∈ [0, 1] and colour c, a display value)
//! is composited after the clamp and before the transfer function:
//! `v' = v + a (c − v)`, so anti-aliased lines blend in linear light.
//!
//! Invariant: row 0 of the [`Frame`] is the top row of the PNG.

use std::f32::consts::PI;

use image::ImageEncoder;
use image::codecs::png::PngEncoder;

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;
use crate::render::frame::Frame;
pub use crate::render::frame::luminance;

/// The fraction of the positive luminances that [`auto_exposure`] keeps
/// below full scale.
pub const AUTO_EXPOSURE_PERCENTILE: f64 = 0.99;
/// The display value [`auto_exposure`] gives to that percentile.
pub const AUTO_EXPOSURE_TARGET: f32 = 0.9;

/// The exposure that maps the 99th percentile of the positive, finite
/// luminances to display value 0.9: `0.9 / p99`.
///
/// So the brightest 1 % (typically a small emitter seen directly) clips to
/// white while the rest of the image keeps its gradation. The percentile is
/// the nearest-rank one (the ⌈0.99 k⌉-th smallest of k values). Without any
/// positive finite luminance (a black image), or when the result would not
/// be finite, the exposure is 1.
pub fn auto_exposure(luminances: impl Iterator<Item = f32>) -> f32 {
    let mut positive: Vec<f32> = luminances.filter(|l| l.is_finite() && *l > 0.0).collect();
    if positive.is_empty() {
        return 1.0;
    }
    let rank = (AUTO_EXPOSURE_PERCENTILE * positive.len() as f64).ceil() as usize;
    let index = rank.clamp(1, positive.len()) - 1;
    let (_, p, _) = positive.select_nth_unstable_by(index, f32::total_cmp);
    let exposure = AUTO_EXPOSURE_TARGET / *p;
    if exposure.is_finite() { exposure } else { 1.0 }
}

/// The display value [`solution_exposure`] gives to a solution's
/// log-average vertex luminance.
pub const SOLUTION_KEY: f32 = 0.25;

/// The display exposure of a solution, whatever view shows it:
/// [`SOLUTION_KEY`] / L̄, with L̄ the log-average (geometric mean) of the
/// positive, finite vertex luminances of B / π, each vertex weighted by a
/// third of the area of its triangles.
///
/// So the surfaces that make up most of the scene sit in the middle of
/// the display range and the few much brighter ones (an emitter, a sunlit
/// light well) clip. It depends on the per-vertex solution only: the same
/// solution gives the same exposure at any render size and from any
/// camera. Without any lit vertex, or when the result would not be finite,
/// the exposure is 1.
pub fn solution_exposure(mesh: &OutputMesh) -> f32 {
    let mut weight = vec![0.0f64; mesh.vertex_count()];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
        let third = (b - a).cross(c - a).length() / 6.0;
        for &i in t {
            weight[i as usize] += third;
        }
    }
    let (mut sum, mut total) = (0.0f64, 0.0f64);
    for (b, &w) in mesh.radiosity.iter().zip(&weight) {
        let l = f64::from(luminance((*b / PI).to_array()));
        if l.is_finite() && l > 0.0 && w > 0.0 {
            sum += w * l.ln();
            total += w;
        }
    }
    if !(total > 0.0) {
        return 1.0;
    }
    let exposure = SOLUTION_KEY / (sum / total).exp() as f32;
    if exposure.is_finite() && exposure > 0.0 {
        exposure
    } else {
        1.0
    }
}

/// The sRGB transfer function applied to a display value in [0, 1].
fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// `v` clamped to [0, 1], NaN to 0.
fn unit(v: f32) -> f32 {
    if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) }
}

/// The 8-bit sRGB code of display value `v` in [0, 1].
fn code(v: f32) -> u8 {
    (srgb_encode(v) * 255.0).round().clamp(0.0, 255.0) as u8
}

/// The 8-bit sRGB code of linear value `linear` under `exposure` (the tone
/// map of the module doc).
pub fn display_byte(linear: f32, exposure: f32) -> u8 {
    code(unit(linear * exposure))
}

/// Lines drawn over an image by [`encode_png_with_overlay`].
#[derive(Clone, Copy, Debug)]
pub struct Overlay<'a> {
    /// Coverage in [0, 1] per pixel, row-major like the frame's pixels.
    pub coverage: &'a [f32],
    /// Line colour: a display value in [0, 1] per channel (linear, before
    /// the sRGB transfer function).
    pub color: [f32; 3],
}

/// Encodes `frame` as an 8-bit RGB PNG with the tone map of the module doc.
/// `exposure` must be finite and non-negative.
pub fn encode_png(frame: &Frame, exposure: f32) -> Result<Vec<u8>> {
    encode(frame, exposure, None)
}

/// [`encode_png`] with `overlay` composited as the module doc says. The
/// coverage must have one value per pixel.
pub fn encode_png_with_overlay(frame: &Frame, exposure: f32, overlay: &Overlay) -> Result<Vec<u8>> {
    encode(frame, exposure, Some(overlay))
}

fn encode(frame: &Frame, exposure: f32, overlay: Option<&Overlay>) -> Result<Vec<u8>> {
    if !exposure.is_finite() || exposure < 0.0 {
        return Err(Error::Setting(format!(
            "exposure {exposure} must be finite and non-negative"
        )));
    }
    let (w, h) = (frame.width, frame.height);
    if w == 0 || h == 0 {
        return Err(Error::encode(
            "the PNG image",
            format!("the image is {w}×{h} pixels"),
        ));
    }
    if frame.pixels.len() != w as usize * h as usize {
        return Err(Error::encode(
            "the PNG image",
            format!("{} pixels for a {w}×{h} image", frame.pixels.len()),
        ));
    }
    let bytes: Vec<u8> = match overlay {
        None => frame
            .pixels
            .iter()
            .flat_map(|p| p.map(|c| display_byte(c, exposure)))
            .collect(),
        Some(o) => {
            if o.coverage.len() != frame.pixels.len() {
                return Err(Error::encode(
                    "the PNG overlay",
                    format!("{} coverage values for a {w}×{h} image", o.coverage.len()),
                ));
            }
            let color = o.color.map(unit);
            frame
                .pixels
                .iter()
                .zip(o.coverage)
                .flat_map(|(p, a)| {
                    let a = unit(*a);
                    [0, 1, 2].map(|k| {
                        let v = unit(p[k] * exposure);
                        code(v + a * (color[k] - v))
                    })
                })
                .collect()
        }
    };
    let mut out = Vec::new();
    PngEncoder::new(&mut out)
        .write_image(&bytes, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::encode("the PNG image", e))?;
    Ok(out)
}

/// Encodes ready-made 8-bit sRGB pixels (`width × height × 3` bytes,
/// row-major, row 0 at the top) as a PNG: for charts and false-colour maps,
/// which are drawn in display colours already.
pub fn encode_rgb8(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>> {
    if width == 0 || height == 0 || rgb.len() != width as usize * height as usize * 3 {
        return Err(Error::encode(
            "the PNG image",
            format!("{} bytes for a {width}×{height} RGB image", rgb.len()),
        ));
    }
    let mut out = Vec::new();
    PngEncoder::new(&mut out)
        .write_image(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::encode("the PNG image", e))?;
    Ok(out)
}
