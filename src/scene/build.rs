//! Building a [`Scene`] from loaded triangles: coordinates checked,
//! degenerate triangles dropped, coplanar pairs merged into quad patches
//! ([`super::quads`]), back patches added for double-sided materials.
//!
//! Invariant: what comes out keeps every invariant of [`Scene`] (one-sided
//! planar patches, counter-clockwise corners, at least one emitter), or
//! the build fails with an error naming the surface and triangle.

use glam::DVec3;

use super::polygon::polygon_area_normal;
use super::quads::pair_triangles;
use super::{
    Camera, InputTriangle, Lights, MAX_COORDINATE, Material, Patch, Scene, SceneStats,
    SceneTriangle, Shape, Side, Surface,
};
use crate::error::{Error, Result};

/// Smallest height of a kept triangle, as a fraction of the scene diagonal.
const DEGENERATE_HEIGHT: f64 = 1e-9;

impl Scene {
    /// Builds patches from loaded triangles, lit by their emitters alone.
    /// Fails when a vertex coordinate is not finite or exceeds
    /// [`MAX_COORDINATE`] (naming the surface and triangle), when nothing
    /// usable is left or when nothing emits.
    pub fn build(
        input: Vec<InputTriangle>,
        materials: Vec<Material>,
        surfaces: Vec<Surface>,
        cameras: Vec<Camera>,
        warnings: Vec<String>,
    ) -> Result<Scene> {
        Scene::build_lit(
            input,
            materials,
            surfaces,
            cameras,
            warnings,
            Lights::default(),
        )
    }

    /// [`Scene::build`] with punctual lights and a sky besides the
    /// emitters; fails ([`Error::NoLight`]) only when there is no light of
    /// any kind.
    pub fn build_lit(
        input: Vec<InputTriangle>,
        materials: Vec<Material>,
        surfaces: Vec<Surface>,
        cameras: Vec<Camera>,
        mut warnings: Vec<String>,
        lights: Lights,
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
                origin: t.origin,
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
        if !patches.iter().any(Patch::is_emitter) && lights.is_empty() {
            return Err(Error::NoLight);
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
            source: None,
            lights,
        })
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
