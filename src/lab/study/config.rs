//! The configuration of `nusselt study`: which methods at which settings.
//!
//! Owns the JSON form of a sweep ([`StudyConfig`], every field optional,
//! unknown fields refused; [`RunSpec`], one line of the sweep) and its
//! expansion into the pipeline's [`SolveSettings`], one per setting.
//! Invariant: every run of a sweep shares the study's view, render samples
//! and seed ([`StudyConfig::view`], `base_settings`), so images compare
//! pixel for pixel and rows differ only by method and setting.

use serde::{Deserialize, Serialize};

use crate::classic::matrix::{Kernel, MatrixSettings};
use crate::error::{Error, Result};
use crate::hierarchical::{Accuracy, HierarchicalSettings, Preset};
use crate::pipeline::{Method, SolveSettings};
use crate::render::RenderSettings;
use crate::render::view::ViewOverrides;
use crate::scene::Scene;

/// One line of the sweep: a method, and the settings it is run at.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Series name in charts and the CSV.
    pub label: String,
    /// `hierarchical`, `direct`, `jacobi`, `gauss-seidel` or `shooting`.
    pub method: String,
    /// Classic methods: the form-factor kernel (default point-polygon).
    #[serde(default)]
    pub kernel: Option<Kernel>,
    /// Classic methods: element sizes as fractions of the scene diagonal.
    #[serde(default)]
    pub element_fractions: Vec<f64>,
    /// Hierarchical: accuracy presets (`preview`, `default`, `high`).
    #[serde(default)]
    pub accuracy: Vec<String>,
}

/// The sweep; `nusselt study --config FILE` reads it as JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StudyConfig {
    /// Width of the reference and of every render, pixels.
    pub width: u32,
    /// Height of the reference and of every render, pixels.
    pub height: u32,
    /// Samples per pixel of the reference.
    pub reference_spp: u32,
    /// Samples per pixel of each run's render.
    pub render_spp: u32,
    /// Seed of the reference, the sampled kernels and the renders.
    pub seed: u64,
    /// The lines of the sweep, in CSV and chart order.
    pub runs: Vec<RunSpec>,
}

impl Default for StudyConfig {
    fn default() -> Self {
        let classic = |label: &str, method: &str, kernel: Kernel, fractions: &[f64]| RunSpec {
            label: label.into(),
            method: method.into(),
            kernel: Some(kernel),
            element_fractions: fractions.to_vec(),
            accuracy: Vec::new(),
        };
        StudyConfig {
            width: 128,
            height: 128,
            reference_spp: 1024,
            render_spp: 16,
            seed: 0,
            runs: vec![
                RunSpec {
                    label: "hierarchical".into(),
                    method: "hierarchical".into(),
                    kernel: None,
                    element_fractions: Vec::new(),
                    accuracy: vec!["preview".into(), "default".into(), "high".into()],
                },
                classic(
                    "jacobi, point-polygon",
                    "jacobi",
                    Kernel::PointPolygon,
                    &[0.1, 0.07, 0.05, 0.035],
                ),
                classic(
                    "gauss-seidel, hemicube",
                    "gauss-seidel",
                    Kernel::Hemicube,
                    &[0.1, 0.07, 0.05],
                ),
                classic(
                    "shooting, point-polygon",
                    "shooting",
                    Kernel::PointPolygon,
                    &[0.1, 0.07, 0.05],
                ),
            ],
        }
    }
}

impl StudyConfig {
    /// Checks every line before anything runs: a known method, known
    /// accuracy presets, positive element fractions, and the settings
    /// each run would solve with.
    pub fn validate(&self) -> Result<()> {
        for spec in &self.runs {
            let method = parse_method(&spec.method)?;
            for a in &spec.accuracy {
                preset(a, self.seed)?.validate()?;
            }
            if let Some(f) = spec
                .element_fractions
                .iter()
                .find(|f| !(**f > 0.0 && f.is_finite()))
            {
                return Err(Error::Setting(format!(
                    "study: element fraction {f} of '{}' must be positive",
                    spec.label
                )));
            }
            SolveSettings {
                method,
                ..base_settings(self, &self.view())
            }
            .validate()?;
        }
        Ok(())
    }

    /// The scene camera's view at the study's size.
    pub(super) fn view(&self) -> ViewOverrides {
        ViewOverrides {
            width: Some(self.width),
            height: Some(self.height),
            ..ViewOverrides::default()
        }
    }
}

impl RunSpec {
    /// The runs of this line, in order: (setting as written in the CSV,
    /// the pipeline's settings). Hierarchical methods run once per
    /// accuracy preset, classic ones once per element fraction of the
    /// scene's diagonal. Fails on an unknown method or preset.
    pub(super) fn runs(
        &self,
        scene: &Scene,
        config: &StudyConfig,
        overrides: &ViewOverrides,
    ) -> Result<Vec<(String, SolveSettings)>> {
        let method = parse_method(&self.method)?;
        Ok(match method {
            Method::Hierarchical => self
                .accuracy
                .iter()
                .map(|a| {
                    Ok((
                        a.clone(),
                        SolveSettings {
                            method,
                            hierarchical: preset(a, config.seed)?,
                            ..base_settings(config, overrides)
                        },
                    ))
                })
                .collect::<Result<_>>()?,
            Method::Classic(_) => self
                .element_fractions
                .iter()
                .map(|&f| {
                    let mut s = SolveSettings {
                        method,
                        element_size: Some(f * scene.diagonal()),
                        ..base_settings(config, overrides)
                    };
                    s.matrix.kernel = self.kernel.unwrap_or(Kernel::PointPolygon);
                    (format!("{f}"), s)
                })
                .collect(),
        })
    }
}

/// The solver named `name` in a [`RunSpec`].
fn parse_method(name: &str) -> Result<Method> {
    <Method as clap::ValueEnum>::from_str(name, false)
        .map_err(|_| Error::Setting(format!("study: unknown method '{name}'")))
}

/// The hierarchical settings of the accuracy preset named `name`.
fn preset(name: &str, seed: u64) -> Result<HierarchicalSettings> {
    let p = <Preset as clap::ValueEnum>::from_str(name, false)
        .map_err(|_| Error::Setting(format!("study: unknown accuracy preset '{name}'")))?;
    Ok(HierarchicalSettings {
        accuracy: Accuracy::preset(p),
        seed,
        ..HierarchicalSettings::default()
    })
}

/// What every run of the study shares: seeds, render samples, the view.
fn base_settings(config: &StudyConfig, overrides: &ViewOverrides) -> SolveSettings {
    SolveSettings {
        matrix: MatrixSettings {
            seed: config.seed,
            ..MatrixSettings::default()
        },
        render: RenderSettings::with_samples(config.render_spp, config.seed),
        view: overrides.clone(),
        ..SolveSettings::default()
    }
}
