//! The command line on bad input: one `error:` line, exit code 1, no partial
//! or clobbered output.

use std::fs;

use crate::fixtures::{TestMesh, assert_user_error, gltf_json, inward_box, nusselt, scene_arg};

fn write(dir: &std::path::Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    fs::write(&p, text).unwrap();
    p.to_string_lossy().into_owned()
}

fn lit_box() -> Vec<TestMesh> {
    inward_box(1.0, [1.0, 1.0, 1.0], [0.5, 0.5, 0.5])
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = nusselt(&["solve", "no-such-scene.gltf", "-q"], dir.path());
    assert_user_error(&out, "no-such-scene.gltf");
}

#[test]
fn malformed_and_truncated_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "bad.gltf",
        "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [",
    );
    assert_user_error(&nusselt(&["solve", &p, "-q"], dir.path()), "bad.gltf");
    let full = gltf_json(&lit_box());
    let p = write(dir.path(), "cut.gltf", &full[..full.len() / 2]);
    assert_user_error(&nusselt(&["solve", &p, "-q"], dir.path()), "cut.gltf");
}

#[test]
fn nan_coordinates_name_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mut meshes = lit_box();
    meshes[2].positions[1][0] = f32::NAN;
    let p = write(dir.path(), "nan.gltf", &gltf_json(&meshes));
    assert_user_error(&nusselt(&["solve", &p, "-q"], dir.path()), "back");
}

#[test]
fn control_characters_in_names_reach_the_terminal_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let mut meshes = lit_box();
    meshes[2].positions[1][0] = f32::NAN;
    // JSON escapes: the name read holds a real ESC and carriage return.
    meshes[2].name = "back\\u001b[2J\\rwall";
    let p = write(dir.path(), "esc.gltf", &gltf_json(&meshes));
    let out = nusselt(&["solve", &p, "-q"], dir.path());
    assert_user_error(&out, "back");
    assert!(
        !out.stderr.iter().any(|&b| b == 0x1b || b == b'\r'),
        "raw control bytes"
    );
    // The scene path itself: only a regular file is read.
    assert_user_error(
        &nusselt(&["solve", "/dev/zero", "-q"], dir.path()),
        "not a regular file",
    );
}

#[test]
fn out_of_range_index_names_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mut meshes = lit_box();
    meshes[4].indices[2] = 99;
    let p = write(dir.path(), "index.gltf", &gltf_json(&meshes));
    assert_user_error(&nusselt(&["solve", &p, "-q"], dir.path()), "left");
}

#[test]
fn no_emitters() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = inward_box(1.0, [0.0; 3], [0.5; 3]);
    let p = write(dir.path(), "dark.gltf", &gltf_json(&meshes));
    assert_user_error(
        &nusselt(&["solve", &p, "-q"], dir.path()),
        "no light in the scene",
    );
}

#[test]
fn unwritable_output_folder_and_earlier_results_survive() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "box.gltf", &gltf_json(&lit_box()));
    fs::write(dir.path().join("a-file"), "x").unwrap();
    let out = nusselt(
        &[
            "solve",
            &p,
            "-q",
            "-o",
            "a-file/out",
            "--accuracy",
            "preview",
        ],
        dir.path(),
    );
    assert_user_error(&out, "a-file");

    // A good run, then a failing one into the same folder: the first
    // run's files stay as they were, and no temporary file is left.
    let ok = nusselt(
        &[
            "solve",
            &p,
            "-q",
            "-o",
            "res",
            "--accuracy",
            "preview",
            "--width",
            "8",
            "--height",
            "8",
        ],
        dir.path(),
    );
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let res = dir.path().join("res");
    let before: Vec<(String, Vec<u8>)> = list(&res);
    assert_eq!(
        before.len(),
        6,
        "{:?}",
        before.iter().map(|b| &b.0).collect::<Vec<_>>()
    );
    let bad = write(dir.path(), "bad.gltf", "not json");
    assert_user_error(
        &nusselt(&["solve", &bad, "-q", "-o", "res"], dir.path()),
        "bad.gltf",
    );
    let fov = nusselt(&["solve", &p, "-q", "-o", "res", "--fov", "0"], dir.path());
    assert_user_error(&fov, "field of view");
    assert_eq!(list(&res), before);
}

