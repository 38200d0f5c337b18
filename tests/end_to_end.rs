//! `nusselt solve` end to end: every output is written, reads back, and
//! agrees with the solution and with energy conservation.

use std::fs;
use std::path::Path;

use glam::DVec3;
use nusselt::output;
use nusselt::render::{RenderSettings, render};
use nusselt::report::Report;

use crate::fixtures::{
    assert_light_adds_up, assert_user_error, bundled_scene, gltf_json, inward_box, nusselt,
    nusselt_ok, scene_arg, scene_path,
};

fn read_report(dir: &Path) -> Report {
    serde_json::from_slice(&fs::read(dir.join("report.json")).unwrap()).unwrap()
}

#[test]
fn cornell_box_outputs_agree_with_the_solution() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = scene_arg("cornell-box.gltf");
    let out = nusselt(
        &[
            "solve",
            &scene_path,
            "-q",
            "-o",
            "out",
            "--width",
            "48",
            "--height",
            "48",
            "--spp",
            "4",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let res = dir.path().join("out");
    let mut names: Vec<String> = fs::read_dir(&res)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "baked.bin",
            "baked.gltf",
            "render.exr",
            "render.png",
            "report.json",
            "solution.exr"
        ]
    );

    let report = read_report(&res);
    let mesh = output::exr::read_solution(&res.join("solution.exr")).unwrap();
    mesh.validate().unwrap();
    assert_eq!(mesh.vertex_count(), report.counts.output_vertices);
    assert_eq!(mesh.triangles.len(), report.counts.output_triangles);
    assert!(report.convergence.converged);
    assert!(report.counts.elements >= report.counts.patches);

    // Energy: what the surfaces absorb never exceeds what is emitted, and in
    // this nearly closed box (open front only) most of it is absorbed.
    let scene = bundled_scene("cornell-box.gltf");
    let phi = scene.emitted_power();
    for c in 0..3 {
        assert!((report.power.emitted[c] - phi[c]).abs() < 1e-6 * phi[c]);
        let absorbed = report.power.absorbed[c];
        assert!(
            absorbed <= phi[c] * 1.02,
            "channel {c}: {absorbed} > {}",
            phi[c]
        );
        assert!(
            absorbed > 0.6 * phi[c],
            "channel {c}: {absorbed} of {}",
            phi[c]
        );
    }

    // The bake carries the same vertices and radiosity.
    let (doc, buffers, _) = gltf::import(res.join("baked.gltf")).unwrap();
    let baked = crate::bake::reassemble(&doc, &buffers);
    assert_eq!(baked.positions.len(), mesh.vertex_count());
    for (p, q) in baked.positions.iter().zip(&mesh.positions) {
        assert!((*p - *q).abs().max_element() < 1e-5, "{p} vs {q}");
    }
    assert_eq!(baked.radiosity, mesh.radiosity);
    assert_eq!(baked.triangles, mesh.triangles);

    // The render is exactly what rendering the solution gives.
    let frame = output::exr::read_image(&res.join("render.exr")).unwrap();
    let view = report.view.clone().unwrap();
    assert_eq!((frame.width, frame.height), (48, 48));
    let again = render(
        &mesh,
        &view,
        &RenderSettings::with_samples(4, 0),
        &nusselt::util::progress::Progress::hidden(),
    );
    assert_eq!(frame, again);

    // Colour bleeding: the white floor is redder near the red (left, +x)
    // wall than near the green one, and greener near the green one.
    let floor: Vec<usize> = (0..mesh.vertex_count())
        .filter(|&k| mesh.normals[k].y > 0.99 && mesh.positions[k].y < 0.01)
        .collect();
    assert!(!floor.is_empty());
    let near = |x_lo: f32, x_hi: f32| {
        let pick: Vec<&usize> = floor
            .iter()
            .filter(|&&k| (x_lo..x_hi).contains(&mesh.positions[k].x))
            .collect();
        let b: DVec3 = pick
            .iter()
            .map(|&&k| mesh.radiosity[k].as_dvec3())
            .sum::<DVec3>()
            / pick.len() as f64;
        b.x / b.y
    };
    let red_side = near(0.45, 0.56);
    let green_side = near(0.0, 0.1);
    assert!(
        red_side > green_side * 1.05,
        "red/green ratio {red_side} vs {green_side}"
    );
}

