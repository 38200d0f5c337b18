//! The path-traced reference: closed forms (furnace, Howell C-11, Lambert's
//! point factor), the noise image as a predictor of the real error,
//! determinism across thread counts, the command line, and the committed
//! point tables read and written back unchanged.
//!
//! Slower, tighter variants run with NUSSELT_SLOW_TESTS=1.

use std::f64::consts::PI;

use glam::DVec3;
use nusselt::formfactor::form_factor_point_polygon;
use nusselt::reference::{ReferenceImage, ReferenceSettings, ReferenceStats, render_reference};
use nusselt::render::frame::Frame;
use nusselt::render::view::{View, ViewOverrides};
use nusselt::scene::{InputTriangle, Material, Scene, Surface};
use nusselt::util::progress::Progress;

use crate::fixtures::{
    assert_user_error, bundled_scene, furnace_box_rgb, nusselt, on_threads, scene_path, slow_tests,
};

fn settings(spp: u32, seed: u64) -> ReferenceSettings {
    ReferenceSettings {
        samples_per_pixel: spp,
        seed,
        max_bounces: None,
    }
}

fn trace(scene: &Scene, view: &View, s: &ReferenceSettings) -> ReferenceImage {
    render_reference(scene, view, s, &Progress::hidden()).unwrap()
}

fn view(eye: DVec3, target: DVec3, up: DVec3, fov_deg: f64, side: u32) -> View {
    let o = ViewOverrides {
        eye: Some(eye),
        target: Some(target),
        up: Some(up),
        fov_deg: Some(fov_deg),
        width: Some(side),
        height: Some(side),
    };
    View::resolve(None, (DVec3::ZERO, DVec3::ONE), &o).unwrap()
}

/// A unit cube seen from inside, every face emitting radiance `le` and
/// reflecting `rho`.
fn furnace(le: DVec3, rho: f64) -> Scene {
    furnace_box_rgb(DVec3::ONE, le, rho)
}

/// Per channel: the image mean, and the standard error of that mean from
/// the noise image (pixels are independent).
fn mean_and_error(r: &ReferenceImage, c: usize) -> (f64, f64) {
    let n = r.image.pixels.len() as f64;
    let mean = r.image.pixels.iter().map(|p| f64::from(p[c])).sum::<f64>() / n;
    let var = r
        .noise
        .pixels
        .iter()
        .map(|p| f64::from(p[c]).powi(2))
        .sum::<f64>();
    (mean, var.sqrt() / n)
}

/// Checks every pixel of `r` against `expected(x, y)` per channel: the
/// image mean within 4 standard errors, and the per-pixel z-scores
/// distributed like a standard normal's where it is robust to the skewed
/// samples of few-sample pixels (median |z| near 0.674, at least 85 %
/// within 2σ), none beyond `z_max`.
fn assert_within_noise(r: &ReferenceImage, expected: impl Fn(u32, u32) -> DVec3, z_max: f64) {
    let (w, h) = (r.image.width, r.image.height);
    let mut zs = Vec::new();
    let mut diff = DVec3::ZERO;
    let mut var = DVec3::ZERO;
    for y in 0..h {
        for x in 0..w {
            let (v, s) = (r.image.get(x, y), r.noise.get(x, y));
            let e = expected(x, y);
            for c in 0..3 {
                let d = f64::from(v[c]) - e[c];
                let s = f64::from(s[c]);
                assert!(s > 0.0, "pixel ({x}, {y}) has no noise estimate");
                let z = d / s;
                assert!(
                    z.abs() < z_max,
                    "pixel ({x}, {y}) channel {c}: {} vs {} (σ {s}, z {z:.2})",
                    v[c],
                    e[c]
                );
                zs.push(z.abs());
                diff[c] += d;
                var[c] += s * s;
            }
        }
    }
    let n = f64::from(w * h);
    for c in 0..3 {
        let (d, se) = (diff[c] / n, var[c].sqrt() / n);
        assert!(d.abs() < 4.0 * se, "channel {c}: mean off by {d} (σ {se})");
    }
    zs.sort_by(f64::total_cmp);
    let median = zs[zs.len() / 2];
    let within2 = zs.iter().filter(|&&z| z < 2.0).count() as f64 / zs.len() as f64;
    assert!((0.45..0.95).contains(&median), "median |z| = {median}");
    assert!(within2 > 0.85, "only {within2} of the pixels within 2σ");
}

