//! The classic methods on the Cornell box at several uniform resolutions:
//! element count, form-factor time, solve time, peak memory and iterations
//! to the residual tolerance.
//!
//! Run: `cargo run --release --example bench-classic [-- SCENE [FRACTIONS]]`
//! where FRACTIONS is a comma list of element sizes as fractions of the
//! scene diagonal (default 0.1,0.05,0.033). Each (resolution, method)
//! runs in a child process of its own so that its peak resident memory
//! (Linux `VmHWM`) is its own. Prints a Markdown table.

#[path = "bench_common.rs"]
mod bench_common;
use bench_common::peak_rss_mib;

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use nusselt::classic::matrix::{FormFactorMatrix, Kernel, MatrixSettings};
use nusselt::classic::solve::{ClassicMethod, Convergence, System, solve};
use nusselt::classic::uniform::UniformMesh;
use nusselt::load::{LoadOptions, load_scene};
use nusselt::util::progress::Progress;
use nusselt::visibility::TriangleBvh;

const METHODS: [(&str, ClassicMethod); 4] = [
    ("direct", ClassicMethod::Direct),
    ("jacobi", ClassicMethod::Jacobi),
    ("gauss-seidel", ClassicMethod::GaussSeidel),
    ("shooting", ClassicMethod::Shooting),
];

/// One configuration, in this (child) process: prints one table row.
fn child(scene_path: &str, fraction: f64, method: &str) -> anyhow::Result<()> {
    let scene = load_scene(Path::new(scene_path), &LoadOptions::default())?;
    let (_, m) = METHODS
        .iter()
        .find(|(n, _)| *n == method)
        .ok_or_else(|| anyhow::anyhow!("unknown method {method}"))?;
    let mesh = UniformMesh::new(&scene, fraction * scene.diagonal());
    let bvh = TriangleBvh::of_scene(&scene);
    let t = Instant::now();
    let settings = MatrixSettings {
        kernel: Kernel::PointPolygon,
        ..MatrixSettings::default()
    };
    let (matrix, _) = FormFactorMatrix::assemble(&mesh, &bvh, &settings, &Progress::hidden())?;
    let ff_time = t.elapsed().as_secs_f64();
    let (rho, e, area) = mesh.element_values(&scene);
    let system = System {
        matrix: &matrix,
        reflectance: &rho,
        emission: &e,
        area: &area,
    };
    let conv = Convergence {
        tolerance: 1e-6,
        max_iterations: 10_000_000,
    };
    let t = Instant::now();
    let s = solve(&system, *m, &conv, 8 << 30, &mut |_, _| {})?;
    let solve_time = t.elapsed().as_secs_f64();
    println!(
        "| {fraction} | {} | {method} | {:.3} | {:.3} | {} | {} | {:.0} |",
        mesh.elements.len(),
        ff_time,
        solve_time,
        s.history.len(),
        if s.converged { "yes" } else { "no" },
        peak_rss_mib()
    );
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() == 5 && args[1] == "--child" {
        return child(&args[2], args[3].parse()?, &args[4]);
    }
    let scene = args
        .get(1)
        .cloned()
        .unwrap_or_else(|| "scenes/cornell-box.gltf".into());
    let fractions = args
        .get(2)
        .cloned()
        .unwrap_or_else(|| "0.1,0.05,0.033".into());
    println!(
        "Scene {scene}; point-polygon kernel, 4 visibility rays; tolerance 1e-6 (gathering: relative change per sweep; shooting: unshot/emitted power).\n"
    );
    println!(
        "| element size / diagonal | elements | method | form factors (s) | solve (s) | iterations | converged | peak memory (MiB) |"
    );
    println!("|---:|---:|---|---:|---:|---:|---|---:|");
    let exe = std::env::current_exe()?;
    for fraction in fractions.split(',') {
        for (method, _) in METHODS {
            let out = Command::new(&exe)
                .args(["--child", &scene, fraction, method])
                .output()?;
            print!("{}", String::from_utf8_lossy(&out.stdout));
            if !out.status.success() {
                eprintln!(
                    "{fraction} {method}: {}",
                    String::from_utf8_lossy(&out.stderr).trim()
                );
            }
        }
    }
    Ok(())
}