#[test]
fn closed_box_conserves_energy_and_is_thread_independent() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("box.gltf");
    fs::write(
        &p,
        gltf_json(&inward_box(2.0, [1.0, 0.8, 0.6], [0.6, 0.5, 0.4])),
    )
    .unwrap();
    let p = p.to_string_lossy().into_owned();
    let args = |o: &'static str, t: &'static str| {
        vec![
            "solve",
            &p,
            "-q",
            "-o",
            o,
            "--threads",
            t,
            // The matrix's closure is checked below: a classic method.
            "--method",
            "jacobi",
            "--element-size",
            "0.25",
            "--width",
            "16",
            "--height",
            "16",
        ]
        .into_iter()
        .map(str::to_owned)
        .collect::<Vec<String>>()
    };
    for (o, t) in [("one", "1"), ("two", "2")] {
        let a = args(o, t);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let out = nusselt(&a, dir.path());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let one = dir.path().join("one");
    let two = dir.path().join("two");
    for f in ["solution.exr", "render.exr", "baked.bin"] {
        assert_eq!(
            fs::read(one.join(f)).unwrap(),
            fs::read(two.join(f)).unwrap(),
            "{f}"
        );
    }
    // In a closed box everything emitted is eventually absorbed; the
    // centroid-collocation form factors close to within a few per cent.
    let r = read_report(&one);
    for c in 0..3 {
        let ratio = r.power.absorbed[c] / r.power.emitted[c];
        assert!(
            (ratio - 1.0).abs() < 0.03,
            "channel {c}: absorbed/emitted = {ratio}"
        );
    }
    let row_sum = r
        .mean_row_sum
        .expect("a classic solve reports its row sums");
    assert!((row_sum - 1.0).abs() < 0.03, "mean row sum {row_sum}");
}

#[test]
fn every_method_and_snapshots_on_the_goral_box() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("goral-box.gltf");
    let mut totals = Vec::new();
    for method in ["direct", "jacobi", "gauss-seidel", "shooting"] {
        let out = nusselt(
            &[
                "solve",
                &scene,
                "-q",
                "-o",
                method,
                "--method",
                method,
                "--element-size",
                "0.2",
                "--width",
                "16",
                "--height",
                "16",
                "--spp",
                "1",
                "--snapshots",
                "1,2",
            ],
            dir.path(),
        );
        assert!(
            out.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let res = dir.path().join(method);
        let r = read_report(&res);
        assert_eq!(r.method, method);
        assert!(r.convergence.converged, "{method}");
        assert!(!r.convergence.history.is_empty());
        for f in [
            "snapshot-00001.png",
            "snapshot-00001.exr",
            "snapshot-00002.png",
            "snapshot-00002.exr",
        ] {
            assert!(res.join(f).exists(), "{method}: {f}");
        }
        totals.push(r.power.radiated);
    }
    // All methods solve the same system: the radiated power agrees.
    for t in &totals {
        for c in 0..3 {
            assert!(
                (t[c] - totals[0][c]).abs() < 1e-4 * totals[0][c],
                "{totals:?}"
            );
        }
    }
}

#[test]
fn render_command_reproduces_the_solve_view() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("goral-box.gltf");
    let args = [
        "solve",
        &scene,
        "-q",
        "-o",
        "res",
        "--accuracy",
        "preview",
        "--width",
        "20",
        "--height",
        "12",
        "--spp",
        "4",
    ];
    assert!(nusselt(&args, dir.path()).status.success());
    let out = nusselt(
        &[
            "render",
            "res/solution.exr",
            "-o",
            "again.exr",
            "--png",
            "again.png",
            "--spp",
            "4",
            "-q",
        ],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let a = output::exr::read_image(&dir.path().join("res/render.exr")).unwrap();
    let b = output::exr::read_image(&dir.path().join("again.exr")).unwrap();
    assert_eq!(a, b);
    assert_eq!(
        fs::read(dir.path().join("res/render.png")).unwrap(),
        fs::read(dir.path().join("again.png")).unwrap()
    );
    // A missing solution is a clean error.
    let out = nusselt(&["render", "nope/solution.exr", "-o", "x.exr"], dir.path());
    assert_user_error(&out, "nope/solution.exr");
}

