//! The area-sampling kernel (the lecture's "Method 2"), adaptive: receiver
//! points where the integrand needs them, and at each point the source cut
//! into pieces dA_j, one visibility ray per piece, summing the pieces'
//! point-to-area factors.
//!
//! Owns: [`form_factor_area_sampling`], its refinement rules and its error
//! estimate.
//!
//! The receiver. F_ij = (1/A_i) ∫_{A_i} Σ_k F(x → S_k) V_k dA_x, with S_k
//! the source's pieces and F(x → S_k) the exact point-to-piece factor
//! ([`form_factor_point_polygon`]).
//! - Each polygon is first clipped to the half-space in front of the
//!   other's plane, so no cut crosses the integrand.
//! - The receiver is cut into triangles (its fan, slivers bisected, then
//!   midpoint quarters). Each triangle is read at its centroid and
//!   compared with its four quarters' readings; the triangle with the
//!   largest error estimate is split next, so receiver points crowd where
//!   the integrand changes fastest (a shared edge, a nearly touching
//!   source, a shadow's edge).
//! - Its error estimate: the deterministic part |coarse − fine| of the
//!   unoccluded sums (or, nearer the source than the triangle is wide,
//!   its area times the spread of its five point factors); the random
//!   part, in quadrature, the readings' own variances plus what the
//!   coarse-against-fine difference of the lost light says beyond them.
//!
//! The source, while nothing occludes, is one piece and one ray: 16 probe
//! rays between stratified points decide, and a pass that meets a blocked
//! ray after all starts again in cells. A pair whose n rays all got
//! through states F / n for an occluder they all missed (one hiding a
//! fraction p escapes with probability (1 − p)ⁿ < e^(−pn)) and casts more
//! probe rays while that is the larger part of its error.
//!
//! The source of an occluded pair is read at each receiver point in cells
//! (`PointView`): a conforming triangulation refined by longest-edge
//! bisection, so that no cell is much larger than its neighbours along a
//! shadow's edge (without it, a round shadow bulging into coarse settled
//! cells left a bias that refinement did not remove: −1.06 % with 0.42 %
//! stated through a round hole).
//! - A cell whose corners and centroid agree is settled (its exact factor,
//!   or nothing); one whose points disagree is mixed, and the mixed cell
//!   with the largest factor is halved while their variance bound Σ f² / 4
//!   is above the reading's target. Corner rays are shared by point.
//! - Rounds of check rays go to the settled cells (drawn by factor); a
//!   contradicted cell becomes mixed. A final round corrects the settled
//!   verdicts without bias, each ray adding (V − verdict) × kernel × area
//!   / f; each mixed cell left casts one ray weighed by the kernel at its
//!   end times the cell's area (a cell's factor times its ray weighs it by
//!   area, 1 % off at grazing angles).
//! - Witnesses: the source points where any reading's random rays found a
//!   verdict wrong (the latest [`WITNESSES`]) get a ray from every later
//!   reading before its checks. A shadow smaller than a start cell is then
//!   found once for all nearby points; before, most readings missed it and
//!   a few corrected for it with a heavy weight (behind a disc at r/h 4 and
//!   10⁻³: 1.3 million rays a factor and 6 of 20 seeds outside twice the
//!   stated error; with witnesses 11,600 rays and 0 of 20).
//! - What every check ray missed is bounded once for the whole receiver,
//!   pooled: Σ S / Σ n over the readings (settled factor, check rays).
//! - A reading's target is [`READING_SHARE`] × tolerance × √(receiver area
//!   / its triangle's area), relative to the larger of its value and the
//!   factor so far: the readings' noise then averages out over the
//!   receiver, and a point in deep shadow is not resolved beside its own
//!   tiny value.
//! - The receiver's refinement is steered only by what each reading
//!   decided before its random rays (the seen cells plus half the mixed,
//!   and their variance bound). Steered by the random outcomes, pieces
//!   whose rays found a shadow were split and their readings replaced,
//!   while pieces whose rays missed it stayed: +0.27 % mean bias at r/h 4,
//!   10⁻³, over 20 seeds (before witnesses); steered by the decisions,
//!   +0.013 %.
//! - Check rays per reading are in proportion to its share of the
//!   receiver (the target above times the spread once more), so the
//!   receiver's check rays total about the same however finely it is cut:
//!   the pooled bound needs no more. Sized per reading alone, a furnace
//!   box's matrix at 10⁻³ cast 19.9 million rays and 38 touching pairs
//!   stopped at the in-scene ray budget 6–11 times over their tolerance
//!   (one spurious blocked ray sends a pair to cells).
//!
//! Measured (`NUSSELT_SLOW_TESTS=1 cargo test --release --test tests
//! area_sampling -- --nocapture`; true / stated relative error, rays a
//! factor). 200 random placements without occluders: all covered, worst
//! 0.47. With a plate between: 200 of 200 covered, worst 0.96, 209,000
//! rays a factor (one random ray per piece before: 196, worst 6.2, 109,000
//! rays); 2000 placements: 1999 covered, worst 2.64. A point against a
//! disc at 10⁻³, five aspect ratios: behind an opaque disc 0.7–1.7 × 10⁻⁴ true in
//! 10,000–98,000 rays, through a round hole 0.3–2.7 × 10⁻⁴ in
//! 97,000–611,000 rays (one ray per piece missed 0.1 % within
//! [`MAX_RAYS`]). Weak: a strip plate between two unit squares at 10⁻³
//! stops at `MAX_RAYS`, 5.5 × 10⁻⁴ off with 2.9 × 10⁻³ stated: the
//! unoccluded sums' |coarse − fine| dominates, as each reading costs tens
//! of rays and the receiver stays coarse.
//!
//! Invariants: the value is finite and in [0, 1] (touching and coplanar
//! polygons included); the error is finite and non-negative; a given random
//! stream gives the same result (refinement is serial, in a fixed order).

