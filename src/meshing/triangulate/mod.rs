//! Crack-free constrained triangulation of every patch of a [`Scene`].
//!
//! Owns: turning each patch polygon, plus extra points and constraint
//! segments lying in its plane, into triangles, such that neighbouring
//! patches agree vertex for vertex along the edges they share; and the
//! validator [`validate_patch_mesh`] that checks exactly that. spade's
//! constrained Delaunay triangulation is used here (in `cdt`) and nowhere
//! else.
//!
//! The pipeline, with the file that owns each step:
//!
//! ```text
//!  per patch (parallel)        global (sequential, hashed)       per patch (parallel)
//!  ┌───────────────────┐   ┌──────────────────────────────┐   ┌────────────────────────┐
//!  │ 2D frame, classify│   │ weld corners + boundary pts  │   │ chain = corners + edge │
//!  │ points, clip segs │──▶│ (canonical f64 positions);   │──▶│ lists; split crossings;│
//!  │ to the polygon    │   │ each canonical point goes to │   │ CDT; keep faces inside │
//!  └───────────────────┘   │ every patch edge it lies on  │   │ the chain (flood fill) │
//!        frame.rs          └──────────────────────────────┘   └────────────────────────┘
//!                                     weld.rs                   constraints.rs, cdt.rs
//! ```
//!
//! `grid.rs` holds the hash grids the steps query, `validate.rs` the
//! validator.
//!
//! With refinement the three steps run twice: the first run refines each
//! patch alone and harvests its Steiner points; the second run treats them as
//! ordinary input points (so Steiner points on a patch edge reach the
//! neighbours too) and does not refine.
//!
//! Invariants of the result:
//! - every vertex on a patch's boundary has one canonical f64 position shared
//!   bit for bit by every patch whose edge passes through it, so every
//!   boundary edge has a twin in each collinearly overlapping neighbour edge
//!   (no cracks, no T-vertices);
//! - triangles are counter-clockwise seen from the patch front and tile the
//!   patch (their areas sum to the patch area);
//! - every input segment, clipped to the patch and split at crossings, is a
//!   union of mesh edges;
//! - no panic escapes: spade is guarded (points welded, segments deduplicated
//!   as unordered pairs and split at their crossings before insertion, its
//!   splitting and refinement calls isolated with `catch_unwind`);
//! - the result depends only on the scene and the inputs, not on the thread
//!   count.
//!
//! Tolerances are relative: the weld radius of a patch is `WELD` times the
//! scene diagonal, reduced to `THIN` times the patch's width for thin
//! patches; points within `ON_EDGE` weld radii of an edge go on it,
//! boundary points within `CORNER` of a corner become that corner.
//!
//! Refinement runs inside a frame of four extra vertices around the patch:
//! rounding leaves boundary points a hair inside the hull, and spade would
//! keep splitting the hull edges of those slivers. Steiner points outside the
//! patch are dropped; ones on its edges are shared like any boundary point.

mod cdt;
mod constraints;
mod frame;
mod grid;
mod validate;
mod weld;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::scene::Scene;
use cdt::{Harvest, mesh_patch, steiner_points};
use frame::{LocalPatch, Polygon};
pub use validate::validate_patch_mesh;
use weld::connect;

/// Weld radius relative to the scene diagonal.
const WELD: f64 = 1e-7;
/// Largest weld radius relative to a patch's width.
const THIN: f64 = 1e-2;
/// A point within this many weld radii of a patch edge is put on it.
const ON_EDGE: f64 = 2.0;
/// A boundary point within this many weld radii of a corner becomes the
/// corner: near a corner, a point would be close to both edges' lines.
const CORNER: f64 = 8.0;

/// Extra input of one patch: points to become vertices and segments to
/// become chains of edges. Both are in world space and meant to lie in the
/// patch plane (they are projected onto it); anything outside the patch is
/// clipped away.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PatchInput {
    /// Points to become vertices.
    pub points: Vec<DVec3>,
    /// Segments (two end points) to become chains of constraint edges.
    pub segments: Vec<[DVec3; 2]>,
}

/// Quality refinement settings.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangulateOptions {
    /// Refine towards this smallest angle (degrees, in (0, 34]); `None`
    /// keeps the plain constrained Delaunay triangulation.
    pub min_angle_deg: Option<f64>,
    /// Most Steiner points refinement may add to one patch.
    pub max_added_vertices: usize,
}

impl Default for TriangulateOptions {
    /// No refinement (the cap stays at 1000 Steiner points per patch).
    fn default() -> Self {
        TriangulateOptions {
            min_angle_deg: None,
            max_added_vertices: 1000,
        }
    }
}

impl TriangulateOptions {
    /// Refinement towards 25° with at most 1000 Steiner points per patch.
    pub fn refined() -> Self {
        TriangulateOptions {
            min_angle_deg: Some(25.0),
            max_added_vertices: 1000,
        }
    }
}

/// The triangulation of one patch, in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PatchTriangulation {
    /// Vertex positions; those on the patch boundary are canonical (shared
    /// bit for bit with the neighbours).
    pub positions: Vec<DVec3>,
    /// Counter-clockwise seen from the patch front.
    pub triangles: Vec<[u32; 3]>,
    /// Edges of the (clipped, split) input segments inside the patch.
    pub constrained_edges: Vec<[u32; 2]>,
    /// Edges along the patch boundary, counter-clockwise.
    pub boundary_edges: Vec<[u32; 2]>,
}

/// Triangulates every patch of `scene` with its input (one per patch, in
/// patch order). Deterministic; parallel over patches.
pub fn triangulate_patches(
    scene: &Scene,
    inputs: &[PatchInput],
    opts: &TriangulateOptions,
) -> Result<Vec<PatchTriangulation>> {
    if inputs.len() != scene.patches.len() {
        return Err(Error::Mesh(format!(
            "{} patch inputs for {} patches",
            inputs.len(),
            scene.patches.len()
        )));
    }
    if let Some(a) = opts.min_angle_deg
        && !(a > 0.0 && a <= 34.0)
    {
        return Err(Error::Setting(format!(
            "minimum triangle angle {a}° is outside (0, 34]"
        )));
    }
    let diagonal = scene.diagonal();
    if !(diagonal > 0.0 && diagonal.is_finite()) {
        return Err(Error::Mesh("the scene has no extent".into()));
    }
    let mut locals: Vec<LocalPatch> = scene
        .patches
        .par_iter()
        .zip(inputs)
        .enumerate()
        .map(|(i, (patch, input))| LocalPatch::build(i, Polygon::new(patch, diagonal), input))
        .collect::<Result<_>>()?;

    if let Some(angle) = opts.min_angle_deg {
        // First run: refine each patch alone, keep its Steiner points as
        // input points.
        let conn = connect(&locals, diagonal);
        let harvests: Vec<Harvest> = locals
            .par_iter()
            .enumerate()
            .map(|(i, local)| steiner_points(i, local, &conn, angle, opts.max_added_vertices))
            .collect::<Result<_>>()?;
        for (local, h) in locals.iter_mut().zip(harvests) {
            local.boundary.extend(h.boundary);
            local.interior.extend(h.interior);
        }
    }
    let conn = connect(&locals, diagonal);

    locals
        .par_iter()
        .enumerate()
        .map(|(i, local)| mesh_patch(i, local, &conn))
        .collect()
}
