//! The output mesh: the triangles and per-vertex radiosity and irradiance
//! that every output (`solution.exr`, `baked.gltf`, renders) is made from.
//!
//! Invariants (checked by [`OutputMesh::validate`]):
//! - all per-vertex arrays have the same length;
//! - every triangle indexes existing vertices, is counter-clockwise seen from
//!   the front of its patch, and its three vertices belong to one patch;
//! - positions and normals are finite, normals unit length, radiosity and
//!   irradiance finite and non-negative;
//! - B = E + ρ H at every vertex, E and ρ those of its patch (the producers
//!   make both from one evaluation; not checked here, the scene is not).

use glam::Vec3;

/// Vertices and triangles with their radiosity, in world space (f32, as
/// written to files).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OutputMesh {
    /// Vertex positions (world space).
    pub positions: Vec<Vec3>,
    /// Unit normal of the patch the vertex belongs to.
    pub normals: Vec<Vec3>,
    /// Index of the input patch the vertex belongs to.
    pub patch: Vec<u32>,
    /// Radiosity B (exitance, W/m² per channel).
    pub radiosity: Vec<Vec3>,
    /// Irradiance H (the light arriving, W/m² per channel): what an engine
    /// multiplies with a surface's own albedo.
    pub irradiance: Vec<Vec3>,
    /// Vertex indices, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
}

impl OutputMesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// When the per-vertex arrays differ in length, a message giving each
    /// length.
    pub fn length_mismatch(&self) -> Option<String> {
        let n = self.positions.len();
        let lengths = [
            self.normals.len(),
            self.radiosity.len(),
            self.irradiance.len(),
            self.patch.len(),
        ];
        lengths.iter().any(|&l| l != n).then(|| {
            let [normals, radiosities, irradiances, patches] = lengths;
            format!(
                "per-vertex arrays differ in length ({n} positions, {normals} normals, \
                 {radiosities} radiosities, {irradiances} irradiances, {patches} patch indices)"
            )
        })
    }

    /// Checks the invariants of the module doc; the first violation is
    /// returned as a message.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(message) = self.length_mismatch() {
            return Err(message);
        }
        let n = self.positions.len();
        for k in 0..n {
            if !self.positions[k].is_finite() {
                return Err(format!("vertex {k}: non-finite position"));
            }
            if (self.normals[k].length() - 1.0).abs() > 1e-4 {
                return Err(format!("vertex {k}: normal is not unit length"));
            }
            let b = self.radiosity[k];
            if !b.is_finite() || b.min_element() < 0.0 {
                return Err(format!(
                    "vertex {k}: radiosity {b} is negative or non-finite"
                ));
            }
            let h = self.irradiance[k];
            if !h.is_finite() || h.min_element() < 0.0 {
                return Err(format!(
                    "vertex {k}: irradiance {h} is negative or non-finite"
                ));
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if tri.iter().any(|&i| i as usize >= n) {
                return Err(format!("triangle {t}: vertex index out of range"));
            }
            let [a, b, c] = tri.map(|i| i as usize);
            if self.patch[a] != self.patch[b] || self.patch[a] != self.patch[c] {
                return Err(format!("triangle {t}: vertices from different patches"));
            }
            let [pa, pb, pc] = [a, b, c].map(|i| self.positions[i].as_dvec3());
            let cross = (pb - pa).cross(pc - pa);
            if cross.dot(self.normals[a].as_dvec3()) <= 0.0 {
                return Err(format!(
                    "triangle {t}: degenerate or wound against its normal"
                ));
            }
        }
        Ok(())
    }
}
