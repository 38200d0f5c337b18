//! Form factors between input surfaces (one glTF node's mesh each), for
//! `nusselt formfactors`.
//!
//! Owns: aggregating an element matrix into surface-to-surface factors with
//! their reciprocity and closure diagnostics.
//!
//! Invariant: F_ST is the fraction of the power leaving S (uniformly over
//! its area, both sides of double-sided surfaces included) that arrives at
//! T: F_ST = Σ_{i∈S} A_i Σ_{j∈T} F_ij / A_S.

use crate::classic::matrix::{FormFactorMatrix, Kernel};
use crate::classic::uniform::UniformMesh;
use crate::scene::Scene;

/// The methods of `nusselt formfactors --method`, by the lecture's names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SurfaceMethod {
    /// Adaptive polygon-to-polygon quadrature of the analytic inner
    /// integral, visibility by rays.
    Analytic,
    /// Adaptive area sampling: receiver points where needed, the source
    /// cut into pieces with one ray each, to `--sampling-tolerance`.
    Sampling,
    /// A hemicube at each element's centroid, z-buffer visibility.
    Hemicube,
}

impl SurfaceMethod {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SurfaceMethod::Analytic => "analytic",
            SurfaceMethod::Sampling => "sampling",
            SurfaceMethod::Hemicube => "hemicube",
        }
    }

    /// The method computed by `kernel`, if one is.
    pub fn of(kernel: Kernel) -> Option<SurfaceMethod> {
        [
            SurfaceMethod::Analytic,
            SurfaceMethod::Sampling,
            SurfaceMethod::Hemicube,
        ]
        .into_iter()
        .find(|m| m.kernel() == kernel)
    }

    /// The kernel that computes it.
    pub fn kernel(self) -> Kernel {
        match self {
            SurfaceMethod::Analytic => Kernel::PolygonPolygon,
            SurfaceMethod::Sampling => Kernel::Sampling,
            SurfaceMethod::Hemicube => Kernel::Hemicube,
        }
    }
}

/// One ordered pair of surfaces with a non-zero factor either way.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SurfacePair {
    /// The surface the power leaves (its node name).
    pub from: String,
    /// The surface it arrives at.
    pub to: String,
    /// F_ST.
    pub form_factor: f64,
    /// F_TS.
    pub reverse: f64,
    /// |A_S F_ST − A_T F_TS| / max of the two (0 when both vanish).
    pub reciprocity_error: f64,
    /// Σ_T F_ST over every T for this `from` surface (1 when S sits in a
    /// closed enclosure).
    pub row_sum: f64,
    /// The kernel's estimated absolute error of F_ST: the element
    /// factors' estimates, area-weighted like the factors and summed (no
    /// cancellation assumed); `None` for a kernel without estimates.
    pub error: Option<f64>,
}

/// Aggregates `matrix` (built on `mesh`) into surface pairs, ordered by
/// (from, to) surface index; `errors` (row-major like the matrix) are the
/// entries' error estimates, when the kernel has them.
pub fn surface_form_factors(
    scene: &Scene,
    mesh: &UniformMesh,
    matrix: &FormFactorMatrix,
    errors: Option<&[f32]>,
) -> Vec<SurfacePair> {
    let k = scene.surfaces.len();
    let surface_of = |e: usize| scene.patches[mesh.elements[e].patch as usize].surface as usize;
    let mut area = vec![0.0; k];
    for (e, el) in mesh.elements.iter().enumerate() {
        area[surface_of(e)] += el.area;
    }
    // power[s][t] = Σ_{i∈s} A_i Σ_{j∈t} F_ij
    let mut power = vec![vec![0.0; k]; k];
    // The same sums over the entries' errors.
    let mut slack = vec![vec![0.0; k]; k];
    let n = mesh.elements.len();
    for i in 0..n {
        let s = surface_of(i);
        for (j, &f) in matrix.row(i).iter().enumerate() {
            if f != 0.0 {
                power[s][surface_of(j)] += mesh.elements[i].area * f as f64;
            }
        }
        if let Some(errors) = errors {
            for (j, &e) in errors[i * n..(i + 1) * n].iter().enumerate() {
                slack[s][surface_of(j)] += mesh.elements[i].area * e as f64;
            }
        }
    }
    let factor = |s: usize, t: usize| {
        if area[s] > 0.0 {
            power[s][t] / area[s]
        } else {
            0.0
        }
    };
    let mut pairs = Vec::new();
    for s in 0..k {
        let row_sum: f64 = (0..k).map(|t| factor(s, t)).sum();
        for t in 0..k {
            let (f, g) = (factor(s, t), factor(t, s));
            if f == 0.0 && g == 0.0 {
                continue;
            }
            let (a, b) = (power[s][t], power[t][s]);
            pairs.push(SurfacePair {
                from: scene.surfaces[s].name.clone(),
                to: scene.surfaces[t].name.clone(),
                form_factor: f,
                reverse: g,
                reciprocity_error: (a - b).abs() / a.max(b),
                row_sum,
                error: errors.map(|_| {
                    if area[s] > 0.0 {
                        slack[s][t] / area[s]
                    } else {
                        0.0
                    }
                }),
            });
        }
    }
    pairs
}
