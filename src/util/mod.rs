//! Domain-free helpers: progress reporting.

pub mod progress;
