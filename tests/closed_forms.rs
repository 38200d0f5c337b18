//! Form-factor kernels against closed forms (Howell's catalogue), and the
//! reciprocity and closure identities.

use glam::DVec3;
use nusselt::formfactor::area_sampling::MAX_RAYS;
use nusselt::formfactor::{
    form_factor_area_sampling, form_factor_point_polygon, form_factor_polygon_polygon,
};
use nusselt::sampling::stream;
use std::f64::consts::PI;

use nusselt::formfactor::closed_form::{c11, c14, discs};

/// An a × b rectangle at the corner of the plane z, facing up or down.
pub(crate) fn rect_xy(a: f64, b: f64, z: f64, up: bool) -> Vec<DVec3> {
    let mut v = vec![
        DVec3::new(0.0, 0.0, z),
        DVec3::new(a, 0.0, z),
        DVec3::new(a, b, z),
        DVec3::new(0.0, b, z),
    ];
    if !up {
        v.reverse();
    }
    v
}

/// A regular m-gon of the same area as the disc of radius r, in the plane
/// z, facing up or down.
pub(crate) fn disc(r: f64, z: f64, m: usize, up: bool) -> Vec<DVec3> {
    let t = 2.0 * PI / m as f64;
    let rr = r * (t / t.sin()).sqrt(); // equal area
    let mut v: Vec<DVec3> = (0..m)
        .map(|k| DVec3::new(rr * (k as f64 * t).cos(), rr * (k as f64 * t).sin(), z))
        .collect();
    if !up {
        v.reverse();
    }
    v
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn closed_forms_reproduce_the_catalogue_checks() {
    assert!((c11(1.0, 1.0, 1.0) - 0.199825).abs() < 1e-6);
    assert!((c11(1.0, 2.0, 1.0) - 0.285875).abs() < 1e-6);
    assert!((c11(1.0, 1.5, 0.5) - 0.4756).abs() < 1e-4);
    assert!((c14(1.0, 1.0, 1.0) - 0.200044).abs() < 1e-6);
    assert!((c14(1.0, 2.0, 1.0) - 0.232853).abs() < 1e-6);
    assert!((c11(1.0, 1.0, 1.0) + 4.0 * c14(1.0, 1.0, 1.0) - 1.0).abs() < 1e-5);
    assert!((discs(1.0, 1.0, 1.0) - (3.0 - 5f64.sqrt()) / 2.0).abs() < 1e-12);
}

#[test]
fn polygon_polygon_parallel_rectangles() {
    for (a, b, c) in [
        (1.0, 1.0, 1.0),
        (1.0, 2.0, 1.0),
        (1.0, 1.5, 0.5),
        (3.0, 0.2, 0.7),
        (0.1, 0.1, 2.0),
    ] {
        let f =
            form_factor_polygon_polygon(&rect_xy(a, b, 0.0, true), &rect_xy(a, b, c, false), 1e-10);
        let exact = c11(a, b, c);
        assert!(
            rel(f.value, exact) < 1e-6,
            "{a}×{b} at {c}: {} vs {exact}",
            f.value
        );
        assert!(f.error < 1e-6 * exact, "error estimate {}", f.error);
    }
}

#[test]
fn polygon_polygon_perpendicular_rectangles() {
    for (w, h, l) in [
        (1.0, 1.0, 1.0),
        (1.0, 2.0, 1.0),
        (0.3, 2.0, 1.5),
        (2.0, 0.5, 0.7),
    ] {
        // Surface 1 (width w) on the floor, surface 2 (height h) a wall,
        // sharing the edge along y of length l.
        let floor = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, l, 0.0),
            DVec3::new(-w, l, 0.0),
            DVec3::new(-w, 0.0, 0.0),
        ];
        let wall = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, h),
            DVec3::new(0.0, l, h),
            DVec3::new(0.0, l, 0.0),
        ];
        let (_, n_floor) = nusselt::scene::polygon_area_normal(&floor);
        let (_, n_wall) = nusselt::scene::polygon_area_normal(&wall);
        assert!(
            n_floor.z > 0.99 && n_wall.x < -0.99,
            "test setup faces each other"
        );
        let f = form_factor_polygon_polygon(&floor, &wall, 1e-9);
        let exact = c14(w, h, l);
        assert!(
            rel(f.value, exact) < 1e-6,
            "w {w} h {h} l {l}: {} vs {exact}",
            f.value
        );
        // Reciprocity: A_1 F_12 = A_2 F_21.
        let g = form_factor_polygon_polygon(&wall, &floor, 1e-9);
        assert!(rel(w * l * f.value, h * l * g.value) < 1e-6);
    }
}

#[test]
fn polygon_polygon_coaxial_discs_with_tessellation_extrapolated() {
    for (r1, r2, a) in [(1.0, 1.0, 1.0), (0.5, 1.5, 0.8)] {
        let f = |m: usize| {
            form_factor_polygon_polygon(&disc(r1, 0.0, m, true), &disc(r2, a, m, false), 1e-10)
                .value
        };
        let (f1, f2) = (f(64), f(128));
        let exact = discs(r1, r2, a);
        // The equal-area polygons converge as 1/m²: the error quarters when
        // m doubles, and Richardson extrapolation removes it.
        let (e1, e2) = ((f1 - exact).abs(), (f2 - exact).abs());
        assert!(e2 < 0.3 * e1, "tessellation error {e1} → {e2}");
        let extrapolated = (4.0 * f2 - f1) / 3.0;
        assert!(rel(extrapolated, exact) < 1e-6, "{extrapolated} vs {exact}");
    }
}

