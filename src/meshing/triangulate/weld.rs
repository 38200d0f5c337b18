//! The global step between the per-patch ones: the boundary points of all
//! patches welded to canonical positions, and each canonical point handed to
//! every patch edge it lies on ([`connect`], giving a [`Connection`]).
//!
//! Invariants:
//! - a canonical point's position is the position of the smallest-index
//!   item of its weld group (corners of every patch first, in patch order,
//!   then every patch's boundary points), so it is the same f64 value for
//!   every patch that uses it;
//! - a patch's corners stay distinct: two weld groups holding corners of
//!   the same patch are never merged;
//! - a point is put on an edge only strictly between its ends, more than
//!   [`CORNER`] weld radii from both corners, and on one edge per patch
//!   (the nearest);
//! - each edge's list is sorted along the edge, ties by id, without repeats.

use std::collections::{HashMap, HashSet};

use glam::{DVec3, Vec3A};
use obvhs::{BvhBuildParams, aabb::Aabb, ray::Ray};
use rayon::prelude::*;

use super::frame::LocalPatch;
use super::grid::{EdgeRef, Grid3};
use super::{CORNER, ON_EDGE};
use crate::util::union_find::UnionFind;

/// Relative slack of the f32 search in [`near_pairs`] (of coordinates and
/// of the edge parameter): far above f32 rounding, far below any tolerance.
const SEARCH_SLACK: f64 = 1e-5;

/// The welded points at one exact position, by weld group: what a later
/// point needs to decide whether it reaches the group here.
struct AtSite {
    /// A member of the group (its representative when last looked at).
    member: usize,
    /// The largest radius of the group's corners here (0 if none).
    corner_radius: f64,
    /// The largest radius of its other points here (0 if none).
    point_radius: f64,
}

/// Welds points closer than the smaller of their radii, or [`CORNER`] times
/// that when one of them is a corner (union-find, the smallest index
/// represents a group). Two groups whose corner owners
/// (patch ids) intersect are never merged: a patch keeps its corners apart.
/// Returns the representative of each point.
///
/// Points at one exact position (a site) are met once per weld group there,
/// not once each, and owner sets are hash sets merged small into large, so
/// a position many patches share (a fan's centre) costs about linear work.
/// Without owner conflicts the groups are the connected components of the
/// "within reach" pairs, whatever the order they are met in.
fn weld(points: &[DVec3], radius: &[f64], owner: &[Option<u32>]) -> Vec<u32> {
    let n = points.len();
    let cell = CORNER * radius.iter().copied().fold(f64::MIN_POSITIVE, f64::max);
    let mut grid = Grid3::new(cell);
    let mut groups = UnionFind::new(n);
    let mut owners: Vec<HashSet<u32>> = owner.iter().map(|o| o.iter().copied().collect()).collect();
    let mut site_of: HashMap<[u64; 3], u32> = HashMap::new();
    let mut sites: Vec<(DVec3, Vec<AtSite>)> = Vec::new();
    let mut near = Vec::new();
    for i in 0..n {
        let p = points[i];
        grid.query(p, CORNER * radius[i], &mut near);
        for &s in &near {
            let (q, at) = &mut sites[s as usize];
            let d = (*q - p).length();
            // Canonical members, one entry a group.
            for a in at.iter_mut() {
                a.member = groups.find(a.member);
            }
            at.sort_by_key(|a| a.member);
            at.dedup_by(|b, a| {
                let same = a.member == b.member;
                if same {
                    a.corner_radius = a.corner_radius.max(b.corner_radius);
                    a.point_radius = a.point_radius.max(b.point_radius);
                }
                same
            });
            for a in at.iter() {
                // Corners attract from further away than ordinary points.
                let reaches = if owner[i].is_some() {
                    d <= CORNER * radius[i].min(a.corner_radius.max(a.point_radius))
                } else {
                    d <= CORNER * radius[i].min(a.corner_radius)
                        || d <= radius[i].min(a.point_radius)
                };
                if !reaches {
                    continue;
                }
                let (ri, rj) = (groups.find(i), groups.find(a.member));
                if ri == rj {
                    continue;
                }
                let (small, large) = if owners[ri].len() <= owners[rj].len() {
                    (ri, rj)
                } else {
                    (rj, ri)
                };
                if owners[small].iter().any(|o| owners[large].contains(o)) {
                    continue;
                }
                let keep = groups.union(ri, rj);
                let mut merged = std::mem::take(&mut owners[large]);
                merged.extend(std::mem::take(&mut owners[small]));
                owners[keep] = merged;
            }
        }
        let key = p.to_array().map(f64::to_bits);
        let s = *site_of.entry(key).or_insert_with(|| {
            sites.push((p, Vec::new()));
            grid.insert_box(p, p, sites.len() as u32 - 1);
            sites.len() as u32 - 1
        });
        let (corner_radius, point_radius) = match owner[i] {
            Some(_) => (radius[i], 0.0),
            None => (0.0, radius[i]),
        };
        sites[s as usize].1.push(AtSite {
            member: i,
            corner_radius,
            point_radius,
        });
    }
    (0..n).map(|i| groups.find(i) as u32).collect()
}

