//! Punctual lights and the sky as sources of the solution: closed forms at
//! the output vertices (point, spot, directional, uniform sky, sky through
//! a hole), energy in a closed box for every method, sharp point-light
//! shadows carried by constraint edges, and agreement with the path tracer
//! on the bundled example scenes.

use std::f64::consts::PI;

use glam::DVec3;
use nusselt::classic::solve::ClassicMethod;
use nusselt::formfactor::form_factor_point_polygon;
use nusselt::mesh::OutputMesh;
use nusselt::pipeline::Method;
use nusselt::reference::{ProbeSettings, probe_radiosity, random_points};
use nusselt::scene::{LightKind, Lights, PunctualLight, Scene, Sky, cone_falloff};
use nusselt::{LoadOptions, Progress, load_scene, solve};

use crate::fixtures::{assert_light_adds_up, box_faces, painted_lit, preview_settings, scene_path};

/// A square of side `2 s` centred on the origin in the plane y = 0, facing
/// up, an n × n grid.
fn floor(s: f64, n: usize) -> ([DVec3; 4], usize, bool) {
    let p = |x: f64, z: f64| DVec3::new(x, 0.0, z);
    ([p(-s, s), p(s, s), p(s, -s), p(-s, -s)], n, false)
}

fn light(kind: LightKind, position: DVec3, direction: DVec3, intensity: DVec3) -> PunctualLight {
    PunctualLight {
        name: "test".into(),
        kind,
        position,
        direction,
        intensity,
        range: None,
    }
}

fn only(lights: Vec<PunctualLight>) -> Lights {
    Lights {
        punctual: lights,
        sky: None,
    }
}

/// The whole solve at the preview preset.
fn solved(scene: &Scene) -> nusselt::SolveRun {
    solve(scene, &preview_settings(None), &Progress::hidden()).unwrap()
}

/// Asserts H at every vertex of `mesh` against `expected` (relative to
/// the largest expected value, at f32 precision).
fn assert_vertices(mesh: &OutputMesh, what: &str, expected: impl Fn(DVec3) -> DVec3) {
    let scale = (0..mesh.vertex_count())
        .map(|k| expected(mesh.positions[k].as_dvec3()).max_element())
        .fold(0.0, f64::max);
    assert!(scale > 0.0, "{what}: nothing lit");
    for k in 0..mesh.vertex_count() {
        let x = mesh.positions[k].as_dvec3();
        let (got, want) = (mesh.irradiance[k].as_dvec3(), expected(x));
        assert!(
            (got - want).abs().max_element() <= 2e-5 * scale,
            "{what}: vertex {k} at {x}: H {got}, closed form {want}"
        );
    }
}

#[test]
fn a_point_light_over_a_plane_gives_i_cos3_over_h2() {
    let (h, i) = (1.2, DVec3::new(10.0, 5.0, 2.0));
    let at = DVec3::new(0.3, h, -0.2);
    let scene = painted_lit(
        &[floor(2.0, 4)],
        0.5,
        0.0,
        only(vec![light(LightKind::Point, at, DVec3::NEG_Y, i)]),
    );
    let run = solved(&scene);
    assert_light_adds_up(&scene, &run.mesh, "point light");
    assert_vertices(&run.mesh, "point light", |x| {
        let r = (at - x).length();
        let cos = h / r;
        i * cos.powi(3) / (h * h)
    });
    // Its power on the plane (the report's lights) is the integral of the
    // same, within the elements' sampling.
    let exact = plane_integral(2.0, |x| {
        let r = (at - x).length();
        i.x * (h / r).powi(3) / (h * h)
    });
    let lights = run.report.power.lights[0];
    assert!(
        (lights / exact - 1.0).abs() < 0.01,
        "{lights} against {exact}"
    );
}

