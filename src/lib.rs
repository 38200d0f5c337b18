//! nusselt: global illumination of diffuse scenes by hierarchical radiosity.
//!
//! The pipeline runs load → scene → visibility → solve → output mesh →
//! outputs; ARCHITECTURE.md has the map. The library does no printing: it
//! returns results and diagnostics, and only [`output`] writes files.

pub mod error;
pub mod formfactor;
pub mod frame;
pub mod hemicube;
pub mod matrix;
pub mod mesh;
pub mod progress;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod solve;
pub mod uniform;
pub mod view;
pub mod visibility;

pub use error::{Error, Result};
