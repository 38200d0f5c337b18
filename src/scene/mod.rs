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
//! - A scene always has at least one patch and one emitting patch.
//! - Every vertex coordinate is finite and at most [`MAX_COORDINATE`] in
//!   magnitude.

use std::collections::HashMap;

use glam::DVec3;

use crate::error::{Error, Result};

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
    pub positions: [DVec3; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Index into [`Scene::surfaces`].
    pub surface: u32,
    /// ρ over this triangle, in [0, 1) per channel.
    pub reflectance: DVec3,
    /// L_e over this triangle (radiance, W / (m² sr) per channel).
    pub emitted_radiance: DVec3,
}

/// Which side of its input triangle(s) a patch represents.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Front,
    Back,
}

/// The two patch shapes: quads (from merged triangle pairs) and triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    Triangle,
    Quad,
}

/// A kept input triangle: an occluder, and the patches it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneTriangle {
    pub positions: [DVec3; 3],
    pub material: u32,
    pub surface: u32,
    /// The front patch containing this triangle.
    pub front_patch: u32,
    /// The back patch, for double-sided materials.
    pub back_patch: Option<u32>,
}

/// A planar, one-sided radiosity surface: a triangle or a convex quad.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// Corners counter-clockwise seen from the front; for a triangle the
    /// fourth corner repeats the third and is never used.
    pub corners: [DVec3; 4],
    pub shape: Shape,
    /// Unit normal of the radiating side.
    pub normal: DVec3,
    pub area: f64,
    pub material: u32,
    pub surface: u32,
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
    pub name: String,
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
    pub materials: Vec<Material>,
    pub surfaces: Vec<Surface>,
    pub triangles: Vec<SceneTriangle>,
    pub patches: Vec<Patch>,
    pub cameras: Vec<Camera>,
    /// Axis-aligned bounds of all kept triangles.
    pub bounds: (DVec3, DVec3),
    pub stats: SceneStats,
    /// Non-fatal findings (dropped triangles, clamped reflectances, ignored
    /// material features), one line each.
    pub warnings: Vec<String>,
}

/// Largest accepted magnitude of a world-space vertex coordinate, in metres.
///
/// Visibility runs in f32 (the BVH and its rays): extents, surface areas
/// (squared extents) and area sums over up to [`crate::load::MAX_TRIANGLES`]
/// primitives must stay finite there, and coordinates near `f32::MAX` make
/// the BVH builder panic. With |x| ≤ 10¹² m a box is at most 2·10¹² m wide,
/// a surface area 3·(2·10¹²)² ≈ 1.2·10²⁵ m², and 2²⁵ of those sum to about
/// 4·10³² — six orders of magnitude below `f32::MAX` (3.4·10³⁸). Real
/// scenes (a planet is 10⁷ m across) are far inside the bound.
pub const MAX_COORDINATE: f64 = 1e12;

/// Relative tolerances of scene building, as fractions of the scene diagonal.
const DEGENERATE_HEIGHT: f64 = 1e-9;
const COPLANAR_DISTANCE: f64 = 1e-7;
/// Largest angle (radians) between the normals of two merged triangles.
const COPLANAR_ANGLE: f64 = 1e-6;
/// Smallest |sin| of a merged quad's corner angle: no 180° corners.
const CONVEX_SIN: f64 = 1e-6;

