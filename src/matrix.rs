//! The dense form-factor matrix of a uniform mesh, for the classic solvers.
//!
//! Owns: [`FormFactorMatrix`] and its assembly from the point-to-polygon
//! kernel with ray-sampled visibility.
//!
//! Invariants:
//! - Row i holds F_ij for receiver i and every source j (f32; sums are taken
//!   in f64 by the solvers); F_ii = 0; every entry is in [0, 1].
//! - A matrix is only allocated when it fits the memory budget; otherwise
//!   assembly fails with a message naming the element count and the memory
//!   it would take.
//! - Entries depend only on the geometry, the seed and the ray count, not on
//!   the thread count.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::formfactor::form_factor_point_polygon;
use crate::progress::Progress;
use crate::sampling::{pair_stream, point_in_polygon, stratified};
use crate::uniform::UniformMesh;
use crate::visibility::TriangleBvh;

/// Default memory budget for dense matrices: 2 GiB.
pub const DEFAULT_MEMORY_BUDGET: u64 = 2 << 30;

/// How the matrix is assembled.
#[derive(Clone, Debug, PartialEq)]
pub struct MatrixSettings {
    /// Visibility rays per element pair (stratified on both elements).
    pub visibility_rays: usize,
    pub seed: u64,
    /// Largest matrix allowed, in bytes.
    pub memory_budget: u64,
}

impl Default for MatrixSettings {
    fn default() -> Self {
        MatrixSettings {
            visibility_rays: 4,
            seed: 0,
            memory_budget: DEFAULT_MEMORY_BUDGET,
        }
    }
}

/// Counters of an assembly.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct MatrixStats {
    /// Pairs with a non-zero unoccluded form factor.
    pub nonzero_pairs: u64,
    pub visibility_rays: u64,
    /// Largest and mean row sum Σ_j F_ij (closure: 1 in an enclosure).
    pub max_row_sum: f64,
    pub mean_row_sum: f64,
}

/// Dense row-major n × n form factors; row = receiver.
#[derive(Clone, Debug, PartialEq)]
pub struct FormFactorMatrix {
    n: usize,
    values: Vec<f32>,
}

impl FormFactorMatrix {
    /// Bytes a matrix of `n` elements takes.
    pub fn bytes_for(n: usize) -> u64 {
        (n as u64) * (n as u64) * 4
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

    /// Assembles F for `mesh`: the analytic form factor from each receiver's
    /// centroid to each source polygon, times the fraction of
    /// `visibility_rays` segments between stratified points of the two
    /// elements that `bvh` leaves unblocked.
    pub fn point_polygon(
        mesh: &UniformMesh,
        bvh: &TriangleBvh,
        settings: &MatrixSettings,
        progress: &Progress,
    ) -> Result<(FormFactorMatrix, MatrixStats)> {
        let n = mesh.elements.len();
        let mut matrix = Self::zeros(n, settings.memory_budget)?;
        let rays = settings.visibility_rays.max(1);
        let phase = progress.phase("form factors", n as u64);
        let ray_count = AtomicU64::new(0);
        let nonzero = AtomicU64::new(0);
        matrix
            .values
            .par_chunks_mut(n.max(1))
            .enumerate()
            .for_each(|(i, row)| {
                let r = &mesh.elements[i];
                let (mut row_rays, mut row_nonzero) = (0, 0);
                for (j, s) in mesh.elements.iter().enumerate() {
                    if s.patch == r.patch {
                        continue;
                    }
                    let f = form_factor_point_polygon(r.centroid, r.normal, &s.corners);
                    if f <= 0.0 {
                        continue;
                    }
                    let mut rng = pair_stream(settings.seed, i as u32, j as u32);
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
                    row_rays += rays as u64;
                    if visible > 0 {
                        row[j] = (f * visible as f64 / rays as f64) as f32;
                        row_nonzero += 1;
                    }
                }
                ray_count.fetch_add(row_rays, Ordering::Relaxed);
                nonzero.fetch_add(row_nonzero, Ordering::Relaxed);
                phase.inc(1);
            });
        let sums: Vec<f64> = (0..n)
            .map(|i| matrix.row(i).iter().map(|&f| f as f64).sum())
            .collect();
        let stats = MatrixStats {
            nonzero_pairs: nonzero.into_inner(),
            visibility_rays: ray_count.into_inner(),
            max_row_sum: sums.iter().copied().fold(0.0, f64::max),
            mean_row_sum: if n > 0 {
                sums.iter().sum::<f64>() / n as f64
            } else {
                0.0
            },
        };
        Ok((matrix, stats))
    }
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
