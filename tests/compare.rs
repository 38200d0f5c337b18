//! `nusselt compare` and its library (`nusselt::lab::compare`): metrics of
//! synthetic images with known differences, the reference-noise correction,
//! the error images, and the command line's errors and exit codes.

use std::fs;
use std::path::{Path, PathBuf};

use nusselt::Error;
use nusselt::lab::chart::{SCALE_BAR_HEIGHT, SCALE_BAR_MIN_WIDTH, colour_map};
use nusselt::lab::compare::{
    DEFAULT_MAX_ERROR, Named, RELATIVE_EPSILON, compare_files, compare_frames, difference,
    error_images, noise_path, relative_luminance_error,
};
use nusselt::output::exr::{ImageInfo, Quantity, decode_image, encode_image};
use nusselt::render::frame::Frame;

use crate::fixtures::{assert_user_error, nusselt};

/// A `w × h` image of one colour.
fn flat(w: u32, h: u32, rgb: [f32; 3]) -> Frame {
    Frame {
        width: w,
        height: h,
        pixels: vec![rgb; (w * h) as usize],
    }
}

fn named<'a>(path: &'a str, frame: &'a Frame) -> Named<'a> {
    Named {
        path: Path::new(path),
        frame,
    }
}

/// Compares without a noise image.
fn metrics(test: &Frame, reference: &Frame) -> nusselt::lab::compare::Metrics {
    compare_frames(named("t.exr", test), named("r.exr", reference), None).unwrap()
}

fn write_exr(dir: &Path, name: &str, frame: &Frame) -> PathBuf {
    let p = dir.join(name);
    fs::write(
        &p,
        encode_image(frame, &ImageInfo::new(Quantity::Radiance)).unwrap(),
    )
    .unwrap();
    p
}

fn decode_png(bytes: &[u8]) -> image::RgbImage {
    image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .unwrap()
        .to_rgb8()
}

#[test]
fn uniform_offset_gives_exact_metrics() {
    let m = metrics(&flat(5, 3, [2.5; 3]), &flat(5, 3, [2.0; 3]));
    assert_eq!((m.width, m.height, m.pixels), (5, 3, 15));
    assert_eq!(m.noise, None);
    for c in [&m.channels.r, &m.channels.g, &m.channels.b, &m.overall] {
        assert_eq!(c.rmse, 0.5);
        assert_eq!(c.relative_rmse, Some(0.25));
        assert_eq!(c.mean_relative_error, Some(0.25));
        assert_eq!(c.max_abs_error, 0.5);
        assert_eq!((c.max_at.x, c.max_at.y), (0, 0));
        assert_eq!(c.mean_test, 2.5);
        assert_eq!(c.mean_reference, 2.0);
        assert_eq!(c.epsilon, RELATIVE_EPSILON * 2.0);
        assert_eq!(c.noise_rms, None);
        assert_eq!(c.noise_relative_rms, None);
        assert_eq!(c.noise_corrected_rmse, None);
    }
    assert_eq!(m.channels.g.max_at.channel, "G");
    assert_eq!(m.overall.max_at.channel, "R");
    // Missing noise is null in the JSON, not absent.
    let json: serde_json::Value = serde_json::to_value(&m).unwrap();
    assert!(json["overall"]["noise_rms"].is_null());
    assert!(json["overall"]["noise_corrected_rmse"].is_null());
    assert_eq!(json["channels"]["R"]["rmse"], 0.5);
    assert_eq!(json["overall"]["relative_rmse"], 0.25);
}

#[test]
fn identical_images_have_zero_error() {
    let f = Frame {
        width: 3,
        height: 2,
        pixels: (0..6).map(|k| [k as f32, 0.5 * k as f32, 1.0]).collect(),
    };
    let m = metrics(&f, &f);
    for c in [&m.channels.r, &m.channels.g, &m.channels.b, &m.overall] {
        assert_eq!(c.rmse, 0.0);
        assert_eq!(c.max_abs_error, 0.0);
        assert_eq!(c.mean_relative_error, Some(0.0));
        assert_eq!(c.mean_test, c.mean_reference);
    }
}

