//! The hierarchical solver across its accuracy presets: how elements,
//! links, visibility rays, time and memory grow as the thresholds tighten,
//! and the growth exponent of links against elements (the O(n) link count
//! that [HSA91] claims shows as an exponent near 1; all-pairs linking
//! would show 2).
//!
//! Run: `cargo run --release --example bench-hierarchical [-- [SCENE...]
//! [PRESETS] [--threads N]]` where each SCENE is a `.gltf`/`.glb` file
//! (default: `scenes/cornell-box.gltf scenes/three-rooms.gltf`) and
//! PRESETS a comma list of accuracy presets (default
//! `preview,default,high`). `--threads N` sets `RAYON_NUM_THREADS` for the
//! measured processes; without it they use every core, or whatever
//! `RAYON_NUM_THREADS` already says.
//!
//! Each (scene, preset) runs in a child process of its own so that its
//! peak resident memory (Linux `VmHWM`) is its own; the child reports its
//! row as one JSON line. Prints a Markdown table, then the exponents.

#[path = "bench_common.rs"]
mod bench_common;
use bench_common::peak_rss_mib;

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use nusselt::hierarchical::{Accuracy, HierarchicalSettings, Preset, solve_hierarchical};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::meshing::leaf::leaf_output_mesh;
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

const DEFAULT_SCENES: [&str; 2] = ["scenes/cornell-box.gltf", "scenes/three-rooms.gltf"];
const DEFAULT_PRESETS: &str = "preview,default,high";

/// One measured configuration, as the child reports it.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Row {
    scene: String,
    preset: String,
    threads: usize,
    patches: usize,
    elements: usize,
    leaves: usize,
    links: u64,
    visibility_rays: u64,
    linking: f64,
    refinement: f64,
    solve: f64,
    /// Wall time of `solve_hierarchical` as a whole.
    total: f64,
    meshing: f64,
    /// Triangles of the leaf output mesh.
    triangles: usize,
    rounds: usize,
    /// Gather iterations over all rounds.
    iterations: usize,
    converged: bool,
    /// Refinement stopped at `max_rounds` or at the link budget.
    cut_short: bool,
    bytes_per_link: f64,
    peak_mib: f64,
}

/// A preset by its command-line name (`preview`, `default`, `high`, …),
/// through the same serde names `--accuracy` and the report use.
fn parse_preset(name: &str) -> anyhow::Result<Preset> {
    serde_json::from_value(serde_json::Value::String(name.to_string()))
        .map_err(|_| anyhow::anyhow!("unknown accuracy preset {name:?}"))
}

/// One configuration, in this (child) process: prints its row as JSON.
fn child(scene_path: &str, preset_name: &str) -> anyhow::Result<()> {
    let preset = parse_preset(preset_name)?;
    let scene = load_scene(Path::new(scene_path), &LoadOptions::default())?;
    let bvh = TriangleBvh::of_scene(&scene);
    let settings = HierarchicalSettings {
        accuracy: Accuracy::preset(preset),
        ..HierarchicalSettings::default()
    };
    let t = Instant::now();
    let solution = solve_hierarchical(&scene, &bvh, &settings, &Progress::hidden());
    let total = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mesh = leaf_output_mesh(&scene, &solution);
    let meshing = t.elapsed().as_secs_f64();
    let links = solution.link_count();
    let row = Row {
        scene: scene_name(scene_path),
        preset: preset_name.to_string(),
        threads: rayon::current_num_threads(),
        patches: scene.patches.len(),
        elements: solution.hierarchy.len(),
        leaves: solution.hierarchy.leaf_count(),
        links,
        visibility_rays: solution.visibility_rays,
        linking: solution.times.linking,
        refinement: solution.times.refinement,
        solve: solution.times.solve,
        total,
        meshing,
        // The mesh is still alive: its memory counts in the peak.
        triangles: mesh.triangles.len(),
        rounds: solution.rounds.len(),
        iterations: solution.history.len(),
        converged: solution.converged,
        cut_short: solution.rounds_exhausted || solution.budget.is_some(),
        bytes_per_link: solution.memory_bytes() as f64 / links.max(1) as f64,
        peak_mib: peak_rss_mib(),
    };
    println!("{}", serde_json::to_string(&row)?);
    Ok(())
}

fn scene_name(path: &str) -> String {
    Path::new(path)
        .file_stem()
        .map_or_else(|| path.to_string(), |s| s.to_string_lossy().into_owned())
}

fn yes_no(b: bool) -> &'static str {
    if b { "yes" } else { "no" }
}

