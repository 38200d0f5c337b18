//! Comparing a rendered image with a reference: the metrics and error
//! images of `nusselt compare`.
//!
//! Owns: the definitions of every comparison metric, the reference-noise
//! correction, and the contents of `error.exr` and `error.png` (drawn by
//! [`crate::lab::chart`], written by `output`).
//!
//! Definitions, over the N pixels of a channel (per channel) or the 3N
//! values of all channels pooled (overall), with test t, reference r and
//! difference d = t − r:
//!
//! ```text
//! RMSE                 sqrt(mean(d²))
//! relative RMSE        RMSE / mean(r)                          (null when mean(r) ≤ 0)
//! ε                    RELATIVE_EPSILON × mean(|r|)            (1 % of the reference level)
//! mean relative error  mean(|d| / max(|r|, ε))                 (null when ε = 0: black reference)
//! max absolute error   max |d|, at its first pixel in row-major order (channels R, G, B)
//! noise RMS            sqrt(mean(s²)), s the reference's standard error per pixel
//! noise-corrected RMSE sqrt(max(0, RMSE² − noise RMS²))
//! ```
//!
//! ε keeps black or nearly black reference pixels (a background, a deep
//! shadow) from dominating the mean relative error: below 1 % of the mean
//! reference level, the error counts relative to that level instead.
//!
//! The noise correction: a path-traced reference r = r̂ + e carries
//! zero-mean noise e of variance s² independent of the test, so
//! E[(t − r)²] = (t − r̂)² + s², and subtracting the mean s² estimates the
//! error against the noise-free image. The noise file `<stem>.noise.exr`
//! beside the reference holds s per pixel and channel (the standard error
//! of the pixel's mean).
//!
//! `error.png` shows, per pixel, the relative luminance error
//! |Y(t) − Y(r)| / max(|Y(r)|, ε_Y), with Y the Rec. 709 luminance and ε_Y
//! = 1 % of the mean |Y(r)|, on the magma colour map from 0 to a maximum
//! (default 20 %, larger errors saturate), with a labelled scale bar.
//!
//! Invariants: metrics are computed in f64 with sequential sums in a fixed
//! order, so the same images give the same JSON; images of different sizes
//! and non-finite pixels are errors naming the file, never NaN metrics.
//! Comparing knows nothing of the solver: it needs only images
//! ([`Frame`]), the output encoders and the generic drawing of
//! [`crate::lab::chart`].

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::lab::chart;
use crate::output::exr;
use crate::output::png::luminance;
use crate::render::frame::Frame;

/// ε as a fraction of the mean absolute reference value (module doc).
pub const RELATIVE_EPSILON: f64 = 0.01;
/// Default top of the `error.png` colour scale: a relative error of 20 %.
pub const DEFAULT_MAX_ERROR: f64 = 0.2;
/// Channel names, in pixel order.
pub const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// Where a maximum occurs.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct PixelAt {
    /// Column, from the left.
    pub x: u32,
    /// Row, from the top.
    pub y: u32,
    /// `R`, `G` or `B`.
    pub channel: String,
}

/// The metrics of one channel, or of all channels pooled.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ChannelMetrics {
    /// Mean of the test image.
    pub mean_test: f64,
    /// Mean of the reference.
    pub mean_reference: f64,
    /// sqrt(mean((t − r)²)).
    pub rmse: f64,
    /// RMSE / mean of the reference; null when that mean is not positive.
    pub relative_rmse: Option<f64>,
    /// Mean of |t − r| / max(|r|, ε); null when ε is 0 (black reference).
    pub mean_relative_error: Option<f64>,
    /// The ε used: [`RELATIVE_EPSILON`] × mean |r|.
    pub epsilon: f64,
    /// max |t − r|.
    pub max_abs_error: f64,
    /// Where the maximum is first reached (row-major, channels R, G, B).
    pub max_at: PixelAt,
    /// RMS of the reference's standard error; null without a noise file.
    pub noise_rms: Option<f64>,
    /// noise RMS / mean of the reference; null without a noise file or when
    /// that mean is not positive.
    pub noise_relative_rms: Option<f64>,
    /// sqrt(max(0, RMSE² − noise RMS²)); null without a noise file.
    pub noise_corrected_rmse: Option<f64>,
}