use std::collections::{BinaryHeap, HashMap};

use glam::{DVec2, DVec3};
use rand::Rng;

use super::point_polygon::clip_to_half_space;
use super::{Estimate, Ranked, form_factor_point_polygon};
use crate::sampling::{PolygonSampler, point_in_polygon, stratified};
use crate::util::geometry::{outside_polygon, segment_distance};

/// Factors below this are resolved to `tolerance` × this, absolutely: a
/// relative tolerance on a vanishing factor would cost without bound.
pub const ABSOLUTE_FLOOR: f64 = 1e-3;

/// Rays between stratified points of the two polygons that decide whether
/// anything occludes them at all.
pub const PROBE_RAYS: usize = 16;

/// The fewest source cells an occluded reading starts from (a quad's fan:
/// 2). More would cost corner rays at every receiver point (8 made a
/// furnace box's matrix cast 10.4 million rays instead of 7.6); a shadow
/// inside a start cell is found by check rays and witnesses.
pub const START_CELLS: usize = 2;

/// The most times a start cell is halved at one receiver point (its
/// finest cells are 2⁻²⁴ of it).
pub const MAX_CELL_DEPTH: u32 = 24;

/// An occluded reading's mixed cells may leave a standard deviation of
/// this fraction of the tolerance (times the receiver's spread, relative
/// to the larger of its value and the factor so far), and its check rounds
/// are sized by the same target.
pub const READING_SHARE: f64 = 0.3;

/// An occluded reading's check rounds grow fourfold from
/// [`FIRST_CHECK_ROUND`] up to this many times S / its target (S the
/// settled cells' factor); a round that contradicts at most one cell ends
/// them (what all check rays missed is bounded once, pooled over the
/// receiver).
pub const CHECK_ROUND: f64 = 2.0;

/// The most check rays in a reading's first round.
pub const FIRST_CHECK_ROUND: usize = 64;

/// How many of the latest witnesses (source points where a reading's
/// random rays found a cell's verdict wrong) later readings cast a ray to.
pub const WITNESSES: usize = 32;

/// The default relative tolerance of `--sampling-tolerance`.
pub const DEFAULT_TOLERANCE: f64 = 0.01;

/// The most rays one form factor may cast by default: enough for a 10⁻⁴
/// tolerance on two touching unit squares.
pub const MAX_RAYS: usize = 2_000_000;

/// A receiver triangle split into its four midpoint quarters, with their
/// readings; ranked by `bias + noise`.
struct Piece {
    children: [[DVec3; 3]; 4],
    readings: [Reading; 4],
    /// The deterministic part of its error: |own − Σ quarters| of the
    /// unoccluded sums, or in the near field (the source closer than the
    /// triangle is wide) its area times their spread, whichever is larger.
    bias: f64,
    /// The random part: the same difference of what occlusion took away,
    /// or the quarters' own standard deviation if larger (independent
    /// between pieces, so summed in quadrature).
    noise: f64,
    /// The same from what the readings decided before their random rays
    /// ([`Reading::expected`]): the piece's rank.
    key_noise: f64,
}

impl Piece {
    fn value(&self) -> f64 {
        self.readings.iter().map(|r| r.value).sum()
    }

    fn ranked(self) -> Ranked<Piece> {
        Ranked {
            key: self.bias + self.key_noise,
            item: self,
        }
    }
}

/// One receiver point's sums, times its triangle's area: Σ_k F(x → S_k)
/// V_k (`value`) and Σ_k F(x → S_k) (`open`, as if nothing occluded), the
/// variance the value may have (times the area squared), and whether any
/// ray was blocked.
#[derive(Clone, Copy, Debug, Default)]
struct Reading {
    value: f64,
    open: f64,
    variance: f64,
    /// The settled cells' factor (times the area), and the check rays
    /// that found nothing wrong in them.
    settled: f64,
    checks: f64,
    blocked: bool,
    /// What the reading decided before its random rays: the seen cells'
    /// factor plus half the mixed ones', and the variance its mixed cells
    /// may leave. The receiver's refinement is steered by these alone: a
    /// piece split because its random rays found a shadow would leave
    /// behind the pieces whose rays missed it, a bias towards light.
    expected: f64,
    predicted: f64,
}

/// Running sums over the pieces: value, bias, noise².
#[derive(Clone, Copy, Default)]
struct Totals {
    value: f64,
    bias: f64,
    noise2: f64,
    settled: f64,
    checks: f64,
}

impl Totals {
    fn add(&mut self, p: &Piece, sign: f64) {
        self.value += sign * p.value();
        self.bias += sign * p.bias;
        self.noise2 += sign * p.noise * p.noise;
        for r in &p.readings {
            self.settled += sign * r.settled;
            self.checks += sign * r.checks;
        }
    }

    /// The pooled bound on what every reading's check rays missed: an
    /// occluder (or opening) no check ray met, hiding a fraction p of the
    /// settled factor everywhere, escapes N rays with probability < e^(−pN).
    fn unseen(&self) -> f64 {
        match self.checks >= 1.0 {
            true => self.settled / self.checks,
            false => self.settled,
        }
    }

    fn error(&self) -> f64 {
        self.bias + self.noise2.max(0.0).sqrt() + self.unseen()
    }

    fn of(heap: &BinaryHeap<Ranked<Piece>>) -> Totals {
        let mut t = Totals::default();
        for p in heap {
            t.add(&p.item, 1.0);
        }
        t
    }
}

