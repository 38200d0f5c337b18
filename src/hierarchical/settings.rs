//! The settings of the hierarchical solver: the accuracy presets and
//! every threshold ([`Accuracy`], relative to the scene), the oracle, rays,
//! seed, iteration limits, clustering and budgets
//! ([`HierarchicalSettings`]).
//!
//! Invariant: every threshold is a fraction of a scene scale (mean emitted
//! exitance, largest patch emitted power, total area), so a setting means
//! the same at any scale; the solver scales them once
//! (`oracle::Thresholds`).

use crate::error::{Error, Result};
use crate::hierarchical::oracle::Oracle;

/// The named accuracy presets of `--accuracy`.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// Coarse: a quick look.
    Preview,
    /// Soft shadows resolved at interactive cost.
    Default,
    /// Finer elements and links for final images.
    High,
}

/// Every threshold of the hierarchical solver, relative to the scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Accuracy {
    /// ff oracle: largest accepted form factor.
    pub ff_eps: f64,
    /// bf oracle: largest accepted ρ_r B_s (V F_err + V_err F + V_err F_err),
    /// as a fraction of the mean emitted exitance (Φ / A_total).
    pub bf_eps: f64,
    /// bf oracle, relative mode: a link's threshold follows its receiver's
    /// radiosity B_r, `bf_eps` × clamp(B_r / M, floor, 1) with M the mean
    /// emitted exitance, so that receivers dimmer than M are resolved to
    /// the same relative error down to `floor` × M. 1 keeps the absolute
    /// threshold; every preset uses 0.25 (a gallery lit a hundredfold more
    /// dimly than its light well was resolved to 8 % at the default
    /// preset with the absolute threshold, to 4-5 % with this, for a
    /// quarter more time).
    pub bf_relative_floor: f64,
    /// power oracle: largest accepted A_r F V ρ_r B_s, as a fraction of the
    /// largest patch emitted power.
    pub power_eps: f64,
    /// Cluster oracle: largest accepted ρ_r times the irradiance error of
    /// a link with a cluster at one end (W/m², as a fraction of the mean
    /// emitted exitance). Finer than `bf_eps`: a cluster link also shares
    /// its light among members it cannot see apart ([`crate::hierarchical::cluster`]).
    pub cluster_eps: f64,
    /// Elements at or below this fraction of the total area are not split.
    pub min_area: f64,
    /// Leaves whose radiosity differs from a sibling's by more than this
    /// fraction of the mean emitted exitance are split (0 disables).
    pub gradient_tol: f64,
    /// Link budget: refinement stops when it is reached (`None`: unlimited).
    pub max_links: Option<u64>,
    /// Element budget: no split makes the hierarchy larger (`None`:
    /// unlimited).
    pub max_elements: Option<u64>,
    /// Refinement rounds (refine, solve) at most.
    pub max_rounds: usize,
    /// Sky rays per output vertex (`crate::illumination`): the sky's
    /// irradiance there is a stratified estimate from this many
    /// directions.
    pub sky_rays: usize,
}

/// The most sky rays per point a setting may ask for.
pub const MAX_SKY_RAYS: usize = 1 << 16;

/// [`Accuracy::bf_relative_floor`] of every preset.
pub const RELATIVE_FLOOR: f64 = 0.25;

impl Accuracy {
    /// Quick look: coarse shadows.
    pub fn preview() -> Accuracy {
        Accuracy {
            ff_eps: 0.05,
            bf_eps: 0.2,
            bf_relative_floor: RELATIVE_FLOOR,
            power_eps: 1e-3,
            cluster_eps: 0.02,
            min_area: 1e-4,
            gradient_tol: 0.5,
            max_links: None,
            max_elements: None,
            max_rounds: 3,
            sky_rays: 256,
        }
    }

    /// The default: soft shadows resolved on the Cornell box in about a
    /// second.
    #[allow(clippy::should_implement_trait)]
    pub fn default() -> Accuracy {
        Accuracy {
            ff_eps: 0.01,
            bf_eps: 0.03,
            bf_relative_floor: RELATIVE_FLOOR,
            power_eps: 1e-4,
            cluster_eps: 0.003,
            min_area: 2e-5,
            gradient_tol: 0.15,
            max_links: None,
            max_elements: None,
            max_rounds: 5,
            sky_rays: 1024,
        }
    }

