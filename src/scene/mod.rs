//! The scene model: materials, input triangles, patches and cameras, in world
//! space, independent of any file format.
//!
//! Owns: turning loaded triangles into radiosity patches. Degenerate triangles
//! are dropped (counted in [`SceneStats`]), pairs of adjacent coplanar
//! triangles of one surface and material that form a convex quad are merged
//! into quad patches, and double-sided triangles get a second, back-facing
//! patch.
//!
//! Invariants:
//! - Every patch is planar and one-sided: it reflects and emits only on the
//!   side its `normal` points to; its corners run counter-clockwise seen from
//!   that side.
//! - `Scene::triangles` holds every kept input triangle exactly once: the
//!   occluders for visibility. A double-sided triangle blocks light once but
//!   owns two patches.
//! - Patch parametrisation (used by every subdivision):
//!
//! ```text
//!   quad                         triangle
//!   p3 ----------- p2            p2
//!    |  v           |             | \
//!    |  ^           |             |   \
//!    |  +--> u      |             | v   \
//!   p0 ----------- p1            p0 --u-- p1
//!   P(u,v) bilinear, u,v in [0,1]     P(u,v) = p0 + u(p1-p0) + v(p2-p0), u+v <= 1
//! ```
//! - A scene always has at least one patch, and some light: an emitting
//!   patch, a punctual light or a sky.
//! - Every vertex coordinate is finite and at most [`MAX_COORDINATE`] in
//!   magnitude.

mod build;
mod lights;
mod polygon;
mod quads;
mod source;

pub use lights::{
    EnvironmentMap, Incident, LightKind, Lights, PunctualLight, Sky, cone_falloff, range_window,
};
pub use polygon::{polygon_area_normal, polygon_centroid};
pub use source::{SourceDocument, TriangleOrigin, interpolate_on_patch};

use std::sync::Arc;

use glam::DVec3;

/// A diffuse material as the contract maps it from glTF.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The glTF material name, or `material<index>` (or `default`).
    pub name: String,
    /// Reflectance factor ρ per channel, already clamped below 1.
    pub reflectance: DVec3,
    /// Emitted radiance factor L_e per channel (emissive factor × strength).
    pub emitted_radiance: DVec3,
    /// Both sides are radiosity surfaces.
    pub double_sided: bool,
}

/// One glTF node's mesh instance: the unit `nusselt formfactors` reports on.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    /// Node name, else mesh name, else `node<index>`.
    pub name: String,
    /// Index of the glTF node.
    pub node: usize,
}

/// A triangle as the loader delivers it: world space, counter-clockwise seen
/// from the front, with its material values already averaged over the
/// triangle (texture means included).
#[derive(Clone, Debug, PartialEq)]
pub struct InputTriangle {
    /// Corners, counter-clockwise seen from the front.
    pub positions: [DVec3; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Index into [`Scene::surfaces`].
    pub surface: u32,
    /// ρ over this triangle, in [0, 1) per channel.
    pub reflectance: DVec3,
    /// L_e over this triangle (radiance, W / (m² sr) per channel).
    pub emitted_radiance: DVec3,
    /// Its primitive and texture coordinates in the input file.
    pub origin: TriangleOrigin,
}

/// Which side of its input triangle(s) a patch represents.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// The side the input triangle faces.
    Front,
    /// The other side of a double-sided triangle.
    Back,
}

/// The two patch shapes: quads (from merged triangle pairs) and triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// One input triangle.
    Triangle,
    /// Two coplanar input triangles merged.
    Quad,
}

/// A kept input triangle: an occluder, and the patches it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneTriangle {
    /// Corners, counter-clockwise seen from the front.
    pub positions: [DVec3; 3],
    /// Index into `Scene::materials`.
    pub material: u32,
    /// Index into `Scene::surfaces`.
    pub surface: u32,
    /// The front patch containing this triangle.
    pub front_patch: u32,
    /// The back patch, for double-sided materials.
    pub back_patch: Option<u32>,
    /// Its primitive and texture coordinates in the input file.
    pub origin: TriangleOrigin,
}

/// A planar, one-sided radiosity surface: a triangle or a convex quad.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// Corners counter-clockwise seen from the front; for a triangle the
    /// fourth corner repeats the third and is never used.
    pub corners: [DVec3; 4],
    /// Triangle or quad.
    pub shape: Shape,
    /// Unit normal of the radiating side.
    pub normal: DVec3,
    /// Area (m²).
    pub area: f64,
    /// Index into `Scene::materials`.
    pub material: u32,
    /// Index into `Scene::surfaces`.
    pub surface: u32,
    /// Which side of its triangles it is.
    pub side: Side,
    /// ρ, area-weighted over the patch's triangles.
    pub reflectance: DVec3,
    /// Emitted exitance E = π L_e, area-weighted over the patch's triangles.
    pub emission: DVec3,
    /// Indices into [`Scene::triangles`]; the second is `u32::MAX` for a
    /// triangle patch.
    pub triangles: [u32; 2],
}

