//! Adaptive area sampling (`formfactor::area_sampling`): Howell's closed
//! forms to its tolerance at five aspect ratios each, occluders seen by its
//! rays, and its error estimate against the true error over random
//! placements.

use glam::{DQuat, DVec2, DVec3};
use nusselt::formfactor::area_sampling::{DEFAULT_TOLERANCE, MAX_RAYS};
use nusselt::formfactor::closed_form::{c11, c14, discs, point_to_disc};
use nusselt::formfactor::{
    Estimate, form_factor_area_sampling, form_factor_point_polygon, form_factor_polygon_polygon,
    form_factor_polygon_polygon_with,
};
use nusselt::sampling::stream;
use rand::Rng;
use std::f64::consts::PI;

use crate::closed_forms::{disc, rect_xy};

/// The tight tolerance the closed forms are also met at.
const TIGHT: f64 = 1e-3;

/// Floor (width w along −x) and wall (height h) sharing the edge of length
/// l along y: Howell C-14 from the floor to the wall.
fn hinge(w: f64, h: f64, l: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    (
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, l, 0.0),
            DVec3::new(-w, l, 0.0),
            DVec3::new(-w, 0.0, 0.0),
        ],
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, h),
            DVec3::new(0.0, l, h),
            DVec3::new(0.0, l, 0.0),
        ],
    )
}

fn sample(r: &[DVec3], s: &[DVec3], tol: f64, key: u64) -> Estimate {
    form_factor_area_sampling(r, s, tol, MAX_RAYS, &mut stream(25, key), |_, _| true)
}

/// Checks `f` against `exact` at tolerance `tol`: the true error within
/// the tolerance, the stated error within it too (the stopping rule) and
/// covering the true error.
fn check(label: &str, f: Estimate, exact: f64, tol: f64) {
    let err = (f.value - exact).abs();
    eprintln!(
        "{label} tol {tol}: F {:.7} exact {exact:.7} rel error {:.2e} stated {:.2e} rays {}",
        f.value,
        err / exact,
        f.error / exact,
        f.evaluations
    );
    assert!(err < tol * exact, "{label} tol {tol}: {f:?} vs {exact}");
    // The stopping rule, on its own estimate of F.
    assert!(
        f.error <= tol * f.value.max(exact) * 1.001,
        "{label} tol {tol}: {f:?}"
    );
    assert!(err <= 2.0 * f.error, "{label} tol {tol}: {f:?} vs {exact}");
}

#[test]
fn parallel_squares_c11_at_five_aspect_ratios() {
    for tol in [DEFAULT_TOLERANCE, TIGHT] {
        for (k, (a, b, c)) in [
            (1.0, 1.0, 1.0),
            (1.0, 2.0, 1.0),
            (1.0, 1.5, 0.5),
            (3.0, 0.5, 0.2),
            (0.2, 0.2, 2.0),
        ]
        .into_iter()
        .enumerate()
        {
            let f = sample(
                &rect_xy(a, b, 0.0, true),
                &rect_xy(a, b, c, false),
                tol,
                k as u64,
            );
            check(&format!("C-11 {a}×{b} at {c}"), f, c11(a, b, c), tol);
        }
    }
}

#[test]
fn perpendicular_rectangles_sharing_an_edge_c14_at_five_aspect_ratios() {
    for tol in [DEFAULT_TOLERANCE, TIGHT] {
        for (k, (w, h, l)) in [
            (1.0, 1.0, 1.0),
            (1.0, 2.0, 1.0),
            (0.3, 2.0, 1.5),
            (2.0, 0.5, 0.7),
            (0.1, 1.0, 3.0),
        ]
        .into_iter()
        .enumerate()
        {
            let (floor, wall) = hinge(w, h, l);
            let f = sample(&floor, &wall, tol, k as u64);
            check(&format!("C-14 w {w} h {h} l {l}"), f, c14(w, h, l), tol);
        }
    }
}

