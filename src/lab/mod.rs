//! The analysis tools around the solver: image comparison, charts,
//! speed-against-accuracy studies and the failure-mode table.
//!
//! Owns nothing the solver needs: everything here reads the pipeline's
//! results, never the other way round. The layering, from the bottom:
//! [`chart`] draws (numbers and pixels in, bytes out); [`compare`] measures
//! one image against another (images, encoders and `chart` only);
//! [`convergence`] charts solve reports; `reference_cache` renders and
//! caches path-traced references for [`study`] and [`failures`], which run
//! the pipeline and measure it; [`points`] scores a solution against
//! path-traced point references.

pub mod chart;
pub mod compare;
pub mod convergence;
#[doc(hidden)]
pub mod failures;
pub mod points;
pub(crate) mod reference_cache;
pub mod study;
