//! Iterative solution of the radiosity system B = E + ρ F B on a dense
//! form-factor matrix.
//!
//! Owns: the gathering iterations and their convergence history.
//!
//! Invariants:
//! - Radiosity sums are taken in f64, each row in a fixed order, so results
//!   are identical for any thread count.
//! - The solver never hides non-convergence: [`Solution::converged`] says
//!   whether the tolerance was met within the iteration budget.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::matrix::FormFactorMatrix;

/// When an iterative solve stops.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Convergence {
    /// Stop when the largest change of any element's radiosity in a sweep,
    /// relative to the largest radiosity, falls below this.
    pub tolerance: f64,
    pub max_iterations: usize,
}

impl Default for Convergence {
    fn default() -> Self {
        Convergence {
            tolerance: 1e-6,
            max_iterations: 10_000,
        }
    }
}

/// One sweep of an iterative solver.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Iteration {
    pub iteration: usize,
    /// Relative change in this sweep (see [`Convergence::tolerance`]).
    pub residual: f64,
    /// Seconds since the solve started.
    pub seconds: f64,
}

/// The outcome of a solve.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// Radiosity B per element.
    pub radiosity: Vec<DVec3>,
    /// Irradiance H per element (what was gathered in the last sweep).
    pub irradiance: Vec<DVec3>,
    pub history: Vec<Iteration>,
    pub converged: bool,
}

/// Jacobi gathering: every sweep computes H = F B from the previous sweep's
/// radiosities, then B = E + ρ H, starting from B = E.
pub fn jacobi(
    matrix: &FormFactorMatrix,
    reflectance: &[DVec3],
    emission: &[DVec3],
    convergence: &Convergence,
) -> Solution {
    let n = matrix.len();
    assert!(reflectance.len() == n && emission.len() == n);
    let start = Instant::now();
    let mut b = emission.to_vec();
    let mut h = vec![DVec3::ZERO; n];
    let mut history = Vec::new();
    let mut converged = n == 0;
    for iteration in 1..=convergence.max_iterations.max(1) {
        if n == 0 {
            break;
        }
        h = (0..n)
            .into_par_iter()
            .with_min_len(16)
            .map(|i| {
                matrix
                    .row(i)
                    .iter()
                    .zip(&b)
                    .filter(|(f, _)| **f != 0.0)
                    .map(|(&f, bj)| f as f64 * *bj)
                    .sum()
            })
            .collect();
        let next: Vec<DVec3> = (0..n)
            .map(|i| emission[i] + reflectance[i] * h[i])
            .collect();
        let scale = next.iter().map(|x| x.max_element()).fold(0.0, f64::max);
        let change = next
            .iter()
            .zip(&b)
            .map(|(x, y)| (*x - *y).abs().max_element())
            .fold(0.0, f64::max);
        let residual = if scale > 0.0 { change / scale } else { 0.0 };
        b = next;
        history.push(Iteration {
            iteration,
            residual,
            seconds: start.elapsed().as_secs_f64(),
        });
        if residual < convergence.tolerance {
            converged = true;
            break;
        }
    }
    Solution {
        radiosity: b,
        irradiance: h,
        history,
        converged,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two elements seeing only each other with F = 1 (an idealised
    /// enclosure): B = E + ρ B gives B = E / (1 − ρ) when both emit E.
    #[test]
    fn furnace_pair() {
        let m = FormFactorMatrix::from_values(2, vec![0.0, 1.0, 1.0, 0.0]).unwrap();
        let rho = vec![DVec3::splat(0.5); 2];
        let e = vec![DVec3::ONE; 2];
        let s = jacobi(&m, &rho, &e, &Convergence::default());
        assert!(s.converged);
        for b in &s.radiosity {
            assert!((b.x - 2.0).abs() < 1e-5, "{b}");
        }
    }
}
