//! Progress reporting for every phase of a run: indicatif bars and spinners
//! on stderr.
//!
//! Owns: the only use of `indicatif`. A phase whose work is countable gets
//! a bar with its count and an ETA ([`Progress::phase`]); one that is not
//! gets a spinner with the time elapsed ([`Progress::spinner`]); either
//! can carry a short message (a round number, a vertex count). Nothing
//! draws unless enabled (not `--quiet`) and stderr is a terminal, so
//! library code reports progress unconditionally and a redirected run
//! prints nothing.
//!
//! Invariant: at most one phase is alive at a time in the pipeline (each
//! is finished and cleared when dropped), so bars never overwrite each
//! other.

use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How often a spinner redraws by itself.
const TICK: Duration = Duration::from_millis(120);

/// Hands out one bar or spinner per phase.
#[derive(Clone, Copy, Debug, Default)]
pub struct Progress {
    enabled: bool,
}

impl Progress {
    /// Bars shown when `enabled` and stderr is a terminal.
    pub fn new(enabled: bool) -> Progress {
        Progress { enabled }
    }

    /// A progress reporter that never draws.
    pub fn hidden() -> Progress {
        Progress { enabled: false }
    }

    /// A bar for a phase of `total` steps, with its count and an ETA.
    pub fn phase(&self, name: &str, total: u64) -> Phase {
        self.start(
            name,
            Some(total),
            "{prefix:>15} [{bar:30}] {pos}/{len} {elapsed_precise} eta {eta} {msg}",
        )
    }

    /// A spinner for a phase whose work cannot be counted ahead: its time
    /// so far and its message.
    pub fn spinner(&self, name: &str) -> Phase {
        let phase = self.start(name, None, "{prefix:>15} {spinner} {elapsed_precise} {msg}");
        phase.bar.enable_steady_tick(TICK);
        phase
    }

    fn start(&self, name: &str, total: Option<u64>, template: &str) -> Phase {
        if !self.enabled {
            return Phase {
                bar: ProgressBar::hidden(),
            };
        }
        let bar = ProgressBar::with_draw_target(total, ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_prefix(name.to_string());
        bar.tick();
        Phase { bar }
    }
}

/// One phase's bar or spinner; finished and cleared when dropped.
pub struct Phase {
    bar: ProgressBar,
}

impl Phase {
    /// Advances by `n` steps (thread-safe).
    pub fn inc(&self, n: u64) {
        self.bar.inc(n);
    }

    /// Sets the position.
    pub fn set(&self, pos: u64) {
        self.bar.set_position(pos);
    }

    /// Shows `message` after the bar (a round, a count).
    pub fn message(&self, message: impl Into<String>) {
        self.bar.set_message(message.into());
    }
}

impl Drop for Phase {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