#[test]
fn formfactors_command_matches_closed_forms() {
    let dir = tempfile::tempdir().unwrap();
    let out = nusselt(
        &["formfactors", &scene_arg("two-squares.gltf"), "-q"],
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = String::from_utf8(out.stdout).unwrap();
    let mut lines = csv.lines();
    assert!(lines.next().unwrap().starts_with("from,to,form_factor"));
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    let f: f64 = row[2].parse().unwrap();
    assert!((f - 0.199825).abs() < 1e-6, "{csv}");
    // The closed Goral box: every surface's row sums to 1, for each method
    // within its error (adaptive area sampling: 1 % at its default
    // tolerance, and its error column says how far each factor may be off).
    for (method, tol) in [("analytic", 1e-4), ("hemicube", 1e-3), ("sampling", 0.01)] {
        let out = nusselt(
            &[
                "formfactors",
                &scene_arg("goral-box.gltf"),
                "--method",
                method,
                "-q",
            ],
            dir.path(),
        );
        assert!(
            out.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let csv = String::from_utf8(out.stdout).unwrap();
        for line in csv.lines().skip(1) {
            let cols: Vec<&str> = line.split(',').collect();
            let row_sum: f64 = cols[5].parse().unwrap();
            assert!((row_sum - 1.0).abs() < tol, "{method}: {line}");
            // The error column: a number for the kernels that estimate
            // one, empty for the hemicube.
            match method {
                "hemicube" => assert_eq!(cols[6], "", "{line}"),
                "sampling" => {
                    let error: f64 = cols[6].parse().unwrap();
                    let f: f64 = cols[2].parse().unwrap();
                    assert!(
                        error >= 0.0 && error <= 0.01 * f.max(1e-3),
                        "{method}: {line}"
                    );
                }
                _ => assert!(cols[6].parse::<f64>().unwrap() >= 0.0, "{line}"),
            }
        }
    }
}

/// A surface name with a comma, quotes and a line break comes back whole
/// from the form-factor CSV: RFC 4180 quoting, read by a standard reader.
#[test]
fn formfactors_csv_quotes_surface_names() {
    let dir = tempfile::tempdir().unwrap();
    let name = "lamp, \"warm\"\nwhite";
    let mut doc: serde_json::Value =
        serde_json::from_slice(&fs::read(scene_path("two-squares.gltf")).unwrap()).unwrap();
    doc["nodes"][0]["name"] = name.into();
    fs::write(
        dir.path().join("named.gltf"),
        serde_json::to_vec(&doc).unwrap(),
    )
    .unwrap();
    fs::copy(
        scene_path("two-squares.bin"),
        dir.path().join("two-squares.bin"),
    )
    .unwrap();
    let out = nusselt_ok(&["formfactors", "named.gltf", "-q"], dir.path());
    let mut reader = csv::Reader::from_reader(out.stdout.as_slice());
    assert_eq!(
        reader.headers().unwrap().iter().collect::<Vec<_>>(),
        [
            "from",
            "to",
            "form_factor",
            "reverse",
            "reciprocity_error",
            "row_sum",
            "error"
        ]
    );
    let rows: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    let lamp = rows
        .iter()
        .find(|r| &r[0] == name && &r[1] == "receiver")
        .unwrap_or_else(|| panic!("no row from {name:?}: {rows:?}"));
    let f: f64 = lamp[2].parse().unwrap();
    assert!((f - 0.199825).abs() < 1e-6, "{rows:?}");
    assert!(rows.iter().any(|r| &r[0] == "receiver" && &r[1] == name));
}

/// The bake's exposure is the solution's: three render sizes and a second
/// camera give byte-identical bakes, and `--exposure` sets it.
#[test]
fn the_bake_is_the_same_whatever_the_render() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = scene_arg("cornell-box.gltf");
    // A preview solve of the Cornell box into `out` with `extra` flags.
    let solve_into = |out: &str, extra: &[&str]| {
        let mut args = vec!["solve", &scene_path, "-q", "--accuracy", "preview"];
        args.extend_from_slice(&["--spp", "1", "-o", out]);
        args.extend_from_slice(extra);
        nusselt_ok(&args, dir.path());
        dir.path().join(out)
    };
    // Its bake and exposure.
    let solve = |out: &str, view: &[&str]| {
        let res = solve_into(out, view);
        let bake = (
            fs::read(res.join("baked.gltf")).unwrap(),
            fs::read(res.join("baked.bin")).unwrap(),
        );
        (bake, read_report(&res).exposure)
    };
    let (first, exposure) = solve("a", &["--width", "16", "--height", "16"]);
    assert!(exposure.is_finite() && exposure > 0.0, "{exposure}");
    for (out, view) in [
        ("b", &["--width", "96", "--height", "64"][..]),
        ("c", &["--width", "200", "--height", "150"][..]),
        (
            "d",
            &["--width", "64", "--height", "64", "--eye", "0.1,0.1,0.1"][..],
        ),
    ] {
        let (bake, e) = solve(out, view);
        assert_eq!(e, exposure, "{view:?}");
        assert!(bake == first, "{view:?}: the bake differs");
    }
    // `--glb`: the same document and buffer in one binary file.
    let g = solve_into("g", &["--width", "16", "--height", "16", "--glb"]);
    assert!(!g.join("baked.gltf").exists() && !g.join("baked.bin").exists());
    let (doc, buffers, _) = gltf::import(g.join("baked.glb")).unwrap();
    let (doc_a, buffers_a, _) = gltf::import(dir.path().join("a/baked.gltf")).unwrap();
    assert_eq!(buffers[0].len(), buffers_a[0].len());
    assert!(buffers[0].0 == buffers_a[0].0, "the glb's buffer differs");
    assert_eq!(doc.accessors().count(), doc_a.accessors().count());
    assert!(matches!(
        doc.buffers().next().unwrap().source(),
        gltf::buffer::Source::Bin
    ));
    assert_eq!(
        doc.as_json().asset.extras.as_ref().map(|e| e.get()),
        doc_a.as_json().asset.extras.as_ref().map(|e| e.get())
    );

    // Given, it is used as it is; out of range, a one-line error.
    let (bake, e) = solve(
        "e",
        &["--width", "16", "--height", "16", "--exposure", "2.5"],
    );
    assert_eq!(e, 2.5);
    assert!(bake != first);
    for bad in [
        "--exposure=0",
        "--exposure=-1",
        "--exposure=inf",
        "--exposure=NaN",
    ] {
        let run = nusselt(&["solve", &scene_path, "-q", "-o", "f", bad], dir.path());
        assert_user_error(&run, "--exposure");
        assert!(!dir.path().join("f").exists());
    }
}

/// Every vertex carries the light arriving, H, beside the light leaving,
/// B = E + ρ H with its patch's E and ρ, in `solution.exr` and in the
/// bake's `_IRRADIANCE`, whichever method solved.
#[test]
fn irradiance_and_radiosity_agree_at_every_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = scene_arg("cornell-box.gltf");
    let scene = bundled_scene("cornell-box.gltf");
    for method in ["hierarchical", "gauss-seidel", "shooting"] {
        // The preview preset for hierarchical; the classic methods' own
        // mesh for the others.
        let accuracy = match method {
            "hierarchical" => ["--accuracy", "preview"],
            _ => ["--element-size", "0.05"],
        };
        let args = [
            "solve",
            &scene_path,
            "-q",
            accuracy[0],
            accuracy[1],
            "--method",
            method,
            "--spp",
            "1",
            "--width",
            "16",
            "--height",
            "16",
            "-o",
            method,
        ];
        nusselt_ok(&args, dir.path());
        let res = dir.path().join(method);
        let mesh = output::exr::read_solution(&res.join("solution.exr")).unwrap();
        mesh.validate().unwrap();
        assert_light_adds_up(&scene, &mesh, method);
        let lit = mesh
            .irradiance
            .iter()
            .filter(|h| h.min_element() > 0.0)
            .count();
        assert!(
            lit > mesh.vertex_count() / 2,
            "{method}: {lit} lit vertices"
        );
        if method == "hierarchical" {
            let (doc, buffers, _) = gltf::import(res.join("baked.gltf")).unwrap();
            let baked = crate::bake::reassemble(&doc, &buffers);
            assert!(
                baked.irradiance == mesh.irradiance,
                "the bake's _IRRADIANCE differs from the solution's H"
            );
        }
    }
}

#[test]
fn a_default_solve_of_every_bundled_scene_prints_no_warning() {
    // Warnings are for results worse than the settings promise; the
    // normal path of a default run has none (three-rooms and office-10k
    // with the slow tests only: half a minute each).
    let mut scenes = vec![
        "cornell-box.gltf",
        "goral-box.gltf",
        "penumbra.gltf",
        "two-squares.gltf",
        "spot-room.gltf",
        "courtyard.gltf",
    ];
    if crate::fixtures::slow_tests("default solves of three-rooms and office-10k print no warning")
    {
        scenes.extend(["three-rooms.gltf", "scale/office-10k.gltf"]);
    }
    for name in scenes {
        let scene = bundled_scene(name);
        assert!(scene.warnings.is_empty(), "{name}: {:?}", scene.warnings);
        let mut settings = nusselt::SolveSettings {
            render: RenderSettings::with_samples(1, 0),
            ..Default::default()
        };
        settings.view.width = Some(16);
        settings.view.height = Some(16);
        let run = nusselt::solve(&scene, &settings, &nusselt::Progress::hidden()).unwrap();
        assert!(
            run.report.warnings.is_empty(),
            "{name}: {:?}",
            run.report.warnings
        );
    }
}
