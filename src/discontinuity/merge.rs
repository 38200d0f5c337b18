//! The last step: merging collinear overlapping pieces, then the segment
//! budget.
//!
//! Owns: [`merge_collinear`], [`apply_budget`] and the ranking of segments
//! ([`rank`]: contact lines first, then weight).
//!
//! Two segments of one patch are on one line when their directions (angles
//! in a frame of the patch plane, modulo π) differ by at most
//! [`MERGE_ANGLE`] and their offsets from a common origin by at most
//! [`MERGE_DIST`] of the diagonal, each step of a chain counting; pieces of
//! one line that overlap or nearly touch become one segment, carrying the
//! kind, emitter and weight of its best-ranked piece.
//!
//! Invariants: the output is ordered by patch, then by line (angle, then
//! offset), then along the line; ties are broken by generation order, so the
//! result does not depend on the thread count. The budget keeps the best
//! segments in their merged order.

use glam::DVec3;
use rayon::prelude::*;

use super::{Segment, SegmentKind};
use crate::scene::Scene;

/// Collinear segments within this distance (fraction of the diagonal) are
/// merged.
const MERGE_DIST: f64 = 1e-6;
/// Collinear segments within this angle (radians) are merged.
const MERGE_ANGLE: f64 = 1e-6;

/// Merges collinear overlapping segments of each patch and orders the result
/// by patch, then by line.
pub(super) fn merge_collinear(raw: Vec<Segment>, scene: &Scene) -> Vec<Segment> {
    let mut by_patch: Vec<(u32, Vec<Segment>)> = Vec::new();
    let mut sorted = raw;
    sorted.sort_by_key(|s| s.patch); // stable: keeps generation order
    for s in sorted {
        match by_patch.last_mut() {
            Some((p, v)) if *p == s.patch => v.push(s),
            _ => by_patch.push((s.patch, vec![s])),
        }
    }
    let merged: Vec<Vec<Segment>> = by_patch
        .into_par_iter()
        .map(|(p, segs)| merge_patch(segs, scene.patches[p as usize].normal, scene.diagonal()))
        .collect();
    merged.into_iter().flatten().collect()
}

/// Merges the collinear overlapping segments of one patch with unit
/// `normal`; `segs` is not empty.
fn merge_patch(segs: Vec<Segment>, normal: DVec3, diagonal: f64) -> Vec<Segment> {
    let dist = MERGE_DIST * diagonal;
    let lines = line_parameters(&segs, normal);
    let mut order: Vec<usize> = (0..segs.len()).collect();
    order.sort_by(|&i, &j| lines[i].0.total_cmp(&lines[j].0).then(i.cmp(&j)));
    let mut out = Vec::new();
    // Same direction: consecutive angles within the tolerance.
    for direction in chains(&order, |k| lines[k].0, MERGE_ANGLE) {
        let mut group: Vec<usize> = direction.to_vec();
        group.sort_by(|&x, &y| lines[x].1.total_cmp(&lines[y].1).then(x.cmp(&y)));
        // Same line: consecutive offsets within the tolerance.
        for line in chains(&group, |k| lines[k].1, dist) {
            merge_line(&segs, line, dist, &mut out);
        }
    }
    out
}

/// The line of each segment in a frame of the plane with unit `normal`,
/// about the first segment's start: (angle in [−MERGE_ANGLE, π −
/// MERGE_ANGLE), signed offset).
fn line_parameters(segs: &[Segment], normal: DVec3) -> Vec<(f64, f64)> {
    let ex = normal.any_orthonormal_vector();
    let ey = normal.cross(ex);
    let origin = segs[0].a;
    segs.iter()
        .map(|s| {
            let d = s.b - s.a;
            let mut theta = d.dot(ey).atan2(d.dot(ex));
            if theta < -MERGE_ANGLE {
                theta += std::f64::consts::PI;
            }
            if theta >= std::f64::consts::PI - MERGE_ANGLE {
                theta -= std::f64::consts::PI;
            }
            let (sin, cos) = theta.sin_cos();
            let p = s.a - origin;
            let offset = -sin * p.dot(ex) + cos * p.dot(ey);
            (theta, offset)
        })
        .collect()
}

