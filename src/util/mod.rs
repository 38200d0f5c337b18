//! Domain-free helpers: geometry, box searches, disjoint sets, named tolerances and
//! progress reporting. Nothing here knows of scenes, patches or light.

pub mod boxes;
pub mod geometry;
pub mod progress;
pub mod tolerance;
pub mod union_find;
