//! The refinement oracles of hierarchical radiosity: whether a link is
//! accurate enough, and if not, which end to split; how many visibility
//! rays a link needs; and how closely an accepted link's form factor is
//! integrated.
//!
//! Owns: [`Oracle`], [`Thresholds`], [`Decision`], [`decide`],
//! [`link_error`], [`receiver_threshold`], [`rays_needed`],
//! [`shadow_error`], [`sharpen`].
//!
//! Invariants:
//! - A decision depends only on the link, its two elements, the source's
//!   state and the receiver's (importance-weighted) reflectance and, in
//!   the relative bf mode, the receiver's radiosity.
//! - Thresholds are absolute (already scaled to the scene by the solver);
//!   the relative bf mode scales the brightness threshold per receiver by
//!   [`receiver_threshold`], in (0, 1].
//! - A link's rays never select on their own noise: a link the oracle
//!   accepts whatever its visibility takes [`FEW_RAYS`]; any other takes
//!   the full count, so a decision that hangs on V is made on the full
//!   estimate ([`rays_needed`]); a link whose source brightened past what
//!   its count allows is resampled first ([`Decision::Resample`]).
//!   (Deciding on a 4-ray V lost 3.6 % of the Cornell box's light at the
//!   preview: links whose rays missed a partial shadow were kept, the
//!   rest split.) A 4-ray link that saw nothing is kept, carrying
//!   nothing, until the solve ends, so that resampling covers it too.

use glam::DVec3;

use crate::hierarchical::hierarchy::{Element, SourceState};
use crate::hierarchical::link::{Link, MAX_QUARTER_RAYS, exact_form_factor};
use crate::scene::Scene;

/// Replaces a kept link's 4-point form factor by an adaptive quadrature
/// of the exact inner integral when the point values spread by more than a
/// tenth of it (close or touching elements, where the midpoint rule is
/// biased). The oracle bounds how F varies over the receiver; this makes
/// its mean right, so that energy is conserved over the hierarchy. The
/// quadrature's tolerance comes from [`sharpen_tolerance`], for the
/// receiver's own (unweighted) reflectance.
pub fn sharpen(scene: &Scene, t: &Thresholds, link: &mut Link, ends: &Ends) {
    let (receiver, source) = (ends.receiver, ends.source);
    let t = &Thresholds {
        bf_eps: t.bf_eps * receiver_threshold(t, receiver),
        ..*t
    };
    let patch = |e: &Element| &scene.patches[e.patch as usize];
    let rho = patch(receiver).reflectance;
    let tolerance = sharpen_tolerance(t, link, receiver.area, rho, &ends.state);
    // The exact mean lies within the spread of the point values (nearly:
    // they sample F's extremes): a spread within the tolerance needs
    // nothing.
    let (f, spread) = (link.form_factor as f64, link.error as f64);
    if !(spread > SHARPEN_CAP * f) || !(spread > tolerance) {
        return;
    }
    let (n_r, n_s) = (patch(receiver).normal, patch(source).normal);
    if let Some(exact) = exact_form_factor(receiver, n_r, source, n_s, tolerance, Some(f)) {
        link.form_factor = exact as f32;
    }
}

/// Loosest relative tolerance [`sharpen_tolerance`] gives a link's
/// quadrature: the spread below which [`sharpen`] keeps the midpoint rule.
pub const SHARPEN_CAP: f64 = 0.1;

/// Receivers reflecting less than this count as reflecting this much in
/// the oracles: the light a dark surface absorbs still has to add up. (A
/// black lamp 0.3 m from the lit panel it faces had its link never split,
/// whatever it absorbed: the panel's mean radiosity, a quarter below what
/// its bright middle sends the lamp, lost 14 % of the scene's light.)
pub const RHO_FLOOR: f64 = 0.05;

/// A link's two ends as the oracle sees them: the receiver, its
/// reflectance weighted by its importance, the source, and the source's
/// state. Every decision about a link takes one.
#[derive(Clone, Copy, Debug)]
pub struct Ends<'a> {
    /// The receiving element.
    pub receiver: &'a Element,
    /// ρ of the receiver's patch times its importance weight.
    pub reflectance: DVec3,
    /// The source element.
    pub source: &'a Element,
    /// The source's radiosity and unevenness ([`SourceState`]).
    pub state: SourceState,
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
    /// Keep the pair but sample its visibility again with the rays
    /// [`rays_needed`] asks for (its source got brighter since).
    Resample,
}