/// A polygon cut into triangles for an occluded reading to start from:
/// a triangle or quad into its fan, a polygon of more sides into the fan
/// from its centroid (a fan from a corner would be slivers).
fn start_cells(polygon: &[DVec3]) -> Vec<[DVec3; 3]> {
    let n = polygon.len();
    let cells: Vec<[DVec3; 3]> = match n {
        0..=4 => (1..n - 1)
            .map(|k| [polygon[0], polygon[k], polygon[k + 1]])
            .collect(),
        _ => {
            let c = polygon.iter().sum::<DVec3>() / n as f64;
            (0..n)
                .map(|k| [c, polygon[k], polygon[(k + 1) % n]])
                .collect()
        }
    };
    cells
        .into_iter()
        .filter(|t| triangle_area(t) > 0.0)
        .collect()
}

/// A triangle's two halves across the midpoint of its longest edge, both
/// with its winding: repeated halving keeps triangles from becoming
/// slivers, and a sliver becomes well shaped.
fn halves(t: &[DVec3; 3]) -> [[DVec3; 3]; 2] {
    let k = longest_edge(t);
    let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
    let m = 0.5 * (a + b);
    [[a, m, c], [m, b, c]]
}

/// A triangle's four midpoint quarters.
fn quarters(t: &[DVec3; 3]) -> [[DVec3; 3]; 4] {
    let [a, b, c] = *t;
    let (ab, bc, ca) = (0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a));
    [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
}

fn triangle_area(t: &[DVec3; 3]) -> f64 {
    0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()
}

/// Adaptive area-sampling form factor F_ij from `receiver` to `source`
/// (convex planar polygons, counter-clockwise from their fronts), to a
/// relative `tolerance` with an absolute floor of `tolerance` ×
/// [`ABSOLUTE_FLOOR`], casting at most about `max_rays` rays through
/// `visible(x, y)`. See the module doc for the algorithm; the result's
/// `error` is the estimated absolute error and `evaluations` the rays cast.
///
/// ```
/// use glam::DVec3;
/// use nusselt::formfactor::form_factor_area_sampling;
/// use nusselt::formfactor::closed_form::c14;
/// // Two unit squares at a right angle sharing an edge (Howell C-14).
/// let floor = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
/// let wall = [DVec3::ZERO, DVec3::Z, DVec3::new(1.0, 0.0, 1.0), DVec3::X];
/// let mut rng = nusselt::sampling::stream(0, 0);
/// let f = form_factor_area_sampling(&floor, &wall, 1e-3, 1_000_000, &mut rng, |_, _| true);
/// assert!((f.value - c14(1.0, 1.0, 1.0)).abs() < 2e-4);
/// assert!(f.error < 1e-3 * f.value);
/// ```
pub fn form_factor_area_sampling(
    receiver: &[DVec3],
    source: &[DVec3],
    tolerance: f64,
    max_rays: usize,
    rng: &mut impl Rng,
    visible: impl Fn(DVec3, DVec3) -> bool,
) -> Estimate {
    let (area, n_r) = crate::scene::polygon_area_normal(receiver);
    let (source_area, n_s) = crate::scene::polygon_area_normal(source);
    if receiver.len() < 3 || source.len() < 3 || !(area > 0.0 && source_area > 0.0) {
        return Estimate::default();
    }
    // Only the part of each in front of the other exchanges light: the
    // receiver's points behind the source's plane see nothing of its
    // front, and the source's part behind the receiver's plane is hidden
    // from every receiver point. Clipping both once leaves an integrand
    // with no cut across the receiver.
    let front = |polygon: &[DVec3], of: &[DVec3], n: DVec3| {
        let mut out = vec![DVec3::ZERO; polygon.len() + 1];
        let k = clip_to_half_space(crate::scene::polygon_centroid(of), n, polygon, &mut out);
        out.truncate(k);
        out.dedup();
        if out.len() > 1 && out.first() == out.last() {
            out.pop();
        }
        out
    };
    let receiver_front = front(receiver, source, n_s);
    let source_front = front(source, receiver, n_r);
    if receiver_front.len() < 3 || source_front.len() < 3 {
        return Estimate::default();
    }
    let mut cells = start_cells(&source_front);
    while !cells.is_empty() && cells.len() < START_CELLS {
        cells = cells.iter().flat_map(halves).collect();
    }
    let mut s = Sampler {
        n_r,
        n_s,
        source: &source_front,
        cells,
        visible,
        rays: 0,
        blocked: false,
        receiver_area: area,
        tolerance,
        max_rays,
        scale: 0.0,
        witnesses: Vec::new(),
        next_witness: 0,
    };
    // Visibility from a point is read by one ray to the whole source only
    // while nothing occludes: one ray to a uniform point weighs the source
    // by area, not by its point factor, which biases a partial reading.
    // So a pair with any occlusion (seen by the probe, or by any ray of a
    // first pass, which then starts again) reads its source in cells.
    let mut occluded = s.probe(&receiver_front, PROBE_RAYS, rng);
    let mut totals = s.refine(&receiver_front, occluded, rng);
    if !occluded && s.blocked {
        occluded = true;
        totals = s.refine(&receiver_front, occluded, rng);
    }
    let (value, error) = (totals.value / area, totals.error() / area);
    if !(value.is_finite() && error.is_finite()) {
        return Estimate::default();
    }
    Estimate {
        value: value.clamp(0.0, 1.0),
        error,
        evaluations: s.rays,
    }
}

/// Most generations of longest-edge bisection of one fan triangle before
/// refinement starts (64 triangles at most).
const MAX_BISECTIONS: u32 = 6;

