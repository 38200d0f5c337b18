//! Argument groups shared by several subcommands (threads, seed and quiet;
//! the view; the form-factor kernel; the hierarchical accuracy), and their
//! conversion into the library's settings.
//!
//! Invariant: the first stage here only parses and converts flags (a
//! count must be a whole number, a budget in GiB becomes bytes); whether a
//! value is in range is for the settings' own `validate`, which the
//! subcommands call before any work.

use anyhow::{Result, bail};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args};
use glam::DVec3;

use nusselt::classic::matrix::{Kernel, MatrixSettings};
use nusselt::formfactor::area_sampling::DEFAULT_TOLERANCE;
use nusselt::hierarchical::oracle::Oracle;
use nusselt::hierarchical::{
    Accuracy, Clustering, DEFAULT_CORRECTION_PASSES, DEFAULT_CORRECTION_RAYS,
    DEFAULT_CORRECTION_TOLERANCE, HierarchicalSettings, Preset,
};
use nusselt::load::LoadOptions;
use nusselt::render::view::ViewOverrides;

/// Threads, seed and quiet, common to every subcommand that computes.
#[derive(Args, Debug)]
#[command(next_help_heading = "Run")]
pub struct Common {
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = at_least_one::<usize>)]
    pub threads: Option<usize>,
    /// Seed of every random choice; the same seed gives the same output.
    #[arg(hide_short_help = true, long, default_value_t = 0)]
    pub seed: u64,
    /// No progress bars and no summary line.
    #[arg(long, short)]
    pub quiet: bool,
}

/// How the scene is read.
#[derive(Args, Debug)]
#[command(next_help_heading = "Scene")]
pub struct LoadArgs {
    /// Reflectances at or above this are clamped to it.
    #[arg(hide_short_help = true, long, default_value_t = 0.999)]
    pub max_reflectance: f64,
}

impl LoadArgs {
    /// The loader's options, checked.
    pub fn options(&self) -> Result<LoadOptions> {
        let options = LoadOptions {
            max_reflectance: self.max_reflectance,
            ..LoadOptions::default()
        };
        super::checked(options.validate())?;
        Ok(options)
    }

    /// [`Self::options`] with the sky of `sky`.
    pub fn options_with(&self, sky: &SkyArgs) -> Result<LoadOptions> {
        let mut options = self.options()?;
        if let Some(spec) = &sky.sky {
            options.sky = Some(std::sync::Arc::new(nusselt::load::parse_sky(spec)?));
        }
        Ok(options)
    }
}

/// The sky, for the subcommands that light a scene (`solve`,
/// `reference`, `probe`).
#[derive(Args, Debug)]
#[command(next_help_heading = "Scene")]
pub struct SkyArgs {
    /// The sky around the scene: a uniform radiance R,G,B (W·m⁻²·sr⁻¹),
    /// or an equirectangular OpenEXR environment (y up, the image centre
    /// toward −z). It lights the scene through its openings and absorbs
    /// what leaves.
    #[arg(long, value_name = "R,G,B|FILE.exr", allow_hyphen_values = true)]
    pub sky: Option<String>,
}

/// The view and image size, the same for `solve`, `render` and
/// `reference` so that their images line up pixel for pixel.
#[derive(Args, Debug)]
#[command(next_help_heading = "View")]
pub struct ViewArgs {
    /// Image width in pixels.
    #[arg(long, value_parser = at_least_one::<u32>)]
    pub width: Option<u32>,
    /// Image height in pixels.
    #[arg(long, value_parser = at_least_one::<u32>)]
    pub height: Option<u32>,
    /// Camera position X,Y,Z (metres).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Point the camera looks at, X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<DVec3>,
    /// Up direction X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<DVec3>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    pub fov: Option<f64>,
    /// Samples per pixel (`solve`, `render`: stratified, rounded up to a
    /// square, and 16 times as many, at most 4096, in pixels whose samples
    /// disagree, such as edges; `reference`: independent paths, at least
    /// 2). At most 65536 (`reference`: 1048576).
    #[arg(long, default_value_t = 16,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_STRATIFIED_SPP)))]
    pub spp: u32,
}

