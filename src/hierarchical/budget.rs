//! The resource budgets of the hierarchical solver (links, elements,
//! memory, time) and the report of the one that stopped refinement; the
//! checks themselves are `limits`.
//!
//! Invariant: a refused split keeps its link, a refused opening its
//! cluster link; [`BudgetHit`] names the first budget that refused. A
//! budget that stops the first linking makes it start again coarser
//! ([`Coarsened`]), so that no solve rests on a half-done first linking.

/// A resource budget of the hierarchical solver.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Budget {
    /// `Accuracy::max_links`.
    Links,
    /// `Accuracy::max_elements`.
    Elements,
    /// `HierarchicalSettings::memory_budget`, in bytes.
    Memory,
    /// `HierarchicalSettings::time_budget`, in milliseconds.
    Time,
}

impl Budget {
    /// What it counts, as in "the link budget".
    pub fn noun(self) -> &'static str {
        match self {
            Budget::Links => "link",
            Budget::Elements => "element",
            Budget::Memory => "memory",
            Budget::Time => "time",
        }
    }

    /// The command-line option that sets it.
    pub fn option(self) -> &'static str {
        match self {
            Budget::Links => "--max-links",
            Budget::Elements => "--max-elements",
            Budget::Memory => "--memory-budget",
            Budget::Time => "--time-budget",
        }
    }
}

/// The budget that stopped refinement (also `budget` in `report.json`):
/// its limit and the value reached when the solve ended (links, elements,
/// or estimated bytes; at most the limit unless the initial linking alone
/// exceeded it).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct BudgetHit {
    /// Which budget.
    pub kind: Budget,
    /// Its limit, in its unit.
    pub limit: u64,
    /// What was reached when the solve ended.
    pub reached: u64,
}

impl BudgetHit {
    /// One line for the warnings, naming the option to raise.
    pub fn message(&self) -> String {
        let (limit, reached) = match self.kind {
            Budget::Links => (format!("{} links", self.limit), self.reached.to_string()),
            Budget::Elements => (format!("{} elements", self.limit), self.reached.to_string()),
            Budget::Memory => {
                let bytes = |b: u64| {
                    let gib = b as f64 / (1u64 << 30) as f64;
                    if gib >= 1.0 {
                        format!("{gib:.2} GiB")
                    } else {
                        format!("{:.1} MiB", gib * 1024.0)
                    }
                };
                (
                    bytes(self.limit),
                    format!("{} estimated", bytes(self.reached)),
                )
            }
            Budget::Time => {
                return format!(
                    "hierarchical: refinement stopped when its share of --time-budget was spent \
                     ({:.0} % of it, counted from the command's start); raise --time-budget for a \
                     finer solution",
                    100.0 * REFINE_SHARE
                );
            }
        };
        format!(
            "hierarchical: refinement stopped at the {} budget of {limit} (reached {reached}); \
             raise {} for a finer solution",
            self.kind.noun(),
            self.kind.option()
        )
    }
}

/// The part of `--time-budget` (counted from the command's start) by whose end
/// the shadow lines stop tracing wedges (the remaining luminaire jobs give
/// no D1 segments; contact lines are all found).
pub const SHADOW_SHARE: f64 = 0.15;

/// The part of `--time-budget` (counted from the command's start) that
/// linking and refinement may use; solving, the output mesh
/// ([`MESH_SHARE`]) and the render get the rest.
pub const REFINE_SHARE: f64 = 0.4;

/// The part of `--time-budget` by whose end the output mesh stops
/// evaluating points by rays (later points take their leaf's value).
pub const MESH_SHARE: f64 = 0.8;

/// The part of `--time-budget` by whose end the render stops sampling
/// beyond one sample a pixel; the rest is for the report and the files
/// (0.2–0.3 s of a 20 s budget on the 100,000-sliver fan).
pub const RENDER_SHARE: f64 = 0.95;

/// The first linking did not fit a budget at the settings' thresholds and
/// started again with every threshold `factor` times coarser (also
/// `coarsened` in `report.json`).
#[derive(
    Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct Coarsened {
    /// The budget that stopped the last attempt that did not fit.
    pub by: Budget,
    /// How much coarser every threshold is than the settings ask.
    pub factor: f64,
}

impl Coarsened {
    /// One line for the warnings, naming the option to raise.
    pub fn message(&self) -> String {
        format!(
            "hierarchical: the first linking did not fit the {} budget, so every threshold \
             is {} times coarser than asked; raise {} for the accuracy asked",
            self.by.noun(),
            self.factor,
            self.by.option()
        )
    }
}