/// A polygon's fan triangles, each bisected across its longest edge
/// until that edge's square is at most 4.5 times the area (a right
/// isosceles triangle is 4), for [`MAX_BISECTIONS`] generations at most:
/// midpoint quarters keep a triangle's shape, so a sliver would stay one,
/// and its centroid would speak for points far away along it. Degenerate
/// triangles are dropped.
fn well_shaped(polygon: &[DVec3]) -> Vec<[DVec3; 3]> {
    let mut todo: Vec<([DVec3; 3], u32)> = (1..polygon.len() - 1)
        .rev()
        .map(|k| ([polygon[0], polygon[k], polygon[k + 1]], 0))
        .collect();
    let mut done = Vec::new();
    while let Some((t, generation)) = todo.pop() {
        let edges = [(0, 1, 2), (1, 2, 0), (2, 0, 1)];
        let length = |e: &(usize, usize, usize)| (t[e.1] - t[e.0]).length_squared();
        let (a, b, c) = edges
            .into_iter()
            .max_by(|x, y| length(x).total_cmp(&length(y)))
            .unwrap_or((0, 1, 2));
        let longest = (t[b] - t[a]).length_squared();
        let area = triangle_area(&t);
        if !(area > 1e-14 * longest) {
            continue; // degenerate: no area to integrate
        }
        if !(longest > 4.5 * area) || generation >= MAX_BISECTIONS {
            done.push(t);
            continue;
        }
        let m = 0.5 * (t[a] + t[b]);
        // Both halves keep the winding of `t`.
        todo.push(([t[c], m, t[b]], generation + 1));
        todo.push(([t[c], t[a], m], generation + 1));
    }
    done
}

/// What one form factor's readings share.
struct Sampler<'a, V> {
    n_r: DVec3,
    n_s: DVec3,
    /// The source's front part.
    source: &'a [DVec3],
    /// The cells an occluded reading starts from.
    cells: Vec<[DVec3; 3]>,
    visible: V,
    rays: usize,
    /// Some ray was blocked.
    blocked: bool,
    /// The whole receiver's area (before clipping).
    receiver_area: f64,
    tolerance: f64,
    max_rays: usize,
    /// The factor as estimated so far: a reading at a point in deep shadow
    /// needs its error small beside this, not beside its own value.
    scale: f64,
    /// The latest [`WITNESSES`] source points where a reading's random
    /// rays contradicted a cell's verdict, and where the next goes.
    witnesses: Vec<DVec3>,
    next_witness: usize,
}

