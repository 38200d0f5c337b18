//! Tests of the hemicube against the exact point-to-polygon kernel:
//! closure, occlusion, rotation, resolution, degenerate and random scenes.

use super::*;
use crate::sampling::stream;
use rand::Rng;

/// The polygon oriented so that its front faces `x`.
fn facing(mut poly: Vec<DVec3>, x: DVec3) -> Vec<DVec3> {
    let n = (poly[1] - poly[0]).cross(poly[2] - poly[0]);
    if n.dot(x - poly[0]) < 0.0 {
        poly.reverse();
    }
    poly
}

/// A `size` × `size` square at height z centred over (cx, cy), front
/// facing down (towards the origin's side).
fn square(cx: f64, cy: f64, z: f64, size: f64) -> Vec<DVec3> {
    let r = 0.5 * size;
    vec![
        DVec3::new(cx - r, cy - r, z),
        DVec3::new(cx - r, cy + r, z),
        DVec3::new(cx + r, cy + r, z),
        DVec3::new(cx + r, cy - r, z),
    ]
}

fn row(hc: &Hemicube, x: DVec3, n: DVec3, polys: &[Vec<DVec3>], rot: f64) -> Vec<f64> {
    let refs: Vec<&[DVec3]> = polys.iter().map(|p| p.as_slice()).collect();
    let mut out = vec![f64::NAN; polys.len()];
    hc.row(x, n, &refs, None, rot, &mut out);
    out
}

fn exact(x: DVec3, n: DVec3, poly: &[DVec3]) -> f64 {
    form_factor_point_polygon(x, n, poly)
}

/// Named configurations with their exact answer for polygon 0.
struct Config {
    name: &'static str,
    x: DVec3,
    normal: DVec3,
    polys: Vec<Vec<DVec3>>,
    exact: f64,
}

fn configs() -> Vec<Config> {
    let x = DVec3::ZERO;
    let wall = |z0: f64| {
        facing(
            vec![
                DVec3::new(-1.0, 1.0, z0),
                DVec3::new(1.0, 1.0, z0),
                DVec3::new(1.0, 1.0, 1.0),
                DVec3::new(-1.0, 1.0, 1.0),
            ],
            x,
        )
    };
    let big = square(0.0, 0.0, 2.0, 2.0);
    let small = square(0.0, 0.0, 1.0, 0.5);
    let tilted_n = DVec3::new(0.3, -0.2, 1.0).normalize();
    let tilted = facing(
        vec![
            DVec3::new(0.2, 0.1, 0.7),
            DVec3::new(1.1, 0.3, 0.9),
            DVec3::new(0.6, 1.2, 1.4),
        ],
        x,
    );
    vec![
        Config {
            name: "square, offset",
            x,
            normal: DVec3::Z,
            polys: vec![square(0.5, 0.3, 1.0, 1.0)],
            exact: exact(x, DVec3::Z, &square(0.5, 0.3, 1.0, 1.0)),
        },
        Config {
            name: "perpendicular wall",
            x,
            normal: DVec3::Z,
            polys: vec![wall(0.0)],
            exact: exact(x, DVec3::Z, &wall(0.0)),
        },
        Config {
            name: "wall half below",
            x,
            normal: DVec3::Z,
            polys: vec![wall(-1.0)],
            exact: exact(x, DVec3::Z, &wall(-1.0)),
        },
        Config {
            name: "occluded square",
            x,
            normal: DVec3::Z,
            exact: exact(x, DVec3::Z, &big) - exact(x, DVec3::Z, &small),
            polys: vec![big, small],
        },
        Config {
            name: "tilted triangle",
            x,
            normal: tilted_n,
            exact: exact(x, tilted_n, &tilted),
            polys: vec![tilted],
        },
    ]
}

