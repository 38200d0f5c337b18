//! Tracing a wedge onto the receivers of its luminaire: the line its plane
//! cuts from each receiver, clipped to the wedge, then to the stretches
//! where the wedge's visibility event really happens.
//!
//! Owns: [`Context::trace`] and [`visible_runs`], with the sampling
//! constants.
//!
//! Approximations (documented, deliberate):
//! - Receivers are found in the plane index (`planes`) by the wedge's box
//!   within the scene, whole planes skipped when the occluder feature lies
//!   in them or the light is behind them; a wedge whose box spans the
//!   scene still visits every receiver of the planes it may reach.
//! - Visibility is ray-cast at a handful of points along the line (source →
//!   occluder feature → receiver point), with bisection at changes; an
//!   occluded stretch shorter than the sample spacing can be missed.
//!
//! Invariants: a receiver is traced only when the occluder feature stands in
//! front of it (not in its plane) and the light comes from its front; every
//! segment kept has weight at least `min_contribution` and passes
//! `Receiver::keeps`; segments come in receiver order, then along the line.

use glam::DVec3;

use super::Segment;
use super::clip::{clip_segment, plane_chord};
use super::context::Context;
use super::luminaires::Luminaire;
use super::planes::GroupPlane;
use super::receivers::Receiver;
use super::wedges::{Traced, Wedge};

/// Bisection steps locating a change of visibility along a segment.
const BISECTIONS: usize = 10;
/// Visibility samples along a segment: one per this fraction of the
/// diagonal, within [`MIN_SAMPLES`, `MAX_SAMPLES`].
const SAMPLE_SPACING: f64 = 0.01;
/// The fewest visibility samples along a segment.
const MIN_SAMPLES: usize = 5;
/// The most visibility samples along a segment.
const MAX_SAMPLES: usize = 33;

impl Context<'_> {
    /// Traces one wedge onto the luminaire's receivers, adding its segments
    /// and the rays cast to `traced`.
    pub(super) fn trace(&self, lum: &Luminaire, wedge: &Wedge, traced: &mut Traced) {
        let bounds = wedge.bounds(&self.bounds);
        let tol = self.tol();
        // `lit_through`, widened by a group's slack: true for a group when
        // it may be true for one of its members.
        let may_be_lit = |g: &GroupPlane| {
            // (A feature in front is not in the plane.)
            let t = tol - g.slack;
            wedge.base.iter().any(|&p| g.distance(p) > t)
                && wedge.source.iter().any(|&p| g.distance(p) > t)
        };
        let mut candidates = Vec::new();
        self.index
            .candidates(&self.receivers, &bounds, may_be_lit, &mut candidates);
        for r in candidates {
            if lum.receivers.binary_search(&r).is_ok() {
                self.trace_onto(lum, wedge, r, traced);
            }
        }
    }

    /// Traces one wedge onto receiver `r`.
    fn trace_onto(&self, lum: &Luminaire, wedge: &Wedge, r: u32, traced: &mut Traced) {
        let rec = &self.receivers[r as usize];
        if !self.lit_through(rec, wedge) {
            return;
        }
        let Some((a, b)) = self.wedge_line(rec, wedge) else {
            return;
        };
        if !(self.weight(lum, r, 0.5 * (a + b)) >= self.settings.min_contribution) {
            return;
        }
        for (u0, u1) in self.visible_stretches(wedge, (a, b), traced) {
            let (p, q) = (a.lerp(b, u0), a.lerp(b, u1));
            if !rec.keeps(p, q, self.diagonal) {
                continue;
            }
            let weight = self.weight(lum, r, 0.5 * (p + q));
            if weight >= self.settings.min_contribution {
                traced.segments.push(Segment {
                    patch: r,
                    a: p,
                    b: q,
                    kind: wedge.kind,
                    emitter: Some(lum.patch),
                    weight,
                });
            }
        }
    }

    /// True when the occluder feature stands in front of the receiver, not
    /// in its plane, and the light comes from its front.
    fn lit_through(&self, rec: &Receiver, wedge: &Wedge) -> bool {
        let tol = self.tol();
        let feature_front = wedge
            .base
            .iter()
            .map(|&p| rec.distance(p))
            .fold(f64::MIN, f64::max);
        let feature_on_plane = wedge.base.iter().all(|&p| rec.distance(p).abs() <= tol);
        let source_front = wedge.source.iter().any(|&p| rec.distance(p) > tol);
        !feature_on_plane && feature_front > tol && source_front
    }

    /// The chord the wedge's plane cuts from the receiver, clipped to the
    /// wedge's half-planes, when something keepable is left.
    fn wedge_line(&self, rec: &Receiver, wedge: &Wedge) -> Option<(DVec3, DVec3)> {
        let chord = plane_chord(&rec.polygon, wedge.normal, wedge.offset, self.tol())?;
        let (a, b) = wedge.half_planes[..wedge.n_half_planes]
            .iter()
            .try_fold(chord, |(a, b), &(o, k)| clip_segment(a, b, o, k))?;
        rec.keeps(a, b, self.diagonal).then_some((a, b))
    }

    /// The stretches of (a, b), as parameter intervals, where the wedge is
    /// unblocked; counts the rays cast in `traced`.
    fn visible_stretches(
        &self,
        wedge: &Wedge,
        (a, b): (DVec3, DVec3),
        traced: &mut Traced,
    ) -> Vec<(f64, f64)> {
        let len = (b - a).length();
        let k = ((len / (SAMPLE_SPACING * self.diagonal)).ceil() as usize)
            .clamp(MIN_SAMPLES, MAX_SAMPLES);
        let mut cast = 0;
        let runs = visible_runs(k, |u| {
            cast += 2;
            wedge.unblocked(self.bvh, a.lerp(b, u))
        });
        traced.rays += cast;
        runs
    }
}

/// Intervals of [0, 1] where `visible` holds, from `k` bin-centre samples
/// refined by bisection at each change; an end bin that is visible extends
/// its interval to the end.
fn visible_runs(k: usize, mut visible: impl FnMut(f64) -> bool) -> Vec<(f64, f64)> {
    let u = |i: usize| (i as f64 + 0.5) / k as f64;
    let status: Vec<bool> = (0..k).map(|i| visible(u(i))).collect();
    let mut runs = Vec::new();
    let mut start: Option<f64> = if status[0] { Some(0.0) } else { None };
    for i in 1..k {
        if status[i] == status[i - 1] {
            continue;
        }
        // Bisect between the two sample points.
        let (mut lo, mut hi) = (u(i - 1), u(i));
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (lo + hi);
            if visible(mid) == status[i - 1] {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let edge = 0.5 * (lo + hi);
        match start.take() {
            Some(s) => runs.push((s, edge)),
            None => start = Some(edge),
        }
    }
    if let Some(s) = start {
        runs.push((s, 1.0));
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn visible_runs_finds_the_gap() {
        let runs = visible_runs(9, |u| !(0.3..0.6).contains(&u));
        assert_eq!(runs.len(), 2);
        assert_eq!(runs[0].0, 0.0);
        assert!((runs[0].1 - 0.3).abs() < 1e-3);
        assert!((runs[1].0 - 0.6).abs() < 1e-3);
        assert_eq!(runs[1].1, 1.0);
        assert!(visible_runs(5, |_| false).is_empty());
    }
}
