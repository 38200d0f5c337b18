//! A rectilinear cell lattice for building room shells.
//!
//! The lattice cuts space by sorted lines along x, y and z; every cell is
//! either solid or open and then tagged with a region (a room, a doorway).
//! [`Lattice::boundary`] emits one quad for every face between an open cell
//! and a solid cell (or the outside), facing into the open cell.
//!
//! Invariants, by construction: the shell is closed around the open space;
//! all quads lie on one lattice, so neighbouring faces share their vertices
//! (no T-junctions, no cracks, no overlapping coplanar faces); every quad's
//! front faces the open space.

use glam::DVec3;

use super::shapes::{Side, Tri, box_face, quad};

/// A face of the boundary between open and solid space.
pub struct BoundaryFace {
    /// Region tag of the open cell the face looks into.
    pub region: usize,
    /// Direction the face looks into (its front normal).
    pub facing: Side,
    /// Bounds of the open cell behind the face.
    pub cell_min: DVec3,
    pub cell_max: DVec3,
    pub triangles: [Tri; 2],
}

pub struct Lattice {
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
    cells: Vec<Option<usize>>,
}

impl Lattice {
    /// An all-solid lattice on the given (strictly increasing) lines.
    pub fn new(xs: Vec<f64>, ys: Vec<f64>, zs: Vec<f64>) -> Lattice {
        for lines in [&xs, &ys, &zs] {
            assert!(
                lines.windows(2).all(|w| w[0] < w[1]),
                "lattice lines must increase"
            );
        }
        let n = (xs.len() - 1) * (ys.len() - 1) * (zs.len() - 1);
        Lattice {
            xs,
            ys,
            zs,
            cells: vec![None; n],
        }
    }

    fn dims(&self) -> [usize; 3] {
        [self.xs.len() - 1, self.ys.len() - 1, self.zs.len() - 1]
    }

    fn idx(&self, i: usize, j: usize, k: usize) -> usize {
        let [nx, ny, _] = self.dims();
        i + nx * (j + ny * k)
    }

    fn bounds(&self, i: usize, j: usize, k: usize) -> (DVec3, DVec3) {
        (
            DVec3::new(self.xs[i], self.ys[j], self.zs[k]),
            DVec3::new(self.xs[i + 1], self.ys[j + 1], self.zs[k + 1]),
        )
    }

    /// Opens every cell whose centre lies inside the box and tags it.
    pub fn open(&mut self, min: DVec3, max: DVec3, region: usize) {
        // Cell centres increase along each axis, so the cells inside form
        // one index range per axis.
        let [xr, yr, zr] = [
            (&self.xs, min.x, max.x),
            (&self.ys, min.y, max.y),
            (&self.zs, min.z, max.z),
        ]
        .map(|(lines, lo, hi)| centres_within(lines, lo, hi));
        for k in zr {
            for j in yr.clone() {
                for i in xr.clone() {
                    let id = self.idx(i, j, k);
                    self.cells[id] = Some(region);
                }
            }
        }
    }

    fn region(&self, i: isize, j: isize, k: isize) -> Option<usize> {
        let [nx, ny, nz] = self.dims();
        if i < 0 || j < 0 || k < 0 || i >= nx as isize || j >= ny as isize || k >= nz as isize {
            return None;
        }
        self.cells[self.idx(i as usize, j as usize, k as usize)]
    }

    /// Every face between an open and a solid cell, in a fixed order (cells
    /// x-fastest, then the six sides in [`Side::ALL`] order).
    pub fn boundary(&self) -> Vec<BoundaryFace> {
        let [nx, ny, nz] = self.dims();
        let mut faces = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let Some(region) = self.cells[self.idx(i, j, k)] else {
                        continue;
                    };
                    let (lo, hi) = self.bounds(i, j, k);
                    for side in Side::ALL {
                        let n = side.normal();
                        let (di, dj, dk) = (n.x as isize, n.y as isize, n.z as isize);
                        if self
                            .region(i as isize + di, j as isize + dj, k as isize + dk)
                            .is_some()
                        {
                            continue;
                        }
                        // The cell's outward face, wound the other way round
                        // so that it looks back into the cell.
                        let (o, u, v) = box_face(lo, hi, side);
                        faces.push(BoundaryFace {
                            region,
                            facing: side.opposite(),
                            cell_min: lo,
                            cell_max: hi,
                            triangles: quad(o, o + v, o + u + v, o + u),
                        });
                    }
                }
            }
        }
        faces
    }
}

/// The cells between consecutive `lines` whose centres lie strictly
/// between `lo` and `hi`.
fn centres_within(lines: &[f64], lo: f64, hi: f64) -> std::ops::Range<usize> {
    let centres: Vec<f64> = lines.windows(2).map(|w| (w[0] + w[1]) * 0.5).collect();
    let start = centres.partition_point(|&c| c <= lo);
    let end = centres.partition_point(|&c| c < hi);
    start..end.max(start)
}

/// Evenly spaced lines from `start` to `end` inclusive, about `step` apart.
pub fn lines(start: f64, end: f64, step: f64) -> Vec<f64> {
    let n = ((end - start) / step).round() as usize;
    (0..=n)
        .map(|i| start + (end - start) * i as f64 / n as f64)
        .collect()
}
