//! The analysis tools around the solver: image comparison, charts,
//! speed-against-accuracy studies and the failure-mode table.

pub mod chart;
pub mod compare;
pub mod convergence;
pub mod failures;
pub mod study;