#[test]
fn usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = nusselt(&["solve"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    let out = nusselt(&["solve", "x.gltf", "--eye", "1,2"], dir.path());
    assert_eq!(out.status.code(), Some(2));
}

fn list(dir: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn matrix_over_the_memory_budget_is_refused_with_its_size() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "box.gltf", &gltf_json(&lit_box()));
    let out = nusselt(
        &[
            "solve",
            &p,
            "-q",
            "--method",
            "jacobi",
            "--element-size",
            "0.01",
            "--memory-budget",
            "0.01",
        ],
        dir.path(),
    );
    // 60,000 elements: 13.41 GiB of f32 matrix and 29 MiB of elements,
    // counted before any is built.
    assert_user_error(&out, "60000 elements, which need 13.44 GiB");
    assert!(!dir.path().join("out").exists(), "nothing written");
}

#[test]
fn mesh_flags_are_checked_and_wireframe_touches_only_the_png() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "box.gltf", &gltf_json(&lit_box()));
    assert_user_error(
        &nusselt(
            &[
                "solve", &p, "-q", "--method", "jacobi", "--mesh", "quadtree",
            ],
            dir.path(),
        ),
        "needs --method hierarchical",
    );
    assert_user_error(
        &nusselt(&["solve", &p, "-q", "--adapt-tol=-1"], dir.path()),
        "--adapt-tol",
    );
    let run = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "solve",
            &p,
            "-q",
            "-o",
            out,
            "--accuracy",
            "preview",
            "--width",
            "32",
            "--height",
            "32",
        ];
        args.extend_from_slice(extra);
        let o = nusselt(&args, dir.path());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let read = |f: &str| fs::read(dir.path().join(out).join(f)).unwrap();
        (read("render.png"), read("render.exr"))
    };
    let (png, exr) = run("plain", &[]);
    let (png_w, exr_w) = run("wire", &["--wireframe"]);
    assert_eq!(exr, exr_w);
    assert_ne!(png, png_w);
}

// The hostile-input suite at the command line (issue 7): a representative
// handful, each one `error:` line and exit code 1. The library-level cases
// are in tests/loader.rs (`hostile_*`).

#[test]
fn hostile_huge_coordinates_name_file_and_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mut meshes = lit_box();
    for p in &mut meshes[0].positions {
        *p = p.map(|c| c * 3e38);
    }
    let p = write(dir.path(), "huge.gltf", &gltf_json(&meshes));
    let out = nusselt(&["solve", &p, "-q", "--accuracy", "preview"], dir.path());
    assert_user_error(&out, "huge.gltf: mesh 'floor' primitive 0: vertex");
    assert!(!dir.path().join("out").exists(), "nothing written");
}

#[test]
fn hostile_wrong_accessor_type_and_missing_buffer() {
    let dir = tempfile::tempdir().unwrap();
    let json = gltf_json(&lit_box());
    // The first POSITION accessor becomes unsigned bytes.
    let pos = r#""componentType":5126,"count":4,"type":"VEC3","min":[0,0,0]"#;
    let bytes = json.replacen(pos, &pos.replace("5126", "5121"), 1);
    assert_ne!(bytes, json, "the test scene changed shape");
    let p = write(dir.path(), "u8.gltf", &bytes);
    assert_user_error(
        &nusselt(&["solve", &p, "-q"], dir.path()),
        "u8.gltf: mesh 'floor' primitive 0: POSITION accessor 0 has type Vec3 U8",
    );
    // The buffer moves to a file that is not there.
    let start = json.find("data:application").unwrap();
    let end = start + json[start..].find('"').unwrap();
    let missing = format!("{}gone.bin{}", &json[..start], &json[end..]);
    let p = write(dir.path(), "missing.gltf", &missing);
    assert_user_error(&nusselt(&["solve", &p, "-q"], dir.path()), "gone.bin");
}

#[test]
fn hostile_output_path_that_is_a_file_is_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "box.gltf", &gltf_json(&lit_box()));
    fs::write(dir.path().join("taken"), "keep me").unwrap();
    let out = nusselt(
        &["solve", &p, "-q", "-o", "taken", "--accuracy", "preview"],
        dir.path(),
    );
    assert_user_error(&out, "taken");
    assert_eq!(fs::read(dir.path().join("taken")).unwrap(), b"keep me");
}

