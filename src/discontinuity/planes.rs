//! The receivers grouped by plane, with a box tree in each group and one
//! over the groups, so that finding the receivers an occluder triangle
//! passes through or an occluder edge rests on costs about the logarithm of
//! their number, not their number. A fan of slivers, whose boxes all meet
//! at its centre, is one plane: the plane test rejects the whole group once.
//!
//! Owns: [`ReceiverIndex`] and [`GroupPlane`].
//!
//! Invariants: a query visits every receiver whose padded box overlaps the
//! query box and whose group plane passes the caller's test, widened by the
//! group's slack (the largest gap, over the scene's box, between a member's
//! own plane distance and the group's); it returns them in ascending order,
//! and the caller applies its exact per-receiver tests, so the result is
//! the one testing every receiver would give.

use glam::DVec3;

use super::clip::Bounds;
use super::receivers::Receiver;
use crate::util::boxes::BoxTree;

/// Normals are grouped on a grid of this step (a key, not a tolerance: the
/// slack keeps every query exact).
const NORMAL_STEP: f64 = 1e-6;
/// Plane offsets likewise, as a fraction of the scene diagonal.
const OFFSET_STEP: f64 = 1e-6;
/// Groups with at most this many members are scanned, not searched.
const SCAN: usize = 16;

/// A group's plane: signed distance `normal · x − offset`, and how far a
/// member's own distance may differ from it inside the scene's box.
pub(super) struct GroupPlane {
    normal: DVec3,
    offset: f64,
    /// Bound on |member distance − group distance| over the scene box.
    pub(super) slack: f64,
}

impl GroupPlane {
    /// Signed distance of `p` from the group's plane.
    pub(super) fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }
}

struct Group {
    plane: GroupPlane,
    /// Receiver indices, ascending.
    members: Vec<u32>,
    /// Over the members' boxes, when there are more than [`SCAN`].
    tree: Option<BoxTree>,
}

/// The receivers of one run, grouped by plane.
pub(super) struct ReceiverIndex {
    groups: Vec<Group>,
    /// Over the groups' boxes, when there are more than [`SCAN`].
    tree: Option<BoxTree>,
    group_boxes: Vec<Bounds>,
}

impl ReceiverIndex {
    /// Groups `receivers` by plane; `scene` is a box holding every point a
    /// query will test, `diagonal` the scene's.
    pub(super) fn new(receivers: &[Receiver], scene: &Bounds, diagonal: f64) -> ReceiverIndex {
        let mut keyed: Vec<([i64; 4], u32)> = receivers
            .iter()
            .enumerate()
            .map(|(r, rec)| {
                let n = (rec.normal / NORMAL_STEP).round();
                let d = (rec.normal.dot(rec.center) / (OFFSET_STEP * diagonal)).round();
                ([n.x as i64, n.y as i64, n.z as i64, d as i64], r as u32)
            })
            .collect();
        keyed.sort_unstable();
        let mid = 0.5 * (scene.lo + scene.hi);
        let half = 0.5 * (scene.hi - scene.lo);
        let mut groups: Vec<Group> = Vec::new();
        for run in keyed.chunk_by(|a, b| a.0 == b.0) {
            let first = &receivers[run[0].1 as usize];
            let (normal, offset) = (first.normal, first.normal.dot(first.center));
            let slack = run
                .iter()
                .map(|&(_, r)| {
                    let rec = &receivers[r as usize];
                    let dn = rec.normal - normal;
                    let doff = rec.normal.dot(rec.center) - offset;
                    (mid.dot(dn) - doff).abs() + half.dot(dn.abs())
                })
                .fold(0.0, f64::max);
            let mut members: Vec<u32> = run.iter().map(|&(_, r)| r).collect();
            members.sort_unstable();
            let tree = (members.len() > SCAN).then(|| {
                BoxTree::new(members.iter().map(|&r| {
                    let b = &receivers[r as usize].bounds;
                    (b.lo, b.hi)
                }))
            });
            groups.push(Group {
                plane: GroupPlane {
                    normal,
                    offset,
                    slack: slack * (1.0 + 1e-9) + 1e-12 * diagonal,
                },
                members,
                tree,
            });
        }
        let group_boxes: Vec<Bounds> = groups
            .iter()
            .map(|g| {
                g.members.iter().fold(
                    Bounds {
                        lo: DVec3::INFINITY,
                        hi: DVec3::NEG_INFINITY,
                    },
                    |b, &r| {
                        let rb = &receivers[r as usize].bounds;
                        Bounds {
                            lo: b.lo.min(rb.lo),
                            hi: b.hi.max(rb.hi),
                        }
                    },
                )
            })
            .collect();
        let tree =
            (groups.len() > SCAN).then(|| BoxTree::new(group_boxes.iter().map(|b| (b.lo, b.hi))));
        ReceiverIndex {
            groups,
            tree,
            group_boxes,
        }
    }

    /// The receivers whose box overlaps `query`, in a group whose plane
    /// passes `plane`, ascending, into `out` (cleared first).
    pub(super) fn candidates(
        &self,
        receivers: &[Receiver],
        query: &Bounds,
        plane: impl Fn(&GroupPlane) -> bool,
        out: &mut Vec<u32>,
    ) {
        out.clear();
        let mut group = |g: usize| {
            if !self.group_boxes[g].overlaps(query) {
                return;
            }
            let group = &self.groups[g];
            if !plane(&group.plane) {
                return;
            }
            let overlaps = |r: u32| receivers[r as usize].bounds.overlaps(query);
            match &group.tree {
                Some(tree) => tree.overlapping(query.lo, query.hi, |i| {
                    let r = group.members[i as usize];
                    if overlaps(r) {
                        out.push(r);
                    }
                }),
                None => out.extend(group.members.iter().copied().filter(|&r| overlaps(r))),
            }
        };
        match &self.tree {
            Some(tree) => tree.overlapping(query.lo, query.hi, |g| group(g as usize)),
            None => (0..self.groups.len()).for_each(&mut group),
        }
        out.sort_unstable();
    }
}
