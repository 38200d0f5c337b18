//! nusselt: global illumination of diffuse scenes by radiosity.
//!
//! The pipeline runs load → scene → visibility → mesh → form factors →
//! solve → output mesh → outputs; ARCHITECTURE.md has the map. The library
//! does no printing: it returns results and diagnostics, and only [`output`]
//! writes files.

// `!(x > y)` is used on purpose throughout: it rejects NaN along with the
// values the comparison excludes. Index loops are the clearest form of the
// numeric kernels here.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

pub mod chart;
pub mod closed_form;
pub mod cluster;
pub mod compare;
pub mod discontinuity;
pub mod error;
pub mod failures;
pub mod formfactor;
pub mod frame;
pub mod hemicube;
pub mod hierarchical;
pub mod hierarchy;
pub mod links;
pub mod load;
pub mod matrix;
pub mod mesh;
pub mod meshing;
pub mod output;
pub mod pipeline;
pub mod progress;
pub mod reference;
pub mod render;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod solve;
pub mod study;
pub mod surfaces;
pub mod triangulate;
pub mod uniform;
pub mod view;
pub mod visibility;
pub mod wireframe;

pub use error::{Error, Result};