/// Coaxial discs (Howell), as 48-gons of the discs' areas: their own
/// factor differs from the discs' by less than 2·10⁻⁴ of it (checked by
/// quadrature), well inside the tolerances.
#[test]
fn coaxial_discs_at_five_aspect_ratios() {
    for tol in [DEFAULT_TOLERANCE, TIGHT] {
        for (k, (r1, r2, a)) in [
            (1.0, 1.0, 1.0),
            (0.5, 1.5, 0.8),
            (1.0, 0.25, 0.5),
            (2.0, 2.0, 0.3),
            (0.3, 0.6, 3.0),
        ]
        .into_iter()
        .enumerate()
        {
            let (r, s) = (disc(r1, 0.0, 48, true), disc(r2, a, 48, false));
            let exact = discs(r1, r2, a);
            let polygons = form_factor_polygon_polygon(&r, &s, 1e-10).value;
            assert!(
                (polygons - exact).abs() < 2e-4 * exact,
                "{polygons} vs {exact}"
            );
            let f = sample(&r, &s, tol, k as u64);
            check(&format!("discs {r1}, {r2} at {a}"), f, exact, tol);
        }
    }
}

/// Whether the segment x → y crosses the axis-aligned rectangle `box_` in
/// the plane z = `z`.
fn crosses(x: DVec3, y: DVec3, z: f64, box_: [f64; 4]) -> bool {
    let t = (z - x.z) / (y.z - x.z);
    if !(0.0..=1.0).contains(&t) {
        return false;
    }
    let p = x + t * (y - x);
    (box_[0]..=box_[1]).contains(&p.x) && (box_[2]..=box_[3]).contains(&p.y)
}

/// An occluder halfway between two parallel unit squares: the rays find
/// it, and the factor meets the exact occluded one (the source's visible
/// part from each receiver point is the source minus the occluder's
/// shadow, a rectangle; integrated by quadrature to 10⁻⁸).
#[test]
fn an_occluder_between_two_squares_is_found_by_the_rays() {
    let (r, s) = (rect_xy(1.0, 1.0, 0.0, true), rect_xy(1.0, 1.0, 1.0, false));
    for (k, plate) in [
        [0.25, 0.75, -1.0, 2.0], // a strip across
        [0.4, 0.6, 0.4, 0.6],    // a small plate
        [0.0, 0.5, 0.0, 0.5],    // a corner
    ]
    .into_iter()
    .enumerate()
    {
        // Seen from x, the plate at z = 0.5 hides [2 p − x] on z = 1.
        let hidden = |x: DVec3| {
            let (x0, x1) = (
                (2.0 * plate[0] - x.x).max(0.0),
                (2.0 * plate[1] - x.x).min(1.0),
            );
            let (y0, y1) = (
                (2.0 * plate[2] - x.y).max(0.0),
                (2.0 * plate[3] - x.y).min(1.0),
            );
            if x0 >= x1 || y0 >= y1 {
                return 0.0;
            }
            let shadow = [
                DVec3::new(x0, y0, 1.0),
                DVec3::new(x0, y1, 1.0),
                DVec3::new(x1, y1, 1.0),
                DVec3::new(x1, y0, 1.0),
            ];
            form_factor_point_polygon(x, DVec3::Z, &shadow)
        };
        let exact = form_factor_polygon_polygon_with(&r, &s, 1e-8, 4_000_000, |x| {
            1.0 - hidden(x) / form_factor_point_polygon(x, DVec3::Z, &s)
        })
        .value;
        assert!(
            exact < 0.9 * c11(1.0, 1.0, 1.0),
            "the plate hides something"
        );
        for tol in [DEFAULT_TOLERANCE, TIGHT] {
            let f = form_factor_area_sampling(
                &r,
                &s,
                tol,
                MAX_RAYS,
                &mut stream(5, k as u64),
                |x, y| !crosses(x, y, 0.5, plate),
            );
            let err = (f.value - exact).abs();
            eprintln!(
                "plate {plate:?} tol {tol}: F {:.6} exact {exact:.6} rel error {:.2e} stated {:.2e} rays {}",
                f.value,
                err / exact,
                f.error / exact,
                f.evaluations
            );
            assert!(
                err < 2.0 * tol * exact,
                "plate {plate:?} tol {tol}: {f:?} vs {exact}"
            );
        }
    }
    // A plate covering everything: nothing gets through.
    let f = form_factor_area_sampling(&r, &s, 0.01, MAX_RAYS, &mut stream(5, 9), |x, y| {
        !crosses(x, y, 0.5, [-5.0, 5.0, -5.0, 5.0])
    });
    assert_eq!(f.value, 0.0, "{f:?}");
}

