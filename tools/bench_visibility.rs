//! Occlusion-ray throughput on the bundled scenes, on 1 and 2 threads.
//!
//! Run: `cargo run --release --example bench-visibility [-- SCENE...]`
//! (default: every .gltf in scenes/). Segments join area-uniform random
//! points of two random patches, as form-factor visibility does; the table
//! gives BVH build time and million rays per second for each thread count.

use std::path::PathBuf;
use std::time::Instant;

use glam::{DVec2, DVec3};
use nusselt::load::{LoadOptions, load_scene};
use nusselt::sampling::{point_in_polygon, stream};
use nusselt::visibility::TriangleBvh;
use rand::Rng;

const RAYS: usize = 2_000_000;

fn main() -> anyhow::Result<()> {
    let mut scenes: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    if scenes.is_empty() {
        for entry in std::fs::read_dir("scenes")? {
            let p = entry?.path();
            if p.extension().is_some_and(|e| e == "gltf" || e == "glb") {
                scenes.push(p);
            }
        }
        scenes.sort();
    }
    println!(
        "| scene | triangles | BVH build (ms) | visible fraction | Mrays/s, 1 thread | Mrays/s, 2 threads |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for path in scenes {
        let scene = load_scene(&path, &LoadOptions::default())?;
        let bvh = TriangleBvh::of_scene(&scene);
        let areas: Vec<f64> = scene.patches.iter().map(|p| p.area).collect();
        let total: f64 = areas.iter().sum();
        let mut rng = stream(42, 0);
        let pick = |rng: &mut rand_pcg::Pcg64Mcg| -> DVec3 {
            let mut x = rng.random::<f64>() * total;
            let mut k = 0;
            while k + 1 < areas.len() && x >= areas[k] {
                x -= areas[k];
                k += 1;
            }
            point_in_polygon(
                scene.patches[k].vertices(),
                DVec2::new(rng.random(), rng.random()),
            )
        };
        let segments: Vec<(DVec3, DVec3)> = (0..RAYS)
            .map(|_| (pick(&mut rng), pick(&mut rng)))
            .collect();
        let mut rates = Vec::new();
        let mut visible = 0;
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()?;
            let t = Instant::now();
            let result = pool.install(|| bvh.visible_batch(&segments));
            rates.push(RAYS as f64 / t.elapsed().as_secs_f64() / 1e6);
            visible = result.iter().filter(|v| **v).count();
        }
        println!(
            "| {} | {} | {:.1} | {:.3} | {:.2} | {:.2} |",
            path.display(),
            bvh.len(),
            bvh.build_time().as_secs_f64() * 1e3,
            visible as f64 / RAYS as f64,
            rates[0],
            rates[1]
        );
    }
    Ok(())
}
