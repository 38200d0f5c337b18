//! Scale-up benchmark of the hierarchical solver: load, BVH, cluster tree
//! and linking, refinement, solve (and optionally the output mesh) on each
//! scene given, with elements, links, rays and peak memory; then the growth
//! exponent of solve time against triangle count.
//!
//! Run: `cargo run --release --example bench-scale -- SCENE...` on the
//! scale-up scenes (`scenes/scale/office-10k.gltf`, and larger ones written
//! by `gen-scenes -- --scale N DIR`), smallest first. Prints one Markdown
//! row a scene. Peak memory is the process's so far: run one scene a
//! process for a per-scene figure.

#[path = "bench_common.rs"]
mod bench_common;

use std::path::PathBuf;
use std::time::Instant;

use bench_common::peak_rss_mib;
use clap::{Parser, ValueEnum};
use nusselt::hierarchical::{
    Accuracy, Clustering, HierarchicalSettings, Preset, solve_hierarchical,
};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::meshing::leaf::{VertexValues, output_mesh};
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Level {
    Preview,
    Default,
    High,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Mode {
    Auto,
    On,
    Off,
}

#[derive(Parser)]
struct Args {
    /// Scenes, smallest first.
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    #[arg(long, value_enum, default_value_t = Level::Default)]
    accuracy: Level,
    #[arg(long, value_enum, default_value_t = Mode::Auto)]
    clustering: Mode,
    /// Also time the output mesh (a final gather at every vertex).
    #[arg(long)]
    output_mesh: bool,
    /// Stop refining at this many seconds of solving (per scene).
    #[arg(long)]
    time_budget: Option<f64>,
    /// The solver's memory budget, GiB.
    #[arg(long, default_value_t = 2.0)]
    memory_budget: f64,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let settings = HierarchicalSettings {
        accuracy: Accuracy::preset(match args.accuracy {
            Level::Preview => Preset::Preview,
            Level::Default => Preset::Default,
            Level::High => Preset::High,
        }),
        clustering: match args.clustering {
            Mode::Auto => Clustering::Auto,
            Mode::On => Clustering::On,
            Mode::Off => Clustering::Off,
        },
        time_budget: args.time_budget,
        memory_budget: (args.memory_budget * (1u64 << 30) as f64) as u64,
        ..HierarchicalSettings::default()
    };
    println!(
        "| scene | triangles | patches | load (s) | BVH (s) | linking (s) | refinement (s) | solve (s) | output mesh (s) | total (s) | elements | links | cluster links | rays | absorbed/emitted | budget | peak RSS (MiB) |"
    );
    println!(
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|"
    );
    let mut points = Vec::new();
    for path in &args.scenes {
        let start = Instant::now();
        let scene = load_scene(path, &LoadOptions::default())?;
        let load = start.elapsed().as_secs_f64();
        let t = Instant::now();
        let bvh = TriangleBvh::of_scene(&scene);
        let build = t.elapsed().as_secs_f64();
        let s = solve_hierarchical(&scene, &bvh, &settings, &Progress::hidden());
        let mesh = if args.output_mesh {
            let t = Instant::now();
            let m = output_mesh(&scene, &bvh, &s, VertexValues::PointGather { seed: 0 });
            drop(m);
            Some(t.elapsed().as_secs_f64())
        } else {
            None
        };
        let total = start.elapsed().as_secs_f64();
        let (mut emitted, mut absorbed) = (0.0, 0.0);
        for id in s.hierarchy.leaves() {
            let e = s.hierarchy.get(id);
            let p = &scene.patches[e.patch as usize];
            emitted += (p.emission * e.area).element_sum();
            absorbed += ((glam::DVec3::ONE - p.reflectance) * s.irradiance[id.index()] * e.area)
                .element_sum();
        }
        let triangles = scene.stats.input_triangles;
        points.push((triangles as f64, total));
        println!(
            "| {} | {triangles} | {} | {load:.2} | {build:.2} | {:.2} | {:.2} | {:.2} | {} | {total:.1} | {} | {} | {} | {} | {:.4} | {} | {:.0} |",
            path.file_name().unwrap_or_default().to_string_lossy(),
            scene.patches.len(),
            s.times.linking,
            s.times.refinement,
            s.times.solve,
            mesh.map_or("–".into(), |m| format!("{m:.2}")),
            s.hierarchy.len(),
            s.link_count(),
            s.cluster_link_count(),
            s.visibility_rays,
            absorbed / emitted,
            s.budget.map_or("–".into(), |b| b.kind.noun().to_string()),
            peak_rss_mib()
        );
    }
    if points.len() >= 2 {
        // Least-squares slope of ln(total time) against ln(triangles).
        let n = points.len() as f64;
        let (lx, ly): (Vec<f64>, Vec<f64>) = points.iter().map(|(x, y)| (x.ln(), y.ln())).unzip();
        let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
        let sxy: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
        let sxx: f64 = lx.iter().map(|x| (x - mx).powi(2)).sum();
        println!(
            "\ngrowth exponent of total time against triangles: {:.2}",
            sxy / sxx
        );
    }
    Ok(())
}
