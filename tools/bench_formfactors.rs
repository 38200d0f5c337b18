//! Time per form factor against accuracy, for each kernel on three pairs of
//! unit squares: touching (at a right angle on a shared edge, Howell
//! C-14), nearly touching (the same with a 10⁻³ gap) and distant (parallel,
//! opposed, 5 apart, C-11); and, for the kernels that see occluders (area
//! sampling through its rays, the hemicube through its z-buffer), a point
//! below a disc with an opaque disc between them (exact: the point's
//! contour integral over the source minus the shadow's closed form).
//!
//! Run: `cargo run --release --example bench-formfactors`. Prints a
//! Markdown table: per kernel and knob (area sampling's
//! `--sampling-tolerance`, polygon-polygon's `--quadrature-tolerance`, the
//! hemicube's resolution at the receiver's centroid), the time per factor,
//! the true relative error (mean over seeds for sampling and the rotated
//! hemicube) and the kernel's own stated error, and the rays or evaluations
//! spent. Visibility is free for the square pairs (nothing occludes) and
//! one plane test a ray for the occluded pair: a real scene adds the rays'
//! cost (see `bench-visibility`).

use std::hint::black_box;
use std::time::Instant;

use glam::DVec3;
use nusselt::formfactor::area_sampling::MAX_RAYS;
use nusselt::formfactor::closed_form::{c11, c14, point_to_disc};
use nusselt::formfactor::hemicube::Hemicube;
use nusselt::formfactor::{
    form_factor_area_sampling, form_factor_point_polygon, form_factor_polygon_polygon,
};
use nusselt::sampling::stream;

/// Repeat each measurement for at least this long.
const MIN_SECONDS: f64 = 0.3;

fn square_up() -> Vec<DVec3> {
    vec![
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
    ]
}

/// A unit wall on x = 1 facing −x, its lower edge at height `gap`.
fn wall(gap: f64) -> Vec<DVec3> {
    vec![
        DVec3::new(1.0, 0.0, gap),
        DVec3::new(1.0, 0.0, gap + 1.0),
        DVec3::new(1.0, 1.0, gap + 1.0),
        DVec3::new(1.0, 1.0, gap),
    ]
}

fn ceiling(z: f64) -> Vec<DVec3> {
    let mut v = square_up();
    for p in &mut v {
        p.z = z;
    }
    v.reverse();
    v
}

/// A regular `m`-gon of the area of the disc of radius `r` about the z
/// axis at height `z`, facing down (towards the origin).
fn disc_down(r: f64, z: f64, m: usize) -> Vec<DVec3> {
    let t = std::f64::consts::TAU / m as f64;
    let rr = r * (t / t.sin()).sqrt();
    (0..m)
        .rev()
        .map(|k| DVec3::new(rr * (k as f64 * t).cos(), rr * (k as f64 * t).sin(), z))
        .collect()
}

/// Runs `f(k)` for k = 0, 1, … until `MIN_SECONDS` have passed (at least
/// twice); returns seconds per call and the results.
fn timed<T>(mut f: impl FnMut(u64) -> T) -> (f64, Vec<T>) {
    let t = Instant::now();
    let mut out = Vec::new();
    while out.len() < 2 || t.elapsed().as_secs_f64() < MIN_SECONDS {
        out.push(black_box(f(out.len() as u64)));
    }
    (t.elapsed().as_secs_f64() / out.len() as f64, out)
}

fn main() {
    let receiver = square_up();
    let nearly = wall(1e-3);
    let near_exact = form_factor_polygon_polygon(&receiver, &nearly, 1e-12).value;
    let pairs: [(&str, Vec<DVec3>, f64); 3] = [
        ("touching", wall(0.0), c14(1.0, 1.0, 1.0)),
        ("nearly touching (gap 1e-3)", nearly, near_exact),
        (
            "distant (parallel, 5 apart)",
            ceiling(5.0),
            c11(1.0, 1.0, 5.0),
        ),
    ];
    println!(
        "| pair | kernel | knob | time per factor | true rel. error | stated rel. error | rays / evaluations |"
    );
    println!("|---|---|---|---:|---:|---:|---:|");
    for (name, source, exact) in &pairs {
        let tols = [1e-1, 1e-2, 1e-3, 1e-4];
        sampling_rows(name, &receiver, source, *exact, &tols, 11, |_, _| true);
        for tol in [1e-3, 1e-4, 1e-5, 1e-6] {
            let (secs, runs) = timed(|_| form_factor_polygon_polygon(&receiver, source, tol));
            let f = runs[0];
            row(
                name,
                "polygon-polygon",
                &format!("quadrature tolerance {tol:e}"),
                secs,
                (f.value - exact).abs() / exact,
                Some(f.error / exact),
                f.evaluations as f64,
            );
        }
        let x = DVec3::new(0.5, 0.5, 0.0);
        let label = "hemicube (at the centroid)";
        hemicube_rows(name, label, x, &[source.as_slice()], *exact);
    }
    occluded();
}