/// An occluder small enough that every ray may miss it (issue 25): two
/// unit squares 3 apart and a plate halfway hiding 2.6 % of the factor. A
/// pair whose rays all got through used to state an unoccluded-sized
/// error (0.4 % at the default tolerance with 58 rays) while missing the
/// plate left it 2.8 % off, in 10 or more of these 40 seeds; now n clear
/// rays state F / n for what they may have missed, and probe rays are
/// added until that fits the tolerance, so the true error is within twice
/// the stated one in at least 37 of 40 seeds (measured: 40, the plate
/// seen in all).
#[test]
fn an_occluder_every_ray_missed_shows_in_the_stated_error() {
    let (c, plate) = (3.0, [0.457, 0.543, 0.457, 0.543]);
    let (r, s) = (rect_xy(1.0, 1.0, 0.0, true), rect_xy(1.0, 1.0, c, false));
    // Seen from x, the plate at c / 2 hides [2 p − x] on z = c.
    let hidden = |x: DVec3| {
        let x0 = (2.0 * plate[0] - x.x).max(0.0);
        let x1 = (2.0 * plate[1] - x.x).min(1.0);
        let y0 = (2.0 * plate[2] - x.y).max(0.0);
        let y1 = (2.0 * plate[3] - x.y).min(1.0);
        shadow_factor(x, [x0, x1, y0, y1], c)
    };
    let open = c11(1.0, 1.0, c);
    let exact = form_factor_polygon_polygon_with(&r, &s, 1e-9, 4_000_000, |x| {
        1.0 - hidden(x) / form_factor_point_polygon(x, DVec3::Z, &s)
    })
    .value;
    assert!(
        exact < 0.985 * open && exact > 0.95 * open,
        "the plate hides 1.5 to 5 %: {exact} of {open}"
    );
    let (mut covered, mut unseen, mut rays) = (0, 0, 0);
    for seed in 0..40 {
        let f = form_factor_area_sampling(
            &r,
            &s,
            DEFAULT_TOLERANCE,
            MAX_RAYS,
            &mut stream(27, seed),
            |x, y| !crosses(x, y, 0.5 * c, plate),
        );
        let err = (f.value - exact).abs();
        rays += f.evaluations;
        if (f.value - open).abs() < 0.2 * (open - exact) {
            unseen += 1;
        }
        if err <= 2.0 * f.error {
            covered += 1;
        } else {
            eprintln!("seed {seed}: {f:?} vs {exact} (open {open})");
        }
    }
    eprintln!(
        "small plate: covered {covered} of 40, unseen in {unseen}, {} rays a factor",
        rays / 40
    );
    assert!(covered >= 37, "covered {covered} of 40");
}

/// The factor from `x` (facing +z) to the rectangle x0–x1 × y0–y1 of the
/// plane z = `c` (0 when it is empty): the part of a source a plate hides.
fn shadow_factor(x: DVec3, [x0, x1, y0, y1]: [f64; 4], c: f64) -> f64 {
    if x0 >= x1 || y0 >= y1 {
        return 0.0;
    }
    let shadow = [
        DVec3::new(x0, y0, c),
        DVec3::new(x0, y1, c),
        DVec3::new(x1, y1, c),
        DVec3::new(x1, y0, c),
    ];
    form_factor_point_polygon(x, DVec3::Z, &shadow)
}

/// A random rotation.
fn rotation(rng: &mut impl Rng) -> DQuat {
    let axis = DVec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    DQuat::from_axis_angle(axis.normalize_or(DVec3::Z), rng.random_range(0.0..PI))
}