/// Every (point, edge) pair, sorted, where the point may lie within `r`
/// of the edge: a superset of the pairs that do (boxes padded for the f32
/// search). The search runs from the edges through a tree over the points,
/// so a point many edges meet (a fan's centre) costs one entry per edge,
/// and a long edge among many (a fan's slivers) only the points beside it:
/// the work is about (points + edges) log points plus the pairs found.
fn near_pairs(points: &[DVec3], edges: &[EdgeRef], r: f64, diagonal: f64) -> Vec<(u32, u32)> {
    if points.is_empty() {
        return Vec::new();
    }
    let boxes: Vec<Aabb> = points
        .iter()
        .map(|p| {
            let pad = DVec3::splat(r + SEARCH_SLACK * (p.abs().max_element() + diagonal));
            Aabb::new(
                Vec3A::from((*p - pad).as_vec3()),
                Vec3A::from((*p + pad).as_vec3()),
            )
        })
        .collect();
    let tree = crate::util::boxes::build_bvh2(&boxes, BvhBuildParams::fast_build());
    let mut pairs: Vec<(u32, u32)> = edges
        .par_iter()
        .enumerate()
        .flat_map_iter(|(e, edge)| {
            let (a, b) = (edge.2, edge.3);
            let ray = Ray::new(
                Vec3A::from(a.as_vec3()),
                Vec3A::from((b - a).as_vec3()),
                -SEARCH_SLACK as f32,
                1.0 + SEARCH_SLACK as f32,
            );
            let mut found = Vec::new();
            tree.ray_traverse_anyhit(ray, |_, id| {
                found.push((tree.primitive_indices[id], e as u32));
            });
            found
        })
        .collect();
    pairs.par_sort_unstable();
    pairs.dedup();
    pairs
}

/// The shared boundary points: canonical positions, and for every patch
/// the canonical ids of its corners, of its own boundary points and the
/// sorted lists of canonical points on each of its edges.
pub(super) struct Connection {
    /// Canonical positions, by canonical id.
    pub(super) points: Vec<DVec3>,
    /// Per patch, per corner: its canonical id.
    pub(super) corners: Vec<Vec<u32>>,
    /// Per patch, per [`LocalPatch::boundary`] point: its canonical id.
    pub(super) boundary: Vec<Vec<u32>>,
    /// Per patch, per edge: the canonical ids strictly between its corners,
    /// in order along the edge.
    pub(super) edges: Vec<Vec<Vec<u32>>>,
}

/// Welds the boundary points of all `locals` and puts every canonical
/// point on the patch edges it lies on.
pub(super) fn connect(locals: &[LocalPatch], diagonal: f64) -> Connection {
    let canonical = Canonical::weld(locals);
    let edges = canonical.patch_edges(locals);
    let mut lists = canonical.points_on_edges(locals, &edges, diagonal);
    canonical.keep_own_boundary_points(locals, &edges, &mut lists);
    let Canonical {
        points,
        corners,
        boundary,
    } = canonical;
    Connection {
        points,
        corners,
        boundary,
        edges: sorted_edge_lists(lists, &edges, locals.len()),
    }
}

/// How far from an edge's line a point may lie to count as on the edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reach {
    /// Within [`ON_EDGE`] weld radii of the line.
    Near,
    /// Any distance: the point is known to belong to the edge.
    Any,
}

/// Parameter and distance of `x` on edge `e`, when it lies on it: strictly
/// between the ends, more than [`CORNER`] weld radii from each, and within
/// `reach` of the line.
fn on_edge(locals: &[LocalPatch], e: &EdgeRef, x: DVec3, reach: Reach) -> Option<(f64, f64)> {
    let l = &locals[e.0 as usize];
    let (a, b) = (e.2, e.3);
    let ab = b - a;
    let t = (x - a).dot(ab) / ab.length_squared();
    let eps = l.shape.eps;
    let off = (a + t * ab - x).length();
    let inside = t > 0.0
        && t < 1.0
        && (x - a).length() > CORNER * eps
        && (x - b).length() > CORNER * eps
        && (reach == Reach::Any || off <= ON_EDGE * eps);
    inside.then_some((t, off))
}

/// The welded boundary points, before they are put on edges.
struct Canonical {
    points: Vec<DVec3>,
    corners: Vec<Vec<u32>>,
    boundary: Vec<Vec<u32>>,
}

