//! The solve's own estimate of its vertex error: where two patches of one
//! flat surface meet, the vertices they share are two separate final
//! gathers of the same irradiance (different leaves, different links,
//! different rays), so their disagreement measures the error the vertex
//! values carry. A checkerboard of patch-wide constants, a patch whose
//! links read a source differently from its neighbour's, and per-vertex ray
//! noise all show here; a bias that every patch shares does not, so the
//! estimate is a lower bound on the error against the truth.
//!
//! Owns: [`SeamSteps`] and [`seam_steps`]. Invariants: only pairs of
//! non-emitting patches whose normals agree (one plane, one side) are
//! compared, by irradiance (B / ρ), so that a change of paint along an edge
//! is not counted as an error; each vertex meets at most [`PARTNERS`] others
//! at its point, so the work is linear in the vertices.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::mesh::OutputMesh;
use crate::scene::Scene;

/// Cosine above which two patch normals count as one plane's.
const SAME_PLANE: f32 = 0.9999;
/// Reflectance channels below this are left out of a vertex's irradiance.
const MIN_REFLECTANCE: f64 = 0.02;
/// Each vertex is compared with at most this many of the vertices after it
/// at its point, so that a point many patches share (a fan's centre) costs
/// linear, not quadratic, work; a grid's corner (four patches) still gets
/// all its pairs.
const PARTNERS: usize = 4;
/// Differences are relative to max(the pair's mean, this fraction of the
/// mean irradiance of all the pairs), so that noise in the dark does not
/// dominate.
const RELATIVE_FLOOR: f64 = 0.01;

/// How much the vertices two coplanar patches share disagree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SeamSteps {
    /// Vertex pairs compared.
    pub pairs: usize,
    /// Median of |H_a − H_b| / mean(H_a, H_b) over the pairs (H the
    /// irradiance, B / ρ, averaged over the channels).
    pub median: f64,
    /// Its 90th percentile.
    pub p90: f64,
    /// Its largest value.
    pub max: f64,
}

/// The seam steps of `mesh`, an output mesh of `scene`; `None` when no two
/// coplanar patches share a vertex.
pub fn seam_steps(scene: &Scene, mesh: &OutputMesh) -> Option<SeamSteps> {
    let irradiance = |v: usize| -> Option<f64> {
        let patch = scene.patches.get(*mesh.patch.get(v)? as usize)?;
        if patch.emission.max_element() > 0.0 {
            return None;
        }
        let b = mesh.radiosity[v].as_dvec3();
        let (sum, n) = (0..3)
            .filter(|&c| patch.reflectance[c] >= MIN_REFLECTANCE)
            .fold((0.0, 0), |(s, n), c| {
                (s + b[c] / patch.reflectance[c], n + 1)
            });
        (n > 0).then(|| sum / f64::from(n))
    };
    let mut at: HashMap<[u32; 3], Vec<usize>> = HashMap::new();
    for (v, p) in mesh.positions.iter().enumerate() {
        at.entry(p.to_array().map(f32::to_bits))
            .or_default()
            .push(v);
    }
    // Groups in vertex order, so that the sums below do not depend on the
    // hash map's order.
    let mut groups: Vec<Vec<usize>> = at.into_values().filter(|g| g.len() > 1).collect();
    groups.sort_unstable_by_key(|g| g[0]);
    let mut pairs: Vec<(f64, f64)> = Vec::new();
    for group in &groups {
        for (i, &a) in group.iter().enumerate() {
            for &b in group.iter().skip(i + 1).take(PARTNERS) {
                // Parallel normals through a shared point: one plane.
                if mesh.patch[a] == mesh.patch[b]
                    || mesh.normals[a].dot(mesh.normals[b]) < SAME_PLANE
                {
                    continue;
                }
                if let (Some(ha), Some(hb)) = (irradiance(a), irradiance(b)) {
                    pairs.push((ha, hb));
                }
            }
        }
    }
    if pairs.is_empty() {
        return None;
    }
    let level = pairs.iter().map(|(a, b)| 0.5 * (a + b)).sum::<f64>() / pairs.len() as f64;
    let floor = RELATIVE_FLOOR * level.abs();
    let mut steps: Vec<f64> = pairs
        .iter()
        .map(|&(a, b)| (a - b).abs() / (0.5 * (a + b)).abs().max(floor).max(f64::MIN_POSITIVE))
        .collect();
    steps.sort_by(f64::total_cmp);
    let q = |f: f64| steps[((f * (steps.len() - 1) as f64).round() as usize).min(steps.len() - 1)];
    Some(SeamSteps {
        pairs: steps.len(),
        median: q(0.5),
        p90: q(0.9),
        max: steps[steps.len() - 1],
    })
}