impl Scene {
    /// Builds patches from loaded triangles. Fails when a vertex coordinate
    /// is not finite or exceeds [`MAX_COORDINATE`] (naming the surface and
    /// triangle), when nothing usable is left or when nothing emits.
    pub fn build(
        input: Vec<InputTriangle>,
        materials: Vec<Material>,
        surfaces: Vec<Surface>,
        cameras: Vec<Camera>,
        mut warnings: Vec<String>,
    ) -> Result<Scene> {
        if let Some((i, t)) = input.iter().enumerate().find(|(_, t)| {
            t.positions
                .iter()
                .any(|p| !(p.abs().max_element() <= MAX_COORDINATE))
        }) {
            let surface = surfaces.get(t.surface as usize).map_or_else(
                || format!("surface {}", t.surface),
                |s| format!("surface '{}'", s.name),
            );
            return Err(Error::scene(
                "<scene>",
                format!(
                    "{surface}, input triangle {i}: a vertex coordinate of {:?} is not finite \
                     or exceeds {MAX_COORDINATE:e} m",
                    t.positions
                ),
            ));
        }
        let mut stats = SceneStats {
            input_triangles: input.len(),
            ..SceneStats::default()
        };
        let (lo, hi) = bounds(input.iter().flat_map(|t| t.positions));
        let diagonal = (hi - lo).length();
        let kept: Vec<InputTriangle> = input
            .into_iter()
            .filter(|t| !is_degenerate(&t.positions, diagonal))
            .collect();
        stats.degenerate_dropped = stats.input_triangles - kept.len();
        if stats.degenerate_dropped > 0 {
            warnings.push(format!(
                "dropped {} zero-area or near-degenerate triangle(s)",
                stats.degenerate_dropped
            ));
        }
        if kept.is_empty() {
            return Err(Error::EmptyScene);
        }
        let bounds = bounds(kept.iter().flat_map(|t| t.positions));
        let diagonal = (bounds.1 - bounds.0).length();

        let pairs = pair_triangles(&kept, diagonal);
        stats.merged_quads = pairs.iter().filter(|p| p.1.is_some()).count();

        let mut triangles: Vec<SceneTriangle> = kept
            .iter()
            .map(|t| SceneTriangle {
                positions: t.positions,
                material: t.material,
                surface: t.surface,
                front_patch: u32::MAX,
                back_patch: None,
            })
            .collect();
        let mut patches = Vec::with_capacity(pairs.len());
        for &(a, b) in &pairs {
            let patch = match b {
                None => triangle_patch(&kept[a], a as u32),
                Some((b, quad)) => quad_patch(&kept[a], &kept[b], quad, [a as u32, b as u32]),
            };
            let id = patches.len() as u32;
            for t in patch.triangles.iter().filter(|&&t| t != u32::MAX) {
                triangles[*t as usize].front_patch = id;
            }
            patches.push(patch);
        }
        let n_front = patches.len();
        for i in 0..n_front {
            if materials[patches[i].material as usize].double_sided {
                let back = back_patch(&patches[i]);
                let id = patches.len() as u32;
                for t in back.triangles.iter().filter(|&&t| t != u32::MAX) {
                    triangles[*t as usize].back_patch = Some(id);
                }
                patches.push(back);
                stats.back_patches += 1;
            }
        }
        if !patches.iter().any(Patch::is_emitter) {
            return Err(Error::NoEmitters);
        }
        Ok(Scene {
            materials,
            surfaces,
            triangles,
            patches,
            cameras,
            bounds,
            stats,
            warnings,
        })
    }

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
}

fn bounds(points: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    points.fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    )
}

/// Zero area, or a height below [`DEGENERATE_HEIGHT`] of the scene size.
fn is_degenerate(p: &[DVec3; 3], diagonal: f64) -> bool {
    let twice_area = (p[1] - p[0]).cross(p[2] - p[0]).length();
    let longest = (p[1] - p[0])
        .length()
        .max((p[2] - p[1]).length())
        .max((p[0] - p[2]).length());
    !(twice_area > 0.0 && twice_area / longest > DEGENERATE_HEIGHT * diagonal)
}

/// Area-weighted centroid of a planar polygon.
pub fn polygon_centroid(v: &[DVec3]) -> DVec3 {
    let mut sum = DVec3::ZERO;
    let mut weight = 0.0;
    for i in 1..v.len() - 1 {
        let a = (v[i] - v[0]).cross(v[i + 1] - v[0]).length();
        sum += a * (v[0] + v[i] + v[i + 1]) / 3.0;
        weight += a;
    }
    if weight > 0.0 {
        sum / weight
    } else {
        v.iter().sum::<DVec3>() / v.len() as f64
    }
}

/// Area and unit normal of a planar polygon (Newell's method).
pub fn polygon_area_normal(v: &[DVec3]) -> (f64, DVec3) {
    let mut n = DVec3::ZERO;
    for i in 1..v.len() - 1 {
        n += (v[i] - v[0]).cross(v[i + 1] - v[0]);
    }
    let len = n.length();
    (0.5 * len, if len > 0.0 { n / len } else { DVec3::Z })
}

fn triangle_patch(t: &InputTriangle, index: u32) -> Patch {
    let [a, b, c] = t.positions;
    let (area, normal) = polygon_area_normal(&t.positions);
    Patch {
        corners: [a, b, c, c],
        shape: Shape::Triangle,
        normal,
        area,
        material: t.material,
        surface: t.surface,
        side: Side::Front,
        reflectance: t.reflectance,
        emission: std::f64::consts::PI * t.emitted_radiance,
        triangles: [index, u32::MAX],
    }
}

fn quad_patch(t1: &InputTriangle, t2: &InputTriangle, quad: [DVec3; 4], ids: [u32; 2]) -> Patch {
    let (a1, _) = polygon_area_normal(&t1.positions);
    let (a2, _) = polygon_area_normal(&t2.positions);
    let (area, normal) = polygon_area_normal(&quad);
    let mean = |x: DVec3, y: DVec3| (a1 * x + a2 * y) / (a1 + a2);
    Patch {
        corners: quad,
        shape: Shape::Quad,
        normal,
        area,
        material: t1.material,
        surface: t1.surface,
        side: Side::Front,
        reflectance: mean(t1.reflectance, t2.reflectance),
        emission: std::f64::consts::PI * mean(t1.emitted_radiance, t2.emitted_radiance),
        triangles: ids,
    }
}