impl<V: Fn(DVec3, DVec3) -> bool> Sampler<'_, V> {
    /// The adaptive refinement over `receiver` until the error is at most
    /// `tolerance` × max(value, [`ABSOLUTE_FLOOR`] × area), or `max_rays`
    /// were cast in all. Values and errors are ∫ dA, not yet divided by
    /// the receiver's area.
    fn refine(&mut self, receiver: &[DVec3], occluded: bool, rng: &mut impl Rng) -> Totals {
        let mut heap = BinaryHeap::new();
        for tri in well_shaped(receiver) {
            let own = self.read(&tri, occluded, rng);
            heap.push(self.split(&tri, own, occluded, rng).ranked());
        }
        let mut totals = Totals::of(&heap);
        let mut steps = 0usize;
        // The floor is on the whole receiver's factor (its full area).
        let floor = ABSOLUTE_FLOOR * self.receiver_area;
        while self.rays < self.max_rays {
            if !occluded && self.blocked {
                break; // the caller starts again with the source in cells
            }
            self.scale = totals.value / self.receiver_area;
            let target = self.tolerance * totals.value.max(floor);
            let unseen = self.unseen(occluded, totals.value);
            let rest = totals.error();
            if rest + unseen <= target {
                break;
            }
            if unseen > rest {
                // Cheaper than readings: probe rays until the bound fits
                // beside the rest (in at least half the target).
                let room = (target - rest).max(0.5 * target);
                let wanted = (totals.value / room).ceil() as usize;
                let n = wanted.saturating_sub(self.rays).max(PROBE_RAYS);
                self.probe(receiver, n.min(self.max_rays), rng);
                continue;
            }
            let Some(Ranked { item: worst, .. }) = heap.pop() else {
                break;
            };
            totals.add(&worst, -1.0);
            for (child, own) in worst.children.iter().zip(worst.readings) {
                let p = self.split(child, own, occluded, rng);
                totals.add(&p, 1.0);
                heap.push(p.ranked());
            }
            // The running sums drift: recompute them now and then.
            steps += 1;
            if steps.is_multiple_of(256) {
                totals = Totals::of(&heap);
            }
        }
        let mut totals = Totals::of(&heap);
        totals.bias += self.unseen(occluded, totals.value);
        totals
    }

    /// The bound on an occluder no ray met while the source is read
    /// whole: one hiding a fraction p of the factor `value` escapes n rays
    /// with probability (1 − p)ⁿ < e^(−pn), so a pair whose n rays all got
    /// through states value / n for it (an occluder hiding twice that
    /// escapes with probability e^(−2) at most). Zero once the source is
    /// read in cells, or once a ray was blocked (the pass is then started
    /// again).
    fn unseen(&self, occluded: bool, value: f64) -> f64 {
        match occluded || self.blocked {
            true => 0.0,
            false => value / self.rays.max(1) as f64,
        }
    }

    /// The reading at the centroid of `tri`: the whole source and one ray
    /// while nothing occludes, else the source in cells.
    fn read(&mut self, tri: &[DVec3; 3], occluded: bool, rng: &mut impl Rng) -> Reading {
        let x = centroid(tri);
        let mut reading = match occluded {
            true => {
                let spread = (self.receiver_area / triangle_area(tri)).sqrt();
                self.read_cells(x, spread, rng)
            }
            false => {
                let f = form_factor_point_polygon(x, self.n_r, self.source);
                let mut reading = Reading::default();
                if f > 0.0 {
                    let y = point_in_polygon(self.source, random_unit(rng));
                    self.rays += 1;
                    reading.open = f;
                    match (self.visible)(x, y) {
                        true => reading.value = f,
                        false => reading.blocked = true,
                    }
                }
                reading
            }
        };
        self.blocked |= reading.blocked;
        if !occluded {
            reading.expected = reading.value;
        }
        let a = triangle_area(tri);
        reading.value *= a;
        reading.open *= a;
        reading.variance *= a * a;
        reading.settled *= a;
        reading.expected *= a;
        reading.predicted *= a * a;
        reading
    }

    /// The source seen from `x`, cell by cell (the module doc's occluded
    /// reading): mixed cells halved to the target, the witnesses' rays,
    /// check rounds until one contradicts at most one cell (each followed
    /// by the same again), then the correction round and one ray per mixed
    /// cell left. `spread` is √(receiver area / this triangle's area).
    fn read_cells(&mut self, x: DVec3, spread: f64, rng: &mut impl Rng) -> Reading {
        let ray_budget = self.max_rays.saturating_sub(self.rays);
        let mut view = PointView {
            x,
            n_r: self.n_r,
            n_s: self.n_s,
            visible: &self.visible,
            seen: HashMap::new(),
            rays: 0,
            cells: Vec::new(),
            edges: HashMap::new(),
            mixed: BinaryHeap::new(),
            sums: Sums::default(),
            roots: self.cells.len(),
            found: Vec::new(),
        };
        for tri in &self.cells {
            view.insert(*tri, 0);
        }
        let target = |sums: &Sums| {
            let value = (sums.seen + 0.5 * sums.mixed)
                .max(self.scale)
                .max(ABSOLUTE_FLOOR);
            (READING_SHARE * self.tolerance * spread).min(1.0) * value
        };
        let mut round = FIRST_CHECK_ROUND / 4;
        let mut checks = 0;
        let mut done = false;
        let mut contradicted = 0;
        loop {
            // Cells the last round contradicted are refined like the rest
            // before the reading ends: one ray across a coarse mixed cell
            // has a variance its factor does not bound.
            while view.rays < ray_budget
                && 2.0 * view.sums.mixed_variance > target(&view.sums).powi(2)
            {
                let Some(Ranked { item: c, .. }) = view.mixed.pop() else {
                    break;
                };
                let cell = &view.cells[c];
                if cell.state == State::Mixed && cell.depth < MAX_CELL_DEPTH {
                    view.bisect(c);
                }
            }
            // What other readings found wrong is looked at first: a small
            // shadow inside a coarse cell is then found once, not missed
            // by most readings and found, with a heavy weight, by a few.
            if view.rays < ray_budget && view.witness(&self.witnesses) > 0 {
                continue;
            }
            if done || view.sums.settled == 0.0 || view.rays >= ray_budget {
                break;
            }
            // Rounds grow fourfold from a small one (the value a round is
            // sized by is a guess before the first), up to this reading's
            // share of the receiver's check rays.
            let wanted =
                (CHECK_ROUND * view.sums.settled / (spread * target(&view.sums))).ceil() as usize;
            round = wanted
                .min(4 * round)
                .min(ray_budget.saturating_sub(view.rays))
                .max(1);
            // The correction's standard deviation will be about S (k + 1)
            // / n: go on while that is above the target.
            let k = view.check(round, rng);
            contradicted = k;
            checks += round - k;
            done = k <= 1 || wanted <= round;
        }
        let (correction, correction_variance) = match view.sums.settled > 0.0 {
            true => view.correction(round, rng),
            false => (0.0, 0.0),
        };
        checks += round;
        let mut reading = Reading {
            value: view.sums.seen + correction,
            open: view.sums.open,
            variance: correction_variance,
            settled: view.sums.settled,
            checks: checks as f64,
            blocked: view.sums.settled > view.sums.seen || view.sums.mixed > 0.0,
            expected: view.sums.seen + 0.5 * view.sums.mixed,
            // The last check round's contradictions foretell the
            // correction's variance: S² k / n².
            predicted: view.sums.mixed_variance
                + (view.sums.settled / round as f64).powi(2) * contradicted as f64,
        };
        let mut rays = view.rays;
        for w in std::mem::take(&mut view.found) {
            match self.witnesses.len() < WITNESSES {
                true => self.witnesses.push(w),
                false => self.witnesses[self.next_witness % WITNESSES] = w,
            }
            self.next_witness += 1;
        }
        for cell in view.cells.iter().filter(|c| c.state == State::Mixed) {
            let y = point_in_polygon(&cell.tri, random_unit(rng));
            rays += 1;
            // The point kernel at y times the cell's area: its factor
            // weighted by where the ray went, so that a partly seen cell
            // counts the part seen by its factor, not by its area.
            let g = kernel(x, self.n_r, y, self.n_s) * triangle_area(&cell.tri);
            if (self.visible)(x, y) {
                reading.value += g;
            }
            reading.variance += 0.25 * cell.f.max(g).powi(2);
        }
        self.rays += rays;
        reading
    }

    /// `tri` (read as `own`) against its four quarters.
    fn split(
        &mut self,
        tri: &[DVec3; 3],
        own: Reading,
        occluded: bool,
        rng: &mut impl Rng,
    ) -> Piece {
        let children = quarters(tri);
        let readings = children.map(|c| self.read(&c, occluded, rng));
        let sum = |f: fn(&Reading) -> f64| readings.iter().map(f).sum::<f64>();
        let open_diff = sum(|r| r.open) - own.open;
        let lost_diff = (sum(|r| r.open - r.expected)) - (own.open - own.expected);
        let area = triangle_area(tri);
        // Per unit area: the unoccluded point factors seen.
        let (mut lo, mut hi) = (own.open / area, own.open / area);
        for r in &readings {
            lo = lo.min(4.0 * r.open / area);
            hi = hi.max(4.0 * r.open / area);
        }
        let wide = (0..3)
            .map(|k| (tri[(k + 1) % 3] - tri[k]).length())
            .fold(0.0, f64::max);
        let near = self.distance(centroid(tri)) < wide;
        Piece {
            children,
            readings,
            bias: match near {
                true => open_diff.abs().max(area * (hi - lo)),
                false => open_diff.abs(),
            },
            // What the lost light's difference says beyond the readings'
            // own noise is the receiver's: E[diff²] = D² + their variances.
            noise: {
                let d2 = (lost_diff * lost_diff - sum(|r| r.predicted) - own.predicted).max(0.0);
                (sum(|r| r.variance) + d2).sqrt()
            },
            key_noise: {
                let predicted = sum(|r| r.predicted);
                let d2 = (lost_diff * lost_diff - predicted - own.predicted).max(0.0);
                (predicted + d2).sqrt()
            },
        }
    }

    /// Whether any of `n` rays between stratified points of `receiver` and
    /// of the source is blocked.
    fn probe(&mut self, receiver: &[DVec3], n: usize, rng: &mut impl Rng) -> bool {
        let from = stratified(n, rng);
        let to = stratified(n, rng);
        self.rays += n;
        let (r, s) = (
            PolygonSampler::new(receiver),
            PolygonSampler::new(self.source),
        );
        let hit = from
            .iter()
            .zip(to.iter().rev())
            .any(|(a, b)| !(self.visible)(r.point(*a), s.point(*b)));
        self.blocked |= hit;
        hit
    }

    /// Distance from `x` to the source polygon.
    fn distance(&self, x: DVec3) -> f64 {
        let polygon = self.source;
        let height = (x - polygon[0]).dot(self.n_s);
        let foot = x - height * self.n_s;
        if outside_polygon(polygon, self.n_s, foot) <= 0.0 {
            return height.abs();
        }
        (0..polygon.len())
            .map(|k| segment_distance(x, polygon[k], polygon[(k + 1) % polygon.len()]))
            .fold(f64::INFINITY, f64::min)
    }
}