/// 200 random placements (seeded) of a rectangle before a unit square:
/// free, hinged on a shared edge at a random angle, and nearly touching.
/// Against quadrature to 10⁻⁹, the true error is within twice the stated
/// one in at least 95 % of them.
#[test]
fn the_stated_error_covers_the_true_error_over_random_placements() {
    let mut rng = stream(2025, 0);
    let receiver = rect_xy(1.0, 1.0, 0.0, true);
    let (mut cases, mut covered, mut tries) = (0, 0, 0);
    let mut worst: f64 = 0.0;
    while cases < 200 {
        tries += 1;
        assert!(tries < 2000, "too few placements see each other");
        let (a, b): (f64, f64) = (rng.random_range(0.2..2.0), rng.random_range(0.2..2.0));
        let kind = cases % 3;
        let source: Vec<DVec3> = match kind {
            0 => {
                // Anywhere above, turned any way.
                let q = rotation(&mut rng);
                let c = DVec3::new(
                    rng.random_range(-1.0..2.0),
                    rng.random_range(-1.0..2.0),
                    rng.random_range(0.1..2.0),
                );
                let v: Vec<DVec3> = rect_xy(a, b, 0.0, true)
                    .iter()
                    .map(|p| c + q * (*p - DVec3::new(0.5 * a, 0.5 * b, 0.0)))
                    .collect();
                // Its front toward the receiver's centre.
                if (DVec3::new(0.5, 0.5, 0.0) - c).dot(q * DVec3::Z) < 0.0 {
                    v.into_iter().rev().collect()
                } else {
                    v
                }
            }
            _ => {
                // Hinged on the edge x = 1 (kind 1) or a gap above it
                // (kind 2), opening by a random angle.
                let angle: f64 = rng.random_range(0.2..PI - 0.2);
                let gap = if kind == 1 {
                    0.0
                } else {
                    10f64.powf(rng.random_range(-3.0..-1.0))
                };
                let y0 = rng.random_range(-0.5..0.5);
                let (u, n) = (
                    DVec3::new(-angle.cos(), 0.0, angle.sin()),
                    DVec3::new(0.0, 1.0, 0.0),
                );
                let o = DVec3::new(1.0, y0, gap);
                let v = vec![o, o + a * u, o + a * u + b * n, o + b * n];
                let (_, normal) = nusselt::scene::polygon_area_normal(&v);
                // Facing the receiver's inside.
                if normal.x > 0.0 {
                    v.into_iter().rev().collect()
                } else {
                    v
                }
            }
        };
        // Receiver points behind the source's plane see none of its front.
        let (_, n_s) = nusselt::scene::polygon_area_normal(&source);
        let c_s = nusselt::scene::polygon_centroid(&source);
        let exact = form_factor_polygon_polygon_with(&receiver, &source, 1e-9, 4_000_000, |x| {
            f64::from((x - c_s).dot(n_s) > 0.0)
        })
        .value;
        if exact <= 1e-4 {
            continue;
        }
        let tol = [DEFAULT_TOLERANCE, 3e-3][cases % 2];
        let f = form_factor_area_sampling(
            &receiver,
            &source,
            tol,
            MAX_RAYS,
            &mut stream(7, cases as u64),
            |_, _| true,
        );
        let err = (f.value - exact).abs();
        worst = worst.max(err / f.error.max(1e-300));
        if err <= 2.0 * f.error + 1e-12 {
            covered += 1;
        } else {
            eprintln!(
                "placement {cases} (kind {kind}): F {} exact {exact} error {err:.2e} stated {:.2e}",
                f.value, f.error
            );
        }
        cases += 1;
    }
    eprintln!("covered {covered} of {cases}; worst true / stated {worst:.2}");
    assert!(covered >= 190, "covered {covered} of {cases}");
}

