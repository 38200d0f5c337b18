//! The classic solutions of the radiosity system B = E + ρ F B on a dense
//! form-factor matrix: direct elimination, Jacobi and Gauss-Seidel
//! gathering, and Southwell shooting (progressive refinement) [GTGB84,
//! CG85, CCWG88].
//!
//! Owns: the iterations, their convergence tests and histories.
//!
//! Invariants:
//! - Radiosity sums are taken in f64, each row in a fixed order, so results
//!   are identical for any thread count.
//! - No solver hides non-convergence: [`Solution::converged`] says whether
//!   the tolerance was met within the iteration budget.
//! - The observer sees the *display* radiosity after every iteration: for
//!   shooting that includes the ambient term, everywhere else it is B.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::classic::matrix::FormFactorMatrix;
use crate::error::{Error, Result};

/// A classic solver.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum ClassicMethod {
    /// LU factorisation of I − ρF per channel (Gaussian elimination).
    Direct,
    /// Gathering from the previous sweep's radiosities.
    Jacobi,
    /// Gathering with each element's new value used at once.
    GaussSeidel,
    /// Southwell iteration: shoot the largest unshot power first.
    Shooting,
}

impl ClassicMethod {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            ClassicMethod::Direct => "direct",
            ClassicMethod::Jacobi => "jacobi",
            ClassicMethod::GaussSeidel => "gauss-seidel",
            ClassicMethod::Shooting => "shooting",
        }
    }
}

/// When an iterative solve stops.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Convergence {
    /// Gathering: stop when the largest change of any element's radiosity in
    /// a sweep, relative to the largest radiosity, falls below this.
    /// Shooting: stop when the unshot power falls below this fraction of the
    /// emitted power.
    pub tolerance: f64,
    /// Sweeps (gathering) or shots (shooting).
    pub max_iterations: usize,
}

impl Default for Convergence {
    fn default() -> Self {
        Convergence {
            tolerance: 1e-6,
            max_iterations: 1_000_000,
        }
    }
}

/// One iteration of a solver.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Iteration {
    /// Sweep or shot number, from 1.
    pub iteration: usize,
    /// Relative change (gathering) or relative unshot power (shooting).
    pub residual: f64,
    /// Seconds since the solve started.
    pub seconds: f64,
}

/// The outcome of a solve.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// Radiosity B per element (for shooting: what has been shot and
    /// received, without the ambient term).
    pub radiosity: Vec<DVec3>,
    /// Irradiance H per element, consistent with `radiosity`: B = E + ρ H.
    pub irradiance: Vec<DVec3>,
    /// One entry per sweep or shot.
    pub history: Vec<Iteration>,
    /// The tolerance was met within the iteration budget.
    pub converged: bool,
}

/// The linear system of a uniform mesh.
#[derive(Clone, Copy, Debug)]
pub struct System<'a> {
    /// F, row i gathering from column j.
    pub matrix: &'a FormFactorMatrix,
    /// ρ per element.
    pub reflectance: &'a [DVec3],
    /// E per element (W/m²).
    pub emission: &'a [DVec3],
    /// Area per element (m²).
    pub area: &'a [f64],
}

impl System<'_> {
    fn len(&self) -> usize {
        self.matrix.len()
    }

    /// H_i = Σ_j F_ij B_j, in parallel over rows, each row in order.
    fn gather(&self, b: &[DVec3]) -> Vec<DVec3> {
        (0..self.len())
            .into_par_iter()
            .with_min_len(16)
            .map(|i| row_dot(self.matrix.row(i), b))
            .collect()
    }
}

fn row_dot(row: &[f32], b: &[DVec3]) -> DVec3 {
    row.iter()
        .zip(b)
        .filter(|(f, _)| **f != 0.0)
        .map(|(&f, bj)| f as f64 * *bj)
        .sum()
}