impl Patch {
    /// The 3 or 4 corners, counter-clockwise.
    pub fn vertices(&self) -> &[DVec3] {
        match self.shape {
            Shape::Triangle => &self.corners[..3],
            Shape::Quad => &self.corners[..4],
        }
    }

    /// The point at parameters (u, v); see the module doc for the layout.
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let [p0, p1, p2, p3] = self.corners;
        match self.shape {
            Shape::Triangle => p0 + u * (p1 - p0) + v * (p2 - p0),
            Shape::Quad => {
                (1.0 - u) * (1.0 - v) * p0 + u * (1.0 - v) * p1 + u * v * p2 + (1.0 - u) * v * p3
            }
        }
    }

    /// Area-weighted centroid.
    pub fn centroid(&self) -> DVec3 {
        polygon_centroid(self.vertices())
    }

    /// True when the patch emits on any channel.
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// A perspective camera from the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// The camera node's name.
    pub name: String,
    /// Position (world space).
    pub eye: DVec3,
    /// Unit viewing direction.
    pub forward: DVec3,
    /// Unit up direction, orthogonal to `forward`.
    pub up: DVec3,
    /// Vertical field of view in radians.
    pub yfov: f64,
    /// Width / height, when the file fixes it.
    pub aspect_ratio: Option<f64>,
}

/// Counts gathered while building the scene.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SceneStats {
    /// Triangles delivered by the loader.
    pub input_triangles: usize,
    /// Zero-area or near-degenerate triangles dropped.
    pub degenerate_dropped: usize,
    /// Triangle pairs merged into quad patches.
    pub merged_quads: usize,
    /// Back patches added for double-sided materials.
    pub back_patches: usize,
}

/// A loaded scene, ready for the solvers.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Every material, by index.
    pub materials: Vec<Material>,
    /// Every surface (glTF node with a mesh), by index.
    pub surfaces: Vec<Surface>,
    /// The kept input triangles: the occluders.
    pub triangles: Vec<SceneTriangle>,
    /// The radiosity patches.
    pub patches: Vec<Patch>,
    /// The scene's cameras, in node order.
    pub cameras: Vec<Camera>,
    /// Axis-aligned bounds of all kept triangles.
    pub bounds: (DVec3, DVec3),
    /// What building did.
    pub stats: SceneStats,
    /// Non-fatal findings (dropped triangles, clamped reflectances, ignored
    /// material features), one line each.
    pub warnings: Vec<String>,
    /// The input document's structure, for the bake; `None` for a scene
    /// not loaded from glTF.
    pub source: Option<Arc<SourceDocument>>,
    /// The lights that are not surfaces: punctual lights and the sky.
    pub lights: Lights,
}

/// Most triangles a scene may hold (after instancing; the loader stops
/// there); about 4 GB of input triangles, far beyond what the solvers can
/// handle.
pub const MAX_TRIANGLES: usize = 1 << 25;

/// Largest accepted magnitude of a world-space vertex coordinate, in metres.
///
/// Visibility runs in f32 (the BVH and its rays): extents, surface areas
/// (squared extents) and area sums over up to [`MAX_TRIANGLES`]
/// primitives must stay finite there, and coordinates near `f32::MAX` make
/// the BVH builder panic. With |x| ≤ 10¹² m a box is at most 2·10¹² m wide,
/// a surface area 3·(2·10¹²)² ≈ 1.2·10²⁵ m², and 2²⁵ of those sum to about
/// 4·10³² — six orders of magnitude below `f32::MAX` (3.4·10³⁸). Real
/// scenes (a planet is 10⁷ m across) are far inside the bound.
pub const MAX_COORDINATE: f64 = 1e12;

impl Scene {
    /// Length of the bounding-box diagonal: the scene's length scale.
    pub fn diagonal(&self) -> f64 {
        (self.bounds.1 - self.bounds.0).length()
    }

    /// Centre of the bounding box.
    pub fn center(&self) -> DVec3 {
        0.5 * (self.bounds.0 + self.bounds.1)
    }

    /// Total area of all patches (both sides of double-sided surfaces count).
    pub fn total_area(&self) -> f64 {
        self.patches.iter().map(|p| p.area).sum()
    }

    /// Total emitted power Φ = Σ E_i A_i per channel (W).
    pub fn emitted_power(&self) -> DVec3 {
        self.patches.iter().map(|p| p.emission * p.area).sum()
    }

    /// The scale of the light entering the scene (W per channel): the
    /// surfaces' emitted power plus [`Lights::power_bound`]. Relative
    /// thresholds are fractions of it.
    pub fn source_power(&self) -> DVec3 {
        self.emitted_power() + self.lights.power_bound(self.bounds.1 - self.bounds.0)
    }

