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

pub mod error;
pub mod util;

pub mod classic;
pub mod discontinuity;
pub mod formfactor;
pub mod hierarchical;
pub mod lab;

#[doc(hidden)]
pub mod fuzz;
pub mod load;
pub mod mesh;
pub mod meshing;
pub mod output;
pub mod pipeline;
pub mod reference;
pub mod render;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod visibility;

pub use error::{Error, Result};
