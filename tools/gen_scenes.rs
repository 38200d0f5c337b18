//! Writes nusselt's bundled scenes (glTF 2.0) and their README, or one
//! member of the scale-up family.
//!
//! Usage:
//! - `cargo run --release --example gen-scenes -- scenes/`: every bundled
//!   scene (including `scale/office-10k`) and `scenes/README.md`;
//! - `cargo run --release --example gen-scenes -- --scale 1000000 DIR`: the
//!   scale-up scene for about that many triangles, as
//!   `DIR/office-<size>.gltf` and `.bin` (see `tools/scenegen/scale.rs`);
//! - `cargo run --release --example gen-scenes -- --fan 10000 DIR`: a disc
//!   of that many slivers under a light, `DIR/fan-<n>.gltf` and `.bin`
//!   (see `tools/scenegen/fan.rs`).
//!
//! The output is deterministic: running it again gives byte-identical files.
//! The scene definitions live in `tools/scenegen/`.

mod scenegen;

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};

/// Largest accepted `--scale` target: the loader's triangle cap is far
/// above it, but such files are gigabytes.
const MAX_SCALE: usize = 20_000_000;

const USAGE: &str = "usage: gen-scenes OUTPUT_DIR | gen-scenes --scale TRIANGLES OUTPUT_DIR \
                     | gen-scenes --fan SLIVERS OUTPUT_DIR";

fn run(args: &[OsString]) -> Result<()> {
    let paths = match args {
        [dir] if !dir.to_string_lossy().starts_with("--") => {
            scenegen::write_all(&PathBuf::from(dir))?
        }
        [flag, n, dir] if flag == "--fan" => {
            let n = count(flag, n, 3)?;
            scenegen::write_fan(&PathBuf::from(dir), n)?
        }
        [flag, target, dir] if flag == "--scale" => {
            let target = count(flag, target, 1)?;
            let (paths, triangles) = scenegen::write_scale(&PathBuf::from(dir), target)?;
            println!("{triangles} triangles (target {target})");
            paths
        }
        _ => bail!("{USAGE}"),
    };
    for p in paths {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// The whole number `value` of option `flag`, in `least..=MAX_SCALE`.
fn count(flag: &OsString, value: &OsString, least: usize) -> Result<usize> {
    let flag = flag.to_string_lossy();
    let n: usize = value
        .to_str()
        .and_then(|t| t.replace('_', "").parse().ok())
        .with_context(|| format!("{flag} {}: not a whole number", value.to_string_lossy()))?;
    if !(least..=MAX_SCALE).contains(&n) {
        bail!("{flag} {n}: must lie in {least}..={MAX_SCALE}");
    }
    Ok(n)
}

fn main() -> ExitCode {
    let args: Vec<OsString> = std::env::args_os().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