#[test]
fn furnace_radiance_is_emission_over_one_minus_reflectance() {
    let le = DVec3::new(0.3, 0.6, 0.9);
    let centre = DVec3::splat(0.5);
    let v = view(centre, DVec3::new(0.4, 0.3, 0.0), DVec3::Y, 90.0, 16);
    let slow = slow_tests(
        "the 256-spp, ρ 0.95 variant of reference::furnace_radiance_is_emission_over_one_minus_reflectance",
    );
    let (spp, rhos): (u32, &[f64]) = if slow {
        (256, &[0.5, 0.8, 0.95])
    } else {
        (64, &[0.5, 0.8])
    };
    for &rho in rhos {
        let scene = furnace(le, rho);
        let r = trace(&scene, &v, &settings(spp, 3));
        let expected = le / (1.0 - rho);
        assert_within_noise(&r, |_, _| expected, 10.0);
        for c in 0..3 {
            let (mean, se) = mean_and_error(&r, c);
            assert!(
                (mean / expected[c] - 1.0).abs() < 0.02,
                "ρ = {rho}: {mean} vs {}",
                expected[c]
            );
            assert!(se > 0.0 && se < 0.01 * expected[c], "σ {se}");
        }
    }
}

#[test]
fn bounce_limit_truncates_the_neumann_series() {
    let le = DVec3::new(0.3, 0.6, 0.9);
    let scene = furnace(le, 0.5);
    let v = view(DVec3::splat(0.5), DVec3::ZERO, DVec3::Y, 60.0, 10);
    let zero = ReferenceSettings {
        max_bounces: Some(0),
        ..settings(8, 1)
    };
    let r = trace(&scene, &v, &zero);
    for (p, s) in r.image.pixels.iter().zip(&r.noise.pixels) {
        for c in 0..3 {
            assert!((f64::from(p[c]) - le[c]).abs() < 1e-6, "{p:?}");
            assert!(s[c] < 1e-6);
        }
    }
    // One bounce: every direction sees an emitter, so L = L_e (1 + ρ).
    let one = ReferenceSettings {
        max_bounces: Some(1),
        ..settings(64, 1)
    };
    let r = trace(&scene, &v, &one);
    assert_within_noise(&r, |_, _| le * 1.5, 10.0);
}

/// Two parallel unit squares at distance 1: the emitter above (facing down,
/// E = 1, black), the receiver below (facing up, ρ = 0.5).
fn two_squares(double_sided_receiver: bool) -> Scene {
    let p = DVec3::new;
    let emitter = [
        p(-0.5, -0.5, 1.),
        p(-0.5, 0.5, 1.),
        p(0.5, 0.5, 1.),
        p(0.5, -0.5, 1.),
    ];
    let receiver = [
        p(-0.5, -0.5, 0.),
        p(0.5, -0.5, 0.),
        p(0.5, 0.5, 0.),
        p(-0.5, 0.5, 0.),
    ];
    let le = DVec3::splat(1.0 / PI);
    let rho = DVec3::splat(0.5);
    let mut tris = Vec::new();
    for (k, q, rho, le) in [
        (0, emitter, DVec3::ZERO, le),
        (1, receiver, rho, DVec3::ZERO),
    ] {
        for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            tris.push(InputTriangle {
                positions: t,
                material: k,
                surface: k,
                reflectance: rho,
                emitted_radiance: le,
                origin: Default::default(),
            });
        }
    }
    let materials = vec![
        Material {
            name: "emitter".into(),
            reflectance: DVec3::ZERO,
            emitted_radiance: le,
            double_sided: false,
        },
        Material {
            name: "receiver".into(),
            reflectance: rho,
            emitted_radiance: DVec3::ZERO,
            double_sided: double_sided_receiver,
        },
    ];
    let surfaces = ["emitter", "receiver"]
        .iter()
        .enumerate()
        .map(|(k, n)| Surface {
            name: n.to_string(),
            node: k,
        })
        .collect();
    Scene::build(tris, materials, surfaces, vec![], vec![]).unwrap()
}