/// The most stratified samples per pixel `solve` and `render` take: a
/// 256 × 256 pattern. Beyond it a run only waits longer for no visible
/// change (the pattern already resolves 1/65536 of a pixel).
pub const MAX_STRATIFIED_SPP: u32 = 1 << 16;

/// The most paths per pixel (`reference`) or per point (`probe`): at the
/// path tracer's 4·10⁵ paths/s on 2 cores, about 2.6 s each. The standard
/// error then is ~0.1 % of a typical pixel's noise at one path; a flag
/// of 2³² − 1 used to run, in effect, for ever.
pub const MAX_PATHS: u32 = 1 << 20;

impl ViewArgs {
    /// The view flags as overrides of the scene's camera.
    pub fn overrides(&self) -> ViewOverrides {
        ViewOverrides {
            eye: self.eye,
            target: self.target,
            up: self.up,
            fov_deg: self.fov,
            width: self.width,
            height: self.height,
        }
    }
}

/// The hierarchical method's accuracy: one preset, and expert overrides of
/// each of its thresholds.
#[derive(Args, Debug)]
#[command(next_help_heading = "Hierarchical")]
pub struct HierarchicalArgs {
    /// Accuracy preset of the hierarchical method; the flags below override
    /// single thresholds.
    #[arg(help_heading = "Accuracy", long, value_enum, default_value_t = Preset::Default)]
    pub accuracy: Preset,
    /// Refinement oracle of the hierarchical method.
    #[arg(hide_short_help = true, long, value_enum, default_value_t = Oracle::Bf)]
    pub oracle: Oracle,
    /// ff oracle: largest form factor a link may keep.
    #[arg(hide_short_help = true, long)]
    pub ff_eps: Option<f64>,
    /// bf oracle: largest ρ·B·(form-factor and visibility error) a link may
    /// keep, as a fraction of the mean emitted exitance.
    #[arg(hide_short_help = true, long)]
    pub bf_eps: Option<f64>,
    /// bf oracle, relative mode: a link's threshold follows its receiver's
    /// radiosity, down to this fraction of the threshold for receivers
    /// dimmer than the mean emitted exitance by as much (1: absolute).
    #[arg(hide_short_help = true, long, value_name = "FLOOR")]
    pub bf_relative_floor: Option<f64>,
    /// power oracle: largest power a link may carry, as a fraction of the
    /// largest patch emitted power.
    #[arg(hide_short_help = true, long)]
    pub power_eps: Option<f64>,
    /// Cluster oracle: largest ρ·(irradiance error) a link with a cluster
    /// at one end may keep, as a fraction of the mean emitted exitance.
    #[arg(hide_short_help = true, long)]
    pub cluster_eps: Option<f64>,
    /// Smallest element, as a fraction of the total surface area.
    #[arg(hide_short_help = true, long)]
    pub min_area: Option<f64>,
    /// Split leaves whose radiosity differs from a sibling's by more than
    /// this fraction of the mean emitted exitance (0 disables).
    #[arg(hide_short_help = true, long)]
    pub gradient_tol: Option<f64>,
    /// Link budget: no split takes the link count past N; refinement stops
    /// there (the report says so).
    #[arg(help_heading = "Budgets", long, value_name = "N")]
    pub max_links: Option<f64>,
    /// Element budget: no split takes the hierarchy past N elements;
    /// refinement stops there (the report says so).
    #[arg(help_heading = "Budgets", long, value_name = "N")]
    pub max_elements: Option<f64>,
    /// Refinement rounds (refine + solve) at most.
    #[arg(hide_short_help = true, long)]
    pub max_rounds: Option<usize>,
    /// Sky rays per output vertex (with --sky).
    #[arg(hide_short_help = true, long)]
    pub sky_rays: Option<usize>,
    /// Start the links from a cluster hierarchy above the patches (no
    /// step over every pair of patches); auto clusters scenes of 1,000
    /// patches or more.
    #[arg(hide_short_help = true, long, value_enum, default_value_t = Clustering::Auto)]
    pub clustering: Clustering,
    /// Seconds the whole run may take, roughly, loading included:
    /// shadow-line wedges stop at
    /// 15 % of it, refinement and correction passes at 40 % (the links as
    /// they are get solved), the output mesh's
    /// points after 80 % take their leaf's value without rays, render
    /// pixels take one sample once the rest would not otherwise end by
    /// 95 %, and pixels begun after it none (they show the nearest rendered
    /// pixel of their column); the report says which. Results then depend
    /// on the machine's speed.
    #[arg(help_heading = "Budgets", long, value_name = "SECONDS")]
    pub time_budget: Option<f64>,