/// The refinement oracles.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum Oracle {
    /// Hanrahan, Salzman and Aupperle (1991): refine while the unoccluded form factor exceeds `ff_eps`.
    Ff,
    /// Brightness-weighted (SPLASH-2): ρ_r B_s (V F_err + V_err F + V_err F_err)
    /// against `bf_eps` × the mean emitted exitance.
    Bf,
    /// RenderPark power: A_r F ρ_r B_s against `power_eps` × the largest
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
    /// Which oracle decides.
    pub oracle: Oracle,
    /// Absolute form-factor threshold (ff).
    pub ff_eps: f64,
    /// Absolute radiosity threshold, W/m² (bf).
    pub bf_eps: f64,
    /// bf, relative mode: (floor, M). The threshold for a receiver of
    /// radiosity B_r is `bf_eps` × clamp(B_r / M, floor, 1), B_r the
    /// largest channel ([`receiver_threshold`]). `None`: absolute.
    pub bf_relative: Option<(f64, f64)>,
    /// Absolute power threshold, W (power).
    pub power_eps: f64,
    /// Absolute cluster-link threshold, W/m² ([`crate::hierarchical::cluster`]).
    pub cluster_eps: f64,
    /// Elements at or below this area (m²) are never split.
    pub min_area: f64,
    /// Visibility rays per link at most (V_err = 1/rays for an unoccluded
    /// link); see [`rays_needed`].
    pub rays: usize,
}

impl Thresholds {
    /// The most visibility rays a link gets: `rays` rounded up to a
    /// multiple of 4, at most 4 × [`MAX_QUARTER_RAYS`].
    pub fn max_rays(&self) -> usize {
        4 * self.rays.max(1).div_ceil(4).min(MAX_QUARTER_RAYS)
    }
}

/// Uncertainty of a link's visibility as seen over its receiver: the
/// spread of V over the receiver's quarters (a shadow edge crossing it),
/// plus the sampling error of V (√(V(1−V)/N) when partly visible, 1/N when
/// all N rays agree).
pub fn visibility_error(link: &Link) -> f64 {
    let n = link.rays().max(1) as f64;
    let v = link.visibility();
    let sampling = if link.partly_visible() {
        (v * (1.0 - v) / n).sqrt()
    } else {
        1.0 / n
    };
    link.spread() + sampling
}

/// The error of handing the receiver the source's mean radiosity:
/// ρ_r F V ΔB_s (bf oracle only).
fn source_error(link: &Link, receiver_reflectance: DVec3, source: &SourceState) -> f64 {
    link.form_factor as f64
        * link.visibility()
        * (receiver_reflectance * source.unevenness).max_element()
}

/// Visibility rays for a link whose acceptance does not hang on its
/// visibility ([`rays_needed`]): one per receiver quarter.
pub const FEW_RAYS: usize = 4;

/// The visibility rays `link` (receiver `receiver`, source `source`)
/// needs: [`FEW_RAYS`] when the oracle accepts it whatever its visibility
/// turns out to be (wholly visible with a shadow edge across the receiver
/// and the sampling error of that few rays), else `t.max_rays()`.
///
/// A cheap link's estimate then only has to be unbiased, which a few rays
/// are; a decision that does hang on V is made on the full estimate.
/// Deciding on a noisy V would select on the noise: links whose few rays
/// happened to miss a partial shadow would be kept, the others split, and
/// light would be lost or gained on average. Only the brightness oracle
/// weighs visibility error; the others always take the maximum.
pub fn rays_needed(t: &Thresholds, link: &Link, ends: &Ends) -> usize {
    let (receiver, source) = (ends.receiver, ends.source);
    let most = t.max_rays();
    if t.oracle != Oracle::Bf || most <= FEW_RAYS {
        return most;
    }
    let (f, f_err) = (link.form_factor as f64, link.error as f64);
    let worst = Link::new(link.source, f, f_err, 1.0, 1.0, FEW_RAYS);
    let (error, eps) = link_error(t, &worst, receiver.area, ends.reflectance, &ends.state);
    let eps = eps * receiver_threshold(t, receiver);
    let minimal = !(receiver.area > t.min_area) && !(source.area > t.min_area);
    if error <= eps || minimal {
        FEW_RAYS
    } else {
        most
    }
}

/// The factor on the bf threshold for links into `receiver`: 1, or in the
/// relative mode ([`Thresholds::bf_relative`]) clamp(B_r / M, floor, 1),
/// from the receiver's radiosity as the last solve left it (the solver
/// turns the mode on only after its first solve).
pub fn receiver_threshold(t: &Thresholds, receiver: &Element) -> f64 {
    match (t.oracle, t.bf_relative) {
        (Oracle::Bf, Some((floor, m))) if m > 0.0 => {
            (receiver.radiosity.max_element() / m).clamp(floor, 1.0)
        }
        _ => 1.0,
    }
}

