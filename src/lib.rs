//! nusselt: global illumination of diffuse scenes by hierarchical radiosity.
//!
//! The pipeline runs load → scene → visibility → solve → output mesh →
//! outputs; ARCHITECTURE.md has the map. The library does no printing: it
//! returns results and diagnostics, and only [`output`] writes files.

pub mod error;
pub mod frame;
pub mod load;
pub mod mesh;
pub mod scene;

pub use error::{Error, Result};
