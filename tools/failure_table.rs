//! Writes the failure-mode table: every method of `nusselt::lab::failures` on
//! every stress scene, measured against closed forms and path-traced
//! references.
//!
//! Usage: `cargo run --release --example failure-table [-- --only furnace-099,slivers]`
//!
//! Writes `scenes/stress/FAILURES.md` (or `--out`) atomically and caches the
//! references in `target/failure-table/` (or `--cache`), so a second run
//! only re-runs the methods. With `--only`, the other scenes are left out
//! of the file: use it for exploring, not for the committed table.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use nusselt::lab::failures::{self, Outcome, TableSettings};
use nusselt::load::{LoadOptions, load_scene};

#[derive(Parser)]
#[command(about = "Every method on every stress scene, measured")]
struct Args {
    /// Folder of the stress scenes.
    #[arg(long, default_value = "scenes/stress")]
    scenes: PathBuf,
    /// Only these scenes (comma-separated file stems).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// The Markdown file written.
    #[arg(long, default_value = "scenes/stress/FAILURES.md")]
    out: PathBuf,
    /// Folder caching the path-traced references.
    #[arg(long, default_value = "target/failure-table")]
    cache: PathBuf,
    /// Paths per pixel of the references.
    #[arg(long, default_value_t = TableSettings::default().reference_spp)]
    reference_spp: u32,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: &Args) -> nusselt::Result<()> {
    let t = TableSettings {
        reference_spp: args.reference_spp,
        ..TableSettings::default()
    };
    let mut names: Vec<String> = std::fs::read_dir(&args.scenes)
        .map_err(|e| nusselt::Error::Setting(format!("{}: {e}", args.scenes.display())))?
        .filter_map(|entry| {
            let path = entry.ok()?.path();
            (path.extension()? == "gltf").then(|| path.file_stem()?.to_str().map(String::from))?
        })
        .filter(|n| args.only.is_empty() || args.only.contains(n))
        .collect();
    names.sort();
    let methods = failures::table_methods(&t);
    let mut tables = Vec::new();
    for name in &names {
        let scene = load_scene(
            &args.scenes.join(format!("{name}.gltf")),
            &LoadOptions::default(),
        )?;
        eprintln!("{name}: reference…");
        let start = Instant::now();
        let table =
            failures::scene_table(&scene, name, &t, &methods, Some(&args.cache), |label, o| {
                let what = match o {
                    Outcome::Ran(m) => format!(
                        "{:.2} s, image error {:.1} %, absorbed/emitted {:.3}",
                        m.seconds,
                        100.0 * m.image_error,
                        m.absorbed_ratio
                    ),
                    Outcome::Refused(e) => format!("refused: {e}"),
                    Outcome::Panicked(e) => format!("PANIC: {e}"),
                };
                eprintln!("{name}: {label}: {what}");
            })?;
        eprintln!("{name}: {:.0} s", start.elapsed().as_secs_f64());
        tables.push(table);
    }
    let mut command = "cargo run --release --example failure-table".to_string();
    if args.reference_spp != TableSettings::default().reference_spp {
        command += &format!(" -- --reference-spp {}", args.reference_spp);
    }
    let text = failures::markdown(&tables, &t, &command);
    nusselt::output::write_atomic(&args.out, text.as_bytes())?;
    eprintln!("wrote {}", args.out.display());
    Ok(())
}