impl Canonical {
    /// Welds every corner, then every local boundary point, and numbers
    /// the groups in order of their representatives' first use.
    fn weld(locals: &[LocalPatch]) -> Canonical {
        let mut pts = Vec::new();
        let mut radius = Vec::new();
        let mut owner = Vec::new();
        for (p, l) in locals.iter().enumerate() {
            for &c in &l.shape.corners {
                pts.push(c);
                radius.push(l.shape.eps);
                owner.push(Some(p as u32));
            }
        }
        for l in locals {
            for &(_, b) in &l.boundary {
                pts.push(b);
                radius.push(l.shape.eps);
                owner.push(None);
            }
        }
        let rep = weld(&pts, &radius, &owner);
        let mut canon_of_rep: HashMap<u32, u32> = HashMap::new();
        let mut points = Vec::new();
        let canon: Vec<u32> = rep
            .iter()
            .map(|&r| {
                *canon_of_rep.entry(r).or_insert_with(|| {
                    points.push(pts[r as usize]);
                    points.len() as u32 - 1
                })
            })
            .collect();
        let mut item = 0;
        let mut corners = Vec::with_capacity(locals.len());
        for l in locals {
            corners.push(canon[item..item + l.shape.n()].to_vec());
            item += l.shape.n();
        }
        let mut boundary = Vec::with_capacity(locals.len());
        for l in locals {
            boundary.push(canon[item..item + l.boundary.len()].to_vec());
            item += l.boundary.len();
        }
        Canonical {
            points,
            corners,
            boundary,
        }
    }

    /// Every patch edge between canonical corners, patch by patch.
    fn patch_edges(&self, locals: &[LocalPatch]) -> Vec<EdgeRef> {
        let mut edges: Vec<EdgeRef> = Vec::new();
        for (p, l) in locals.iter().enumerate() {
            for k in 0..l.shape.n() {
                let a = self.points[self.corners[p][k] as usize];
                let b = self.points[self.corners[p][(k + 1) % l.shape.n()] as usize];
                edges.push((p as u32, k, a, b));
            }
        }
        edges
    }

    /// Every canonical point on every patch edge it lies on (within
    /// [`Reach::Near`]): per edge, (parameter, canonical id), unsorted.
    fn points_on_edges(
        &self,
        locals: &[LocalPatch],
        edges: &[EdgeRef],
        diagonal: f64,
    ) -> Vec<Vec<(f64, u32)>> {
        let r_max = locals
            .iter()
            .map(|l| ON_EDGE * l.shape.eps)
            .fold(0.0, f64::max);
        // (point, edge) pairs by point, each point's edges ascending.
        let near = near_pairs(&self.points, edges, r_max, diagonal);
        let hits: Vec<(u32, Vec<(u32, f64)>)> = near
            .chunk_by(|x, y| x.0 == y.0)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|run| {
                let i = run[0].0;
                let x = self.points[i as usize];
                // Near a corner a point can be close to both edges' lines: it
                // goes on the nearer one only.
                let mut found: Vec<(u32, f64, f64)> = Vec::new();
                for &(_, e) in run {
                    let edge = &edges[e as usize];
                    if self.corners[edge.0 as usize].contains(&i) {
                        continue;
                    }
                    let Some((t, off)) = on_edge(locals, edge, x, Reach::Near) else {
                        continue;
                    };
                    match found.iter_mut().find(|f| edges[f.0 as usize].0 == edge.0) {
                        Some(f) if off < f.2 => *f = (e, t, off),
                        Some(_) => {}
                        None => found.push((e, t, off)),
                    }
                }
                (i, found.into_iter().map(|(e, t, _)| (e, t)).collect())
            })
            .collect();
        let mut lists: Vec<Vec<(f64, u32)>> = vec![Vec::new(); edges.len()];
        for (i, h) in &hits {
            for &(e, t) in h {
                lists[e as usize].push((t, *i));
            }
        }
        lists
    }

    /// A patch's own boundary points stay on their edge even when the weld
    /// moved them a little further than the search radius: each one on
    /// none of its patch's edges yet goes on its own edge.
    fn keep_own_boundary_points(
        &self,
        locals: &[LocalPatch],
        edges: &[EdgeRef],
        lists: &mut [Vec<(f64, u32)>],
    ) {
        let mut first_edge = Vec::with_capacity(locals.len());
        let mut count = 0;
        for l in locals {
            first_edge.push(count);
            count += l.shape.n();
        }
        for (p, l) in locals.iter().enumerate() {
            for (j, &(k, _)) in l.boundary.iter().enumerate() {
                let id = self.boundary[p][j];
                let e = first_edge[p] + k;
                if self.corners[p].contains(&id) {
                    continue;
                }
                let placed = first_edge[p]..first_edge[p] + l.shape.n();
                if lists[placed]
                    .iter()
                    .any(|list| list.iter().any(|x| x.1 == id))
                {
                    continue;
                }
                if let Some((t, _)) =
                    on_edge(locals, &edges[e], self.points[id as usize], Reach::Any)
                {
                    lists[e].push((t, id));
                }
            }
        }
    }
}

/// Each edge's points sorted along it (ties by id) without repeats,
/// grouped by patch.
fn sorted_edge_lists(
    lists: Vec<Vec<(f64, u32)>>,
    edges: &[EdgeRef],
    patches: usize,
) -> Vec<Vec<Vec<u32>>> {
    let mut per_patch: Vec<Vec<Vec<u32>>> = (0..patches).map(|_| Vec::new()).collect();
    for (e, mut list) in lists.into_iter().enumerate() {
        list.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let mut ids: Vec<u32> = Vec::with_capacity(list.len());
        for (_, id) in list {
            if !ids.contains(&id) {
                ids.push(id);
            }
        }
        per_patch[edges[e].0 as usize].push(ids);
    }
    per_patch
}
