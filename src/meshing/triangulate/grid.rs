//! Uniform hash grids for the triangulator's neighbour queries: [`Grid3`]
//! over world space (the global weld, points on patch edges, the
//! validator's twin search) and [`Grid2`] over one patch's frame (its
//! vertex set).
//!
//! Invariant: a query returns every id inserted into a cell the query box
//! overlaps (a superset of the true neighbours: callers test the distance
//! themselves); [`Grid3::query`] and [`Grid2::query_segment`] return them
//! sorted and without duplicates, so results never depend on hash order.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

/// The smallest cell of [`edge_grid`], relative to the scene diagonal.
const MIN_EDGE_CELL: f64 = 1e-3;

/// A uniform 3D grid of ids by cell.
pub(super) struct Grid3 {
    cell: f64,
    map: HashMap<[i64; 3], Vec<u32>>,
}

impl Grid3 {
    /// An empty grid of cubic cells of side `cell`.
    pub(super) fn new(cell: f64) -> Grid3 {
        Grid3 {
            cell,
            map: HashMap::new(),
        }
    }
    fn cell_of(&self, p: DVec3) -> [i64; 3] {
        (p / self.cell).floor().to_array().map(|x| x as i64)
    }
    fn cells(&self, lo: DVec3, hi: DVec3) -> impl Iterator<Item = [i64; 3]> + use<> {
        let (a, b) = (self.cell_of(lo), self.cell_of(hi));
        (a[0]..=b[0]).flat_map(move |x| {
            (a[1]..=b[1]).flat_map(move |y| (a[2]..=b[2]).map(move |z| [x, y, z]))
        })
    }
    /// Puts `id` in every cell the box lo–hi overlaps.
    pub(super) fn insert_box(&mut self, lo: DVec3, hi: DVec3, id: u32) {
        for c in self.cells(lo, hi).collect::<Vec<_>>() {
            self.map.entry(c).or_default().push(id);
        }
    }
    /// Inserts a segment as a chain of boxes no longer than a cell.
    pub(super) fn insert_segment(&mut self, a: DVec3, b: DVec3, id: u32) {
        let pieces = ((b - a).length() / self.cell).ceil().clamp(1.0, 1e6) as usize;
        for i in 0..pieces {
            let p = a.lerp(b, i as f64 / pieces as f64);
            let q = if i + 1 == pieces {
                b
            } else {
                a.lerp(b, (i + 1) as f64 / pieces as f64)
            };
            self.insert_box(p.min(q), p.max(q), id);
        }
    }
    /// Ids in the cells overlapping the box around p of half-size r,
    /// deduplicated and sorted.
    pub(super) fn query(&self, p: DVec3, r: f64, out: &mut Vec<u32>) {
        out.clear();
        for c in self.cells(p - DVec3::splat(r), p + DVec3::splat(r)) {
            if let Some(ids) = self.map.get(&c) {
                out.extend_from_slice(ids);
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}

/// A patch edge: (patch, edge index, start corner, end corner).
pub(super) type EdgeRef = (u32, usize, DVec3, DVec3);

/// A grid over all `edges`, each inserted under its index; the cell is the
/// median edge length, kept between [`MIN_EDGE_CELL`] times `diagonal` and
/// `diagonal`.
pub(super) fn edge_grid(edges: &[EdgeRef], diagonal: f64) -> Grid3 {
    let mut lengths: Vec<f64> = edges.iter().map(|e| (e.3 - e.2).length()).collect();
    lengths.sort_by(f64::total_cmp);
    let median = lengths.get(lengths.len() / 2).copied().unwrap_or(diagonal);
    let cell = median.clamp(diagonal * MIN_EDGE_CELL, diagonal.max(f64::MIN_POSITIVE));
    let mut grid = Grid3::new(cell);
    for (i, e) in edges.iter().enumerate() {
        grid.insert_segment(e.2, e.3, i as u32);
    }
    grid
}

/// A 2D grid of vertex ids.
pub(super) struct Grid2 {
    cell: f64,
    map: HashMap<[i64; 2], Vec<u32>>,
}

impl Grid2 {
    /// An empty grid of square cells of side `cell`.
    pub(super) fn new(cell: f64) -> Grid2 {
        Grid2 {
            cell,
            map: HashMap::new(),
        }
    }
    fn cell_of(&self, p: DVec2) -> [i64; 2] {
        (p / self.cell).floor().to_array().map(|x| x as i64)
    }
    /// Puts `id` in the cell of `p`.
    pub(super) fn insert(&mut self, p: DVec2, id: u32) {
        let c = self.cell_of(p);
        self.map.entry(c).or_default().push(id);
    }
    /// Appends the ids in the cells overlapping the box lo–hi to `out`
    /// (unsorted, possibly repeated).
    pub(super) fn query_box(&self, lo: DVec2, hi: DVec2, out: &mut Vec<u32>) {
        let (a, b) = (self.cell_of(lo), self.cell_of(hi));
        for x in a[0]..=b[0] {
            for y in a[1]..=b[1] {
                if let Some(ids) = self.map.get(&[x, y]) {
                    out.extend_from_slice(ids);
                }
            }
        }
    }
    /// Ids near segment a–b (within r), sorted and deduplicated.
    pub(super) fn query_segment(&self, a: DVec2, b: DVec2, r: f64, out: &mut Vec<u32>) {
        out.clear();
        let pieces = ((b - a).length() / self.cell).ceil().clamp(1.0, 1e6) as usize;
        for i in 0..pieces {
            let p = a.lerp(b, i as f64 / pieces as f64);
            let q = a.lerp(b, (i + 1) as f64 / pieces as f64);
            let rr = DVec2::splat(r);
            self.query_box(p.min(q) - rr, p.max(q) + rr, out);
        }
        out.sort_unstable();
        out.dedup();
    }
}
