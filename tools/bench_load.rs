//! Loading cost of large scenes: glTF load (with patch building) and the
//! occluder BVH, without solving.
//!
//! Run: `cargo run --release --example bench-load -- SCENE...`, for example
//! on the scale-up scenes written by `gen-scenes -- --scale N DIR`. Prints
//! one Markdown row a scene: input triangles, degenerate triangles dropped,
//! merged quads, patches, emitting patches, load and BVH build times, and
//! the process's peak resident memory so far (run one scene a process for
//! a per-scene peak).

#[path = "bench_common.rs"]
mod bench_common;

use std::path::PathBuf;
use std::time::Instant;

use bench_common::peak_rss_mib;
use nusselt::load::{LoadOptions, load_scene};
use nusselt::visibility::TriangleBvh;

fn main() -> anyhow::Result<()> {
    let scenes: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    if scenes.is_empty() {
        anyhow::bail!("usage: bench-load SCENE...");
    }
    println!(
        "| scene | triangles | dropped | merged quads | patches | emitting | load (s) | BVH (s) | peak RSS (MiB) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for path in scenes {
        let start = Instant::now();
        let scene = load_scene(&path, &LoadOptions::default())?;
        let load = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let bvh = TriangleBvh::of_scene(&scene);
        let build = start.elapsed().as_secs_f64();
        drop(bvh);
        let emitting = scene
            .patches
            .iter()
            .filter(|p| p.emission.max_element() > 0.0)
            .count();
        println!(
            "| {} | {} | {} | {} | {} | {} | {load:.2} | {build:.2} | {:.0} |",
            path.display(),
            scene.stats.input_triangles,
            scene.stats.degenerate_dropped,
            scene.stats.merged_quads,
            scene.patches.len(),
            emitting,
            peak_rss_mib()
        );
    }
    Ok(())
}