/// ∫ f over the square [−s, s]² of the plane y = 0 (midpoint rule).
fn plane_integral(s: f64, f: impl Fn(DVec3) -> f64) -> f64 {
    let n = 800;
    let d = 2.0 * s / n as f64;
    let mut sum = 0.0;
    for a in 0..n {
        for b in 0..n {
            let x = DVec3::new(-s + (a as f64 + 0.5) * d, 0.0, -s + (b as f64 + 0.5) * d);
            sum += f(x) * d * d;
        }
    }
    sum
}

#[test]
fn a_spot_light_follows_the_spec_cone_on_a_plane() {
    let (h, i) = (1.5, DVec3::splat(8.0));
    let (inner, outer) = (0.3f64, 0.6f64);
    let at = DVec3::new(0.0, h, 0.0);
    let kind = LightKind::Spot {
        cos_inner: inner.cos(),
        cos_outer: outer.cos(),
    };
    let scene = painted_lit(
        &[floor(2.0, 6)],
        0.5,
        0.0,
        only(vec![light(kind, at, DVec3::NEG_Y, i)]),
    );
    let run = solved(&scene);
    let expected = |x: DVec3| {
        let r = (at - x).length();
        let cos = h / r;
        i * cos.powi(3) / (h * h) * cone_falloff(cos, inner.cos(), outer.cos())
    };
    assert_vertices(&run.mesh, "spot light", expected);
    // Inside the inner cone, outside the outer, and on the ramp between.
    let radius = |k: usize| {
        let p = run.mesh.positions[k].as_dvec3();
        DVec3::new(p.x, 0.0, p.z).length()
    };
    let ramp = (0..run.mesh.vertex_count())
        .filter(|&k| (h * inner.tan()..h * outer.tan()).contains(&radius(k)))
        .count();
    let dark = (0..run.mesh.vertex_count())
        .filter(|&k| radius(k) > h * outer.tan() && run.mesh.irradiance[k].max_element() == 0.0)
        .count();
    assert!(ramp > 0 && dark > 0, "ramp {ramp}, dark {dark}");
}

#[test]
fn a_directional_light_on_a_tilted_plane_gives_e_cos() {
    // The floor tilted 30° about z.
    let (sin, cos) = 30f64.to_radians().sin_cos();
    let tilt = |p: DVec3| DVec3::new(p.x * cos - p.y * sin, p.x * sin + p.y * cos, p.z);
    let (q, n, lamp) = floor(1.0, 3);
    let e = DVec3::new(2.0, 1.5, 1.0);
    let scene = painted_lit(
        &[(q.map(tilt), n, lamp)],
        0.5,
        0.0,
        only(vec![light(
            LightKind::Directional,
            DVec3::ZERO,
            DVec3::NEG_Y,
            e,
        )]),
    );
    let run = solved(&scene);
    assert_vertices(&run.mesh, "sun", |_| e * cos);
}

fn uniform_sky(l: DVec3) -> Lights {
    Lights {
        punctual: Vec::new(),
        sky: Some(Sky::Uniform(l)),
    }
}

#[test]
fn a_uniform_sky_gives_pi_l_on_an_open_plane() {
    let l = DVec3::new(0.3, 0.4, 0.6);
    let scene = painted_lit(&[floor(1.0, 3)], 0.5, 0.0, uniform_sky(l));
    let run = solved(&scene);
    assert_vertices(&run.mesh, "open sky", |_| PI * l);
    let lights = run.report.power.lights;
    assert!(
        (lights[2] / (PI * l.z * 4.0) - 1.0).abs() < 1e-9,
        "{lights:?}"
    );
}

/// A closed 2 × 1 × 2 m box, faces inward, ρ = 0 (no bounce), whose
/// ceiling has a square hole of side `hole` in its middle.
fn box_with_skylight(hole: f64) -> Vec<([DVec3; 4], usize, bool)> {
    let (lo, hi) = (DVec3::new(-1.0, 0.0, -1.0), DVec3::new(1.0, 1.0, 1.0));
    let mut quads: Vec<([DVec3; 4], usize, bool)> = box_faces(lo, hi)
        .into_iter()
        .map(|q| ([q[0], q[3], q[2], q[1]], 4, false))
        .filter(|(q, _, _)| !q.iter().all(|p| p.y == 1.0))
        .collect();
    // The ceiling around the hole, four quads facing down.
    let h = hole / 2.0;
    let c = |x: f64, z: f64| DVec3::new(x, 1.0, z);
    for (x0, x1, z0, z1) in [
        (-1.0, 1.0, -1.0, -h),
        (-1.0, 1.0, h, 1.0),
        (-1.0, -h, -h, h),
        (h, 1.0, -h, h),
    ] {
        quads.push(([c(x0, z0), c(x1, z0), c(x1, z1), c(x0, z1)], 2, false));
    }
    quads
}