#[test]
fn single_pixel_difference() {
    let reference = flat(4, 4, [1.0; 3]);
    let mut test = reference.clone();
    test.pixels[4 + 2][1] = 3.0; // x = 2, y = 1, channel G
    let m = metrics(&test, &reference);
    assert_eq!(m.channels.r.rmse, 0.0);
    assert_eq!(m.channels.b.rmse, 0.0);
    assert_eq!(m.channels.g.rmse, 0.5); // sqrt(2² / 16)
    assert_eq!(m.channels.g.relative_rmse, Some(0.5));
    assert_eq!(m.channels.g.mean_relative_error, Some(0.125)); // 2 / 16
    assert_eq!(m.channels.g.max_abs_error, 2.0);
    assert_eq!(m.channels.g.mean_test, 1.125);
    assert_eq!(m.overall.rmse, (4.0f64 / 48.0).sqrt());
    assert_eq!(m.overall.mean_relative_error, Some(2.0 / 48.0));
    assert_eq!(m.overall.max_abs_error, 2.0);
    let at = &m.overall.max_at;
    assert_eq!((at.x, at.y, at.channel.as_str()), (2, 1, "G"));
}

#[test]
fn per_channel_differences() {
    let m = metrics(&flat(2, 2, [1.5, 2.0, 3.0]), &flat(2, 2, [1.0, 2.0, 4.0]));
    assert_eq!(m.channels.r.rmse, 0.5);
    assert_eq!(m.channels.r.relative_rmse, Some(0.5));
    assert_eq!(m.channels.g.rmse, 0.0);
    assert_eq!(m.channels.g.relative_rmse, Some(0.0));
    assert_eq!(m.channels.b.rmse, 1.0);
    assert_eq!(m.channels.b.relative_rmse, Some(0.25));
    assert_eq!(m.channels.b.mean_relative_error, Some(0.25));
    // Pooled: Σd² = 4 × (0.25 + 0 + 1) over 12 values; mean r = 28 / 12.
    assert_eq!(m.overall.rmse, (5.0f64 / 12.0).sqrt());
    assert_eq!(m.overall.mean_reference, 28.0 / 12.0);
    assert_eq!(m.overall.max_abs_error, 1.0);
    assert_eq!(m.overall.max_at.channel, "B");
}

#[test]
fn epsilon_bounds_the_relative_error_of_black_pixels() {
    // R: reference 0 and 4, test 0.25 and 4: mean |r| = 2, ε = 0.02.
    let reference = Frame {
        width: 2,
        height: 1,
        pixels: vec![[0.0, 1.0, 1.0], [4.0, 1.0, 1.0]],
    };
    let mut test = reference.clone();
    test.pixels[0][0] = 0.25;
    let m = metrics(&test, &reference);
    let eps = RELATIVE_EPSILON * 2.0;
    assert_eq!(m.channels.r.epsilon, eps);
    let expected = (0.25 / eps + 0.0) / 2.0;
    let got = m.channels.r.mean_relative_error.unwrap();
    assert!(
        (got - expected).abs() <= 1e-12 * expected,
        "{got} vs {expected}"
    );
    // A black reference channel has no relative errors or relative RMSE.
    let m = metrics(&flat(2, 2, [0.5, 1.0, 1.0]), &flat(2, 2, [0.0, 1.0, 1.0]));
    assert_eq!(m.channels.r.mean_relative_error, None);
    assert_eq!(m.channels.r.relative_rmse, None);
    assert_eq!(m.channels.r.rmse, 0.5);
    assert!(m.overall.relative_rmse.is_some());
}