/// A run that fails while putting its files in place (a folder stands where
/// its last file goes) leaves the earlier run's files byte-identical and no
/// temporary file behind.
#[test]
fn hostile_failure_on_write_keeps_the_earlier_output() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "box.gltf", &gltf_json(&lit_box()));
    let run = |extra: &[&str]| {
        let mut args = vec![
            "solve",
            &p,
            "-q",
            "-o",
            "res",
            "--accuracy",
            "preview",
            "--height",
            "8",
        ];
        args.extend_from_slice(extra);
        nusselt(&args, dir.path())
    };
    let ok = run(&["--width", "8"]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let res = dir.path().join("res");
    // The snapshot files of the second run are blocked by folders.
    fs::create_dir(res.join("snapshot-00001.png")).unwrap();
    fs::write(res.join("snapshot-00001.png").join("inside"), "x").unwrap();
    let files = list_files;
    let before = files(&res);
    assert_eq!(
        before.len(),
        6,
        "{:?}",
        before.iter().map(|b| &b.0).collect::<Vec<_>>()
    );
    // Different settings: every file of the second run would differ.
    let failed = run(&["--snapshots", "1", "--width", "12"]);
    assert_user_error(&failed, "snapshot-00001.png");
    assert_eq!(files(&res), before, "the earlier output changed");
    let leftovers: Vec<String> = fs::read_dir(&res)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// Regular files of `dir` with their bytes, sorted by name.
fn list_files(dir: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_type().unwrap().is_file())
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

/// Asserts a usage error: exit code 2 and one `error:` line containing
/// `needle`.
fn assert_usage_error(out: &std::process::Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert!(errors[0].contains(needle), "'{needle}' not in: {stderr}");
}

#[test]
fn bad_values_are_usage_errors_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("cornell-box.gltf");
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    for (args, needle) in [
        (
            vec!["solve", &scene, "-o", o, "--threads", "0"],
            "--threads",
        ),
        (vec!["solve", &scene, "-o", o, "--width", "0"], "--width"),
        (
            vec!["solve", &scene, "-o", o, "--height", "1.5"],
            "--height",
        ),
        (vec!["solve", &scene, "-o", o, "--spp", "0"], "--spp"),
        (vec!["solve", &scene, "-o", o, "--spp", "65537"], "--spp"),
        (
            vec!["reference", &scene, "-o", "ref.exr", "--spp", "4294967295"],
            "--spp",
        ),
        (
            vec![
                "probe", &scene, "--random", "4", "-o", "t.csv", "--spp", "1048577",
            ],
            "--spp",
        ),
        (
            vec!["solve", &scene, "-o", o, "--max-iterations", "0"],
            "--max-iterations",
        ),
        (
            vec!["reference", &scene, "-o", "ref.exr", "--spp", "1"],
            "--spp",
        ),
        (
            vec![
                "probe", &scene, "--random", "4", "-o", "t.csv", "--spp", "1",
            ],
            "--spp",
        ),
        (
            vec!["reference", &scene, "-o", "ref.png"],
            "must end in .exr",
        ),
        (
            vec!["reference", &scene, "-o", "ref.exr", "--png", "ref.jpg"],
            "must end in .png",
        ),
        (
            vec!["render", "solution.exr", "-o", "looks.png"],
            "must end in .exr",
        ),
        (
            vec!["probe", &scene, "--random", "4", "-o", "table.txt"],
            "must end in .csv",
        ),
    ] {
        assert_usage_error(&nusselt(&args, dir.path()), needle);
    }
    assert!(!out.exists(), "nothing written");
}

/// A sampling tolerance that is not a positive, finite number is one
/// `error:` line naming the flag, before any form factor is computed.
#[test]
fn a_bad_sampling_tolerance_is_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("two-squares.gltf");
    for bad in ["0", "-0.01", "nan", "inf"] {
        let flag = format!("--sampling-tolerance={bad}");
        let out = nusselt(
            &["formfactors", &scene, "-q", "--method", "sampling", &flag],
            dir.path(),
        );
        assert_user_error(&out, "--sampling-tolerance");
        assert!(out.stdout.is_empty(), "{bad}: no form factors computed");
        let o = dir.path().join("out");
        let out = nusselt(
            &[
                "solve",
                &scene,
                "-q",
                "-o",
                o.to_str().unwrap(),
                "--method",
                "jacobi",
                "--kernel",
                "sampling",
                &flag,
            ],
            dir.path(),
        );
        assert_user_error(&out, "--sampling-tolerance");
        assert!(!o.exists(), "{bad}: nothing written");
    }
}

