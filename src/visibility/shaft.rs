//! Shaft culling (\[HW91\]): whether anything at all can stand between two
//! convex pieces of surface, asked of the BVH once instead of by rays.
//!
//! Owns: [`Shaft`], the convex hull of two point sets (a receiver polygon
//! or a single point, and a source polygon) cut by the half-spaces in
//! front of each surface, and [`TriangleBvh::shaft_clear`].
//!
//! Every segment from a point of one set to a point of the other lies in
//! the hull of their union, and a segment that carries light leaves the
//! front of both surfaces. So when every occluder triangle lies wholly on
//! the outer side of one of the shaft's planes, no such segment is
//! blocked: the visible fraction is exactly 1, with no ray and no noise.
//!
//! Invariants:
//! - The test is conservative: it answers "clear" only when every
//!   triangle is outside some plane of the shaft, within [`SHAFT_GAP`] of
//!   the scene diagonal (so triangles lying in a surface's own plane, the
//!   surface itself and its coplanar neighbours, never count, whatever
//!   f32 rounding did to them). Any subset of the planes bounds a larger
//!   region, so dropping planes (more than [`MAX_PLANES`]) stays
//!   conservative.
//! - BVH nodes are tested by their (outward-rounded) child boxes, so no
//!   triangle inside the shaft is skipped.

use glam::{DVec3, UVec2, Vec3A};
use obvhs::cwbvh::node::extract_byte64;
use obvhs::traverse;

use super::TriangleBvh;

/// Occluders that reach less than this fraction of the scene diagonal into
/// a shaft do not count (a hundredth of the rays' own endpoint gap, far
/// above f32 rounding of the geometry).
pub const SHAFT_GAP: f64 = 1e-6;

/// Planes a shaft keeps at most: the hull of two quads has at most twelve
/// faces, plus the two surfaces' own planes.
pub const MAX_PLANES: usize = 16;

/// A convex region as the intersection of half-spaces n·p ≤ d (n unit,
/// pointing out), in the coordinates it was built in.
#[derive(Clone, Debug)]
pub struct Shaft {
    planes: [(DVec3, f64); MAX_PLANES],
    count: usize,
    lo: DVec3,
    hi: DVec3,
}

impl Shaft {
    /// The hull of `a` ∪ `b`, each a convex polygon (its vertices in
    /// order) or a single point, at most eight vertices in all, cut by the
    /// front half-spaces of `fronts` (a point on each surface and its
    /// normal): the region every light-carrying segment between a point of
    /// `a` and a point of `b` lies in. `None` when there are more than
    /// eight vertices or the hull is flat (nothing passes between the
    /// two).
    pub fn new(a: &[DVec3], b: &[DVec3], fronts: &[(DVec3, DVec3)]) -> Option<Shaft> {
        let mut pts = [DVec3::ZERO; 8];
        let n = a.len() + b.len();
        if n > pts.len() || a.is_empty() || b.is_empty() {
            return None;
        }
        for (slot, p) in pts.iter_mut().zip(a.iter().chain(b)) {
            *slot = *p;
        }
        let pts = &pts[..n];
        let (lo, hi) = pts
            .iter()
            .fold((pts[0], pts[0]), |(l, h), p| (l.min(*p), h.max(*p)));
        let extent = (hi - lo).length();
        if !(extent > 0.0) || !extent.is_finite() {
            return None;
        }
        let mut shaft = Shaft {
            planes: [(DVec3::ZERO, 0.0); MAX_PLANES],
            count: 0,
            lo,
            hi,
        };
        for &(p, normal) in fronts {
            let n = normal.normalize_or_zero();
            if n != DVec3::ZERO {
                // In front: n·x ≥ n·p, i.e. (−n)·x ≤ −n·p.
                shaft.push(-n, -n.dot(p), extent);
            }
        }
        // Faces of the hull besides the two surfaces' own planes: each
        // holds an edge of one polygon and a vertex of the other (a face
        // with two vertices of one polygon on it holds the edge between
        // them, as the polygon lies on one side).
        let flat = 1e-9 * extent;
        let mut faces = 0;
        let (na, nb) = (a.len(), b.len());
        let edges = |first: usize, len: usize| {
            (0..if len >= 3 { len } else { 0 }).map(move |i| (first + i, first + (i + 1) % len))
        };
        let candidates = edges(0, na)
            .flat_map(|e| (na..n).map(move |v| (e, v)))
            .chain(edges(na, nb).flat_map(|e| (0..na).map(move |v| (e, v))));
        for ((i, j), k) in candidates {
            let c = (pts[j] - pts[i]).cross(pts[k] - pts[i]);
            let len = c.length();
            if !(len > 1e-12 * extent * extent) {
                continue;
            }
            let u = c / len;
            let d = u.dot(pts[i]);
            let (mut above, mut below) = (false, false);
            for p in pts {
                let s = u.dot(*p) - d;
                above |= s > flat;
                below |= s < -flat;
            }
            match (above, below) {
                (false, true) => shaft.push(u, d, extent),
                (true, false) => shaft.push(-u, -d, extent),
                (false, false) => return None,
                (true, true) => continue,
            }
            faces += 1;
        }
        (faces > 0).then_some(shaft)
    }

