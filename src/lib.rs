//! nusselt: global illumination of diffuse scenes by radiosity.
//!
//! The pipeline runs load → scene → visibility → mesh → form factors →
//! solve → output mesh → outputs; ARCHITECTURE.md has the map. The library
//! does no printing: it returns results and diagnostics, and only [`output`]
//! writes files.

pub mod error;
pub mod formfactor;
pub mod frame;
pub mod hemicube;
pub mod load;
pub mod matrix;
pub mod mesh;
pub mod output;
pub mod pipeline;
pub mod progress;
pub mod render;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod solve;
pub mod surfaces;
pub mod uniform;
pub mod view;
pub mod visibility;

pub use error::{Error, Result};
