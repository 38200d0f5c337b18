//! The hard-interior benchmark of issue 21: each scene × accuracy preset
//! scored against a path-traced point table (time, point error median and
//! 90th percentile, mean and power bias, absorbed / emitted, and beside
//! them the error the solve estimates itself, `report.estimated_error`),
//! and, in the same run on the same machine, the default solve's image
//! against the path tracer's at equal wall time.
//!
//! Run: `cargo run --release --example bench-hard -- --points SCENE=TABLE.csv
//! ... --image SCENE=TRUTH.exr ...`. Tables come from `nusselt probe SCENE
//! --random N --spp S -o TABLE.csv`, truths from `nusselt reference SCENE
//! --width W --height H --spp S -o TRUTH.exr` (its `.noise.exr` beside it).
//! Image runs use the scene's camera at the truth's size. The path tracer's
//! paths per pixel are set from a short pilot run so that its wall time
//! matches the solve's (`report.times.total`: everything but loading and
//! writing); both images are scored against the truth with its noise
//! removed (`nusselt compare`'s noise-corrected relative RMSE). Prints
//! Markdown tables; ratios within one run hold, absolute seconds drift
//! between runs on shared machines.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use nusselt::hierarchical::{Accuracy, Preset};
use nusselt::lab::compare::{Metrics, Named, compare_frames, noise_path};
use nusselt::lab::points::{read_table, score};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::output::exr::read_image;
use nusselt::pipeline::{SolveRun, SolveSettings, solve};
use nusselt::reference::{ReferenceSettings, render_reference};
use nusselt::render::frame::Frame;
use nusselt::render::view::{View, ViewOverrides};
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;

/// `SCENE=FILE`.
fn pair(s: &str) -> Result<(PathBuf, PathBuf), String> {
    let (a, b) = s
        .split_once('=')
        .ok_or_else(|| format!("expected SCENE=FILE, got {s:?}"))?;
    Ok((a.into(), b.into()))
}

#[derive(Parser)]
struct Args {
    /// SCENE=TABLE.csv: score every preset's solution at the table's points.
    #[arg(long = "points", value_parser = pair)]
    points: Vec<(PathBuf, PathBuf)>,
    /// SCENE=TRUTH.exr: the solve's image against the path tracer's at equal
    /// wall time, for the scene's camera at the truth's size.
    #[arg(long = "image", value_parser = pair)]
    images: Vec<(PathBuf, PathBuf)>,
    /// Presets of the point runs.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "preview,default,high"
    )]
    presets: Vec<Preset>,
    /// Presets of the image runs.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "default")]
    image_presets: Vec<Preset>,
    /// Passed to every solve as `--bf-relative-floor`.
    #[arg(long)]
    bf_relative_floor: Option<f64>,
}

fn settings(preset: Preset, relative_floor: Option<f64>, view: ViewOverrides) -> SolveSettings {
    let mut s = SolveSettings::default();
    s.hierarchical.accuracy = Accuracy::preset(preset);
    if let Some(f) = relative_floor {
        s.hierarchical.accuracy.bf_relative_floor = f;
    }
    s.view = view;
    s
}

fn name(path: &Path) -> String {
    path.file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .into()
}

fn preset_name(p: Preset) -> &'static str {
    match p {
        Preset::Preview => "preview",
        Preset::Default => "default",
        Preset::High => "high",
    }
}

/// Absorbed / emitted, pooled over the channels.
fn closure(run: &SolveRun) -> f64 {
    let p = &run.report.power;
    p.absorbed.iter().sum::<f64>() / p.emitted.iter().sum::<f64>()
}

fn load(path: &Path) -> anyhow::Result<Scene> {
    Ok(load_scene(path, &LoadOptions::default())?)
}

/// The truth and its noise image.
fn truth(path: &Path) -> anyhow::Result<(Frame, Frame)> {
    Ok((read_image(path)?, read_image(&noise_path(path))?))
}