#[test]
fn the_same_stream_gives_the_same_factor() {
    let (floor, wall) = hinge(1.0, 1.0, 1.0);
    let plate = [0.2, 0.4, -5.0, 5.0];
    let run = || {
        form_factor_area_sampling(&floor, &wall, 1e-3, MAX_RAYS, &mut stream(1, 1), |x, y| {
            !crosses(x, y, 0.5, plate)
        })
    };
    assert_eq!(run(), run());
}

/// A square of side `side` centred on (a, 0, 0), facing up.
fn small_square(a: f64, side: f64) -> Vec<DVec3> {
    let e = 0.5 * side;
    vec![
        DVec3::new(a - e, -e, 0.0),
        DVec3::new(a + e, -e, 0.0),
        DVec3::new(a + e, e, 0.0),
        DVec3::new(a - e, e, 0.0),
    ]
}

/// Where the segment x → y crosses the plane z, if it does.
fn crossing(x: DVec3, y: DVec3, z: f64) -> Option<DVec3> {
    let t = (z - x.z) / (y.z - x.z);
    (0.0..=1.0).contains(&t).then(|| x + t * (y - x))
}

/// A visibility test, `visible(x, y)`.
type Visibility<'a> = &'a dyn Fn(DVec3, DVec3) -> bool;

/// A point against a disc, at five aspect ratios r/h (¼ to 4), on and off
/// the axis, bare and with an occluder halfway that the rays must find: an
/// opaque disc (the visible part is the source minus the occluder's
/// shadow, a disc twice its radius), and a plate with a round hole above
/// the point (the visible part is a disc of 0.4 times the source's radius,
/// 2–42 % of the factor).
/// Every exact answer is a difference of the closed form.
///
/// The kernel integrates over a receiver area, so the point is a square
/// of side 10⁻⁴ h: its mean factor differs from the point's by about 10⁻⁸
/// of it. The source is a 64-gon of the disc's area; its exact factor
/// (Lambert's contour integral) differs from the disc's by less than
/// 10⁻⁴ of it (asserted), so the tolerance is met against the disc's
/// closed form, and the stated error is checked against the 64-gon's.
#[test]
fn a_point_against_a_disc_at_five_aspect_ratios_with_occluders() {
    // (r, h, offset a, occluding disc radius), the occluder at h/2.
    let cases = [
        (0.5, 2.0, 0.0, 0.1),
        (1.0, 2.0, 0.3, 0.2),
        (1.0, 1.0, 0.5, 0.15),
        (2.0, 1.0, 0.8, 0.4),
        (2.0, 0.5, 1.0, 0.3),
    ];
    // The closed form itself, against the contour integral on a 4096-gon.
    for &(r, h, a, _) in &cases {
        let fine =
            form_factor_point_polygon(DVec3::new(a, 0.0, 0.0), DVec3::Z, &disc(r, h, 4096, false));
        let closed = point_to_disc(r, h, a);
        assert!((fine - closed).abs() < 1e-6 * closed, "{fine} vs {closed}");
    }
    for tol in [DEFAULT_TOLERANCE, TIGHT] {
        for (k, &(r, h, a, ro)) in cases.iter().enumerate() {
            let receiver = small_square(a, 1e-4 * h);
            let source = disc(r, h, 64, false);
            let x = DVec3::new(a, 0.0, 0.0);
            let polygon_bare = form_factor_point_polygon(x, DVec3::Z, &source);
            let bare = point_to_disc(r, h, a);
            assert!(
                (polygon_bare - bare).abs() < 1e-4 * bare,
                "{polygon_bare} vs {bare}"
            );
            // Seen from x at h/2, a disc of radius ρ on the axis casts on
            // the source's plane a disc of radius 2ρ, 2a off x's foot.
            assert!(
                a + 2.0 * ro < r * (PI / 64.0).cos(),
                "the shadow is on the source"
            );
            let blocker = move |x: DVec3, y: DVec3| {
                crossing(x, y, 0.5 * h).is_none_or(|p| p.truncate().length() >= ro)
            };
            let shadow = point_to_disc(2.0 * ro, h, 2.0 * a);
            // A hole of radius ρ at h/2 right above x shows a disc of
            // radius 2ρ = 0.4 r on the axis.
            let hole_radius = 0.2 * r;
            let hole = move |x: DVec3, y: DVec3| {
                crossing(x, y, 0.5 * h)
                    .is_none_or(|p| p.truncate().distance(DVec2::new(a, 0.0)) < hole_radius)
            };
            let through_hole = point_to_disc(2.0 * hole_radius, h, 0.0);
            // Behind an occluder the source is the disc's bounding square:
            // an occluded reading starts from the centroid fan of a
            // many-sided polygon, 64 thin wedges here, whose four points
            // each can miss a shadow's edge running along it (+1.8 % at
            // r/h 1 when tried).
            let square = [(-r, -r), (-r, r), (r, r), (r, -r)].map(|(u, v)| DVec3::new(u, v, h));
            let square_exact = form_factor_point_polygon(x, DVec3::Z, &square);
            let runs: [(&str, &[DVec3], f64, f64, Visibility); 3] = [
                ("bare", &source, bare, polygon_bare, &|_, _| true),
                (
                    "behind a disc",
                    &square,
                    square_exact - shadow,
                    square_exact - shadow,
                    &blocker,
                ),
                ("through a hole", &square, through_hole, through_hole, &hole),
            ];
            for (n, (what, source, exact, polygon_exact, visible)) in runs.into_iter().enumerate() {
                let f = form_factor_area_sampling(
                    &receiver,
                    source,
                    tol,
                    MAX_RAYS,
                    &mut stream(26, (10 * k + n) as u64),
                    visible,
                );
                let err = (f.value - exact).abs();
                eprintln!(
                    "point {what}, r/h {} off {a} tol {tol}: F {:.7} exact {exact:.7} rel error {:.2e} stated {:.2e} rays {}",
                    r / h,
                    f.value,
                    err / exact,
                    f.error / exact,
                    f.evaluations
                );
                let label = format!("{what} r {r} h {h} a {a} tol {tol}");
                assert!(err < tol * exact, "{label}: {f:?} vs {exact}");
                assert!(
                    f.error <= tol * f.value.max(exact) * 1.001,
                    "{label}: {f:?}"
                );
                let against_polygon = (f.value - polygon_exact).abs();
                assert!(
                    against_polygon <= 2.0 * f.error + 1e-6 * exact,
                    "{label}: {f:?} vs {polygon_exact}"
                );
            }
        }
    }
}

