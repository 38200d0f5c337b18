//! Links of hierarchical radiosity \[HSA91\]: element-to-element
//! interactions and their evaluation (form factor, its error, visibility).
//! Whether a link is accurate enough is the oracle's business
//! ([`crate::hierarchical::oracle`]).
//!
//! Owns: [`Link`], [`evaluate_link`], [`weighted_visibility`],
//! [`faces_each_other`].
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
//! inner integral, which is zero behind the source's plane), replaced by
//! the exact value when the points disagree by more than 10 %
//! (`oracle::sharpen`: closed form for aligned rectangles, else adaptive
//! quadrature); F_err = max − min of the point values at those
//! centroids and at the receiver's corners (for elements far apart, where
//! F is near linear over the receiver, twice the centroids' range
//! instead). A source smaller than its receiver is also sampled at its own
//! points (reciprocity): when that gives half as much again, the
//! quadrature over the smaller element decides. Quadratures always run
//! over the smaller element.
//!
//! Visibility: exactly 1 with no ray when no occluder stands in the shaft
//! between the two elements ([`crate::visibility::Shaft`]; the link is
//! then [`Link::unobstructed`], for its receiver's descendants too); else
//! the kernel-weighted unoccluded fraction of N rays between
//! stratified points of the two elements, and its spread over the
//! receiver's quarters (a shadow edge crossing it). N comes from the
//! caller's plan (the oracle's `rays_needed`); a link records its N.
//! Visibility is inherited only as a hint: a link refining a wholly
//! visible one first casts one probe ray per receiver quarter and takes
//! the full set only when a probe is blocked; the error model still
//! counts the full set.

use glam::DVec3;

use crate::formfactor::point_polygon::clip_to_half_space;
use crate::formfactor::rectangles::aligned_rectangles;
use crate::formfactor::{form_factor_point_polygon, form_factor_polygon_polygon_checked};
use crate::hierarchical::hierarchy::{Element, ElementId, split_corners};
use crate::sampling::{PolygonSampler, pair_stream, point_in_polygon, stratified};
use crate::scene::{Scene, polygon_centroid};
use crate::util::geometry::outside_polygon;
use crate::visibility::{Shaft, TriangleBvh};

/// One interaction, kept in its receiver's list (20 bytes).
///
/// It holds two readings of its visible fraction: the one the oracle
/// decided on, which every later decision uses too, and the one it
/// carries light with, from independent rays when the decision hung on
/// the first. A decision that kept the reading it was made on would
/// select on that reading's noise: links read dark are kept, those read
/// bright are split and read again, so light is lost (§ refine).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Link {
    /// The element gathered from.
    pub source: ElementId,
    /// Unoccluded form factor receiver → source estimate, in [0, 1].
    pub form_factor: f32,
    /// Form-factor error estimate F_err (spread of the point values).
    pub error: f32,
    /// Visible fraction in [0, 1] the oracle decides on, fixed point (0
    /// and 1 exact).
    visibility: u16,
    /// Visible fraction in [0, 1] the link carries light with, fixed
    /// point.
    carried: u16,
    /// How the rays of the carried reading that got through spread over
    /// the source's four quarters (its children, or the children a split
    /// will give it): four nibbles, each quarter's kernel-weighted share in
    /// 15ths of the largest; 0 when not recorded (see [`Link::seen_shares`]).
    seen: u16,
    /// Spread of the visible fraction over the receiver's four quarters
    /// (max − min), fixed point rounded up: how much a shadow edge crossing
    /// the receiver varies this link's light over it.
    spread: u8,
    /// Visibility rays per receiver quarter the estimate stands for (0: no
    /// visibility was sampled), and in the top bit [`UNOBSTRUCTED`].
    quarter_rays: u8,
}

/// Set in [`Link`]'s `quarter_rays` when nothing stands in the shaft
/// between receiver and source: every point of the receiver, and of its
/// descendants, sees the source whole.
const UNOBSTRUCTED: u8 = 0x80;

fn to_fixed(x: f64) -> u16 {
    (x.clamp(0.0, 1.0) * f64::from(u16::MAX)).round() as u16
}

