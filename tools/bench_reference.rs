//! The reference path tracer on the Cornell box: paths per second, and the
//! samples per pixel and wall time needed to reach 5 %, 2 % and 1 %
//! relative RMS error.
//!
//! Run: `cargo run --release --example bench-reference [-- SIDE LONG_SPP]`
//! (defaults 256 and 1024). A long run of LONG_SPP paths per pixel stands in
//! for the truth; each short run's mean squared error against it is
//! corrected for the long run's own noise (its noise image: E[(A − R)²] =
//! σ_A² + σ_R²). Relative RMSE = RMSE / mean of the long run, over all
//! pixels and channels. The spp for a target error is extrapolated from the
//! largest short run by the 1/√spp law (checked by the measured column
//! across runs), its time from the measured paths per second. Prints
//! Markdown tables.

use std::path::Path;

use nusselt::load::{LoadOptions, load_scene};
use nusselt::reference::{ReferenceImage, ReferenceSettings, render_reference};
use nusselt::render::view::{View, ViewOverrides};
use nusselt::util::progress::Progress;

fn values(r: &ReferenceImage) -> impl Iterator<Item = (f64, f64)> + '_ {
    r.image
        .pixels
        .iter()
        .zip(&r.noise.pixels)
        .flat_map(|(p, s)| (0..3).map(move |c| (f64::from(p[c]), f64::from(s[c]))))
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let side: u32 = args.first().map_or(Ok(256), |s| s.parse())?;
    let long_spp: u32 = args.get(1).map_or(Ok(1024), |s| s.parse())?;
    let scene = load_scene(
        Path::new("scenes/cornell-box.gltf"),
        &LoadOptions::default(),
    )?;
    let overrides = ViewOverrides {
        width: Some(side),
        height: Some(side),
        ..Default::default()
    };
    let view = View::resolve(scene.cameras.first(), scene.bounds, &overrides)?;
    let run = |spp: u32, seed: u64| {
        let settings = ReferenceSettings {
            samples_per_pixel: spp,
            seed,
            max_bounces: None,
        };
        render_reference(&scene, &view, &settings, &Progress::new(true))
    };
    let threads = rayon::current_num_threads();
    eprintln!("long run: {long_spp} spp at {side} × {side} on {threads} threads …");
    let long = run(long_spp, 1_000_000)?;
    let truth: Vec<f64> = values(&long).map(|(v, _)| v).collect();
    let long_var = values(&long).map(|(_, s)| s * s).sum::<f64>() / truth.len() as f64;
    let mean = long.stats.mean_radiance;

    println!("Cornell box, {side} × {side}, {threads} threads; truth: {long_spp} spp");
    println!(
        "(relative noise of the truth itself: {:.3} %)\n",
        100.0 * long.stats.relative_noise
    );
    println!("| spp | time (s) | Mpaths/s | measured rel. RMSE | predicted (noise image) |");
    println!("|---:|---:|---:|---:|---:|");
    let mut last = None;
    let mut rates = Vec::new();
    for (k, spp) in [16u32, 64, 256].into_iter().enumerate() {
        let r = run(spp, k as u64)?;
        let mse = values(&r)
            .zip(&truth)
            .map(|((a, _), t)| (a - t).powi(2))
            .sum::<f64>()
            / truth.len() as f64;
        let rel = (mse - long_var).max(0.0).sqrt() / mean;
        println!(
            "| {spp} | {:.2} | {:.3} | {:.2} % | {:.2} % |",
            r.stats.time_seconds,
            r.stats.samples_per_second / 1e6,
            100.0 * rel,
            100.0 * r.stats.relative_noise
        );
        rates.push(r.stats.samples_per_second);
        last = Some((spp, rel));
    }
    rates.push(long.stats.samples_per_second);
    println!(
        "| {long_spp} (truth) | {:.2} | {:.3} | — | {:.2} % |",
        long.stats.time_seconds,
        long.stats.samples_per_second / 1e6,
        100.0 * long.stats.relative_noise
    );
    let rate = rates.iter().sum::<f64>() / rates.len() as f64;
    let (spp0, rel0) = last.expect("at least one short run");
    println!("\n| target rel. RMSE | spp (1/√spp law from {spp0} spp) | wall time (s) |");
    println!("|---:|---:|---:|");
    for target in [0.05, 0.02, 0.01] {
        let spp = (f64::from(spp0) * (rel0 / target).powi(2)).ceil();
        let time = spp * f64::from(side * side) / rate;
        println!("| {:.0} % | {spp:.0} | {time:.1} |", 100.0 * target);
    }
    Ok(())
}
