//! Luminaires: the emitter polygons whose wedges are traced.
//!
//! Owns: [`Luminaire`], the grouping of emitter patches into luminaires
//! ([`significant`]), the union polygon of a group, the scene's mean
//! exitance and the scalar (channel-mean) reduction of a colour.
//!
//! A punctual light is a luminaire of one vertex (its VE wedges are its
//! hard shadow lines; it has no EV wedges); a directional light stands
//! [`SUN_DISTANCE`] diagonals away.
//!
//! A luminaire is one emitter patch, or several adjacent (edge-sharing)
//! coplanar emitter patches of one surface and one emission whose union is
//! one convex polygon. Emitter patches that do not merge are traced
//! separately, so their shared vertices make lines that cancel in the sum
//! (a documented approximation).
//!
//! Invariants:
//! - Luminaires are ordered by their lowest patch index, which names them in
//!   segments; a merged luminaire's polygon is strictly convex,
//!   counter-clockwise about its normal, without collinear vertices.
//! - Grouping depends only on the patches, not on the order of the
//!   disjoint-set operations (the smallest index represents a set).
//! - A luminaire's receivers are ascending patch indices (searchable by
//!   bisection), never its own patches.

use std::collections::HashMap;

use glam::DVec3;

use super::PLANE_TOL;
use super::receivers::Receiver;
use crate::scene::{LightKind, PunctualLight, Scene, polygon_area_normal};
use crate::util::geometry::{PositionKey, position_key};
use crate::util::union_find::UnionFind;

/// Two neighbouring emitter patches are coplanar when the dot product of
/// their normals exceeds 1 minus this.
const SAME_NORMAL: f64 = 1e-12;
/// How far back a directional light's luminaire stands, in scene
/// diagonals: its wedges' planes are within 1/1000 rad of the true
/// parallel ones.
const SUN_DISTANCE: f64 = 1e3;
/// A boundary vertex is collinear with its neighbours, and dropped, when
/// the cross product of its two edges is at most this fraction of the
/// product of their lengths.
const COLLINEAR: f64 = 1e-9;

/// An emitter polygon: one emitter patch, or several coplanar adjacent ones
/// of one surface and emission whose union is convex; or a punctual light,
/// a polygon of one vertex.
pub(super) struct Luminaire {
    /// Counter-clockwise about `normal`.
    pub(super) polygon: Vec<DVec3>,
    /// The side it lights is in front of its plane (through `polygon[0]`),
    /// unless `omni`.
    pub(super) normal: DVec3,
    /// A point light: it lights every direction, no half-space.
    pub(super) omni: bool,
    /// The punctual light it stands for (index into the scene's).
    pub(super) light: Option<usize>,
    /// Scalar (channel-mean) exitance.
    pub(super) exitance: f64,
    pub(super) power: f64,
    /// Lowest patch index: the luminaire's name in segments.
    pub(super) patch: u32,
    pub(super) patches: Vec<u32>,
    /// Receivers facing this luminaire.
    pub(super) receivers: Vec<u32>,
}

impl Luminaire {
    /// The luminaire of one emitter patch.
    fn single(scene: &Scene, p: u32) -> Luminaire {
        let patch = &scene.patches[p as usize];
        Luminaire {
            polygon: patch.vertices().to_vec(),
            normal: patch.normal,
            omni: false,
            light: None,
            exitance: scalar(patch.emission),
            power: scalar(patch.emission) * patch.area,
            patch: p,
            patches: vec![p],
            receivers: Vec::new(),
        }
    }

    /// The luminaire of several patches (ascending) whose union is `polygon`.
    fn merged(scene: &Scene, patches: Vec<u32>, polygon: Vec<DVec3>) -> Luminaire {
        let first = &scene.patches[patches[0] as usize];
        let (area, _) = polygon_area_normal(&polygon);
        Luminaire {
            polygon,
            normal: first.normal,
            omni: false,
            light: None,
            exitance: scalar(first.emission),
            power: scalar(first.emission) * area,
            patch: patches[0],
            patches,
            receivers: Vec::new(),
        }
    }