    /// Passes of defect correction after the last round: the solution's
    /// own radiosities gathered by rays at every patch, the difference
    /// from what its links deliver fed back, the links solved again (0:
    /// off)
    #[arg(hide_short_help = true, long, default_value_t = DEFAULT_CORRECTION_PASSES,
          value_parser = clap::value_parser!(u32).range(0..=8))]
    pub correction_passes: u32,

    /// Rays per patch of each correction pass (a patch smaller than the mean: a share by its area; any patch: 16 per leaf)
    #[arg(hide_short_help = true, long, default_value_t = DEFAULT_CORRECTION_RAYS as u64,
          value_parser = clap::value_parser!(u64).range(1..=65536))]
    pub correction_rays: u64,

    /// A patch's correction is used once it is three standard errors from
    /// zero or known to this fraction of its light; a patch whose own rays
    /// fall short borrows the pooled correction of the patches around it
    /// that face the same way
    #[arg(help_heading = "Budgets", hide_short_help = true, hide_short_help = true, long, default_value_t = DEFAULT_CORRECTION_TOLERANCE)]
    pub correction_tolerance: f64,
}

/// What the hierarchical method takes from other flag groups.
pub struct HierarchicalExtras {
    /// Seed of every ray.
    pub seed: u64,
    /// Visibility rays per link.
    pub rays: usize,
    /// Gathering tolerance of each round.
    pub tolerance: f64,
    /// Iterations per round at most.
    pub max_iterations: usize,
    /// Memory budget in bytes.
    pub memory_budget: u64,
}

impl HierarchicalArgs {
    /// The preset with the overrides given; budgets must be whole numbers.
    pub fn settings(&self, extras: HierarchicalExtras) -> Result<HierarchicalSettings> {
        let mut a = Accuracy::preset(self.accuracy);
        for (slot, v) in [
            (&mut a.ff_eps, self.ff_eps),
            (&mut a.bf_eps, self.bf_eps),
            (&mut a.bf_relative_floor, self.bf_relative_floor),
            (&mut a.power_eps, self.power_eps),
            (&mut a.cluster_eps, self.cluster_eps),
            (&mut a.min_area, self.min_area),
            (&mut a.gradient_tol, self.gradient_tol),
        ] {
            if let Some(v) = v {
                *slot = v;
            }
        }
        a.max_links = count("max-links", self.max_links)?;
        a.max_elements = count("max-elements", self.max_elements)?;
        if let Some(r) = self.max_rounds {
            a.max_rounds = r;
        }
        if let Some(r) = self.sky_rays {
            a.sky_rays = r;
        }
        Ok(HierarchicalSettings {
            oracle: self.oracle,
            accuracy: a,
            visibility_rays: extras.rays,
            seed: extras.seed,
            tolerance: extras.tolerance,
            max_iterations: extras.max_iterations,
            memory_budget: extras.memory_budget,
            time_budget: self.time_budget,
            importance: None,
            clustering: self.clustering,
            correction_passes: self.correction_passes,
            correction_rays: self.correction_rays as usize,
            correction_tolerance: self.correction_tolerance,
        })
    }
}