/// Solves `system` with `method`. `observe(iteration, display_radiosity)`
/// is called after every iteration (once, with the answer, for the direct
/// method). Fails only when the direct method's factorisation would not fit
/// `memory_budget` bytes or the matrix is singular.
pub fn solve(
    system: &System,
    method: ClassicMethod,
    convergence: &Convergence,
    memory_budget: u64,
    observe: &mut dyn FnMut(usize, &[DVec3]),
) -> Result<Solution> {
    let n = system.len();
    assert!(system.reflectance.len() == n && system.emission.len() == n && system.area.len() == n);
    Ok(match method {
        ClassicMethod::Direct => direct(system, memory_budget, observe)?,
        ClassicMethod::Jacobi => gather(system, convergence, Sweep::Jacobi, observe),
        ClassicMethod::GaussSeidel => gather(system, convergence, Sweep::GaussSeidel, observe),
        ClassicMethod::Shooting => shoot(system, convergence, observe),
    })
}

/// Gaussian elimination: (I − diag(ρ_c) F) B_c = E_c, one LU factorisation
/// with partial pivoting per channel.
fn direct(
    system: &System,
    memory_budget: u64,
    observe: &mut dyn FnMut(usize, &[DVec3]),
) -> Result<Solution> {
    let n = system.len();
    let start = Instant::now();
    let bytes = (n as u64) * (n as u64) * 8;
    if bytes + FormFactorMatrix::bytes_for(n) > memory_budget {
        return Err(Error::Setting(format!(
            "the direct method for {n} elements needs {:.2} GiB for its factorisation besides the matrix, \
             over the memory budget of {:.2} GiB",
            bytes as f64 / (1u64 << 30) as f64,
            memory_budget as f64 / (1u64 << 30) as f64
        )));
    }
    let mut b = vec![DVec3::ZERO; n];
    for c in 0..3 {
        let m = nalgebra::DMatrix::<f64>::from_fn(n, n, |i, j| {
            let f = f64::from(system.matrix.get(i, j));
            (if i == j { 1.0 } else { 0.0 }) - system.reflectance[i][c] * f
        });
        let rhs = nalgebra::DVector::<f64>::from_fn(n, |i, _| system.emission[i][c]);
        let x = m
            .lu()
            .solve(&rhs)
            .ok_or_else(|| Error::Setting("the radiosity matrix is singular".into()))?;
        for i in 0..n {
            b[i][c] = x[i];
        }
    }
    let h = system.gather(&b);
    // The residual of the solved system, relative to the largest radiosity.
    let scale = b.iter().map(|x| x.abs().max_element()).fold(0.0, f64::max);
    let residual = (0..n)
        .map(|i| {
            (system.emission[i] + system.reflectance[i] * h[i] - b[i])
                .abs()
                .max_element()
        })
        .fold(0.0, f64::max);
    let history = vec![Iteration {
        iteration: 1,
        residual: if scale > 0.0 { residual / scale } else { 0.0 },
        seconds: start.elapsed().as_secs_f64(),
    }];
    observe(1, &b);
    Ok(Solution {
        radiosity: b,
        irradiance: h,
        history,
        converged: true,
    })
}

/// How a gathering sweep uses what it has just computed.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Sweep {
    /// Jacobi: every element from the previous sweep's radiosities.
    Jacobi,
    /// Gauss-Seidel: each element's new value used at once.
    GaussSeidel,
}

