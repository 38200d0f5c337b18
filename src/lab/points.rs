//! Point tables and scoring a solution against them: the bias of a
//! solution at surface points, against path-traced references
//! (`nusselt probe`), which pixel noise and image averages do not hide.
//!
//! Owns: the CSV of probe points (`x,y,z,nx,ny,nz`, more columns
//! ignored), the CSV of point references (the same, then `patch`, the
//! radiosity `r,g,b` and its standard error `se_r,se_g,se_b`), read and
//! written through [`crate::output::csv`]; [`score`]: each point's value
//! interpolated in the solution's output mesh, its relative error, and the
//! median, 90th percentile, worst error and mean bias over the points; and
//! the CSV of those errors, one row per point ([`encode_errors`]).
//!
//! Invariants: the scalar compared is the mean of the three channels; a
//! relative error divides by the reference's value or, when that is
//! below [`RELATIVE_FLOOR`] of the points' mean, by that floor; a point is
//! found in the triangles of its own patch only.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;
use crate::output::csv;
use crate::reference::{ProbePoint, ProbeValue};

/// References below this fraction of the points' mean count as this much
/// in relative errors, so that nearly black points do not explode them.
pub const RELATIVE_FLOOR: f64 = 0.01;

/// Barycentric coordinates this far below zero still count as inside a
/// triangle (points on shared edges).
const INSIDE: f64 = 1e-6;

/// The header of a point-reference table.
pub const TABLE_HEADER: &str = "x,y,z,nx,ny,nz,patch,r,g,b,se_r,se_g,se_b";

/// The columns a points file must have.
const POINT_COLUMNS: [&str; 6] = ["x", "y", "z", "nx", "ny", "nz"];

/// A row of a points file.
#[derive(Deserialize)]
struct PointRow {
    x: f64,
    y: f64,
    z: f64,
    nx: f64,
    ny: f64,
    nz: f64,
}

/// A row of a point-reference table, fields in [`TABLE_HEADER`] order:
/// positions and normals as Rust prints them (the shortest text that reads
/// back exactly), radiosities to 10 significant digits, standard errors
/// to 4.
#[derive(Serialize, Deserialize)]
struct TableRow {
    #[serde(serialize_with = "csv::plain")]
    x: f64,
    #[serde(serialize_with = "csv::plain")]
    y: f64,
    #[serde(serialize_with = "csv::plain")]
    z: f64,
    #[serde(serialize_with = "csv::plain")]
    nx: f64,
    #[serde(serialize_with = "csv::plain")]
    ny: f64,
    #[serde(serialize_with = "csv::plain")]
    nz: f64,
    patch: u32,
    #[serde(serialize_with = "csv::sci::<9, _>")]
    r: f64,
    #[serde(serialize_with = "csv::sci::<9, _>")]
    g: f64,
    #[serde(serialize_with = "csv::sci::<9, _>")]
    b: f64,
    #[serde(serialize_with = "csv::sci::<3, _>")]
    se_r: f64,
    #[serde(serialize_with = "csv::sci::<3, _>")]
    se_g: f64,
    #[serde(serialize_with = "csv::sci::<3, _>")]
    se_b: f64,
}

/// Reads probe points from CSV: a header naming at least `x,y,z,nx,ny,nz`
/// (any order, more columns ignored), then one point per line.
pub fn read_points(path: &Path) -> Result<Vec<ProbePoint>> {
    csv::read(path, &POINT_COLUMNS, |r: PointRow| {
        finite(&[
            ("x", r.x),
            ("y", r.y),
            ("z", r.z),
            ("nx", r.nx),
            ("ny", r.ny),
            ("nz", r.nz),
        ])?;
        Ok(ProbePoint {
            position: DVec3::new(r.x, r.y, r.z),
            normal: DVec3::new(r.nx, r.ny, r.nz),
        })
    })
}

/// Reads a point-reference table written by [`encode_table`].
pub fn read_table(path: &Path) -> Result<Vec<ProbeValue>> {
    let columns: Vec<&str> = TABLE_HEADER.split(',').collect();
    csv::read(path, &columns, |r: TableRow| {
        finite(&[
            ("x", r.x),
            ("y", r.y),
            ("z", r.z),
            ("nx", r.nx),
            ("ny", r.ny),
            ("nz", r.nz),
            ("r", r.r),
            ("g", r.g),
            ("b", r.b),
            ("se_r", r.se_r),
            ("se_g", r.se_g),
            ("se_b", r.se_b),
        ])?;
        Ok(ProbeValue {
            point: ProbePoint {
                position: DVec3::new(r.x, r.y, r.z),
                normal: DVec3::new(r.nx, r.ny, r.nz),
            },
            patch: r.patch,
            radiosity: DVec3::new(r.r, r.g, r.b),
            standard_error: DVec3::new(r.se_r, r.se_g, r.se_b),
        })
    })
}

/// Refuses the first of the named `values` that is not finite.
fn finite(values: &[(&str, f64)]) -> std::result::Result<(), String> {
    match values.iter().find(|(_, v)| !v.is_finite()) {
        Some((name, v)) => Err(format!("column '{name}' ({v}) is not a finite number")),
        None => Ok(()),
    }
}