/// The oracle's error measure for a link (in the unit of its threshold) and
/// the threshold.
pub fn link_error(
    t: &Thresholds,
    link: &Link,
    receiver_area: f64,
    receiver_reflectance: DVec3,
    source: &SourceState,
) -> (f64, f64) {
    let f = link.form_factor as f64;
    let v = link.visibility();
    let rho_b = (receiver_reflectance * source.radiosity).max_element();
    match t.oracle {
        Oracle::Ff => (f, t.ff_eps),
        Oracle::Bf => {
            let f_err = link.error as f64;
            let v_err = visibility_error(link);
            let uneven = source_error(link, receiver_reflectance, source);
            (rho_b * (v * f_err + v_err * (f + f_err)) + uneven, t.bf_eps)
        }
        Oracle::Power => (receiver_area * f * v * rho_b, t.power_eps),
    }
}

/// How closely [`sharpen`] integrates a link's form factor: to 1 % of it,
/// or, when looser, to an error in F that moves the oracle's measure by
/// 5 % of its threshold (for the brightness and power oracles, given the
/// source's current radiosity; a source still dark integrates to 1 %), but
/// never looser than [`SHARPEN_CAP`] of F. Dim links spend little. (At 1 %
/// of the threshold the quadratures took a sixth of a default office-10k
/// solve; at 5 % the Cornell box's patch errors moved by less than 0.03
/// points.)
///
/// The cap is what keeps the sum right: the midpoint rule's error has one
/// sign over the many links a receiver may have, so a floor that each link
/// respects adds up. A wall beside 2,304 small emitters, each link far below
/// the threshold, took its light with a 4-point form factor: the
/// many-emitters room absorbed 1.141 of the power it emits at `preview`
/// (0.997 with the cap; the gallery's default solve 4 % slower, the
/// Cornell box's point errors unchanged; BENCHMARKS.md).
pub fn sharpen_tolerance(
    t: &Thresholds,
    link: &Link,
    receiver_area: f64,
    receiver_reflectance: DVec3,
    source: &SourceState,
) -> f64 {
    let relative = 0.01 * link.form_factor as f64;
    let rho_b = (receiver_reflectance * source.radiosity).max_element();
    let (per_unit_f, eps) = match t.oracle {
        Oracle::Ff => (1.0, t.ff_eps),
        Oracle::Bf => (rho_b * link.visibility(), t.bf_eps),
        Oracle::Power => (receiver_area * rho_b * link.visibility(), t.power_eps),
    };
    if per_unit_f > 0.0 && eps > 0.0 {
        relative
            .max(0.05 * eps / per_unit_f)
            .min(SHARPEN_CAP * link.form_factor as f64)
    } else {
        relative
    }
}

/// The part of a link's error that a shadow edge crossing the receiver
/// causes (V's spread over the receiver's quarters), in the unit of the
/// oracle's threshold. Summed over the links from one source patch, it
/// bounds how wrong the receiver's light from that patch is across the
/// receiver, however finely the source was split.
pub fn shadow_error(
    t: &Thresholds,
    link: &Link,
    receiver_area: f64,
    receiver_reflectance: DVec3,
    source_radiosity: DVec3,
) -> f64 {
    let f = link.form_factor as f64;
    let rho_b = (receiver_reflectance * source_radiosity).max_element();
    let spread = link.spread();
    match t.oracle {
        Oracle::Ff => f * spread,
        Oracle::Bf => rho_b * (f + link.error as f64) * spread,
        Oracle::Power => receiver_area * f * rho_b * spread,
    }
}

/// True when `link`, whatever its visibility by `rays` rays, will be split:
/// the oracles' errors are smallest for a fully occluded link (V = 0: no
/// spread, the smallest sampling error), so when even that is rejected,
/// the link needs no visibility rays ([`decide`] at V = 0 is then the
/// decision at any V).
pub fn split_at_any_visibility(t: &Thresholds, link: &Link, ends: &Ends, rays: usize) -> bool {
    let (f, f_err) = (link.form_factor as f64, link.error as f64);
    let occluded = Link::new(link.source, f, f_err, 0.0, 0.0, rays);
    matches!(
        decide(t, &occluded, ends),
        Decision::SplitReceiver | Decision::SplitSource
    )
}