fn back_patch(front: &Patch) -> Patch {
    let mut back = front.clone();
    back.side = Side::Back;
    back.normal = -front.normal;
    back.corners = match front.shape {
        Shape::Triangle => {
            let [a, b, c, _] = front.corners;
            [a, c, b, b]
        }
        Shape::Quad => {
            let [a, b, c, d] = front.corners;
            [a, d, c, b]
        }
    };
    back
}

type VertexKey = [u64; 3];

fn key(p: DVec3) -> VertexKey {
    // +0.0 and -0.0 are the same point.
    [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits)
}

/// Groups triangles into patches: `(a, None)` for a lone triangle, `(a,
/// Some((b, quad)))` for a merged pair. Greedy and deterministic: triangles
/// are visited in order and first try their longest edge (the diagonal of a
/// rectangle split in two), then their other edges.
#[allow(clippy::type_complexity)]
fn pair_triangles(
    tris: &[InputTriangle],
    diagonal: f64,
) -> Vec<(usize, Option<(usize, [DVec3; 4])>)> {
    let mut edges: HashMap<(VertexKey, VertexKey), Vec<usize>> = HashMap::new();
    for (i, t) in tris.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (key(t.positions[e]), key(t.positions[(e + 1) % 3]));
            // Directed edge a->b; a consistently wound neighbour has b->a.
            edges.entry((a, b)).or_default().push(i);
        }
    }
    let mut partner: Vec<Option<(usize, [DVec3; 4])>> = vec![None; tris.len()];
    let mut taken = vec![false; tris.len()];
    for pass in 0..2 {
        for i in 0..tris.len() {
            if taken[i] {
                continue;
            }
            let t = &tris[i];
            let mut order = [0usize, 1, 2];
            let len = |e: usize| (t.positions[(e + 1) % 3] - t.positions[e]).length();
            order.sort_by(|&x, &y| len(y).total_cmp(&len(x)));
            let candidates: &[usize] = if pass == 0 { &order[..1] } else { &order[1..] };
            for &e in candidates {
                let (a, b) = (t.positions[e], t.positions[(e + 1) % 3]);
                let Some(others) = edges.get(&(key(b), key(a))) else {
                    continue;
                };
                let found = others.iter().copied().find_map(|j| {
                    if j == i || taken[j] {
                        return None;
                    }
                    merge_quad(t, &tris[j], e, diagonal).map(|q| (j, q))
                });
                if let Some((j, quad)) = found {
                    taken[i] = true;
                    taken[j] = true;
                    partner[i] = Some((j, quad));
                    break;
                }
            }
        }
    }
    let mut out = Vec::with_capacity(tris.len());
    for i in 0..tris.len() {
        match partner[i] {
            Some(p) => out.push((i, Some(p))),
            None if !taken[i] => out.push((i, None)),
            None => {} // the second triangle of a pair
        }
    }
    out
}

/// The convex quad formed by `t1` and `t2` across `t1`'s edge `e`, if they
/// share a surface and material and are coplanar.
fn merge_quad(
    t1: &InputTriangle,
    t2: &InputTriangle,
    e: usize,
    diagonal: f64,
) -> Option<[DVec3; 4]> {
    if t1.material != t2.material || t1.surface != t2.surface {
        return None;
    }
    let a = t1.positions[e];
    let b = t1.positions[(e + 1) % 3];
    let c = t1.positions[(e + 2) % 3];
    let d = *t2
        .positions
        .iter()
        .find(|&&p| key(p) != key(a) && key(p) != key(b))?;
    let (_, n1) = polygon_area_normal(&t1.positions);
    let (_, n2) = polygon_area_normal(&t2.positions);
    if n1.dot(n2) < COPLANAR_ANGLE.cos() || (d - a).dot(n1).abs() > COPLANAR_DISTANCE * diagonal {
        return None;
    }
    // t1 = (a, b, c) and t2 = (b, a, d): the quad runs a, d, b, c.
    let quad = [a, d, b, c];
    for i in 0..4 {
        let p = quad[i];
        let prev = quad[(i + 3) % 4];
        let next = quad[(i + 1) % 4];
        let (u, w) = (p - prev, next - p);
        let sin = u.cross(w).dot(n1) / (u.length() * w.length());
        if !(sin > CONVEX_SIN) {
            return None;
        }
    }
    Some(quad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(p: [[f64; 3]; 3], material: u32) -> InputTriangle {
        InputTriangle {
            positions: p.map(DVec3::from_array),
            material,
            surface: 0,
            reflectance: DVec3::splat(0.5),
            emitted_radiance: DVec3::splat(1.0),
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
        assert!(matches!(err, Error::NoEmitters));
    }
}
