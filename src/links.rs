//! Links of hierarchical radiosity [HSA91]: element-to-element interactions,
//! their evaluation (form factor, visibility, error) and the refinement
//! oracles that decide whether a link is accurate enough.
//!
//! Owns: [`Link`], [`evaluate_link`], [`Oracle`], [`Thresholds`] and the
//! decision [`Decision`].
//!
//! Invariants:
//! - A link is stored with its receiver and names its source; argument order
//!   is always (receiver, source): "the receiver gathers F·V·B_source".
//! - `form_factor` and `visibility` are finite and in [0, 1], touching and
//!   coplanar elements included (the point-to-polygon kernel is bounded).
//! - Evaluation depends only on the two elements' geometry, their ids and
//!   the seed: the visibility rays come from `pair_stream(seed, r, s)`.
//!
//! Form factor: F = Σ_k (A_k/A_r) F(x_k → source), x_k the centroids of the
//! receiver's four virtual children (a 4-point midpoint rule of the exact
//! inner integral), F_err = max_k − min_k of those point values.
//! Visibility: the unoccluded fraction of N rays between stratified points
//! of the two elements.

use glam::DVec3;

use crate::formfactor::form_factor_point_polygon;
use crate::hierarchy::{Element, ElementId, split_corners};
use crate::sampling::{pair_stream, point_in_polygon, stratified};
use crate::scene::{Scene, polygon_centroid};
use crate::visibility::TriangleBvh;

/// One interaction, kept in its receiver's list (16 bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Link {
    pub source: ElementId,
    /// Unoccluded form factor receiver → source estimate, in [0, 1].
    pub form_factor: f32,
    /// Visible fraction, in [0, 1].
    pub visibility: f32,
    /// Form-factor error estimate F_err (spread of the point values).
    pub error: f32,
}

impl Link {
    /// The coupling F·V the gather uses.
    pub fn coupling(&self) -> f64 {
        self.form_factor as f64 * self.visibility as f64
    }
}

/// Centroid of `e` and a point strictly inside.
fn receiver_points(e: &Element) -> ([DVec3; 4], [f64; 4]) {
    let kids = split_corners(e.shape, &e.corners);
    let n = e.vertices().len();
    let mut pts = [DVec3::ZERO; 4];
    let mut w = [0.25; 4];
    for (k, c) in kids.iter().enumerate() {
        pts[k] = polygon_centroid(&c[..n]);
        w[k] = crate::scene::polygon_area_normal(&c[..n]).0 / e.area;
    }
    (pts, w)
}

/// True when some part of `source` lies in front of `receiver`'s plane and
/// some part of `receiver` in front of `source`'s (back-facing pairs can
/// exchange no light). `tol` is a length below which "in front" does not
/// count.
pub fn faces_each_other(
    receiver: &[DVec3],
    n_r: DVec3,
    source: &[DVec3],
    n_s: DVec3,
    tol: f64,
) -> bool {
    let front =
        |pts: &[DVec3], origin: DVec3, n: DVec3| pts.iter().any(|p| (*p - origin).dot(n) > tol);
    front(source, receiver[0], n_r) && front(receiver, source[0], n_s)
}

/// Evaluates the link (receiver `r_id`, source `s_id`): its form factor
/// and error, then its visibility by `rays` rays, unless `skip_visibility`
/// says the unoccluded link already decides (its visibility stays 0).
/// Returns the link and the rays cast.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_link(
    scene: &Scene,
    elements: &[Element],
    r_id: ElementId,
    s_id: ElementId,
    bvh: &TriangleBvh,
    rays: usize,
    seed: u64,
    skip_visibility: impl Fn(&Link) -> bool,
) -> (Link, u64) {
    let r = &elements[r_id.index()];
    let s = &elements[s_id.index()];
    let n_r = scene.patches[r.patch as usize].normal;
    let (pts, w) = receiver_points(r);
    let mut f = 0.0;
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for (x, wk) in pts.iter().zip(w) {
        let v = form_factor_point_polygon(*x, n_r, s.vertices());
        f += wk * v;
        lo = lo.min(v);
        hi = hi.max(v);
    }
    let f = f.clamp(0.0, 1.0);
    let mut link = Link {
        source: s_id,
        form_factor: f as f32,
        visibility: 0.0,
        error: (hi - lo).max(0.0) as f32,
    };
    if f <= 0.0 || skip_visibility(&link) {
        return (link, 0);
    }
    let rays = rays.max(1);
    let mut rng = pair_stream(seed, r_id.0, s_id.0);
    let from = stratified(rays, &mut rng);
    let mut to = stratified(rays, &mut rng);
    // Pair receiver stratum k with a shuffled source stratum, so that rays
    // cross the gap in well-spread directions.
    use rand::seq::SliceRandom;
    to.shuffle(&mut rng);
    let visible = from
        .iter()
        .zip(&to)
        .filter(|(a, b)| {
            bvh.visible(
                point_in_polygon(r.vertices(), **a),
                point_in_polygon(s.vertices(), **b),
            )
        })
        .count();
    link.visibility = visible as f32 / rays as f32;
    (link, rays as u64)
}