    /// Finer elements and links for final images.
    pub fn high() -> Accuracy {
        Accuracy {
            ff_eps: 0.002,
            bf_eps: 0.006,
            bf_relative_floor: RELATIVE_FLOOR,
            power_eps: 2e-5,
            cluster_eps: 0.0006,
            min_area: 4e-6,
            gradient_tol: 0.05,
            max_links: None,
            max_elements: None,
            max_rounds: 8,
            sky_rays: 4096,
        }
    }

    /// The preset's values.
    pub fn preset(p: Preset) -> Accuracy {
        match p {
            Preset::Preview => Accuracy::preview(),
            Preset::Default => Accuracy::default(),
            Preset::High => Accuracy::high(),
        }
    }
}

impl Default for Accuracy {
    fn default() -> Self {
        Accuracy::default()
    }
}

/// How `solve --method hierarchical` runs.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HierarchicalSettings {
    /// The refinement oracle.
    pub oracle: Oracle,
    /// Every threshold, from a preset or overridden.
    pub accuracy: Accuracy,
    /// Rays per link for its visible fraction.
    pub visibility_rays: usize,
    /// Seed of every visibility ray.
    pub seed: u64,
    /// Stop gathering when an iteration changes the reflected power, summed
    /// element by element, by less than this fraction of Σ B·A (between
    /// refinement rounds, by less than this or 1e-4, whichever is looser).
    pub tolerance: f64,
    /// Gather + push-pull iterations per round at most.
    pub max_iterations: usize,
    /// Bytes the hierarchy, the links and the solver's working arrays may
    /// take, as `memory_estimate` counts them: no split crosses it.
    pub memory_budget: u64,
    /// Whether links start from a cluster hierarchy above the patches
    /// ([`crate::hierarchical::cluster`]) or from every pair of patches.
    pub clustering: Clustering,
    /// Seconds of linking and refinement after which no element is split
    /// and no cluster pair opened unless its clusters touch: the links as
    /// they are then are solved. Results then depend on the machine's
    /// speed (`None`: no limit).
    pub time_budget: Option<f64>,
    /// View importance \[SAS92\]: per patch, 1 where a view sees it directly
    /// (else 0). Refinement then weighs each receiver's link errors by the
    /// patch's importance, this seen-ness carried back along the links
    /// (see `Solver::update_importance`); `None`: every patch counts
    /// fully.
    #[serde(skip)]
    pub importance: Option<Vec<f32>>,
    /// Passes of defect correction after the last round
    /// (`hierarchical::correction`): 0 solves the links alone.
    pub correction_passes: u32,
    /// Rays per patch of each correction pass (a patch smaller than the
    /// mean a share by its area; any patch 16 per leaf).
    pub correction_rays: usize,
    /// A residual share is used once it is significant (three standard
    /// errors) or known to this fraction of the links' reflected light; a
    /// patch whose own rays do not know it borrows its neighbours' pooled
    /// share (`correction::pooled`).
    pub correction_tolerance: f64,
}

/// `--clustering`: how the initial links are made.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum Clustering {
    /// Clusters when the scene has at least 1,000 patches
    /// (`Clustering::AUTO_PATCHES`).
    #[default]
    Auto,
    /// Always start from the root cluster's self-link.
    On,
    /// Link every pair of patches that face each other (k² pairs).
    Off,
}

impl Clustering {
    /// Patch count from which `Auto` clusters: a million patch pairs.
    pub const AUTO_PATCHES: usize = 1000;

    /// True when a scene of `patches` patches is clustered.
    pub fn applies(self, patches: usize) -> bool {
        match self {
            Clustering::Auto => patches >= Clustering::AUTO_PATCHES,
            Clustering::On => true,
            Clustering::Off => false,
        }
    }
}