/// Per-quarter weights as four nibbles in 15ths of the largest (0: none).
fn pack_shares(w: Option<[f64; 4]>) -> u16 {
    let Some(w) = w else {
        return 0;
    };
    let top = w.iter().copied().fold(0.0, f64::max);
    if !(top > 0.0) || !top.is_finite() {
        return 0;
    }
    w.iter().enumerate().fold(0u16, |acc, (k, x)| {
        acc | (((15.0 * x / top).round().clamp(0.0, 15.0) as u16) << (4 * k))
    })
}

/// One reading of a pair's visibility: the kernel-weighted visible
/// fraction, its spread over the receiver's quarters, and, for a partial
/// reading of the full count of rays, how the rays that got through spread
/// over the source's quarters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// Visible fraction in [0, 1].
    pub visibility: f64,
    /// Its spread over the receiver's quarters.
    pub spread: f64,
    /// Kernel weight of the rays that got through, per source quarter.
    pub seen: Option<[f64; 4]>,
}

/// Most rays per receiver quarter a link records ([`Link::rays`]).
pub const MAX_QUARTER_RAYS: usize = (UNOBSTRUCTED - 1) as usize;

impl Link {
    /// A link with the given values, each clamped to [0, 1] (errors to ≥ 0);
    /// `rays` is the number of visibility rays its visibility stands for
    /// (rounded up to a multiple of 4, at most 4 × [`MAX_QUARTER_RAYS`]).
    pub fn new(
        source: ElementId,
        form_factor: f64,
        error: f64,
        visibility: f64,
        spread: f64,
        rays: usize,
    ) -> Link {
        Link {
            source,
            form_factor: form_factor.clamp(0.0, 1.0) as f32,
            error: error.max(0.0) as f32,
            visibility: to_fixed(visibility),
            carried: to_fixed(visibility),
            seen: 0,
            spread: (spread.clamp(0.0, 1.0) * f64::from(u8::MAX)).ceil() as u8,
            quarter_rays: rays.div_ceil(4).min(MAX_QUARTER_RAYS) as u8,
        }
    }

    /// A wholly visible link whose shaft holds no occluder (see
    /// [`Link::unobstructed`]), standing for `rays` rays.
    pub fn unobstructed_link(source: ElementId, form_factor: f64, error: f64, rays: usize) -> Link {
        let mut link = Link::new(source, form_factor, error, 1.0, 0.0, rays);
        link.quarter_rays |= UNOBSTRUCTED;
        link
    }

    /// True when nothing stands between receiver and source (shaft
    /// culling, not rays): every point of the receiver and of its
    /// descendants sees the source whole.
    pub fn unobstructed(&self) -> bool {
        self.quarter_rays & UNOBSTRUCTED != 0
    }

    /// Visible fraction V in [0, 1] that the oracle decides on.
    pub fn visibility(&self) -> f64 {
        f64::from(self.visibility) / f64::from(u16::MAX)
    }

    /// Visible fraction in [0, 1] that the link carries light with (the
    /// decision's reading unless fresh rays replaced it).
    pub fn carried_visibility(&self) -> f64 {
        f64::from(self.carried) / f64::from(u16::MAX)
    }

    /// Spread of V over the receiver's quarters, in [0, 1].
    pub fn spread(&self) -> f64 {
        f64::from(self.spread) / f64::from(u8::MAX)
    }

    /// Visibility rays the link's V stands for.
    pub fn rays(&self) -> usize {
        4 * (self.quarter_rays & !UNOBSTRUCTED) as usize
    }

    /// True when some but not all visibility rays were blocked.
    pub fn partly_visible(&self) -> bool {
        self.visibility > 0 && self.visibility < u16::MAX
    }

    /// True when no ray was blocked: the link saw its source whole.
    pub fn wholly_visible(&self) -> bool {
        self.visibility == u16::MAX && self.spread == 0
    }

    /// The coupling F·V the gather uses (V the carried reading).
    pub fn coupling(&self) -> f64 {
        self.form_factor as f64 * self.carried_visibility()
    }
}

/// The centroids of `e`'s four quarters and their shares of its area.
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

