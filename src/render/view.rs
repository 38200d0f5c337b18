//! The view: which camera an image is taken from, and the mapping from
//! pixels to rays shared by every renderer.
//!
//! Owns: resolving the scene camera, the command-line overrides and the
//! default framing into one [`View`].
//!
//! Invariants:
//! - Pixel (x, y) covers [x, x+1) × [y, y+1) in image coordinates, row 0 at
//!   the top; every renderer maps image points to rays with [`View::ray`],
//!   so images of the same view line up pixel for pixel.
//! - `forward`, `right`, `up` are orthonormal.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::classic::uniform::human_bytes;
use crate::error::{Error, Result};
use crate::scene::Camera;

/// Default image width when nothing else fixes it.
pub const DEFAULT_WIDTH: u32 = 512;
/// Vertical field of view of the default framing, degrees.
pub const DEFAULT_FOV_DEG: f64 = 45.0;
/// Largest image side accepted.
pub const MAX_SIDE: u32 = 16_384;
/// Bytes a render holds per pixel at most: each pixel's mean and sample
/// spread (32 bytes, twice while the rows are joined), the frame (12), its
/// encodings (up to 24) and a wireframe's coverage (4), rounded up.
pub const RENDER_BYTES_PER_PIXEL: u64 = 128;
/// Bytes a finished frame holds per pixel (linear RGB f32).
pub const FRAME_BYTES_PER_PIXEL: u64 = 12;

/// Command-line overrides of the view; any subset may be given.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewOverrides {
    /// Camera position.
    pub eye: Option<DVec3>,
    /// Point the camera looks at.
    pub target: Option<DVec3>,
    /// Up direction.
    pub up: Option<DVec3>,
    /// Vertical field of view in degrees.
    pub fov_deg: Option<f64>,
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
}