/// A budget given as a number: a whole number from 1 to 2^53 (exact in an
/// f64).
fn count(name: &str, v: Option<f64>) -> Result<Option<u64>> {
    match v {
        Some(v) if !((1.0..=9_007_199_254_740_992.0).contains(&v) && v.fract() == 0.0) => {
            bail!("--{name} must be a whole number of at least 1, not {v}")
        }
        v => Ok(v.map(|v| v as u64)),
    }
}

/// How form factors are computed: each kernel's own knobs (the kernel is
/// chosen by `solve --kernel` or `formfactors --method`).
#[derive(Args, Debug)]
#[command(next_help_heading = "Kernel")]
pub struct KernelArgs {
    /// Visibility rays per element pair (point-polygon; default 4), per
    /// quadrature point (polygon-polygon; default 4) or per link
    /// (hierarchical; default 32).
    #[arg(hide_short_help = true, long)]
    pub visibility_rays: Option<usize>,
    /// Relative tolerance of each form factor (sampling): receiver points
    /// and source pieces are added until the estimated error is below it,
    /// or below it times 0.001 absolutely for smaller factors.
    #[arg(hide_short_help = true, long, default_value_t = DEFAULT_TOLERANCE)]
    pub sampling_tolerance: f64,
    /// Absolute tolerance of each form factor (polygon-polygon).
    #[arg(hide_short_help = true, long, default_value_t = 1e-4)]
    pub quadrature_tolerance: f64,
    /// Hemicube top-face resolution (cells per side; even).
    #[arg(hide_short_help = true, long, default_value_t = 128)]
    pub hemicube_resolution: u32,
    /// Do not turn each hemicube by a random angle about its normal.
    #[arg(hide_short_help = true, long)]
    pub no_hemicube_rotation: bool,
    /// Largest dense matrix (and direct-method factorisation) allowed, in
    /// GiB; for hierarchical, the estimated memory of the elements and
    /// links, where refinement stops (the report says so). Every size read
    /// from the scene or the flags (triangles after instancing, textures,
    /// classic elements, uniform output vertices) is checked against it
    /// before it is allocated.
    #[arg(long, value_name = "GIB", default_value_t = 2.0)]
    pub memory_budget: f64,
}

/// `--memory-budget GIB` in bytes: a positive, finite number of GiB.
fn gib_bytes(gib: f64) -> Result<u64> {
    if !(gib > 0.0 && gib.is_finite()) {
        bail!("--memory-budget must be a positive number of GiB");
    }
    Ok((gib * (1u64 << 30) as f64) as u64)
}

/// The memory budget of the subcommands that render without solving
/// (`render`, `reference`).
#[derive(Args, Debug)]
#[command(next_help_heading = "View")]
pub struct ImageBudgetArgs {
    /// Largest memory the image (its buffers and encodings) and, for
    /// `reference`, the scene's textures and triangles may take, in GiB;
    /// a larger --width × --height is refused before anything is
    /// rendered.
    #[arg(long, value_name = "GIB", default_value_t = 2.0)]
    pub memory_budget: f64,
}

impl ImageBudgetArgs {
    /// The budget in bytes; validated.
    pub fn bytes(&self) -> Result<u64> {
        gib_bytes(self.memory_budget)
    }
}

impl KernelArgs {
    /// The settings of `kernel`; validated.
    pub fn settings(&self, kernel: Kernel, seed: u64) -> Result<MatrixSettings> {
        let memory_budget = gib_bytes(self.memory_budget)?;
        let settings = MatrixSettings {
            kernel,
            visibility_rays: self.visibility_rays.unwrap_or(4).max(1),
            sampling_tolerance: self.sampling_tolerance,
            quadrature_tolerance: self.quadrature_tolerance,
            hemicube_resolution: self.hemicube_resolution,
            hemicube_rotation: !self.no_hemicube_rotation,
            seed,
            memory_budget,
        };
        super::checked(settings.validate())?;
        Ok(settings)
    }
}