/// A point's bits, to key the rays cast to it and the edges through it.
type Key = [u64; 3];

fn key(p: DVec3) -> Key {
    p.to_array().map(f64::to_bits)
}

/// What a source cell's corners and centroid saw of it.
#[derive(Clone, Copy, PartialEq, Debug)]
enum State {
    Seen,
    Hidden,
    /// They disagree: it holds part of a shadow's edge.
    Mixed,
    /// Halved: its halves stand for it.
    Split,
}

/// A source cell: a triangle with the winding of the source, its point
/// factor, how many halvings made it, and what its points saw.
struct Cell {
    tri: [DVec3; 3],
    f: f64,
    depth: u32,
    state: State,
    /// Its halves, once split.
    halves: Option<[usize; 2]>,
}

/// Sums of point factors over the cells not split: all of them, the seen,
/// the settled (seen or hidden), the mixed, and Σ f² / 4 over the mixed.
#[derive(Clone, Copy, Default)]
struct Sums {
    open: f64,
    seen: f64,
    settled: f64,
    mixed: f64,
    mixed_variance: f64,
}

/// One receiver point's reading of the source in cells: a conforming
/// triangulation refined by longest-edge bisection (a cell's longest edge
/// is its neighbour's too, or the neighbour is halved first), so no cell
/// has a corner of another inside an edge, and a cell next to a shadow's
/// edge is never much larger than the cells along it. The rays it cast,
/// by point (a corner is shared by its cells and cast once).
struct PointView<'v, V> {
    x: DVec3,
    n_r: DVec3,
    n_s: DVec3,
    visible: &'v V,
    seen: HashMap<Key, bool>,
    rays: usize,
    cells: Vec<Cell>,
    /// The cells on each edge, by its ends' keys in order.
    edges: HashMap<[Key; 2], Vec<usize>>,
    /// Mixed cells by point factor (entries of cells since halved or
    /// settled are skipped).
    mixed: BinaryHeap<Ranked<usize>>,
    sums: Sums,
    /// The start cells are the first `roots`.
    roots: usize,
    /// Source points where this reading's random rays contradicted a
    /// cell's verdict.
    found: Vec<DVec3>,
}

fn edge_key(a: DVec3, b: DVec3) -> [Key; 2] {
    let (ka, kb) = (key(a), key(b));
    match ka <= kb {
        true => [ka, kb],
        false => [kb, ka],
    }
}

/// The index k of `tri`'s longest edge (tri[k], tri[k + 1]); ties go to
/// the smaller key, so two cells sharing an edge agree on it.
fn longest_edge(tri: &[DVec3; 3]) -> usize {
    (0..3)
        .max_by(|&i, &j| {
            let length = |e: usize| (tri[(e + 1) % 3] - tri[e]).length_squared();
            let edge = |e: usize| edge_key(tri[e], tri[(e + 1) % 3]);
            length(i)
                .total_cmp(&length(j))
                .then_with(|| edge(j).cmp(&edge(i)))
        })
        .unwrap_or(0)
}

