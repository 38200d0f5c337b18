//! The dense form-factor matrix of a uniform mesh, for the classic solvers.
//!
//! Owns: [`FormFactorMatrix`] and its assembly with any of the kernels
//! (point-polygon, polygon-polygon, area sampling, hemicube).
//!
//! Invariants:
//! - Row i holds F_ij for receiver i and every source j (f32; sums are taken
//!   in f64 by the solvers); F_ii = 0; every entry is in [0, 1].
//! - A matrix is only allocated when it fits the memory budget; otherwise
//!   assembly fails with a message naming the element count and the memory
//!   it would take.
//! - Entries depend only on the geometry and the settings (seed included),
//!   not on the thread count.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::classic::uniform::UniformMesh;
use crate::error::{Error, Result};
use crate::formfactor::area_sampling::DEFAULT_TOLERANCE;
use crate::formfactor::{
    form_factor_area_sampling, form_factor_point_polygon, form_factor_polygon_polygon_with,
};
use crate::sampling::{pair_stream, point_in_polygon, stratified};
use crate::util::progress::Progress;
use crate::visibility::TriangleBvh;

/// Default memory budget for dense matrices: 2 GiB.
pub const DEFAULT_MEMORY_BUDGET: u64 = 2 << 30;

/// Which form-factor kernel fills the matrix.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum Kernel {
    /// Analytic form factor from the receiver's centroid to the source
    /// polygon, times the visible fraction of `visibility_rays` rays.
    PointPolygon,
    /// Adaptive quadrature over the receiver of the analytic inner integral,
    /// each point weighted by its visible fraction of the source.
    PolygonPolygon,
    /// Adaptive area sampling to `sampling_tolerance`: receiver points
    /// where the integrand needs them, the source cut into pieces with one
    /// ray each where visibility is partial.
    Sampling,
    /// A hemicube at each receiver's centroid; visibility by its z-buffer.
    Hemicube,
}

impl Kernel {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::PointPolygon => "point-polygon",
            Kernel::PolygonPolygon => "polygon-polygon",
            Kernel::Sampling => "sampling",
            Kernel::Hemicube => "hemicube",
        }
    }
}

/// How the matrix is assembled.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MatrixSettings {
    /// The form-factor kernel.
    pub kernel: Kernel,
    /// Visibility rays per element pair (point-polygon), or per quadrature
    /// point (polygon-polygon).
    pub visibility_rays: usize,
    /// Relative tolerance of each form factor, with an absolute floor of
    /// this times [`ABSOLUTE_FLOOR`](crate::formfactor::area_sampling::ABSOLUTE_FLOOR)
    /// (sampling).
    pub sampling_tolerance: f64,
    /// Absolute tolerance on each form factor (polygon-polygon).
    pub quadrature_tolerance: f64,
    /// Top-face cells per side (hemicube).
    pub hemicube_resolution: u32,
    /// Turn each hemicube by a random angle about its normal (hemicube).
    pub hemicube_rotation: bool,
    /// Seed of the visibility rays and sample points.
    pub seed: u64,
    /// Largest matrix allowed, in bytes.
    pub memory_budget: u64,
}

impl MatrixSettings {
    /// Checks the kernel's knobs: an even hemicube resolution from 2 to
    /// 8192, a positive quadrature tolerance and a positive, finite
    /// sampling tolerance. The error names the command-line option.
    pub fn validate(&self) -> Result<()> {
        let r = self.hemicube_resolution;
        if !(2..=8192).contains(&r) || !r.is_multiple_of(2) {
            return Err(Error::Setting(
                "--hemicube-resolution must be an even number from 2 to 8192".into(),
            ));
        }
        if !(self.quadrature_tolerance > 0.0) {
            return Err(Error::Setting(
                "--quadrature-tolerance must be positive".into(),
            ));
        }
        if !(self.sampling_tolerance > 0.0 && self.sampling_tolerance.is_finite()) {
            return Err(Error::Setting(format!(
                "--sampling-tolerance must be a positive, finite number, not {}",
                self.sampling_tolerance
            )));
        }
        Ok(())
    }
}