impl HierarchicalSettings {
    /// Checks every threshold and budget: thresholds positive (the gradient
    /// tolerance zero or positive), budgets at least 1, at least one round,
    /// a positive time budget and gathering tolerance. The error names the
    /// command-line option.
    pub fn validate(&self) -> Result<()> {
        let a = &self.accuracy;
        for (name, v) in [
            ("ff-eps", a.ff_eps),
            ("bf-eps", a.bf_eps),
            ("power-eps", a.power_eps),
            ("cluster-eps", a.cluster_eps),
            ("min-area", a.min_area),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(setting(format!("--{name} must be a positive number")));
            }
        }
        if !(a.bf_relative_floor > 0.0 && a.bf_relative_floor <= 1.0) {
            return Err(setting("--bf-relative-floor must be in (0, 1]"));
        }
        if !(a.gradient_tol >= 0.0 && a.gradient_tol.is_finite()) {
            return Err(setting("--gradient-tol must be zero or positive"));
        }
        for (name, v) in [("max-links", a.max_links), ("max-elements", a.max_elements)] {
            if v == Some(0) {
                return Err(setting(format!(
                    "--{name} must be a whole number of at least 1, not 0"
                )));
            }
        }
        if !(self.correction_tolerance > 0.0 && self.correction_tolerance <= 1.0) {
            return Err(setting("--correction-tolerance must be in (0, 1]"));
        }
        if a.max_rounds == 0 {
            return Err(setting("--max-rounds must be at least 1"));
        }
        if !(1..=MAX_SKY_RAYS).contains(&a.sky_rays) {
            return Err(setting(format!("--sky-rays must be in 1..={MAX_SKY_RAYS}")));
        }
        if self
            .time_budget
            .is_some_and(|t| !(t > 0.0 && t.is_finite()))
        {
            return Err(setting(
                "--time-budget must be a positive number of seconds",
            ));
        }
        if !(self.tolerance > 0.0) {
            return Err(setting("--tolerance must be positive"));
        }
        Ok(())
    }
}

fn setting(message: impl Into<String>) -> Error {
    Error::Setting(message.into())
}

impl Default for HierarchicalSettings {
    fn default() -> Self {
        HierarchicalSettings {
            oracle: Oracle::Bf,
            accuracy: Accuracy::default(),
            visibility_rays: 32,
            seed: 0,
            tolerance: 1e-5,
            max_iterations: 10_000,
            memory_budget: DEFAULT_MEMORY_BUDGET,
            clustering: Clustering::Auto,
            time_budget: None,
            importance: None,
            correction_passes: DEFAULT_CORRECTION_PASSES,
            correction_rays: DEFAULT_CORRECTION_RAYS,
            correction_tolerance: DEFAULT_CORRECTION_TOLERANCE,
        }
    }
}

/// Default of [`HierarchicalSettings::correction_passes`]: two. They take
/// the gallery hall's excess from 6.9 % to 3.1 % for about a sixth more
/// time; a third pass changes the points by less than their noise
/// (BENCHMARKS.md, "Defect correction").
pub const DEFAULT_CORRECTION_PASSES: u32 = 2;

/// Default of [`HierarchicalSettings::correction_tolerance`].
pub const DEFAULT_CORRECTION_TOLERANCE: f64 = 0.005;

/// Default of [`HierarchicalSettings::correction_rays`]: 1024. In an
/// interior lit through an opening a few per cent of a wall's rays bring a
/// third of its light, and 256 knew a wall's gather to 15 %: the gallery
/// hall's residual (2–3 %) stayed below significance and was not fed back.
/// 1024 took the gallery from 3.81 % / 10.6 % (median / p90) to 3.22 % /
/// 8.5 % at seed 0 and from 3.37 % / 9.75 % to 2.91 % / 9.14 % at seed 2,
/// for 7–11 s more in a 110 s run; the held-out corridor and the Cornell
/// box are unchanged within their seed-to-seed spread (BENCHMARKS.md,
/// "What the correction's rays can see").
pub const DEFAULT_CORRECTION_RAYS: usize = 1024;

/// Default of [`HierarchicalSettings::memory_budget`]: 2 GiB, the same as
/// the dense matrix's.
pub const DEFAULT_MEMORY_BUDGET: u64 = 2 << 30;