    /// The luminaire of punctual light `k`: its position (for a directional
    /// light, a point [`SUN_DISTANCE`] diagonals back along its direction),
    /// named `patch_count + k` in segments.
    fn punctual(scene: &Scene, k: usize, light: &PunctualLight) -> Luminaire {
        let position = match light.kind {
            LightKind::Directional => {
                scene.center() - SUN_DISTANCE * scene.diagonal() * light.direction
            }
            _ => light.position,
        };
        Luminaire {
            polygon: vec![position],
            normal: light.direction,
            omni: light.kind == LightKind::Point,
            light: Some(k),
            exitance: 0.0,
            power: scalar(light.power(scene.bounds.1 - scene.bounds.0)),
            patch: (scene.patches.len() + k) as u32,
            patches: Vec::new(),
            receivers: Vec::new(),
        }
    }

    /// How far `p` lies in front of the luminaire's plane (`f64::MAX` for
    /// an omnidirectional one).
    pub(super) fn front(&self, p: DVec3) -> f64 {
        match self.omni {
            true => f64::MAX,
            false => (p - self.polygon[0]).dot(self.normal),
        }
    }

    /// The receivers, other than its own patches, that some of the
    /// luminaire lies in front of and that lie partly in front of it
    /// (beyond `tol`).
    fn facing(&self, receivers: &[Receiver], tol: f64) -> Vec<u32> {
        let own = &self.patches;
        (0..receivers.len() as u32)
            .filter(|r| !own.contains(r))
            .filter(|&r| {
                let rec = &receivers[r as usize];
                let lit = self.polygon.iter().any(|&v| rec.distance(v) > tol);
                let ahead = rec.polygon.iter().any(|&v| self.front(v) > tol);
                lit && ahead
            })
            .collect()
    }
}

/// The channel mean of a colour.
pub(super) fn scalar(v: DVec3) -> f64 {
    (v.x + v.y + v.z) / 3.0
}

/// Scalar mean exitance over all emitting area; without emitters, the
/// scene's mean source exitance (what its lights bring, over its area).
pub(super) fn mean_exitance(scene: &Scene) -> f64 {
    let (power, area) = scene
        .patches
        .iter()
        .filter(|p| p.is_emitter())
        .fold((0.0, 0.0), |(w, a), p| {
            (w + scalar(p.emission) * p.area, a + p.area)
        });
    if area > 0.0 {
        power / area
    } else {
        scalar(scene.source_power()) / scene.total_area()
    }
}

/// The luminaires with at least `min_fraction` of the strongest one's power
/// (and some power at all), each with its facing `receivers`.
pub(super) fn significant(
    scene: &Scene,
    diagonal: f64,
    min_fraction: f64,
    receivers: &[Receiver],
) -> Vec<Luminaire> {
    let tol = PLANE_TOL * diagonal;
    let mut luminaires = luminaires(scene, diagonal);
    let strongest = luminaires.iter().map(|l| l.power).fold(0.0, f64::max);
    luminaires.retain(|l| l.power > 0.0 && l.power >= min_fraction * strongest);
    for l in &mut luminaires {
        l.receivers = l.facing(receivers, tol);
    }
    luminaires
}

/// Groups emitter patches into luminaires: adjacent (sharing an edge),
/// coplanar patches of one surface and one emission whose union is convex
/// become one polygon; others stay single patches. Ordered by lowest patch.
fn luminaires(scene: &Scene, diagonal: f64) -> Vec<Luminaire> {
    let emitters: Vec<u32> = (0..scene.patches.len() as u32)
        .filter(|&i| scene.patches[i as usize].is_emitter())
        .collect();
    let mut out = Vec::new();
    for g in groups(scene, &emitters, PLANE_TOL * diagonal) {
        let patches: Vec<u32> = g.iter().map(|&k| emitters[k]).collect();
        match union_polygon(scene, &patches) {
            Some(polygon) if patches.len() > 1 => {
                out.push(Luminaire::merged(scene, patches, polygon));
            }
            _ => out.extend(patches.into_iter().map(|p| Luminaire::single(scene, p))),
        }
    }
    let lights = &scene.lights.punctual;
    out.extend(
        lights
            .iter()
            .enumerate()
            .map(|(k, l)| Luminaire::punctual(scene, k, l)),
    );
    out
}