/// One random placement with an occluder whose exact effect is known: a
/// unit square receiver at z = 0, a rectangle source facing it at height
/// c, and an axis-aligned rectangular plate between them at height z_o,
/// all turned and moved together by a random rigid motion. From x, the
/// plate hides the rectangle it projects onto the source's plane (scaled
/// by c / z_o about x) clipped to the source, so the exact factor is the
/// quadrature (to 10⁻⁷ absolute) of the open point factor minus the hidden
/// rectangle's. Returns (receiver, source, exact, plate's height and box,
/// motion), or None when the plate hides less than 5 % or more than 95 %.
#[allow(clippy::type_complexity)]
fn occluded_placement(
    rng: &mut impl Rng,
) -> Option<(Vec<DVec3>, Vec<DVec3>, f64, f64, [f64; 4], DQuat, DVec3)> {
    let c = rng.random_range(0.3..2.0);
    let (w, l) = (rng.random_range(0.3..2.0), rng.random_range(0.3..2.0));
    let (ox, oy) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
    let source: Vec<DVec3> = rect_xy(w, l, c, false)
        .iter()
        .map(|p| *p + DVec3::new(ox, oy, 0.0))
        .collect();
    let t: f64 = rng.random_range(0.2..0.8);
    let z_o = t * c;
    // The plate about the line between the two centres, at its height.
    let centre =
        (1.0 - t) * DVec3::new(0.5, 0.5, 0.0) + t * DVec3::new(ox + 0.5 * w, oy + 0.5 * l, c);
    let (hx, hy) = (rng.random_range(0.05..0.6), rng.random_range(0.05..0.6));
    let (jx, jy) = (rng.random_range(-0.4..0.4), rng.random_range(-0.4..0.4));
    let plate = [
        centre.x + jx - hx,
        centre.x + jx + hx,
        centre.y + jy - hy,
        centre.y + jy + hy,
    ];
    let receiver = rect_xy(1.0, 1.0, 0.0, true);
    let s = c / z_o;
    let hidden = |x: DVec3| {
        let x0 = (x.x + (plate[0] - x.x) * s).max(ox);
        let x1 = (x.x + (plate[1] - x.x) * s).min(ox + w);
        let y0 = (x.y + (plate[2] - x.y) * s).max(oy);
        let y1 = (x.y + (plate[3] - x.y) * s).min(oy + l);
        shadow_factor(x, [x0, x1, y0, y1], c)
    };
    let open = form_factor_polygon_polygon(&receiver, &source, 1e-9).value;
    let exact = form_factor_polygon_polygon_with(&receiver, &source, 1e-7, 4_000_000, |x| {
        let f = form_factor_point_polygon(x, DVec3::Z, &source);
        if f > 0.0 { 1.0 - hidden(x) / f } else { 1.0 }
    })
    .value;
    if !(exact > 0.05 * open && exact < 0.95 * open && exact > 1e-3) {
        return None;
    }
    let q = rotation(rng);
    let shift = DVec3::new(
        rng.random_range(-3.0..3.0),
        rng.random_range(-3.0..3.0),
        rng.random_range(-3.0..3.0),
    );
    let place = |v: &[DVec3]| v.iter().map(|p| q * *p + shift).collect::<Vec<_>>();
    Some((
        place(&receiver),
        place(&source),
        exact,
        z_o,
        plate,
        q,
        shift,
    ))
}