    /// Adds the half-space n·x ≤ d unless a kept plane is the same.
    fn push(&mut self, n: DVec3, d: f64, extent: f64) {
        let same = self.planes[..self.count]
            .iter()
            .any(|(m, e)| m.dot(n) > 1.0 - 1e-12 && (e - d).abs() <= 1e-9 * extent);
        if !same && self.count < MAX_PLANES {
            self.planes[self.count] = (n, d);
            self.count += 1;
        }
    }

    /// The planes, n·x ≤ d inside.
    pub fn planes(&self) -> &[(DVec3, f64)] {
        &self.planes[..self.count]
    }
}

/// A shaft in the BVH's f32 scaled coordinates.
struct Scaled {
    normals: [Vec3A; MAX_PLANES],
    offsets: [f32; MAX_PLANES],
    count: usize,
    lo: Vec3A,
    hi: Vec3A,
    gap: f32,
}

impl Scaled {
    /// True when the box [lo, hi] lies wholly outside (or within the gap
    /// of) some plane, or outside the shaft's bounding box.
    fn box_outside(&self, lo: Vec3A, hi: Vec3A) -> bool {
        if lo.cmpgt(self.hi + self.gap).any() || hi.cmplt(self.lo - self.gap).any() {
            return true;
        }
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        (0..self.count).any(|i| {
            let n = self.normals[i];
            n.dot(centre) - n.abs().dot(half) - self.offsets[i] > -self.gap
        })
    }

    /// True when the triangle lies wholly outside (or within the gap of)
    /// some plane.
    fn triangle_outside(&self, v: [Vec3A; 3]) -> bool {
        (0..self.count).any(|i| {
            let (n, d) = (self.normals[i], self.offsets[i]);
            v.iter().all(|p| n.dot(*p) - d > -self.gap)
        })
    }
}

impl TriangleBvh {
    /// True when no occluder triangle reaches into `shaft` (by more than
    /// [`SHAFT_GAP`] of the diagonal): every segment inside it is
    /// unblocked. Conservative: false when in doubt.
    pub fn shaft_clear(&self, shaft: &Shaft) -> bool {
        if self.triangles.is_empty() {
            return true;
        }
        let s = self.scale;
        let mut scaled = Scaled {
            normals: [Vec3A::ZERO; MAX_PLANES],
            offsets: [0.0; MAX_PLANES],
            count: shaft.count,
            lo: (shaft.lo * s).as_vec3().into(),
            hi: (shaft.hi * s).as_vec3().into(),
            gap: (SHAFT_GAP * self.diagonal * s) as f32,
        };
        for (i, (n, d)) in shaft.planes().iter().enumerate() {
            scaled.normals[i] = n.as_vec3().into();
            scaled.offsets[i] = (d * s) as f32;
        }
        let mut state = self.bvh.new_traversal(Vec3A::X);
        let mut node;
        let mut clear = true;
        'outer: {
            traverse!(
                self.bvh,
                node,
                state,
                {
                    let e = node.compute_extent();
                    let p = Vec3A::from(node.p);
                    let (child_bits8, bit_index8) = node.get_child_and_index_bits(state.oct_inv4);
                    let mut mask = 0;
                    for child in 0..8 {
                        let q = node.local_child_aabb(child);
                        if !scaled.box_outside(p + e * q.min, p + e * q.max) {
                            mask |= extract_byte64(child_bits8, child)
                                << extract_byte64(bit_index8, child);
                        }
                    }
                    mask
                },
                {
                    let t = &self.triangles[state.primitive_id as usize];
                    if !scaled.triangle_outside([t.v0, t.v1, t.v2]) {
                        clear = false;
                        break 'outer;
                    }
                }
            );
        }
        clear
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn square(z: f32, x0: f32, x1: f32) -> [[Vec3; 3]; 2] {
        let p = |x: f32, y: f32| Vec3::new(x, y, z);
        [
            [p(x0, x0), p(x1, x0), p(x1, x1)],
            [p(x0, x0), p(x1, x1), p(x0, x1)],
        ]
    }

    fn quad(z: f64, x0: f64, x1: f64) -> [DVec3; 4] {
        [
            DVec3::new(x0, x0, z),
            DVec3::new(x1, x0, z),
            DVec3::new(x1, x1, z),
            DVec3::new(x0, x1, z),
        ]
    }