/// The CSV of a point-reference table ([`TABLE_HEADER`]).
pub fn encode_table(values: &[ProbeValue]) -> Result<Vec<u8>> {
    let header: Vec<&str> = TABLE_HEADER.split(',').collect();
    csv::encode(
        &header,
        values.iter().map(|v| {
            let (p, n) = (v.point.position, v.point.normal);
            let (b, e) = (v.radiosity, v.standard_error);
            TableRow {
                x: p.x,
                y: p.y,
                z: p.z,
                nx: n.x,
                ny: n.y,
                nz: n.z,
                patch: v.patch,
                r: b.x,
                g: b.y,
                b: b.z,
                se_r: e.x,
                se_g: e.y,
                se_b: e.z,
            }
        }),
    )
}

/// The CSV of a scoring's points (`compare -o`'s `points.csv`): per
/// point, its row in the table, test and reference to 10 significant
/// digits, the standard error to 4, the relative error to 6 decimals, and
/// whether it fell inside a triangle.
pub fn encode_errors(errors: &[PointError]) -> Result<Vec<u8>> {
    /// A row of `points.csv`.
    #[derive(Serialize)]
    struct ErrorRow {
        point: usize,
        #[serde(serialize_with = "csv::sci::<9, _>")]
        test: f64,
        #[serde(serialize_with = "csv::sci::<9, _>")]
        reference: f64,
        #[serde(serialize_with = "csv::sci::<3, _>")]
        standard_error: f64,
        #[serde(serialize_with = "csv::fixed::<6, _>")]
        relative: f64,
        inside: bool,
    }
    csv::encode(
        &[
            "point",
            "test",
            "reference",
            "standard_error",
            "relative",
            "inside",
        ],
        errors.iter().enumerate().map(|(k, e)| ErrorRow {
            point: k,
            test: e.test,
            reference: e.reference,
            standard_error: e.standard_error,
            relative: e.relative,
            inside: e.inside,
        }),
    )
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

#[cfg(test)]
mod tests {
    use super::*;

    fn file(dir: &Path, text: &str) -> std::path::PathBuf {
        let path = dir.join("points.csv");
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn a_table_keeps_its_text_and_reads_back() {
        let value = ProbeValue {
            point: ProbePoint {
                position: DVec3::new(1.7039420428411791, 0.034416583760763286, 0.0),
                normal: DVec3::Z,
            },
            patch: 4,
            radiosity: DVec3::new(0.9463865008, 0.8377670856, 0.6777142333),
            standard_error: DVec3::new(9.165e-4, 7.433e-4, 4.961e-4),
        };
        let bytes = encode_table(&[value]).unwrap();
        // A row of scenes/hard/corridor.points.csv, as written before the
        // `csv` crate wrote the tables.
        assert_eq!(
            String::from_utf8(bytes.clone()).unwrap(),
            format!(
                "{TABLE_HEADER}\n1.7039420428411791,0.034416583760763286,0,0,0,1,4,\
                 9.463865008e-1,8.377670856e-1,6.777142333e-1,9.165e-4,7.433e-4,4.961e-4\n"
            )
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("table.csv");
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(read_table(&path).unwrap(), vec![value]);
        // A table is a points file too.
        assert_eq!(read_points(&path).unwrap(), vec![value.point]);
    }

    #[test]
    fn points_are_read_by_column_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = file(
            dir.path(),
            "label,nz,ny,nx,z,y,x\n\"a, \"\"b\"\"\",1,0,0,3,2,1\n\nc,0,1,0,6,5,4\n",
        );
        let points = read_points(&path).unwrap();
        assert_eq!(points.len(), 2);
        assert_eq!(points[0].position, DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(points[0].normal, DVec3::Z);
        assert_eq!(points[1].position, DVec3::new(4.0, 5.0, 6.0));
    }

    #[test]
    fn a_malformed_points_file_is_an_error_naming_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let head = "x,y,z,nx,ny,nz\n0,0,0,0,0,1\n";
        for (text, needle) in [
            (
                format!("{head}1,2,three,0,0,1\n"),
                "line 3: column 'z' (\"three\"): invalid float",
            ),
            (
                format!("{head}\n1,2,3,0,0\n"),
                "line 4: 5 fields, the header has 6",
            ),
            (
                format!("{head}1,2,inf,0,0,1\n"),
                "line 3: column 'z' (inf) is not",
            ),
            ("x,y,z\n1,2,3\n".to_string(), "no column 'nx' in the header"),
        ] {
            let path = file(dir.path(), &text);
            let message = read_points(&path).unwrap_err().to_string();
            assert!(
                message.starts_with(&format!("{}: ", path.display())),
                "{message}"
            );
            assert!(message.contains(needle), "{needle:?} not in {message:?}");
            assert!(!message.contains('\n'), "{message}");
        }
        // A table's patch must be a whole number.
        let path = file(
            dir.path(),
            &format!("{TABLE_HEADER}\n0,0,0,0,0,1,2.5,1,1,1,0,0,0\n"),
        );
        let message = read_table(&path).unwrap_err().to_string();
        assert!(
            message.contains("line 2: column 'patch' (\"2.5\")"),
            "{message}"
        );
    }

    #[test]
    fn errors_of_a_scoring_keep_their_text() {
        let errors = [PointError {
            test: 0.5,
            reference: 0.25,
            standard_error: 0.001,
            relative: 1.0,
            inside: true,
        }];
        assert_eq!(
            String::from_utf8(encode_errors(&errors).unwrap()).unwrap(),
            "point,test,reference,standard_error,relative,inside\n\
             0,5.000000000e-1,2.500000000e-1,1.000e-3,1.000000,true\n"
        );
    }
}
