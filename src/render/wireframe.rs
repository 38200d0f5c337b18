//! The wireframe overlay of `render.png`: the output mesh's triangle edges
//! seen from a view, hidden lines removed, as a per-pixel line coverage.
//!
//! Owns: edge extraction, clipping, projection and line rasterization. The
//! compositing is [`crate::output::png::encode_png_with_overlay`]'s.
//!
//! Method: every distinct edge (keyed by its endpoint positions, so an edge
//! shared by two triangles, even through duplicated vertices, draws once)
//! is clipped to the near plane (depth ≥ [`NEAR`] × the mesh diagonal),
//! projected with [`View::project`], clipped to the image, and stepped
//! along its major axis one pixel centre at a time; each step lights the two
//! pixels nearest the line across it, in proportion to their closeness (a
//! 1 px wide anti-aliased line, after Wu). At each step the edge point P is
//! recovered perspective-correctly, and the step draws only if the camera
//! ray from the eye through P first hits the mesh no nearer than
//! (1 − [`DEPTH_TOL`]) · |P − eye|: the surface visible there is P's own.
//!
//! Invariants:
//! - the mask has `width × height` values in [0, 1], row-major, row 0 at the
//!   top, pixel for pixel with the render of the same view;
//! - overlapping lines combine by maximum, so the mask depends neither on
//!   edge order nor on the thread count;
//! - no input panics: edges with an out-of-range index or a non-finite or
//!   coincident endpoint are skipped, and edges behind the eye are clipped.

use glam::DVec3;
use rayon::prelude::*;

use crate::mesh::OutputMesh;
use crate::render::mesh_bvh;
use crate::render::view::View;
use crate::util::geometry::{PositionKey, position_key};
use crate::visibility::TriangleBvh;

/// Near clipping depth, as a fraction of the mesh's bounding-box diagonal.
pub const NEAR: f64 = 1e-6;
/// Relative depth tolerance of the hidden-line test: a surface hides an edge
/// point only if it is nearer than (1 − `DEPTH_TOL`) times the point's
/// distance from the eye.
pub const DEPTH_TOL: f64 = 1e-3;
/// The default line colour: a display value (linear, before the sRGB
/// transfer) in [0, 1] per channel; orange, which no grey scene has.
pub const LINE_COLOR: [f32; 3] = [1.0, 0.35, 0.0];

/// Line coverage in [0, 1] of `mesh`'s visible triangle edges, one value per
/// pixel of `view` (`view.width × view.height`, row-major, row 0 at the top).
pub fn wireframe_mask(mesh: &OutputMesh, view: &View) -> Vec<f32> {
    let (w, h) = (view.width as usize, view.height as usize);
    let mut mask = vec![0.0f32; w * h];
    let edges = distinct_edges(mesh);
    if edges.is_empty() {
        return mask;
    }
    let (lo, hi) = edges
        .iter()
        .flatten()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let near = NEAR * (hi - lo).length();
    let bvh = mesh_bvh(mesh);
    let drawn: Vec<Vec<(usize, f32)>> = edges
        .par_iter()
        .with_min_len(64)
        .map(|&[a, b]| draw_edge(view, &bvh, a, b, near))
        .collect();
    for (pixel, coverage) in drawn.into_iter().flatten() {
        mask[pixel] = mask[pixel].max(coverage);
    }
    mask
}

/// The distinct edges of the mesh's triangles as endpoint pairs, in a fixed
/// order; degenerate and invalid ones left out.
fn distinct_edges(mesh: &OutputMesh) -> Vec<[DVec3; 2]> {
    let mut keys: Vec<[PositionKey; 2]> = Vec::with_capacity(3 * mesh.triangles.len());
    for tri in &mesh.triangles {
        for k in 0..3 {
            let ends = [tri[k], tri[(k + 1) % 3]].map(|i| mesh.positions.get(i as usize));
            let [Some(a), Some(b)] = ends else { continue };
            if !(a.is_finite() && b.is_finite()) {
                continue;
            }
            let (ka, kb) = (position_key(a.as_dvec3()), position_key(b.as_dvec3()));
            if ka != kb {
                keys.push([ka.min(kb), ka.max(kb)]);
            }
        }
    }
    keys.sort_unstable();
    keys.dedup();
    keys.iter()
        .map(|k| k.map(|p| DVec3::from(p.map(f64::from_bits))))
        .collect()
}

