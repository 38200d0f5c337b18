//! Writes nusselt's bundled scenes (glTF 2.0) and their README.
//!
//! Usage: `cargo run --release --example gen-scenes -- scenes/`
//!
//! The output is deterministic: running it again gives byte-identical files.
//! The scene definitions live in `tools/scenegen/`.

mod scenegen;

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args = std::env::args_os().skip(1);
    let (Some(dir), None) = (args.next(), args.next()) else {
        eprintln!("usage: gen-scenes OUTPUT_DIR");
        return ExitCode::from(2);
    };
    match scenegen::write_all(&PathBuf::from(dir)) {
        Ok(paths) => {
            for p in paths {
                println!("wrote {}", p.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