    #[test]
    fn a_shaft_sees_what_stands_between_and_nothing_beside() {
        // Floor at z = 0 and ceiling at z = 2, both part of the occluders;
        // a small plate at z = 1 either between them or off to the side.
        let floor = quad(0.0, 0.0, 1.0);
        let ceiling = quad(2.0, 0.0, 1.0);
        let fronts = [(floor[0], DVec3::Z), (ceiling[0], -DVec3::Z)];
        let shaft = Shaft::new(&floor, &ceiling, &fronts).unwrap();
        let mut tris: Vec<[Vec3; 3]> = square(0.0, 0.0, 1.0).to_vec();
        tris.extend(square(2.0, 0.0, 1.0));
        // Neighbours of the floor in its own plane never count.
        tris.extend(square(0.0, 1.0, 3.0));
        let base = tris.clone();
        assert!(TriangleBvh::new(&base, 4.0).shaft_clear(&shaft));
        tris.extend(square(1.0, 0.4, 0.6));
        assert!(!TriangleBvh::new(&tris, 4.0).shaft_clear(&shaft));
        let mut beside = base.clone();
        beside.extend(square(1.0, 3.0, 4.0));
        assert!(TriangleBvh::new(&beside, 4.0).shaft_clear(&shaft));
    }

    #[test]
    fn a_floor_and_a_wall_that_share_an_edge() {
        // Floor z = 0 and wall x = 0 meet along the y axis; their
        // neighbours in their own planes, and the rest of a room, stand
        // outside the shaft; a block in the corner does not.
        let floor = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let wall = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 1.0),
            DVec3::new(0.0, 0.0, 1.0),
        ];
        let fronts = [(floor[0], DVec3::Z), (wall[0], DVec3::X)];
        let shaft = Shaft::new(&floor, &wall, &fronts).unwrap();
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let room = vec![
            [v(0.0, 0.0, 0.0), v(3.0, 0.0, 0.0), v(3.0, 3.0, 0.0)],
            [v(0.0, 0.0, 0.0), v(3.0, 3.0, 0.0), v(0.0, 3.0, 0.0)],
            [v(0.0, 0.0, 0.0), v(0.0, 3.0, 0.0), v(0.0, 3.0, 3.0)],
            [v(0.0, 0.0, 0.0), v(0.0, 3.0, 3.0), v(0.0, 0.0, 3.0)],
            [v(0.0, 0.0, 3.0), v(3.0, 0.0, 3.0), v(3.0, 3.0, 3.0)],
            [v(3.0, 0.0, 0.0), v(3.0, 3.0, 0.0), v(3.0, 3.0, 3.0)],
        ];
        assert!(TriangleBvh::new(&room, 5.0).shaft_clear(&shaft));
        let mut blocked = room.clone();
        blocked.push([v(0.1, 0.4, 0.0), v(0.3, 0.4, 0.0), v(0.1, 0.4, 0.2)]);
        assert!(!TriangleBvh::new(&blocked, 5.0).shaft_clear(&shaft));
    }

    #[test]
    fn a_point_shaft_is_a_pyramid() {
        let source = quad(2.0, 0.0, 1.0);
        let x = DVec3::new(0.5, 0.5, 0.0);
        let fronts = [(x, DVec3::Z), (source[0], -DVec3::Z)];
        let shaft = Shaft::new(&[x], &source, &fronts).unwrap();
        // A plate near the floor, outside the pyramid's foot but inside
        // the box of the two: not in the way.
        let plate = [[
            Vec3::new(0.9, 0.9, 0.1),
            Vec3::new(1.0, 0.9, 0.1),
            Vec3::new(1.0, 1.0, 0.1),
        ]];
        assert!(TriangleBvh::new(&plate, 4.0).shaft_clear(&shaft));
        let blocker = [[
            Vec3::new(0.45, 0.45, 0.5),
            Vec3::new(0.55, 0.45, 0.5),
            Vec3::new(0.5, 0.55, 0.5),
        ]];
        assert!(!TriangleBvh::new(&blocker, 4.0).shaft_clear(&shaft));
    }

    #[test]
    fn a_clear_shaft_agrees_with_rays() {
        // Random small plates among the points of two facing quads: where
        // the shaft says clear, no ray between them is blocked.
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let a = quad(0.0, 0.0, 1.0);
        let b = quad(1.5, 0.3, 0.8);
        let fronts = [(a[0], DVec3::Z), (b[0], -DVec3::Z)];
        let shaft = Shaft::new(&a, &b, &fronts).unwrap();
        let mut clear_seen = 0;
        for _ in 0..200 {
            let c = Vec3::new(
                rng.random_range(-0.5..1.5),
                rng.random_range(-0.5..1.5),
                rng.random_range(0.1..1.4),
            );
            let h = 0.08;
            let tris = [[c, c + Vec3::new(h, 0.0, 0.0), c + Vec3::new(0.0, h, 0.02)]];
            let bvh = TriangleBvh::new(&tris, 3.0);
            if !bvh.shaft_clear(&shaft) {
                continue;
            }
            clear_seen += 1;
            for _ in 0..64 {
                let (u, v): (f64, f64) = (rng.random(), rng.random());
                let x = DVec3::new(u, v, 0.0);
                let (u, v): (f64, f64) = (rng.random(), rng.random());
                let y = DVec3::new(0.3 + 0.5 * u, 0.3 + 0.5 * v, 1.5);
                assert!(bvh.visible(x, y), "{c:?}");
            }
        }
        assert!(clear_seen > 20, "{clear_seen}");
    }
}