#[test]
fn lambert_point_to_polygon_matches_howell() {
    let f = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &rect_xy(1.0, 2.0, 1.0, false));
    assert!((f - 0.167375).abs() < 1e-6);
    // The differential limit of C-11: a point under the centre of a square
    // is four corner configurations.
    let f = form_factor_point_polygon(
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::Z,
        &rect_xy(1.0, 1.0, 1.0, false),
    );
    let corner = form_factor_point_polygon(DVec3::ZERO, DVec3::Z, &rect_xy(0.5, 0.5, 1.0, false));
    assert!(rel(f, 4.0 * corner) < 1e-12);
}

#[test]
fn closure_in_a_cube_and_reciprocity() {
    // The six inward faces of the unit cube: every row sums to 1.
    let faces: Vec<Vec<DVec3>> = vec![
        rect_xy(1.0, 1.0, 0.0, true),
        rect_xy(1.0, 1.0, 1.0, false),
        vec![
            DVec3::new(0., 0., 0.),
            DVec3::new(0., 0., 1.),
            DVec3::new(1., 0., 1.),
            DVec3::new(1., 0., 0.),
        ],
        vec![
            DVec3::new(0., 1., 0.),
            DVec3::new(1., 1., 0.),
            DVec3::new(1., 1., 1.),
            DVec3::new(0., 1., 1.),
        ],
        vec![
            DVec3::new(0., 0., 0.),
            DVec3::new(0., 1., 0.),
            DVec3::new(0., 1., 1.),
            DVec3::new(0., 0., 1.),
        ],
        vec![
            DVec3::new(1., 0., 0.),
            DVec3::new(1., 0., 1.),
            DVec3::new(1., 1., 1.),
            DVec3::new(1., 1., 0.),
        ],
    ];
    for (i, r) in faces.iter().enumerate() {
        let (_, n) = nusselt::scene::polygon_area_normal(r);
        let c = nusselt::scene::polygon_centroid(r);
        assert!(
            (DVec3::splat(0.5) - c).dot(n) > 0.0,
            "face {i} faces inward"
        );
        let sum: f64 = faces
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, s)| form_factor_polygon_polygon(r, s, 1e-10).value)
            .sum();
        assert!((sum - 1.0).abs() < 1e-6, "row {i} sums to {sum}");
    }
}

#[test]
fn area_sampling_is_within_its_error_and_the_error_falls_with_the_tolerance() {
    let r = rect_xy(1.0, 1.0, 0.0, true);
    let s = rect_xy(1.0, 1.0, 1.0, false);
    let exact = c11(1.0, 1.0, 1.0);
    let mut last = f64::INFINITY;
    for (k, tol) in [1e-2, 1e-3, 1e-4].into_iter().enumerate() {
        let mut rng = stream(7, k as u64);
        let f = form_factor_area_sampling(&r, &s, tol, MAX_RAYS, &mut rng, |_, _| true);
        assert!(
            (f.value - exact).abs() <= 2.0 * f.error,
            "tol {tol}: {} ± {} vs {exact}",
            f.value,
            f.error
        );
        assert!(f.error <= tol * f.value, "tol {tol}: {f:?}");
        assert!(
            f.error < 0.5 * last,
            "stated error should fall with the tolerance: {} after {last}",
            f.error
        );
        last = f.error;
    }
}

#[test]
fn kernels_stay_in_range_for_touching_and_nearly_touching_polygons() {
    use rand::Rng;
    let mut rng = stream(99, 0);
    for case in 0..100 {
        let gap = [0.0, 1e-9, 1e-6, 1e-3, 0.1][case % 5];
        // A receiver square on the floor and a randomly tilted source quad
        // near or touching it, sometimes facing away.
        let r = rect_xy(1.0, 1.0, 0.0, true);
        let angle: f64 = rng.random_range(0.0..PI);
        let (c, s) = (angle.cos(), angle.sin());
        let x0: f64 = rng.random_range(-0.5..1.5);
        let src: Vec<DVec3> = [(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0)]
            .iter()
            .map(|&(u, v): &(f64, f64)| DVec3::new(x0 + u * c, v, gap + u * s))
            .collect();
        for kernel in 0..3 {
            let f = match kernel {
                0 => form_factor_point_polygon(DVec3::new(0.5, 0.5, 0.0), DVec3::Z, &src),
                1 => form_factor_polygon_polygon(&r, &src, 1e-4).value,
                _ => {
                    form_factor_area_sampling(&r, &src, 0.01, MAX_RAYS, &mut rng, |_, _| true).value
                }
            };
            assert!(
                f.is_finite() && (0.0..=1.0).contains(&f),
                "case {case} kernel {kernel}: {f}"
            );
        }
    }
}