#[test]
fn the_sky_through_a_hole_matches_the_holes_form_factor() {
    let l = DVec3::splat(1.0);
    let hole = 0.8;
    let scene = painted_lit(&box_with_skylight(hole), 0.0, 0.0, uniform_sky(l));
    // Many sky rays: the stratified estimate's own error (about 3 % at
    // the corners, where the opening is smallest) below the check's.
    let mut settings = preview_settings(None);
    settings.hierarchical.accuracy.sky_rays = 4096;
    let run = solve(&scene, &settings, &Progress::hidden()).unwrap();
    let h = hole / 2.0;
    // Counter-clockwise seen from below.
    let polygon = [
        DVec3::new(-h, 1.0, -h),
        DVec3::new(h, 1.0, -h),
        DVec3::new(h, 1.0, h),
        DVec3::new(-h, 1.0, h),
    ];
    let (mut worst, mut sum, mut squares, mut count) = (0.0f64, 0.0, 0.0, 0);
    for k in 0..run.mesh.vertex_count() {
        let x = run.mesh.positions[k].as_dvec3();
        if !(x.y == 0.0 && run.mesh.normals[k].y > 0.5) {
            continue;
        }
        let exact = PI * l.x * form_factor_point_polygon(x, DVec3::Y, &polygon);
        let got = f64::from(run.mesh.irradiance[k].x);
        let e = got / exact - 1.0;
        worst = worst.max(e.abs());
        sum += e;
        squares += e * e;
        count += 1;
    }
    let bias = sum / count as f64;
    let rms = (squares / count as f64).sqrt();
    assert!(count > 20, "{count} floor vertices");
    eprintln!("sky through a hole: rms {rms:.4}, worst {worst:.4}, bias {bias:.4}");
    assert!(
        rms < 0.03 && worst < 0.08 && bias.abs() < 0.01,
        "rms {rms}, worst {worst}, bias {bias}"
    );
}

#[test]
fn a_point_light_in_a_closed_box_adds_up_for_every_method() {
    let i = DVec3::new(3.0, 2.0, 1.0);
    let quads: Vec<([DVec3; 4], usize, bool)> = box_faces(DVec3::ZERO, DVec3::splat(2.0))
        .into_iter()
        .map(|q| ([q[0], q[3], q[2], q[1]], 3, false))
        .collect();
    let at = DVec3::new(0.7, 1.2, 0.9);
    let scene = painted_lit(
        &quads,
        0.6,
        0.0,
        only(vec![light(LightKind::Point, at, DVec3::NEG_Y, i)]),
    );
    for method in [
        Method::Hierarchical,
        Method::Classic(ClassicMethod::Jacobi),
        Method::Classic(ClassicMethod::Shooting),
    ] {
        let mut settings = preview_settings(None);
        settings.method = method;
        let run = solve(&scene, &settings, &Progress::hidden()).unwrap();
        let power = &run.report.power;
        for c in 0..3 {
            // All of 4π I lands on the walls...
            let sent = 4.0 * PI * i[c];
            assert!(
                (power.lights[c] / sent - 1.0).abs() < 0.01,
                "{method:?}: lights {} of {sent}",
                power.lights[c]
            );
            // ... and is absorbed after its bounces.
            let ratio = power.absorbed[c] / power.emitted[c];
            assert!(
                (ratio - 1.0).abs() < 0.005,
                "{method:?}: absorbed/emitted {ratio}"
            );
        }
    }
}