/// What the oracle says about a link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    /// Accurate enough: keep the link.
    Accept,
    /// Replace the link by links from the receiver's children.
    SplitReceiver,
    /// Replace the link by links to the source's children.
    SplitSource,
}

/// The refinement oracles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Oracle {
    /// [HSA91]: refine while the unoccluded form factor exceeds `ff_eps`.
    Ff,
    /// Brightness-weighted (SPLASH-2): ρ_r B_s (V F_err + V_err F + V_err F_err)
    /// against `bf_eps` × the mean emitted exitance.
    Bf,
    /// [RenderPark] power: A_r F ρ_r B_s against `power_eps` × the largest
    /// patch emitted power.
    Power,
}

impl Oracle {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Oracle::Ff => "ff",
            Oracle::Bf => "bf",
            Oracle::Power => "power",
        }
    }
}

/// The oracle's thresholds, already scaled to the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    pub oracle: Oracle,
    /// Absolute form-factor threshold (ff).
    pub ff_eps: f64,
    /// Absolute radiosity threshold, W/m² (bf).
    pub bf_eps: f64,
    /// Absolute power threshold, W (power).
    pub power_eps: f64,
    /// Elements at or below this area (m²) are never split.
    pub min_area: f64,
    /// Visibility rays per link (V_err = 1/rays for an unoccluded link).
    pub rays: usize,
}

/// The oracle's error measure for a link (in the unit of its threshold) and
/// the threshold.
pub fn link_error(
    t: &Thresholds,
    link: &Link,
    receiver_area: f64,
    receiver_reflectance: DVec3,
    source_radiosity: DVec3,
) -> (f64, f64) {
    let f = link.form_factor as f64;
    let v = link.visibility as f64;
    let rho_b = (receiver_reflectance * source_radiosity).max_element();
    match t.oracle {
        Oracle::Ff => (f, t.ff_eps),
        Oracle::Bf => {
            let f_err = link.error as f64;
            let v_err = if v > 0.0 && v < 1.0 {
                1.0
            } else {
                1.0 / t.rays.max(1) as f64
            };
            (rho_b * (v * f_err + v_err * f + v_err * f_err), t.bf_eps)
        }
        Oracle::Power => (receiver_area * f * v * rho_b, t.power_eps),
    }
}

/// True when `link`, whatever its visibility, will be split: the oracles'
/// errors are smallest for a fully occluded link (V = 0), so when even that
/// is rejected, the link needs no visibility rays ([`decide`] at V = 0 is
/// then the decision at any V).
pub fn split_at_any_visibility(
    t: &Thresholds,
    link: &Link,
    receiver: &Element,
    source: &Element,
    receiver_reflectance: DVec3,
) -> bool {
    let occluded = Link {
        visibility: 0.0,
        ..*link
    };
    decide(t, &occluded, receiver, source, receiver_reflectance) != Decision::Accept
}

/// The decision for a link: accept it when its error is within the
/// threshold; otherwise split the larger of the two elements (by area),
/// unless it is at the minimum area, then the other one; accept when both
/// are minimal. Fully occluded and zero links are always accepted.
pub fn decide(
    t: &Thresholds,
    link: &Link,
    receiver: &Element,
    source: &Element,
    receiver_reflectance: DVec3,
) -> Decision {
    if link.form_factor <= 0.0 {
        return Decision::Accept;
    }
    let (error, eps) = link_error(
        t,
        link,
        receiver.area,
        receiver_reflectance,
        source.radiosity,
    );
    if !(error > eps) {
        return Decision::Accept;
    }
    let r_ok = receiver.area > t.min_area;
    let s_ok = source.area > t.min_area;
    match (r_ok, s_ok) {
        (true, true) if receiver.area >= source.area => Decision::SplitReceiver,
        (true, true) => Decision::SplitSource,
        (true, false) => Decision::SplitReceiver,
        (false, true) => Decision::SplitSource,
        (false, false) => Decision::Accept,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_is_sixteen_bytes() {
        assert_eq!(std::mem::size_of::<Link>(), 16);
    }

    #[test]
    fn partly_visible_links_weigh_more() {
        let t = Thresholds {
            oracle: Oracle::Bf,
            ff_eps: 0.0,
            bf_eps: 1.0,
            power_eps: 0.0,
            min_area: 0.0,
            rays: 9,
        };
        let mut l = Link {
            source: ElementId(0),
            form_factor: 0.1,
            visibility: 1.0,
            error: 0.0,
        };
        let (clear, _) = link_error(&t, &l, 1.0, DVec3::splat(0.5), DVec3::splat(10.0));
        l.visibility = 0.5;
        let (shadow, _) = link_error(&t, &l, 1.0, DVec3::splat(0.5), DVec3::splat(10.0));
        assert!((clear - 0.5 * 10.0 * 0.1 / 9.0).abs() < 1e-6, "{clear}");
        assert!((shadow - 0.5 * 10.0 * 0.1).abs() < 1e-6, "{shadow}");
    }
}
