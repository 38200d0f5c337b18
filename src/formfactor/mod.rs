//! Form-factor kernels: pure geometry, visibility only through a closure,
//! no hierarchy, no meshes.
//!
//! Owns the kernels the solvers build on, one per file: point → polygon
//! (Lambert's contour integral, [`point_polygon`]), polygon → polygon
//! (adaptive quadrature of the exact inner integral, [`polygon_polygon`]),
//! aligned rectangles in closed form ([`rectangles`]),
//! adaptive area sampling ([`area_sampling`]), the hemicube ([`hemicube`]), and
//! Howell's closed forms as yardsticks ([`closed_form`]). Argument order
//! is always (receiver, source), matching F_ij: "i gathers from j".
//!
//! Invariants: every kernel returns a finite value in [0, 1], including for
//! touching, coplanar and degenerate configurations.
//!
//! References: Lambert's contour integral for a differential area to a
//! polygon, as catalogued by Howell; \[CW93\] §4; \[CG85\] for the hemicube.

pub mod area_sampling;
pub mod closed_form;
pub mod hemicube;
pub mod point_polygon;
pub mod polygon_polygon;
pub mod rectangles;

pub use area_sampling::form_factor_area_sampling;
pub use point_polygon::form_factor_point_polygon;
pub use polygon_polygon::{
    MAX_EVALUATIONS, form_factor_polygon_polygon, form_factor_polygon_polygon_checked,
    form_factor_polygon_polygon_with,
};

/// A kernel's result with its error estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Estimate {
    /// The form factor, in [0, 1].
    pub value: f64,
    /// Estimated absolute error (quadrature and area sampling: the sum of
    /// the local differences between successive subdivisions).
    pub error: f64,
    /// Integrand evaluations (quadrature points; area sampling: rays).
    pub evaluations: usize,
}

/// An item of a max-heap (the adaptive kernels' worst piece first),
/// ranked by `key` in `f64::total_cmp` order.
pub(crate) struct Ranked<T> {
    pub(crate) key: f64,
    pub(crate) item: T,
}

impl<T> PartialEq for Ranked<T> {
    fn eq(&self, other: &Self) -> bool {
        self.key == other.key
    }
}
impl<T> Eq for Ranked<T> {}
impl<T> PartialOrd for Ranked<T> {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl<T> Ord for Ranked<T> {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.key.total_cmp(&other.key)
    }
}