/// A pinhole view and image size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct View {
    /// Camera position.
    #[schemars(with = "[f64; 3]")]
    pub eye: DVec3,
    /// Unit viewing direction.
    #[schemars(with = "[f64; 3]")]
    pub forward: DVec3,
    /// Unit right vector of the image plane.
    #[schemars(with = "[f64; 3]")]
    pub right: DVec3,
    /// Unit up vector of the image plane.
    #[schemars(with = "[f64; 3]")]
    pub up: DVec3,
    /// Vertical field of view, radians.
    pub yfov: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl View {
    /// The view from `base` (the scene's first camera, or else a default
    /// framing of `bounds`), with `overrides` applied.
    pub fn resolve(
        base: Option<&Camera>,
        bounds: (DVec3, DVec3),
        o: &ViewOverrides,
    ) -> Result<View> {
        let (eye, forward, up, yfov, aspect) = match base {
            Some(c) => (c.eye, c.forward, c.up, c.yfov, c.aspect_ratio),
            None => {
                let center = 0.5 * (bounds.0 + bounds.1);
                let radius = 0.5 * (bounds.1 - bounds.0).length().max(1e-9);
                let fov = DEFAULT_FOV_DEG.to_radians();
                let dir = DVec3::new(0.0, 0.35, 1.0).normalize();
                let eye = center + dir * (radius / (0.5 * fov).sin());
                (eye, -dir, DVec3::Y, fov, None)
            }
        };
        let eye = o.eye.unwrap_or(eye);
        let forward = match o.target {
            Some(t) => t - eye,
            None => forward,
        };
        let up = o.up.unwrap_or(up);
        let yfov = o.fov_deg.map(f64::to_radians).unwrap_or(yfov);
        if !(yfov > 0.0 && yfov < std::f64::consts::PI) {
            return Err(Error::Setting(format!(
                "field of view {:.3}° must be between 0 and 180",
                yfov.to_degrees()
            )));
        }
        let forward = forward.normalize_or_zero();
        let right = forward.cross(up).normalize_or_zero();
        if forward == DVec3::ZERO || right == DVec3::ZERO || !eye.is_finite() {
            return Err(Error::Setting(
                "degenerate view: eye, target and up must be finite, distinct and not collinear"
                    .into(),
            ));
        }
        let aspect = aspect.filter(|a| a.is_finite() && *a > 0.0).unwrap_or(1.0);
        let (width, height) = match (o.width, o.height) {
            (Some(w), Some(h)) => (w, h),
            (Some(w), None) => (w, (w as f64 / aspect).round().max(1.0) as u32),
            (None, Some(h)) => ((h as f64 * aspect).round().max(1.0) as u32, h),
            (None, None) => (
                DEFAULT_WIDTH,
                (DEFAULT_WIDTH as f64 / aspect).round().max(1.0) as u32,
            ),
        };
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(Error::Setting(format!(
                "image size {width} × {height}: each side must be between 1 and {MAX_SIDE}"
            )));
        }
        Ok(View {
            eye,
            forward,
            right,
            up: right.cross(forward),
            yfov,
            width,
            height,
        })
    }

    /// Pixels of the image.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Refuses, before anything is rendered, a view whose render, with
    /// the `more` images held beside it (what they are, for the message,
    /// and their bytes), would need more than `memory_budget`. The error
    /// names the flags that fixed the size (`o`) and what each part needs.
    pub fn check_memory(
        &self,
        o: &ViewOverrides,
        more: &[(String, u64)],
        memory_budget: u64,
    ) -> Result<()> {
        let render = self.pixels().saturating_mul(RENDER_BYTES_PER_PIXEL);
        let total = more
            .iter()
            .fold(render, |t, (_, bytes)| t.saturating_add(*bytes));
        if total <= memory_budget {
            return Ok(());
        }
        let source = match (o.width, o.height) {
            (Some(w), Some(h)) => format!("--width {w} --height {h}"),
            (Some(w), None) => format!("--width {w} and the camera's aspect ratio"),
            (None, Some(h)) => format!("--height {h} and the camera's aspect ratio"),
            (None, None) => format!("the default width {DEFAULT_WIDTH}, the camera's aspect ratio"),
        };
        let mut message = format!(
            "the {} × {} render ({source}) needs {}",
            self.width,
            self.height,
            human_bytes(render)
        );
        for (what, bytes) in more {
            message.push_str(&format!(", {what} {}", human_bytes(*bytes)));
        }
        if !more.is_empty() {
            message.push_str(&format!(": {} in all", human_bytes(total)));
        }
        Err(Error::Setting(format!(
            "{message}, over the memory budget of {} (raise --memory-budget or ask for fewer pixels)",
            human_bytes(memory_budget)
        )))
    }

    /// The ray through image point (x, y) (pixels, row 0 at the top):
    /// origin and unit direction.
    pub fn ray(&self, x: f64, y: f64) -> (DVec3, DVec3) {
        let tan = (0.5 * self.yfov).tan();
        let aspect = self.width as f64 / self.height as f64;
        let sx = (2.0 * x / self.width as f64 - 1.0) * tan * aspect;
        let sy = (1.0 - 2.0 * y / self.height as f64) * tan;
        let d = self.forward + sx * self.right + sy * self.up;
        (self.eye, d.normalize())
    }

    /// Where `p` appears: the image point (x, y) in pixels, as [`View::ray`]
    /// takes them, and the depth of `p` along `forward`. The inverse of
    /// [`View::ray`] when the depth is positive; meaningless otherwise.
    pub fn project(&self, p: DVec3) -> (f64, f64, f64) {
        let v = p - self.eye;
        let depth = v.dot(self.forward);
        let tan = (0.5 * self.yfov).tan();
        let aspect = self.width as f64 / self.height as f64;
        let sx = v.dot(self.right) / (depth * tan * aspect);
        let sy = v.dot(self.up) / (depth * tan);
        (
            0.5 * (sx + 1.0) * self.width as f64,
            0.5 * (1.0 - sy) * self.height as f64,
            depth,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            name: "c".into(),
            eye: DVec3::new(0.0, 0.0, 5.0),
            forward: -DVec3::Z,
            up: DVec3::Y,
            yfov: 0.8,
            aspect_ratio: Some(2.0),
        }
    }

    #[test]
    fn camera_aspect_sets_height_and_centre_ray_is_forward() {
        let v = View::resolve(
            Some(&camera()),
            (DVec3::ZERO, DVec3::ONE),
            &ViewOverrides::default(),
        )
        .unwrap();
        assert_eq!((v.width, v.height), (512, 256));
        let (o, d) = v.ray(256.0, 128.0);
        assert_eq!(o, DVec3::new(0.0, 0.0, 5.0));
        assert!((d + DVec3::Z).length() < 1e-12);
        // Top of the image looks up, the right edge looks right.
        assert!(v.ray(256.0, 0.0).1.y > 0.0);
        assert!(v.ray(512.0, 128.0).1.x > 0.0);
        let top = v.ray(256.0, 0.0).1;
        assert!((top.y.atan2(-top.z) - 0.4).abs() < 1e-12);
        // `project` inverts `ray`.
        let (o, d) = v.ray(100.25, 30.5);
        let (x, y, depth) = v.project(o + 3.0 * d);
        assert!(
            (x - 100.25).abs() < 1e-9 && (y - 30.5).abs() < 1e-9,
            "{x} {y}"
        );
        assert!((depth - 3.0 * d.dot(v.forward)).abs() < 1e-12);
    }

    #[test]
    fn overrides_and_bad_views() {
        let o = ViewOverrides {
            eye: Some(DVec3::new(1.0, 0.0, 0.0)),
            target: Some(DVec3::ZERO),
            fov_deg: Some(90.0),
            width: Some(10),
            height: Some(20),
            ..Default::default()
        };
        let v = View::resolve(None, (DVec3::ZERO, DVec3::ONE), &o).unwrap();
        assert!((v.forward + DVec3::X).length() < 1e-12);
        assert_eq!((v.width, v.height), (10, 20));
        let bad = ViewOverrides {
            up: Some(DVec3::Z),
            ..Default::default()
        };
        let c = camera();
        assert!(View::resolve(Some(&c), (DVec3::ZERO, DVec3::ONE), &bad).is_err());
        let bad = ViewOverrides {
            fov_deg: Some(0.0),
            ..Default::default()
        };
        assert!(View::resolve(Some(&c), (DVec3::ZERO, DVec3::ONE), &bad).is_err());
    }
}
