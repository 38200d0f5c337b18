//! The contact sheet of a study: every image beside its error map.
//!
//! Owns the tiles and their labels. Tiles go in pairs (an image, then its
//! relative luminance error on the magma map from 0 to
//! [`compare::DEFAULT_MAX_ERROR`]): first the reference with its own
//! relative noise (or a blank tile when the noise is unknown), then every
//! run in order. Invariant: every image is shown at the reference's
//! exposure, so brightness differences between tiles are real.

use crate::error::Result;
use crate::lab::chart;
use crate::lab::compare;
use crate::lab::study::measure::StudyReference;
use crate::output;
use crate::pipeline::Method;
use crate::render::frame::Frame;

/// Columns of the contact sheet: three (image, error) pairs to a row.
const COLUMNS: usize = 6;

/// The tiles of a contact sheet, in order.
pub(super) struct ContactSheet {
    exposure: f32,
    tiles: Vec<(String, Vec<[u8; 3]>)>,
}

impl ContactSheet {
    /// A sheet starting with the reference and its relative noise, shown at
    /// `exposure`.
    pub(super) fn new(reference: &StudyReference, exposure: f32) -> ContactSheet {
        let image = &reference.image;
        let mut tiles = vec![("reference".to_string(), display(image, exposure))];
        tiles.push(match &reference.noise {
            Some(n) => {
                let noisy = Frame {
                    pixels: image
                        .pixels
                        .iter()
                        .zip(&n.pixels)
                        .map(|(r, e)| [r[0] + e[0], r[1] + e[1], r[2] + e[2]])
                        .collect(),
                    ..image.clone()
                };
                (
                    "reference noise".to_string(),
                    false_colour(&compare::relative_luminance_error(&noisy, image)),
                )
            }
            None => (
                "(noise unknown)".to_string(),
                vec![chart::BACKGROUND; image.pixels.len()],
            ),
        });
        ContactSheet { exposure, tiles }
    }

    /// Adds a run's render and its error against `reference`: the render
    /// labelled by its setting (`h=` before an element fraction) and
    /// method, the error map by the mean relative error.
    pub(super) fn push_run(&mut self, run: RunTile, frame: &Frame, reference: &Frame) {
        let errors = compare::relative_luminance_error(frame, reference);
        let short = match run.method {
            Method::Hierarchical => run.setting.to_string(),
            Method::Classic(_) => format!("h={}", run.setting),
        };
        self.tiles.push((
            format!("{short} {}", run.method_name),
            display(frame, self.exposure),
        ));
        self.tiles.push((
            format!(
                "mean rel. err. {:.1} %",
                100.0 * run.mean_relative_error.unwrap_or(f64::NAN)
            ),
            false_colour(&errors),
        ));
    }

    /// The sheet as PNG, tiles `width` × `height`.
    pub(super) fn encode(&self, width: u32, height: u32) -> Result<Vec<u8>> {
        chart::contact_sheet(&self.tiles, width, height, COLUMNS)
    }
}

/// What labels a run's pair of tiles.
pub(super) struct RunTile<'a> {
    /// The solver run.
    pub method: Method,
    /// The method as the configuration names it.
    pub method_name: &'a str,
    /// The accuracy preset or element fraction.
    pub setting: &'a str,
    /// The run's mean relative error, all channels pooled.
    pub mean_relative_error: Option<f64>,
}

/// Relative errors on the colour map, 0 to [`compare::DEFAULT_MAX_ERROR`].
fn false_colour(errors: &[f64]) -> Vec<[u8; 3]> {
    errors
        .iter()
        .map(|&e| chart::colour_map(e / compare::DEFAULT_MAX_ERROR))
        .collect()
}

/// 8-bit sRGB pixels of `frame` at `exposure`.
fn display(frame: &Frame, exposure: f32) -> Vec<[u8; 3]> {
    frame
        .pixels
        .iter()
        .map(|p| p.map(|c| output::png::display_byte(c, exposure)))
        .collect()
}
