//! Uniform meshing: every patch cut into a regular grid of elements no
//! larger than a requested size, and the output mesh built on that grid.
//!
//! Owns: [`UniformMesh`], the element list of the classic solvers, and the
//! count of its elements from the patch edges alone
//! ([`UniformMesh::element_count`]), which [`UniformMesh::within_budget`]
//! checks against a memory budget before anything is allocated.
//!
//! Invariants:
//! - [`UniformMesh::element_count`] is exactly the length of
//!   [`UniformMesh::elements`] for the same size (saturating at
//!   `u64::MAX`), computed without allocating.
//! - The elements of a patch tile it exactly (their areas sum to the
//!   patch's area) and keep its orientation.
//! - Cut counts depend only on patch edge lengths, so patches of the same
//!   shape and size meeting along a whole edge (the walls of a box) cut it at
//!   the same points and their output vertices coincide there. Elsewhere the
//!   grid can leave T-vertices between patches; it is the simplest mesh, kept
//!   for comparisons.
//!
//! Grid layout, in the patch parametrisation of [`crate::scene`]:
//!
//! ```text
//!  quad, n_u × n_v cells           triangle, n² cells
//!  (0,nv) ... (nu,nv)              (0,n)
//!    |  cell (i,j) |                 | \  "up" cell (i,j): (i,j) (i+1,j) (i,j+1)
//!  (0,0) ---- (nu,0)               (0,0) -- (n,0)   "down" cell: (i+1,j) (i+1,j+1) (i,j+1)
//! ```

use glam::{DVec3, Vec3};

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;
use crate::scene::{Patch, Scene, Shape, polygon_area_normal, polygon_centroid};

/// One element of a uniform mesh: a convex planar polygon on one patch.
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    /// The patch the element lies on.
    pub patch: u32,
    /// 3 or 4 corners, counter-clockwise seen from the front.
    pub corners: Vec<DVec3>,
    /// Area-weighted centroid.
    pub centroid: DVec3,
    /// Unit normal (the patch's).
    pub normal: DVec3,
    /// Area (m²).
    pub area: f64,
}

/// The grid of one patch: its vertex nodes and its cells.
#[derive(Clone, Debug, PartialEq)]
struct PatchGrid {
    /// World positions of the grid nodes.
    nodes: Vec<DVec3>,
    /// For each element of the patch, its corner node indices.
    cells: Vec<Vec<u32>>,
    /// Index of the patch's first element in [`UniformMesh::elements`].
    first_element: usize,
}

/// All patches of a scene cut into elements.
#[derive(Clone, Debug)]
pub struct UniformMesh {
    /// Every element, patch by patch.
    pub elements: Vec<Element>,
    /// The requested largest element edge, in metres.
    pub element_size: f64,
    grids: Vec<PatchGrid>,
}

/// Cuts needed so that pieces of an edge of length `len` are at most `h`.
fn cuts(len: f64, h: f64) -> usize {
    // Round lengths so that equal edges computed in different orders agree.
    let n = (len / h * (1.0 - 1e-9)).ceil();
    if n.is_finite() {
        n.clamp(1.0, 1e6) as usize
    } else {
        1
    }
}

/// Bytes a uniform mesh and the classic solve hold per element, besides
/// the matrix: the element with its corners on the heap (about 200), its
/// grid cell and node (about 70), and the eight per-element vectors of the
/// solve (reflectance, emission, area, light, source, radiosity,
/// irradiance, output sums; about 180); rounded up.
pub const ELEMENT_BYTES: u64 = 512;

/// `bytes` for messages: in MiB below 1 GiB, else in the largest of GiB,
/// TiB, PiB and EiB that keeps at least 1; a saturated count
/// (`u64::MAX`) reads "more than 16 EiB".
pub fn human_bytes(bytes: u64) -> String {
    if bytes == u64::MAX {
        return "more than 16 EiB".into();
    }
    let mib = bytes as f64 / (1u64 << 20) as f64;
    if mib < 1024.0 {
        return format!("{mib:.1} MiB");
    }
    let mut value = mib / 1024.0;
    for unit in ["GiB", "TiB", "PiB"] {
        if value < 1024.0 {
            return format!("{value:.2} {unit}");
        }
        value /= 1024.0;
    }
    format!("{value:.2} EiB")
}

