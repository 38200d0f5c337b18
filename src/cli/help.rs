//! Help text that depends on the subcommand: the wording of a shared flag
//! where it means something different (`--spp`, `--visibility-rays`,
//! `--sampling-tolerance`), each accuracy knob's value under every preset,
//! and the examples shown after the options.
//!
//! Invariant: the preset values shown are read from
//! [`Accuracy::preset`], never written out by hand, so the help cannot
//! drift from what a preset does.

use clap::Command;
use nusselt::hierarchical::{Accuracy, Preset};

use super::args::MAX_PATHS;

/// A knob's value under a preset, as the help shows it.
type PresetValue = fn(&Accuracy) -> String;

/// The hierarchical knobs whose default comes from `--accuracy`, each with
/// its value under a preset.
const PRESET_KNOBS: [(&str, PresetValue); 9] = [
    ("ff_eps", |a| a.ff_eps.to_string()),
    ("bf_eps", |a| a.bf_eps.to_string()),
    ("bf_relative_floor", |a| a.bf_relative_floor.to_string()),
    ("power_eps", |a| a.power_eps.to_string()),
    ("cluster_eps", |a| a.cluster_eps.to_string()),
    ("min_area", |a| a.min_area.to_string()),
    ("gradient_tol", |a| a.gradient_tol.to_string()),
    ("max_rounds", |a| a.max_rounds.to_string()),
    ("sky_rays", |a| a.sky_rays.to_string()),
];

/// `cmd` (the whole `nusselt` command) with its subcommands' help tailored.
pub fn tailor(cmd: Command) -> Command {
    cmd.mut_subcommand("solve", solve)
        .mut_subcommand("render", |c| {
            c.mut_arg("spp", |a| a.help(STRATIFIED_SPP))
                .after_help(RENDER_EXAMPLES)
        })
        .mut_subcommand("reference", |c| {
            c.mut_arg("spp", |a| {
                a.help("Independent paths per pixel, 2 (the noise image needs two) to 1048576")
                    .value_parser(clap::value_parser!(u32).range(2..=i64::from(MAX_PATHS)))
            })
            .after_help(REFERENCE_EXAMPLES)
        })
        .mut_subcommand("formfactors", |c| {
            c.mut_arg("visibility_rays", |a| {
                a.help("analytic: visibility rays per quadrature point [default: 4]")
            })
            .mut_arg("sampling_tolerance", |a| {
                a.help(
                    "sampling: relative tolerance of each form factor (absolute below a factor \
                     of 0.001); the CSV's error column is the estimate it was met by",
                )
            })
            .after_help(FORMFACTORS_EXAMPLES)
        })
        .mut_subcommand("compare", |c| c.after_help(COMPARE_EXAMPLES))
        .mut_subcommand("chart", |c| c.after_help(CHART_EXAMPLES))
        .mut_subcommand("probe", |c| c.after_help(PROBE_EXAMPLES))
        .mut_subcommand("study", |c| c.after_help(STUDY_EXAMPLES))
}

/// `solve`: preset values on the accuracy knobs, its own kernel wording.
fn solve(mut cmd: Command) -> Command {
    for (id, value) in PRESET_KNOBS {
        let values = [Preset::Preview, Preset::Default, Preset::High]
            .map(|p| format!("{} {}", preset_name(p), value(&Accuracy::preset(p))))
            .join(", ");
        cmd = cmd.mut_arg(id, |a| {
            let help = a.get_help().map(ToString::to_string).unwrap_or_default();
            a.help(format!("{help} [by preset: {values}]"))
        });
    }
    cmd.mut_arg("spp", |a| a.help(STRATIFIED_SPP))
        .mut_arg("visibility_rays", |a| {
            a.help(
                "Visibility rays per link (hierarchical) [default: 32], per element pair \
                 (point-polygon) or per quadrature point (polygon-polygon) [default: 4]",
            )
        })
        .mut_arg("sampling_tolerance", |a| {
            a.help(
                "sampling kernel: relative tolerance of each element-to-element form factor \
                 (absolute below a factor of 0.001)",
            )
        })
        .after_help(SOLVE_EXAMPLES)
}

/// A preset's name on the command line.
fn preset_name(p: Preset) -> &'static str {
    match p {
        Preset::Preview => "preview",
        Preset::Default => "default",
        Preset::High => "high",
    }
}

const STRATIFIED_SPP: &str = "Samples per pixel, stratified (rounded up to a square), and 16 \
     times as many, at most 4096, in pixels whose samples disagree, such as edges; at most 65536";

const SOLVE_EXAMPLES: &str = "\
Examples:
  nusselt solve scenes/cornell-box.gltf                       # default bake → out/cornell-box/
  nusselt solve level.glb -o out/level --lightmap 2048 --glb  # for a game engine
  nusselt solve scenes/cornell-box.gltf --accuracy high --width 1024
  nusselt solve scenes/courtyard.gltf --sky 0.25,0.32,0.45    # open scene under a sky
  nusselt solve scenes/cornell-box.gltf --method jacobi --kernel hemicube --element-size 0.05";

const RENDER_EXAMPLES: &str = "\
Examples:
  nusselt render out/cb/solution.exr -o view.exr --png view.png --eye 0.3,0.3,-0.6
  nusselt render out/cb/solution.exr -o big.exr --width 2048 --height 2048";

const REFERENCE_EXAMPLES: &str = "\
Examples:
  nusselt reference scenes/cornell-box.gltf --width 128 --spp 256 -o out/ref.exr
  nusselt compare out/cb/render.exr out/ref.exr -o out/cmp   # then score a solve against it";

const FORMFACTORS_EXAMPLES: &str = "\
Examples:
  nusselt formfactors scenes/two-squares.gltf > factors.csv
  nusselt formfactors scenes/two-squares.gltf --method hemicube --hemicube-resolution 512";

const COMPARE_EXAMPLES: &str = "\
Examples:
  nusselt compare out/cb/render.exr out/ref.exr -o out/cmp > metrics.json
  nusselt compare out/cb/solution.exr points.csv -o out/points  # against a probe table";

const CHART_EXAMPLES: &str = "\
Examples:
  nusselt chart out/jacobi/report.json out/shooting/report.json -o out/charts";

const PROBE_EXAMPLES: &str = "\
Examples:
  nusselt probe scenes/cornell-box.gltf --random 200 --spp 16384 -o points.csv
  nusselt compare out/cb/solution.exr points.csv";

const STUDY_EXAMPLES: &str = "\
Examples:
  nusselt study scenes/cornell-box.gltf -o study
  nusselt study scenes/cornell-box.gltf -o study --config sweep.json";