/// The pixels (index, coverage) that the visible parts of edge `a`–`b` cover.
fn draw_edge(view: &View, bvh: &TriangleBvh, a: DVec3, b: DVec3, near: f64) -> Vec<(usize, f32)> {
    let mut out = Vec::new();
    // Clip to the near plane in world space.
    let depth = |p: DVec3| (p - view.eye).dot(view.forward);
    let (da, db) = (depth(a), depth(b));
    if !(da >= near || db >= near) {
        return out;
    }
    let a_clip = if da < near {
        a + (b - a) * ((near - da) / (db - da))
    } else {
        a
    };
    let b_clip = if db < near {
        b + (a - b) * ((near - db) / (da - db))
    } else {
        b
    };
    let (a, b) = (a_clip, b_clip);
    let (xa, ya, za) = view.project(a);
    let (xb, yb, zb) = view.project(b);
    if ![xa, ya, za, xb, yb, zb].iter().all(|v| v.is_finite()) {
        return out;
    }
    // Image-space clip (Liang–Barsky) to the image grown by one pixel.
    let (w, h) = (view.width as f64, view.height as f64);
    let (mut s0, mut s1) = (0.0f64, 1.0f64);
    for (p, d, lo, hi) in [(xa, xb - xa, -1.0, w + 1.0), (ya, yb - ya, -1.0, h + 1.0)] {
        if d == 0.0 {
            if p < lo || p > hi {
                return out;
            }
            continue;
        }
        let (t_lo, t_hi) = ((lo - p) / d, (hi - p) / d);
        s0 = s0.max(t_lo.min(t_hi));
        s1 = s1.min(t_lo.max(t_hi));
    }
    if !(s0 <= s1) {
        return out;
    }
    // Step along the major axis: `m` is the major coordinate, `n` the minor.
    let x_major = (xb - xa).abs() >= (yb - ya).abs();
    let (ma, mb, na, nb) = if x_major {
        (xa, xb, ya, yb)
    } else {
        (ya, yb, xa, xb)
    };
    let (n_major, n_minor) = if x_major { (w, h) } else { (h, w) };
    if ma == mb {
        return out;
    }
    let (m0, m1) = (ma + s0 * (mb - ma), ma + s1 * (mb - ma));
    let first = (m0.min(m1) - 0.5).ceil().max(0.0);
    let last = (m0.max(m1) - 0.5).floor().min(n_major - 1.0);
    let mut i = first;
    while i <= last {
        let s = (i + 0.5 - ma) / (mb - ma);
        // 1/depth is linear in image space: the edge parameter of P.
        let u = s * za / ((1.0 - s) * zb + s * za);
        let p = a + u.clamp(0.0, 1.0) * (b - a);
        if visible(bvh, view.eye, p) {
            let c = na + s * (nb - na) - 0.5;
            let j0 = c.floor();
            for (j, coverage) in [(j0, 1.0 - (c - j0)), (j0 + 1.0, c - j0)] {
                if coverage > 0.0 && j >= 0.0 && j < n_minor {
                    let (x, y) = if x_major { (i, j) } else { (j, i) };
                    out.push((
                        y as usize * view.width as usize + x as usize,
                        coverage as f32,
                    ));
                }
            }
        }
        i += 1.0;
    }
    out
}

/// True when nothing hides `p` from `eye` (up to [`DEPTH_TOL`]).
fn visible(bvh: &TriangleBvh, eye: DVec3, p: DVec3) -> bool {
    let v = p - eye;
    let dist = v.length();
    if !(dist > 0.0) {
        return false;
    }
    bvh.closest_hit(eye, v / dist, dist * (1.0 - DEPTH_TOL))
        .is_none()
}