/// A points file that cannot be read is one error line naming the file
/// and the line, before any probing; nothing is written.
#[test]
fn a_malformed_points_file_names_its_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("points.csv"),
        "x,y,z,nx,ny,nz\n0.5,0.5,0,0,0,1\n0.5,0.5,zero,0,0,1\n",
    )
    .unwrap();
    let scene = scene_arg("two-squares.gltf");
    let args = [
        "probe",
        &scene,
        "--points",
        "points.csv",
        "--spp",
        "8",
        "-o",
        "table.csv",
        "-q",
    ];
    let out = nusselt(&args, dir.path());
    assert_user_error(&out, "points.csv: line 3: column 'z' (\"zero\")");
    assert!(!dir.path().join("table.csv").exists());
}

#[test]
fn an_output_folder_that_cannot_be_one_fails_before_the_scene_is_read() {
    // The scene does not exist: an error about the folder shows that the
    // folder was checked first, before any loading or solving.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("taken");
    std::fs::write(&file, b"keep me").unwrap();
    let inside = file.join("sub");
    for target in [file.to_str().unwrap(), inside.to_str().unwrap()] {
        let out = nusselt(&["solve", "missing.gltf", "-q", "-o", target], dir.path());
        assert_user_error(&out, "is a file, not a folder");
    }
    let image = inside.join("ref.exr");
    let out = nusselt(
        &[
            "reference",
            "missing.gltf",
            "-q",
            "-o",
            image.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_user_error(&out, "is a file, not a folder");
    assert_eq!(std::fs::read(&file).unwrap(), b"keep me");
}

#[test]
fn a_flag_the_method_does_not_read_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("cornell-box.gltf");
    for (extra, needle) in [
        (
            &["--kernel", "hemicube"][..],
            "--kernel applies only to the classic methods",
        ),
        (&["--element-size", "0.05"][..], "--element-size"),
        (
            &["--hemicube-resolution", "64"][..],
            "--hemicube-resolution",
        ),
        (
            &["--quadrature-tolerance", "1e-3"][..],
            "--quadrature-tolerance",
        ),
        (
            &["--sampling-tolerance", "0.01"][..],
            "--sampling-tolerance",
        ),
        (
            &[
                "--method",
                "jacobi",
                "--accuracy",
                "high",
                "--oracle",
                "ff",
                "--max-links",
                "3",
            ][..],
            "--accuracy, --oracle, --max-links apply only to --method hierarchical, not to --method jacobi",
        ),
        (
            &["--method", "shooting", "--importance"][..],
            "--importance",
        ),
        (
            &["--method", "direct", "--sky-rays", "64"][..],
            "--sky-rays",
        ),
        (
            &[
                "--method",
                "jacobi",
                "--kernel",
                "hemicube",
                "--sampling-tolerance",
                "0.01",
            ][..],
            "--sampling-tolerance applies only to --kernel sampling, not to --kernel hemicube",
        ),
        (
            &["--method", "gauss-seidel", "--quadrature-tolerance", "1e-3"][..],
            "--quadrature-tolerance applies only to --kernel polygon-polygon, not to --kernel point-polygon",
        ),
        (
            &[
                "--method",
                "jacobi",
                "--kernel",
                "sampling",
                "--visibility-rays",
                "8",
            ][..],
            "--visibility-rays applies only to --kernel point-polygon and --kernel polygon-polygon",
        ),
    ] {
        let mut args = vec!["solve", scene.as_str(), "-q", "-o", "out"];
        args.extend(extra);
        assert_usage_error(&nusselt(&args, dir.path()), needle);
    }
    assert!(!dir.path().join("out").exists(), "nothing written");

    // formfactors: the kernel is --method's; its knobs apply to their own.
    for (extra, needle) in [
        (&["--kernel", "hemicube"][..], "--kernel"),
        (
            &["--method", "sampling", "--hemicube-resolution", "64"][..],
            "--hemicube-resolution applies only to --method hemicube, not to --method sampling",
        ),
        (
            &["--sampling-tolerance", "0.001"][..],
            "--sampling-tolerance applies only to --method sampling, not to --method analytic",
        ),
    ] {
        let mut args = vec!["formfactors", scene.as_str(), "-q"];
        args.extend(extra);
        let out = nusselt(&args, dir.path());
        assert_usage_error(&out, needle);
        assert!(out.stdout.is_empty(), "no form factors computed");
    }
}

#[test]
fn help_has_headings_examples_and_preset_values_and_short_help_hides_expert_knobs() {
    let dir = tempfile::tempdir().unwrap();
    let text = |args: &[&str]| {
        let out = nusselt(args, dir.path());
        assert!(out.status.success());
        String::from_utf8(out.stdout).unwrap()
    };
    let long = text(&["solve", "--help"]);
    let short = text(&["solve", "-h"]);
    for heading in [
        "Accuracy:",
        "Hierarchical:",
        "Budgets:",
        "Classic methods:",
        "Kernel:",
        "Output:",
        "View:",
        "Run:",
        "Examples:",
    ] {
        assert!(long.contains(heading), "--help lacks {heading}");
    }
    // Each preset's own value, read from the presets.
    let default = nusselt::hierarchical::Accuracy::preset(nusselt::hierarchical::Preset::Default);
    assert!(
        long.contains(&format!("default {}", default.max_rounds)),
        "{long}"
    );
    assert!(long.contains("--bf-eps") && !short.contains("--bf-eps"));
    assert!(short.contains("--accuracy") && short.contains("Examples:"));
    assert!(short.lines().count() * 2 < long.lines().count());
    // Wrapped: no line runs on (clap wraps at 100 columns off a terminal).
    let widest = long.lines().map(|l| l.chars().count()).max().unwrap();
    assert!(widest <= 110, "a help line of {widest} characters");
    // Per-subcommand wording of a shared flag.
    assert!(text(&["reference", "--help"]).contains("Independent paths per pixel"));
    assert!(!text(&["render", "--help"]).contains("Independent paths"));
}

#[test]
fn completions_and_man_pages_are_generated_from_the_parser() {
    let dir = tempfile::tempdir().unwrap();
    let bash = nusselt(&["completions", "bash"], dir.path());
    assert!(bash.status.success());
    let bash = String::from_utf8(bash.stdout).unwrap();
    assert!(bash.contains("--accuracy") && bash.contains("formfactors"));
    let man = nusselt(&["manpage"], dir.path());
    assert!(man.status.success());
    assert!(
        String::from_utf8(man.stdout)
            .unwrap()
            .starts_with(".ie \\n(.g .ds Aq")
    );
    let out = nusselt(&["manpage", "-o", "man"], dir.path());
    assert!(out.status.success());
    let solve = std::fs::read_to_string(dir.path().join("man/nusselt-solve.1")).unwrap();
    assert!(
        solve.contains("accuracy") && solve.contains(".TH nusselt-solve"),
        "{solve}"
    );
    assert_usage_error(&nusselt(&["completions", "tcsh"], dir.path()), "tcsh");
}

/// Runs nusselt under a pseudo-terminal (`script`), returning what it
/// drew on the terminal; `None` where `script` is missing.
fn on_a_terminal(args: &str, dir: &std::path::Path) -> Option<String> {
    let bin = env!("CARGO_BIN_EXE_nusselt");
    let out = std::process::Command::new("script")
        .args(["-qec", &format!("{bin} {args}"), "/dev/null"])
        .current_dir(dir)
        .stdin(std::process::Stdio::null())
        .output()
        .ok()?;
    let drawn = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{drawn}");
    Some(drawn)
}

#[test]
fn every_phase_shows_progress_on_a_terminal_and_nothing_otherwise() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("cornell-box.gltf");
    let args = format!(
        "solve {scene} -o h --accuracy preview --width 64 --height 64 --spp 1 --lightmap 128"
    );
    let Some(drawn) = on_a_terminal(&args, dir.path()) else {
        println!("skipped: no `script` to run under a terminal");
        return;
    };
    for phase in [
        "load",
        "occluders",
        "shadow lines",
        "linking",
        "rounds",
        "output mesh",
        "render",
        "lightmap",
        "write",
    ] {
        assert!(drawn.contains(phase), "no {phase:?} progress in {drawn:?}");
    }
    let classic = on_a_terminal(
        &format!(
            "solve {scene} -o c --method jacobi --element-size 0.2 --width 64 --height 64 --spp 1"
        ),
        dir.path(),
    )
    .unwrap();
    for phase in ["form factors", "jacobi"] {
        assert!(
            classic.contains(phase),
            "no {phase:?} progress in {classic:?}"
        );
    }
    // --quiet on a terminal, and any run whose stderr is not one: nothing.
    let quiet = on_a_terminal(&format!("{args} --quiet"), dir.path()).unwrap();
    assert!(quiet.trim().is_empty(), "{quiet:?}");
    let piped = nusselt(
        &["solve", &scene, "-o", "p", "--accuracy", "preview"],
        dir.path(),
    );
    assert!(
        piped.status.success() && piped.stderr.is_empty(),
        "{:?}",
        String::from_utf8_lossy(&piped.stderr)
    );
}

