//! A run's files all or nothing (`nusselt::output::commit`, issue 26): a
//! `solve` killed with SIGKILL at random moments of its write phase leaves
//! its folder exactly as before or exactly the new result set once the
//! next nusselt command has looked at it; Ctrl-C and SIGTERM while staging
//! leave nothing behind; the leftovers of dead processes are removed and
//! those of live ones kept; an earlier run's snapshots go with it; and
//! `report.json` lists every other file of its run.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use nusselt::output::{self, OutputSet};
use serde_json::Value;

use crate::fixtures::{gltf_json, inward_box, nusselt, nusselt_ok};

/// Every entry of `dir` (hidden ones and folders too), sorted, with the
/// bytes of each file (folders: `None`).
fn entries(dir: &Path) -> Vec<(String, Option<Vec<u8>>)> {
    let mut v: Vec<(String, Option<Vec<u8>>)> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .map(|e| {
            let bytes = e
                .file_type()
                .unwrap()
                .is_file()
                .then(|| fs::read(e.path()).unwrap());
            (e.file_name().to_string_lossy().into_owned(), bytes)
        })
        .collect();
    v.sort();
    v
}

fn names(dir: &Path) -> Vec<String> {
    entries(dir).into_iter().map(|(n, _)| n).collect()
}

/// A lit box scene in `dir`, as a command-line argument.
fn scene(dir: &Path) -> String {
    let path = dir.join("box.gltf");
    fs::write(&path, gltf_json(&inward_box(1.0, [1.0; 3], [0.5; 3]))).unwrap();
    path.to_string_lossy().into_owned()
}

/// `solve` arguments for a small run into `out`, plus `extra`.
fn solve_args<'a>(scene: &'a str, out: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "solve",
        scene,
        "-q",
        "-o",
        out,
        "--accuracy",
        "preview",
        "--height",
        "8",
    ];
    args.extend_from_slice(extra);
    args
}

/// Starts `nusselt args` in `cwd` with every step of its write phase
/// slowed down by `delay_ms`.
fn spawn_slowed(args: &[&str], cwd: &Path, delay_ms: u64) -> Child {
    Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .current_dir(cwd)
        .env("NUSSELT_COMMIT_STEP_DELAY_MS", delay_ms.to_string())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the nusselt binary runs")
}