#[test]
fn cells_sum_to_one_at_every_resolution() {
    println!("   R   sum of exact cells   sum of cell-centre ΔF [CG85]");
    for r in [2u32, 4, 8, 16, 32, 64, 128, 256, 512, 1024] {
        let hc = Hemicube::new(r);
        assert_eq!(hc.resolution(), r);
        let total = hc.total();
        assert!((total - 1.0).abs() < 1e-10, "R = {r}: {total}");
        // The classic cell-centre delta form factors, for comparison:
        // they converge to the exact cells as R grows.
        let h = 2.0 / r as f64;
        let (mut midpoint, mut worst) = (0.0, 0.0f64);
        let ru = r as usize;
        for j in 0..ru {
            for i in 0..ru {
                let (s, t) = (-1.0 + (i as f64 + 0.5) * h, -1.0 + (j as f64 + 0.5) * h);
                let f = h * h / (std::f64::consts::PI * (1.0 + s * s + t * t).powi(2));
                midpoint += f;
                worst = worst.max((f / hc.top[j * ru + i] - 1.0).abs());
                if j < ru / 2 {
                    let t = (j as f64 + 0.5) * h;
                    let f = t * h * h / (std::f64::consts::PI * (1.0 + s * s + t * t).powi(2));
                    midpoint += 4.0 * f;
                    worst = worst.max((f / hc.side[j * ru + i] - 1.0).abs());
                }
            }
        }
        println!("{r:>4}   {total:.15}   {midpoint:.9} (worst cell off by {worst:.2e})");
        // The cell-centre rule is second order: the exact cells are in
        // the right places with the right sizes.
        // (The worst relative error times R² tends to 8/3.)
        assert!(worst * (r * r) as f64 <= 2.7, "R = {r}: {worst}");
    }
    // Odd and out-of-range resolutions are adjusted, not refused.
    assert_eq!(Hemicube::new(0).resolution(), 2);
    assert_eq!(Hemicube::new(7).resolution(), 8);
    assert_eq!(Hemicube::new(u32::MAX).resolution(), MAX_RESOLUTION);
}

#[test]
fn parallel_square_at_several_offsets() {
    let hc = Hemicube::new(256);
    for z in [0.25, 0.5, 1.0, 2.0] {
        for (cx, cy) in [(0.0, 0.0), (0.5, 0.5), (1.2, -0.3), (-3.0, 0.4)] {
            let sq = square(cx, cy, z, 1.0);
            let want = exact(DVec3::ZERO, DVec3::Z, &sq);
            for rot in [0.0, 0.37] {
                let got = row(&hc, DVec3::ZERO, DVec3::Z, std::slice::from_ref(&sq), rot)[0];
                assert!(
                    (got - want).abs() < 2e-3,
                    "z {z}, centre ({cx}, {cy}), rotation {rot}: {got} vs {want}"
                );
            }
        }
    }
    // The closed form of the doc example (centred unit square, height 1).
    let got = row(
        &hc,
        DVec3::ZERO,
        DVec3::Z,
        &[square(0.0, 0.0, 1.0, 1.0)],
        0.3,
    )[0];
    assert!((got - 0.239_5).abs() < 2e-3, "{got}");
}

#[test]
fn walls_and_clipping_match_the_exact_kernel() {
    let hc = Hemicube::new(256);
    for c in configs() {
        if c.polys.len() != 1 {
            continue;
        }
        let got = row(&hc, c.x, c.normal, &c.polys, 0.21)[0];
        assert!(
            got > 0.0 && (got - c.exact).abs() < 2e-3,
            "{}: {got} vs {}",
            c.name,
            c.exact
        );
    }
    // A wall entirely below the tangent plane is not seen at all.
    let below = facing(
        vec![
            DVec3::new(-1.0, 1.0, -2.0),
            DVec3::new(1.0, 1.0, -2.0),
            DVec3::new(1.0, 1.0, -0.01),
            DVec3::new(-1.0, 1.0, -0.01),
        ],
        DVec3::ZERO,
    );
    assert_eq!(row(&hc, DVec3::ZERO, DVec3::Z, &[below], 0.0)[0], 0.0);
    // A receiver looking sideways sees the same wall as a parallel one.
    let wall = facing(square(0.0, 0.0, 1.0, 1.0), DVec3::ZERO);
    let normal = DVec3::new(0.0, 0.6, 0.8);
    let got = row(&hc, DVec3::ZERO, normal, std::slice::from_ref(&wall), 1.0)[0];
    let want = exact(DVec3::ZERO, normal, &wall);
    assert!((got - want).abs() < 2e-3, "{got} vs {want}");
}