fn print_row(r: &Row) {
    println!(
        "| {} | {} | {} | {} | {} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {} | {} | {} | {:.0} | {:.0} |",
        r.scene,
        r.preset,
        r.patches,
        r.elements,
        r.leaves,
        r.links,
        r.visibility_rays,
        r.linking,
        r.refinement,
        r.solve,
        r.total,
        r.meshing,
        r.triangles,
        r.rounds,
        yes_no(r.converged),
        yes_no(!r.cut_short),
        r.bytes_per_link,
        r.peak_mib,
    );
}

/// Slope of ln(links) against ln(elements): between the first and last
/// rows, and the least-squares fit over all rows. `None` when the rows do
/// not spread over more than one element count.
fn exponents(rows: &[&Row]) -> Option<(f64, f64)> {
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.elements > 0 && r.links > 0)
        .map(|r| ((r.elements as f64).ln(), (r.links as f64).ln()))
        .collect();
    let (first, last) = (pts.first()?, pts.last()?);
    if first.0 == last.0 {
        return None;
    }
    let ends = (last.1 - first.1) / (last.0 - first.0);
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    Some((ends, sxy / sxx))
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() == 3 && args[0] == "--child" {
        return child(&args[1], &args[2]);
    }
    let mut scenes = Vec::new();
    let mut presets = None;
    let mut threads = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--threads" {
            let n: usize = it
                .next()
                .ok_or_else(|| anyhow::anyhow!("--threads needs a number"))?
                .parse()?;
            anyhow::ensure!(n >= 1, "--threads must be at least 1");
            threads = Some(n);
        } else if a.ends_with(".gltf") || a.ends_with(".glb") {
            scenes.push(a.clone());
        } else {
            presets = Some(a.clone());
        }
    }
    if scenes.is_empty() {
        scenes = DEFAULT_SCENES.map(String::from).to_vec();
    }
    let presets: Vec<String> = presets
        .as_deref()
        .unwrap_or(DEFAULT_PRESETS)
        .split(',')
        .map(str::to_string)
        .collect();
    for p in &presets {
        parse_preset(p)?;
    }

    let d = HierarchicalSettings::default();
    println!(
        "bf oracle, {} visibility rays per link, tolerance {} on the total power; threads: {}.\n",
        d.visibility_rays,
        d.tolerance,
        threads.unwrap_or_else(rayon::current_num_threads),
    );
    println!(
        "| scene | preset | patches | elements | leaves | links | visibility rays | linking (s) | refinement (s) | solve (s) | total (s) | meshing (s) | output triangles | rounds | converged | refinement settled | bytes / link | peak memory (MiB) |"
    );
    println!(
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---:|"
    );
    let exe = std::env::current_exe()?;
    let mut rows: Vec<Row> = Vec::new();
    let mut failed = 0;
    for scene in &scenes {
        for preset in &presets {
            let mut cmd = Command::new(&exe);
            cmd.args(["--child", scene, preset]);
            if let Some(n) = threads {
                cmd.env("RAYON_NUM_THREADS", n.to_string());
            }
            let t = Instant::now();
            let out = cmd.output()?;
            eprintln!("{scene} {preset}: {:.1} s wall", t.elapsed().as_secs_f64());
            let stdout = String::from_utf8_lossy(&out.stdout);
            let row = out
                .status
                .success()
                .then(|| serde_json::from_str::<Row>(stdout.trim()).ok())
                .flatten();
            match row {
                Some(r) => {
                    print_row(&r);
                    rows.push(r);
                }
                None => {
                    // The error line, without anyhow's backtrace.
                    let stderr = String::from_utf8_lossy(&out.stderr);
                    let why = stderr.lines().next().unwrap_or("no output");
                    eprintln!("{scene} {preset} failed: {why}");
                    failed += 1;
                }
            }
        }
    }

    println!("\nGrowth of links against elements (slope of ln links over ln elements):\n");
    println!("| scene | first → last preset | least squares, all presets |");
    println!("|---|---:|---:|");
    let mut names: Vec<&str> = rows.iter().map(|r| r.scene.as_str()).collect();
    names.dedup();
    for name in names {
        let of: Vec<&Row> = rows.iter().filter(|r| r.scene == name).collect();
        match exponents(&of) {
            Some((ends, fit)) => println!("| {name} | {ends:.2} | {fit:.2} |"),
            None => println!("| {name} | n/a | n/a |"),
        }
    }
    anyhow::ensure!(failed == 0, "{failed} configuration(s) failed");
    Ok(())
}
