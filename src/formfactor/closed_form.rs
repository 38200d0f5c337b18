//! Closed-form form factors from Howell's catalogue: the independent
//! yardsticks the kernels, the stress table and the tests are checked
//! against.
//!
//! Owns: nothing but the formulas. Invariant: each is the catalogue's
//! expression, not an approximation, valid for positive lengths.

use std::f64::consts::PI;

/// Howell C-11: identical parallel, directly opposed rectangles a × b at
/// distance c.
pub fn c11(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (x2, y2) = (x * x, y * y);
    2.0 / (PI * x * y)
        * (((1.0 + x2) * (1.0 + y2) / (1.0 + x2 + y2)).sqrt().ln()
            + x * (1.0 + y2).sqrt() * (x / (1.0 + y2).sqrt()).atan()
            + y * (1.0 + x2).sqrt() * (y / (1.0 + x2).sqrt()).atan()
            - x * x.atan()
            - y * y.atan())
}

/// Howell C-14: rectangles at 90° sharing an edge of length l; from the
/// surface of width w to the one of height h.
pub fn c14(w: f64, h: f64, l: f64) -> f64 {
    let (w, h) = (w / l, h / l);
    let (w2, h2) = (w * w, h * h);
    let s = (h2 + w2).sqrt();
    let log = ((1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2)).ln()
        + w2 * (w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2))).ln()
        + h2 * (h2 * (1.0 + w2 + h2) / ((1.0 + h2) * (w2 + h2))).ln();
    (w * (1.0 / w).atan() + h * (1.0 / h).atan() - s * (1.0 / s).atan() + 0.25 * log) / (PI * w)
}

/// Coaxial parallel discs of radii r1 (from) and r2 (to) at distance a.
pub fn discs(r1: f64, r2: f64, a: f64) -> f64 {
    let (r1, r2) = (r1 / a, r2 / a);
    let x = 1.0 + (1.0 + r2 * r2) / (r1 * r1);
    0.5 * (x - (x * x - 4.0 * (r2 / r1).powi(2)).sqrt())
}

/// From a differential area to a parallel disc of radius `r` facing it, at
/// height `h` and `a` off the disc's axis (on the axis r² / (h² + r²)).
pub fn point_to_disc(r: f64, h: f64, a: f64) -> f64 {
    let (h2, a2, r2) = (h * h, a * a, r * r);
    0.5 * (1.0 - (h2 + a2 - r2) / ((h2 + a2 + r2).powi(2) - 4.0 * a2 * r2).sqrt())
}