#[test]
fn nearer_square_occludes_farther_one() {
    let hc = Hemicube::new(256);
    let big = square(0.0, 0.0, 2.0, 2.0);
    let small = square(0.0, 0.0, 1.0, 0.5);
    let (fb, fs) = (
        exact(DVec3::ZERO, DVec3::Z, &big),
        exact(DVec3::ZERO, DVec3::Z, &small),
    );
    // The small square's shadow on the big one is exactly its own
    // projection, so the big one loses exactly the small one's F.
    let alone = row(&hc, DVec3::ZERO, DVec3::Z, std::slice::from_ref(&big), 0.4)[0];
    for polys in [
        vec![big.clone(), small.clone()],
        vec![small.clone(), big.clone()],
    ] {
        let out = row(&hc, DVec3::ZERO, DVec3::Z, &polys, 0.4);
        let (gb, gs) = if polys[0] == big {
            (out[0], out[1])
        } else {
            (out[1], out[0])
        };
        assert!((gs - fs).abs() < 2e-3, "small {gs} vs {fs}");
        assert!((gb - (fb - fs)).abs() < 2e-3, "big {gb} vs {}", fb - fs);
        assert!(
            (gb + gs - alone).abs() < 1e-12,
            "covered cells are shared, not lost"
        );
    }
    // Seen from behind, the small square still shadows but gets nothing.
    let mut back = small.clone();
    back.reverse();
    let out = row(
        &hc,
        DVec3::ZERO,
        DVec3::Z,
        &[big.clone(), back.clone()],
        0.4,
    );
    assert_eq!(out[1], 0.0);
    assert!(
        (out[0] - (fb - fs)).abs() < 2e-3,
        "{} vs {}",
        out[0],
        fb - fs
    );
    // Both sides (a double-sided surface): the front side wins the tie,
    // whatever the drawing order.
    for polys in [
        vec![big.clone(), small.clone(), back.clone()],
        vec![big.clone(), back, small.clone()],
    ] {
        let out = row(&hc, DVec3::ZERO, DVec3::Z, &polys, 0.4);
        let (gs, gback) = if polys[1] == square(0.0, 0.0, 1.0, 0.5) {
            (out[1], out[2])
        } else {
            (out[2], out[1])
        };
        assert_eq!(gback, 0.0);
        assert!((gs - fs).abs() < 2e-3, "{gs} vs {fs}");
        assert!((out[0] - (fb - fs)).abs() < 2e-3);
    }
    // A farther polygon does not hide a nearer one.
    let far_small = square(0.0, 0.0, 3.0, 0.5);
    let out = row(&hc, DVec3::ZERO, DVec3::Z, &[big.clone(), far_small], 0.4);
    assert!((out[0] - fb).abs() < 2e-3 && out[1] == 0.0, "{out:?}");
    // `skip` removes a polygon entirely, as occluder too.
    let refs: Vec<&[DVec3]> = vec![&big, &small];
    let mut out = [0.0; 2];
    hc.row(DVec3::ZERO, DVec3::Z, &refs, Some(1), 0.4, &mut out);
    assert!(out[1] == 0.0 && (out[0] - fb).abs() < 2e-3, "{out:?}");
}

#[test]
fn rotation_changes_results_only_within_aliasing() {
    let hc = Hemicube::new(128);
    let mut rng = stream(7, 0);
    for c in configs() {
        let values: Vec<f64> = (0..16)
            .map(|_| {
                let rot = rng.random::<f64>() * std::f64::consts::TAU;
                row(&hc, c.x, c.normal, &c.polys, rot)[0]
            })
            .collect();
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!(hi > lo, "{}: rotation must move the cells", c.name);
        assert!(hi - lo < 4e-3, "{}: spread {}", c.name, hi - lo);
        for v in values {
            assert!((v - c.exact).abs() < 3e-3, "{}: {v} vs {}", c.name, c.exact);
        }
    }
    // Turning by a full turn is the same hemicube.
    let c = &configs()[0];
    let a = row(&hc, c.x, c.normal, &c.polys, 0.3)[0];
    let b = row(&hc, c.x, c.normal, &c.polys, 0.3 + std::f64::consts::TAU)[0];
    assert!((a - b).abs() < 1e-12);
}

