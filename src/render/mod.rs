//! Rendering a solved output mesh from a view: ray casting with stratified
//! supersampling, more samples where a pixel's samples disagree (edges),
//! and a box pixel filter.
//!
//! Owns: turning per-vertex radiosity into an image. Radiance at a hit is
//! L = B / π with B interpolated linearly (barycentric) across the hit
//! triangle; the back of a one-sided surface and the background are black.
//!
//! Edges. A pixel cut by a silhouette, a shadow line or an emitter's rim
//! holds two very different radiances, and 16 samples put its mean off by
//! up to a sixteenth of the step: on office-10k at 160 × 120 that aliasing
//! was two thirds of the image's error against a converged path tracer
//! (6.3 % at 16 samples, 2.0 % at 256 everywhere). So a pixel whose
//! samples' luminances span more than [`EDGE_SPREAD`] of the image's mean
//! is sampled again with `edge_samples_per_pixel`.
//!
//! Invariants: each pixel is the mean of `samples_per_pixel` samples placed
//! in a jittered grid over the pixel's footprint, or of
//! `edge_samples_per_pixel` (a finer grid, in place of the first) when it
//! is an edge pixel; sample positions depend only on (seed, pixel), and
//! the edge test only on the first pass's image, so images are identical
//! for any thread count (under a time budget, [`render_until`], which
//! pixels are cut depends on the clock).

pub mod frame;
pub mod view;
pub mod wireframe;

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

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
    /// Samples of an edge pixel (see the module doc), rounded up to a
    /// square number; at most `samples_per_pixel` turns the edge pass off.
    pub edge_samples_per_pixel: u32,
    /// Seed of the sample positions.
    pub seed: u64,
}

impl RenderSettings {
    /// `samples_per_pixel` with the seed, and [`EDGE_FACTOR`] times as many
    /// (at most [`MAX_EDGE_SAMPLES`], at least as many) for edge pixels.
    pub fn with_samples(samples_per_pixel: u32, seed: u64) -> RenderSettings {
        RenderSettings {
            samples_per_pixel,
            edge_samples_per_pixel: samples_per_pixel
                .saturating_mul(EDGE_FACTOR)
                .min(MAX_EDGE_SAMPLES)
                .max(samples_per_pixel),
            seed,
        }
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings::with_samples(16, 0)
    }
}

/// Edge pixels get this many times the samples of the others.
pub const EDGE_FACTOR: u32 = 16;

/// The most samples [`RenderSettings::with_samples`] gives an edge pixel.
pub const MAX_EDGE_SAMPLES: u32 = 4096;

/// A pixel is an edge pixel when its samples' luminances span more than
/// this fraction of the image's mean luminance.
pub const EDGE_SPREAD: f64 = 0.05;

/// [`frame::luminance`] of a radiance.
fn luminance(c: DVec3) -> f64 {
    f64::from(frame::luminance(c.as_vec3().to_array()))
}

/// Renders `mesh` from `view`.
pub fn render(
    mesh: &OutputMesh,
    view: &View,
    settings: &RenderSettings,
    progress: &Progress,
) -> Frame {
    render_until(mesh, view, settings, progress, None).0
}