/// Sums over the rays (x on the receiver, y on the source) of the kernel
/// weight cos θ_x cos θ_y / r², of all rays with both ends in front of the
/// other's plane and of the unblocked ones: their ratio is the
/// kernel-weighted visible fraction.
pub fn weighted_visibility(
    bvh: &TriangleBvh,
    rays: impl Iterator<Item = (DVec3, DVec3)>,
    n_r: DVec3,
    n_s: DVec3,
) -> (f64, f64) {
    let (mut total, mut seen) = (0.0, 0.0);
    for (x, y) in rays {
        let d = y - x;
        let kernel = d.dot(n_r) * -d.dot(n_s) / d.length_squared().powi(2);
        if !(kernel > 0.0) || !kernel.is_finite() {
            continue;
        }
        total += kernel;
        if bvh.visible(x, y) {
            seen += kernel;
        }
    }
    (total, seen)
}

/// What the link a new one refines saw of its source: a hint for the new
/// link's visibility sampling.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Inherited {
    /// Nothing to go on (a first link, a resample, a partly visible
    /// parent): sample fully.
    #[default]
    Nothing,
    /// The refined link saw its source whole: one probe ray per receiver
    /// quarter first (`sample_visibility`).
    WhollyVisible,
    /// Nothing stood between the refined link's ends
    /// ([`Link::unobstructed`]), so nothing stands between any of their
    /// parts: no shaft query, no ray.
    Unobstructed,
    /// The refined link saw its source in part: the new link lies in a
    /// penumbra, where a visibility of exactly 0 or 1 from its own rays is
    /// a selection, not an estimate ([`Evaluator::fresh_visibility`]).
    PartlyVisible,
}

impl Link {
    /// The hint this link leaves to the links that refine it.
    pub fn inherited(&self) -> Inherited {
        if self.unobstructed() {
            Inherited::Unobstructed
        } else if self.wholly_visible() {
            Inherited::WhollyVisible
        } else if self.partly_visible() || self.spread() > 0.0 {
            Inherited::PartlyVisible
        } else {
            Inherited::Nothing
        }
    }

    /// The link carrying light with `reading` (fresh rays'), its
    /// decision's reading unchanged.
    pub fn carrying(&self, reading: &Reading) -> Link {
        if self.unobstructed() {
            // Nothing stands between the two: no reading changes that.
            return *self;
        }
        Link {
            carried: to_fixed(reading.visibility),
            seen: pack_shares(reading.seen),
            ..*self
        }
    }

    /// The source's quarters as the carried reading's rays that got
    /// through saw them (kernel-weighted, in 255ths of the largest), when
    /// they were recorded: only for a partial reading of the full count of
    /// rays. A link whose source is split hands its receiver its children's
    /// radiosities by these shares, not their mean: through the gaps
    /// between slats a wall sees a slat's dim lower edge, not its lit
    /// middle.
    pub fn seen_shares(&self) -> Option<[u8; 4]> {
        (self.seen != 0).then(|| [0, 1, 2, 3].map(|k| ((self.seen >> (4 * k)) & 15) as u8 * 17))
    }
}

impl Reading {
    /// A whole view, known without rays.
    pub const CLEAR: Reading = Reading {
        visibility: 1.0,
        spread: 0.0,
        seen: None,
    };
}

/// Mixed into the seed of [`Evaluator::fresh_visibility`]'s rays, so that
/// they are independent of the rays that decided the link.
const FRESH_TAG: u64 = 0x6672_6573_6876_6973;

/// What link evaluation needs of a solve: the scene, the elements, the
/// occluders and the seed of the visibility rays.
#[derive(Clone, Copy)]
pub struct Evaluator<'a> {
    /// The scene (patch normals).
    pub scene: &'a Scene,
    /// The hierarchy's arena.
    pub elements: &'a [Element],
    /// The occluders.
    pub bvh: &'a TriangleBvh,
    /// Seed of the visibility rays.
    pub seed: u64,
}