#[test]
fn error_falls_as_resolution_grows() {
    const ROTATIONS: usize = 8;
    let resolutions = [16u32, 32, 64, 128, 256];
    let configs = configs();
    let mut table = vec![vec![0.0; resolutions.len()]; configs.len()];
    for (ri, &r) in resolutions.iter().enumerate() {
        let hc = Hemicube::new(r);
        for (ci, c) in configs.iter().enumerate() {
            let mut rng = stream(11, ci as u64);
            let mean: f64 = (0..ROTATIONS)
                .map(|_| {
                    let rot = rng.random::<f64>() * std::f64::consts::TAU;
                    (row(&hc, c.x, c.normal, &c.polys, rot)[0] - c.exact).abs()
                })
                .sum::<f64>()
                / ROTATIONS as f64;
            table[ci][ri] = mean;
        }
    }
    println!("mean |F_hemicube − F_exact| over {ROTATIONS} random rotations");
    print!("{:<20} {:>9}", "configuration", "F_exact");
    for r in resolutions {
        print!(" {:>9}", format!("R={r}"));
    }
    println!();
    for (c, errors) in configs.iter().zip(&table) {
        print!("{:<20} {:>9.6}", c.name, c.exact);
        for e in errors {
            print!(" {e:>9.2e}");
        }
        println!();
        // A clear trend: 16× the resolution cuts the error by 16× at
        // least, and no doubling makes it more than a little worse.
        let (first, last) = (errors[0], errors[errors.len() - 1]);
        assert!(last < first / 16.0, "{}: {errors:?}", c.name);
        for w in errors.windows(2) {
            assert!(w[1] < 1.5 * w[0], "{}: {errors:?}", c.name);
        }
    }
}

/// A unit cube around the receiver, each face facing inwards; the floor
/// (z = 0) first.
fn cube() -> Vec<Vec<DVec3>> {
    let c = DVec3::splat(0.5);
    let corners = |axis: usize, side: f64| {
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
            .map(|(a, b)| {
                let mut p = DVec3::ZERO;
                p[axis] = side;
                p[i] = a;
                p[j] = b;
                p
            })
            .to_vec()
    };
    let mut faces = Vec::new();
    for axis in [2, 0, 1] {
        for side in [0.0, 1.0] {
            faces.push(facing(corners(axis, side), c));
        }
    }
    faces
}

#[test]
fn closed_cube_rows_sum_to_one() {
    let hc = Hemicube::new(128);
    let faces = cube();
    let refs: Vec<&[DVec3]> = faces.iter().map(|p| p.as_slice()).collect();
    for x in [
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::new(0.1, 0.8, 0.0),
        DVec3::new(1e-6, 0.5, 0.0),
        DVec3::new(1e-6, 1e-6, 0.0),
    ] {
        let mut out = [f64::NAN; 6];
        hc.row(x, DVec3::Z, &refs, Some(0), 0.7, &mut out);
        let sum: f64 = out.iter().sum();
        assert!((sum - 1.0).abs() < 1e-9, "{x}: {sum} {out:?}");
        assert_eq!(out[0], 0.0);
        for (k, f) in out.iter().enumerate().skip(1) {
            let want = exact(x, DVec3::Z, &faces[k]);
            assert!((f - want).abs() < 5e-3, "{x}, face {k}: {f} vs {want}");
        }
    }
    // At a corner of the floor the two walls through x are seen
    // edge-on; the rest is finite and matches the exact kernel.
    let x = DVec3::ZERO;
    let mut out = [f64::NAN; 6];
    hc.row(x, DVec3::Z, &refs, Some(0), 0.7, &mut out);
    for (k, f) in out.iter().enumerate().skip(1) {
        let want = exact(x, DVec3::Z, &faces[k]);
        assert!((f - want).abs() < 5e-3, "corner, face {k}: {f} vs {want}");
    }
}

