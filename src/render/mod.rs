//! Rendering a solved output mesh from a view: ray casting with stratified
//! supersampling and a box pixel filter.
//!
//! Owns: turning per-vertex radiosity into an image. Radiance at a hit is
//! L = B / π with B interpolated linearly (barycentric) across the hit
//! triangle; the back of a one-sided surface and the background are black.
//!
//! Invariants: each pixel is the mean of `samples_per_pixel` samples placed
//! in a jittered grid over the pixel's footprint; sample positions depend
//! only on (seed, pixel), so images are identical for any thread count.

pub mod frame;
pub mod view;
pub mod wireframe;

use glam::{DVec3, Vec3};
use rand::Rng;
use rayon::prelude::*;

use crate::mesh::OutputMesh;
use crate::render::frame::Frame;
use crate::render::view::View;
use crate::sampling::stream;
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// Image sampling settings.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RenderSettings {
    /// Samples per pixel, rounded up to a square number.
    pub samples_per_pixel: u32,
    /// Seed of the sample positions.
    pub seed: u64,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            samples_per_pixel: 16,
            seed: 0,
        }
    }
}

/// Renders `mesh` from `view`.
pub fn render(
    mesh: &OutputMesh,
    view: &View,
    settings: &RenderSettings,
    progress: &Progress,
) -> Frame {
    let bvh = mesh_bvh(mesh);
    let side = (settings.samples_per_pixel.max(1) as f64).sqrt().ceil() as u32;
    let (w, h) = (view.width, view.height);
    let phase = progress.phase("render", h as u64);
    let rows: Vec<Vec<[f32; 3]>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let row = (0..w)
                .map(|x| {
                    let mut rng = stream(settings.seed ^ 0x7265_6e64, (y as u64) << 32 | x as u64);
                    let mut sum = DVec3::ZERO;
                    for sy in 0..side {
                        for sx in 0..side {
                            let px = x as f64 + (sx as f64 + rng.random::<f64>()) / side as f64;
                            let py = y as f64 + (sy as f64 + rng.random::<f64>()) / side as f64;
                            let (o, d) = view.ray(px, py);
                            sum += radiance(mesh, &bvh, o, d);
                        }
                    }
                    (sum / (side * side) as f64).as_vec3().to_array()
                })
                .collect();
            phase.inc(1);
            row
        })
        .collect();
    Frame {
        width: w,
        height: h,
        pixels: rows.into_iter().flatten().collect(),
    }
}

/// Largest coordinate magnitude [`mesh_bvh`] accepts: beyond it the BVH
/// build's f32 surface areas overflow (obvhs then panics).
const MAX_COORDINATE: f32 = 1e15;

/// The BVH of `mesh`'s triangles, indexed as `mesh.triangles`, with the
/// mesh's bounding-box diagonal as length scale. A triangle with an
/// out-of-range index or a vertex beyond [`MAX_COORDINATE`] (or not finite)
/// becomes a point at the origin, which no ray hits.
pub(crate) fn mesh_bvh(mesh: &OutputMesh) -> TriangleBvh {
    let ok = |p: &Vec3| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE;
    let tris: Vec<[Vec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| mesh.positions.get(i as usize).copied());
            match p {
                [Some(a), Some(b), Some(c)] if ok(&a) && ok(&b) && ok(&c) => [a, b, c],
                _ => [Vec3::ZERO; 3],
            }
        })
        .collect();
    let (lo, hi) = mesh
        .positions
        .iter()
        .filter(|p| ok(p))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let diagonal = if lo.cmple(hi).all() {
        (hi - lo).length() as f64
    } else {
        1.0
    };
    TriangleBvh::new(&tris, diagonal)
}

/// Radiance seen along the ray: interpolated B / π on the front of the
/// closest triangle, zero otherwise.
fn radiance(mesh: &OutputMesh, bvh: &TriangleBvh, o: DVec3, d: DVec3) -> DVec3 {
    let Some(hit) = bvh.closest_hit(o, d, f64::from(f32::MAX)) else {
        return DVec3::ZERO;
    };
    let [a, b, c] = mesh.triangles[hit.triangle as usize].map(|i| i as usize);
    let [pa, pb, pc] = [a, b, c].map(|i| mesh.positions[i].as_dvec3());
    let n = (pb - pa).cross(pc - pa);
    if n.dot(d) >= 0.0 {
        return DVec3::ZERO;
    }
    let p = o + hit.t * d;
    let area = n.length_squared();
    let wb = (p - pa).cross(pc - pa).dot(n) / area;
    let wc = (pb - pa).cross(p - pa).dot(n) / area;
    let wb = wb.clamp(0.0, 1.0);
    let wc = wc.clamp(0.0, 1.0 - wb);
    let wa = 1.0 - wb - wc;
    let rad = |i: usize| mesh.radiosity[i].as_dvec3();
    (wa * rad(a) + wb * rad(b) + wc * rad(c)) / std::f64::consts::PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::view::ViewOverrides;

    /// A square facing the camera with B rising linearly in x: the image
    /// shows B / π, linear across, and black outside and from behind.
    #[test]
    fn interpolates_radiosity_over_the_square() {
        let mesh = OutputMesh {
            positions: vec![
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(-1.0, 1.0, 0.0),
            ],
            normals: vec![Vec3::Z; 4],
            patch: vec![0; 4],
            radiosity: vec![Vec3::ZERO, Vec3::splat(2.0), Vec3::splat(2.0), Vec3::ZERO],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        mesh.validate().unwrap();
        let o = ViewOverrides {
            eye: Some(DVec3::new(0.0, 0.0, 2.0)),
            target: Some(DVec3::ZERO),
            fov_deg: Some(90.0),
            width: Some(8),
            height: Some(8),
            ..Default::default()
        };
        let view = View::resolve(None, (DVec3::splat(-1.0), DVec3::ONE), &o).unwrap();
        let settings = RenderSettings {
            samples_per_pixel: 1024,
            seed: 1,
        };
        let f = render(&mesh, &view, &settings, &Progress::hidden());
        // Jittered samples: the error of a pixel mean is about 0.002 here.
        // The square spans the central 4 × 4 pixels; pixel x = 2 covers
        // square x in [-1, -0.5], where B = x + 1 averages 0.25.
        let l = f.get(2, 3)[0] as f64;
        assert!((l - 0.25 / std::f64::consts::PI).abs() < 3e-3, "{l}");
        let l = f.get(5, 4)[0] as f64;
        assert!((l - 1.75 / std::f64::consts::PI).abs() < 3e-3, "{l}");
        assert_eq!(f.get(0, 0), [0.0; 3]);
        // From behind: black.
        let o = ViewOverrides {
            eye: Some(DVec3::new(0.0, 0.0, -2.0)),
            ..o
        };
        let view = View::resolve(None, (DVec3::splat(-1.0), DVec3::ONE), &o).unwrap();
        let f = render(
            &mesh,
            &view,
            &RenderSettings::default(),
            &Progress::hidden(),
        );
        assert!(f.pixels.iter().all(|p| *p == [0.0; 3]));
    }
}