#[test]
fn reference_noise_is_reported_and_subtracted() {
    let (test, reference) = (flat(3, 3, [2.5; 3]), flat(3, 3, [2.0; 3]));
    let noise = flat(3, 3, [0.3; 3]);
    let m = compare_frames(
        named("t.exr", &test),
        named("r.exr", &reference),
        Some(named("r.noise.exr", &noise)),
    )
    .unwrap();
    assert_eq!(m.noise.as_deref(), Some("r.noise.exr"));
    let s = f64::from(0.3f32);
    for c in [&m.channels.r, &m.channels.g, &m.channels.b, &m.overall] {
        assert_eq!(c.rmse, 0.5);
        let rms = c.noise_rms.unwrap();
        assert!((rms - s).abs() < 1e-15, "{rms}");
        assert!((c.noise_relative_rms.unwrap() - s / 2.0).abs() < 1e-15);
        let corrected = c.noise_corrected_rmse.unwrap();
        assert!((corrected - (0.25 - s * s).sqrt()).abs() < 1e-12);
        assert!((corrected - 0.4).abs() < 1e-6, "{corrected}");
    }
    // Noise larger than the error: the estimate is 0, never NaN.
    let loud = flat(3, 3, [1.0; 3]);
    let m = compare_frames(
        named("t.exr", &test),
        named("r.exr", &reference),
        Some(named("r.noise.exr", &loud)),
    )
    .unwrap();
    assert_eq!(m.overall.noise_corrected_rmse, Some(0.0));
    assert_eq!(m.overall.noise_rms, Some(1.0));
}

#[test]
fn noise_file_beside_the_reference_is_found() {
    assert_eq!(
        noise_path(Path::new("refs/cornell.exr")),
        Path::new("refs/cornell.noise.exr")
    );
    let dir = tempfile::tempdir().unwrap();
    let t = write_exr(dir.path(), "test.exr", &flat(4, 2, [2.5; 3]));
    let r = write_exr(dir.path(), "ref.exr", &flat(4, 2, [2.0; 3]));
    let without = compare_files(&t, &r).unwrap();
    assert_eq!(without.metrics.noise, None);
    assert_eq!(without.metrics.overall.noise_rms, None);
    let n = write_exr(dir.path(), "ref.noise.exr", &flat(4, 2, [0.25, 0.5, 0.0]));
    let with = compare_files(&t, &r).unwrap();
    assert_eq!(with.metrics.noise, Some(n.display().to_string()));
    assert_eq!(with.metrics.channels.r.noise_rms, Some(0.25));
    assert_eq!(with.metrics.channels.g.noise_rms, Some(0.5));
    assert_eq!(with.metrics.channels.g.noise_corrected_rmse, Some(0.0));
    assert_eq!(with.metrics.channels.b.noise_corrected_rmse, Some(0.5));
    assert_eq!(
        with.metrics.channels.r.noise_corrected_rmse,
        Some(0.1875f64.sqrt())
    );
    // A noise image of the wrong size, or with negative values, is an error
    // naming the noise file.
    write_exr(dir.path(), "ref.noise.exr", &flat(2, 2, [0.1; 3]));
    let err = compare_files(&t, &r).unwrap_err().to_string();
    assert!(
        err.contains("ref.noise.exr") && err.contains("2×2"),
        "{err}"
    );
    write_exr(dir.path(), "ref.noise.exr", &flat(4, 2, [0.1, -0.1, 0.1]));
    let err = compare_files(&t, &r).unwrap_err().to_string();
    assert!(
        err.contains("ref.noise.exr") && err.contains("negative"),
        "{err}"
    );
}

#[test]
fn mismatched_sizes_and_non_finite_pixels_are_errors() {
    let err = compare_frames(
        named("small.exr", &flat(2, 2, [1.0; 3])),
        named("big.exr", &flat(3, 2, [1.0; 3])),
        None,
    )
    .unwrap_err();
    assert!(matches!(err, Error::Data { .. }));
    let msg = err.to_string();
    assert!(
        msg.starts_with("small.exr:") && msg.contains("big.exr"),
        "{msg}"
    );
    assert!(msg.contains("2×2") && msg.contains("3×2"), "{msg}");

    let mut nan = flat(3, 3, [1.0; 3]);
    nan.pixels[3 + 1][2] = f32::NAN;
    let msg = compare_frames(
        named("t.exr", &nan),
        named("r.exr", &flat(3, 3, [1.0; 3])),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(msg.starts_with("t.exr:") && msg.contains("NaN"), "{msg}");
    assert!(msg.contains("(1, 1)") && msg.contains("channel B"), "{msg}");

    let mut inf = flat(3, 3, [1.0; 3]);
    inf.pixels[0][0] = f32::INFINITY;
    let msg = compare_frames(
        named("t.exr", &flat(3, 3, [1.0; 3])),
        named("r.exr", &inf),
        None,
    )
    .unwrap_err()
    .to_string();
    assert!(msg.starts_with("r.exr:") && msg.contains("inf"), "{msg}");
}

#[test]
fn missing_and_unreadable_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let r = write_exr(dir.path(), "ref.exr", &flat(2, 2, [1.0; 3]));
    let err = compare_files(&dir.path().join("absent.exr"), &r).unwrap_err();
    assert!(matches!(err, Error::Input { .. }));
    assert!(err.to_string().contains("absent.exr"));
    let junk = dir.path().join("junk.exr");
    fs::write(&junk, b"not an image").unwrap();
    let err = compare_files(&r, &junk).unwrap_err().to_string();
    assert!(err.contains("junk.exr"), "{err}");
}