/// Per-channel metrics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ChannelSet {
    /// Red.
    #[serde(rename = "R")]
    pub r: ChannelMetrics,
    /// Green.
    #[serde(rename = "G")]
    pub g: ChannelMetrics,
    /// Blue.
    #[serde(rename = "B")]
    pub b: ChannelMetrics,
}

/// Everything `nusselt compare` prints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Metrics {
    /// The test image's file.
    pub test: String,
    /// The reference's file.
    pub reference: String,
    /// The reference's noise file, when one was found.
    pub noise: Option<String>,
    /// Width of both images, pixels.
    pub width: u32,
    /// Height of both images, pixels.
    pub height: u32,
    /// Pixels per channel (width × height).
    pub pixels: u64,
    /// [`RELATIVE_EPSILON`].
    pub relative_epsilon: f64,
    /// Each channel apart.
    pub channels: ChannelSet,
    /// All channels pooled.
    pub overall: ChannelMetrics,
}

/// An image with the file it came from (named in errors).
#[derive(Clone, Copy, Debug)]
pub struct Named<'a> {
    /// The file (or name) errors and metrics give.
    pub path: &'a Path,
    /// The image.
    pub frame: &'a Frame,
}

/// The noise file of `reference`: `<stem>.noise.exr` in the same folder.
pub fn noise_path(reference: &Path) -> PathBuf {
    let stem = reference
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    reference.with_file_name(format!("{stem}.noise.exr"))
}

/// Which pixel values [`check`] accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Values {
    /// Any finite value (an image).
    Finite,
    /// Finite and not negative (a standard-error image).
    NonNegative,
}