/// The emitters (indices into `emitters`) joined through shared edges with
/// neighbours that [`continue_each_other`], as groups ordered by their first
/// member, each ascending.
fn groups(scene: &Scene, emitters: &[u32], tol: f64) -> Vec<Vec<usize>> {
    let mut sets = UnionFind::new(emitters.len());
    let mut edge_owner: HashMap<(PositionKey, PositionKey), usize> = HashMap::new();
    for (k, &p) in emitters.iter().enumerate() {
        let v = scene.patches[p as usize].vertices();
        for i in 0..v.len() {
            let (a, b) = (position_key(v[i]), position_key(v[(i + 1) % v.len()]));
            // A neighbour walks the shared edge the other way.
            if let Some(&other) = edge_owner.get(&(b, a))
                && continue_each_other(scene, p, emitters[other], tol)
            {
                sets.union(k, other);
            }
            edge_owner.insert((a, b), k);
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut group_of: HashMap<usize, usize> = HashMap::new();
    for k in 0..emitters.len() {
        let root = sets.find(k);
        let g = *group_of.entry(root).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(k);
    }
    groups
}

/// True when patches `p` and `other` are of one surface and one emission,
/// and coplanar: parallel normals and `other`'s corners within `tol` of
/// `p`'s plane.
fn continue_each_other(scene: &Scene, p: u32, other: u32, tol: f64) -> bool {
    let (pi, po) = (&scene.patches[p as usize], &scene.patches[other as usize]);
    pi.surface == po.surface
        && pi.emission == po.emission
        && pi.normal.dot(po.normal) > 1.0 - SAME_NORMAL
        && po
            .vertices()
            .iter()
            .all(|&q| (q - pi.corners[0]).dot(pi.normal).abs() <= tol)
}

/// The boundary of the union of coplanar, edge-sharing patches, without
/// collinear vertices, when it is one convex loop.
fn union_polygon(scene: &Scene, patches: &[u32]) -> Option<Vec<DVec3>> {
    let mut directed: Vec<(DVec3, DVec3)> = Vec::new();
    for &p in patches {
        let v = scene.patches[p as usize].vertices();
        for i in 0..v.len() {
            directed.push((v[i], v[(i + 1) % v.len()]));
        }
    }
    let loop_ = boundary_loop(&directed)?;
    let normal = scene.patches[patches[0] as usize].normal;
    convex_corners(&loop_, normal)
}

/// The one boundary loop of a set of directed edges (the edges without
/// their reverse), starting at the first boundary edge's tail; `None` when
/// there is no boundary, several loops, or a vertex where the boundary
/// touches itself.
fn boundary_loop(directed: &[(DVec3, DVec3)]) -> Option<Vec<DVec3>> {
    let keys: Vec<(PositionKey, PositionKey)> = directed
        .iter()
        .map(|&(a, b)| (position_key(a), position_key(b)))
        .collect();
    let mut count: HashMap<(PositionKey, PositionKey), usize> = HashMap::new();
    for &k in &keys {
        *count.entry(k).or_default() += 1;
    }
    let mut next: HashMap<PositionKey, DVec3> = HashMap::new();
    let mut start = None;
    for (i, &(a, b)) in keys.iter().enumerate() {
        if count.contains_key(&(b, a)) {
            continue; // interior edge
        }
        if next.insert(a, directed[i].1).is_some() {
            return None; // a vertex where the boundary touches itself
        }
        start.get_or_insert(directed[i].0);
    }
    let start = start?;
    let mut loop_ = vec![start];
    let mut at = start;
    for _ in 0..next.len() {
        at = *next.get(&position_key(at))?;
        if position_key(at) == position_key(start) {
            break;
        }
        loop_.push(at);
    }
    if loop_.len() != next.len() {
        return None; // several loops
    }
    Some(loop_)
}

/// The loop without its collinear vertices, when at least three remain and
/// every corner turns counter-clockwise about `normal` (strictly convex).
fn convex_corners(loop_: &[DVec3], normal: DVec3) -> Option<Vec<DVec3>> {
    let n = loop_.len();
    let corners: Vec<DVec3> = (0..n)
        .filter(|&i| {
            let (p, c, q) = (loop_[(i + n - 1) % n], loop_[i], loop_[(i + 1) % n]);
            let (u, w) = (c - p, q - c);
            u.cross(w).length() > COLLINEAR * u.length() * w.length()
        })
        .map(|i| loop_[i])
        .collect();
    let m = corners.len();
    if m < 3 {
        return None;
    }
    let convex = (0..m).all(|i| {
        let (p, c, q) = (corners[(i + m - 1) % m], corners[i], corners[(i + 1) % m]);
        (c - p).cross(q - c).dot(normal) > 0.0
    });
    convex.then_some(corners)
}