/// Flags only the hierarchical method reads, with a valid value (none for
/// a switch).
const HIERARCHICAL_FLAGS: [(&str, Option<&str>); 21] = [
    ("--accuracy", Some("high")),
    ("--oracle", Some("ff")),
    ("--ff-eps", Some("0.1")),
    ("--bf-eps", Some("0.1")),
    ("--bf-relative-floor", Some("0.5")),
    ("--power-eps", Some("0.1")),
    ("--cluster-eps", Some("0.1")),
    ("--min-area", Some("0.001")),
    ("--gradient-tol", Some("0.1")),
    ("--max-links", Some("100")),
    ("--max-elements", Some("100")),
    ("--max-rounds", Some("2")),
    ("--sky-rays", Some("8")),
    ("--clustering", Some("on")),
    ("--time-budget", Some("5")),
    ("--correction-passes", Some("1")),
    ("--correction-rays", Some("8")),
    ("--correction-tolerance", Some("0.1")),
    ("--adapt-tol", Some("0.1")),
    ("--uniform-vertices", Some("100")),
    ("--importance", None),
];

/// Kernel flags, a valid value, and the `solve --kernel`s that read them.
const KERNEL_FLAGS: [(&str, Option<&str>, &[&str]); 5] = [
    (
        "--visibility-rays",
        Some("8"),
        &["point-polygon", "polygon-polygon"],
    ),
    ("--sampling-tolerance", Some("0.01"), &["sampling"]),
    (
        "--quadrature-tolerance",
        Some("0.001"),
        &["polygon-polygon"],
    ),
    ("--hemicube-resolution", Some("64"), &["hemicube"]),
    ("--no-hemicube-rotation", None, &["hemicube"]),
];