/// `x` as written, or in scientific notation when that is shorter.
fn short_number(x: f64) -> String {
    let plain = x.to_string();
    let sci = format!("{x:e}");
    if sci.len() < plain.len() { sci } else { plain }
}

impl UniformMesh {
    /// How many elements [`Self::new`] makes for `element_size`, from the
    /// patch edges alone (saturating; nothing is allocated).
    pub fn element_count(scene: &Scene, element_size: f64) -> u64 {
        scene
            .patches
            .iter()
            .map(|patch| {
                let (a, b) = grid_cuts(patch, element_size);
                let (a, b) = (a as u64, b as u64);
                match patch.shape {
                    Shape::Quad => a.saturating_mul(b),
                    Shape::Triangle => a.saturating_mul(a),
                }
            })
            .fold(0u64, u64::saturating_add)
    }

    /// [`Self::new`], once the elements' memory ([`ELEMENT_BYTES`] each)
    /// plus `solver_bytes(elements)` (the matrix and whatever the solver
    /// adds, described by `solver`, as in "with their dense matrix") fits
    /// `memory_budget`; otherwise an error naming `--element-size`, the
    /// element count and the memory it would need.
    pub fn within_budget(
        scene: &Scene,
        element_size: f64,
        memory_budget: u64,
        solver: &str,
        solver_bytes: impl Fn(u64) -> u64,
    ) -> Result<UniformMesh> {
        let n = Self::element_count(scene, element_size);
        let need = n
            .saturating_mul(ELEMENT_BYTES)
            .saturating_add(solver_bytes(n));
        if need > memory_budget {
            return Err(Error::Setting(format!(
                "--element-size {} makes {n} elements, which need {} {solver}, \
                 over the memory budget of {} (use larger elements or raise --memory-budget)",
                short_number(element_size),
                human_bytes(need),
                human_bytes(memory_budget)
            )));
        }
        Ok(Self::new(scene, element_size))
    }

    /// Cuts every patch of `scene` into elements whose edges are at most
    /// `element_size` long (at least one element per patch).
    pub fn new(scene: &Scene, element_size: f64) -> UniformMesh {
        let mut elements = Vec::new();
        let mut grids = Vec::with_capacity(scene.patches.len());
        for (pi, patch) in scene.patches.iter().enumerate() {
            let grid = patch_grid(patch, element_size, elements.len());
            for cell in &grid.cells {
                let corners: Vec<DVec3> = cell.iter().map(|&k| grid.nodes[k as usize]).collect();
                let (area, normal) = polygon_area_normal(&corners);
                elements.push(Element {
                    patch: pi as u32,
                    centroid: polygon_centroid(&corners),
                    normal: if normal.dot(patch.normal) > 0.0 {
                        normal
                    } else {
                        patch.normal
                    },
                    area,
                    corners,
                });
            }
            grids.push(grid);
        }
        UniformMesh {
            elements,
            element_size,
            grids,
        }
    }

    /// Per element: the reflectance and emitted exitance of its patch, and
    /// its area — the vectors of the radiosity system on this mesh.
    pub fn element_values(&self, scene: &Scene) -> (Vec<DVec3>, Vec<DVec3>, Vec<f64>) {
        let patch = |e: &Element| &scene.patches[e.patch as usize];
        (
            self.elements.iter().map(|e| patch(e).reflectance).collect(),
            self.elements.iter().map(|e| patch(e).emission).collect(),
            self.elements.iter().map(|e| e.area).collect(),
        )
    }