#[test]
fn error_exr_is_the_signed_difference() {
    let reference = Frame {
        width: 3,
        height: 2,
        pixels: (0..6)
            .map(|k| [k as f32 * 0.7, 1.0, 2.0 - k as f32])
            .collect(),
    };
    let test = Frame {
        width: 3,
        height: 2,
        pixels: (0..6)
            .map(|k| [1.0, k as f32 * 0.3, 2.0 + 0.1 * k as f32])
            .collect(),
    };
    let d = difference(&test, &reference);
    for (k, p) in d.pixels.iter().enumerate() {
        for (c, v) in p.iter().enumerate() {
            assert_eq!(*v, test.pixels[k][c] - reference.pixels[k][c]);
        }
    }
    assert!(d.pixels.iter().any(|p| p.iter().any(|v| *v < 0.0)));
    let images = error_images(&test, &reference, DEFAULT_MAX_ERROR).unwrap();
    let back = decode_image(&images.exr, Path::new("error.exr")).unwrap();
    assert_eq!(back, d);
}

#[test]
fn error_png_shows_the_relative_error_and_a_scale_bar() {
    // Reference grey 1; the left half of the test is 10 % brighter.
    let (w, h) = (40, 30);
    let reference = flat(w, h, [1.0; 3]);
    let mut test = reference.clone();
    for y in 0..h {
        for x in 0..w / 2 {
            test.pixels[(y * w + x) as usize] = [1.1; 3];
        }
    }
    let rel = relative_luminance_error(&test, &reference);
    assert!((rel[0] - 0.1).abs() < 1e-6, "{}", rel[0]);
    assert_eq!(rel[(w - 1) as usize], 0.0);

    let images = error_images(&test, &reference, 0.2).unwrap();
    let png = decode_png(&images.png);
    let canvas_w = w.max(SCALE_BAR_MIN_WIDTH);
    assert_eq!(png.dimensions(), (canvas_w, h + SCALE_BAR_HEIGHT));
    let left = (canvas_w - w) / 2;
    let close = |a: [u8; 3], b: [u8; 3]| a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= 2);
    // 10 % of a 20 % scale: the middle of the colour map; 0: its bottom.
    let brighter = png.get_pixel(left + 3, 5).0;
    assert!(close(brighter, colour_map(0.5)), "{brighter:?}");
    let equal = png.get_pixel(left + w - 3, h - 5).0;
    assert!(close(equal, colour_map(0.0)), "{equal:?}");
    // The bar: colours from the dark bottom to the bright top of the map,
    // and text (dark grey or black pixels) below it.
    let bar: Vec<[u8; 3]> = (h..h + SCALE_BAR_HEIGHT)
        .flat_map(|y| (0..canvas_w).map(move |x| (x, y)))
        .map(|(x, y)| png.get_pixel(x, y).0)
        .collect();
    let background = nusselt::lab::chart::BACKGROUND;
    assert!(bar.iter().filter(|p| **p != background).count() > 1000);
    assert!(bar.iter().any(|p| close(*p, colour_map(0.02))));
    assert!(bar.iter().any(|p| close(*p, colour_map(0.98))));

    // A different maximum changes the colours of the same error.
    let png = decode_png(&error_images(&test, &reference, 0.1).unwrap().png);
    assert!(close(png.get_pixel(left + 3, 5).0, colour_map(1.0)));
    // A wide image keeps its width.
    let wide = flat(500, 4, [1.0; 3]);
    let png = decode_png(&error_images(&wide, &wide, 0.2).unwrap().png);
    assert_eq!(png.dimensions(), (500, 4 + SCALE_BAR_HEIGHT));
    // The scale maximum must be positive.
    assert!(error_images(&test, &reference, 0.0).is_err());
    assert!(error_images(&test, &reference, f64::NAN).is_err());
}