/// The decision for a link: accept it when its error is within the
/// threshold. Otherwise, when a shadow edge crossing the receiver makes up
/// most of the error, split the receiver (splitting the source cannot
/// resolve a shadow on the receiver); when the source's uneven radiosity
/// does, link to its children; else split the larger of the two elements
/// (by area). An element at the minimum area is not split: the
/// other one is, and the link is accepted when both are minimal. Zero
/// links are always accepted. Before any of this, a link whose visibility
/// stands for fewer rays than [`rays_needed`] now asks is resampled (one
/// with no visibility sampled is decided at V = 0 by one ray: a split).
pub fn decide(t: &Thresholds, link: &Link, ends: &Ends) -> Decision {
    if !(link.form_factor > 0.0) {
        return Decision::Accept;
    }
    let rays = link.rays();
    if rays > 0 && rays < rays_needed(t, link, ends) {
        return Decision::Resample;
    }
    let (receiver, source) = (ends.receiver, ends.source);
    let (receiver_reflectance, state) = (ends.reflectance, &ends.state);
    let (error, eps) = link_error(t, link, receiver.area, receiver_reflectance, state);
    let eps = eps * receiver_threshold(t, receiver);
    if !(error > eps) {
        return Decision::Accept;
    }
    let r_ok = receiver.area > t.min_area;
    let s_ok = source.area > t.min_area;
    let shadow = shadow_error(
        t,
        link,
        receiver.area,
        receiver_reflectance,
        source.radiosity,
    );
    let uneven = match t.oracle {
        Oracle::Bf => source_error(link, receiver_reflectance, state),
        _ => 0.0,
    };
    match (r_ok, s_ok) {
        (true, _) if 2.0 * shadow >= error => Decision::SplitReceiver,
        (_, true) if 2.0 * uneven >= error => Decision::SplitSource,
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
    use crate::hierarchical::hierarchy::ElementId;

    #[test]
    fn link_is_twenty_bytes() {
        assert_eq!(std::mem::size_of::<Link>(), 20);
    }

    #[test]
    fn shadow_edges_across_the_receiver_weigh_most() {
        let t = Thresholds {
            oracle: Oracle::Bf,
            ff_eps: 0.0,
            bf_eps: 1.0,
            bf_relative: None,
            power_eps: 0.0,
            cluster_eps: 0.0,
            min_area: 0.0,
            rays: 16,
        };
        let err = |v: f64, spread: f64| {
            let l = Link::new(ElementId(0), 0.1, 0.0, v, spread, 16);
            let source = SourceState {
                radiosity: DVec3::splat(10.0),
                unevenness: DVec3::ZERO,
            };
            link_error(&t, &l, 1.0, DVec3::splat(0.5), &source).0
        };
        let rho_b_f = 0.5 * 10.0 * 0.1;
        assert!((err(1.0, 0.0) - rho_b_f / 16.0).abs() < 1e-6);
        assert!((err(0.0, 0.0) - rho_b_f / 16.0).abs() < 1e-6);
        // Half the source hidden alike from the whole receiver: sampling
        // error only; a shadow edge across the receiver: its spread too.
        assert!((err(0.5, 0.0) - rho_b_f * 0.125).abs() < 1e-6);
        assert!((err(0.5, 1.0) - rho_b_f * 1.125).abs() < 1e-4);
    }

    #[test]
    fn a_dim_link_is_sharpened_to_a_tenth_of_its_form_factor_at_most() {
        let t = Thresholds {
            oracle: Oracle::Bf,
            ff_eps: 0.0,
            bf_eps: 0.2,
            bf_relative: None,
            power_eps: 0.0,
            cluster_eps: 0.0,
            min_area: 0.0,
            rays: 16,
        };
        let source = SourceState {
            radiosity: DVec3::splat(6.0),
            unevenness: DVec3::ZERO,
        };
        let tol = |f: f64| {
            let l = Link::new(ElementId(0), f, 0.0, 1.0, 0.0, 16);
            sharpen_tolerance(&t, &l, 1.0, DVec3::splat(0.7), &source)
        };
        // A bright link: 1 % of F. A dim one: the threshold's share, which
        // for a link to one of many small sources (F = 10⁻⁴) would exceed
        // F itself; the cap holds it to a tenth.
        assert!((tol(0.5) - 0.005).abs() < 1e-12);
        let floor = 0.05 * 0.2 / (0.7 * 6.0);
        assert!((tol(0.1) - floor).abs() < 1e-12);
        assert!((tol(1e-4) - SHARPEN_CAP * 1e-4).abs() < 1e-12);
    }
}