/// Splits `sorted` (indices in increasing order of `value`) into maximal
/// runs in which consecutive values differ by at most `tol`.
fn chains(sorted: &[usize], value: impl Fn(usize) -> f64, tol: f64) -> Vec<&[usize]> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let mut j = i + 1;
        while j < sorted.len() && value(sorted[j]) - value(sorted[j - 1]) <= tol {
            j += 1;
        }
        out.push(&sorted[i..j]);
        i = j;
    }
    out
}

/// A stretch of a line: its parameter interval along the line and the
/// points at its ends.
#[derive(Clone, Copy)]
struct Span {
    lo: f64,
    hi: f64,
    from: DVec3,
    to: DVec3,
}

/// Merges the overlapping members of one line's segments (gaps of at most
/// `dist` close), pushing the merged segments in order along the line.
fn merge_line(segs: &[Segment], members: &[usize], dist: f64, out: &mut Vec<Segment>) {
    let anchor = segs[members[0]];
    let dir = (anchor.b - anchor.a).normalize_or_zero();
    let t = |p: DVec3| (p - anchor.a).dot(dir);
    let mut spans: Vec<(Span, usize)> = members
        .iter()
        .map(|&k| {
            let s = segs[k];
            let span = if t(s.a) <= t(s.b) {
                Span {
                    lo: t(s.a),
                    hi: t(s.b),
                    from: s.a,
                    to: s.b,
                }
            } else {
                Span {
                    lo: t(s.b),
                    hi: t(s.a),
                    from: s.b,
                    to: s.a,
                }
            };
            (span, k)
        })
        .collect();
    spans.sort_by(|x, y| x.0.lo.total_cmp(&y.0.lo).then(x.1.cmp(&y.1)));
    // The span being grown and its best-ranked piece.
    let mut current: Option<(Span, Segment)> = None;
    for (span, k) in spans {
        let s = segs[k];
        current = match current {
            Some((mut run, mut best)) if span.lo <= run.hi + dist => {
                if rank(&s) > rank(&best) {
                    best = s;
                }
                if span.hi > run.hi {
                    run.hi = span.hi;
                    run.to = span.to;
                }
                Some((run, best))
            }
            done => {
                if let Some((run, best)) = done {
                    out.push(Segment {
                        a: run.from,
                        b: run.to,
                        ..best
                    });
                }
                Some((span, s))
            }
        };
    }
    if let Some((run, best)) = current {
        out.push(Segment {
            a: run.from,
            b: run.to,
            ..best
        });
    }
}

/// Contact lines outrank D1 segments; then weight decides.
fn rank(s: &Segment) -> (bool, f64) {
    (s.kind == SegmentKind::Contact, s.weight)
}

/// Keeps at most `max` segments: the best by [`rank`], in their order.
pub(super) fn apply_budget(segments: &mut Vec<Segment>, max: usize) {
    if segments.len() <= max {
        return;
    }
    let mut order: Vec<usize> = (0..segments.len()).collect();
    order.sort_by(|&i, &j| {
        let (ri, rj) = (rank(&segments[i]), rank(&segments[j]));
        rj.0.cmp(&ri.0).then(rj.1.total_cmp(&ri.1)).then(i.cmp(&j))
    });
    let mut keep = vec![false; segments.len()];
    for &i in &order[..max] {
        keep[i] = true;
    }
    let mut k = 0;
    segments.retain(|_| {
        k += 1;
        keep[k - 1]
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_joins_overlapping_collinear_pieces() {
        let seg = |a: [f64; 3], b: [f64; 3], w: f64| Segment {
            patch: 0,
            a: DVec3::from_array(a),
            b: DVec3::from_array(b),
            kind: SegmentKind::Ve,
            emitter: Some(0),
            weight: w,
        };
        let segs = vec![
            seg([0., 0., 0.], [1., 0., 0.], 0.1),
            seg([2., 0., 0.], [0.5, 0., 0.], 0.3),
            seg([0., 1., 0.], [1., 1., 0.], 0.2),
            seg([3., 0., 0.], [4., 0., 0.], 0.2),
        ];
        let out = merge_patch(segs, DVec3::Z, 1.0);
        assert_eq!(out.len(), 3);
        let long = out
            .iter()
            .find(|s| (s.b - s.a).length() > 1.5)
            .expect("merged");
        assert_eq!(long.weight, 0.3);
        assert!(
            (long.a.x.min(long.b.x)).abs() < 1e-15 && (long.a.x.max(long.b.x) - 2.0).abs() < 1e-15
        );
    }
}
