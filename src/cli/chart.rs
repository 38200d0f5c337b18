//! `nusselt chart`: convergence charts from the `report.json` of one or
//! more solves.
//!
//! Invariant: the charts are written together or not at all.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use nusselt::lab::convergence;
use nusselt::output::OutputSet;

#[derive(Args, Debug)]
pub struct ChartArgs {
    /// report.json files written by `nusselt solve`.
    #[arg(required = true)]
    reports: Vec<PathBuf>,
    /// Output folder for residual-iterations.svg/.png and residual-time.svg/.png.
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
}

/// Runs `nusselt chart`.
pub fn run(args: ChartArgs) -> Result<()> {
    for report in &args.reports {
        super::recover_beside(report)?;
    }
    let runs = args
        .reports
        .iter()
        .map(|p| convergence::read_convergence(p))
        .collect::<nusselt::Result<Vec<_>>>()?;
    let charts = convergence::convergence_charts(&runs)?;
    let mut set = OutputSet::create(&args.output)?.replacing(&[
        "residual-iterations.svg",
        "residual-iterations.png",
        "residual-time.svg",
        "residual-time.png",
    ]);
    for chart in &charts {
        set.stage(&format!("{}.svg", chart.stem), chart.images.svg.as_bytes())?;
        set.stage(&format!("{}.png", chart.stem), &chart.images.png)?;
    }
    set.commit()?;
    for chart in &charts {
        if chart.images.skipped_points > 0 {
            eprintln!(
                "warning: {}: {} points with a zero or negative value were left off the log axes",
                chart.stem, chart.images.skipped_points
            );
        }
    }
    Ok(())
}