/// The error estimate with occluders: `n` random placements of
/// [`occluded_placement`] at the default tolerance and at 3·10⁻³; returns
/// how many had the true error within twice the stated one.
fn occluded_coverage(n: usize, seed: u64) -> usize {
    let mut rng = stream(seed, 0);
    let (mut cases, mut covered, mut tries) = (0, 0, 0);
    let (mut worst, mut rays): (f64, usize) = (0.0, 0);
    while cases < n {
        tries += 1;
        assert!(tries < 20 * n, "too few placements are partly occluded");
        let Some((receiver, source, exact, z_o, plate, q, shift)) = occluded_placement(&mut rng)
        else {
            continue;
        };
        let back = q.inverse();
        let tol = [DEFAULT_TOLERANCE, 3e-3][cases % 2];
        let f = form_factor_area_sampling(
            &receiver,
            &source,
            tol,
            MAX_RAYS,
            &mut stream(8, cases as u64),
            |x, y| !crosses(back * (x - shift), back * (y - shift), z_o, plate),
        );
        rays += f.evaluations;
        let err = (f.value - exact).abs();
        worst = worst.max(err / f.error.max(1e-300));
        if err <= 2.0 * f.error + 1e-12 {
            covered += 1;
        } else {
            eprintln!(
                "occluded placement {cases} tol {tol}: F {} exact {exact} error {err:.2e} stated {:.2e}",
                f.value, f.error
            );
        }
        cases += 1;
    }
    eprintln!(
        "occluded: covered {covered} of {cases}; worst true / stated {worst:.2}; {} rays a factor",
        rays / cases
    );
    covered
}

/// 200 random partly occluded placements: the true error is within twice
/// the stated one in at least 95 % of them.
#[test]
fn the_stated_error_covers_the_true_error_with_occluders() {
    let covered = occluded_coverage(200, 2026);
    assert!(covered >= 190, "covered {covered} of 200");
}

/// The same over 2000 placements (`NUSSELT_SLOW_TESTS=1`).
#[test]
fn the_stated_error_covers_the_true_error_with_occluders_2000() {
    if !crate::fixtures::slow_tests("the_stated_error_covers_the_true_error_with_occluders_2000") {
        return;
    }
    let covered = occluded_coverage(2000, 2027);
    assert!(covered >= 1900, "covered {covered} of 2000");
}