/// [`render`] within a time budget that ends at `deadline`. Rows are
/// taken in [`spread_rows`] order. A pixel takes its full count only while
/// the pixels not yet begun, at one sample each at the rate measured so
/// far, would still end by the deadline, and one sample after that; a
/// pixel begun after the deadline takes none, beyond the first
/// [`FLOOR_ROWS`] rows, and shows the nearest rendered pixel of its
/// column. Edge pixels are sampled again only while the deadline lasts.
/// So the overrun is about one pixel's samples (plus the floor rows).
/// Returns the image, how many of its pixels got fewer samples than
/// `settings` asks but at least one, and how many got none (both 0
/// without a deadline).
pub fn render_until(
    mesh: &OutputMesh,
    view: &View,
    settings: &RenderSettings,
    progress: &Progress,
    deadline: Option<Instant>,
) -> (Frame, u64, u64) {
    let short = AtomicU64::new(0);
    let bvh = mesh_bvh(mesh);
    let (w, h) = (view.width, view.height);
    let started = Instant::now();
    let (begun, samples) = (AtomicU64::new(0), AtomicU64::new(0));
    // Whether the pixels not yet begun, at one sample each, would end
    // after the deadline (or it has passed). One sample a pixel costs more
    // than a sample of a full pixel (its rays are less coherent, and the
    // rows left may be the slow ones): on the 100,000-sliver fan the
    // estimate alone ended 0.95 s late of 7; [`FLOOR_MARGIN`] times it.
    let late = || {
        deadline.is_some_and(|d| {
            let now = Instant::now();
            let taken = samples.load(Ordering::Relaxed);
            let left = (u64::from(w) * u64::from(h)).saturating_sub(begun.load(Ordering::Relaxed));
            let rest = match taken {
                0 => 0.0,
                _ => FLOOR_MARGIN * (now - started).as_secs_f64() / taken as f64 * left as f64,
            };
            now >= d || rest >= (d - now).as_secs_f64()
        })
    };
    let side = |spp: u32| (spp.max(1) as f64).sqrt().ceil() as u32;
    // One pixel's mean and the span of its samples' luminances, from a
    // jittered `n` × `n` grid.
    let pixel = |x: u32, y: u32, n: u32, key: u64| {
        let mut rng = stream(settings.seed ^ key, (y as u64) << 32 | x as u64);
        let mut sum = DVec3::ZERO;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for sy in 0..n {
            for sx in 0..n {
                let px = x as f64 + (sx as f64 + rng.random::<f64>()) / n as f64;
                let py = y as f64 + (sy as f64 + rng.random::<f64>()) / n as f64;
                let (o, d) = view.ray(px, py);
                let l = radiance(mesh, &bvh, o, d);
                sum += l;
                lo = lo.min(luminance(l));
                hi = hi.max(luminance(l));
            }
        }
        (sum / (n * n) as f64, hi - lo)
    };
    let first = side(settings.samples_per_pixel);
    let edge = side(settings.edge_samples_per_pixel);
    let phase = progress.phase("render", h as u64);
    let past = || deadline.is_some_and(|d| Instant::now() >= d);
    let skipped = AtomicU64::new(0);
    let order = spread_rows(h);
    let rows: Vec<Row> = order
        .par_iter()
        .enumerate()
        .map(|(k, &y)| {
            let row: Vec<_> = (0..w)
                .map(|x| {
                    if k >= FLOOR_ROWS && past() {
                        skipped.fetch_add(1, Ordering::Relaxed);
                        return None;
                    }
                    let n = match first > 1 && late() {
                        true => {
                            short.fetch_add(1, Ordering::Relaxed);
                            1
                        }
                        false => first,
                    };
                    begun.fetch_add(1, Ordering::Relaxed);
                    let p = pixel(x, y, n, 0x7265_6e64);
                    samples.fetch_add(u64::from(n * n), Ordering::Relaxed);
                    Some(p)
                })
                .collect();
            phase.inc(1);
            (y, row)
        })
        .collect();
    let mut pixels = nearest_rendered(w, h, rows);
    if edge > first && !pixels.is_empty() {
        let mean = pixels.iter().map(|(c, _)| luminance(*c)).sum::<f64>() / pixels.len() as f64;
        let limit = EDGE_SPREAD * mean;
        pixels
            .par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .for_each(|(k, p)| {
                if p.1 > limit {
                    if past() {
                        short.fetch_add(1, Ordering::Relaxed);
                        return;
                    }
                    let (x, y) = ((k % w as usize) as u32, (k / w as usize) as u32);
                    *p = pixel(x, y, edge, 0x6564_6765);
                }
            });
    }
    let frame = Frame {
        width: w,
        height: h,
        pixels: pixels
            .into_iter()
            .map(|(c, _)| c.as_vec3().to_array())
            .collect(),
    };
    (frame, short.into_inner(), skipped.into_inner())
}

/// A row's number and its pixels (each its mean and the span of its
/// samples' luminances), None where no sample was taken.
type Row = (u32, Vec<Option<(DVec3, f64)>>);

/// Rows a budgeted render gives at least one sample a pixel, whatever the
/// clock: the first ones of [`spread_rows`], spread over the frame.
const FLOOR_ROWS: usize = 16;

/// The rows 0..h in bit-reversed order (0, h/2, h/4, 3h/4, …): however
/// many a time budget lets through, they are spread over the frame.
fn spread_rows(h: u32) -> Vec<u32> {
    let bits = h.max(1).next_power_of_two().trailing_zeros();
    (0..h.max(1).next_power_of_two())
        .map(|i| i.reverse_bits().checked_shr(32 - bits).unwrap_or(0))
        .filter(|&y| y < h)
        .collect()
}

