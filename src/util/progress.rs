//! Progress reporting for long phases: indicatif bars on stderr.
//!
//! Owns: the only use of `indicatif`. Bars draw only when enabled and stderr
//! is a terminal; otherwise every call is a no-op, so library code can report
//! progress unconditionally.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Hands out one bar per phase.
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

    /// A bar for a phase of `total` steps.
    pub fn phase(&self, name: &str, total: u64) -> Phase {
        let bar = if self.enabled {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
            if let Ok(style) = ProgressStyle::with_template(
                "{prefix:>14} [{bar:30}] {percent:>3}% {elapsed_precise} eta {eta}",
            ) {
                bar.set_style(style.progress_chars("=> "));
            }
            bar.set_prefix(name.to_string());
            bar
        } else {
            ProgressBar::hidden()
        };
        Phase { bar }
    }
}

/// One phase's bar; finished and cleared when dropped.
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
}

impl Drop for Phase {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