/// Waits (at most 60 s) until `dir` holds a staging folder with at least
/// one staged file: the write phase has begun.
fn wait_for_staging(dir: &Path, child: &mut Child) {
    let start = Instant::now();
    loop {
        let staged = fs::read_dir(dir).into_iter().flatten().flatten().any(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with(".nusselt-staging-")
                && fs::read_dir(e.path()).is_ok_and(|mut d| d.next().is_some())
        });
        if staged {
            return;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before its write phase was seen"
        );
        assert!(start.elapsed() < Duration::from_secs(60), "no write phase");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// `report.json` without what differs between two runs of the same
/// settings: wall-clock times (as in tests/determinism.rs).
fn stable_report(bytes: &[u8]) -> Value {
    fn strip(v: &mut Value) {
        match v {
            Value::Object(map) => {
                map.retain(|k, _| !(k == "times" || k.ends_with("seconds")));
                map.values_mut().for_each(strip);
            }
            Value::Array(items) => items.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut report: Value = serde_json::from_slice(bytes).unwrap();
    strip(&mut report);
    report
}

/// Whether `now` is `expected` file for file, `report.json` up to its
/// times.
fn same_result(now: &[(String, Option<Vec<u8>>)], expected: &[(String, Option<Vec<u8>>)]) -> bool {
    now.len() == expected.len()
        && now.iter().zip(expected).all(|((n, a), (m, b))| {
            n == m
                && match (a, b) {
                    (Some(a), Some(b)) if n == "report.json" => {
                        stable_report(a) == stable_report(b)
                    }
                    _ => a == b,
                }
        })
}

/// A tiny deterministic generator (SplitMix64) for the kill moments.
struct SplitMix(u64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// 20 SIGKILLs at seeded random moments of a solve's write phase (slowed
/// to 25 ms a step, 19 steps: staging 6 files, the commit point, removing
/// the old seal and the 5 snapshot and lightmap files of the earlier run,
/// renaming 6 files). After each, `render` reads the folder; the folder
/// then holds exactly the earlier run's files or exactly the new run's (as
/// a run that was not killed writes them), the user's own file untouched,
/// nothing else. Some kills must land before the commit point and some in
/// the middle of putting files in place (finished by `render`).
#[test]
fn kill_9_in_the_write_phase_leaves_the_old_or_the_new_result() {
    let root = tempfile::tempdir().unwrap();
    let root = root.path();
    let scene = scene(root);
    // The earlier result: other settings, with snapshots and a lightmap.
    let old_args = ["--width", "12", "--snapshots", "1", "--lightmap", "64"];
    nusselt_ok(&solve_args(&scene, "before", &old_args), root);
    fs::write(root.join("before").join("notes.txt"), "the user's own").unwrap();
    let before = entries(&root.join("before"));
    assert!(before.iter().any(|(n, _)| n.starts_with("snapshot-")));
    // The new result, as an uninterrupted run writes it.
    let new_args = ["--width", "8"];
    nusselt_ok(&solve_args(&scene, "expected", &new_args), root);
    fs::write(root.join("expected").join("notes.txt"), "the user's own").unwrap();
    let expected = entries(&root.join("expected"));
    assert!(!same_result(&before, &expected));

    let delay_ms = 25;
    let write_phase = Duration::from_millis(delay_ms * 22);
    let mut rng = SplitMix(26);
    let (mut old, mut new, mut rolled_forward) = (0, 0, 0);
    for trial in 0..20 {
        let out = format!("trial-{trial}");
        let dir = root.join(&out);
        fs::create_dir(&dir).unwrap();
        for (name, bytes) in &before {
            fs::write(dir.join(name), bytes.as_ref().unwrap()).unwrap();
        }
        let mut child = spawn_slowed(&solve_args(&scene, &out, &new_args), root, delay_ms);
        wait_for_staging(&dir, &mut child);
        std::thread::sleep(write_phase.mul_f64(rng.next_f64()));
        child.kill().unwrap();
        // Reaped: a zombie would still count as a live owner.
        child.wait().unwrap();
        if dir.join(".nusselt-commit").exists() {
            rolled_forward += 1;
        }
        // The next command that looks at the folder.
        let solution = format!("{out}/solution.exr");
        let image = format!("render-{trial}.exr");
        nusselt_ok(
            &[
                "render", &solution, "-q", "-o", &image, "--width", "4", "--height", "4",
            ],
            root,
        );
        let now = entries(&dir);
        if same_result(&now, &before) {
            old += 1;
        } else if same_result(&now, &expected) {
            new += 1;
        } else {
            panic!(
                "trial {trial}: neither the earlier result nor the new one: {:?}",
                names(&dir)
            );
        }
    }
    eprintln!(
        "kill -9: {old} left the earlier result, {new} the new one \
         ({rolled_forward} finished by the next command)"
    );
    assert!(
        old > 0 && rolled_forward > 0,
        "{old} old, {new} new, {rolled_forward} rolled forward: kills before and after \
         the commit point expected"
    );
}

/// Sends `signal` to a solve once it is staging: it exits 130, its staged
/// files are gone and the earlier result is as it was.
fn interrupt_while_staging(signal: nix::sys::signal::Signal) {
    let root = tempfile::tempdir().unwrap();
    let root = root.path();
    let scene = scene(root);
    nusselt_ok(&solve_args(&scene, "res", &["--width", "12"]), root);
    let dir = root.join("res");
    let before = entries(&dir);
    let mut child = spawn_slowed(&solve_args(&scene, "res", &["--width", "8"]), root, 300);
    wait_for_staging(&dir, &mut child);
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    nix::sys::signal::kill(pid, signal).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{signal}");
    assert_eq!(String::from_utf8_lossy(&out.stderr).trim(), "interrupted");
    let left: Vec<String> = names(&dir)
        .into_iter()
        .filter(|n| n.starts_with(".nusselt-") || n.contains(".tmp-"))
        .collect();
    assert!(left.is_empty(), "{signal}: left behind: {left:?}");
    assert_eq!(
        entries(&dir),
        before,
        "{signal}: the earlier result changed"
    );
}

#[test]
fn sigint_while_staging_removes_the_staged_files() {
    interrupt_while_staging(nix::sys::signal::Signal::SIGINT);
}

#[test]
fn sigterm_while_staging_removes_the_staged_files() {
    interrupt_while_staging(nix::sys::signal::Signal::SIGTERM);
}

/// The id of a process that has ended.
fn dead_pid() -> u32 {
    let mut child = Command::new("true").spawn().unwrap();
    let pid = child.id();
    child.wait().unwrap();
    pid
}

/// Leftovers named after a dead process are removed by the next run in
/// their folder; those of a live process (this one), and one whose lock
/// is held (its owner lives in another PID namespace), are kept.
#[test]
fn leftovers_of_dead_processes_are_removed_and_of_live_ones_kept() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let (dead, live) = (dead_pid(), std::process::id());
    let dead_temp = format!(".solution.exr.tmp-{dead}-0");
    let dead_staging = format!(".nusselt-staging-{dead}-3");
    let live_temp = format!(".render.exr.tmp-{live}-900");
    let live_staging = format!(".nusselt-staging-{live}-901");
    let locked_temp = format!(".report.json.tmp-{dead}-7");
    fs::write(dir.join(&dead_temp), "half a file").unwrap();
    fs::create_dir(dir.join(&dead_staging)).unwrap();
    fs::write(dir.join(&dead_staging).join("render.exr"), "staged").unwrap();
    fs::write(dir.join(&live_temp), "being written").unwrap();
    fs::create_dir(dir.join(&live_staging)).unwrap();
    fs::write(dir.join(&locked_temp), "being written elsewhere").unwrap();
    let _held = nix::fcntl::Flock::lock(
        fs::File::open(dir.join(&locked_temp)).unwrap(),
        nix::fcntl::FlockArg::LockExclusive,
    )
    .unwrap();
    fs::write(dir.join("mine.txt"), "the user's own").unwrap();

    let mut set = OutputSet::create(dir).unwrap();
    set.stage("solution.exr", b"new").unwrap();
    set.commit().unwrap();
    let mut kept = vec![live_staging.clone(), live_temp.clone(), locked_temp.clone()];
    kept.extend(["mine.txt".to_string(), "solution.exr".to_string()]);
    kept.sort();
    assert_eq!(names(dir), kept);

    // A reader's recovery and a single file's write do the same.
    let other = format!(".baked.bin.tmp-{dead}-1");
    fs::write(dir.join(&other), "x").unwrap();
    output::recover(dir).unwrap();
    assert_eq!(names(dir), kept);
    fs::write(dir.join(&other), "x").unwrap();
    output::write_atomic(&dir.join("mine.txt"), b"again").unwrap();
    assert_eq!(names(dir), kept);
}

/// A commit killed after its commit point, at every step of putting its
/// files in place, is finished by the next reader: the earlier run's
/// files that the set replaces are gone, the new ones are in place.
#[test]
fn an_interrupted_commit_is_rolled_forward() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    for (name, text) in [
        ("report.json", "old seal"),
        ("solution.exr", "old"),
        ("snapshot-00001.exr", "old"),
        ("mine.txt", "the user's own"),
    ] {
        fs::write(dir.join(name), text).unwrap();
    }
    // What a killed commit leaves: the journal folder, the old seal and
    // the snapshot already removed, solution.exr already renamed.
    let journal = dir.join(".nusselt-commit");
    fs::create_dir(&journal).unwrap();
    fs::write(
        journal.join(".nusselt-journal"),
        "nusselt-journal 1\nremove snapshot-00001.exr\nplace solution.exr\nplace report.json\n",
    )
    .unwrap();
    fs::write(journal.join("report.json"), "new seal").unwrap();
    fs::remove_file(dir.join("report.json")).unwrap();
    fs::remove_file(dir.join("snapshot-00001.exr")).unwrap();
    fs::write(dir.join("solution.exr"), "new").unwrap();
    output::recover(dir).unwrap();
    assert_eq!(
        entries(dir),
        [
            ("mine.txt".to_string(), Some(b"the user's own".to_vec())),
            ("report.json".to_string(), Some(b"new seal".to_vec())),
            ("solution.exr".to_string(), Some(b"new".to_vec())),
        ]
    );
    // A commit killed while removing its finished folder.
    fs::create_dir(&journal).unwrap();
    output::recover(dir).unwrap();
    assert_eq!(names(dir), ["mine.txt", "report.json", "solution.exr"]);
}

/// A later solve removes the earlier run's snapshots and lightmaps that it
/// does not write, keeps the user's files, and its `report.json` lists
/// every other file of the run with its size and CRC-32.
#[test]
fn a_new_run_replaces_the_earlier_runs_snapshots_and_lists_its_files() {
    let root = tempfile::tempdir().unwrap();
    let root = root.path();
    let scene = scene(root);
    let dir: PathBuf = root.join("res");
    nusselt_ok(
        &solve_args(
            &scene,
            "res",
            &["--width", "8", "--snapshots", "1", "--lightmap", "64"],
        ),
        root,
    );
    assert!(names(&dir).iter().any(|n| n.starts_with("snapshot-")));
    fs::write(dir.join("snapshot-notes.txt"), "the user's own").unwrap();
    nusselt_ok(&solve_args(&scene, "res", &["--width", "8"]), root);
    let now = names(&dir);
    assert_eq!(
        now,
        [
            "baked.bin",
            "baked.gltf",
            "render.exr",
            "render.png",
            "report.json",
            "snapshot-notes.txt",
            "solution.exr",
        ]
    );
    let report: Value =
        serde_json::from_slice(&fs::read(dir.join("report.json")).unwrap()).unwrap();
    let files = report["files"].as_array().unwrap();
    let listed: Vec<&str> = files.iter().map(|f| f["name"].as_str().unwrap()).collect();
    assert_eq!(
        listed,
        [
            "solution.exr",
            "baked.bin",
            "baked.gltf",
            "render.exr",
            "render.png"
        ]
    );
    for file in files {
        let bytes = fs::read(dir.join(file["name"].as_str().unwrap())).unwrap();
        assert_eq!(file["bytes"], bytes.len() as u64);
        assert_eq!(file["crc32"], crc32fast::hash(&bytes));
    }
    // A run that fails is one error line and leaves all of this alone.
    let before = entries(&dir);
    let out = nusselt(&solve_args(&scene, "res", &["--width", "0"]), root);
    assert!(!out.status.success());
    assert_eq!(entries(&dir), before);
}