#[test]
fn error_images_are_deterministic() {
    let reference = flat(16, 8, [0.5, 0.25, 1.0]);
    let mut test = reference.clone();
    test.pixels[9] = [0.6, 0.2, 1.1];
    let a = error_images(&test, &reference, 0.2).unwrap();
    let b = error_images(&test, &reference, 0.2).unwrap();
    assert_eq!(a, b);
}

#[test]
fn cli_prints_metrics_and_writes_error_images() {
    let dir = tempfile::tempdir().unwrap();
    let mut test = flat(6, 4, [2.5; 3]);
    test.pixels[5] = [2.0, 2.5, 2.5];
    write_exr(dir.path(), "test.exr", &test);
    write_exr(dir.path(), "ref.exr", &flat(6, 4, [2.0; 3]));

    // Without -o: metrics only, no file written.
    let out = nusselt(&["compare", "test.exr", "ref.exr"], dir.path());
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let m: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(m["channels"]["G"]["rmse"], 0.5);
    assert_eq!(m["channels"]["G"]["relative_rmse"], 0.25);
    assert_eq!(m["pixels"], 24);
    assert!(m["noise"].is_null());
    assert_eq!(m["channels"]["R"]["max_at"]["x"], 0);
    let r_rmse = m["channels"]["R"]["rmse"].as_f64().unwrap();
    // serde_json's default float parser may be off by one unit in the last
    // place, so this one is compared with a tolerance.
    let expected = (0.25f64 * 23.0 / 24.0).sqrt();
    assert!((r_rmse - expected).abs() < 1e-15, "{r_rmse}");
    let mut names: Vec<_> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert_eq!(names, ["ref.exr", "test.exr"]);

    // With -o: the same metrics, and the error images.
    let out = nusselt(
        &[
            "compare",
            "test.exr",
            "ref.exr",
            "-o",
            "cmp",
            "--max-error",
            "0.5",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let again: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(again, m);
    let saved: serde_json::Value =
        serde_json::from_slice(&fs::read(dir.path().join("cmp/metrics.json")).unwrap()).unwrap();
    assert_eq!(saved, m);
    let diff = nusselt::output::exr::read_image(&dir.path().join("cmp/error.exr")).unwrap();
    assert_eq!(diff.get(5, 0), [0.0, 0.5, 0.5]);
    assert_eq!(diff.get(0, 0), [0.5, 0.5, 0.5]);
    let png = decode_png(&fs::read(dir.path().join("cmp/error.png")).unwrap());
    assert_eq!(
        png.dimensions(),
        (SCALE_BAR_MIN_WIDTH, 4 + SCALE_BAR_HEIGHT)
    );
}

#[test]
fn cli_errors_and_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    write_exr(dir.path(), "a.exr", &flat(4, 4, [1.0; 3]));
    write_exr(dir.path(), "small.exr", &flat(2, 4, [1.0; 3]));
    let mut nan = flat(4, 4, [1.0; 3]);
    nan.pixels[7][0] = f32::NAN;
    write_exr(dir.path(), "nan.exr", &nan);

    let out = nusselt(&["compare", "small.exr", "a.exr", "-o", "o"], dir.path());
    assert_user_error(&out, "small.exr");
    assert!(!dir.path().join("o").join("error.png").exists());
    assert_user_error(
        &nusselt(&["compare", "a.exr", "nan.exr"], dir.path()),
        "nan.exr",
    );
    assert_user_error(
        &nusselt(&["compare", "nope.exr", "a.exr"], dir.path()),
        "nope.exr",
    );
    assert_user_error(
        &nusselt(&["compare", "a.exr", "nope.exr"], dir.path()),
        "nope.exr",
    );
    assert_user_error(
        &nusselt(
            &["compare", "a.exr", "a.exr", "--max-error", "0"],
            dir.path(),
        ),
        "--max-error",
    );
    // Usage errors exit with 2.
    assert_eq!(
        nusselt(&["compare", "a.exr"], dir.path()).status.code(),
        Some(2)
    );
}