impl Evaluator<'_> {
    /// The visible fraction and spread of (receiver `r`, source `s`) from
    /// `rays` rays independent of those [`evaluate_link`] casts, and the
    /// rays cast. For a pair whose evaluation cast rays: its shaft is not
    /// clear, and is not asked again (an unobstructed link needs no fresh
    /// reading). A link accepted because its own rays saw its source wholly
    /// hidden (anywhere) or wholly visible (inside a penumbra) keeps this
    /// value instead: refinement keeps the links whose rays read 0 and
    /// refines the others, so the deciding reading, kept, loses the light
    /// of every partly hidden source that happened to read 0 (and gains
    /// where they read 1); and a link read as dark is dropped for good.
    pub fn fresh_visibility(&self, r: ElementId, s: ElementId, rays: usize) -> (Reading, u64) {
        let (re, se) = (&self.elements[r.index()], &self.elements[s.index()]);
        let mut rng = pair_stream(self.seed ^ FRESH_TAG, r.0, s.0);
        let rays = rays.clamp(1, 4 * MAX_QUARTER_RAYS);
        sample_visibility(
            self.scene,
            re,
            se,
            self.bvh,
            rays,
            Inherited::Nothing,
            &mut rng,
        )
    }

    /// [`evaluate_link`] of (receiver `r`, source `s`).
    pub fn evaluate(
        &self,
        r: ElementId,
        s: ElementId,
        inherited: Inherited,
        plan: impl Fn(&Link) -> usize,
    ) -> (Link, u64) {
        evaluate_link(self, r, s, inherited, plan)
    }
}