#[test]
fn touching_and_degenerate_polygons_stay_in_range() {
    let hc = Hemicube::new(128);
    let x = DVec3::ZERO;
    let check = |polys: &[Vec<DVec3>], n: DVec3| {
        let out = row(&hc, x, n, polys, 0.9);
        for f in &out {
            assert!(f.is_finite() && (0.0..=1.0).contains(f), "{out:?}");
        }
        assert!(out.iter().sum::<f64>() <= 1.0 + 1e-12);
        out
    };
    // A wall standing on the tangent plane, sharing its bottom edge
    // with it.
    let wall = facing(
        vec![
            DVec3::new(-1.0, 0.5, 0.0),
            DVec3::new(1.0, 0.5, 0.0),
            DVec3::new(1.0, 0.5, 1.0),
            DVec3::new(-1.0, 0.5, 1.0),
        ],
        x,
    );
    let f = check(std::slice::from_ref(&wall), DVec3::Z)[0];
    assert!((f - exact(x, DVec3::Z, &wall)).abs() < 3e-3, "{f}");
    // A wall through x: seen edge-on.
    let through = facing(
        vec![
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(-1.0, 0.0, 1.0),
        ],
        DVec3::Y,
    );
    assert_eq!(check(&[through], DVec3::Z)[0], 0.0);
    // Squares 1e-6 above x: centred (almost the whole hemisphere) and
    // with x under a corner (almost a quarter).
    for sq in [square(0.0, 0.0, 1e-6, 1.0), square(0.5, 0.5, 1e-6, 1.0)] {
        let f = check(std::slice::from_ref(&sq), DVec3::Z)[0];
        let want = exact(x, DVec3::Z, &sq);
        assert!((f - want).abs() < 3e-3, "{f} vs {want}");
    }
    // Coplanar with the receiver: nothing.
    let floor = facing(square(2.0, 0.0, 0.0, 1.0), DVec3::Z);
    assert_eq!(check(&[floor], DVec3::Z)[0], 0.0);
    // Degenerate input draws nothing and harms no other polygon.
    let sq = square(0.0, 0.0, 1.0, 1.0);
    let want = exact(x, DVec3::Z, &sq);
    let junk = vec![
        vec![
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::new(1.0, 0.0, 0.5),
            DVec3::new(2.0, 0.0, 0.5),
        ],
        vec![DVec3::new(0.0, 0.0, 0.5), DVec3::new(1.0, 0.0, 0.5)],
        vec![
            DVec3::new(f64::NAN, 0.0, 0.5),
            DVec3::new(1.0, 0.0, 0.5),
            DVec3::Z,
        ],
        vec![DVec3::splat(f64::INFINITY); 4],
        vec![],
        sq,
    ];
    let out = check(&junk, DVec3::Z);
    assert_eq!(&out[..5], &[0.0; 5]);
    assert!((out[5] - want).abs() < 3e-3);
    // A degenerate receiver gets a zero row.
    let refs: Vec<&[DVec3]> = junk.iter().map(|p| p.as_slice()).collect();
    for (x, n) in [
        (DVec3::ZERO, DVec3::ZERO),
        (DVec3::NAN, DVec3::Z),
        (x, DVec3::NAN),
    ] {
        let mut out = [1.0; 6];
        hc.row(x, n, &refs, None, f64::NAN, &mut out);
        assert_eq!(out, [0.0; 6]);
    }
}

#[test]
fn polygons_of_many_vertices_are_drawn_whole() {
    let hc = Hemicube::new(256);
    for m in [5usize, 8, 9, 12, 40] {
        let poly: Vec<DVec3> = (0..m)
            .map(|k| {
                let a = -(k as f64) * std::f64::consts::TAU / m as f64;
                DVec3::new(0.3 + a.cos(), a.sin(), 1.0)
            })
            .collect();
        let poly = facing(poly, DVec3::ZERO);
        // The exact kernel takes at most 15 vertices: sum over a fan.
        let want: f64 = (1..m - 1)
            .map(|k| exact(DVec3::ZERO, DVec3::Z, &[poly[0], poly[k], poly[k + 1]]))
            .sum();
        let got = row(&hc, DVec3::ZERO, DVec3::Z, &[poly], 0.5)[0];
        assert!((got - want).abs() < 2e-3, "{m} vertices: {got} vs {want}");
    }
}

#[test]
fn random_scenes_give_bounded_deterministic_rows() {
    let hc = Hemicube::new(32);
    let mut rng = stream(3, 1);
    for _ in 0..100 {
        let polys: Vec<Vec<DVec3>> = (0..20)
            .map(|_| {
                let c = DVec3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-1.0..2.0),
                );
                let m = if rng.random::<bool>() { 3 } else { 4 };
                let (e1, e2) = DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
                .normalize()
                .any_orthonormal_pair();
                let size = rng.random_range(0.01..2.0);
                (0..m)
                    .map(|k| {
                        let a = k as f64 * std::f64::consts::TAU / m as f64;
                        c + size * (a.cos() * e1 + a.sin() * e2)
                    })
                    .collect()
            })
            .collect();
        let n = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let rot = rng.random_range(0.0..7.0);
        let a = row(&hc, DVec3::ZERO, n, &polys, rot);
        let b = row(&hc, DVec3::ZERO, n, &polys, rot);
        assert_eq!(a, b);
        assert!(
            a.iter().all(|f| f.is_finite() && (0.0..=1.0).contains(f)),
            "{a:?}"
        );
        assert!(a.iter().sum::<f64>() <= 1.0 + 1e-12);
    }
}