#[test]
fn parallel_squares_match_howell_c11_and_lambert() {
    let scene = two_squares(false);
    // From 0.9 above the receiver, looking straight down, with a field of
    // view that makes the 40-pixel image span [-1, 1]² on the receiver's
    // plane: pixels 10..30 cover the receiver exactly, 0.05 m each.
    let fov = 2.0 * (1.0f64 / 0.9).atan().to_degrees();
    let side = 40;
    let (first, cells) = (10, 20);
    let v = view(DVec3::new(0.0, 0.0, 0.9), DVec3::ZERO, DVec3::Y, fov, side);
    let slow = slow_tests(
        "the 4096-spp variant of reference::parallel_squares_match_howell_c11_and_lambert",
    );
    let spp = if slow { 4096 } else { 256 };
    let r = trace(&scene, &v, &settings(spp, 11));
    let emitter = scene.patches[scene.triangles[0].front_patch as usize].vertices();
    // The image-plane point (px, py) maps to the receiver point under it.
    let ground = |px: f64, py: f64| {
        let (o, d) = v.ray(px, py);
        o + d * (-o.z / d.z)
    };
    let pixel_value = |x: u32, y: u32| {
        // Lambert's point factor averaged over a 4 × 4 grid of the pixel.
        let mut f = 0.0;
        for j in 0..4 {
            for i in 0..4 {
                let q = ground(
                    f64::from(x) + (i as f64 + 0.5) / 4.0,
                    f64::from(y) + (j as f64 + 0.5) / 4.0,
                );
                f += form_factor_point_polygon(q, DVec3::Z, emitter);
            }
        }
        DVec3::splat(0.5 * f / 16.0 / PI)
    };
    let inside = first..first + cells;
    let count = f64::from(cells * cells);
    let mut area_mean = 0.0;
    let mut expected_mean = 0.0;
    let mut var = 0.0;
    for y in 0..side {
        for x in 0..side {
            let value = f64::from(r.image.get(x, y)[1]);
            if inside.contains(&x) && inside.contains(&y) {
                area_mean += value / count;
                expected_mean += pixel_value(x, y)[1] / count;
                var += (f64::from(r.noise.get(x, y)[1]) / count).powi(2);
            } else {
                // At most a stray sample on the receiver's very edge (the
                // BVH's f32 intersection test).
                let howell = 0.5 * 0.199825 / PI;
                assert!(
                    value < 2.0 * howell / f64::from(spp),
                    "pixel ({x}, {y}) outside the receiver shows {value}"
                );
            }
        }
    }
    // Howell C-11: F = 0.199825 between unit squares at distance 1. The
    // Lambert pixel values must agree with it (a check of the test itself).
    let howell = 0.5 * 0.199825 / PI;
    assert!(
        (expected_mean / howell - 1.0).abs() < 2e-3,
        "{expected_mean}"
    );
    let se = var.sqrt();
    assert!(
        (area_mean - howell).abs() < 4.0 * se,
        "area mean {area_mean} vs ρF E/π = {howell} (σ {se})"
    );
    assert!(
        se < 0.01 * howell,
        "σ {se} too large for a meaningful check"
    );
    // Pixel by pixel, against Lambert.
    let receiver_only = ReferenceImage {
        image: crop(&r.image, first, cells),
        noise: crop(&r.noise, first, cells),
        stats: r.stats.clone(),
    };
    assert_within_noise(
        &receiver_only,
        |x, y| pixel_value(x + first, y + first),
        8.0,
    );

    // From below, the receiver shows its back: black, without noise.
    let below = view(DVec3::new(0.0, 0.0, -0.9), DVec3::ZERO, DVec3::Y, fov, 8);
    let r = trace(&scene, &below, &settings(4, 1));
    assert!(r.image.pixels.iter().all(|p| *p == [0.0; 3]));
    assert!(r.noise.pixels.iter().all(|p| *p == [0.0; 3]));
    // A double-sided receiver shows its lit front from above as before and
    // its unlit back (nothing emits below) as black.
    let scene = two_squares(true);
    let r = trace(&scene, &below, &settings(4, 1));
    assert!(r.image.pixels.iter().all(|p| *p == [0.0; 3]));
    let r = trace(&scene, &v, &settings(64, 2));
    let centre = f64::from(r.image.get(20, 20)[0]);
    let e = pixel_value(20, 20)[0];
    let s = f64::from(r.noise.get(20, 20)[0]);
    assert!((centre - e).abs() < 5.0 * s, "{centre} vs {e} (σ {s})");
}