impl<V: Fn(DVec3, DVec3) -> bool> PointView<'_, V> {
    fn sees(&mut self, p: DVec3) -> bool {
        let (x, visible) = (self.x, self.visible);
        let rays = &mut self.rays;
        *self.seen.entry(key(p)).or_insert_with(|| {
            *rays += 1;
            visible(x, p)
        })
    }

    /// Adds or takes away cell `c`'s factor in the sums of its state.
    fn account(&mut self, c: usize, sign: f64) {
        let Cell { f, state, .. } = self.cells[c];
        let sums = &mut self.sums;
        let f = sign * f;
        match state {
            State::Seen => (sums.seen += f, sums.settled += f, sums.open += f),
            State::Hidden => ((), sums.settled += f, sums.open += f),
            State::Mixed => (
                sums.mixed += f,
                sums.mixed_variance += 0.25 * f * f / sign,
                sums.open += f,
            ),
            State::Split => ((), (), ()),
        };
    }

    fn set_state(&mut self, c: usize, state: State) {
        self.account(c, -1.0);
        self.cells[c].state = state;
        self.account(c, 1.0);
        if state == State::Mixed {
            self.mixed.push(Ranked {
                key: self.cells[c].f,
                item: c,
            });
        }
    }

    /// Adds cell `tri` (halved `depth` times): settled if its corners and
    /// centroid agree, else mixed. A cell facing away casts no rays.
    fn insert(&mut self, tri: [DVec3; 3], depth: u32) {
        let f = form_factor_point_polygon(self.x, self.n_r, &tri).max(0.0);
        let c = self.cells.len();
        self.cells.push(Cell {
            tri,
            f,
            depth,
            state: State::Split,
            halves: None,
        });
        for k in 0..3 {
            let edge = edge_key(tri[k], tri[(k + 1) % 3]);
            self.edges.entry(edge).or_default().push(c);
        }
        let state = match f > 0.0 {
            false => State::Hidden,
            true => {
                let first = self.sees(tri[0]);
                // All four are cast: the corners are shared with the
                // neighbours, which will ask for them anyway.
                let others = [tri[1], tri[2], centroid(&tri)].map(|p| self.sees(p));
                let agree = others.iter().all(|&seen| seen == first);
                match (agree, first) {
                    (true, true) => State::Seen,
                    (true, false) => State::Hidden,
                    (false, _) => State::Mixed,
                }
            }
        };
        self.set_state(c, state);
    }

    /// Halves cell `c` across its longest edge, and the neighbour across
    /// that edge with it, halving the neighbour first (recursively) until
    /// that edge is its longest too.
    fn bisect(&mut self, c: usize) {
        let tri = self.cells[c].tri;
        let k = longest_edge(&tri);
        let edge = edge_key(tri[k], tri[(k + 1) % 3]);
        loop {
            let neighbour = self.edges[&edge].iter().copied().find(|&n| n != c);
            let Some(n) = neighbour else { break };
            let other = self.cells[n].tri;
            let kn = longest_edge(&other);
            if edge_key(other[kn], other[(kn + 1) % 3]) == edge {
                self.halve(n, kn);
                break;
            }
            self.bisect(n);
        }
        self.halve(c, k);
    }

    /// Replaces cell `c` by its halves across edge k.
    fn halve(&mut self, c: usize, k: usize) {
        let Cell { tri, depth, .. } = self.cells[c];
        self.set_state(c, State::Split);
        for j in 0..3 {
            let edge = edge_key(tri[j], tri[(j + 1) % 3]);
            if let Some(cells) = self.edges.get_mut(&edge) {
                cells.retain(|&other| other != c);
                if cells.is_empty() {
                    self.edges.remove(&edge);
                }
            }
        }
        let (a, b, o) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
        let m = 0.5 * (a + b);
        let first = self.cells.len();
        self.insert([a, m, o], depth + 1);
        self.insert([m, b, o], depth + 1);
        self.cells[c].halves = Some([first, first + 1]);
    }

    /// The unsplit cell holding source point `w`, if any: down from the
    /// start cell that holds it (the first `roots` cells).
    fn locate(&self, w: DVec3) -> Option<usize> {
        let mut c = (0..self.roots).find(|&c| inside(&self.cells[c].tri, w))?;
        while let Some([a, b]) = self.cells[c].halves {
            c = match inside(&self.cells[a].tri, w) {
                true => a,
                false => b,
            };
        }
        Some(c)
    }

    /// Casts a ray to each witness (a source point where another reading
    /// found a cell's verdict wrong); the settled cells one contradicts
    /// become mixed. How many did.
    fn witness(&mut self, witnesses: &[DVec3]) -> usize {
        let mut contradicted = 0;
        for &w in witnesses {
            let Some(c) = self.locate(w) else { continue };
            let Cell { f, state, .. } = self.cells[c];
            if f > 0.0
                && matches!(state, State::Seen | State::Hidden)
                && self.sees(w) != (state == State::Seen)
            {
                self.set_state(c, State::Mixed);
                contradicted += 1;
            }
        }
        contradicted
    }

    /// `n` rays to uniform points of settled cells, each cell drawn with
    /// probability its share of their factor S; calls `ray(cell, y, seen)`.
    fn draw(&mut self, n: usize, rng: &mut impl Rng, mut ray: impl FnMut(usize, DVec3, bool)) {
        let settled: Vec<usize> = (0..self.cells.len())
            .filter(|&c| matches!(self.cells[c].state, State::Seen | State::Hidden))
            .filter(|&c| self.cells[c].f > 0.0)
            .collect();
        let mut cumulative = Vec::with_capacity(settled.len());
        let mut total = 0.0;
        for &c in &settled {
            total += self.cells[c].f;
            cumulative.push(total);
        }
        if settled.is_empty() {
            return;
        }
        for _ in 0..n {
            let u = rng.random::<f64>() * total;
            let k = cumulative
                .partition_point(|&s| s <= u)
                .min(settled.len() - 1);
            let y = point_in_polygon(&self.cells[settled[k]].tri, random_unit(rng));
            self.rays += 1;
            ray(settled[k], y, (self.visible)(self.x, y));
        }
    }

    /// `n` check rays ([`Self::draw`]); the cells a ray contradicts become
    /// mixed. How many rays did.
    fn check(&mut self, n: usize, rng: &mut impl Rng) -> usize {
        let mut contradicted = Vec::new();
        let mut states: Vec<State> = self.cells.iter().map(|c| c.state).collect();
        let mut found = Vec::new();
        self.draw(n, rng, |c, y, seen| {
            if seen != (states[c] == State::Seen) {
                contradicted.push(c);
                found.push(y);
                states[c] = State::Mixed;
            }
        });
        self.found.extend(found);
        for &c in &contradicted {
            if self.cells[c].state != State::Mixed {
                self.set_state(c, State::Mixed);
            }
        }
        contradicted.len()
    }

    /// What the settled cells' verdicts got wrong, estimated without bias
    /// by `n` rays ([`Self::draw`]): each adds (V(y) − verdict) times the
    /// kernel at y times its cell's area over its cell's factor, and the
    /// mean times S is the correction. Returns it and its variance, taken
    /// as if at least one ray had disagreed (S² / n² at the least).
    fn correction(&mut self, n: usize, rng: &mut impl Rng) -> (f64, f64) {
        let (mut sum, mut squares) = (0.0, 0.0);
        let (x, n_r, n_s) = (self.x, self.n_r, self.n_s);
        let cells: Vec<([DVec3; 3], f64, bool)> = self
            .cells
            .iter()
            .map(|c| (c.tri, c.f, c.state == State::Seen))
            .collect();
        let mut found = Vec::new();
        self.draw(n, rng, |c, y, seen| {
            let (tri, f, verdict) = cells[c];
            if seen != verdict {
                found.push(y);
                let term = (seen as u8 as f64 - verdict as u8 as f64)
                    * kernel(x, n_r, y, n_s)
                    * triangle_area(&tri)
                    / f;
                sum += term;
                squares += term * term;
            }
        });
        self.found.extend(found);
        let (settled, n) = (self.sums.settled, n.max(1) as f64);
        (settled * sum / n, settled * settled * squares / (n * n))
    }
}

