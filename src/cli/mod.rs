//! The `nusselt` command line: the subcommands, one file each, and the
//! argument groups they share ([`args`]).
//!
//! Owns: argument parsing (clap, in two stages: flags parsed and
//! converted here, ranges checked by the library's settings), the thread
//! pool, and turning every failure into one `error:` line on stderr with
//! exit code 1 (usage errors exit 2, through clap).
//!
//! Invariant: nothing a user can cause ends in a panic message or a
//! backtrace; an internal bug is still reported as one line.

mod args;
mod chart;
mod compare;
mod formfactors;
mod help;
mod manual;
mod probe;
mod reference;
mod render;
mod solve;
mod study;

use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "nusselt",
    version,
    about = "Radiosity for glTF scenes of diffuse surfaces"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Solve a scene and write solution.exr, baked.gltf, render.exr/png and report.json.
    Solve(Box<solve::SolveArgs>),
    /// Render a new view of an earlier solution without solving again.
    Render(render::RenderArgs),
    /// Form factors between the scene's surfaces (glTF nodes), as CSV on stdout.
    Formfactors(formfactors::FormFactorArgs),
    /// Compare an image with a reference: metrics as JSON on stdout, error images with -o.
    Compare(compare::CompareArgs),
    /// Convergence charts (SVG and PNG) from the report.json of one or more solves.
    Chart(chart::ChartArgs),
    /// Path-trace an independent reference image of the same view, with a
    /// per-pixel noise image and a JSON sidecar.
    Reference(reference::ReferenceArgs),
    /// Path-trace the radiosity at surface points, with standard errors: a
    /// table that `compare SOLUTION.exr TABLE.csv` scores solutions against.
    Probe(probe::ProbeArgs),
    /// Sweep methods and settings against a path-traced reference: results.csv, charts, contact sheet.
    Study(study::StudyArgs),
    /// Print the shell completion script for SHELL (bash, zsh, fish, elvish, powershell).
    Completions(manual::CompletionsArgs),
    /// Print the man page (roff), or write one per subcommand with -o.
    Manpage(manual::ManpageArgs),
}

/// Runs the command line: parses the arguments, runs the subcommand, and
/// prints a failure as one `error:` line.
pub fn main() -> ExitCode {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!(
            "error: internal error (a bug in nusselt): {}{at}",
            msg.replace('\n', " ")
        );
    }));
    let command = help::tailor(Cli::command());
    let matches = command.clone().get_matches();
    // A flag the chosen method does not read is a usage error, not ignored.
    let inapplicable = match matches.subcommand() {
        Some(("solve", m)) => solve::inapplicable(m),
        Some(("formfactors", m)) => formfactors::inapplicable(m),
        _ => None,
    };
    if let Some(message) = inapplicable {
        clap::Error::raw(
            clap::error::ErrorKind::ArgumentConflict,
            format!("{message}\n"),
        )
        .exit();
    }
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    on_interrupt();
    // The command is only read (for completions and man pages), never
    // left half-changed by a panic: asserting unwind safety is sound.
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match cli.command {
        Command::Solve(args) => solve::run(*args),
        Command::Render(args) => render::run(args),
        Command::Formfactors(args) => formfactors::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Chart(args) => chart::run(args),
        Command::Reference(args) => reference::run(args),
        Command::Probe(args) => probe::run(args),
        Command::Study(args) => study::run(args),
        Command::Completions(args) => manual::completions(args, command.clone()),
        Command::Manpage(args) => manual::manpage(args, command.clone()),
    }));
    match result {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(err)) => {
            eprintln!("error: {}", printable(&format!("{err:#}")));
            ExitCode::from(1)
        }
        Err(_) => ExitCode::from(1),
    }
}

/// Loads the scene at `path` under a "load" spinner.
fn load(
    path: &std::path::Path,
    options: &nusselt::LoadOptions,
    progress: &nusselt::util::progress::Progress,
) -> Result<nusselt::scene::Scene> {
    let phase = progress.spinner("load");
    phase.message(path.display().to_string());
    Ok(nusselt::load::load_scene(path, options)?)
}

/// On Ctrl-C (or SIGTERM): clear the progress line, say "interrupted",
/// remove this run's staged files and exit 130. Outputs are put in place
/// only after success, all together (`nusselt::output::commit`), so an
/// interrupted run leaves earlier results as they were; one interrupted
/// during its last few renames finishes them first.
fn on_interrupt() {
    let _ = ctrlc::set_handler(|| {
        use std::io::{IsTerminal, Write};
        let mut err = std::io::stderr();
        if err.is_terminal() {
            let _ = write!(err, "\r\x1b[2K");
        }
        let _ = writeln!(err, "interrupted");
        nusselt::output::clean_up_and_exit(130);
    });
}

/// Before `file` is read as (part of) a result: finishes a commit of its
/// folder that a killed run left half done (`nusselt::output::recover`), so
/// that what is read belongs to one run.
fn recover_beside(file: &std::path::Path) -> nusselt::Result<()> {
    let dir = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => std::path::Path::new("."),
    };
    nusselt::output::recover(dir)
}

/// `text` on one line, safe for a terminal: line breaks become spaces and
/// other control characters (an ESC or `\r` in a node name of an untrusted
/// scene) are shown escaped, never sent raw.
fn printable(text: &str) -> String {
    text.chars()
        .map(|c| match c {
            '\n' => " ".to_string(),
            c if c.is_control() => c.escape_unicode().to_string(),
            c => c.to_string(),
        })
        .collect()
}

/// Prints a warning of the run on stderr, as one line ([`printable`]).
fn warn(warning: &str) {
    eprintln!("warning: {}", printable(warning));
}

/// Sets up the global thread pool (`--threads`).
fn init_threads(threads: Option<usize>) -> Result<()> {
    if let Some(n) = threads {
        // At least 1: the flag's parser refuses 0.
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("setting up the thread pool")?;
    }
    Ok(())
}

/// A settings check of the library, its message (which names the option)
/// as the error line.
fn checked(result: nusselt::Result<()>) -> Result<()> {
    match result {
        Err(nusselt::Error::Setting(message)) => bail!(message),
        other => Ok(other?),
    }
}