/// Jacobi or Gauss-Seidel sweeps, starting from B = E.
fn gather(
    system: &System,
    convergence: &Convergence,
    sweep: Sweep,
    observe: &mut dyn FnMut(usize, &[DVec3]),
) -> Solution {
    let n = system.len();
    let (e, rho) = (system.emission, system.reflectance);
    let start = Instant::now();
    let mut b = e.to_vec();
    let mut history = Vec::new();
    let mut converged = n == 0;
    for iteration in 1..=convergence.max_iterations.max(1) {
        if n == 0 {
            break;
        }
        let change = if sweep == Sweep::GaussSeidel {
            let mut change: f64 = 0.0;
            for i in 0..n {
                let next = e[i] + rho[i] * row_dot(system.matrix.row(i), &b);
                change = change.max((next - b[i]).abs().max_element());
                b[i] = next;
            }
            change
        } else {
            let h = system.gather(&b);
            let next: Vec<DVec3> = (0..n).map(|i| e[i] + rho[i] * h[i]).collect();
            let change = next
                .iter()
                .zip(&b)
                .map(|(x, y)| (*x - *y).abs().max_element())
                .fold(0.0, f64::max);
            b = next;
            change
        };
        let scale = b.iter().map(|x| x.max_element()).fold(0.0, f64::max);
        let residual = if scale > 0.0 { change / scale } else { 0.0 };
        history.push(Iteration {
            iteration,
            residual,
            seconds: start.elapsed().as_secs_f64(),
        });
        observe(iteration, &b);
        if residual < convergence.tolerance {
            converged = true;
            break;
        }
    }
    let h = system.gather(&b);
    Solution {
        radiosity: b,
        irradiance: h,
        history,
        converged,
    }
}