/// Checks that `image` has the size of `like` (when given) and only
/// `values` pixels.
fn check(image: Named, like: Option<Named>, what: &str, values: Values) -> Result<()> {
    let f = image.frame;
    if f.width == 0 || f.height == 0 || f.pixels.len() != f.width as usize * f.height as usize {
        return Err(Error::data(
            image.path,
            format!("the {what} has no usable pixels ({}×{})", f.width, f.height),
        ));
    }
    if let Some(other) = like {
        let o = other.frame;
        if (f.width, f.height) != (o.width, o.height) {
            return Err(Error::data(
                image.path,
                format!(
                    "the {what} is {}×{} pixels but {} is {}×{}",
                    f.width,
                    f.height,
                    other.path.display(),
                    o.width,
                    o.height
                ),
            ));
        }
    }
    for (k, p) in f.pixels.iter().enumerate() {
        for (c, v) in p.iter().enumerate() {
            if !v.is_finite() || (values == Values::NonNegative && *v < 0.0) {
                let (x, y) = (k % f.width as usize, k / f.width as usize);
                return Err(Error::data(
                    image.path,
                    format!(
                        "the {what} has {} {v} in channel {} at pixel ({x}, {y})",
                        if v.is_finite() {
                            "the negative value"
                        } else {
                            "the non-finite value"
                        },
                        CHANNELS[c]
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// The metrics of the values of `channels` (pooled), module doc.
fn scope_metrics(
    test: &Frame,
    reference: &Frame,
    noise: Option<&Frame>,
    channels: &[usize],
) -> ChannelMetrics {
    let width = reference.width as usize;
    let mut sum_t = 0.0;
    let mut sum_r = 0.0;
    let mut sum_abs_r = 0.0;
    let mut sum_d2 = 0.0;
    let mut sum_s2 = 0.0;
    let mut max_abs = -1.0;
    let mut max_at = (0, channels[0]);
    for (k, (t, r)) in test.pixels.iter().zip(&reference.pixels).enumerate() {
        for &c in channels {
            let (tv, rv) = (f64::from(t[c]), f64::from(r[c]));
            let d = tv - rv;
            sum_t += tv;
            sum_r += rv;
            sum_abs_r += rv.abs();
            sum_d2 += d * d;
            if d.abs() > max_abs {
                max_abs = d.abs();
                max_at = (k, c);
            }
            if let Some(n) = noise {
                let s = f64::from(n.pixels[k][c]);
                sum_s2 += s * s;
            }
        }
    }
    let count = (reference.pixels.len() * channels.len()) as f64;
    let mean_reference = sum_r / count;
    let mse = sum_d2 / count;
    let rmse = mse.sqrt();
    let epsilon = RELATIVE_EPSILON * sum_abs_r / count;
    let mean_relative_error = (epsilon > 0.0).then(|| {
        let mut sum = 0.0;
        for (t, r) in test.pixels.iter().zip(&reference.pixels) {
            for &c in channels {
                let (tv, rv) = (f64::from(t[c]), f64::from(r[c]));
                sum += (tv - rv).abs() / rv.abs().max(epsilon);
            }
        }
        sum / count
    });
    let relative = |v: f64| (mean_reference > 0.0).then(|| v / mean_reference);
    let noise_ms = noise.map(|_| sum_s2 / count);
    ChannelMetrics {
        mean_test: sum_t / count,
        mean_reference,
        rmse,
        relative_rmse: relative(rmse),
        mean_relative_error,
        epsilon,
        max_abs_error: max_abs.max(0.0),
        max_at: PixelAt {
            x: (max_at.0 % width) as u32,
            y: (max_at.0 / width) as u32,
            channel: CHANNELS[max_at.1].to_string(),
        },
        noise_rms: noise_ms.map(f64::sqrt),
        noise_relative_rms: noise_ms.and_then(|ms| relative(ms.sqrt())),
        noise_corrected_rmse: noise_ms.map(|ms| (mse - ms).max(0.0).sqrt()),
    }
}

/// Compares `test` with `reference` (and the reference's standard-error
/// image `noise`, when known). Fails, naming the file, when the sizes
/// differ or a pixel is not finite (or a noise value is negative).
pub fn compare_frames(test: Named, reference: Named, noise: Option<Named>) -> Result<Metrics> {
    check(reference, None, "reference", Values::Finite)?;
    check(test, Some(reference), "test image", Values::Finite)?;
    if let Some(n) = noise {
        check(
            n,
            Some(reference),
            "reference's noise image",
            Values::NonNegative,
        )?;
    }
    let noise_frame = noise.map(|n| n.frame);
    let (t, r) = (test.frame, reference.frame);
    Ok(Metrics {
        test: test.path.display().to_string(),
        reference: reference.path.display().to_string(),
        noise: noise.map(|n| n.path.display().to_string()),
        width: r.width,
        height: r.height,
        pixels: r.pixels.len() as u64,
        relative_epsilon: RELATIVE_EPSILON,
        channels: ChannelSet {
            r: scope_metrics(t, r, noise_frame, &[0]),
            g: scope_metrics(t, r, noise_frame, &[1]),
            b: scope_metrics(t, r, noise_frame, &[2]),
        },
        overall: scope_metrics(t, r, noise_frame, &[0, 1, 2]),
    })
}

/// Two images read from disk, the noise image when there is one, and
/// their metrics.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// The test image.
    pub test: Frame,
    /// The reference.
    pub reference: Frame,
    /// The reference's standard error per pixel, when its file exists.
    pub noise: Option<Frame>,
    /// Their metrics.
    pub metrics: Metrics,
}

/// Reads `test`, `reference` and, when it exists, the reference's noise
/// file ([`noise_path`]), and compares them.
pub fn compare_files(test: &Path, reference: &Path) -> Result<Comparison> {
    let test_frame = exr::read_image(test)?;
    let reference_frame = exr::read_image(reference)?;
    let noise_file = noise_path(reference);
    let noise = if noise_file.is_file() {
        Some(exr::read_image(&noise_file)?)
    } else {
        None
    };
    let metrics = compare_frames(
        Named {
            path: test,
            frame: &test_frame,
        },
        Named {
            path: reference,
            frame: &reference_frame,
        },
        noise.as_ref().map(|frame| Named {
            path: &noise_file,
            frame,
        }),
    )?;
    Ok(Comparison {
        test: test_frame,
        reference: reference_frame,
        noise,
        metrics,
    })
}

/// The signed difference `test − reference`, pixel by pixel and channel by
/// channel (the contents of `error.exr`). The images must have one size.
pub fn difference(test: &Frame, reference: &Frame) -> Frame {
    Frame {
        width: reference.width,
        height: reference.height,
        pixels: test
            .pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(t, r)| [t[0] - r[0], t[1] - r[1], t[2] - r[2]])
            .collect(),
    }
}

/// The relative luminance error per pixel, row-major (what `error.png`
/// shows): |Y(t) − Y(r)| / max(|Y(r)|, ε_Y), ε_Y = [`RELATIVE_EPSILON`] ×
/// mean |Y(r)|. Equal pixels give 0; a differing pixel of an all-black
/// reference gives +∞.
pub fn relative_luminance_error(test: &Frame, reference: &Frame) -> Vec<f64> {
    let y = |p: &[f32; 3]| f64::from(luminance(*p));
    let n = reference.pixels.len().max(1) as f64;
    let epsilon = RELATIVE_EPSILON * reference.pixels.iter().map(|p| y(p).abs()).sum::<f64>() / n;
    test.pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(t, r)| {
            let d = (y(t) - y(r)).abs();
            if d == 0.0 {
                0.0
            } else {
                d / y(r).abs().max(epsilon)
            }
        })
        .collect()
}

/// A relative error as a percentage tick label: `5 %`, `2.5 %`.
fn percent_label(v: &f64) -> String {
    let p = v * 100.0;
    if (p - p.round()).abs() < 1e-6 {
        format!("{:.0} %", p.round())
    } else if (p * 10.0 - (p * 10.0).round()).abs() < 1e-6 {
        format!("{p:.1} %")
    } else {
        format!("{p:.2} %")
    }
}

/// The bytes of `error.exr` and `error.png`.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorImages {
    /// The signed difference, float RGB OpenEXR.
    pub exr: Vec<u8>,
    /// The relative luminance error on the colour map, PNG.
    pub png: Vec<u8>,
}

/// Encodes the error images of two images of one size: the signed
/// difference as float RGB OpenEXR, and the relative luminance error as a
/// false-colour PNG scaled from 0 to `max_error` (a fraction, e.g. 0.2 for
/// 20 %) with a scale bar.
pub fn error_images(test: &Frame, reference: &Frame, max_error: f64) -> Result<ErrorImages> {
    if !(max_error > 0.0 && max_error.is_finite()) {
        return Err(Error::Setting(format!(
            "the largest error shown ({max_error}) must be a positive number"
        )));
    }
    if (test.width, test.height) != (reference.width, reference.height) {
        return Err(Error::Setting(format!(
            "cannot draw the error of a {}×{} image against a {}×{} reference",
            test.width, test.height, reference.width, reference.height
        )));
    }
    let exr = exr::encode_image(
        &difference(test, reference),
        &exr::ImageInfo::new(exr::Quantity::RadianceDifference),
    )?;
    let png = chart::false_colour_png(
        reference.width,
        reference.height,
        &relative_luminance_error(test, reference),
        max_error,
        "relative luminance error |test - reference| / max(reference, eps)",
        &percent_label,
    )?;
    Ok(ErrorImages { exr, png })
}