fn crop(f: &Frame, start: u32, side: u32) -> Frame {
    let mut pixels = Vec::new();
    for y in start..start + side {
        for x in start..start + side {
            pixels.push(f.get(x, y));
        }
    }
    Frame {
        width: side,
        height: side,
        pixels,
    }
}

fn cornell(side: u32) -> (Scene, View) {
    let scene = bundled_scene("cornell-box.gltf");
    let o = ViewOverrides {
        width: Some(side),
        height: Some(side),
        ..Default::default()
    };
    let v = View::resolve(scene.cameras.first(), scene.bounds, &o).unwrap();
    (scene, v)
}

/// Mean over pixels and channels of `f(image value, noise value, i)`.
fn mean_over(r: &ReferenceImage, f: impl Fn(f64, f64, usize) -> f64) -> f64 {
    let mut sum = 0.0;
    for (i, (p, s)) in r.image.pixels.iter().zip(&r.noise.pixels).enumerate() {
        for c in 0..3 {
            sum += f(f64::from(p[c]), f64::from(s[c]), 3 * i + c);
        }
    }
    sum / (3 * r.image.pixels.len()) as f64
}

#[test]
fn noise_image_predicts_the_real_error() {
    // The image-wide error is dominated by a few dozen pixels on the
    // light's edges, so several short runs are pooled to keep the check
    // itself from being noisy.
    let slow =
        slow_tests("the 64-pixel, 8-run variant of reference::noise_image_predicts_the_real_error");
    let (side, n, runs) = if slow { (64, 64, 8) } else { (48, 32, 4) };
    let (scene, v) = cornell(side);
    let long = trace(&scene, &v, &settings(16 * n, 1000));
    let long_values: Vec<f64> = long
        .image
        .pixels
        .iter()
        .flat_map(|p| p.map(f64::from))
        .collect();
    let long_var = mean_over(&long, |_, s, _| s * s);
    let (mut actual, mut predicted, mut noise_rms) = (0.0, 0.0, 0.0);
    for seed in 0..runs {
        let short = trace(&scene, &v, &settings(n, seed));
        // E[(A − R)²] = σ_A² + σ_R²: the long run's share is removed below.
        actual += mean_over(&short, |a, _, i| (a - long_values[i]).powi(2)) / runs as f64;
        let var = mean_over(&short, |_, s, _| s * s);
        predicted += var / runs as f64;
        noise_rms += short.stats.noise_rms / runs as f64;
        // The sidecar's figures describe the same images.
        assert_eq!(short.stats.spp, n);
        assert!((short.stats.noise_rms - var.sqrt()).abs() < 1e-9 * var.sqrt().max(1.0));
        let mean = mean_over(&short, |a, _, _| a);
        assert!((short.stats.mean_radiance - mean).abs() < 1e-9);
        assert!((short.stats.relative_noise - var.sqrt() / mean).abs() < 1e-9);
    }
    let actual = (actual - long_var).max(0.0).sqrt();
    let predicted = predicted.sqrt();
    let ratio = actual / predicted;
    assert!(
        (1.0 / 1.5..1.5).contains(&ratio),
        "actual RMS error {actual}, predicted {predicted}"
    );
    // Sixteen times the samples: a quarter of the noise.
    let q = long.stats.noise_rms / noise_rms;
    assert!((0.15..0.35).contains(&q), "noise ratio {q}");
}