/// The form factor's kernel cos θ_x cos θ_y / (π r²) between a receiver
/// point `x` (normal `n_x`) and a source point `y` (normal `n_y`).
fn kernel(x: DVec3, n_x: DVec3, y: DVec3, n_y: DVec3) -> f64 {
    let d = y - x;
    let r2 = d.length_squared();
    let cosines = n_x.dot(d).max(0.0) * (-n_y.dot(d)).max(0.0);
    match r2 > 0.0 {
        true => cosines / (std::f64::consts::PI * r2 * r2),
        false => 0.0,
    }
}

/// Whether point `w` of the triangle's plane is inside it (edges
/// included).
fn inside(t: &[DVec3; 3], w: DVec3) -> bool {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    (0..3).all(|k| n.dot((t[(k + 1) % 3] - t[k]).cross(w - t[k])) >= 0.0)
}

fn centroid(t: &[DVec3; 3]) -> DVec3 {
    (t[0] + t[1] + t[2]) / 3.0
}

/// A uniform point of the unit square.
fn random_unit(rng: &mut impl Rng) -> DVec2 {
    DVec2::new(rng.random(), rng.random())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formfactor::closed_form::{c11, c14};
    use crate::sampling::stream;

    fn square(z: f64, up: bool) -> Vec<DVec3> {
        let mut v = vec![
            DVec3::new(0.0, 0.0, z),
            DVec3::new(1.0, 0.0, z),
            DVec3::new(1.0, 1.0, z),
            DVec3::new(0.0, 1.0, z),
        ];
        if !up {
            v.reverse();
        }
        v
    }

    #[test]
    fn parallel_and_perpendicular_squares_meet_their_tolerance() {
        let wall = [DVec3::ZERO, DVec3::Z, DVec3::new(1.0, 0.0, 1.0), DVec3::X];
        for (source, exact) in [
            (square(1.0, false), c11(1.0, 1.0, 1.0)),
            (wall.to_vec(), c14(1.0, 1.0, 1.0)),
        ] {
            for tol in [1e-2, 1e-3] {
                let f = form_factor_area_sampling(
                    &square(0.0, true),
                    &source,
                    tol,
                    MAX_RAYS,
                    &mut stream(1, 2),
                    |_, _| true,
                );
                let err = (f.value - exact).abs();
                assert!(err < tol * exact, "{f:?} vs {exact}");
                assert!(f.error <= tol * f.value.max(exact) * 1.001, "{f:?}");
                assert!(err <= 2.0 * f.error + 1e-12, "{f:?} vs {exact}");
            }
        }
    }

    #[test]
    fn a_wholly_hidden_source_gives_zero_and_a_back_facing_one_no_rays() {
        let mut rng = stream(3, 4);
        let f = form_factor_area_sampling(
            &square(0.0, true),
            &square(1.0, false),
            0.01,
            MAX_RAYS,
            &mut rng,
            |_, _| false,
        );
        assert_eq!(f.value, 0.0);
        let f = form_factor_area_sampling(
            &square(0.0, true),
            &square(1.0, true),
            0.01,
            MAX_RAYS,
            &mut rng,
            |_, _| true,
        );
        assert_eq!((f.value, f.evaluations), (0.0, 0));
    }
}