    /// The output mesh, with each vertex's radiosity and irradiance the
    /// area-weighted means of those of the elements of its patch that touch
    /// it (`element_radiosity` and `element_irradiance` are indexed like
    /// [`Self::elements`]).
    pub fn output_mesh(
        &self,
        scene: &Scene,
        element_radiosity: &[DVec3],
        element_irradiance: &[DVec3],
    ) -> OutputMesh {
        let mut mesh = OutputMesh::default();
        for (pi, grid) in self.grids.iter().enumerate() {
            let base = mesh.positions.len() as u32;
            let normal = scene.patches[pi].normal.as_vec3();
            let mut sum = vec![DVec3::ZERO; grid.nodes.len()];
            let mut sum_h = vec![DVec3::ZERO; grid.nodes.len()];
            let mut weight = vec![0.0; grid.nodes.len()];
            for (c, cell) in grid.cells.iter().enumerate() {
                let e = &self.elements[grid.first_element + c];
                for &k in cell {
                    sum[k as usize] += e.area * element_radiosity[grid.first_element + c];
                    sum_h[k as usize] += e.area * element_irradiance[grid.first_element + c];
                    weight[k as usize] += e.area;
                }
                mesh.triangles
                    .push([base + cell[0], base + cell[1], base + cell[2]]);
                if cell.len() == 4 {
                    mesh.triangles
                        .push([base + cell[0], base + cell[2], base + cell[3]]);
                }
            }
            for (k, node) in grid.nodes.iter().enumerate() {
                mesh.positions.push(node.as_vec3());
                mesh.normals.push(normal);
                mesh.patch.push(pi as u32);
                let mean = |sum: DVec3| match weight[k] > 0.0 {
                    true => (sum / weight[k]).max(DVec3::ZERO).as_vec3(),
                    false => Vec3::ZERO,
                };
                mesh.radiosity.push(mean(sum[k]));
                mesh.irradiance.push(mean(sum_h[k]));
            }
        }
        drop_unused_vertices(mesh)
    }
}

/// Removes vertices no triangle uses (possible only for degenerate grids).
fn drop_unused_vertices(mut mesh: OutputMesh) -> OutputMesh {
    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    if used.iter().all(|&u| u) {
        return mesh;
    }
    let mut remap = vec![u32::MAX; used.len()];
    let mut out = OutputMesh::default();
    for (k, _) in used.iter().enumerate().filter(|(_, u)| **u) {
        remap[k] = out.positions.len() as u32;
        out.positions.push(mesh.positions[k]);
        out.normals.push(mesh.normals[k]);
        out.patch.push(mesh.patch[k]);
        out.radiosity.push(mesh.radiosity[k]);
        out.irradiance.push(mesh.irradiance[k]);
    }
    out.triangles = mesh
        .triangles
        .drain(..)
        .map(|t| t.map(|i| remap[i as usize]))
        .collect();
    out
}

/// The cuts of a patch's grid: (n_u, n_v) for a quad, (n, n) for a
/// triangle.
fn grid_cuts(patch: &Patch, h: f64) -> (usize, usize) {
    let [p0, p1, p2, p3] = patch.corners;
    match patch.shape {
        Shape::Quad => (
            cuts((p1 - p0).length().max((p2 - p3).length()), h),
            cuts((p3 - p0).length().max((p2 - p1).length()), h),
        ),
        Shape::Triangle => {
            let longest = (p1 - p0)
                .length()
                .max((p2 - p1).length())
                .max((p0 - p2).length());
            let n = cuts(longest, h);
            (n, n)
        }
    }
}