fn image_error(test: &Frame, truth: &(Frame, Frame)) -> anyhow::Result<Metrics> {
    let named = |frame| Named {
        path: Path::new("-"),
        frame,
    };
    Ok(compare_frames(
        named(test),
        named(&truth.0),
        Some(named(&truth.1)),
    )?)
}

/// Noise-corrected relative RMSE and mean test / truth.
fn figures(m: &Metrics) -> (f64, f64) {
    let o = &m.overall;
    (
        o.noise_corrected_rmse.unwrap_or(o.rmse) / o.mean_reference,
        o.mean_test / o.mean_reference,
    )
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let hidden = Progress::hidden();
    if !args.points.is_empty() {
        println!(
            "| scene | preset | total s | output mesh s | links | median | p90 | worst | mean bias | power bias | absorbed / emitted | estimated: seam median, p90 |"
        );
        println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    }
    for (scene_path, table_path) in &args.points {
        let scene = load(scene_path)?;
        let table = read_table(table_path)?;
        for &preset in &args.presets {
            let s = settings(preset, args.bf_relative_floor, ViewOverrides::default());
            let run = solve(&scene, &s, &hidden)?;
            let (p, _) = score(&run.mesh, &table)?;
            let t = &run.report.times;
            println!(
                "| {} | {} | {:.1} | {:.1} | {} | {:.2} % | {:.2} % | {:.2} | {:+.2} % | {:+.2} % | {:.4} | {} |",
                name(scene_path),
                preset_name(preset),
                t.total,
                t.output_mesh,
                run.report.counts.links,
                100.0 * p.median,
                100.0 * p.p90,
                p.worst,
                100.0 * p.mean_bias,
                100.0 * p.power_bias,
                closure(&run),
                run.report
                    .estimated_error
                    .as_ref()
                    .map_or("–".into(), |e| format!(
                        "{:.2} %, {:.2} %",
                        100.0 * e.median,
                        100.0 * e.p90
                    ))
            );
        }
    }
    if !args.images.is_empty() {
        println!(
            "\n| scene | run | wall s | paths / pixel | relative RMSE | mean / truth | path tracer / radiosity error |"
        );
        println!("|---|---|---:|---:|---:|---:|---:|");
    }
    for (scene_path, truth_path) in &args.images {
        let scene = load(scene_path)?;
        let truth = truth(truth_path)?;
        let size = ViewOverrides {
            width: Some(truth.0.width),
            height: Some(truth.0.height),
            ..ViewOverrides::default()
        };
        let view = View::resolve(scene.cameras.first(), scene.bounds, &size)?;
        let pixels = f64::from(view.width) * f64::from(view.height);
        // Paths per second of this scene, from a pilot of 4 paths a pixel.
        let pilot = ReferenceSettings {
            samples_per_pixel: 4,
            seed: 1,
            max_bounces: None,
        };
        let rate = render_reference(&scene, &view, &pilot, &hidden)?
            .stats
            .samples_per_second;
        for &preset in &args.image_presets {
            let s = settings(preset, args.bf_relative_floor, size.clone());
            let start = Instant::now();
            let run = solve(&scene, &s, &hidden)?;
            let wall = start.elapsed().as_secs_f64();
            let (solve_error, solve_mean) = figures(&image_error(&run.frame, &truth)?);
            let spp = ((wall * rate / pixels).round() as u32).max(2);
            let traced = ReferenceSettings {
                samples_per_pixel: spp,
                seed: 2,
                max_bounces: None,
            };
            let pt = render_reference(&scene, &view, &traced, &hidden)?;
            let (pt_error, pt_mean) = figures(&image_error(&pt.image, &truth)?);
            let scene_name = name(scene_path);
            println!(
                "| {scene_name} | `solve` {} | {wall:.1} | – | {:.2} % | {solve_mean:.3} | |",
                preset_name(preset),
                100.0 * solve_error
            );
            println!(
                "| {scene_name} | path tracer | {:.1} | {spp} | {:.2} % | {pt_mean:.3} | {:.2} |",
                pt.stats.time_seconds,
                100.0 * pt_error,
                pt_error / solve_error
            );
        }
    }
    Ok(())
}
