//! Point tables and scoring a solution against them: the bias of a
//! solution at surface points, against path-traced references
//! (`nusselt probe`), which pixel noise and image averages do not hide.
//!
//! Owns: the CSV of probe points (`x,y,z,nx,ny,nz`, more columns
//! ignored), the CSV of point references (the same, then `patch`, the
//! radiosity `r,g,b` and its standard error `se_r,se_g,se_b`), and
//! [`score`]: each point's value interpolated in the solution's output
//! mesh, its relative error, and the median, 90th percentile, worst error
//! and mean bias over the points.
//!
//! Invariants: the scalar compared is the mean of the three channels; a
//! relative error divides by the reference's value or, when that is
//! below [`RELATIVE_FLOOR`] of the points' mean, by that floor; a point is
//! found in the triangles of its own patch only.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;
use crate::reference::{ProbePoint, ProbeValue};

/// References below this fraction of the points' mean count as this much
/// in relative errors, so that nearly black points do not explode them.
pub const RELATIVE_FLOOR: f64 = 0.01;

/// Barycentric coordinates this far below zero still count as inside a
/// triangle (points on shared edges).
const INSIDE: f64 = 1e-6;

/// The header of a point-reference table.
pub const TABLE_HEADER: &str = "x,y,z,nx,ny,nz,patch,r,g,b,se_r,se_g,se_b";

/// Reads probe points from CSV: a header naming at least `x,y,z,nx,ny,nz`
/// (any order, more columns ignored), then one point per line.
pub fn read_points(path: &Path) -> Result<Vec<ProbePoint>> {
    let rows = read_rows(path, &["x", "y", "z", "nx", "ny", "nz"])?;
    Ok(rows
        .iter()
        .map(|v| ProbePoint {
            position: DVec3::new(v[0], v[1], v[2]),
            normal: DVec3::new(v[3], v[4], v[5]),
        })
        .collect())
}

/// Reads a point-reference table written by [`encode_table`].
pub fn read_table(path: &Path) -> Result<Vec<ProbeValue>> {
    let names: Vec<&str> = TABLE_HEADER.split(',').collect();
    let rows = read_rows(path, &names)?;
    rows.iter()
        .enumerate()
        .map(|(k, v)| {
            if !(v[6] >= 0.0 && v[6] < f64::from(u32::MAX) && v[6].fract() == 0.0) {
                return Err(Error::data(
                    path,
                    format!("row {}: bad patch {}", k + 2, v[6]),
                ));
            }
            Ok(ProbeValue {
                point: ProbePoint {
                    position: DVec3::new(v[0], v[1], v[2]),
                    normal: DVec3::new(v[3], v[4], v[5]),
                },
                patch: v[6] as u32,
                radiosity: DVec3::new(v[7], v[8], v[9]),
                standard_error: DVec3::new(v[10], v[11], v[12]),
            })
        })
        .collect()
}

/// The CSV rows of `path`, the columns `names` in that order, every value
/// finite.
fn read_rows(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, e))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| Error::data(path, "empty file: a header line is needed"))?
        .split(',')
        .map(str::trim)
        .collect();
    let columns: Vec<usize> = names
        .iter()
        .map(|n| {
            header
                .iter()
                .position(|h| h == n)
                .ok_or_else(|| Error::data(path, format!("no column '{n}' in the header")))
        })
        .collect::<Result<_>>()?;
    lines
        .enumerate()
        .map(|(k, line)| {
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            columns
                .iter()
                .map(|&c| {
                    fields
                        .get(c)
                        .and_then(|f| f.parse::<f64>().ok())
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| {
                            Error::data(
                                path,
                                format!("row {}: column {} is not a number", k + 2, header[c]),
                            )
                        })
                })
                .collect()
        })
        .collect()
}

/// The CSV of a point-reference table ([`TABLE_HEADER`]).
pub fn encode_table(values: &[ProbeValue]) -> Vec<u8> {
    let mut out = format!("{TABLE_HEADER}\n");
    for v in values {
        let (p, n) = (v.point.position, v.point.normal);
        let (b, e) = (v.radiosity, v.standard_error);
        out.push_str(&format!(
            "{},{},{},{},{},{},{},{:.9e},{:.9e},{:.9e},{:.3e},{:.3e},{:.3e}\n",
            p.x, p.y, p.z, n.x, n.y, n.z, v.patch, b.x, b.y, b.z, e.x, e.y, e.z
        ));
    }
    out.into_bytes()
}

/// One point's comparison.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PointError {
    /// The solution's value there (mean of the channels).
    pub test: f64,
    /// The reference's (mean of the channels).
    pub reference: f64,
    /// The reference's standard error (mean of the channels).
    pub standard_error: f64,
    /// (test − reference) / max(reference, floor).
    pub relative: f64,
    /// Whether the point fell inside a triangle of its patch (else the
    /// nearest one was used).
    pub inside: bool,
}