fn patch_grid(patch: &Patch, h: f64, first_element: usize) -> PatchGrid {
    let (nu, nv) = grid_cuts(patch, h);
    match patch.shape {
        Shape::Quad => {
            let mut nodes = Vec::with_capacity((nu + 1) * (nv + 1));
            for j in 0..=nv {
                for i in 0..=nu {
                    nodes.push(patch.point(i as f64 / nu as f64, j as f64 / nv as f64));
                }
            }
            let id = |i: usize, j: usize| (j * (nu + 1) + i) as u32;
            let mut cells = Vec::with_capacity(nu * nv);
            for j in 0..nv {
                for i in 0..nu {
                    cells.push(vec![id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
                }
            }
            PatchGrid {
                nodes,
                cells,
                first_element,
            }
        }
        Shape::Triangle => {
            let n = nu;
            debug_assert_eq!(nu, nv);
            let mut index = vec![vec![0u32; n + 1]; n + 1];
            let mut nodes = Vec::with_capacity((n + 1) * (n + 2) / 2);
            for j in 0..=n {
                for i in 0..=(n - j) {
                    index[i][j] = nodes.len() as u32;
                    nodes.push(patch.point(i as f64 / n as f64, j as f64 / n as f64));
                }
            }
            let mut cells = Vec::with_capacity(n * n);
            for j in 0..n {
                for i in 0..(n - j) {
                    cells.push(vec![index[i][j], index[i + 1][j], index[i][j + 1]]);
                    if i + j + 2 <= n {
                        cells.push(vec![index[i + 1][j], index[i + 1][j + 1], index[i][j + 1]]);
                    }
                }
            }
            PatchGrid {
                nodes,
                cells,
                first_element,
            }
        }
    }
}

/// Converts a vertex list to f32 for files and BVHs.
pub fn to_f32(points: &[DVec3]) -> Vec<Vec3> {
    points.iter().map(|p| p.as_vec3()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{InputTriangle, Material, Surface};

    #[test]
    fn human_bytes_picks_a_readable_unit() {
        assert_eq!(human_bytes(3 << 20), "3.0 MiB");
        assert_eq!(human_bytes(3 << 30), "3.00 GiB");
        assert_eq!(human_bytes(1536 << 30), "1.50 TiB");
        assert_eq!(human_bytes(5 << 50), "5.00 PiB");
        assert_eq!(human_bytes(3 << 60), "3.00 EiB");
        assert_eq!(human_bytes(u64::MAX), "more than 16 EiB");
    }

    fn scene(tris: Vec<[[f64; 3]; 3]>) -> Scene {
        let input = tris
            .into_iter()
            .map(|p| InputTriangle {
                positions: p.map(DVec3::from_array),
                material: 0,
                surface: 0,
                reflectance: DVec3::splat(0.5),
                emitted_radiance: DVec3::ONE,
                origin: Default::default(),
            })
            .collect();
        let m = Material {
            name: "m".into(),
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::ONE,
            double_sided: false,
        };
        let s = Surface {
            name: "s".into(),
            node: 0,
        };
        Scene::build(input, vec![m], vec![s], vec![], vec![]).unwrap()
    }

    #[test]
    fn elements_tile_quads_and_triangles() {
        let s = scene(vec![
            [[0., 0., 0.], [2., 0., 0.], [2., 1., 0.]],
            [[0., 0., 0.], [2., 1., 0.], [0., 1., 0.]],
            [[0., 0., 1.], [1., 0., 1.], [0., 1., 1.]],
        ]);
        let m = UniformMesh::new(&s, 0.3);
        for (pi, p) in s.patches.iter().enumerate() {
            let area: f64 = m
                .elements
                .iter()
                .filter(|e| e.patch == pi as u32)
                .map(|e| e.area)
                .sum();
            assert!(
                (area - p.area).abs() < 1e-12 * p.area.max(1.0),
                "patch {pi}"
            );
        }
        for e in &m.elements {
            for w in e.corners.windows(2) {
                assert!((w[1] - w[0]).length() <= 0.3 * 1.5);
            }
        }
        // 2 × 1 quad at h = 0.3: 7 × 4 cells; the unit right triangle is cut
        // by its hypotenuse, √2 / 0.3 → 5 cuts, 5² cells.
        assert_eq!(m.elements.len(), 28 + 25);
        assert_eq!(UniformMesh::element_count(&s, 0.3), 28 + 25);
        // Far below the smallest size: every edge at its 10⁶ cuts, counted
        // (not built) and refused by the budget with the flag named.
        assert_eq!(
            UniformMesh::element_count(&s, 1e-300),
            2 * 1_000_000_000_000
        );
        let e = UniformMesh::within_budget(&s, 1e-300, 2 << 30, "", |n| n.saturating_mul(n))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--element-size") && e.contains("2000000000000 elements"),
            "{e}"
        );
        assert!(e.contains("more than 16 EiB"), "{e}");
        let b: Vec<DVec3> = m
            .elements
            .iter()
            .map(|e| DVec3::splat(e.centroid.x))
            .collect();
        let h: Vec<DVec3> = b.iter().map(|b| 2.0 * b).collect();
        let out = m.output_mesh(&s, &b, &h);
        out.validate().unwrap();
        for (b, h) in out.radiosity.iter().zip(&out.irradiance) {
            assert!(
                (2.0 * b - h).length() < 1e-5 * h.length().max(1.0),
                "{b} {h}"
            );
        }
        assert_eq!(out.triangles.len(), 2 * 28 + 25);
    }
}