#[test]
fn a_point_lights_shadow_edge_is_a_constraint_line() {
    // A 0.6 m square slab (2 cm thick) whose top is 0.5 m over the floor,
    // the light 1.5 m over its centre: the top's edges cast the shadow, a
    // square of side 0.6 × 1.5 / 1.0 = 0.9 m.
    let y = 0.5;
    let s = 0.3;
    let at = DVec3::new(0.0, 1.5, 0.0);
    let mut quads = vec![floor(1.5, 3)];
    let slab = box_faces(DVec3::new(-s, y - 0.02, -s), DVec3::new(s, y, s));
    quads.extend(slab.into_iter().map(|q| (q, 1, false)));
    let scene = painted_lit(
        &quads,
        0.5,
        0.0,
        only(vec![light(
            LightKind::Point,
            at,
            DVec3::NEG_Y,
            DVec3::splat(5.0),
        )]),
    );
    let run = solved(&scene);
    let mesh = &run.mesh;
    let half = s * at.y / (at.y - y);
    // Signed distance outside the shadow square (negative inside).
    let outside = |k: u32| {
        let p = mesh.positions[k as usize].as_dvec3();
        p.x.abs().max(p.z.abs()) - half
    };
    let tol = 1e-5;
    let mut on_line = 0;
    for t in &mesh.triangles {
        let p = mesh.positions[t[0] as usize];
        if p.y != 0.0 {
            continue;
        }
        let d = t.map(outside);
        let inside = d.iter().any(|&d| d < -tol);
        let lit = d.iter().any(|&d| d > tol);
        assert!(
            !(inside && lit),
            "a floor triangle straddles the shadow edge: {d:?}"
        );
        on_line += d.iter().filter(|d| d.abs() <= tol).count();
    }
    assert!(on_line > 0, "no vertex on the shadow line");
    // Either side of the line the direct light differs by what it brings:
    // just outside, the full I cos³θ / h²; just inside, none of it.
    let direct = |x: DVec3| 5.0 * (at.y / (at - x).length()).powi(3) / (at.y * at.y);
    let (mut inside_max, mut outside_min) = (0.0f64, f64::MAX);
    for k in 0..mesh.vertex_count() as u32 {
        let p = mesh.positions[k as usize].as_dvec3();
        if p.y != 0.0 {
            continue;
        }
        let h = f64::from(mesh.irradiance[k as usize].x);
        let d = outside(k);
        if d < -tol && d > -0.05 {
            inside_max = inside_max.max(h);
        } else if d > tol && d < 0.05 {
            outside_min = outside_min.min(h - direct(p));
        }
    }
    assert!(
        inside_max < 0.25 * direct(DVec3::new(half, 0.0, 0.0)),
        "just inside the shadow: {inside_max}"
    );
    assert!(outside_min > -1e-3, "just outside: {outside_min}");
}

/// Solves a bundled example scene at the preview preset and scores it
/// against path-traced point references: (median, power bias). Without
/// a sky the scene must be closed, and its energy add up.
fn against_the_path_tracer(name: &str, sky: Option<Sky>) -> (f64, f64) {
    let closed = sky.is_none();
    let options = LoadOptions {
        sky: sky.map(std::sync::Arc::new),
        ..LoadOptions::default()
    };
    let scene = load_scene(&scene_path(name), &options).unwrap();
    let run = solved(&scene);
    let points = random_points(&scene, 48, 7);
    let settings = ProbeSettings {
        samples: 2048,
        seed: 3,
        max_bounces: None,
    };
    let table = probe_radiosity(&scene, &points, &settings, &Progress::hidden()).unwrap();
    let (score, _) = nusselt::lab::points::score(&run.mesh, &table).unwrap();
    let power = &run.report.power;
    if closed {
        // Measured 1.0058 at the preview preset, 0.9988 at the default,
        // 1.0002 at high.
        let ratio = power.absorbed[0] / power.emitted[0];
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "{name}: absorbed/emitted {ratio}"
        );
    }
    (score.median, score.power_bias)
}