/// Southwell shooting \[CCWG88\]: repeatedly take the element with the largest
/// unshot power ΔB_i A_i (summed over channels; ties to the lowest index)
/// and distribute it: every j receives ΔB_j += ρ_j F_ji ΔB_i. The display
/// radiosity adds the ambient term ρ_j · R · Σ ΔB_i A_i / Σ A_i with
/// R = 1 / (1 − ρ_mean), the area-weighted mean reflectance.
fn shoot(
    system: &System,
    convergence: &Convergence,
    observe: &mut dyn FnMut(usize, &[DVec3]),
) -> Solution {
    let n = system.len();
    let (e, rho, area) = (system.emission, system.reflectance, system.area);
    let start = Instant::now();
    let mut b = e.to_vec();
    let mut unshot = e.to_vec();
    let mut h = vec![DVec3::ZERO; n];
    let total_area: f64 = area.iter().sum();
    let emitted: f64 = (0..n).map(|i| (e[i] * area[i]).element_sum()).sum();
    let rho_mean: DVec3 = if total_area > 0.0 {
        (0..n).map(|i| rho[i] * area[i]).sum::<DVec3>() / total_area
    } else {
        DVec3::ZERO
    };
    let overrelax = DVec3::ONE / (DVec3::ONE - rho_mean).max(DVec3::splat(1e-6));
    let mut history = Vec::new();
    let mut converged = n == 0 || emitted <= 0.0;
    let mut display = vec![DVec3::ZERO; n];
    for iteration in 1..=convergence.max_iterations.max(1) {
        if converged {
            break;
        }
        let mut best = 0;
        let mut best_power = -1.0;
        for i in 0..n {
            let p = (unshot[i] * area[i]).element_sum();
            if p > best_power {
                best = i;
                best_power = p;
            }
        }
        let shot = unshot[best];
        unshot[best] = DVec3::ZERO;
        for j in 0..n {
            let f = system.matrix.get(j, best);
            if f != 0.0 {
                let incident = (f as f64) * shot;
                h[j] += incident;
                let received = rho[j] * incident;
                unshot[j] += received;
                b[j] += received;
            }
        }
        let remaining: DVec3 = (0..n).map(|i| unshot[i] * area[i]).sum();
        let residual = remaining.element_sum() / emitted;
        history.push(Iteration {
            iteration,
            residual,
            seconds: start.elapsed().as_secs_f64(),
        });
        let ambient = overrelax * remaining / total_area.max(f64::MIN_POSITIVE);
        for j in 0..n {
            display[j] = b[j] + rho[j] * ambient;
        }
        observe(iteration, &display);
        if residual < convergence.tolerance {
            converged = true;
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

    const ALL: [ClassicMethod; 4] = [
        ClassicMethod::Direct,
        ClassicMethod::Jacobi,
        ClassicMethod::GaussSeidel,
        ClassicMethod::Shooting,
    ];

    fn run(
        m: &FormFactorMatrix,
        rho: &[DVec3],
        e: &[DVec3],
        area: &[f64],
        method: ClassicMethod,
    ) -> Solution {
        let system = System {
            matrix: m,
            reflectance: rho,
            emission: e,
            area,
        };
        let conv = Convergence {
            tolerance: 1e-12,
            max_iterations: 100_000,
        };
        solve(&system, method, &conv, 1 << 30, &mut |_, _| {}).unwrap()
    }

    /// Two elements seeing only each other with F = 1 (an idealised
    /// enclosure): B = E + ρ B gives B = E / (1 − ρ) when both emit E.
    #[test]
    fn furnace_pair_every_method() {
        let m = FormFactorMatrix::from_values(2, vec![0.0, 1.0, 1.0, 0.0]).unwrap();
        let rho = vec![DVec3::splat(0.5); 2];
        let e = vec![DVec3::ONE; 2];
        for method in ALL {
            let s = run(&m, &rho, &e, &[1.0, 1.0], method);
            assert!(s.converged, "{method:?}");
            for b in &s.radiosity {
                assert!((b.x - 2.0).abs() < 1e-9, "{method:?}: {b}");
            }
        }
    }

    #[test]
    fn methods_agree_on_a_random_matrix() {
        use rand::Rng;
        let n = 40;
        let mut rng = crate::sampling::stream(5, 0);
        let area: Vec<f64> = (0..n).map(|_| rng.random_range(0.5..2.0)).collect();
        // Rows summing to at most 1, zero diagonal.
        let mut v = vec![0f32; n * n];
        for i in 0..n {
            let w: Vec<f64> = (0..n)
                .map(|j| if i == j { 0.0 } else { rng.random::<f64>() })
                .collect();
            let s: f64 = w.iter().sum::<f64>() / rng.random_range(0.7..1.0);
            for j in 0..n {
                v[i * n + j] = (w[j] / s) as f32;
            }
        }
        let m = FormFactorMatrix::from_values(n, v).unwrap();
        let rho: Vec<DVec3> = (0..n)
            .map(|_| DVec3::new(0.9, 0.5, rng.random_range(0.0..0.95)))
            .collect();
        let e: Vec<DVec3> = (0..n)
            .map(|i| {
                if i % 7 == 0 {
                    DVec3::new(3.0, 2.0, 1.0)
                } else {
                    DVec3::ZERO
                }
            })
            .collect();
        let reference = run(&m, &rho, &e, &area, ClassicMethod::Direct);
        for method in ALL {
            let s = run(&m, &rho, &e, &area, method);
            assert!(s.converged);
            for (x, y) in s.radiosity.iter().zip(&reference.radiosity) {
                assert!(
                    (*x - *y).abs().max_element() <= 1e-6 * y.max_element().max(1e-9),
                    "{method:?}: {x} vs {y}"
                );
            }
            // B = E + ρ H holds for the reported irradiance.
            for i in 0..n {
                let b = e[i] + rho[i] * s.irradiance[i];
                assert!((b - s.radiosity[i]).abs().max_element() < 1e-6);
            }
        }
    }

    #[test]
    fn budget_stops_and_is_reported() {
        let m = FormFactorMatrix::from_values(2, vec![0.0, 1.0, 1.0, 0.0]).unwrap();
        let rho = vec![DVec3::splat(0.99); 2];
        let e = vec![DVec3::ONE; 2];
        let system = System {
            matrix: &m,
            reflectance: &rho,
            emission: &e,
            area: &[1.0, 1.0],
        };
        let conv = Convergence {
            tolerance: 1e-9,
            max_iterations: 5,
        };
        let mut seen = Vec::new();
        let s = solve(
            &system,
            ClassicMethod::Jacobi,
            &conv,
            1 << 30,
            &mut |k, _| seen.push(k),
        )
        .unwrap();
        assert!(!s.converged);
        assert_eq!(s.history.len(), 5);
        assert_eq!(seen, [1, 2, 3, 4, 5]);
        let err = solve(&system, ClassicMethod::Direct, &conv, 16, &mut |_, _| {}).unwrap_err();
        assert!(err.to_string().contains("2 elements"), "{err}");
    }
}