#[test]
fn same_seed_same_image_on_any_thread_count() {
    let (scene, v) = cornell(16);
    let run =
        |threads: usize, seed: u64| on_threads(threads, || trace(&scene, &v, &settings(8, seed)));
    let one = run(1, 7);
    let two = run(2, 7);
    let bits = |f: &Frame| -> Vec<u32> { f.pixels.iter().flatten().map(|v| v.to_bits()).collect() };
    assert_eq!(bits(&one.image), bits(&two.image));
    assert_eq!(bits(&one.noise), bits(&two.noise));
    let other = run(2, 8);
    assert_ne!(bits(&one.image), bits(&other.image));
    // Fewer than two samples cannot estimate the noise: refused.
    let err = render_reference(&scene, &v, &settings(1, 0), &Progress::hidden()).unwrap_err();
    assert!(err.to_string().contains("at least 2"), "{err}");
}

#[test]
fn command_line_writes_image_noise_and_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_path("cornell-box.gltf");
    let out = nusselt(
        &[
            "reference",
            scene.to_str().unwrap(),
            "--spp",
            "4",
            "--width",
            "24",
            "--seed",
            "5",
            "-o",
            "refs/cornell.exr",
            "--png",
            "refs/cornell.png",
            "-q",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let refs = dir.path().join("refs");
    let image = nusselt::output::exr::read_image(&refs.join("cornell.exr")).unwrap();
    let noise = nusselt::output::exr::read_image(&refs.join("cornell.noise.exr")).unwrap();
    assert_eq!((image.width, image.height), (24, 24));
    assert_eq!((noise.width, noise.height), (24, 24));
    let stats: ReferenceStats =
        serde_json::from_slice(&std::fs::read(refs.join("cornell.json")).unwrap()).unwrap();
    assert_eq!((stats.spp, stats.seed, stats.width), (4, 5, 24));
    assert!(stats.samples_per_second > 0.0 && stats.relative_noise > 0.0);
    assert!(std::fs::metadata(refs.join("cornell.png")).unwrap().len() > 0);
    // The same view from the library: the same pixels.
    let (scene_data, v) = cornell(24);
    let lib = trace(&scene_data, &v, &settings(4, 5));
    assert_eq!(lib.image, image);
    // No temporary files left behind.
    let names: Vec<String> = std::fs::read_dir(&refs)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 4, "{names:?}");

    let missing = nusselt(
        &["reference", "no-such-scene.gltf", "-o", "x.exr", "-q"],
        dir.path(),
    );
    assert_user_error(&missing, "no-such-scene.gltf");
    assert!(!dir.path().join("x.exr").exists());
    let one = nusselt(
        &[
            "reference",
            scene.to_str().unwrap(),
            "--spp",
            "1",
            "-o",
            "y.exr",
            "-q",
        ],
        dir.path(),
    );
    // A usage error (exit 2), found by the parser before any work.
    let stderr = String::from_utf8_lossy(&one.stderr);
    assert_eq!(one.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.contains("--spp"),
        "{stderr}"
    );
    assert!(!dir.path().join("y.exr").exists());
}

/// The committed point tables, written before the tables went through the
/// `csv` crate, read back and encode to the same bytes: the columns and
/// number formats of `nusselt probe`'s tables did not change.
#[test]
fn committed_point_tables_encode_to_the_same_bytes() {
    use nusselt::lab::points::{encode_table, read_table};
    for name in [
        "cornell-box.points.csv",
        "hard/corridor.points.csv",
        "hard/gallery.points.csv",
        "hard/table-gap.points.csv",
    ] {
        let path = scene_path(name);
        let table = read_table(&path).unwrap();
        assert!(table.len() >= 60, "{name}");
        let text = String::from_utf8(encode_table(&table).unwrap()).unwrap();
        assert_eq!(text, std::fs::read_to_string(&path).unwrap(), "{name}");
    }
}