/// The frame's pixels in row order from its rendered rows; a pixel not
/// rendered takes the value of the nearest rendered one in its column
/// (each column has one: [`FLOOR_ROWS`] rows are always rendered whole).
fn nearest_rendered(w: u32, h: u32, rows: Vec<Row>) -> Vec<(DVec3, f64)> {
    let (w, h) = (w as usize, h as usize);
    let mut grid: Vec<Option<(DVec3, f64)>> = vec![None; w * h];
    for (y, row) in rows {
        grid[y as usize * w..][..w].copy_from_slice(&row);
    }
    let mut out = vec![(DVec3::ZERO, 0.0); w * h];
    for x in 0..w {
        let rendered: Vec<usize> = (0..h).filter(|&y| grid[y * w + x].is_some()).collect();
        let mut next = 0;
        for y in 0..h {
            while next + 1 < rendered.len()
                && rendered[next + 1].abs_diff(y) <= rendered[next].abs_diff(y)
            {
                next += 1;
            }
            if let Some(&from) = rendered.get(next) {
                out[y * w + x] = grid[from * w + x].unwrap_or_default();
            }
        }
    }
    out
}

/// How many times the measured cost of a sample [`render_until`] allows
/// for each pixel not yet begun.
const FLOOR_MARGIN: f64 = 2.0;

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
            irradiance: vec![Vec3::ZERO, Vec3::splat(4.0), Vec3::splat(4.0), Vec3::ZERO],
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
            edge_samples_per_pixel: 0,
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

    /// A uniformly bright square whose right edge cuts a pixel at 60 % of
    /// its width: that pixel is an edge pixel and gets its coverage to the
    /// finer grid's accuracy; inside, pixels are left as the first pass
    /// found them.
    #[test]
    fn an_edge_pixel_is_sampled_again() {
        let p = |x: f32, y: f32| Vec3::new(x, y, 0.0);
        let mesh = OutputMesh {
            positions: vec![p(-1.0, -1.0), p(0.8, -1.0), p(0.8, 1.0), p(-1.0, 1.0)],
            normals: vec![Vec3::Z; 4],
            patch: vec![0; 4],
            radiosity: vec![Vec3::splat(2.0); 4],
            irradiance: vec![Vec3::splat(4.0); 4],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        // The image plane at the square spans [-2, 2]: pixels 0.5 wide,
        // pixel x = 5 covers [0.5, 1.0], 60 % of it inside the square.
        let o = ViewOverrides {
            eye: Some(DVec3::new(0.0, 0.0, 2.0)),
            target: Some(DVec3::ZERO),
            fov_deg: Some(90.0),
            width: Some(8),
            height: Some(8),
            ..Default::default()
        };
        let view = View::resolve(None, (DVec3::splat(-1.0), DVec3::ONE), &o).unwrap();
        let inside = 2.0 / std::f64::consts::PI;
        let at = |settings: &RenderSettings| {
            let f = render(&mesh, &view, settings, &Progress::hidden());
            assert_eq!(f.get(3, 3)[0] as f64, (inside as f32) as f64);
            f.get(5, 3)[0] as f64 / inside
        };
        // Four samples know the coverage only to a quarter or so; 4 × 16
        // jittered in a finer grid to about a percent.
        let coarse = at(&RenderSettings {
            edge_samples_per_pixel: 4,
            ..RenderSettings::with_samples(4, 3)
        });
        let fine = at(&RenderSettings::with_samples(4, 3));
        assert!((fine - 0.6).abs() < 0.02, "edge pixel coverage {fine}");
        assert!((coarse - 0.6).abs() > (fine - 0.6).abs(), "{coarse} {fine}");
    }

    #[test]
    fn spread_rows_take_every_row_once_coarse_ones_first() {
        for h in [1, 2, 3, 16, 100, 512] {
            let mut rows = spread_rows(h);
            rows.sort_unstable();
            assert_eq!(rows, (0..h).collect::<Vec<_>>(), "h = {h}");
        }
        assert_eq!(spread_rows(512)[..4], [0, 256, 128, 384]);
        // The floor rows of a 100-row frame leave no gap over 8 rows.
        let mut floor = spread_rows(100)[..FLOOR_ROWS].to_vec();
        floor.sort_unstable();
        assert!(floor.windows(2).all(|p| p[1] - p[0] <= 8), "{floor:?}");
    }

    #[test]
    fn a_pixel_not_rendered_shows_the_nearest_rendered_one_of_its_column() {
        let px = |v: f64| Some((DVec3::splat(v), 0.0));
        let rows = vec![
            (0, vec![px(0.0), px(10.0)]),
            (3, vec![px(3.0), None]),
            (1, vec![None, None]),
            (2, vec![None, None]),
            (4, vec![None, None]),
        ];
        let out = nearest_rendered(2, 5, rows);
        let column = |x: usize| (0..5).map(|y| out[y * 2 + x].0.x).collect::<Vec<_>>();
        assert_eq!(column(0), [0.0, 0.0, 3.0, 3.0, 3.0]);
        assert_eq!(column(1), [10.0; 5]);
    }
}