/// Every flag × method (and kernel) pair it does not apply to is a usage
/// error naming the flag, before any work; and the table covers every flag
/// `solve --help` lists under Hierarchical.
#[test]
fn table_every_flag_where_it_does_not_apply_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_arg("cornell-box.gltf");
    let refused = |extra: &[&str], flag: &str| {
        let mut args = vec!["solve", scene.as_str(), "-q", "-o", "out"];
        args.extend(extra);
        let out = nusselt(&args, dir.path());
        assert_usage_error(&out, flag);
    };
    let with = |flag: &'static str, value: Option<&'static str>| -> Vec<&'static str> {
        std::iter::once(flag).chain(value).collect()
    };
    for (flag, value) in HIERARCHICAL_FLAGS {
        for method in ["direct", "jacobi", "gauss-seidel", "shooting"] {
            let mut extra = vec!["--method", method];
            extra.extend(with(flag, value));
            refused(&extra, flag);
        }
    }
    refused(&["--element-size", "0.1"], "--element-size");
    refused(&["--kernel", "hemicube"], "--kernel");
    let kernels = ["point-polygon", "polygon-polygon", "sampling", "hemicube"];
    for (flag, value, readers) in KERNEL_FLAGS {
        if !readers.contains(&"point-polygon") && flag != "--visibility-rays" {
            // A classic-only kernel flag is refused with hierarchical too.
            refused(&with(flag, value), flag);
        }
        for kernel in kernels.iter().filter(|k| !readers.contains(k)) {
            let mut extra = vec!["--method", "jacobi", "--kernel", kernel];
            extra.extend(with(flag, value));
            refused(&extra, flag);
        }
    }
    assert!(!dir.path().join("out").exists(), "nothing written");

    let help = String::from_utf8(nusselt(&["solve", "--help"], dir.path()).stdout).unwrap();
    // The lines from the heading to the next heading (unindented).
    let listed: Vec<&str> = help
        .lines()
        .skip_while(|l| *l != "Hierarchical:")
        .skip(1)
        .take_while(|l| l.is_empty() || l.starts_with(' '))
        .filter_map(|l| l.trim_start().strip_prefix("--"))
        .map(|l| l.split([' ', '\t']).next().unwrap())
        .collect();
    assert!(!listed.is_empty(), "{help}");
    for flag in listed {
        let flag = format!("--{flag}");
        assert!(
            HIERARCHICAL_FLAGS.iter().any(|(f, _)| *f == flag),
            "{flag} is listed under Hierarchical but missing from the table"
        );
    }
}