impl Default for MatrixSettings {
    fn default() -> Self {
        MatrixSettings {
            kernel: Kernel::PointPolygon,
            visibility_rays: 4,
            sampling_tolerance: DEFAULT_TOLERANCE,
            quadrature_tolerance: 1e-4,
            hemicube_resolution: 128,
            hemicube_rotation: true,
            seed: 0,
            memory_budget: DEFAULT_MEMORY_BUDGET,
        }
    }
}

/// Integrand evaluations one polygon-polygon matrix entry may spend.
const QUADRATURE_BUDGET: usize = 2_000;

/// Rays one area-sampling matrix entry may cast (about 2 ms of rays); an
/// entry that reaches it keeps its larger error estimate.
const SAMPLING_BUDGET: usize = 200_000;

/// Counters of an assembly.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct MatrixStats {
    /// Non-zero entries.
    pub nonzero_pairs: u64,
    /// Visibility rays cast.
    pub visibility_rays: u64,
    /// Largest and mean row sum Σ_j F_ij (closure: 1 in an enclosure).
    pub max_row_sum: f64,
    /// Mean Σ_j F_ij over the rows.
    pub mean_row_sum: f64,
    /// The kernel's own error estimates (sampling, polygon-polygon; `None`
    /// for the kernels that have none): the largest of any entry.
    pub max_error: Option<f64>,
    /// The mean over the rows of Σ_j (error of F_ij): how far a row sum may
    /// be off by the kernel's own account.
    pub mean_row_error: Option<f64>,
}

/// Dense row-major n × n form factors; row = receiver.
#[derive(Clone, Debug, PartialEq)]
pub struct FormFactorMatrix {
    n: usize,
    values: Vec<f32>,
}

impl FormFactorMatrix {
    /// Bytes a matrix of `n` elements takes (saturating).
    pub fn bytes_for(n: usize) -> u64 {
        Self::bytes_for_count(n as u64)
    }

    /// [`Self::bytes_for`] of a count not yet known to fit a `usize`.
    pub fn bytes_for_count(n: u64) -> u64 {
        n.saturating_mul(n).saturating_mul(4)
    }

    /// An all-zero matrix, if it fits the budget.
    pub fn zeros(n: usize, memory_budget: u64) -> Result<FormFactorMatrix> {
        let bytes = Self::bytes_for(n);
        if bytes > memory_budget {
            return Err(Error::Setting(format!(
                "a dense form-factor matrix for {n} elements needs {:.2} GiB, over the memory budget of {:.2} GiB \
                 (use larger elements or raise the budget)",
                bytes as f64 / (1u64 << 30) as f64,
                memory_budget as f64 / (1u64 << 30) as f64
            )));
        }
        Ok(FormFactorMatrix {
            n,
            values: vec![0.0; n * n],
        })
    }

