//! The classic radiosity methods of the lecture: a uniform element grid,
//! the dense form-factor matrix, and the solvers that run on it (direct,
//! Jacobi, Gauss-Seidel, Southwell shooting), with the surface-to-surface
//! factors of `nusselt formfactors`.

pub mod matrix;
pub mod solve;
pub mod surfaces;
pub mod uniform;