fn row(pair: &str, kernel: &str, knob: &str, secs: f64, err: f64, stated: Option<f64>, work: f64) {
    let time = if secs < 1e-3 {
        format!("{:.1} µs", secs * 1e6)
    } else {
        format!("{:.2} ms", secs * 1e3)
    };
    let stated = stated.map_or("–".to_string(), |s| format!("{s:.1e}"));
    let work = if work > 0.0 {
        format!("{work:.0}")
    } else {
        "–".to_string()
    };
    println!("| {pair} | {kernel} | {knob} | {time} | {err:.1e} | {stated} | {work} |");
}

/// A point (a square of side 10⁻⁴) 0.5 off the axis of a unit disc 1
/// above it, an opaque disc of radius 0.15 halfway: it hides a disc of
/// radius 0.3 of the source, 1.0 off the point's foot.
fn occluded() {
    let (r, h, a, ro) = (1.0, 1.0, 0.5, 0.15);
    let e = 0.5e-4;
    let receiver = vec![
        DVec3::new(a - e, -e, 0.0),
        DVec3::new(a + e, -e, 0.0),
        DVec3::new(a + e, e, 0.0),
        DVec3::new(a - e, e, 0.0),
    ];
    let source = disc_down(r, h, 64);
    let x = DVec3::new(a, 0.0, 0.0);
    let exact =
        form_factor_point_polygon(x, DVec3::Z, &source) - point_to_disc(2.0 * ro, h, 2.0 * a);
    let name = "point behind a disc (hides 5 %)";
    let visible = |x: DVec3, y: DVec3| {
        let t = (0.5 * h - x.z) / (y.z - x.z);
        !(0.0..=1.0).contains(&t) || (x + t * (y - x)).truncate().length() >= ro
    };
    sampling_rows(
        name,
        &receiver,
        &source,
        exact,
        &[1e-1, 1e-2, 1e-3],
        12,
        visible,
    );
    let blocker = disc_down(ro, 0.5 * h, 64);
    let polygons = [source.as_slice(), blocker.as_slice()];
    hemicube_rows(name, "hemicube (at the point)", x, &polygons, exact);
}

/// Area sampling's rows at tolerances `tols`: time, mean true and stated
/// relative error over seeds (streams `key`, 0, 1, …), mean rays.
fn sampling_rows(
    name: &str,
    receiver: &[DVec3],
    source: &[DVec3],
    exact: f64,
    tols: &[f64],
    key: u64,
    visible: impl Fn(DVec3, DVec3) -> bool + Copy,
) {
    for &tol in tols {
        let (secs, runs) = timed(|k| {
            form_factor_area_sampling(
                receiver,
                source,
                tol,
                MAX_RAYS,
                &mut stream(key, k),
                visible,
            )
        });
        let n = runs.len() as f64;
        let err = runs.iter().map(|f| (f.value - exact).abs()).sum::<f64>() / n;
        let stated = runs.iter().map(|f| f.error).sum::<f64>() / n;
        let rays = runs.iter().map(|f| f.evaluations).sum::<usize>() as f64 / n;
        row(
            name,
            "sampling",
            &format!("tolerance {tol:e}"),
            secs,
            err / exact,
            Some(stated / exact),
            rays,
        );
    }
}

/// The hemicube's rows at `x` (normal +z), turned by a new angle each
/// call: the factor to the first of `polygons`, the others occluding.
fn hemicube_rows(name: &str, label: &str, x: DVec3, polygons: &[&[DVec3]], exact: f64) {
    for res in [32, 128, 512] {
        let cube = Hemicube::new(res);
        let mut out = vec![0.0; polygons.len()];
        let (secs, runs) = timed(|k| {
            let angle = k as f64 * 0.618_033_988_749_895 * std::f64::consts::TAU;
            cube.row(x, DVec3::Z, polygons, None, angle, &mut out);
            out[0]
        });
        let err = runs.iter().map(|f| (f - exact).abs()).sum::<f64>() / runs.len() as f64;
        row(
            name,
            label,
            &format!("resolution {res}"),
            secs,
            err / exact,
            None,
            0.0,
        );
    }
}