/// Evaluates the link (receiver `r_id`, source `s_id`): its form factor
/// and error, then its visibility with the number of rays `plan` asks for
/// given the unoccluded link (0: none, when the unoccluded link already
/// decides; its visibility stays 0). Visibility rays: the plan rounded up
/// to a multiple of 4, a quarter of them from each of the receiver's four
/// quarters (its virtual children, at the same relative points) to the
/// same stratified source points (so quarters differ only by where they
/// are: the spread measures a shadow edge, not sampling noise), each ray
/// weighted by the kernel cos θ_x cos θ_y / r², so that both the
/// kernel-weighted visible fraction and its spread over the receiver are
/// known. When the link this one refines saw its source whole
/// ([`Inherited::WhollyVisible`]), one ray per quarter probes first, and
/// the link is wholly visible when none is blocked (`sample_visibility`).
/// Returns the link and the rays cast.
pub fn evaluate_link(
    at: &Evaluator,
    r_id: ElementId,
    s_id: ElementId,
    inherited: Inherited,
    plan: impl Fn(&Link) -> usize,
) -> (Link, u64) {
    let Evaluator {
        scene,
        elements,
        bvh,
        seed,
    } = *at;
    let r = &elements[r_id.index()];
    let s = &elements[s_id.index()];
    let n_r = scene.patches[r.patch as usize].normal;
    let n_s = scene.patches[s.patch as usize].normal;
    // The contour integral does not know which side of the source emits:
    // a point behind the source's plane gets nothing.
    let point_ff = |x: DVec3| {
        if (x - s.corners[0]).dot(n_s) > 0.0 {
            form_factor_point_polygon(x, n_r, s.vertices())
        } else {
            0.0
        }
    };
    let (pts, w) = receiver_points(r);
    let mut f = 0.0;
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for (x, wk) in pts.iter().zip(w) {
        let v = point_ff(*x);
        f += wk * v;
        lo = lo.min(v);
        hi = hi.max(v);
    }
    // The extremes of F over the receiver are often at its corners (next
    // to a shared edge F → 0 for far parts of the source): include them in
    // the spread. Far apart, F is near linear over the receiver and its
    // range at the corners is twice that at the quarter centroids.
    if far_apart(r, n_r, s, n_s) {
        hi = lo + 2.0 * (hi - lo);
    } else {
        for x in r.vertices() {
            let v = point_ff(*x);
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    // Every quarter centroid behind the source's plane while a corner sees
    // it: the midpoint rule says 0 for a pair that does exchange light (a
    // floor around the base of a box, beside a face that leans away). The
    // quadrature decides.
    if !(f > 0.0) && hi > 0.0 {
        f = exact_form_factor(r, n_r, s, n_s, 0.01 * hi, None).unwrap_or(0.0);
    }
    // A source smaller than its receiver, in area or in extent, or only
    // partly in front of it: the receiver's points may all lie far from
    // where its light falls (a small lamp next to a wall; a slat 12 m long
    // that cuts into a wall, whose face next to the wall takes a seventh of
    // the light of the wall's strip above the joint, between the slat's
    // quarter centroids and behind the wall's). By reciprocity, F_rs =
    // (A_s / A_r) F_sr with F_sr from points of the source's part in front
    // of the receiver. When those see half as much again (the receiver's
    // points missed a peak), the quadrature over the source decides, and
    // the receiver's F varies at least as much as the two differ.
    let mut spread = hi - lo;
    let mut front = [DVec3::ZERO; 5];
    let k = clip_to_half_space(r.corners[0], n_r, s.vertices(), &mut front);
    let front_area = if k >= 3 {
        crate::scene::polygon_area_normal(&front[..k]).0
    } else {
        0.0
    };
    let clipped = front_area < (1.0 - 1e-6) * s.area;
    if front_area > 0.0 && (s.area < r.area || radius(s) < radius(r) || clipped) {
        let sampler = PolygonSampler::new(&front[..k]);
        let f_sr: f64 = [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
            .map(|(u, v)| sampler.point(glam::DVec2::new(u, v)))
            .iter()
            .filter(|y| (**y - r.corners[0]).dot(n_r) > 0.0)
            .map(|y| 0.25 * form_factor_point_polygon(*y, n_s, r.vertices()))
            .sum::<f64>()
            * (front_area / s.area);
        let f_rec = s.area / r.area * f_sr;
        if f_rec > 1.5 * f {
            let tol = 0.01 * f_rec;
            let exact = exact_form_factor(r, n_r, s, n_s, tol, None).unwrap_or(f_rec);
            spread = spread.max((exact - f).abs());
            f = exact;
        }
    }
    let link = Link::new(s_id, f, spread, 0.0, 0.0, 0);
    let rays = if f > 0.0 { plan(&link) } else { 0 };
    if rays == 0 {
        return (link, 0);
    }
    let rays = rays.min(4 * MAX_QUARTER_RAYS);
    if inherited == Inherited::Unobstructed || unobstructed(scene, r, s, bvh) {
        return (Link::unobstructed_link(s_id, f, spread, rays), 0);
    }
    let mut rng = pair_stream(seed, r_id.0, s_id.0);
    let (reading, cast) = sample_visibility(scene, r, s, bvh, rays, inherited, &mut rng);
    let link = Link::new(s_id, f, spread, reading.visibility, reading.spread, rays);
    (link.carrying(&reading), cast)
}

/// True when no occluder stands in the shaft between elements `r` and `s`
/// (their hull, cut by the front of each): every ray between them passes.
pub(crate) fn unobstructed(scene: &Scene, r: &Element, s: &Element, bvh: &TriangleBvh) -> bool {
    let n_r = scene.patches[r.patch as usize].normal;
    let n_s = scene.patches[s.patch as usize].normal;
    let fronts = [(r.corners[0], n_r), (s.corners[0], n_s)];
    Shaft::new(r.vertices(), s.vertices(), &fronts).is_some_and(|sh| bvh.shaft_clear(&sh))
}

/// The radius of the smallest sphere about `e`'s centroid that holds it.
fn radius(e: &Element) -> f64 {
    let c = e.centroid();
    e.vertices()
        .iter()
        .map(|p| (*p - c).length_squared())
        .fold(0.0, f64::max)
        .sqrt()
}

/// Centres at least this many times the sum of the two elements' radii
/// apart count as far ([`far_apart`]).
const FAR_FIELD: f64 = 4.0;

/// True when elements `r` and `s` are far apart for the form factor: their
/// centres at least [`FAR_FIELD`] times the sum of their radii apart, and
/// each wholly in front of the other's plane (no clipping).
pub(crate) fn far_apart(r: &Element, n_r: DVec3, s: &Element, n_s: DVec3) -> bool {
    let (c_r, c_s) = (r.centroid(), s.centroid());
    let (rad_r, rad_s) = (radius(r), radius(s));
    (c_s - c_r).length() >= FAR_FIELD * (rad_r + rad_s)
        && (c_r - c_s).dot(n_s) > rad_r
        && (c_s - c_r).dot(n_r) > rad_s
}

/// The kernel-weighted visible fraction of `s` from `r` and its spread
/// over `r`'s quarters (see [`evaluate_link`]), and the rays cast.
///
/// With [`Inherited::WhollyVisible`], one ray per quarter goes first, from strata spread over
/// the sample pattern; when none is blocked the pair is taken as wholly
/// visible, its V standing for all `rays`. Used for the children of a
/// wholly visible link, whose ray pairs are a subset of the pairs its
/// parent's rays sampled: a probe that finds a blocker falls back to the
/// full set. With one ray per quarter the probe is the full set.
fn sample_visibility(
    scene: &Scene,
    r: &Element,
    s: &Element,
    bvh: &TriangleBvh,
    rays: usize,
    inherited: Inherited,
    rng: &mut impl rand::Rng,
) -> (Reading, u64) {
    let n_r = scene.patches[r.patch as usize].normal;
    let n_s = scene.patches[s.patch as usize].normal;
    let per_quarter = rays.max(1).div_ceil(4);
    let total = 4 * per_quarter;
    let from = stratified(per_quarter, rng);
    let mut to = stratified(per_quarter, rng);
    use rand::seq::SliceRandom;
    to.shuffle(rng);
    let source = PolygonSampler::new(s.vertices());
    let targets: Vec<DVec3> = to.iter().map(|b| source.point(*b)).collect();
    let quarters = split_corners(r.shape, &r.corners);
    let n = r.vertices().len();
    let mut probed = 0;
    if inherited == Inherited::WhollyVisible && per_quarter > 1 {
        let clear = quarters.iter().enumerate().all(|(k, quarter)| {
            let j = k * per_quarter / 4;
            let x = point_in_polygon(&quarter[..n], from[j]);
            let (w, seen) = weighted_visibility(bvh, std::iter::once((x, targets[j])), n_r, n_s);
            seen == w
        });
        probed = 4;
        if clear {
            return (Reading::CLEAR, probed);
        }
    }
    // Per receiver quarter, the kernel-weighted visibility sums: V (their
    // ratio over all quarters) is what scales the unoccluded form factor.
    // The rays that got through are kept (target, kernel) for the shares
    // of the source's quarters, needed only when the reading is partial.
    let mut passed: Vec<(usize, f64)> = Vec::new();
    let sums = quarters.map(|quarter| {
        let sampler = PolygonSampler::new(&quarter[..n]);
        let (mut total, mut seen) = (0.0, 0.0);
        for (j, (a, y)) in from.iter().zip(&targets).enumerate() {
            let x = sampler.point(*a);
            let d = *y - x;
            let kernel = d.dot(n_r) * -d.dot(n_s) / d.length_squared().powi(2);
            if !(kernel > 0.0) || !kernel.is_finite() {
                continue;
            }
            total += kernel;
            if bvh.visible(x, *y) {
                seen += kernel;
                passed.push((j, kernel));
            }
        }
        (total, seen)
    });
    let (weight, seen) = (sums.map(|q| q.0), sums.map(|q| q.1));
    let counted: f64 = weight.iter().sum();
    if !(counted > 0.0) {
        // Every ray joined points that do not face each other: the pair
        // faces only in part. Its visibility comes from the parts that do.
        let (v, cast) = facing_visibility(r, n_r, s, n_s, bvh, total, rng);
        let reading = Reading {
            visibility: v,
            spread: 0.0,
            seen: None,
        };
        return (reading, probed + total as u64 + cast);
    }
    let v = seen.iter().sum::<f64>() / counted;
    let (min, max) = (0..4)
        .filter(|&k| weight[k] > 0.0)
        .map(|k| seen[k] / weight[k])
        .fold((1.0f64, 0.0f64), |(lo, hi), q| (lo.min(q), hi.max(q)));
    let spread = (max - min).max(0.0);
    // Shares only from a partial reading of more than a few rays: a whole
    // one sees the quarters as the form factor does, and four rays, one
    // per receiver quarter, say little about the source's.
    let partial = v > 0.0 && v < 1.0 && per_quarter > 1;
    let reading = Reading {
        visibility: v,
        spread,
        seen: partial.then(|| source_shares(s, n_s, &targets, &passed)),
    };
    (reading, probed + total as u64)
}

/// The kernel weight of the rays that got through (`passed`: target index
/// and kernel, in the order cast) per quarter of the source `s` (the
/// children a split gives it) that their targets lie in.
fn source_shares(s: &Element, n_s: DVec3, targets: &[DVec3], passed: &[(usize, f64)]) -> [f64; 4] {
    let kids = split_corners(s.shape, &s.corners);
    let m = s.vertices().len();
    let mut quarter_of: Vec<Option<usize>> = vec![None; targets.len()];
    let mut through = [0.0; 4];
    for &(j, kernel) in passed {
        let q = *quarter_of[j].get_or_insert_with(|| {
            // The quarter the target is least outside of (the first of
            // equals).
            let out = [0, 1, 2, 3].map(|k| outside_polygon(&kids[k][..m], n_s, targets[j]));
            (1..4).fold(0, |best, k| {
                if out[k].total_cmp(&out[best]).is_lt() {
                    k
                } else {
                    best
                }
            })
        });
        through[q] += kernel;
    }
    through
}

/// The kernel-weighted visible fraction of `s` from `r` by `rays` rays
/// between the part of each in front of the other's plane (where every ray
/// counts: both cosines are positive), and the rays cast. 0 when either
/// part is empty or no ray counts: such a pair exchanges no light that a
/// ray could confirm, and a visibility of 1 there would carry light
/// through walls (a receiver whose sample points all lie below a source's
/// plane, beside a sealed room).
fn facing_visibility(
    r: &Element,
    n_r: DVec3,
    s: &Element,
    n_s: DVec3,
    bvh: &TriangleBvh,
    rays: usize,
    rng: &mut impl rand::Rng,
) -> (f64, u64) {
    let mut front_r = [DVec3::ZERO; 5];
    let mut front_s = [DVec3::ZERO; 5];
    let kr = clip_to_half_space(s.corners[0], n_s, r.vertices(), &mut front_r);
    let ks = clip_to_half_space(r.corners[0], n_r, s.vertices(), &mut front_s);
    if kr < 3 || ks < 3 {
        return (0.0, 0);
    }
    let (from, to) = (
        PolygonSampler::new(&front_r[..kr]),
        PolygonSampler::new(&front_s[..ks]),
    );
    let a = stratified(rays, rng);
    let mut b = stratified(rays, rng);
    use rand::seq::SliceRandom;
    b.shuffle(rng);
    let pairs = a
        .iter()
        .zip(&b)
        .map(|(a, b)| (from.point(*a), to.point(*b)));
    let (total, seen) = weighted_visibility(bvh, pairs, n_r, n_s);
    let v = if total > 0.0 { seen / total } else { 0.0 };
    (v, rays as u64)
}

/// Integrand evaluations [`exact_form_factor`] may spend on one link.
const SHARPEN_EVALUATIONS: usize = 600;

/// The unoccluded form factor receiver → source (zero behind the far
/// element's plane), in [0, 1]: in closed form for aligned rectangles
/// facing each other or perpendicular ([`aligned_rectangles`]; walls,
/// floors and their elements), else by adaptive quadrature of the exact
/// inner integral to `tolerance`, with `guess` the midpoint rule's value;
/// `None` when the quadrature fails. The outer integral runs over the
/// element of smaller extent (F_rs = (A_s / A_r) F_sr): its points see the
/// other one smoothly, where the other one's points may miss a small
/// source's light altogether (a long strip beside a small patch).
pub(crate) fn exact_form_factor(
    receiver: &Element,
    receiver_normal: DVec3,
    source: &Element,
    source_normal: DVec3,
    tolerance: f64,
    guess: Option<f64>,
) -> Option<f64> {
    if let Some(f) = aligned_rectangles(
        receiver.vertices(),
        receiver_normal,
        source.vertices(),
        source_normal,
    ) {
        return Some(f);
    }
    let (near, far, far_normal, scale) = if radius(source) < radius(receiver) {
        (
            source,
            receiver,
            receiver_normal,
            source.area / receiver.area,
        )
    } else {
        (receiver, source, source_normal, 1.0)
    };
    let exact = form_factor_polygon_polygon_checked(
        near.vertices(),
        far.vertices(),
        tolerance / scale,
        SHARPEN_EVALUATIONS,
        guess.map(|g| g / scale),
        |x| f64::from(u8::from((x - far.corners[0]).dot(far_normal) > 0.0)),
    );
    let value = exact.value * scale;
    value.is_finite().then(|| value.clamp(0.0, 1.0))
}