#[test]
fn the_example_scenes_agree_with_the_path_tracer() {
    let (median, bias) = against_the_path_tracer("spot-room.gltf", None);
    assert!(
        median < 0.05 && bias.abs() < 0.03,
        "spot room: median {median}, bias {bias}"
    );
    let sky = Sky::Uniform(DVec3::new(0.25, 0.32, 0.45));
    let (median, bias) = against_the_path_tracer("courtyard.gltf", Some(sky));
    assert!(
        median < 0.05 && bias.abs() < 0.03,
        "courtyard: median {median}, bias {bias}"
    );
}

#[test]
fn an_environment_map_lights_by_direction() {
    // Bright above the horizon, black below: an open floor facing up sees
    // only the bright half, π L (but for directions within half a texel
    // of the horizon, which weigh 6e-4 of the cosine hemisphere).
    let (w, h) = (128u32, 64u32);
    let l = [0.5f32, 1.0, 2.0];
    let texels = (0..w * h)
        .map(|k| if k / w < h / 2 { l } else { [0.0; 3] })
        .collect();
    let map = nusselt::scene::EnvironmentMap {
        width: w,
        height: h,
        texels,
    };
    let lights = Lights {
        punctual: Vec::new(),
        sky: Some(Sky::Map(map)),
    };
    let scene = painted_lit(&[floor(1.0, 2)], 0.5, 0.0, lights.clone());
    let run = solved(&scene);
    let want = PI * DVec3::from(l.map(f64::from));
    for k in 0..run.mesh.vertex_count() {
        let got = run.mesh.irradiance[k].as_dvec3();
        assert!(
            (got - want).abs().max_element() < 2e-3 * want.max_element(),
            "{got} {want}"
        );
    }
    // Facing down, the floor sees only the black half.
    let (q, n, lamp) = floor(1.0, 2);
    let down = [q[0], q[3], q[2], q[1]];
    let scene = painted_lit(&[(down, n, lamp)], 0.5, 0.0, lights);
    let run = solved(&scene);
    let most = (0..run.mesh.vertex_count())
        .map(|k| run.mesh.irradiance[k].max_element())
        .fold(0.0f32, f32::max);
    assert!(f64::from(most) < 2e-3 * want.max_element(), "{most}");
}

#[test]
fn the_command_line_takes_a_sky_and_refuses_a_bad_one() {
    use crate::fixtures::{assert_user_error, nusselt, scene_arg};
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let out = dir.join("out");
    let frame = nusselt::render::frame::Frame {
        width: 4,
        height: 2,
        pixels: vec![[0.2, 0.3, 0.4]; 8],
    };
    let sky = dir.join("sky.exr");
    std::fs::write(
        &sky,
        nusselt::output::exr::encode_image(
            &frame,
            &nusselt::output::exr::ImageInfo::new(nusselt::output::exr::Quantity::Radiance),
        )
        .unwrap(),
    )
    .unwrap();
    let scene = scene_arg("courtyard.gltf");
    let o = out.to_str().unwrap();
    let solve_with = |flag: &str, value: &str| {
        let args = [
            "solve",
            &scene,
            flag,
            value,
            "-o",
            o,
            "--accuracy",
            "preview",
            "--width",
            "16",
            "--height",
            "9",
            "-q",
        ];
        nusselt(&args, dir)
    };
    for sky in ["0.2,0.3,0.4", sky.to_str().unwrap()] {
        let run = solve_with("--sky", sky);
        assert_eq!(
            run.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
        let lights = report["power"]["lights"][2].as_f64().unwrap();
        assert!(lights > 0.0, "{report}");
    }
    for (flag, value, needle) in [
        ("--sky", "-1,0,0", "not negative"),
        ("--sky", "nan,0,0", "not negative"),
        ("--sky", "missing.exr", "missing.exr"),
        ("--sky-rays", "0", "--sky-rays"),
    ] {
        assert_user_error(&solve_with(flag, value), needle);
    }
}