    /// A distance from any point of the scene to beyond all of it.
    pub fn far(&self) -> f64 {
        2.0 * self.diagonal().max(f64::MIN_POSITIVE)
            + (self.bounds.0.abs().max(self.bounds.1.abs())).length()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    fn tri(p: [[f64; 3]; 3], material: u32) -> InputTriangle {
        InputTriangle {
            positions: p.map(DVec3::from_array),
            material,
            surface: 0,
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::splat(1.0),
            origin: Default::default(),
        }
    }

    fn materials(double_sided: bool) -> Vec<Material> {
        (0..2)
            .map(|i| Material {
                name: format!("m{i}"),
                reflectance: DVec3::splat(0.5),
                emitted_radiance: DVec3::ONE,
                double_sided,
            })
            .collect()
    }

    fn surfaces() -> Vec<Surface> {
        vec![Surface {
            name: "s".into(),
            node: 0,
        }]
    }

    #[test]
    fn square_of_two_triangles_becomes_one_quad() {
        let t = vec![
            tri([[0., 0., 0.], [1., 0., 0.], [1., 1., 0.]], 0),
            tri([[0., 0., 0.], [1., 1., 0.], [0., 1., 0.]], 0),
        ];
        let s = Scene::build(t, materials(false), surfaces(), vec![], vec![]).unwrap();
        assert_eq!(s.patches.len(), 1);
        let p = &s.patches[0];
        assert_eq!(p.shape, Shape::Quad);
        assert!((p.area - 1.0).abs() < 1e-12);
        assert!((p.normal - DVec3::Z).length() < 1e-12);
        assert!((p.centroid() - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-12);
        // Parametrisation covers the square.
        let mut corners: Vec<_> = [(0., 0.), (1., 0.), (1., 1.), (0., 1.)]
            .iter()
            .map(|&(u, v)| p.point(u, v).to_array())
            .collect();
        corners.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(corners[0], [0., 0., 0.]);
        assert_eq!(corners[3], [1., 1., 0.]);
        assert_eq!(s.triangles[0].front_patch, 0);
        assert_eq!(s.triangles[1].front_patch, 0);
    }

    #[test]
    fn different_materials_or_folds_do_not_merge() {
        let t = vec![
            tri([[0., 0., 0.], [1., 0., 0.], [1., 1., 0.]], 0),
            tri([[0., 0., 0.], [1., 1., 0.], [0., 1., 0.]], 1),
        ];
        let s = Scene::build(t, materials(false), surfaces(), vec![], vec![]).unwrap();
        assert_eq!(s.patches.len(), 2);
        let t = vec![
            tri([[0., 0., 0.], [1., 0., 0.], [1., 1., 0.]], 0),
            tri([[0., 0., 0.], [1., 1., 0.], [0., 1., 0.5]], 0),
        ];
        let s = Scene::build(t, materials(false), surfaces(), vec![], vec![]).unwrap();
        assert_eq!(s.patches.len(), 2);
    }

    #[test]
    fn concave_pair_does_not_merge() {
        // An arrowhead: the union is not convex.
        let t = vec![
            tri([[0., 0., 0.], [1., 0.2, 0.], [0.3, 0.3, 0.]], 0),
            tri([[0., 0., 0.], [0.3, 0.3, 0.], [0.2, 1., 0.]], 0),
        ];
        let s = Scene::build(t, materials(false), surfaces(), vec![], vec![]).unwrap();
        assert_eq!(s.patches.len(), 2);
    }

    #[test]
    fn double_sided_adds_back_patches_and_degenerates_drop() {
        let t = vec![
            tri([[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]], 0),
            tri([[0., 0., 0.], [1., 0., 0.], [2., 0., 0.]], 0),
        ];
        let s = Scene::build(t, materials(true), surfaces(), vec![], vec![]).unwrap();
        assert_eq!(s.stats.degenerate_dropped, 1);
        assert_eq!(s.patches.len(), 2);
        assert_eq!(s.patches[1].side, Side::Back);
        assert!((s.patches[1].normal + DVec3::Z).length() < 1e-12);
        let (_, n) = polygon_area_normal(s.patches[1].vertices());
        assert!((n + DVec3::Z).length() < 1e-12, "back patch winding");
        assert_eq!(s.triangles[0].back_patch, Some(1));
        assert_eq!(s.warnings.len(), 1);
    }

    #[test]
    fn no_emitters_is_an_error() {
        let mut t = tri([[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]], 0);
        t.emitted_radiance = DVec3::ZERO;
        let err = Scene::build(vec![t], materials(false), surfaces(), vec![], vec![]).unwrap_err();
        assert!(matches!(err, Error::NoLight));
    }
}