/// Errors over a point table.
#[derive(Clone, Debug, PartialEq, Serialize, schemars::JsonSchema)]
pub struct PointScore {
    /// Points compared.
    pub points: usize,
    /// Median of |relative error|.
    pub median: f64,
    /// 90th percentile of |relative error|.
    pub p90: f64,
    /// Largest |relative error|, and the point (row of the table, from 0).
    pub worst: f64,
    /// See `worst`.
    pub worst_point: usize,
    /// Mean signed relative error: the bias.
    pub mean_bias: f64,
    /// Σ test / Σ reference − 1: the bias in the power the points carry.
    pub power_bias: f64,
    /// Median of the references' relative standard errors: the floor
    /// below which the errors above say nothing.
    pub reference_noise: f64,
    /// Points that fell outside every triangle of their patch (by more than
    /// a hair; the nearest triangle was used).
    pub outside: usize,
}

/// Scores `mesh` (a solution's output mesh) against `table`.
pub fn score(mesh: &OutputMesh, table: &[ProbeValue]) -> Result<(PointScore, Vec<PointError>)> {
    if table.is_empty() {
        return Err(Error::Setting("no points to score".into()));
    }
    let mut by_patch: HashMap<u32, Vec<usize>> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&p) = mesh.patch.get(tri[0] as usize) {
            by_patch.entry(p).or_default().push(t);
        }
    }
    let mean = |v: DVec3| v.element_sum() / 3.0;
    let level = table.iter().map(|v| mean(v.radiosity)).sum::<f64>() / table.len() as f64;
    let floor = RELATIVE_FLOOR * level.abs();
    let errors: Vec<PointError> = table
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let tris = by_patch.get(&v.patch).ok_or_else(|| {
                Error::Setting(format!(
                    "point {k}: the solution has no triangle on patch {} (another scene?)",
                    v.patch
                ))
            })?;
            let (value, inside) = interpolate(mesh, tris, v.point.position);
            let (test, reference) = (mean(value), mean(v.radiosity));
            Ok(PointError {
                test,
                reference,
                standard_error: mean(v.standard_error),
                relative: (test - reference) / reference.abs().max(floor),
                inside,
            })
        })
        .collect::<Result<_>>()?;
    let mut abs: Vec<f64> = errors.iter().map(|e| e.relative.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let quantile = |q: f64| abs[((q * (abs.len() - 1) as f64).round() as usize).min(abs.len() - 1)];
    let (worst_point, worst) = errors
        .iter()
        .map(|e| e.relative.abs())
        .enumerate()
        .fold((0, 0.0), |a, (k, e)| if e > a.1 { (k, e) } else { a });
    let mut noise: Vec<f64> = errors
        .iter()
        .map(|e| e.standard_error / e.reference.abs().max(floor))
        .collect();
    noise.sort_by(f64::total_cmp);
    let sum_t: f64 = errors.iter().map(|e| e.test).sum();
    let sum_r: f64 = errors.iter().map(|e| e.reference).sum();
    let score = PointScore {
        points: errors.len(),
        median: quantile(0.5),
        p90: quantile(0.9),
        worst,
        worst_point,
        mean_bias: errors.iter().map(|e| e.relative).sum::<f64>() / errors.len() as f64,
        power_bias: if sum_r > 0.0 {
            sum_t / sum_r - 1.0
        } else {
            0.0
        },
        reference_noise: noise[noise.len() / 2],
        outside: errors.iter().filter(|e| !e.inside).count(),
    };
    Ok((score, errors))
}

/// The mesh's radiosity at `x`, interpolated in the triangle of `tris`
/// that holds it best (the largest smallest barycentric coordinate), and
/// whether it lies inside that one.
fn interpolate(mesh: &OutputMesh, tris: &[usize], x: DVec3) -> (DVec3, bool) {
    let at = |i: u32| mesh.positions[i as usize].as_dvec3();
    let mut best = (f64::NEG_INFINITY, DVec3::ZERO);
    for &t in tris {
        let [i, j, k] = mesh.triangles[t];
        let (a, b, c) = (at(i), at(j), at(k));
        let n = (b - a).cross(c - a);
        let area2 = n.length_squared();
        if !(area2 > 0.0) {
            continue;
        }
        let w = [
            (c - b).cross(x - b).dot(n) / area2,
            (a - c).cross(x - c).dot(n) / area2,
            (b - a).cross(x - a).dot(n) / area2,
        ];
        let least = w[0].min(w[1]).min(w[2]);
        if least > best.0 {
            let value = [i, j, k]
                .iter()
                .zip(w)
                .map(|(&v, w)| w.clamp(0.0, 1.0) * mesh.radiosity[v as usize].as_dvec3())
                .sum::<DVec3>()
                / w.iter().map(|w| w.clamp(0.0, 1.0)).sum::<f64>().max(1e-300);
            best = (least, value);
        }
    }
    (best.1, best.0 >= -INSIDE)
}