    /// A matrix from row-major values (row = receiver). Fails unless there
    /// are n² values, each in [0, 1], with a zero diagonal.
    pub fn from_values(n: usize, values: Vec<f32>) -> Result<FormFactorMatrix> {
        if values.len() != n * n {
            return Err(Error::Setting(format!(
                "{} values for a {n} × {n} matrix",
                values.len()
            )));
        }
        if let Some(k) = values.iter().position(|f| !(0.0..=1.0).contains(f)) {
            return Err(Error::Setting(format!(
                "form factor {} at ({}, {}) outside [0, 1]",
                values[k],
                k / n,
                k % n
            )));
        }
        if let Some(i) = (0..n).find(|&i| values[i * n + i] != 0.0) {
            return Err(Error::Setting(format!(
                "non-zero diagonal form factor at {i}"
            )));
        }
        Ok(FormFactorMatrix { n, values })
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True for a 0 × 0 matrix.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Row i: F_ij for all j.
    pub fn row(&self, i: usize) -> &[f32] {
        &self.values[i * self.n..(i + 1) * self.n]
    }

    /// F_ij.
    pub fn get(&self, i: usize, j: usize) -> f32 {
        self.values[i * self.n + j]
    }

    /// Assembles F for `mesh` with the kernel of `settings`, rows in
    /// parallel. Pairs on the same patch are zero (a planar patch does not
    /// see itself).
    pub fn assemble(
        mesh: &UniformMesh,
        bvh: &TriangleBvh,
        settings: &MatrixSettings,
        progress: &Progress,
    ) -> Result<(FormFactorMatrix, MatrixStats)> {
        Self::assemble_inner(mesh, bvh, settings, progress, false).map(|(m, s, _)| (m, s))
    }

    /// [`Self::assemble`], also returning each entry's error estimate
    /// (row-major, as the matrix; zeros for kernels with none, see
    /// [`MatrixStats::max_error`]). The errors take as much memory again,
    /// not counted in the budget.
    pub fn assemble_with_errors(
        mesh: &UniformMesh,
        bvh: &TriangleBvh,
        settings: &MatrixSettings,
        progress: &Progress,
    ) -> Result<(FormFactorMatrix, MatrixStats, Vec<f32>)> {
        Self::assemble_inner(mesh, bvh, settings, progress, true)
    }

    fn assemble_inner(
        mesh: &UniformMesh,
        bvh: &TriangleBvh,
        settings: &MatrixSettings,
        progress: &Progress,
        keep_errors: bool,
    ) -> Result<(FormFactorMatrix, MatrixStats, Vec<f32>)> {
        let n = mesh.elements.len();
        let mut matrix = Self::zeros(n, settings.memory_budget)?;
        let mut errors = vec![0f32; if keep_errors { n * n } else { 0 }];
        let phase = progress.phase("form factors", n as u64);
        let hemicube = (settings.kernel == Kernel::Hemicube)
            .then(|| crate::formfactor::hemicube::Hemicube::new(settings.hemicube_resolution));
        let polygons: Vec<&[DVec3]> = mesh.elements.iter().map(|e| e.corners.as_slice()).collect();
        let row = |i: usize, row: &mut [f32], errors: &mut [f32]| {
            let rays = match &hemicube {
                Some(cube) => hemicube_row(mesh, &polygons, cube, settings, i, row),
                None => row_by_pairs(mesh, bvh, settings, i, row, errors),
            };
            phase.inc(1);
            let max = errors.iter().copied().fold(0f32, f32::max) as f64;
            let sum = errors.iter().map(|&e| e as f64).sum::<f64>();
            (rays, max, sum)
        };
        let chunk = n.max(1);
        let per_row: Vec<(u64, f64, f64)> = if keep_errors {
            matrix
                .values
                .par_chunks_mut(chunk)
                .zip(errors.par_chunks_mut(chunk))
                .enumerate()
                .map(|(i, (r, e))| row(i, r, e))
                .collect()
        } else {
            matrix
                .values
                .par_chunks_mut(chunk)
                .enumerate()
                .map(|(i, r)| row(i, r, &mut vec![0f32; n]))
                .collect()
        };
        let sums: Vec<f64> = (0..n)
            .map(|i| matrix.row(i).iter().map(|&f| f as f64).sum())
            .collect();
        let mean = |v: &mut dyn Iterator<Item = f64>| {
            if n > 0 {
                v.sum::<f64>() / n as f64
            } else {
                0.0
            }
        };
        let estimates = matches!(settings.kernel, Kernel::Sampling | Kernel::PolygonPolygon);
        let stats = MatrixStats {
            nonzero_pairs: matrix.values.iter().filter(|f| **f != 0.0).count() as u64,
            visibility_rays: per_row.iter().map(|r| r.0).sum(),
            max_row_sum: sums.iter().copied().fold(0.0, f64::max),
            mean_row_sum: mean(&mut sums.iter().copied()),
            max_error: estimates.then(|| per_row.iter().map(|r| r.1).fold(0.0, f64::max)),
            mean_row_error: estimates.then(|| mean(&mut per_row.iter().map(|r| r.2))),
        };
        Ok((matrix, stats, errors))
    }
}

/// Fills row `i` pair by pair with a ray-traced kernel, and `errors` with
/// each entry's error estimate where the kernel has one; returns rays cast.
fn row_by_pairs(
    mesh: &UniformMesh,
    bvh: &TriangleBvh,
    settings: &MatrixSettings,
    i: usize,
    row: &mut [f32],
    errors: &mut [f32],
) -> u64 {
    let r = &mesh.elements[i];
    let mut rays_cast = 0u64;
    for (j, s) in mesh.elements.iter().enumerate() {
        if s.patch == r.patch {
            continue;
        }
        // Cheap exact cull: no part of the source in front of the receiver,
        // or no part of the receiver in front of the source.
        if (form_factor_point_polygon(r.centroid, r.normal, &s.corners) <= 0.0
            && s.corners
                .iter()
                .all(|p| (*p - r.centroid).dot(r.normal) <= 0.0))
            || r.corners
                .iter()
                .all(|p| (*p - s.centroid).dot(s.normal) <= 0.0)
        {
            continue;
        }
        // The contour integral does not know which side of the source
        // emits: a receiver point behind the source's plane gets nothing.
        let facing = |x: DVec3| (x - s.centroid).dot(s.normal) > 0.0;
        let mut rng = pair_stream(settings.seed, i as u32, j as u32);
        let f = match settings.kernel {
            Kernel::PointPolygon => {
                if !facing(r.centroid) {
                    continue;
                }
                let f = form_factor_point_polygon(r.centroid, r.normal, &s.corners);
                if f <= 0.0 {
                    continue;
                }
                let rays = settings.visibility_rays.max(1);
                let from = stratified(rays, &mut rng);
                let to = stratified(rays, &mut rng);
                let visible = from
                    .iter()
                    .zip(&to)
                    .filter(|(a, b)| {
                        bvh.visible(
                            point_in_polygon(&r.corners, **a),
                            point_in_polygon(&s.corners, **b),
                        )
                    })
                    .count();
                rays_cast += rays as u64;
                f * visible as f64 / rays as f64
            }
            Kernel::PolygonPolygon => {
                let rays = settings.visibility_rays.max(1);
                let targets: Vec<DVec3> = stratified(rays, &mut rng)
                    .into_iter()
                    .map(|t| point_in_polygon(&s.corners, t))
                    .collect();
                let cast = AtomicU64::new(0);
                let estimate = form_factor_polygon_polygon_with(
                    &r.corners,
                    &s.corners,
                    settings.quadrature_tolerance,
                    QUADRATURE_BUDGET,
                    |x| {
                        if !facing(x) {
                            return 0.0;
                        }
                        cast.fetch_add(rays as u64, Ordering::Relaxed);
                        targets.iter().filter(|y| bvh.visible(x, **y)).count() as f64 / rays as f64
                    },
                );
                rays_cast += cast.into_inner();
                errors[j] = estimate.error as f32;
                estimate.value
            }
            Kernel::Sampling => {
                let estimate = form_factor_area_sampling(
                    &r.corners,
                    &s.corners,
                    settings.sampling_tolerance,
                    SAMPLING_BUDGET,
                    &mut rng,
                    |x, y| bvh.visible(x, y),
                );
                rays_cast += estimate.evaluations as u64;
                errors[j] = estimate.error as f32;
                estimate.value
            }
            Kernel::Hemicube => unreachable!("hemicube rows are filled whole"),
        };
        row[j] = f.clamp(0.0, 1.0) as f32;
    }
    rays_cast
}

/// Fills row `i` from one hemicube at the receiver's centroid; no rays.
fn hemicube_row(
    mesh: &UniformMesh,
    polygons: &[&[DVec3]],
    cube: &crate::formfactor::hemicube::Hemicube,
    settings: &MatrixSettings,
    i: usize,
    row: &mut [f32],
) -> u64 {
    let r = &mesh.elements[i];
    let rotation = if settings.hemicube_rotation {
        use rand::Rng;
        crate::sampling::stream(settings.seed, i as u64).random::<f64>() * std::f64::consts::TAU
    } else {
        0.0
    };
    let mut out = vec![0.0; polygons.len()];
    cube.row(r.centroid, r.normal, polygons, Some(i), rotation, &mut out);
    for (j, f) in out.iter().enumerate() {
        if mesh.elements[j].patch != r.patch {
            row[j] = f.clamp(0.0, 1.0) as f32;
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn over_budget_names_count_and_memory() {
        let err = FormFactorMatrix::zeros(100_000, DEFAULT_MEMORY_BUDGET).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("100000 elements") && msg.contains("37.25 GiB"),
            "{msg}"
        );
    }
}