/// Each kernel flag (argument id) and the kernels that read it.
const KERNEL_FLAGS: [(&str, &[Kernel]); 5] = [
    (
        "visibility_rays",
        &[Kernel::PointPolygon, Kernel::PolygonPolygon],
    ),
    ("sampling_tolerance", &[Kernel::Sampling]),
    ("quadrature_tolerance", &[Kernel::PolygonPolygon]),
    ("hemicube_resolution", &[Kernel::Hemicube]),
    ("no_hemicube_rotation", &[Kernel::Hemicube]),
];

/// The flags among `ids` that the command line gave, as `--name`.
pub fn given(matches: &ArgMatches, ids: &[&str]) -> Vec<String> {
    ids.iter()
        .filter(|id| matches.value_source(id) == Some(ValueSource::CommandLine))
        .map(|id| format!("--{}", id.replace('_', "-")))
        .collect()
}

/// "--a, --b apply" or "--a applies".
pub fn flags_apply(flags: &[String]) -> String {
    let verb = if flags.len() == 1 { "applies" } else { "apply" };
    format!("{} {verb}", flags.join(", "))
}

/// The kernel flags given that `kernel` does not read, as one sentence;
/// `chosen` names a kernel the way the subcommand's flag does (e.g.
/// `--kernel hemicube` or `--method analytic`), `None` for a kernel the
/// subcommand does not offer.
pub fn kernel_inapplicable(
    matches: &ArgMatches,
    kernel: Kernel,
    chosen: impl Fn(Kernel) -> Option<String>,
) -> Option<String> {
    let mut sentences = Vec::new();
    for (id, readers) in KERNEL_FLAGS {
        if readers.contains(&kernel) {
            continue;
        }
        let flags = given(matches, &[id]);
        if !flags.is_empty() {
            let to: Vec<String> = readers.iter().filter_map(|&k| chosen(k)).collect();
            sentences.push(format!(
                "{} only to {}, not to {}",
                flags_apply(&flags),
                to.join(" and "),
                chosen(kernel).unwrap_or_default()
            ));
        }
    }
    (!sentences.is_empty()).then(|| sentences.join("; "))
}

/// Parses `X,Y,Z` into a finite vector.
pub fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got '{s}'"));
    }
    let mut v = [0.0; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("'{p}' is not a finite number"))?;
    }
    Ok(DVec3::from_array(v))
}

/// A file path whose extension is `ext` (case-insensitive): a value
/// parser, so a wrong one is a usage error (exit 2) before any work.
fn with_extension(s: &str, ext: &str) -> Result<std::path::PathBuf, String> {
    let path = std::path::PathBuf::from(s);
    let ok = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext));
    match ok {
        true => Ok(path),
        false => Err(format!("'{s}' must end in .{ext}")),
    }
}

/// An OpenEXR file path (`.exr`).
pub fn exr_path(s: &str) -> Result<std::path::PathBuf, String> {
    with_extension(s, "exr")
}

/// A PNG file path (`.png`).
pub fn png_path(s: &str) -> Result<std::path::PathBuf, String> {
    with_extension(s, "png")
}

/// A CSV file path (`.csv`).
pub fn csv_path(s: &str) -> Result<std::path::PathBuf, String> {
    with_extension(s, "csv")
}

/// A whole number of at least 1.
pub fn at_least_one<T: std::str::FromStr + PartialOrd + From<u8>>(s: &str) -> Result<T, String> {
    match s.trim().parse::<T>() {
        Ok(v) if v >= T::from(1) => Ok(v),
        _ => Err(format!("'{s}' is not a whole number of at least 1")),
    }
}
